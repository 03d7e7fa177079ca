"""Choosing the model ``gpcd train`` fits (``--model auto``, the default).

Two questions, answered from the training recordings alone:

* **Which models can the data carry?** P_f, SP_S and SP_P need the robot's
  rigid-body model; SP_C needs the controller's target current among the
  inputs, and a target current that does *not* already contain the servo's
  feedback: :func:`check_target_current` (:data:`FEEDBACK_RULE`). A target
  that is the servo's full command follows the measured current, contacts
  included, so a mean made of it subtracts the contact it should reveal.
  :func:`candidate_models` lists the models possible and why the others
  are not.
* **Which of them serves detection best?** :func:`compare_models` fits
  each candidate on all training recordings but one and runs ``gpcd
  calibrate``'s alarm rule on the residual of the one left out
  (:data:`CHOICE_RULE`): the thresholds that rule would set across the
  left-out recordings -- the largest excursions times the
  leave-one-recording-out margin -- are what a contact must exceed, so the
  smallest wins; the prediction error (nMSE) breaks near ties. A model
  whose residual is small on average but whose extremes jump from one
  recording to the next (a large margin) loses, though its nMSE is the
  smallest.
"""

import time
from dataclasses import dataclass, field

import numpy as np

from .._gate import DEFAULT_SIGMA_V
from .training import MODELS, ROBOT_MODELS, TrainingSet, train_model

__all__ = ["CHOICE_RULE", "CHOICE_TIE", "FEEDBACK_LIMIT", "FEEDBACK_MIN_WINDOWS", "FEEDBACK_RULE",
           "FEEDBACK_SPEED", "FEEDBACK_WINDOW",
           "FOLD_ROWS", "FOLD_SUPPORT", "FOLD_TEST_ROWS", "SIGNALS", "ModelComparison",
           "TargetCurrentCheck",
           "candidate_models", "check_target_current", "choose_model", "compare_models",
           "input_signals"]

#: Controller signals model inputs may use (``gpcd train --signals``).
SIGNALS = ("target_q", "target_qd", "target_current")
#: GP support rows per joint of the fits :func:`choose_model` compares (fewer
#: when the model's own ``n_support`` is smaller).
FOLD_SUPPORT = 200
#: Training rows of each fit :func:`compare_models` makes, at most (every
#: k-th row of the recordings not left out).
FOLD_ROWS = 5_000
#: Rows of a left-out recording the fold's model predicts, at most (the first
#: ones, contiguous: the alarm rule filters and debounces them in time).
FOLD_TEST_ROWS = 30_000
#: Candidates whose threshold score is within this factor of the smallest
#: are tied; the smallest nMSE among them wins (:data:`CHOICE_RULE`).
CHOICE_TIE = 1.05
#: Length [s] of the windows over which :func:`check_target_current` averages
#: ``current - target_current``.
FEEDBACK_WINDOW = 0.1
#: Speed [rad/s] above which a joint moves, for :func:`check_target_current`
#: (the quasi-static threshold's default). A joint that never moves may need no
#: feedback at all (its feed-forward holds it exactly): its ``current -
#: target_current`` is then white whatever the target is, and tells nothing.
FEEDBACK_SPEED = DEFAULT_SIGMA_V
#: Windows in which a joint moves throughout that it needs for
#: :func:`check_target_current` to judge it.
FEEDBACK_MIN_WINDOWS = 20
#: Below this ratio on some joint, the target current follows the measured
#: current (:data:`FEEDBACK_RULE`). Chosen between the package simulator's
#: full servo command (ratio 0.9-1.1 on every joint of D1 runs of the UR10,
#: UR10e, UR5e) and feed-forward targets: the real UR10e (Mamedov et al.)
#: 6.5-11.2 on the 12 identification runs the real-robot benchmark trains on,
#: 3.3-7.3 on each jointwise run alone (the joint that moves), 11.1-19.7 on the
#: point-to-point validation run; the simulator's feed-forward
#: (``RobotSimulator(target_current="feedforward")``) 8.1 or more. White
#: noise's ratio scatters by about 1 / sqrt(2 x windows), under 0.1 from 50
#: windows on.
FEEDBACK_LIMIT = 2.0
#: How :func:`check_target_current` decides.
FEEDBACK_RULE = (
    "For each joint, r = current - target_current over the training recordings, less a "
    "least-squares constant and current-loop lag (a multiple of d target_current / dt); r is "
    "averaged over consecutive 0.1 s windows (n samples), and the ratio is the RMS of "
    "those means over the noise they would have if r were white sensor noise (sigma / "
    "sqrt(n), sigma from the median absolute second difference of r). White noise gives 1: "
    "the target already holds everything the servo commands, feedback included, and the "
    "measured current follows it within the sensor noise -- a contact too. A feed-forward "
    "target leaves the servo's feedback and the model errors in r (holding currents at "
    "rest, friction and tracking errors in motion), slow content many times the noise. A "
    "joint is judged when it moves (|qd| > 0.01 rad/s) throughout at least 20 windows; the "
    "target current follows the measured current when the ratio of a judged joint is below "
    "2. Then SP_C is not fitted and the inputs leave the target current out; the same when "
    "no joint can be judged."
)
#: How :func:`compare_models` scores the candidates (``gpcd train --model auto``).
CHOICE_RULE = (
    "Leave-one-recording-out: up to 4 training recordings (evenly spread in their order; "
    "one recording is cut into 3 contiguous pieces) are each left out in turn; every "
    "candidate is fitted on the others (every k-th row up to 5,000 rows, 200 GP support "
    "rows per joint, the optimizer asked for) and predicts the one left out (its first "
    "30,000 rows, contiguous). The residual of each left-out recording goes through gpcd "
    "calibrate's alarm rule (2 Hz low-pass, 5-sample debounce, regimes moving / settling / "
    "rest with a 5 s rest reference), and the thresholds that rule would set across the "
    "left-out recordings are computed as gpcd calibrate does: per regime and joint the "
    "largest excursion of the recordings times the leave-one-recording-out margin (the "
    "largest factor by which one recording's excursion exceeds the others'). A contact "
    "must exceed these thresholds, in A whatever the model, so the score is their "
    "geometric mean over joints, weighted by the time in each regime (the mean log "
    "threshold gpcd calibrate --select minimises); the smallest wins. Candidates within "
    "5 % of the smallest are tied, and the smallest prediction error among them wins: "
    "nMSE, the mean squared error over the left-out rows over the variance of the joint's "
    "current over the training rows, geometric mean over joints. The winner is fitted on "
    "all rows."
)
_NAMES = {"sp_p": "SP_P", "sp_s": "SP_S", "p_f": "P_f", "sp_c": "SP_C", "gp": "GP"}
_NOISE_MAD = 0.6745 * np.sqrt(6.0)  # MAD of a second difference of unit white noise


@dataclass
class TargetCurrentCheck:
    """Whether a logged target current already follows the measured current.

    From :func:`check_target_current`; see :data:`FEEDBACK_RULE`.

    Attributes
    ----------
    ratio : ndarray of shape (n_joints,)
        Slow part of ``current - target_current`` over what white noise
        would give (about 1 for a full servo command); NaN for a joint with
        too little motion to judge.
    noise : ndarray of shape (n_joints,)
        White-noise level of ``current - target_current`` [A].
    n_windows : ndarray of shape (n_joints,)
        Windows in which each joint moves throughout.
    limit : float
        Ratio below which a joint's target follows the current.

    Examples
    --------
    >>> import numpy as np
    >>> check = TargetCurrentCheck(np.array([1.0, 8.0]), np.array([0.03, 0.03]),
    ...                            np.array([50, 50]))
    >>> check.follows, check.joints, check.decided
    (True, [1], True)
    """

    ratio: np.ndarray
    noise: np.ndarray
    n_windows: np.ndarray
    limit: float = FEEDBACK_LIMIT

    @property
    def joints(self):
        """1-based joints whose target current follows the measured current."""
        return [j + 1 for j, r in enumerate(self.ratio) if r < self.limit]

    @property
    def decided(self):
        """Some joint moved enough to judge."""
        return bool(np.isfinite(self.ratio).any())

    @property
    def follows(self):
        """True when some joint's target current follows the measured current."""
        return bool(self.joints)

    @property
    def usable(self):
        """The target current may serve as a mean: decided, and follows on no joint."""
        return self.decided and not self.follows

    def text(self, sp_c_asked=False):
        """The verdict in one line.

        Parameters
        ----------
        sp_c_asked : bool, default=False
            SP_C was asked for by name (``--model sp_c``): it is fitted on the
            target current whatever the verdict, and the line says so.

        Returns
        -------
        text : str

        Examples
        --------
        >>> import numpy as np
        >>> TargetCurrentCheck(np.array([9.5, np.nan]), np.array([0.1, 0.1]),
        ...                    np.array([80, 0])).text()[:60]
        'target current: a feed-forward (slow part of i - i_target 9.'
        """
        ratios = " ".join("-" if not np.isfinite(r) else f"{r:.1f}" for r in self.ratio)
        detail = f"slow part of i - i_target {ratios} times the sensor noise"
        then = ("SP_C is fitted on it all the same (--model sp_c)" if sp_c_asked
                else "SP_C is not fitted and the inputs leave it out")
        if self.follows:
            joints = ", ".join(map(str, self.joints))
            return (f"target current: FOLLOWS the measured current on joint(s) {joints} "
                    f"({detail}, below {self.limit:g}): it includes the servo's feedback, so "
                    f"a contact would show in it too; {then}")
        if not self.decided:
            return ("target current: cannot tell whether it includes the servo's feedback "
                    f"(no joint moves for {FEEDBACK_MIN_WINDOWS} windows of "
                    f"{FEEDBACK_WINDOW:g} s); {then}")
        return (f"target current: a feed-forward ({detail}, at least {self.limit:g} where "
                "measured): a contact shows in i - i_target, the target can serve as a mean")

    def summary(self):
        """The verdict as ``target_current_check`` of a model file's training record.

        Returns
        -------
        summary : dict
            JSON-ready: ratios, noise, windows, limit and verdict.

        Examples
        --------
        >>> import numpy as np
        >>> TargetCurrentCheck(np.array([1.0]), np.array([0.03]), np.array([40])).summary()[
        ...     "follows"]
        True
        """
        return {"ratio": [None if not np.isfinite(r) else round(float(r), 3)
                          for r in self.ratio],
                "noise_A": [float(n) for n in self.noise],
                "n_windows": [int(n) for n in self.n_windows], "limit": self.limit,
                "decided": self.decided, "follows": self.follows, "joints": self.joints}


def check_target_current(recordings, *, window=FEEDBACK_WINDOW, limit=FEEDBACK_LIMIT,
                         speed=FEEDBACK_SPEED, min_windows=FEEDBACK_MIN_WINDOWS):
    """Does the logged target current follow the measured current (feedback included)?

    See :data:`FEEDBACK_RULE`. A controller that logs its full servo command
    (feed-forward plus feedback) as the target current makes the measured
    current follow it within the sensor noise, contacts included; one that
    logs a feed-forward (a UR's ``target_current``) does not.

    Parameters
    ----------
    recordings : list of Recording
        Collision-free recordings that all log ``target_current``.
    window : float, default=FEEDBACK_WINDOW
        Averaging window [s].
    limit : float, default=FEEDBACK_LIMIT
        Ratio below which a joint's target follows the current.
    speed : float, default=FEEDBACK_SPEED
        A joint moves above this speed [rad/s].
    min_windows : int, default=FEEDBACK_MIN_WINDOWS
        Windows in which a joint moves throughout that it needs to be judged.

    Returns
    -------
    check : TargetCurrentCheck

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(2000) * 0.008
    >>> q = np.sin(t)[:, None]
    >>> command = 3 * np.cos(t)[:, None]
    >>> measured = command + 0.03 * rng.normal(size=(2000, 1))   # follows it
    >>> rec = Recording(time=t, q=q, qd=np.cos(t)[:, None], current=measured,
    ...                 target_current=command)
    >>> check_target_current([rec]).follows
    True
    >>> feedback = 0.2 * np.sin(3 * t)[:, None]                   # a feed-forward
    >>> check_target_current([rec.replace(current=measured + feedback)]).follows
    False
    """
    recordings = list(recordings)
    if not recordings:
        raise ValueError("no recordings to check")
    if (lacking := next((r.name for r in recordings if r.target_current is None), None)):
        raise ValueError(f"{lacking or 'a recording'} does not log target_current")
    residual, slope, moving, sizes = [], [], [], []
    for r in recordings:
        target = np.asarray(r.target_current, float)
        residual.append(np.asarray(r.current, float) - target)
        slope.append(np.gradient(target, r.time, axis=0) if r.n_samples > 1
                     else np.zeros_like(target))
        moving.append(np.abs(np.asarray(r.qd, float)) > speed)
        sizes.append(max(2, int(round(window / np.median(np.diff(r.time)))))
                     if r.n_samples > 1 else 2)
    n_joints = residual[0].shape[1]
    ratio, noise = np.full(n_joints, np.nan), np.zeros(n_joints)
    counts = np.zeros(n_joints, int)
    for j in range(n_joints):
        second = np.concatenate([np.diff(res[:, j], 2) for res in residual])
        sigma = float(np.median(np.abs(second))) / _NOISE_MAD if second.size else 0.0
        if sigma == 0.0 and second.size:  # quantised logs: most differences are 0
            sigma = float(np.sqrt(np.mean(second ** 2) / 6.0))
        noise[j] = sigma
        blocks, counts[j] = [], 0  # (residual, slope) of each window; windows of motion
        for res, d, move, n in zip(residual, slope, moving, sizes):
            m = len(res) // n
            counts[j] += int(move[: m * n, j].reshape(m, n).all(axis=1).sum())
            blocks += [(res[k * n:(k + 1) * n, j], d[k * n:(k + 1) * n, j]) for k in range(m)]
        if counts[j] < min_windows:
            continue
        R = np.concatenate([b[0] for b in blocks])
        A = np.column_stack([np.ones(len(R)), np.concatenate([b[1] for b in blocks])])
        coef = np.linalg.lstsq(A, R, rcond=None)[0]
        scaled = [np.sqrt(len(res)) * np.mean(res - coef[0] - coef[1] * d)
                  for res, d in blocks]
        slow = float(np.sqrt(np.mean(np.square(scaled))))
        ratio[j] = slow / sigma if sigma > 0 else (0.0 if slow == 0 else np.inf)
    return TargetCurrentCheck(ratio=ratio, noise=noise, n_windows=counts, limit=float(limit))


def candidate_models(robot, signals, target_check=None):
    """The models ``--model auto`` compares, and why the others are left out.

    Parameters
    ----------
    robot : Robot or None
        The robot's rigid-body model (P_f, SP_S and SP_P need it).
    signals : tuple of str
        Controller signals of the inputs (``TrainingSet.features.signals_``);
        SP_C needs ``"target_current"``.
    target_check : TargetCurrentCheck or None, default=None
        When it finds that the target current follows the measured current,
        or cannot tell, SP_C is left out.

    Returns
    -------
    models : list of str
        In the order of :data:`~sklearn_gpcd.workflow.MODELS`.
    left_out : dict of str to str
        Model -> why it is not compared.

    Examples
    --------
    >>> candidate_models(None, ("target_current",))
    (['sp_c', 'gp'], {'sp_p': 'needs the robot model (--robot)', \
'sp_s': 'needs the robot model (--robot)', 'p_f': 'needs the robot model (--robot)'})
    """
    left_out = {}
    for model in MODELS:
        if model in ROBOT_MODELS and robot is None:
            left_out[model] = "needs the robot model (--robot)"
        elif model == "sp_c" and target_check is not None and target_check.follows:
            left_out[model] = ("the target current follows the measured current (feedback "
                               "included): a mean made of it would absorb contacts")
        elif model == "sp_c" and target_check is not None and not target_check.decided:
            left_out[model] = ("cannot tell whether the target current includes the "
                               "servo's feedback (too little motion)")
        elif model == "sp_c" and "target_current" not in tuple(signals):
            left_out[model] = "needs the target current among the inputs"
    return [m for m in MODELS if m not in left_out], left_out


@dataclass
class ModelComparison:
    """Leave-one-recording-out errors of candidate models (:func:`compare_models`).

    Attributes
    ----------
    models : list of str
        The candidates, in the order of ``errors``' rows.
    errors : ndarray of shape (n_models, n_joints)
        nMSE per joint on the left-out rows (:data:`CHOICE_RULE`).
    thresholds : ndarray of shape (n_models, n_joints)
        Per joint, the thresholds the alarm rule would set across the
        left-out recordings, geometric mean over the regimes weighted by
        their time [A, or the recordings' current unit].
    margins : ndarray of shape (n_models,)
        Leave-one-recording-out margin of those thresholds.
    seconds : list of float
        Time spent fitting and predicting each candidate, all folds.
    held_out : list of str
        What each fold left out (recording names, or pieces of one).
    n_support : int
        GP support rows per joint of the fold fits.
    left_out : dict of str to str
        Models not compared, and why.
    regimes : list of str or None
        The alarm rule's regimes on the left-out recordings (moving,
        settling and its stages, rest).
    regime_windows : list of tuple or None
        Each regime's window after the arm stops, ``(start, end)`` in s
        (``end`` inf for rest; None for moving):
        :meth:`~sklearn_gpcd.detection.AlarmRule.since_stop`.
    regime_thresholds : ndarray of shape (n_models, n_regimes, n_joints) or None
        The thresholds per regime and joint that ``thresholds`` are the
        time-weighted geometric mean of; a regime absent from every left-out
        recording holds the largest of the others (see ``regime_logs``).
    regime_seconds : ndarray of shape (n_regimes,) or None
        Time in each regime over the left-out recordings [s].
    regime_logs : ndarray of shape (n_regimes,) or None
        Left-out recordings that hold each regime: a threshold set by one
        recording alone has no left-out check.

    Examples
    --------
    >>> import numpy as np
    >>> table = ModelComparison(["sp_c", "gp"], np.array([[0.02, 0.04], [0.05, 0.06]]),
    ...                         [1.0, 2.0], ["a", "b"], 200,
    ...                         thresholds=np.array([[0.9, 1.6], [0.5, 0.8]]),
    ...                         margins=np.array([3.0, 1.2]))
    >>> table.best, table.threshold_score.round(3).tolist(), table.score.round(4).tolist()
    ('gp', [1.2, 0.632], [0.0283, 0.0548])
    """

    models: list
    errors: np.ndarray
    seconds: list
    held_out: list
    n_support: int
    left_out: dict = field(default_factory=dict)
    thresholds: np.ndarray = None
    margins: np.ndarray = None
    regimes: list = None
    regime_windows: list = None
    regime_thresholds: np.ndarray = None
    regime_seconds: np.ndarray = None
    regime_logs: np.ndarray = None

    @property
    def score(self):
        """Geometric mean of the nMSE over joints, per model."""
        return _geometric_mean(self.errors)

    @property
    def threshold_score(self):
        """Geometric mean of :attr:`thresholds` over joints, per model (None without)."""
        return None if self.thresholds is None else _geometric_mean(self.thresholds)

    @property
    def best(self):
        """The smallest :attr:`threshold_score`; the smallest nMSE among near ties.

        Candidates within :data:`CHOICE_TIE` of the smallest threshold score
        are tied (:data:`CHOICE_RULE`); without thresholds, the smallest nMSE.
        """
        score, tied = self.score, np.ones(len(self.models), bool)
        if self.thresholds is not None:
            detection = self.threshold_score
            tied = detection <= detection.min() * CHOICE_TIE
        return self.models[int(np.argmin(np.where(tied, score, np.inf)))]

    def text(self):
        """The comparison table, best first, in lines.

        Returns
        -------
        lines : list of str

        Examples
        --------
        >>> import numpy as np
        >>> table = ModelComparison(["gp"], np.array([[0.05, 0.06]]), [2.0], ["a", "b"], 200,
        ...                         thresholds=np.array([[0.4, 0.9]]), margins=np.array([1.3]))
        >>> print("\\n".join(table.text()[1:]))
          model  thresholds per joint  geo. mean  margin  nMSE (geo. mean)    time
          GP     0.400 0.900           0.600      1.30    0.0548             2.0 s  <- chosen
        """
        errors = np.asarray(self.errors, float)
        detection = self.threshold_score
        if detection is None:
            detection = np.full(len(self.models), np.nan)
            thresholds = np.full_like(errors, np.nan)
            margins = np.full(len(self.models), np.nan)
        else:
            thresholds, margins = np.asarray(self.thresholds), np.asarray(self.margins)
        width = max(len("thresholds per joint"), 6 * errors.shape[1] - 1)
        lines = [f"model choice (--model auto), leave-one-recording-out over "
                 f"{len(self.held_out)} fold(s) (left out: {', '.join(self.held_out)}), "
                 f"{self.n_support} support rows per joint; the smallest thresholds the "
                 "alarm rule would set on the left-out recordings win, nMSE breaks ties "
                 f"within {CHOICE_TIE - 1:.0%}:",
                 f"  model  {'thresholds per joint':<{width}}  geo. mean  margin  "
                 "nMSE (geo. mean)    time"]
        order = np.lexsort((self.score, np.nan_to_num(detection, nan=np.inf)))
        for k in order:
            joints = " ".join(f"{e:.3f}" for e in thresholds[k])
            lines.append(f"  {_NAMES[self.models[k]]:<5}  {joints:<{width}}  "
                         f"{detection[k]:<9.3f}  {margins[k]:<6.2f}  {self.score[k]:<16.4f}"
                         f"{self.seconds[k]:6.1f} s"
                         + ("  <- chosen" if self.models[k] == self.best else ""))
        for model, why in self.left_out.items():
            lines.append(f"  {_NAMES[model]:<5}  not compared: {why}")
        if self.regime_thresholds is not None:
            best = self.models.index(self.best)
            lines.append(f"  {_NAMES[self.best]}'s thresholds per regime on the left-out "
                         "recordings: gpcd calibrate's floors for settling and rest where 2 or "
                         "more recordings held the regime 1 s or more (for moving, the "
                         "time-weighted figure above):")
            for name, row, seconds, logs in zip(self.regimes, self.regime_thresholds[best],
                                                self.regime_seconds, self.regime_logs):
                lines.append(f"    {name:<22} " + " ".join(f"{v:.3f}" for v in row)
                             + f"  ({seconds:.1f} s in {logs} recording(s))")
        return lines

    def summary(self):
        """The table as ``model_choice`` of a model file's training record.

        Returns
        -------
        summary : dict
            JSON-ready: candidates, errors, scores, times, folds and the best.

        Examples
        --------
        >>> import numpy as np
        >>> ModelComparison(["gp"], np.array([[0.05]]), [2.0], ["a"], 200).summary()["best"]
        'gp'
        """
        detection = self.threshold_score
        return {"rule": "leave-one-recording-out thresholds of the alarm rule, geometric "
                        "mean over joints; nMSE breaks ties within "
                        f"{CHOICE_TIE - 1:.0%}",
                "best": self.best, "models": list(self.models),
                "thresholds": (None if self.thresholds is None else
                               [[float(e) for e in row] for row in self.thresholds]),
                "threshold_score": (None if detection is None
                                    else [float(v) for v in detection]),
                "margin": (None if self.margins is None
                           else [float(m) for m in self.margins]),
                "nmse": [[float(e) for e in row] for row in np.asarray(self.errors)],
                "score": [float(s) for s in self.score],
                "seconds": [float(s) for s in self.seconds], "held_out": list(self.held_out),
                "n_support": int(self.n_support), "left_out": dict(self.left_out),
                **self._regime_summary()}

    def _regime_summary(self):
        """The thresholds per regime behind :attr:`thresholds`, JSON-ready (or {})."""
        if self.regime_thresholds is None:
            return {}
        return {"regimes": list(self.regimes),
                "regime_windows": [None if w is None else
                                   [float(w[0]), None if np.isinf(w[1]) else float(w[1])]
                                   for w in self.regime_windows],
                "regime_thresholds": np.asarray(self.regime_thresholds, float).tolist(),
                "regime_seconds": [float(v) for v in self.regime_seconds],
                "regime_logs": [int(v) for v in self.regime_logs]}


def _geometric_mean(values):
    """Geometric mean over the last axis (zeros count as the tiniest float)."""
    values = np.maximum(np.asarray(values, float), np.finfo(float).tiny)
    return np.exp(np.log(values).mean(axis=-1))


def _folds(data, n_folds):
    """``[(name, test_mask)]``: recordings left out, or pieces of a single one."""
    sizes = list(data.sizes) or [len(data.y)]
    bounds = np.concatenate([[0], np.cumsum(sizes)])
    if len(sizes) >= 2:
        chosen = sorted(set(np.round(np.linspace(0, len(sizes) - 1,
                                                 min(n_folds, len(sizes)))).astype(int)))
        names = [name if data.names.count(name) == 1 else f"{name or 'recording'} {k + 1}"
                 for k, name in enumerate(data.names)]  # one fold each, named or not
        pieces = [(names[k], bounds[k], bounds[k + 1]) for k in chosen]
    else:
        cuts = np.linspace(0, len(data.y), min(n_folds, 3) + 1).round().astype(int)
        pieces = [(f"{data.names[0]} piece {p + 1}/{len(cuts) - 1}", cuts[p], cuts[p + 1])
                  for p in range(len(cuts) - 1)]
    folds = []
    for name, start, stop in pieces:
        mask = np.zeros(len(data.y), bool)
        mask[start:stop] = True
        folds.append((name, mask))
    return folds


def _subset(data, rows, name):
    """A :class:`TrainingSet` of ``data``'s ``rows`` (same features)."""
    return TrainingSet(X=data.X[rows], y=data.y[rows], features=data.features,
                       inputs=data.inputs, names=[name], n_rows=int(len(rows)), step=1,
                       has_target_current=data.has_target_current, sizes=(int(len(rows)),),
                       sample_time=data.sample_time)


def _alarm_template(data, sigma_v):
    """The detector of ``gpcd calibrate``'s default alarm rule, without a regressor yet."""
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..detection import AlarmRule, CollisionDetector, Regimes
    from .calibration import DEFAULT_REST_REFERENCE, DETECTOR_RULE

    rule = AlarmRule(**DETECTOR_RULE, regimes=Regimes(rest_reference=DEFAULT_REST_REFERENCE))
    extra = {} if sigma_v is None else {"sigma_v": sigma_v}
    return CollisionDetector(None, n_joints=data.y.shape[1],
                             sample_time=data.sample_time or 1.0, rules=rule, **extra)


def _excursions(template, regressor, X, y):
    """Peaks per (regime, joint) of the debounced residual, samples per regime, and
    the regimes' names and windows after the stop."""
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from sklearn.base import clone
    from sklearn.frozen import FrozenEstimator

    # deferred, as above
    from ..detection import regime_excursions, stack_currents

    block = stack_currents(X, y)
    detector = clone(template).set_params(regressor=FrozenEstimator(regressor)).fit(block)
    _, regime, peaks = regime_excursions(detector, {"fold": block})["fold"]
    rule = detector.rules_[0]
    return (peaks, np.bincount(regime, minlength=peaks.shape[0]),
            (list(rule.regime_names_), rule.since_stop()))


def _fold_thresholds(peaks, counts):
    """Thresholds per joint (geometric mean over regimes weighted by time), margin,
    and the thresholds per (regime, joint) they are the mean of.

    .. math::

        T_{g\\ell} = \\mu\\, L_{g\\ell}, \\qquad
        T_\\ell = \\exp \\sum_g \\frac{n_g}{n} \\log T_{g\\ell}

    with :math:`L` the largest peak of the left-out recordings per regime and
    joint and :math:`\\mu` their leave-one-recording-out margin
    (:func:`~sklearn_gpcd.detection.loro_margin`), as ``gpcd calibrate``.
    """
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..detection import loro_margin, regime_levels

    keys = list(peaks)
    margin = loro_margin(peaks, keys)
    thresholds = np.maximum(margin * regime_levels(peaks, keys), np.finfo(float).tiny)
    weights = np.asarray(sum(counts.values()), float)
    weights /= weights.sum()
    return np.exp(weights @ np.log(thresholds)), float(margin.max()), thresholds


def compare_models(data, robot=None, models=None, *, n_folds=4, n_support=FOLD_SUPPORT,
                   max_rows=FOLD_ROWS, optimizer="auto", sigma_v=None, seed=0, n_jobs=None,
                   coulomb_width=None, progress=None):
    """Leave-one-recording-out thresholds and error of candidate models (:data:`CHOICE_RULE`).

    Parameters
    ----------
    data : TrainingSet
        Inputs of the training recordings (:func:`~sklearn_gpcd.workflow.training_set`).
    robot : Robot or None, default=None
        For P_f, SP_S and SP_P.
    models : list of str or None, default=None
        Candidates; None: :func:`candidate_models` of ``robot`` and the
        inputs' signals.
    n_folds : int, default=4
        Recordings left out at most (pieces when there is one recording).
    n_support : int, default=FOLD_SUPPORT
        GP support rows per joint of each fit.
    max_rows : int, default=FOLD_ROWS
        Training rows of each fit at most (every k-th row).
    optimizer : {"auto", "adam", "fmin_l_bfgs_b"}, default="auto"
        Of each fit.
    sigma_v : float or None, default=None
        Of each fit (:func:`~sklearn_gpcd.workflow.train_model`) and of the
        alarm rule's regimes.
    seed : int, default=0
        Of each fit.
    n_jobs : int or None, default=None
        Joints fitted in parallel.
    coulomb_width : float or None, default=None
        Coulomb column of P_f, SP_S and SP_P (:func:`~sklearn_gpcd.workflow.train_model`).
    progress : callable or None, default=None
        ``progress(label, total)`` returning an object with ``update()``:
        one step per fit.

    Returns
    -------
    comparison : ModelComparison

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> from sklearn_gpcd.workflow import training_set
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(300) * 0.01
    >>> runs = []
    >>> for k in range(3):
    ...     q = np.sin(t + k)[:, None]
    ...     runs.append(Recording(time=t, q=q, qd=np.cos(t + k)[:, None],
    ...                           current=2 * q + 0.01 * rng.normal(size=q.shape),
    ...                           target_current=2 * q, name=f"run{k}"))
    >>> table = compare_models(training_set(runs), n_support=50)
    >>> table.models, table.best, table.held_out
    (['sp_c', 'gp'], 'sp_c', ['run0', 'run1', 'run2'])
    >>> table.thresholds.shape, bool(table.margins.min() >= 1)
    ((2, 1), True)
    """
    left_out = {}
    if models is None:
        models, left_out = candidate_models(robot, data.features.signals_)
    models = list(models)
    if not models:
        raise ValueError("no candidate model to compare")
    var = np.var(data.y, axis=0)
    var[var == 0] = 1.0
    folds = _folds(data, n_folds)
    template = _alarm_template(data, sigma_v)
    sse = np.zeros((len(models), data.y.shape[1]))
    peaks = [{} for _ in models]
    counts = [{} for _ in models]
    regimes = None
    seconds = [0.0] * len(models)
    n_test = 0
    bar = progress("comparing models (leave one recording out)",
                   len(models) * len(folds)) if progress is not None else None
    for name, test in folds:
        train_rows = np.flatnonzero(~test)
        train_rows = train_rows[::max(1, -(-len(train_rows) // max_rows))]
        fold = _subset(data, train_rows, f"all but {name}")
        test_rows = np.flatnonzero(test)[:FOLD_TEST_ROWS]  # contiguous: filtered in time
        X_test, y_test = data.X[test_rows], data.y[test_rows]
        n_test += len(y_test)
        for k, model in enumerate(models):
            tic = time.perf_counter()
            fitted = train_model(
                fold, robot, model, n_support=min(n_support, len(train_rows)),
                optimizer=optimizer, sigma_v=sigma_v, seed=seed, n_jobs=n_jobs,
                coulomb_width=coulomb_width if model in ROBOT_MODELS else None)
            predicted = np.reshape(fitted.regressor.predict(X_test), y_test.shape)
            sse[k] += ((predicted - y_test) ** 2).sum(axis=0)
            peaks[k][name], counts[k][name], regimes = _excursions(
                template, fitted.regressor, X_test, y_test)
            seconds[k] += time.perf_counter() - tic
            if bar is not None:
                bar.update()
    comparison = ModelComparison(models=models, errors=sse / n_test / var, seconds=seconds,
                                 held_out=[name for name, _ in folds],
                                 n_support=int(n_support), left_out=left_out)
    if len(folds) >= 2:
        triples = [_fold_thresholds(p, c) for p, c in zip(peaks, counts)]
        samples = np.array(list(counts[0].values()))  # the regimes follow q: same per model
        comparison.thresholds = np.array([t for t, _, _ in triples])
        comparison.margins = np.array([m for _, m, _ in triples])
        comparison.regimes, comparison.regime_windows = regimes
        comparison.regime_thresholds = np.array([table for _, _, table in triples])
        comparison.regime_seconds = samples.sum(axis=0) * (data.sample_time or np.nan)
        comparison.regime_logs = (samples > 0).sum(axis=0)
    return comparison


def input_signals(recordings, signals="auto", model="auto"):
    """The controller signals of a model's inputs, and the target-current check.

    The check (:func:`check_target_current`) runs whenever the inputs would
    use the target current; with ``signals="auto"`` a target that fails it
    leaves the inputs unless ``model`` is ``"sp_c"`` (a list is taken as
    given). P_f and SP_S use no controller signal.

    Parameters
    ----------
    recordings : list of Recording
    signals : "auto", "none" or tuple of str, default="auto"
        ``"auto"``: each of :data:`SIGNALS` that every recording logs.
    model : str, default="auto"
        The model asked for (``gpcd train --model``).

    Returns
    -------
    signals : tuple of str
    check : TargetCurrentCheck or None
        None when the inputs do not use a logged target current.

    Raises
    ------
    ValueError
        For ``model="sp_c"`` without the target current (asked or logged).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> t = np.arange(100) * 0.01
    >>> rec = Recording(time=t, q=t[:, None], qd=np.ones((100, 1)), current=t[:, None],
    ...                 target_q=t[:, None])
    >>> input_signals([rec]), input_signals([rec], model="p_f")
    ((('target_q',), None), ((), None))
    """
    if model == "sp_c":
        if signals == "none" or (signals != "auto" and "target_current" not in signals):
            raise ValueError("--model sp_c needs the target current among the inputs; drop "
                             "--signals or include target_current in it")
        if (lacking := [r.name for r in recordings if r.target_current is None]):
            raise ValueError(f"model sp_c needs the target current; {', '.join(lacking)} "
                             f"do{'es' * (len(lacking) == 1)} not log it: leave "
                             f"{'it' if len(lacking) == 1 else 'them'} out, or use --model "
                             "auto (or gp)")
    if signals == "none" or model in ("p_f", "sp_s"):
        return (), None
    logged = tuple(s for s in SIGNALS if all(getattr(r, s) is not None for r in recordings))
    auto, signals = signals == "auto", logged if signals == "auto" else tuple(signals)
    if "target_current" not in signals or "target_current" not in logged:
        return signals, None
    check = check_target_current(recordings)
    if not check.usable and model != "sp_c" and auto:
        signals = tuple(s for s in signals if s != "target_current")
    return signals, check


def choose_model(data, robot=None, target_check=None, *, signals="auto", n_support="auto",
                 **fit):
    """``gpcd train --model auto``: the one model the data allow, or the best compared.

    The candidates are :func:`candidate_models`; with several, each is scored
    by :func:`compare_models` (:data:`CHOICE_RULE`) with at most
    :data:`FOLD_SUPPORT` support rows per joint.

    Parameters
    ----------
    data : TrainingSet
    robot : Robot or None, default=None
    target_check : TargetCurrentCheck or None, default=None
    signals : "auto", "none" or tuple of str, default="auto"
        The signals asked for (says why SP_C is left out).
    n_support : int or "auto", default="auto"
        Support rows of the model to be trained (bounds the folds').
    **fit
        ``optimizer``, ``sigma_v``, ``seed``, ``n_jobs``, ``coulomb_width``,
        ``progress`` of :func:`compare_models`.

    Returns
    -------
    model : str
    comparison : ModelComparison or None
        None when one model only is possible.
    note : str or None
        Why, in that case.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> from sklearn_gpcd.workflow import training_set
    >>> t = np.arange(200) * 0.01
    >>> rec = Recording(time=t, q=np.sin(t)[:, None], qd=np.cos(t)[:, None],
    ...                 current=np.sin(t)[:, None])
    >>> choose_model(training_set([rec], signals=()))[::2]
    ('gp', 'model choice (--model auto): GP, the only model these recordings allow; \
SP_P needs the robot model (--robot); SP_S needs the robot model (--robot); \
P_F needs the robot model (--robot); SP_C the recordings do not all log the target current')
    """
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..gp import resolve_n_support

    models, left_out = candidate_models(robot, data.features.signals_, target_check)
    if signals == "none":
        left_out["sp_c"] = "--signals none: the inputs have no target current"
    elif "sp_c" in left_out and not data.has_target_current:
        left_out["sp_c"] = "the recordings do not all log the target current"
    if len(models) == 1:
        return models[0], None, (
            f"model choice (--model auto): {models[0].upper()}, the only model these "
            "recordings allow; " + "; ".join(f"{m.upper()} {why}" for m, why in left_out.items()))
    fold_support = min(FOLD_SUPPORT, resolve_n_support(n_support, len(data.y)))
    comparison = compare_models(data, robot, models, n_support=fold_support, **fit)
    comparison.left_out = left_out
    return comparison.best, comparison, None
