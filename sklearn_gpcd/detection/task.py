"""Teach a task: the residual a global model leaves in one task's own states.

A cobot repeats its program. The global model (the paper's Eq. 17, trained
once per robot) leaves a residual ``s = i - i_hat`` that is not noise but a
function of where the task goes: unmodelled friction at the task's speeds,
payload, cable forces. :class:`TaughtTask` learns that function from a few
collision-free cycles of the task and monitors what is left:

.. math:: e_l(t) = s_l(t) - r_l(\\phi(x_t)),\\qquad
          \\phi(x) = [q,\\ \\sin q,\\ \\cos q,\\ \\dot q,\\
          \\tanh(\\dot q / w_1), \\dots, \\tanh(\\dot q / w_6),\\ \\ddot q]

``r`` is a ridge regression on the standardised features ``phi`` (it
extrapolates in speed, which nearest neighbours on ``[q, qd]`` do not: the
task's collision runs go a little slower than its teaching run). ``e`` is
low-pass filtered (``cutoff``, ``order``) and debounced (``min_duration``)
as the detector's bands are.

**Thresholds without multiplying comparisons.** The taught cycles are the
exchangeable units. Each cycle ``c`` is predicted by the reference fitted on
the other cycles (cross-fitting), so its residual ``e^{(-c)}`` is an honest
sample of the taught monitor's error. Per joint, ``scale_l`` is the largest
debounced ``|m_l|`` over the cycles; a cycle's score is
``max_{t, l} |m_l(t)| / scale^{(-c)}_l`` with the scale taken from the *other*
cycles, and the one level ``level_`` is the largest score. With ``n`` cycles
a new cycle of the same task exceeds it with probability of about
``1 / (n + 1)`` (split-conformal, one comparison per cycle whatever the
number of joints or states). That is a weak promise for a few cycles (a
2-minute log of a 30-s task: 1/5 per cycle), so the level is at least the
Gumbel quantile of the cycle scores at ``false_alarm_rate`` per hour
(:func:`tail_level`): cycle scores are maxima, and the law of maxima
extrapolates where four cycles cannot count.

**Where it protects.** Far from every taught state (``novelty > 1``: the
nearest taught ``[q / 0.1 rad, qd / 0.5 rad/s]`` is more than
``novelty_radius`` away) the reference is not trusted: the general
detector's decision stands there, and the monitor says the motion is
untaught.

**Keep learning, safely.** :meth:`TaughtTask.partial_fit` learns from
monitored logs a slow drift of the whole robot (warm-up changes friction):
per joint ``d_l(x) = a_l + b_l tanh(qd_l / DRIFT_WIDTH)``, subtracted with
the reference. Only whole cycles teach it: no alarm or event in them or in the cycles
beside them, and below ``LEARN_BELOW`` of the thresholds once their own
drift is taken away; each accepted cycle moves ``(a, b)`` by ``LEARN_RATE``
of the way to its own least-squares fit (at most ``LEARN_STEP`` of the
threshold per cycle), and ``|a_l| + |b_l|`` never exceeds ``LEARN_LIMIT``
of the joint's threshold. The thresholds are never raised.
A contact that grows slowly is learned at most by that bound: it is caught
when it exceeds ``(1 + LEARN_LIMIT)`` times the threshold, at worst.
"""

from numbers import Integral, Real

import numpy as np
from scipy.signal import lfilter_zi
from scipy.spatial import cKDTree
from sklearn.base import BaseEstimator, _fit_context
from sklearn.linear_model import Ridge
from sklearn.utils import Bunch
from sklearn.utils._param_validation import HasMethods, Interval
from sklearn.utils.validation import check_is_fitted

from .._gate import DEFAULT_SIGMA_V
from ..layout import block_columns
from ._regimes import EVENT_HOLD_S, MOVING, EventHold, event_rows, ratio_over_level
from ._signal import filter_segments, lowpass_coefficients, segment_starts, window_segments

__all__ = ["EventHold", "TaughtTask", "TaskStream", "drift_features", "local_states",
           "tail_level", "task_features", "task_period"]

#: Widths [rad/s] of the smooth Coulomb columns of the task features: a
#: basis over the velocity scales of friction near a reversal (chosen by the
#: cross-fitted variance it explains on the teaching log, docs: results).
COULOMB_WIDTHS = (0.005, 0.01, 0.02, 0.05, 0.1, 0.2)
#: Scales [rad, rad/s, rad/s^2] of the local correction's distance.
LOCAL_SCALE = (0.05, 0.05, 0.5)
#: Taught states the local correction averages over.
LOCAL_NEIGHBOURS = 10
#: Seconds of motion after a start from rest before the taught thresholds
#: apply: the breakaway from static friction is history, not state.
BREAKAWAY_S = 0.25
#: Taught states kept for the novelty search (every k-th row beyond this).
MAX_TAUGHT_STATES = 20_000
#: A monitored cycle teaches the drift only if, once its own drift fit is
#: taken away, its largest taught ratio (signal over threshold) is at most this.
LEARN_BELOW = 0.8
#: Bound of the learned drift ``|a_l| + |b_l|``, as a share of each joint's
#: threshold: what learning may take in of a slowly growing contact.
LEARN_LIMIT = 0.5
#: Share of the way to an accepted cycle's own fit that the drift moves.
LEARN_RATE = 0.5
#: Largest change of the drift per accepted cycle, ``sum |step|``, as a share
#: of each joint's threshold: warm-up is slow, a contact is not.
LEARN_STEP = 0.1
#: Velocity width [rad/s] of the drift's friction column.
DRIFT_WIDTH = 0.05
#: Share of a cycle's rows that must be taught for it to teach the drift.
LEARN_TAUGHT_SHARE = 0.5


def task_features(X, n_joints):
    """The task reference's features ``phi(x)`` of the regressor inputs.

    Parameters
    ----------
    X : ndarray of shape (n_samples, n_inputs)
        Regressor inputs in the paper's layout (``q, qd, qdd`` blocks first,
        :mod:`sklearn_gpcd.layout`).
    n_joints : int

    Returns
    -------
    phi : ndarray of shape (n_samples, (5 + len(COULOMB_WIDTHS)) * n_joints)
        ``[q, sin q, cos q, qd, tanh(qd / w) for w in COULOMB_WIDTHS, qdd]``.

    Examples
    --------
    >>> import numpy as np
    >>> task_features(np.zeros((4, 3)), 1).shape
    (4, 11)
    """
    q, qd, qdd = (X[:, block_columns(b, n_joints)] for b in ("q", "qd", "qdd"))
    return np.hstack([q, np.sin(q), np.cos(q), qd,
                      *(np.tanh(qd / w) for w in COULOMB_WIDTHS), qdd])


def local_states(X, n_joints):
    """Where the local correction looks: ``[q / 0.05 rad, qd / 0.05 rad/s, qdd / 0.5 rad/s^2]``.

    Parameters
    ----------
    X : ndarray of shape (n_samples, n_inputs)
        Regressor inputs in the paper's layout.
    n_joints : int

    Returns
    -------
    z : ndarray of shape (n_samples, 3 * n_joints)

    Examples
    --------
    >>> import numpy as np
    >>> local_states(np.ones((2, 3)), 1).tolist()
    [[20.0, 20.0, 2.0], [20.0, 20.0, 2.0]]
    """
    return np.hstack([X[:, block_columns(b, n_joints)] / s for b, s in zip(
        ("q", "qd", "qdd"), LOCAL_SCALE)])


def task_period(q, sample_time, min_period=1.0):
    """Period of a repeated motion from the autocorrelation of ``q``.

    The first peak of the autocorrelation of the centred joint positions,
    after it has crossed zero and at least ``min_period`` seconds, that is
    nearly (90 %) as high as the highest.

    Parameters
    ----------
    q : ndarray of shape (n_samples, n_joints)
    sample_time : float
        [s].
    min_period : float, default=1.0
        [s].

    Returns
    -------
    period : float or None
        [s]; None when the log holds less than two cycles or no repetition.
    correlation : float
        Autocorrelation at that lag (1: the cycles repeat exactly).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(0, 20, 0.01)
    >>> period, corr = task_period(np.sin(2 * np.pi * t / 4)[:, None], 0.01)
    >>> round(period, 1), corr > 0.9
    (4.0, True)
    """
    q = np.asarray(q, dtype=float)
    q = q - q.mean(axis=0)
    n = len(q)
    power = np.sum(q * q)
    if n < 4 or power <= 0:
        return None, 0.0
    lags = np.arange(n // 2)
    spectrum = np.fft.rfft(q, 2 * n, axis=0)
    ac = np.fft.irfft(np.abs(spectrum) ** 2, axis=0)[: n // 2].sum(axis=1)
    ac = ac / (n - lags) / (power / n)
    crossed = np.flatnonzero(ac < 0)
    start = max(int(crossed[0]) if crossed.size else n // 2,
                int(np.ceil(min_period / sample_time)))
    if start >= n // 2:
        return None, 0.0
    tail = ac[start:]
    peaks = np.flatnonzero((tail[1:-1] >= tail[:-2]) & (tail[1:-1] >= tail[2:])) + 1
    if not peaks.size:
        return None, 0.0
    # the first peak nearly as high as the highest: one period, not a multiple of it
    lag = start + int(peaks[np.argmax(tail[peaks] >= 0.9 * tail[peaks].max())])
    if ac[lag] <= 0:
        return None, float(ac[lag])
    return lag * sample_time, float(ac[lag])


def _moving(general, n_rows):
    """Rows the detector's first band calls moving (all rows without regimes)."""
    regime = general.get("regime")
    if regime is None:
        return np.ones(n_rows, dtype=bool)
    return np.asarray(regime).reshape(n_rows) == MOVING


def tail_level(scores, period, cutoff, n_joints, false_alarm_rate):
    """The level a cycle's score exceeds ``false_alarm_rate`` times per hour.

    A cycle's score is a maximum over its samples and joints, so the scores
    follow a Gumbel law ``P(S <= s) = exp(-exp(-(s - mu) / beta))``. ``beta``
    comes from the moments of the scores (``std * sqrt(6) / pi``), but not below
    the maxima of ``N`` Gaussian samples, ``beta >= mean / (2 ln N)`` with
    ``N = 2 cutoff period n_joints`` independent samples per cycle (a band of
    ``cutoff`` Hz); ``mu = mean - 0.5772 beta``. With ``p =
    false_alarm_rate * period / 3600`` per cycle, the level is
    ``mu - beta ln(-ln(1 - p))``. A few cycles cannot bound such a rate
    without a law: this is the law, and the teach summary says so beside
    the distribution-free ``1 / (n + 1)``.

    Parameters
    ----------
    scores : array-like of shape (n_cycles,)
    period : float
        Cycle length [s].
    cutoff : float
        Band [Hz].
    n_joints : int
    false_alarm_rate : float
        Per hour.

    Returns
    -------
    level : float

    Examples
    --------
    >>> from sklearn_gpcd.detection.task import tail_level
    >>> round(tail_level([0.95, 1.0, 1.05], 20.0, 10.0, 6, 0.1), 2)
    1.44
    """
    s = np.asarray(scores, dtype=float)
    mean = float(s.mean())
    n_samples = max(2.0 * cutoff * period * n_joints, 3.0)
    beta = max(float(s.std(ddof=1)) * np.sqrt(6.0) / np.pi if s.size > 1 else 0.0,
               mean / (2.0 * np.log(n_samples)))
    mu = mean - 0.5772156649 * beta
    p = min(false_alarm_rate * period / 3600.0, 0.5)
    return float(mu - beta * np.log(-np.log1p(-p)))


def _detector_sigma_v(detector):
    """The detector's ``sigma_v`` [rad/s] (the trained model's, :mod:`sklearn_gpcd._gate`)."""
    rule = detector.rules_[0]
    value = getattr(rule, "sigma_v_", None)
    return DEFAULT_SIGMA_V if value is None else float(value)


def _sliding(inputs, n_joints, sigma_v, starts, hold):
    """(n, n_joints): joints at ``|qd| >= sigma_v`` for ``hold`` rows in a row.
    Below it a joint's friction is static, set by how it got there (the
    paper's quasi-static gate), and so is its breakaway: the taught reference
    does not speak for that joint then."""
    fast = np.abs(inputs[:, block_columns("qd", n_joints)]) >= sigma_v
    return window_segments(fast.astype(float), hold, starts, np.min, pad=0.0) > 0


def _held(moving, starts, hold):
    """Rows moving for ``hold`` rows in a row: at rest, settling and in the
    breakaway from rest the current hangs on friction's history, which no
    function of the state predicts; the detector's regimes keep those."""
    held = window_segments(moving.astype(float)[:, None], hold, starts, np.min, pad=0.0)
    return held[:, 0] > 0


def drift_features(qd):
    """Columns ``[1, tanh(qd_l / DRIFT_WIDTH)]`` of the drift, shape (2, n, n_joints)."""
    qd = np.atleast_2d(qd)
    return np.stack([np.ones_like(qd), np.tanh(qd / DRIFT_WIDTH)])


def _cycle_units(starts, n_rows, period_rows):
    """Row ranges ``(lo, hi)`` of the cycles: each recording cut every
    ``period_rows`` rows; a remainder under half a period joins the last cycle."""
    bounds = np.append(starts, n_rows)
    units = []
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        cuts = list(range(lo, hi, period_rows)) + [hi]
        if len(cuts) > 2 and cuts[-1] - cuts[-2] < period_rows // 2:
            cuts.pop(-2)
        units += list(zip(cuts[:-1], cuts[1:]))
    return units


class TaughtTask(BaseEstimator):
    """A task reference on a calibrated detector: taught thresholds where it is known.

    Parameters
    ----------
    detector : CollisionDetector
        Fitted (calibrated); its decision stands in untaught states.
    alpha : float, default=1.0
        Ridge penalty of the reference on standardised features.
    cutoff : float, default=10.0
        Low-pass cut-off [Hz] of the taught residual (the task's own cycles
        allow a faster band than the general 2 Hz one).
    order : {1, 2}, default=1
        Filter order.
    min_duration : int, default=2
        Debounce [samples].
    novelty_radius : float, default=1.0
        Distance in ``[q / 0.1 rad, qd / 0.5 rad/s]`` beyond which a state is
        untaught.
    min_period : float, default=1.0
        Shortest cycle [s] searched for (:func:`task_period`).
    false_alarm_rate : float, default=0.1
        Target false alarms per hour of the task: the level is at least the
        Gumbel quantile of the cycle scores at that rate (:func:`tail_level`).

    Attributes
    ----------
    period_ : float
        Cycle length [s] (the recording's length when it does not repeat).
    n_cycles_ : int
    repeatability_ : float
        Autocorrelation of the joint positions at one period.
    explained_ : ndarray of shape (n_joints,)
        Share of the residual's variance that the cross-fitted reference removes.
    coef_, intercept_, feature_mean_, feature_scale_ : ndarray
        The reference ``r(phi) = ((phi - mean) / scale) @ coef_ + intercept_``.
    bias_ : ndarray of shape (n_joints,)
        Median of the filtered cross-fitted residual.
    scale_ : ndarray of shape (n_joints,)
        Largest debounced ``|m_l - bias_l|`` over the taught cycles [A].
    conformal_level_ : float
        The largest cycle score: a new cycle exceeds it with probability
        at most ``1 / (n_cycles_ + 1)``.
    tail_level_ : float
        The score a new cycle exceeds ``false_alarm_rate`` times per hour
        under a Gumbel law of the cycle scores (:func:`tail_level`).
    level_ : float
        The larger of the two; ``thresholds_ = level_ * scale_``.
    thresholds_ : ndarray of shape (n_joints,)
    cycle_scores_ : ndarray of shape (n_cycles,)
        Each cycle's score against the other cycles' scale (``level_`` is
        the largest; a score far above the rest marks a cycle unlike the
        others, e.g. the first after a start: :meth:`summary` names it).
    cycle_times_ : ndarray of shape (n_cycles, 2)
        Start and end [s from the first taught row] of each cycle.
    filter_coefficients_ : tuple of ndarray
    drift_ : ndarray of shape (2, n_joints)
        The learned drift ``(a, b)`` (zero after :meth:`fit`; see
        :meth:`partial_fit`).
    sigma_v_ : float
        The detector's ``sigma_v`` [rad/s]: a joint slower than it is not
        taught (static friction is history, not state).
    learned_cycles_ : int
        Monitored cycles that taught the drift since :meth:`fit`.
    pending_drift_ : ndarray of shape (2, n_joints) or None
        The last monitored cycle's drift, applied if the next one is clean.
    last_cycle_alarm_ : bool
        Whether an alarm or event touched the last monitored cycle.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.linear_model import Ridge
    >>> from sklearn_gpcd.detection import AlarmRule, CollisionDetector, TaughtTask
    >>> t = np.arange(0, 24, 0.01)
    >>> q = np.sin(2 * np.pi * t / 4)[:, None]
    >>> qd = np.gradient(q[:, 0], t)[:, None]
    >>> X = np.hstack([q, qd, np.gradient(qd[:, 0], t)[:, None]])
    >>> current = 0.3 * np.tanh(qd[:, 0] / 0.05) + 0.01 * np.sin(40 * t)
    >>> rule = AlarmRule("per_joint", false_alarm_rate=0.0, margin=2.0)
    >>> det = CollisionDetector(Ridge(), rules=rule,
    ...                         sample_time=0.01).fit(np.column_stack([X, current]))
    >>> task = TaughtTask(det).fit(np.column_stack([X, current]))
    >>> task.n_cycles_, round(task.period_, 1)
    (6, 4.0)
    >>> pushed = current.copy()
    >>> pushed[1000:1050] += 0.5
    >>> alarms = task.monitoring_signal(np.column_stack([X, pushed])).alarms
    >>> bool(alarms[1000:1050].any()), bool(alarms[:900].any())
    (True, False)
    """

    _parameter_constraints = {
        "detector": [HasMethods(["monitoring_signal", "residuals"])],
        "alpha": [Interval(Real, 0, None, closed="left")],
        "cutoff": [Interval(Real, 0, None, closed="neither")],
        "order": [Interval(Integral, 1, 2, closed="both")],
        "min_duration": [Interval(Integral, 1, None, closed="left")],
        "novelty_radius": [Interval(Real, 0, None, closed="neither")],
        "min_period": [Interval(Real, 0, None, closed="neither")],
        "false_alarm_rate": [Interval(Real, 0, None, closed="neither")],
    }

    def __init__(self, detector, *, alpha=1.0, cutoff=10.0, order=1, min_duration=2,
                 novelty_radius=1.0, min_period=1.0, false_alarm_rate=0.1):
        self.detector = detector
        self.alpha = alpha
        self.cutoff = cutoff
        self.order = order
        self.min_duration = min_duration
        self.novelty_radius = novelty_radius
        self.min_period = min_period
        self.false_alarm_rate = false_alarm_rate

    # -- fit -------------------------------------------------------------------
    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X, y=None, groups=None):
        """Learn the reference, the taught states and the thresholds.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
            The detector's input (regressor inputs, then the currents) of
            collision-free cycles of one task.
        y : None
            Ignored.
        groups : array-like of shape (n_samples,), default=None
            Recording of each row (the filters restart, cycles never span two).

        Returns
        -------
        self : TaughtTask
        """
        det = self.detector
        check_is_fitted(det, "rules_")
        X = np.asarray(X, dtype=float)
        n_joints = det.n_joints
        starts = segment_starts(len(X), groups)
        self.n_joints_ = n_joints
        self.sample_time_ = float(det.sample_time_)
        self.filter_coefficients_ = lowpass_coefficients(self.cutoff, self.sample_time_,
                                                         self.order)
        general = det.monitoring_signal(X, groups)
        residual = np.asarray(general.residual, dtype=float).reshape(len(X), -1)
        moving = _held(_moving(general, len(X)), starts, self._hold())
        phi = task_features(X[:, :-n_joints], n_joints)
        z = local_states(X[:, :-n_joints], n_joints)
        units = self._cycles(X[:, block_columns("q", n_joints)], starts)
        held = np.empty_like(residual)
        for lo, hi in units:
            rest = moving.copy()
            rest[lo:hi] = False
            ref = self._fit_reference(phi[rest], z[rest], residual[rest], self.alpha)
            held[lo:hi] = self._evaluate(ref, phi[lo:hi], z[lo:hi])
        self._set_reference(self._fit_reference(phi[moving], z[moving], residual[moving],
                                                self.alpha))
        cross = residual - held
        self.explained_ = 1.0 - (cross[moving].var(axis=0)
                                 / np.maximum(residual[moving].var(axis=0), 1e-12))
        m = filter_segments(cross, *self.filter_coefficients_, starts)
        self.bias_ = np.median(m[moving], axis=0)
        self.sigma_v_ = _detector_sigma_v(det)
        sliding = moving[:, None] & _sliding(X[:, :-n_joints], n_joints, self.sigma_v_,
                                             starts, self._hold())
        self._set_thresholds(m, starts, units, sliding)
        self._set_states(X[moving, :-n_joints])
        self.drift_ = np.zeros((2, n_joints))
        self.learned_cycles_ = 0
        self.pending_drift_, self.last_cycle_alarm_ = None, False
        return self

    def partial_fit(self, X, y=None, groups=None):
        """Learn the slow drift from monitored logs of the task (keep learning).

        Each recording is cut into cycles of ``period_``; successive calls are
        successive cycles (a cell learning between cycles or shifts). A cycle
        is a candidate if at least half its rows are taught and no alarm or
        event touched it or the cycles beside it: the last cycle of a call
        waits (``pending_drift_``) until the next call shows its first cycle
        clean. Its own drift ``(a, b)`` is the least-squares
        fit of ``s - r(x) - bias_`` on ``[1, tanh(qd / DRIFT_WIDTH)]`` over its
        taught rows; it teaches only if what that fit leaves stays at or below
        ``LEARN_BELOW`` of the thresholds (a slow drift is what the fit takes
        away; a contact, shaped by the arm's Jacobian along the cycle, is not).
        Then the drift moves ``LEARN_RATE`` of the way to the cycle's, by at
        most ``LEARN_STEP`` of each joint's threshold, and is shrunk so that
        ``|a_l| + |b_l| <= LEARN_LIMIT * thresholds_l``. Nothing else
        changes: the thresholds are never raised, the reference is the taught
        one.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
            Monitored rows (the detector's input).
        y : None
            Ignored.
        groups : array-like of shape (n_samples,), default=None
            Recording of each row.

        Returns
        -------
        self : TaughtTask
            With ``drift_``, ``learned_cycles_`` updated and
            ``last_learning_`` (``accepted`` and ``rejected`` cycle counts, the
            reasons, the drift before and after).
        """
        check_is_fitted(self, "drift_")
        X = np.asarray(X, dtype=float)
        n = self.n_joints_
        res = self.monitoring_signal(X, groups)
        starts = segment_starts(len(X), groups)
        units = _cycle_units(starts, len(X), int(round(self.period_ / self.sample_time_)))
        verdicts, bad = self._learning_verdicts(res, units, starts)
        before = self.drift_.copy()
        pending = self.pending_drift_
        if pending is not None and not bad[0]:   # the cycle after it was clean too
            self._learn_drift(pending)
        if self.last_cycle_alarm_ and verdicts[0] == "candidate":
            verdicts[0] = "beside an alarm"
        self.pending_drift_ = None
        qd = X[:, block_columns("qd", n)]
        u = res.residual - self.reference(X[:, :-n]) - self.bias_
        for k, (lo, hi) in enumerate(units):
            if verdicts[k] != "candidate":
                continue
            target, left = self._cycle_drift(u[lo:hi], qd[lo:hi], res.taught[lo:hi])
            if left > LEARN_BELOW:
                verdicts[k] = "above LEARN_BELOW"
            elif k + 1 == len(units):       # waits for the next cycle to be clean
                verdicts[k], self.pending_drift_ = "pending", target
            else:
                verdicts[k] = "accepted"
                self._learn_drift(target)
        self.last_cycle_alarm_ = bad[-1]
        self.learned_cycles_ += verdicts.count("accepted") + (
            pending is not None and not bad[0])
        self.last_learning_ = {
            "accepted": verdicts.count("accepted"), "rejected": len(units) - verdicts.count(
                "accepted") - verdicts.count("pending"), "verdicts": verdicts,
            "drift_before_A": before.tolist(), "drift_A": self.drift_.tolist()}
        return self

    def _learning_verdicts(self, res, units, starts):
        """Per cycle: "candidate", or why not ("alarm", "beside an alarm",
        "untaught"); and whether an alarm or event touched it."""
        bad = [bool(res.alarms[lo:hi].any() or res.event[lo:hi].any()) for lo, hi in units]
        first = {int(s) for s in starts}
        verdicts = []
        for k, (lo, hi) in enumerate(units):
            near = (k > 0 and lo not in first and bad[k - 1]) or (
                k + 1 < len(units) and units[k + 1][0] not in first and bad[k + 1])
            verdicts.append("alarm" if bad[k] else "beside an alarm" if near else
                            "untaught" if res.taught[lo:hi].mean() < LEARN_TAUGHT_SHARE
                            else "candidate")
        return verdicts, bad

    def _cycle_drift(self, u, qd, taught):
        """The cycle's own drift fit ``(a, b)`` on its taught rows, and the largest
        ratio of what it leaves (filtered and debounced as the monitor does)."""
        g = drift_features(qd)                        # (2, rows, joints)
        target = np.empty_like(self.drift_)
        for j in range(self.n_joints_):
            target[:, j] = np.linalg.lstsq(g[:, taught, j].T, u[taught, j], rcond=None)[0]
        left = u - np.einsum("knj,kj->nj", g, target)
        m = filter_segments(left, *self.filter_coefficients_, np.array([0]))
        debounced = window_segments(np.abs(m), self.min_duration, np.array([0]), np.min,
                                    pad=0.0)
        return target, float((debounced[taught] / self.thresholds_).max())

    def _learn_drift(self, target):
        """Move ``drift_`` toward ``target``: ``LEARN_RATE`` of the way, at most
        ``LEARN_STEP`` and in all ``LEARN_LIMIT`` of each joint's threshold."""
        step = LEARN_RATE * (target - self.drift_)
        size = np.abs(step).sum(axis=0)
        step *= np.minimum(1.0, LEARN_STEP * self.thresholds_ / np.maximum(size, 1e-300))
        drift = self.drift_ + step
        size = np.abs(drift).sum(axis=0)
        bound = LEARN_LIMIT * self.thresholds_
        self.drift_ = drift * np.minimum(1.0, bound / np.maximum(size, 1e-300))

    def drift(self, inputs):
        """The learned drift ``d(x)`` [A] of regressor inputs, (n, n_joints)."""
        check_is_fitted(self, "coef_")
        qd = np.asarray(inputs, dtype=float)[:, block_columns("qd", self.n_joints_)]
        return np.einsum("knj,kj->nj", drift_features(qd), self._drift())

    def _sigma_v(self):
        """``sigma_v_`` (files taught before it existed: the default)."""
        return getattr(self, "sigma_v_", DEFAULT_SIGMA_V)

    def _drift(self):
        """``drift_`` (files taught before keep-learning existed have none)."""
        return getattr(self, "drift_", np.zeros((2, self.n_joints_)))

    def _hold(self):
        """Rows of motion before the taught thresholds apply (``BREAKAWAY_S``)."""
        return self._hold_rows(BREAKAWAY_S)

    def _hold_rows(self, seconds):
        return max(1, int(round(seconds / self.sample_time_)))

    def _cycles(self, q, starts):
        """Cycles of the taught recordings (``period_``, ``n_cycles_``, ``repeatability_``)."""
        period, corr = task_period(q, self.sample_time_, self.min_period)
        self.repeatability_ = corr
        rows = len(q) if period is None else int(round(period / self.sample_time_))
        units = _cycle_units(starts, len(q), rows)
        if len(units) < 2:
            raise ValueError(
                f"teaching needs at least two cycles of the task; the log holds "
                f"{len(q) * self.sample_time_:.1f} s and no repetition of at least "
                f"{self.min_period:g} s was found: record two or more cycles")
        self.period_ = rows * self.sample_time_
        self.n_cycles_ = len(units)
        return units

    @staticmethod
    def _fit_reference(phi, z, residual, alpha):
        """The reference's numbers: ridge on standardised ``phi``, and what it
        leaves at each taught state ``z`` for the local correction."""
        mean, scale = phi.mean(axis=0), phi.std(axis=0)
        scale[scale < 1e-9] = 1.0
        ridge = Ridge(alpha=alpha).fit((phi - mean) / scale, residual)
        coef = np.atleast_2d(ridge.coef_).T
        intercept = np.atleast_1d(ridge.intercept_)
        left = residual - (((phi - mean) / scale) @ coef + intercept)
        return Bunch(mean=mean, scale=scale, coef=coef, intercept=intercept,
                     tree=cKDTree(z), left=left)

    @staticmethod
    def _evaluate(ref, phi, z):
        """``r = ridge(phi) + sum_k w_k left_k / sum_k w_k * (1 - exp(-sum_k w_k))``,
        ``w_k = exp(-|z - z_k|^2 / 2)`` over the nearest taught states: the
        local correction fades out away from them."""
        smooth = ((phi - ref.mean) / ref.scale) @ ref.coef + ref.intercept
        d, i = ref.tree.query(z, k=min(LOCAL_NEIGHBOURS, ref.tree.n))
        d, i = d.reshape(len(z), -1), i.reshape(len(z), -1)
        w = np.exp(-0.5 * d ** 2)
        total = w.sum(axis=1)
        local = np.einsum("nk,nkj->nj", w, ref.left[i]) / np.maximum(total, 1e-300)[:, None]
        return smooth + local * (1.0 - np.exp(-total))[:, None]

    def _set_reference(self, ref):
        self.feature_mean_, self.feature_scale_ = ref.mean, ref.scale
        self.coef_, self.intercept_ = ref.coef.copy(), ref.intercept.copy()
        self.local_states_, self.local_residual_ = ref.tree.data.copy(), ref.left.copy()
        self._ref = ref

    def _set_thresholds(self, m, starts, units, sliding):
        """``scale_``, ``level_``, ``thresholds_`` from the filtered cross-fitted residual
        where each joint is taught (``sliding``, (n, n_joints)): each cycle's peaks
        scored against the scale of the *other* cycles, one level."""
        debounced = window_segments(np.abs(m - self.bias_), self.min_duration, starts,
                                    np.min, pad=0.0)
        debounced[~sliding] = 0.0
        peaks = np.array([debounced[lo:hi].max(axis=0) for lo, hi in units])
        floor = np.finfo(float).tiny
        self.scale_ = np.maximum(peaks.max(axis=0), floor)
        scores = [np.max(p / np.maximum(np.delete(peaks, c, axis=0).max(axis=0), floor))
                  for c, p in enumerate(peaks)]
        self.cycle_scores_ = np.asarray(scores)
        self.cycle_times_ = np.array([(lo, hi) for lo, hi in units]) * self.sample_time_
        self.conformal_level_ = float(max(scores))
        self.tail_level_ = tail_level(scores, self.period_, self.cutoff, self.n_joints_,
                                      self.false_alarm_rate)
        self.level_ = max(self.conformal_level_, self.tail_level_)
        self.thresholds_ = self.level_ * self.scale_

    def _set_states(self, inputs):
        states = self._scaled_states(inputs)
        step = max(1, int(np.ceil(len(states) / MAX_TAUGHT_STATES)))
        self.taught_states_ = states[::step].copy()
        self._tree = cKDTree(self.taught_states_)

    def _scaled_states(self, inputs):
        n = self.n_joints_
        return np.hstack([inputs[:, block_columns("q", n)] / 0.1,
                          inputs[:, block_columns("qd", n)] / 0.5])

    def __getstate__(self):
        state = self.__dict__.copy()
        state.pop("_tree", None)
        state.pop("_ref", None)
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        if "taught_states_" in state:
            self._tree = cKDTree(self.taught_states_)
            self._ref = Bunch(mean=self.feature_mean_, scale=self.feature_scale_,
                              coef=self.coef_, intercept=self.intercept_,
                              tree=cKDTree(self.local_states_), left=self.local_residual_)

    # -- use -------------------------------------------------------------------
    def reference(self, inputs):
        """The taught residual ``r(x)`` [A] of regressor inputs, (n, n_joints)."""
        check_is_fitted(self, "coef_")
        inputs = np.asarray(inputs, dtype=float)
        return self._evaluate(self._ref, task_features(inputs, self.n_joints_),
                              local_states(inputs, self.n_joints_))

    def novelty(self, inputs):
        """Distance to the nearest taught state over ``novelty_radius``: > 1 is untaught.

        Parameters
        ----------
        inputs : array-like of shape (n_samples, n_inputs)
            Regressor inputs (without the currents).

        Returns
        -------
        novelty : ndarray of shape (n_samples,)
        """
        check_is_fitted(self, "taught_states_")
        d, _ = self._tree.query(self._scaled_states(np.asarray(inputs, dtype=float)))
        return d / self.novelty_radius

    def monitoring_signal(self, X, groups=None):
        """Batch decisions: taught thresholds in taught states, the detector's elsewhere.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
        groups : array-like of shape (n_samples,), default=None

        Returns
        -------
        result : Bunch
            ``residual`` (the detector's ``i - i_hat``, A), ``signal`` (its
            filtered taught part minus ``bias_``, A),
            ``novelty``, ``moving`` (the detector's regime), ``taught``
            (``novelty <= 1`` after ``BREAKAWAY_S`` of motion), ``joints``
            (n, n_joints: where each joint's taught threshold applies),
            ``taught_alarms``,
            ``general_alarms`` and ``general_ratio`` (n, n_joints) and ``alarms``: the taught ones
            where taught and the joint has slid (``|qd_l| >= sigma_v_``) for
            ``BREAKAWAY_S``, the
            general ones elsewhere; ``ratio``, the largest of the debounced
            ``|m_l| / threshold_l`` where taught and of the detector's
            ratio over its level elsewhere (``ratio_over_level``),
            ``event`` (bool): the rows of contact events (:class:`EventHold`
            on those ratios per joint) and ``event_onset`` (bool): the rows
            where an event begins.
        """
        check_is_fitted(self, "coef_")
        X = np.asarray(X, dtype=float)
        n = self.n_joints_
        starts = segment_starts(len(X), groups)
        general = self.detector.monitoring_signal(X, groups)
        residual = np.asarray(general.residual, dtype=float).reshape(len(X), -1)
        inputs = X[:, :-n]
        m = filter_segments(residual - self.reference(inputs) - self.drift(inputs),
                            *self.filter_coefficients_, starts) - self.bias_
        debounced = window_segments(np.abs(m), self.min_duration, starts, np.min, pad=0.0)
        taught_alarms = debounced > self.thresholds_
        novelty = self.novelty(inputs)
        moving = _moving(general, len(X))
        taught = (novelty <= 1.0) & _held(moving, starts, self._hold())
        general_alarms = np.asarray(general.alarms, dtype=bool).reshape(len(X), -1)
        joints = taught[:, None] & _sliding(inputs, n, self._sigma_v(), starts, self._hold())
        alarms = np.where(joints, taught_alarms, general_alarms)
        over = ratio_over_level(general.bands).reshape(len(X), -1)
        joint_ratio = np.where(joints, debounced / self.thresholds_, over)
        event, onset = event_rows(joint_ratio, starts, self._hold_rows(EVENT_HOLD_S))
        return Bunch(residual=residual, signal=m, novelty=novelty, moving=moving,
                     taught=taught, joints=joints, taught_alarms=taught_alarms,
                     general_alarms=general_alarms, general_ratio=over, alarms=alarms,
                     ratio=joint_ratio.max(axis=1), event=event, event_onset=onset)

    def predict(self, X, groups=None):
        """+1 normal, -1 collision, per row.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
        groups : array-like of shape (n_samples,), default=None

        Returns
        -------
        y : ndarray of shape (n_samples,)
        """
        return np.where(self.monitoring_signal(X, groups).alarms.any(axis=1), -1, 1)

    def stream(self):
        """A :class:`TaskStream`: the same decisions, one sample at a time."""
        check_is_fitted(self, "coef_")
        return TaskStream(self)

    def deviant_cycles(self, factor=2.0):
        """Cycles whose score is more than ``factor`` times the median score.

        A cycle whose peaks are twice what the other cycles all stay within
        held something the others did not (a touch while teaching, a start
        from another state).

        Parameters
        ----------
        factor : float, default=2.0

        Returns
        -------
        cycles : list of dict
            ``index``, ``start_s``, ``end_s`` (from the first taught row) and
            ``score`` of each; such a cycle alone sets ``level_``.
        """
        check_is_fitted(self, "cycle_scores_")
        median = float(np.median(self.cycle_scores_))
        return [{"index": int(c), "start_s": float(self.cycle_times_[c, 0]),
                 "end_s": float(self.cycle_times_[c, 1]), "score": float(score)}
                for c, score in enumerate(self.cycle_scores_) if score > factor * median]

    def summary(self):
        """What the teach step found, as a dict of plain numbers."""
        check_is_fitted(self, "coef_")
        return {"period_s": self.period_, "n_cycles": self.n_cycles_,
                "cycle_scores": self.cycle_scores_.tolist(),
                "deviant_cycles": self.deviant_cycles(),
                "repeatability": self.repeatability_,
                "explained": self.explained_.tolist(), "level": self.level_,
                "thresholds_A": self.thresholds_.tolist(),
                "filter": {"cutoff_hz": self.cutoff, "order": self.order,
                           "min_duration": self.min_duration},
                "conformal_level": self.conformal_level_, "tail_level": self.tail_level_,
                "false_alarm_rate": self.false_alarm_rate,
                "false_alarm_bound_per_cycle": 1.0 / (self.n_cycles_ + 1),
                "false_alarms_per_hour_bound": 3600.0 / self.period_ / (self.n_cycles_ + 1),
                "drift_A": self._drift().tolist(),
                "learned_cycles": int(getattr(self, "learned_cycles_", 0))}


class TaskStream:
    """Tick-by-tick :meth:`TaughtTask.monitoring_signal` (the taught half).

    Parameters
    ----------
    task : TaughtTask
        Fitted.

    Attributes
    ----------
    signal : ndarray of shape (n_joints,) or None
        The taught part's filtered residual at the last tick [A].
    joints : ndarray of bool, shape (n_joints,)
        Where the taught thresholds decided the last tick.
    ratio : float
        The largest ratio over its threshold at the last tick.
    event, event_onset : bool
        Whether a contact event is open, and whether one began, at the last
        tick (:class:`EventHold` on each joint's ratio).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.linear_model import Ridge
    >>> from sklearn_gpcd.detection import AlarmRule, CollisionDetector, TaughtTask
    >>> t = np.arange(0, 12, 0.01)
    >>> q = np.sin(2 * np.pi * t / 4)[:, None]
    >>> qd = np.gradient(q[:, 0], t)[:, None]
    >>> X = np.hstack([q, qd, np.zeros_like(q), 0.2 * qd])
    >>> det = CollisionDetector(Ridge(), rules=AlarmRule(contamination=0.01),
    ...                         sample_time=0.01).fit(X)
    >>> task = TaughtTask(det).fit(X)
    >>> stream = task.stream()
    >>> quiet = np.zeros(1, bool), np.zeros(1)   # the detector's alarms and ratio
    >>> for row in X[:30]:        # taught after BREAKAWAY_S (0.25 s) of motion
    ...     alarm, taught = stream.step(row[:-1], row[-1:], *quiet)
    >>> bool(alarm.any()), bool(taught)
    (False, True)
    """

    def __init__(self, task):
        self.task = task
        b, a = task.filter_coefficients_
        self._b, self._a = b, a
        self._zi0 = lfilter_zi(b, a)
        n = task.n_joints_
        self._q, self._qd, self._qdd = (np.asarray(block_columns(b, n))
                                        for b in ("q", "qd", "qdd"))
        self._widths = np.asarray(COULOMB_WIDTHS)
        self._local_scale = np.repeat(LOCAL_SCALE, n)
        self._k = min(LOCAL_NEIGHBOURS, task._ref.tree.n)
        self._hold = task._hold()
        self._drift = task._drift()
        self._sigma_v = task._sigma_v()
        self.reset()

    def _reference(self, x):
        """:meth:`TaughtTask.reference` plus :meth:`TaughtTask.drift`, and the
        novelty of one row, without the per-call checks (the same arithmetic)."""
        task = self.task
        q, qd, qdd = x[self._q], x[self._qd], x[self._qdd]
        phi = np.concatenate([q, np.sin(q), np.cos(q), qd,
                              np.tanh(qd[None, :] / self._widths[:, None]).ravel(), qdd])
        smooth = ((phi - task.feature_mean_) / task.feature_scale_) @ task.coef_ \
            + task.intercept_
        d, i = task._ref.tree.query(np.concatenate([q, qd, qdd]) / self._local_scale,
                                    k=self._k)
        w = np.exp(-0.5 * np.atleast_1d(d) ** 2)
        total = w.sum()
        local = w @ task.local_residual_[np.atleast_1d(i)] / max(total, 1e-300)
        novelty, _ = task._tree.query(np.concatenate([q / 0.1, qd / 0.5]))
        drift = self._drift[0] + self._drift[1] * np.tanh(qd / DRIFT_WIDTH)
        return (smooth + local * (1.0 - np.exp(-total)) + drift,
                novelty / task.novelty_radius)

    def reset(self):
        """Restart the filter and debounce (a new recording, or after a fault)."""
        self._z = None
        self._window = []
        self._moving_run = 0
        self._sliding_run = np.zeros(self.task.n_joints_, dtype=int)
        self._first = True
        self._events = EventHold(self.task._hold_rows(EVENT_HOLD_S))
        self.joints = np.zeros(self.task.n_joints_, dtype=bool)
        self.signal = None
        self.ratio = 0.0
        self.event = False
        self.event_onset = False

    def step(self, inputs, current, general_alarm, general_ratio, moving=True,
             predicted=None):
        """One sample.

        Parameters
        ----------
        inputs : ndarray of shape (n_inputs,)
        current : ndarray of shape (n_joints,)
        general_alarm : ndarray of bool, shape (n_joints,)
            The detector's per-joint alarm at this sample.
        general_ratio : ndarray of shape (n_joints,)
            The detector's per-joint ratio over its level (``ratio_over_level``):
            the event of an untaught joint holds on it, as the detector's own.
        moving : bool, default=True
            Whether the detector's regime is "moving" (the taught thresholds
            apply after ``BREAKAWAY_S`` of it)
            (:attr:`StreamingMonitor.regime <sklearn_gpcd.detection.StreamingMonitor.regime>`).
        predicted : ndarray of shape (n_joints,), default=None
            The detector's predicted currents (computed here when None).

        Returns
        -------
        alarm : ndarray of bool, shape (n_joints,)
        taught : bool
        """
        task = self.task
        inputs = np.asarray(inputs, dtype=float)
        if predicted is None:
            predicted = task.detector.regressor_.predict(inputs[None, :])
        reference, novelty = self._reference(inputs)
        u = np.asarray(current, dtype=float) - np.reshape(predicted, -1) - reference
        b, a = self._b, self._a
        if self._z is None:
            self._z = self._zi0[:, None] * u[None, :]
        y = b[0] * u + self._z[0]
        for k in range(1, len(self._z)):   # direct form II transposed
            self._z[k - 1] = b[k] * u + self._z[k] - a[k] * y
        self._z[-1] = b[-1] * u - a[-1] * y
        self.signal = y - task.bias_
        self._window.append(np.abs(self.signal))
        if len(self._window) > task.min_duration:
            self._window.pop(0)
        debounced = (np.min(self._window, axis=0) if len(self._window) == task.min_duration
                     else np.zeros_like(u))
        self._moving_run = self._moving_run + 1 if moving else 0
        taught = self._moving_run >= self._hold and bool(novelty <= 1.0)
        general_alarm = np.asarray(general_alarm, bool)
        fast = np.abs(inputs[self._qd]) >= self._sigma_v
        self._sliding_run = np.where(fast, self._sliding_run + 1, 0)
        self.joints = joints = (self._sliding_run >= self._hold) & taught
        alarm = np.where(joints, debounced > task.thresholds_, general_alarm)
        joint_ratio = np.where(joints, debounced / task.thresholds_, general_ratio)
        self.ratio = float(joint_ratio.max())
        self.event = self._events.step(joint_ratio, self._first)
        self.event_onset = self._events.onset
        self._first = False
        return alarm, taught
