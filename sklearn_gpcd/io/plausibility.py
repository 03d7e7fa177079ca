"""Plausibility of a recording's signals: gaps, units, and what the model knows.

The one home of the checks that tell a swapped, scaled or mislabelled column
from a real signal. Nothing here drops or changes a row; each check gives a
sentence naming the column.

Model-free checks (the readers' single
:class:`~sklearn_gpcd.io.RecordingWarning`, ``gpcd`` refuses them unless
``--units-confirmed``):

* :func:`find_gaps` -- time steps longer than :data:`GAP_WARNING_FACTOR`
  median sampling periods. Derivatives and filters interpolate across a
  gap, so the user should know where it is (and may split the recording).
* :func:`looks_like_degrees` -- joint positions beyond ``2 pi + 0.25`` rad
  on more than 5 % of the samples.
* velocity against the derivative of position (:class:`SignalCheck`,
  :func:`units_note`), at rest too: over blocks of :data:`BLOCK_SECONDS`,
  the position change :math:`A_j = q_j(t_1) - q_j(t_0)` against the
  integrated velocity :math:`B_j = \\int_{t_0}^{t_1} \\dot q_j\\,dt`
  (trapezoids). With consistent units :math:`\\sum |A_j - B_j|` is a small
  share of the travel :math:`\\max(\\sum |A_j|, \\sum |B_j|)` (the UR10e
  logs: gains 0.997-1.004 in motion) plus the position noise
  (:data:`BLOCK_NOISE` per block). The gain :math:`g_j = \\sum |A_j| /
  \\sum |B_j|` names the cause: :math:`180/\\pi`, ``q`` in degrees and
  ``qd`` in rad/s; :math:`\\pi/180` the reverse; :math:`10^{-3}` a time
  column in milliseconds; near 0 with a velocity that integrates to metres
  of travel while the arm stands still, ``q`` and ``qd`` swapped (or ``q``
  scaled down). Unlike a correlation test, this needs no motion: a
  velocity that is not zero at rest integrates to a travel the positions
  never show.
* the reverse at rest: a position cannot span more than the path its
  velocity allows, :math:`\\max q_j - \\min q_j \\le \\int |\\dot q_j|\\,dt`.
  A span beyond :data:`SPAN_FACTOR` times that path plus
  :data:`FROZEN_STEPS` of the position's smallest steps is a velocity
  scaled down or frozen (``qd`` x0.001 of a push at rest: the UR10e log
  moves 11-26 encoder steps while ``qd`` is 0 at 4 decimals; the
  recordings of the data set stay within 2 steps where ``qd`` is 0).

Checks against what the model knows (:class:`SignalCheck` with the ranges
:func:`signal_ranges` of the training and calibration recordings, stored in
the model and detector files; ``gpcd calibrate``, ``gpcd monitor`` and
:func:`sklearn_gpcd.workflow.check_signals`):

* currents: beyond :data:`GROSS_FACTOR` times the largest current of the
  training data, or the drive limits (an error), and against the model's
  prediction :math:`\\hat\\imath_j`: where :math:`|\\hat\\imath_j|` is at
  least :data:`PREDICTION_FLOOR` of the training peak (on at least
  :data:`PREDICTION_SHARE` of the samples), the ratio
  :math:`i_j / \\hat\\imath_j` lies below 3 and above ``-1/3`` on most
  samples (a collision moves it on a few); a majority below ``-1/3`` is a
  sign flip, a majority above 3 a scale (x57.3, x1000): errors, counted
  only where ``|i - i_hat|`` exceeds the detector's loosest threshold
  (where the column changes the answer; the calibration logs of a model
  that errs stay within their thresholds). Ratios
  near 0 are not judged (the UR10e model errs that way at some poses of
  the jointwise runs); a current scaled down leaves the training range
  (a warning); this holds at rest, where gravity alone sets the current;
* currents below the sensor noise: the step :math:`|i_j(t_{k+1}) -
  i_j(t_k)|` under :math:`1/`:data:`NOISE_FACTOR` of ``current_noise`` (the
  smallest median step of the recordings the model knows, per joint) on
  most samples is a current scaled down (x0.001) or frozen, in motion and
  at rest alike (an error; UR10e: 0.011-0.039 A per joint);
* permuted currents: the clipped residual :math:`c_{ab} = \\overline{\\min(
  |i_a - \\hat\\imath_b| / s_b, 3)}` of column ``a`` read as joint ``b``
  (``s_b`` the detector's loosest threshold) is summed over the permutation
  that minimizes it (every permutation up to 7 joints); when it beats the
  columns as labelled by more than :data:`PERMUTATION_GAIN`, the moved
  columns are named (an error). At rest gravity sets the prediction, so
  two joints of different loads swapped are caught standing still;
* joint positions beyond the robot's limits (an error), or outside the
  training range (a warning: the model extrapolates there, which a
  scaled or swapped ``q`` also does);
* velocities outside the training range (a warning);
* time steps against the detector's sample time: a factor 10 or more is
  another time unit (an error).
"""

import itertools
import warnings
from typing import NamedTuple

import numpy as np

#: Joint positions beyond this [rad] suggest degrees (UR joints span +-2 pi).
DEGREES_THRESHOLD = 2 * np.pi + 0.25
#: Fraction of samples that must exceed it before the degrees warning fires.
DEGREES_FRACTION = 0.05
#: Time steps longer than this many median sampling periods are reported.
GAP_WARNING_FACTOR = 10
#: Fewest time steps needed to judge sampling gaps and velocity units.
MIN_STEPS = 10
#: A gain within this factor of 1 is consistent units.
GAIN_TOLERANCE = 1.25
#: Gains with a known cause, and the cause.
KNOWN_GAINS = (
    (180 / np.pi, "q looks like degrees while qd is in rad/s (convert q with numpy.deg2rad)"),
    (np.pi / 180, "qd looks like deg/s while q is in rad (convert qd with numpy.deg2rad)"),
    (1e-3, "time looks like milliseconds (pass time_scale=1e-3)"),
    (1e-6, "time looks like microseconds (pass time_scale=1e-6)"),
    (1e-9, "time looks like nanoseconds (pass time_scale=1e-9)"),
)
#: Items quoted in messages.
N_QUOTED = 5


def looks_like_degrees(q):
    """True when more than 5 % of the samples have ``|q_j| > 2 pi + 0.25``.

    Parameters
    ----------
    q : ndarray of shape (n_samples, n_joints)
        Joint positions.

    Returns
    -------
    degrees : bool

    A UR joint spans ``[-2 pi, 2 pi]`` rad, so positions beyond that on a
    sizeable share of the samples are almost surely degrees. A recording in
    degrees that stays within +-6.5 deg cannot be told apart this way (see
    :func:`velocity_gain`).

    Examples
    --------
    >>> import numpy as np
    >>> looks_like_degrees(np.array([[0.0, -90.0, 90.0]] * 10))
    True
    >>> looks_like_degrees(np.array([[0.0, -1.57, 1.57]] * 10))
    False
    """
    if q.size == 0:
        return False
    beyond = np.max(np.abs(q), axis=1) > DEGREES_THRESHOLD
    return bool(np.mean(beyond) > DEGREES_FRACTION)


def degrees_note(q, labels=None):
    """Sentence for the warning when :func:`looks_like_degrees`, else None.

    Parameters
    ----------
    q : ndarray of shape (n_samples, n_joints)
    labels : list of str or None, default=None
        Column labels of ``q`` (default ``q[0]``, ``q[1]``, ...); the
        sentence names the columns that reach beyond ``2 pi + 0.25`` rad.

    Returns
    -------
    note : str or None

    Examples
    --------
    >>> import numpy as np
    >>> degrees_note(np.array([[0.0, 90.0]] * 10))[:34]
    'q[1] reaches |q| = 90 with more th'
    """
    if not looks_like_degrees(q):
        return None
    peaks = np.max(np.abs(q), axis=0)
    beyond = np.flatnonzero(peaks > DEGREES_THRESHOLD)
    names = [labels[j] if labels is not None else f"q[{j}]" for j in beyond]
    verb = "reaches" if len(names) == 1 else "reach"
    return (f"{', '.join(names)} {verb} |q| = {float(peaks.max()):.4g} with more than "
            f"{100 * DEGREES_FRACTION:.0f} % of the samples beyond 2*pi rad; the angles "
            "look like degrees (convert with numpy.deg2rad).")


def find_gaps(time, factor=GAP_WARNING_FACTOR):
    """Indices ``k`` where ``time[k + 1] - time[k]`` exceeds ``factor`` median steps.

    Parameters
    ----------
    time : ndarray of shape (n,)
        Strictly increasing time stamps.
    factor : float, default=10
        Gap threshold in median sampling periods.

    Returns
    -------
    gaps : ndarray of int
        Step indices; empty with fewer than :data:`MIN_STEPS` steps.
    median : float
        Median sampling period (NaN when too short).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.r_[np.arange(20) * 0.01, 5.0 + np.arange(20) * 0.01]
    >>> gaps, median = find_gaps(t)
    >>> gaps.tolist(), round(float(median), 3)
    ([19], 0.01)
    """
    steps = np.diff(time)
    if steps.size < MIN_STEPS:
        return np.empty(0, dtype=int), float("nan")
    median = float(np.median(steps))
    return np.flatnonzero(steps > factor * median), median


def gaps_note(time, row_ids, kind="line"):
    """Sentence naming every gap :func:`find_gaps` finds, and the gaps.

    Parameters
    ----------
    time : ndarray of shape (n,)
        Time stamps of the kept rows.
    row_ids : ndarray of int, shape (n,)
        Their line (row) numbers.
    kind : str, default="line"
        What ``row_ids`` count.

    Returns
    -------
    note : str or None
        None without gaps.
    gaps : list of [int, float]
        ``[row number after the gap, gap length in s]`` per gap.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.r_[np.arange(20) * 0.01, 3.0 + np.arange(20) * 0.01]
    >>> note, gaps = gaps_note(t, np.arange(40) + 2)
    >>> gaps
    [[22, 2.81]]
    >>> note[:46]
    '1 gap in time longer than 10 median sampling p'
    """
    idx, median = find_gaps(time)
    if idx.size == 0:
        return None, []
    steps = np.diff(time)
    gaps = [[int(row_ids[k + 1]), round(float(steps[k]), 9)] for k in idx]
    shown = "; ".join(f"{steps[k]:.4g} s before {kind} {row_ids[k + 1]} "
                      f"(t={float(time[k + 1])!r})" for k in idx[:N_QUOTED])
    more = f"; ... ({idx.size} in all)" if idx.size > N_QUOTED else ""
    plural = "s" if idx.size != 1 else ""
    note = (f"{idx.size} gap{plural} in time longer than {GAP_WARNING_FACTOR} median sampling "
            f"periods ({median:.4g} s): {shown}{more}. Nothing was dropped, but derivatives "
            "interpolate across a gap: split the recording there if the robot moved "
            "meanwhile (their rows are in recording.metadata['gaps']).")
    return note, gaps


#: Length [s] of the blocks over which position change and integrated velocity meet.
BLOCK_SECONDS = 0.5
#: Position noise [rad] allowed per block (4-decimal logs: 1e-4 rad steps).
BLOCK_NOISE = 1e-3
#: Share of the travel by which position and integrated velocity may disagree.
TRAVEL_TOLERANCE = 0.25
#: Currents beyond this many times the training data's largest |current| are absurd.
GROSS_FACTOR = 10.0
#: Ratio ``i / i_hat`` counted where ``|i_hat|`` is at least this share of the training peak.
PREDICTION_FLOOR = 0.1
#: Share of the samples on which the prediction must be large enough to judge the ratio:
#: a model that errs on a few samples (a pose it knows badly) is not a scaled column.
PREDICTION_SHARE = 0.2
#: ``i / i_hat`` within ``[1 / RATIO_BAND, RATIO_BAND]`` agrees with the model.
RATIO_BAND = 3.0
#: Fewest samples a ratio or range verdict needs.
MIN_SAMPLES = 20
#: Share of the samples outside the training range that makes a warning (positions,
#: velocities; currents: a collision leaves the range for a while, a scaled column
#: for good).
RANGE_FRACTION = {"q": 0.05, "qd": 0.05, "current": 0.5}
#: Slack around a training range: this share of its span, at least ``RANGE_FLOOR``.
RANGE_SLACK = 0.1
#: Smallest slack per field [rad, rad/s, A].
RANGE_FLOOR = {"q": 0.1, "qd": 0.1, "current": 0.2}
#: Position slack [rad] beyond the robot's limits.
LIMIT_SLACK = 0.1
#: Time steps this many times the sample time (or its inverse) are another unit.
TIME_UNIT_FACTOR = 10.0
#: The fields of :func:`signal_ranges`.
RANGE_FIELDS = ("q", "qd", "current")
#: A position that spans more than this many times the path its velocity allows
#: (``int |qd| dt``), plus :data:`FROZEN_STEPS` position steps, moved without it.
SPAN_FACTOR = 2.0
#: Position steps (the smallest change of ``q`` in the recording) of slack on the span.
FROZEN_STEPS = 10
#: A current whose step ``|i(t_k+1) - i(t_k)|`` is below 1 / this of the smallest noise
#: the model's data show (``current_noise``) on most samples is scaled down or frozen.
NOISE_FACTOR = 10.0
#: Share of the samples below that floor that makes the error.
QUIET_SHARE = 0.5
#: Residuals ``|i_a - i_hat_b| / threshold_b`` are clipped here (a collision counts little).
RESIDUAL_CAP = 3.0
#: Mean clipped residual (in thresholds, summed over joints) by which a permutation of the
#: current columns must beat the columns as labelled to be reported.
PERMUTATION_GAIN = 0.5
#: Most joints whose permutations are all tried (7! = 5040); beyond, pairs are swapped.
MAX_PERMUTED_JOINTS = 7


class Finding(NamedTuple):
    """One implausible signal: ``kind``, the ``columns`` named, ``severity``, ``sentence``.

    ``severity`` is ``"error"`` where the signal would change the answer
    (``gpcd`` refuses it unless ``--units-confirmed``), ``"warning"`` where
    the model extrapolates.

    Examples
    --------
    >>> Finding("current", ["current[2]"], "error", "...").severity
    'error'
    """

    kind: str
    columns: list
    severity: str
    sentence: str


def signal_ranges(recordings, ranges=None):
    """Per-joint ``[low, high]`` of q, qd and current over recordings.

    Parameters
    ----------
    recordings : iterable of Recording
    ranges : dict or None, default=None
        Ranges to widen (e.g. the training ranges a model file stores).

    Returns
    -------
    ranges : dict
        ``{"q": [[low_0, ...], [high_0, ...]], "qd": ..., "current": ...,
        "current_noise": [...], "units": "A"}``: plain lists, to store in a
        model or detector file. Non-finite values are left out.
        ``current_noise`` is, per joint, the smallest over the recordings of
        the median step ``|i(t_{k+1}) - i(t_k)|``: the sensor noise a real
        current never falls below (:data:`NOISE_FACTOR`).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> rec = Recording(time=[0.0, 0.01], q=[[0.0], [1.0]], qd=[[0.0], [0.5]],
    ...                 current=[[-2.0], [3.0]])
    >>> signal_ranges([rec])["current"]
    [[-2.0], [3.0]]
    """
    out = {} if ranges is None else {k: [list(v[0]), list(v[1])] if k in RANGE_FIELDS else v
                                     for k, v in ranges.items()}
    for rec in recordings:
        out.setdefault("units", rec.units)
        for field in RANGE_FIELDS:
            values = np.where(np.isfinite(getattr(rec, field)), getattr(rec, field), np.nan)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                low, high = np.nanmin(values, axis=0), np.nanmax(values, axis=0)
            if field in out:
                low = np.fmin(low, out[field][0])
                high = np.fmax(high, out[field][1])
            out[field] = [[float(v) for v in low], [float(v) for v in high]]
        noise = _median_step(rec.current)
        if noise is not None:
            known = out.get("current_noise")
            out["current_noise"] = [float(v) for v in
                                    (noise if known is None else np.fmin(noise, known))]
    return out


def _median_step(current):
    """Per-joint median of ``|i(t_k+1) - i(t_k)|`` over the finite steps, or None."""
    steps = np.abs(np.diff(np.asarray(current, dtype=float), axis=0))
    if len(steps) < MIN_SAMPLES:
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        median = np.nanmedian(np.where(np.isfinite(steps), steps, np.nan), axis=0)
    return np.nan_to_num(median, nan=0.0)  # a joint without finite steps is not judged


class SignalCheck:
    """Plausibility of streamed signals, chunk by chunk, against what the model knows.

    Feed samples with :meth:`update` (one sample or a chunk of rows, in
    time order; the state carried between chunks is a few arrays per joint,
    so memory does not grow with the recording), then read
    :meth:`findings`. The checks are those of the module docstring; each
    needs only what is given (no ``ranges``: no range or prediction check;
    no ``predicted`` in :meth:`update`: no prediction check).

    Parameters
    ----------
    n_joints : int
        Joints of the samples.
    ranges : dict or None, default=None
        :func:`signal_ranges` of the data the model knows.
    position_limits : array-like of shape (2, n_joints) or None, default=None
        The robot's ``[lower, upper]`` joint limits [rad].
    current_limits : array-like of shape (n_joints,) or None, default=None
        The drives' largest ``|current|`` (in the recording's units).
    sample_time : float or None, default=None
        The detector's sample time [s].
    thresholds : array-like of shape (n_joints,) or None, default=None
        The detector's loosest alarm threshold per joint (in the current's
        units): a ratio ``i / i_hat`` counts against the signal only where
        ``|i - i_hat|`` exceeds it, where it would change the answer (a
        model that errs where its thresholds allow is not a wrong column).
    labels : dict or None, default=None
        Column labels per field (``{"q": ["'q_0'", ...]}``) for the
        sentences; default ``q[0]``, ``current[2]``, ...

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(500) * 0.01
    >>> q = np.c_[np.sin(t), np.full(500, -1.5)]
    >>> qd = np.c_[np.cos(t), np.zeros(500)]
    >>> check = SignalCheck(2)
    >>> check.update(t, q, qd, np.zeros((500, 2))).findings()
    []
    >>> [f.columns for f in SignalCheck(2).update(t, qd, q, np.zeros((500, 2))).findings()]
    [['q[0]', 'qd[0]'], ['q[1]', 'qd[1]']]
    """

    def __init__(self, n_joints, *, ranges=None, position_limits=None, current_limits=None,
                 sample_time=None, thresholds=None, labels=None):
        self.n_joints = n_joints
        self.ranges = ranges
        self.thresholds = thresholds
        self.position_limits = position_limits
        self.current_limits = current_limits
        self.sample_time = sample_time
        self.labels = labels
        self.reset()

    def reset(self):
        """Forget every sample (a new recording or window); returns self."""
        n = self.n_joints
        zeros = lambda: np.zeros(n)  # noqa: E731
        self.n_samples = 0
        self._last = None  # (t, q, qd) of the last sample
        self._step = None  # typical time step [s]
        self._block = [zeros(), zeros(), 0.0]  # A, B, seconds of the open block
        self._travel = {"q": zeros(), "qd": zeros(), "gap": zeros()}
        self._n_blocks = 0
        self._log_dt = [0.0, 0]
        self._outside = {f: zeros() for f in RANGE_FIELDS}
        self._beyond = {"limits": zeros(), "gross": zeros(), "drive": zeros()}
        self._peak = {f: zeros() for f in ("q", "current")}
        self._ratio = {"n": zeros(), "agree": zeros(), "opposite": zeros(), "log": zeros(),
                       "fed": 0}
        # position span against the path its velocity allows; the position step
        self._span = [np.full(n, np.inf), np.full(n, -np.inf)]
        self._path = zeros()
        self._q_step = np.full(n, np.inf)
        # current steps below the known noise; clipped residuals per (column, joint)
        self._last_current = None
        self._quiet = [zeros(), 0]
        self._residual = [np.zeros((n, n)), 0]
        return self

    # ------------------------------------------------------------ feeding
    def update(self, time, q, qd, current, predicted=None):
        """Add one sample (1-D arrays) or a chunk of rows (2-D); returns self.

        Parameters
        ----------
        time : float or ndarray of shape (n,)
        q, qd, current : ndarray of shape (n_joints,) or (n, n_joints)
        predicted : ndarray like ``current`` or None, default=None
            The model's prediction of ``current`` for the same samples; NaN
            rows are left out of the prediction check (predict every k-th
            row of a long recording).

        Returns
        -------
        self : SignalCheck
        """
        time = np.atleast_1d(np.asarray(time, dtype=float))
        q, qd, current = (np.asarray(v, dtype=float).reshape(len(time), -1)
                          for v in (q, qd, current))
        ok = np.isfinite(time) & np.isfinite(q).all(1) & np.isfinite(qd).all(1) \
            & np.isfinite(current).all(1)
        time, q, qd, current = time[ok], q[ok], qd[ok], current[ok]
        if predicted is not None:
            predicted = np.asarray(predicted, dtype=float).reshape(len(ok), -1)[ok]
        if not len(time):
            return self
        self.n_samples += len(time)
        self._velocity(time, q, qd)
        self._magnitudes(q, qd, current)
        self._current_steps(current)
        if predicted is not None and self.ranges is not None:
            self._prediction(current, predicted)
            self._residuals(current, predicted)
        return self

    def _current_steps(self, current):
        """Count the current steps below 1 / NOISE_FACTOR of the noise the model knows."""
        noise = (self.ranges or {}).get("current_noise")
        joined = current if self._last_current is None else np.r_[[self._last_current], current]
        self._last_current = current[-1].copy()
        if noise is None or len(joined) < 2:
            return
        floor = np.asarray(noise, dtype=float) / NOISE_FACTOR
        self._quiet[0] += (np.abs(np.diff(joined, axis=0)) < floor).sum(0)
        self._quiet[1] += len(joined) - 1

    def _residuals(self, current, predicted):
        """Clipped ``|i_a - i_hat_b| / s_b`` summed for every column ``a`` and joint ``b``.

        ``s_b`` is the detector's loosest threshold of joint ``b`` (without one,
        the span of the training currents): the cost of reading column ``a``
        as joint ``b``'s current.
        """
        rows = np.isfinite(predicted).all(1)
        if not rows.any():
            return
        if self.thresholds is not None:
            scale = np.asarray(self.thresholds, dtype=float)
        else:
            low, high = (np.asarray(v, dtype=float) for v in self.ranges["current"])
            scale = high - low
        scale = np.where(np.isfinite(scale) & (scale > 0), scale, np.inf)
        gap = np.abs(current[rows][:, :, None] - predicted[rows][:, None, :]) / scale
        self._residual[0] += np.minimum(gap, RESIDUAL_CAP).sum(0)
        self._residual[1] += int(rows.sum())

    def _velocity(self, time, q, qd):
        """Blocks of position change against integrated velocity; time steps."""
        if self._last is not None:
            time, q, qd = (np.r_[[last], now] for last, now in zip(self._last, (time, q, qd)))
        self._last = (time[-1], q[-1].copy(), qd[-1].copy())
        self._span = [np.fmin(self._span[0], q.min(0)), np.fmax(self._span[1], q.max(0))]
        if len(time) < 2:
            return
        dt = np.diff(time)
        moves = np.abs(np.diff(q, axis=0))
        self._q_step = np.fmin(self._q_step, np.where(moves > 0, moves, np.inf).min(0))
        if self._step is None:
            self._step = float(self.sample_time or np.median(dt[dt > 0]) if (dt > 0).any()
                               else 0.0) or None
            if self._step is None:
                return
        steady = (dt > 0) & (dt <= GAP_WARNING_FACTOR * self._step)
        # the path |qd| allows (across a gap: the position's own step, nothing to judge)
        speed = 0.5 * (np.abs(qd[1:]) + np.abs(qd[:-1])) * dt[:, None]
        self._path += np.where(steady[:, None], speed, moves).sum(0)
        if steady.any():
            self._log_dt[0] += float(np.log(dt[steady]).sum())
            self._log_dt[1] += int(steady.sum())
        dq = np.where(steady[:, None], np.diff(q, axis=0), 0.0)
        v = np.where(steady[:, None], 0.5 * (qd[1:] + qd[:-1]) * dt[:, None], 0.0)
        # blocks of BLOCK_SECONDS: the open block's sums carried across chunks
        elapsed = self._block[2] + np.cumsum(np.where(steady, dt, 0.0))
        block = np.floor(elapsed / BLOCK_SECONDS).astype(int)
        n_closed = int(block[-1])
        # only the blocks that hold samples (and the carried open one, 0) are summed:
        # memory bounded by the chunk, however long the stamps say it lasted
        occupied = np.unique(np.r_[0, block])
        sums_q = np.zeros((len(occupied), self.n_joints))
        sums_v = np.zeros_like(sums_q)
        rows = np.searchsorted(occupied, block)
        np.add.at(sums_q, rows, dq)
        np.add.at(sums_v, rows, v)
        sums_q[0] += self._block[0]
        sums_v[0] += self._block[1]
        closed_q, closed_v = sums_q[:-1], sums_v[:-1]
        self._travel["q"] += np.abs(closed_q).sum(0)
        self._travel["qd"] += np.abs(closed_v).sum(0)
        self._travel["gap"] += np.abs(closed_q - closed_v).sum(0)
        self._n_blocks += n_closed
        self._block = [sums_q[-1], sums_v[-1], float(elapsed[-1] - n_closed * BLOCK_SECONDS)]

    def _magnitudes(self, q, qd, current):
        """Counts beyond the training ranges, the robot's limits and absurd currents."""
        with np.errstate(over="ignore", invalid="ignore"):
            self._peak["q"] = np.fmax(self._peak["q"], np.abs(q).max(0))
            self._peak["current"] = np.fmax(self._peak["current"], np.abs(current).max(0))
            if self.ranges is not None:
                for field, values in zip(RANGE_FIELDS, (q, qd, current)):
                    low, high = (np.asarray(v, dtype=float) for v in self.ranges[field])
                    slack = np.maximum(RANGE_SLACK * (high - low), RANGE_FLOOR[field])
                    self._outside[field] += ((values < low - slack)
                                             | (values > high + slack)).sum(0)
                low, high = (np.asarray(v, dtype=float) for v in self.ranges["current"])
                peak = np.maximum(np.abs(low), np.abs(high))
                self._beyond["gross"] += (np.abs(current) > GROSS_FACTOR * peak).sum(0)
            if self.position_limits is not None:
                low, high = np.asarray(self.position_limits, dtype=float)
                self._beyond["limits"] += ((q < low - LIMIT_SLACK)
                                           | (q > high + LIMIT_SLACK)).sum(0)
            if self.current_limits is not None:
                self._beyond["drive"] += (np.abs(current)
                                          > np.asarray(self.current_limits, dtype=float)).sum(0)

    def _prediction(self, current, predicted):
        """Ratios ``i / i_hat`` where the prediction is large enough to judge."""
        low, high = (np.asarray(v, dtype=float) for v in self.ranges["current"])
        floor = PREDICTION_FLOOR * np.maximum(np.abs(low), np.abs(high))
        self._ratio["fed"] += int(np.isfinite(predicted).all(1).sum())
        usable = np.isfinite(predicted) & (np.abs(predicted) >= floor) & (floor > 0)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            ratio = np.where(usable, current / np.where(usable, predicted, 1.0), np.nan)
            size = np.log(np.abs(ratio))
            if self.thresholds is not None:  # within the thresholds: the answer stands
                within = np.abs(current - predicted) <= np.asarray(self.thresholds, dtype=float)
                ratio = np.where(within, 1.0, ratio)
        self._ratio["n"] += usable.sum(0)
        self._ratio["agree"] += (ratio < RATIO_BAND).sum(0) - (ratio <= -1 / RATIO_BAND).sum(0)
        self._ratio["opposite"] += (ratio <= -1 / RATIO_BAND).sum(0)
        self._ratio["log"] += np.where(usable & np.isfinite(size), size, 0.0).sum(0)

    # ------------------------------------------------------------ verdicts
    def _label(self, field, j):
        labels = (self.labels or {}).get(field)
        return labels[j] if labels is not None else f"{field}[{j}]"

    def findings(self):
        """What is implausible in the samples fed since :meth:`reset`.

        Returns
        -------
        findings : list of Finding
            Errors first, then warnings; empty when all is plausible.
        """
        found = [self._time_finding(), *self._velocity_findings(), *self._frozen_findings(),
                 *self._current_findings(), *self._quiet_findings(),
                 self._permutation_finding(), *self._range_findings()]
        found = [f for f in found if f is not None]
        return sorted(found, key=lambda f: f.severity != "error")

    def statistics(self):
        """How near each column check is to its verdict, for choosing and auditing limits.

        Returns
        -------
        statistics : dict
            ``"quiet_share"``: per joint, the share of current steps below
            the noise floor (reported above :data:`QUIET_SHARE`);
            ``"span_steps"``: per joint, the span of ``q`` beyond
            :data:`SPAN_FACTOR` times its velocity's path, in position steps
            (reported above :data:`FROZEN_STEPS`); ``"permutation_gain"``:
            what the best permutation of the current columns gains
            (reported above :data:`PERMUTATION_GAIN`). NaN where not judged.

        Examples
        --------
        >>> import numpy as np
        >>> t = np.arange(100) * 0.01
        >>> stats = SignalCheck(1).update(t, np.c_[t], np.c_[np.ones(100)],
        ...                               np.zeros((100, 1))).statistics()
        >>> stats["span_steps"]
        [0.0]
        """
        quiet, n = self._quiet
        span = self._span[1] - self._span[0]
        step = np.where(np.isfinite(self._q_step) & (self._q_step > 0), self._q_step, np.nan)
        with np.errstate(invalid="ignore"):
            beyond = np.maximum(span - SPAN_FACTOR * self._path, 0.0) / step
        beyond = np.where(np.isfinite(span) & (span == 0), 0.0, beyond)
        gain = self._permutation()[1]
        return {"quiet_share": [float(v) for v in (quiet / n if n else np.full(self.n_joints,
                                                                                np.nan))],
                "span_steps": [float(v) for v in beyond], "permutation_gain": gain}

    def _time_finding(self):
        total, n = self._log_dt
        if not self.sample_time or n < MIN_STEPS:
            return None
        typical = float(np.exp(total / n))
        factor = typical / self.sample_time
        if 1 / TIME_UNIT_FACTOR < factor < TIME_UNIT_FACTOR:
            return None
        cause = next((why for value, why in KNOWN_GAINS
                      if value / GAIN_TOLERANCE <= 1 / factor <= value * GAIN_TOLERANCE),
                     "the time column is in another unit than seconds")
        return Finding("time", ["time"], "error",
                       f"time steps of {typical:.4g} are {factor:.4g} times the detector's "
                       f"sample time {self.sample_time:.4g} s; {cause}.")

    def _velocity_findings(self):
        if self._n_blocks < 2:
            return []
        travel_q, travel_v, gap = self._travel["q"], self._travel["qd"], self._travel["gap"]
        allowed = TRAVEL_TOLERANCE * np.maximum(travel_q, travel_v) \
            + BLOCK_NOISE * self._n_blocks
        out = []
        for j in np.flatnonzero(gap > allowed):
            gain = travel_q[j] / travel_v[j] if travel_v[j] > 0 else np.inf
            cause = next((why for value, why in KNOWN_GAINS
                          if value / GAIN_TOLERANCE <= gain <= value * GAIN_TOLERANCE), None)
            if cause is None and gain < 1 / GAIN_TOLERANCE:
                cause = (f"qd integrates to {travel_v[j]:.3g} rad of travel where q moves "
                         f"{travel_q[j]:.3g} rad: q and qd swapped, or q scaled down")
            elif cause is None:
                cause = "q, qd or time are in other units than rad, rad/s and s"
            cols = [self._label("q", j), self._label("qd", j)]
            out.append(Finding("units", cols, "error",
                               f"{cols[0]} and {cols[1]} disagree: position steps are "
                               f"{gain:.4g} times the velocity times the time step (1 "
                               f"expected); {cause}."))
        return out

    def _frozen_findings(self):
        """A position that moved further than its velocity allows (qd scaled down)."""
        span = self._span[1] - self._span[0]
        step = np.where(np.isfinite(self._q_step), self._q_step, 0.0)
        out = []
        for j in np.flatnonzero(np.isfinite(span) & (span > SPAN_FACTOR * self._path
                                                     + FROZEN_STEPS * step) & (span > 0)):
            cols = [self._label("q", j), self._label("qd", j)]
            out.append(Finding("units", cols, "error",
                               f"{cols[0]} spans {span[j]:.4g} rad ({span[j] / step[j]:.0f} of "
                               f"its smallest steps) but {cols[1]} allows a path of "
                               f"{self._path[j]:.3g} rad (the integral of |qd| dt): the "
                               "velocity is scaled down (x0.001?) or frozen, or is not the "
                               f"velocity of {cols[0]}."))
        return out

    def _quiet_findings(self):
        """Currents that vary less than the sensor noise the model's data show."""
        quiet, n = self._quiet
        noise = (self.ranges or {}).get("current_noise")
        if noise is None or n < MIN_SAMPLES:
            return []
        units = self.ranges.get("units", "A")
        out = []
        for j in np.flatnonzero(quiet > QUIET_SHARE * n):
            col = self._label("current", j)
            out.append(Finding("current", [col], "error",
                               f"{col} changes by less than {noise[j] / NOISE_FACTOR:.3g} "
                               f"{units} from one sample to the next on {100 * quiet[j] / n:.0f} "
                               f"% of the samples, where the recordings the model knows "
                               f"never fall below a median of {noise[j]:.3g} {units} (sensor "
                               "noise): a current scaled down (x0.001?) or frozen, or "
                               "another signal."))
        return out

    def _permutation(self):
        """The best permutation of the current columns and what it gains (NaN: none)."""
        total, n = self._residual
        if n < MIN_SAMPLES:
            return np.arange(self.n_joints), float("nan")
        cost = total / n
        best = _best_assignment(cost)
        return best, float(np.trace(cost) - cost[np.arange(len(best)), best].sum())

    def _permutation_finding(self):
        """Current columns that match the model's prediction far better permuted."""
        best, gain = self._permutation()
        moved = np.flatnonzero(best != np.arange(len(best)))
        if not gain > PERMUTATION_GAIN or not moved.size:
            return None
        cols = [self._label("current", j) for j in moved]
        pairs = ", ".join(f"{self._label('current', j)} as joint {best[j]}" for j in moved)
        return Finding("current", cols, "error",
                       f"{', '.join(cols)} match the model's prediction far better permuted "
                       f"({pairs}): the mean clipped residual falls by {gain:.2f} "
                       "thresholds; current columns swapped?")

    def _current_findings(self):
        out = []
        units = (self.ranges or {}).get("units", "A")
        for j in range(self.n_joints):
            col = self._label("current", j)
            if self._beyond["gross"][j] or self._beyond["drive"][j]:
                peak = self._peak["current"][j]
                what = ("the drive's limit" if self._beyond["drive"][j] else
                        f"{GROSS_FACTOR:g} times the largest of the training data")
                out.append(Finding("current", [col], "error",
                                   f"{col} reaches |i| = {peak:.4g} {units}, beyond {what}: "
                                   "a scaled column (mA? x1000, x57.3) or another signal."))
                continue
            n = self._ratio["n"][j]
            if n < max(MIN_SAMPLES, PREDICTION_SHARE * self._ratio["fed"]) \
                    or self._ratio["agree"][j] >= 0.5 * n:
                continue
            if self._ratio["opposite"][j] >= 0.5 * n:
                how = "has the opposite sign of the model's prediction (a current x-1?)"
            else:  # larger: a model that errs near a pose gives smaller ratios, not this
                how = (f"is about {float(np.exp(self._ratio['log'][j] / n)):.3g} times the "
                       "model's prediction (a scaled column?)")
            out.append(Finding("current", [col], "error",
                               f"{col} {how} on {100 * (1 - self._ratio['agree'][j] / n):.0f} "
                               f"% of {int(n)} samples where the model predicts a clear "
                               "current; a collision moves a few samples, not most."))
        return out

    def _range_findings(self):
        out = []
        units = (self.ranges or {}).get("units", "A")
        if self.position_limits is not None:
            low, high = np.asarray(self.position_limits, dtype=float)
            for j in np.flatnonzero(self._beyond["limits"]):
                col = self._label("q", j)
                out.append(Finding("limits", [col], "error",
                                   f"{col} goes beyond the robot's joint limits [{low[j]:.4g}, "
                                   f"{high[j]:.4g}] rad (|q| up to {self._peak['q'][j]:.4g}): "
                                   "degrees, or another column."))
        if self.ranges is None or self.n_samples < MIN_SAMPLES:
            return out
        for field, unit in (("q", "rad"), ("qd", "rad/s"), ("current", units)):
            low, high = self.ranges[field]
            share = self._outside[field] / self.n_samples
            for j in np.flatnonzero(share > RANGE_FRACTION[field]):
                col = self._label(field, j)
                out.append(Finding("range", [col], "warning",
                                   f"{col} is outside the range the model knows [{low[j]:.4g}, "
                                   f"{high[j]:.4g}] {unit} on {100 * share[j]:.0f} % of the samples: the "
                                   "model extrapolates there (or the column is scaled or "
                                   "swapped)."))
        return out


def _best_assignment(cost):
    """The permutation ``p`` minimizing ``sum_a cost[a, p[a]]``: every permutation up to
    :data:`MAX_PERMUTED_JOINTS` joints, else the best single swap of two columns."""
    n = len(cost)
    if n <= MAX_PERMUTED_JOINTS:
        perms = np.array(list(itertools.permutations(range(n))))
        return perms[np.argmin(cost[np.arange(n), perms].sum(1))]
    best, gain = np.arange(n), 0.0
    for a, b in itertools.combinations(range(n), 2):
        change = cost[a, b] + cost[b, a] - cost[a, a] - cost[b, b]
        if change < gain:
            best, gain = np.arange(n), change
            best[[a, b]] = [b, a]
    return best


def units_note(time, q, qd, q_labels):
    """Sentence when q, qd and time disagree (:class:`SignalCheck`), else None.

    Parameters
    ----------
    time : ndarray of shape (n,)
    q, qd : ndarray of shape (n, n_joints)
    q_labels : list of str
        Column labels of ``q`` for the message.

    Returns
    -------
    note : str or None
        The sentences of the ``"units"`` findings of :class:`SignalCheck`.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(300) * 0.01
    >>> units_note(t * 1000, np.sin(t)[:, None], np.cos(t)[:, None], ["'q'"])[-52:]
    'time looks like milliseconds (pass time_scale=1e-3).'
    """
    n_joints = q.shape[1]
    labels = {"q": list(q_labels), "qd": [f"qd[{j}]" for j in range(n_joints)]}
    check = SignalCheck(n_joints, labels=labels)
    check.update(time, q, qd, np.zeros_like(q))
    # the block test only: a reader keeps a spike the user let through
    # (max_joint_speed=None), which the span against the velocity's path would name
    notes = [f.sentence for f in check._velocity_findings()]
    return " ".join(notes) or None

#: Shortest recording [s] :func:`recording_problems` accepts by default.
MIN_DURATION = 1.0


def recording_problems(recording, min_duration=MIN_DURATION):
    """What makes a loaded recording suspect: degrees, other time units, too short.

    A reader only warns about these (:class:`~sklearn_gpcd.io.RecordingWarning`);
    a caller that should not go on (the ``gpcd`` command) turns them into
    errors unless the user confirms.

    Parameters
    ----------
    recording : Recording
    min_duration : float, default=1.0
        Shortest duration [s] that is not reported.

    Returns
    -------
    problems : list of (str, str)
        ``(kind, sentence)`` with kind ``"degrees"`` (:func:`degrees_note`),
        ``"units"`` (:func:`units_note`: milliseconds, deg/s, ...) or
        ``"short"``.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> t = np.arange(5) * 0.01
    >>> rec = Recording(time=t, q=np.full((5, 1), 90.0), qd=np.zeros((5, 1)),
    ...                 current=np.zeros((5, 1)))
    >>> [kind for kind, _ in recording_problems(rec)]
    ['degrees', 'short']
    """
    q_labels = [f"q[{j}]" for j in range(recording.n_joints)]
    units = units_note(recording.time, recording.q, recording.qd, q_labels)
    notes = {"degrees": [degrees_note(recording.q)], "units": [], "short": []}
    notes["degrees" if units and "deg" in units.rpartition(";")[2] else "units"].append(units)
    if recording.duration < min_duration:
        notes["short"].append(f"{recording.n_samples} samples over {recording.duration:.3g} "
                              f"s, shorter than {min_duration:g} s.")
    return [(kind, " ".join(n for n in found if n)) for kind, found in notes.items()
            if any(found)]
