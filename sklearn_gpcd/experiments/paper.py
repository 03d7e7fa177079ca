"""The paper's experiments end to end on the built-in simulator (Sec. III-C, V).

:func:`reproduce` is what ``gpcd reproduce`` runs:

1. simulate D1, D2, the joint-1 cyclic test and the interaction test
   (:mod:`sklearn_gpcd.datasets`);
2. build the inputs ``x^a`` (Eq. 13) and train P_f, SP_S and SP_P on D1
   (hyperparameters by marginal likelihood, posterior on the support subset
   D_SDP);
3. evaluate the nMSE (Eq. 18) per joint on D1_test (D1 minus D_SDP) and D2,
   split into dynamic (``|qd_l| >= sigma_v``) and quasi-static samples;
4. monitoring signals on the cyclic test (s_SP_S vs s_SP_P, Fig. 2) and the
   collision detector on the interaction test (Fig. 3);
5. ``report.md``, figures and ``results.json`` (:mod:`.report`).
"""

import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from .. import datasets
from .._gate import DEFAULT_SIGMA_V, quasi_static
from ..layout import block_columns
from sklearn.frozen import FrozenEstimator

from ..detection import AlarmRule, CollisionDetector, stack_currents
from ..dynamics import RigidBodyFeatures
from ..features import CausalFeatures, contiguous_segments, make_inputs
from ..gp import make_p_f, make_sp_p, make_sp_s
from ..metrics import alarm_onsets, nmse
from ..robots import resolve_robot
from .report import ESTIMATORS, write_report


@dataclass(frozen=True)
class PaperConfig:
    """Sizes of one ``reproduce`` run.

    Parameters
    ----------
    d1_targets, d2_targets : int
        Random targets of D1 (paper: 200, ~80,000 samples) and D2 (paper: 50
        plus the circle, ~22,000 samples).
    n_support : int
        Size of D_SDP, the posterior's support subset (paper: 5,000).
    batch_size : int
        Rows per minibatch of the Adam optimiser of the marginal likelihood
        (the paper: "stochastic gradient descent ... ADAM", Sec. V-A).
    rest_duration : float
        Seconds of rest after the circle in the interaction test.
    sigma_v : float
        Quasi-static velocity threshold (paper: 1e-2 rad/s).

    Examples
    --------
    >>> from sklearn_gpcd.experiments import PaperConfig
    >>> PaperConfig.quick().n_support
    1000
    """

    d1_targets: int = 200
    d2_targets: int = 50
    n_support: int = 5000
    batch_size: int = 512
    rest_duration: float = 30.0
    sigma_v: float = DEFAULT_SIGMA_V

    @classmethod
    def quick(cls):
        """Small sizes for a run of a few minutes."""
        return cls(d1_targets=30, d2_targets=10, n_support=1000, batch_size=256,
                   rest_duration=20.0)

    @classmethod
    def full(cls):
        """The paper's sizes."""
        return cls()


class Progress:
    """Timestamped progress lines on stdout (silent when ``verbose`` is False)."""

    def __init__(self, verbose=True):
        self.verbose = verbose
        self.start = time.perf_counter()

    def __call__(self, message):
        if self.verbose:
            print(f"[{time.perf_counter() - self.start:7.1f}s] {message}", flush=True)

    @property
    def elapsed(self):
        return time.perf_counter() - self.start


def simulate_datasets(robot, config, random_state, progress):
    """Simulate the four recordings of the paper's experiments.

    Returns
    -------
    recordings : dict of str -> Recording
        Keys ``"d1"``, ``"d2"``, ``"cyclic"``, ``"interaction"``.
    """
    rng = np.random.RandomState(random_state)
    seeds = rng.randint(0, 2**31 - 1, size=4)
    makers = {
        "d1": lambda s: datasets.simulate_d1(robot, n_targets=config.d1_targets, random_state=s),
        "d2": lambda s: datasets.simulate_d2(robot, n_targets=config.d2_targets, random_state=s),
        "cyclic": lambda s: datasets.simulate_joint1_cyclic(robot, random_state=s),
        "interaction": lambda s: datasets.simulate_interaction_test(
            robot, rest_duration=config.rest_duration, random_state=s),
    }
    recordings = {}
    for (key, make), seed in zip(makers.items(), seeds):
        tic = time.perf_counter()
        recordings[key] = make(int(seed))
        rec = recordings[key]
        progress(f"simulated {key}: {rec.n_samples} samples, {rec.duration:.0f} s of robot "
                 f"time in {time.perf_counter() - tic:.1f} s")
    return recordings


def build_estimators(robot, config, random_state, n_jobs):
    """P_f, SP_S and SP_P for ``robot`` (Sec. V), sharing one D_SDP rule."""
    n = robot.n_joints
    features = [RigidBodyFeatures(robot, joint=j) for j in range(n)]
    gp = dict(n_support=config.n_support, optimizer="adam", batch_size=config.batch_size,
              random_state=random_state, n_jobs=n_jobs)
    return {
        "P_f": make_p_f(features, n, **gp),
        "SP_S": make_sp_s(features, n, **gp),
        "SP_P": make_sp_p(features, n, sigma_v=config.sigma_v, **gp),
    }


def split_nmse(y, y_pred, qd, sigma_v, rows=None):
    """nMSE (Eq. 18) per joint, split into dynamic and quasi-static samples.

    Each split is normalised by the variance of the measured current over
    that split's own samples, i.e. Eq. 18 applied with ``X_*`` the split.

    Parameters
    ----------
    y, y_pred, qd : ndarray of shape (n_samples, n_joints)
    sigma_v : float
    rows : ndarray of shape (n_samples, n_joints) of bool, default=None
        Extra per-joint row mask (e.g. D1 minus each joint's D_SDP).

    Returns
    -------
    result : dict
        ``{"dynamic": [...], "quasi_static": [...], "n_dynamic": [...],
        "n_quasi_static": [...]}``, one value per joint (NaN where a split
        has fewer than 10 samples).

    Examples
    --------
    >>> import numpy as np
    >>> y = np.random.RandomState(0).normal(size=(100, 1))
    >>> qd = np.r_[np.zeros(50), np.ones(50)][:, None]
    >>> split_nmse(y, y, qd, 1e-2)["dynamic"]
    [0.0]
    """
    rows = np.ones(y.shape, dtype=bool) if rows is None else rows
    out = {"dynamic": [], "quasi_static": [], "n_dynamic": [], "n_quasi_static": []}
    for j in range(y.shape[1]):
        still = quasi_static(qd[:, j], sigma_v)
        for name, mask in (("dynamic", ~still & rows[:, j]), ("quasi_static", still & rows[:, j])):
            out[f"n_{name}"].append(int(mask.sum()))
            value = nmse(y[mask, j], y_pred[mask, j]) if mask.sum() >= 10 else np.nan
            out[name].append(float(value))
    return out


def _held_out_rows(model, n_samples, n_joints):
    """Per-joint mask of D1 rows outside that joint's D_SDP (the paper's D1_test)."""
    rows = np.ones((n_samples, n_joints), dtype=bool)
    support = model.support_indices_
    support = support if isinstance(support, list) else [support] * n_joints
    for j, idx in enumerate(support):
        rows[idx, j] = False
    return rows


def _qd(X, n_joints):
    return X[:, block_columns("qd", n_joints)]


def cyclic_signals(models, X, y):
    """Monitoring signals s = i - i_hat of SP_S and SP_P on the cyclic test."""
    return {name: y - models[name].predict(X) for name in ("SP_S", "SP_P")}


def rest_phase_stats(recording, signal, joint=0, sigma_v=DEFAULT_SIGMA_V, min_samples=25):
    """Mean |s| of ``joint`` in each rest phase (all joints below ``sigma_v``)."""
    n = recording.n_joints
    still = np.all(quasi_static(recording.qd, sigma_v), axis=1)
    phases = [(a, b) for a, b in contiguous_segments(still) if b - a >= min_samples]
    return [
        {"start_s": float(recording.time[a] - recording.time[0]),
         "stop_s": float(recording.time[b - 1] - recording.time[0]),
         "q1": float(np.mean(recording.q[a:b, joint])),
         "mean_abs_s": float(np.mean(np.abs(signal[a:b, joint])))}
        for a, b in phases
    ] if n else []


#: How ``reproduce`` computes every detection figure (written to the report).
DETECTION_PATH = ("causal path: CausalFeatures inputs (backward-difference acceleration, "
                  "5 Hz first-order low-pass), causal 2 Hz residual filter, no look-ahead")


def make_detector(model, n_joints):
    """The collision detector of the interaction test, around a fitted SP_P.

    Thresholds come from a collision-free recording the model was not
    trained on (the experiments use D2): the fraction ``contamination`` of D1 samples would be flagged, the
    residual is low-pass filtered at 2 Hz (the moving-phase residual is
    high-frequency, Sec. V-B) and a joint must stay out of its band for 5
    samples (40 ms at 125 Hz) before it fires.
    """
    rule = AlarmRule("contamination", contamination=1e-3, filter_cutoff=2.0, min_duration=5)
    return CollisionDetector(FrozenEstimator(model), n_joints=n_joints, sample_time=1 / 125,
                             rules=rule)


def _commanded_rest(recording, sigma_v):
    """Samples where the robot is told to stand still (all joints).

    Uses the reference velocity when logged: a push at rest makes a joint
    slip a little, yet the robot is still "at rest" in the experiment's sense.
    """
    qd = recording.target_qd if recording.target_qd is not None else recording.qd
    return np.all(quasi_static(qd, sigma_v), axis=1)


def interaction_outcome(detector, X, y, recording, sigma_v):
    """Detection outcome on the labelled interaction test.

    Returns
    -------
    outcome : dict
        Per push (label k > 0): detected or not and the delay of the first
        alarm after onset; false alarms in the moving part and in the
        collision-free rest phases, where "rest" is the commanded rest
        (``target_qd`` below ``sigma_v`` on all joints); also the number of
        alarm samples outside pushes.

    Notes
    -----
    A false alarm is an alarm *onset* (an alarm sample whose predecessor has
    none) on a collision-free sample, as in
    :func:`~sklearn_gpcd.metrics.false_alarms_per_hour`. An alarm that
    starts in a push and outlasts its label (the 2 Hz residual filter
    decays after the contact ends) is that push's detection, not a false
    alarm; its samples after the push count in ``false_alarm_samples_*``.
    """
    alarms = detector.predict(stack_currents(X, y)) == -1
    commanded_rest = _commanded_rest(recording, sigma_v)
    labels = recording.labels
    t = recording.time - recording.time[0]
    pushes = []
    for k in sorted(set(labels[labels > 0].tolist())):
        idx = np.flatnonzero(labels == k)
        hit = idx[alarms[idx]]
        moving = bool(np.any(~commanded_rest[idx]))
        pushes.append({
            "event": int(k),
            "start_s": float(t[idx[0]]), "stop_s": float(t[idx[-1]]),
            "while_moving": moving,
            "detected": bool(hit.size),
            "delay_s": float(t[hit[0]] - t[idx[0]]) if hit.size else None,
        })
    free = labels == 0
    onsets = [a for a in alarm_onsets(alarms) if free[a]]
    return {
        "pushes": pushes,
        "all_pushes_detected": all(p["detected"] for p in pushes),
        "false_alarms_moving": sum(1 for a in onsets if not commanded_rest[a]),
        "false_alarms_rest": sum(1 for a in onsets if commanded_rest[a]),
        "false_alarm_samples_rest": int(np.sum(alarms & free & commanded_rest)),
        "false_alarm_samples_moving": int(np.sum(alarms & free & ~commanded_rest)),
        "alarm": alarms,
    }


def reproduce(output_dir, quick=False, robot="ur10", random_state=0, n_jobs=None,
              verbose=True, config=None):
    """Run the paper's experiments on the simulator and write the report.

    Parameters
    ----------
    output_dir : str or Path
        Folder for ``report.md``, the figures and ``results.json``.
    quick : bool, default=False
        Use :meth:`PaperConfig.quick` sizes instead of the paper's.
    robot : str or Robot, default="ur10"
        Built-in name, URDF path or Robot.
    random_state : int, default=0
    n_jobs : int or None, default=None
        Joints fitted in parallel.
    verbose : bool, default=True
        Print progress.
    config : PaperConfig, default=None
        Explicit sizes (overrides ``quick``).

    Returns
    -------
    results : dict
        Everything written to ``results.json``.

    Examples
    --------
    A run takes minutes (``quick=True``) to hours, so it is not executed
    here; ``config`` sets the sizes:

    >>> from sklearn_gpcd.experiments import PaperConfig, reproduce
    >>> config = PaperConfig.quick()
    >>> config.d1_targets, config.n_support
    (30, 1000)
    >>> results = reproduce("gpcd-results", config=config)  # doctest: +SKIP
    >>> sorted(results)[:3]  # doctest: +SKIP
    ['checks', 'config', 'cyclic_rest_phases']
    """
    progress = Progress(verbose)
    config = config or (PaperConfig.quick() if quick else PaperConfig.full())
    robot = resolve_robot(robot)
    out = Path(output_dir)
    out.mkdir(parents=True, exist_ok=True)
    progress(f"gpcd reproduce: robot {robot.name}, {'quick' if quick else 'full'} sizes "
             f"{asdict(config)}")

    recs = simulate_datasets(robot, config, random_state, progress)
    data = {key: make_inputs(rec, augmented=True) for key, rec in recs.items()}
    n = robot.n_joints
    X1, y1 = data["d1"]

    models = build_estimators(robot, config, random_state, n_jobs)
    fit_seconds = {}
    for name, model in models.items():
        tic = time.perf_counter()
        progress(f"training {name} on D1 ({len(y1)} samples, D_SDP {config.n_support})")
        model.fit(X1, y1)
        fit_seconds[name] = time.perf_counter() - tic
        progress(f"trained {name} in {fit_seconds[name]:.1f} s")

    held_out = _held_out_rows(models["SP_P"], len(y1), n)
    nmse_table = {}
    for name, model in models.items():
        nmse_table[name] = {
            "D1_test": split_nmse(y1, model.predict(X1), _qd(X1, n), config.sigma_v, held_out),
            "D2": split_nmse(data["d2"][1], model.predict(data["d2"][0]),
                             _qd(data["d2"][0], n), config.sigma_v),
        }
        progress(f"nMSE {name}: D2 quasi-static "
                 + " ".join(f"{v:.3f}" for v in nmse_table[name]["D2"]["quasi_static"]))

    Xc, yc = data["cyclic"]
    s_cyclic = cyclic_signals(models, Xc, yc)
    cyclic = {name: rest_phase_stats(recs["cyclic"], s, sigma_v=config.sigma_v)
              for name, s in s_cyclic.items()}

    progress(f"calibrating the collision detector on the collision-free D2 residuals (SP_P), "
             f"{DETECTION_PATH}")
    causal = CausalFeatures().fit(recs["d1"])
    detector = make_detector(models["SP_P"], n).fit(
        stack_currents(causal.transform(recs["d2"]), recs["d2"].current))
    Xi, yi = causal.transform(recs["interaction"]), recs["interaction"].current
    data["interaction"] = (Xi, yi)  # the figures show what the robot would see
    outcome = interaction_outcome(detector, Xi, yi, recs["interaction"], config.sigma_v)
    progress(f"interaction test: {sum(p['detected'] for p in outcome['pushes'])}/"
             f"{len(outcome['pushes'])} pushes detected, false alarms at rest "
             f"{outcome['false_alarms_rest']}, while moving {outcome['false_alarms_moving']}")

    results = {
        "robot": robot.name,
        "mode": "quick" if quick else "full",
        "config": asdict(config),
        "random_state": random_state,
        "n_samples": {key: int(rec.n_samples) for key, rec in recs.items()},
        "fit_seconds": fit_seconds,
        "log_marginal_likelihood": {
            name: np.atleast_1d(m.log_marginal_likelihood_value_).tolist()
            for name, m in models.items()},
        "nmse": nmse_table,
        "cyclic_rest_phases": cyclic,
        "detector": {"thresholds": np.asarray(detector.thresholds_).tolist(),
                     "path": DETECTION_PATH},
        "interaction": {k: v for k, v in outcome.items() if k != "alarm"},
    }
    results["checks"] = acceptance_checks(results)
    figures = write_report(out, results, recs, data, models, detector, s_cyclic, outcome)
    results["figures"] = figures
    results["elapsed_s"] = progress.elapsed
    with open(out / "results.json", "w") as fh:
        json.dump(_jsonable(results), fh, indent=2)
    progress(f"wrote {out / 'report.md'} and {out / 'results.json'}")
    return results


def acceptance_checks(results):
    """The paper's claims, checked on this run's numbers.

    Returns
    -------
    checks : dict of str -> bool
        ``sp_p_quasi_static_best_majority``: SP_P's quasi-static nMSE on D2
        is below both SP_S's and P_f's for a majority of joints;
        ``all_pushes_detected``; ``no_false_alarm_at_rest``.
    """
    d2 = {name: np.asarray(results["nmse"][name]["D2"]["quasi_static"]) for name in ESTIMATORS}
    valid = ~np.isnan(d2["SP_P"])
    better = (d2["SP_P"] < d2["SP_S"]) & (d2["SP_P"] < d2["P_f"]) & valid
    inter = results["interaction"]
    return {
        "sp_p_quasi_static_best_joints": np.flatnonzero(better).tolist(),
        "sp_p_quasi_static_best_majority": bool(better.sum() > valid.sum() / 2),
        "all_pushes_detected": bool(inter["all_pushes_detected"]),
        "no_false_alarm_at_rest": inter.get("false_alarm_samples_rest", 0) == 0
        and inter["false_alarms_rest"] == 0,
    }


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        return None if not np.isfinite(obj) else float(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj
