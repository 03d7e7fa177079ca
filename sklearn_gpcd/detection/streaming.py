"""Tick-by-tick collision monitoring with bounded memory."""

import warnings
from enum import Enum

import numpy as np
from scipy.signal import lfilter_zi
from sklearn.utils import Bunch
from sklearn.utils.validation import check_is_fitted

from ..layout import column_names
from .._persistence import VersionedStateMixin
from ..features.inputs import as_recordings
from ..gp import compile_predictor
from ._regimes import MOVING, AlarmState, EventHold, ratio_over_level
from .detector import _SAMPLE_TIME_RTOL, SampleTimeWarning, reads_currents
from .task import TaughtTask


class MonitorStatus(str, Enum):
    """Outcome of one :meth:`StreamingMonitor.update` call.

    - ``OK`` (``"ok"``): a valid sample, no joint fired.
    - ``COLLISION`` (``"collision"``): a valid sample and at least one joint
      fired (``monitor.alarms`` tells which); batch ``predict`` gives -1.
    - ``SENSOR_FAULT`` (``"sensor_fault"``): the sample could not be used
      and is skipped: neither a collision nor an all-clear.

    Members compare equal to their string values, and ``str(status)`` is the
    value, so arrays and logs of statuses keep it whole.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.detection import MonitorStatus
    >>> MonitorStatus.COLLISION == "collision"
    True
    >>> MonitorStatus("sensor_fault") is MonitorStatus.SENSOR_FAULT
    True
    >>> str(MonitorStatus.OK)
    'ok'
    >>> np.asarray([MonitorStatus.OK, MonitorStatus.SENSOR_FAULT]).tolist()
    ['ok', 'sensor_fault']
    """

    OK = "ok"
    COLLISION = "collision"
    SENSOR_FAULT = "sensor_fault"

    def __str__(self):
        return self.value


def _numbers(value, name):
    """``value`` as a float array (None entries become NaN); ValueError if not numeric."""
    if isinstance(value, np.ndarray) and value.dtype.kind in "fiub":
        return value  # the per-tick path: no conversion, no allocation
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must hold numbers (NaN or None when missing): {exc}") from None


def _time_stamp(time):
    """``time`` as a float, or None; ValueError when it is not a number."""
    if time is None:
        return None
    try:
        return float(time)
    except (TypeError, ValueError):
        raise ValueError(f"time must be a number (seconds), got {time!r}") from None


def _filter_transition(coefficients):
    """One step of the detector's low-pass filter as a matrix, and its unit steady state.

    scipy's ``lfilter`` (direct form II transposed, ``a[0] = 1``, order
    ``N``) maps input ``u`` and state ``z`` to

    .. math::

        y = b_0 u + z_1, \\qquad
        z'_k = b_k u + z_{k+1} - a_k y = (b_k - a_k b_0)\\, u - a_k z_1 + z_{k+1}

    (``z_{N+1} = 0``), so ``[y; z'] = T [u; z]`` with the ``(N + 1) x (N +
    1)`` matrix ``T``: a filter step for every joint is one matrix product.
    Without a filter ``T = [[1]]`` (``y = u``, no state). Also returns the
    (N, 1) state of a filter at rest on a unit input (``lfilter_zi``).
    """
    if coefficients is None:
        return np.ones((1, 1)), np.zeros((0, 1))
    b, a = (np.asarray(c, dtype=float) for c in coefficients)
    order = len(b) - 1
    transition = np.zeros((order + 1, order + 1))
    transition[0, :2] = b[0], 1.0
    transition[1:, 0] = b[1:] - a[1:] * b[0]
    transition[1:, 1] = -a[1:]
    transition[1:-1, 2:] += np.eye(order - 1)
    return transition, lfilter_zi(b, a)[:, None]


def _frame_maker(detector):
    """Wrap a 2-D input block as the regressor saw it in fit (named or not)."""
    names = getattr(detector, "feature_names_in_", None)
    if names is None:
        return lambda block: block
    import pandas as pd  # the detector was fitted on a DataFrame

    columns = list(names[: -detector.n_joints])
    return lambda block: pd.DataFrame(block, columns=columns)


class BandState:
    """One alarm rule's causal state in a :class:`StreamingMonitor`.

    The low-pass filter as a state-space step, then the regimes, debounce
    and alarm of the batch detector's per-sample state, in preallocated
    arrays: a tick allocates nothing.

    Parameters
    ----------
    rule : AlarmRule
        Fitted (a detector's ``rules_[b]``).
    n_joints : int

    Attributes
    ----------
    signal : ndarray of shape (n_joints,)
        Monitoring signal ``m`` of the last valid tick.
    ratio : ndarray of shape (n_joints,)
        Debounced ``|m|`` over the scale of the current regime.
    alarms : ndarray of bool, shape (n_joints,)
        Joints that fired in this band.
    regime : int
        Regime code of the last valid tick (0 without regimes).
    level : float
        The rule's :math:`\\gamma`: the band fires where ``ratio > level``.
    thresholds : ndarray of shape (n_regimes, n_joints)
        The rule's thresholds, one row per regime.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.detection import AlarmRule
    >>> rule = AlarmRule("false_alarm_rate", false_alarm_rate=0.0).calibrate(
    ...     np.random.default_rng(0).normal(size=(500, 1)), sample_time=0.01)
    >>> band = BandState(rule, 1)
    >>> band.thresholds.shape, band.regime, band.alarms.tolist()
    ((1, 1), 0, [False])
    """

    #: Views rebuilt on load (see :meth:`_bind`).
    _REBUILT = ("_filter_flat", "_filter_in", "_filter_out", "_u", "_z", "signal", "_z_next",
                "ratio", "alarms")

    def __init__(self, rule, n_joints):
        self.rule = rule
        self.level = -float(rule.offset_)
        self.thresholds = np.atleast_2d(np.asarray(rule.thresholds_, dtype=float))
        self.state = AlarmState(n_joints, rule.regime_settings(), rule.scale_, self.level,
                                rule.min_duration)
        self._transition, self._zi_unit = _filter_transition(rule.filter_coefficients_)
        order = self._transition.shape[0] - 1
        # [u; z] -> [y; z']: filter input and state, output and next state
        self._filter = np.full((2, order + 1, n_joints), np.nan)
        self._filter_finite = np.empty(self._filter.size, dtype=bool)
        self._bind()
        self.reset()

    def __getstate__(self):
        state = self.__dict__.copy()
        for name in self._REBUILT:
            state.pop(name, None)
        return state

    def __setstate__(self, state):
        if state.get("_envelope") is not None:  # the ring of a band saved before issue 45
            raise ValueError("this monitor was saved with the motion envelope (gpcd calibrate "
                             "--motion-envelope), which was removed, and its thresholds hold "
                             "only with it: calibrate again with gpcd calibrate and start a "
                             "new monitor")
        self.__dict__.update(state)
        self._bind()

    def _bind(self):
        """The views a tick goes through: ``_filter[0]`` is ``[u; z]`` (input,
        state), ``_filter[1]`` ``[y; z']`` (``signal``, next state); one product
        with ``_transition`` is one filter step, ``z'`` becomes ``z`` on accept."""
        self._filter_flat = self._filter.reshape(-1)
        self._filter_in, self._filter_out = self._filter
        self._u, self._z = self._filter_in[0], self._filter_in[1:]
        self.signal, self._z_next = self._filter_out[0], self._filter_out[1:]
        self.ratio, self.alarms = self.state.ratio, self.state.alarms

    @property
    def regime(self):
        return self.state.regime

    @property
    def alarmed(self):
        return self.state.alarmed

    def reset(self):
        """Forget the filter, regime and debounce history."""
        self._fresh = True
        self.state.reset()

    def _filter_step(self, u):
        """Filter ``u`` (the residual, over the std with ``normalize="std"``), not
        yet accepted; whether input, output and state are finite."""
        np.copyto(self._u, u)
        if self._fresh:  # steady state of the first sample, as in batch
            np.multiply(self._zi_unit, self._u, out=self._z)
        np.matmul(self._transition, self._filter_in, out=self._filter_out)
        finite = np.isfinite(self._filter_flat, out=self._filter_finite)
        return np.count_nonzero(finite) == finite.size

    def _commit(self, motion):
        """Accept the tick filtered last (regime, debounce, ratio, alarms); the
        largest ratio over the joints. ``motion``: what the regimes read."""
        np.copyto(self._z, self._z_next)
        self._fresh = False
        return self.state.step(self.signal, motion)

    def _reject(self):
        """A rejected tick: no signal, no decision (the state is kept)."""
        self.signal[:] = np.nan
        self.ratio[:] = np.nan
        self.state.clear()

    def _non_finite_joints(self):
        """Joints whose filter input, output or state was not finite in the last step."""
        return np.flatnonzero(~np.all(np.isfinite(self._filter), axis=(0, 1)))


class StreamingMonitor(VersionedStateMixin):
    """Run a fitted :class:`CollisionDetector` one sample at a time.

    Each :meth:`update` takes one input row and the measured currents and
    makes the same decision as the detector's batch ``predict`` on the same
    rows (in order, ``groups`` restarts mapped to :meth:`reset`): residual,
    normalisation and, per alarm rule, filter, regimes, debounce and
    threshold are carried forward in preallocated state (one
    :class:`BandState` per rule, one prediction per tick for all). Memory is
    bounded and a tick allocates no array. The prediction is compiled once
    into a single-sample path (:func:`~sklearn_gpcd.gp.compile_predictor`);
    ``normalize="std"`` goes through ``regressor.predict(...,
    return_std=True)`` and is much slower.

    **Sensor faults.** A missing sample (``x=None``), a NaN or infinite
    value, a ``time`` not after the last valid sample's, or a non-finite
    prediction or signal makes :meth:`update` return
    ``MonitorStatus.SENSOR_FAULT`` (never ``COLLISION``, never an exception)
    and drop the sample, as if it had never arrived (a fault does not end an
    alarm either). A sample of the wrong length or with non-numeric values
    is a wiring error (``ValueError``, state unchanged). What a run of faults
    means is the caller's policy (user guide, streaming page).

    **Raw samples.** Given the fitted
    :class:`~sklearn_gpcd.features.CausalFeatures` that built the training
    inputs, :meth:`update_raw` builds the input row causally from what the
    robot logs; :meth:`replay_recording` equals ``detector.predict`` on
    ``stack_currents(features.transform(rec), rec.current)``.

    **A taught task.** Given a fitted :class:`TaughtTask` as ``detector``,
    each tick also runs its :class:`TaskStream` on the same prediction: where
    the arm moves through taught states ``alarms`` are the task's, elsewhere
    the bands' (``taught`` says which), as in
    :meth:`TaughtTask.monitoring_signal`.

    Parameters
    ----------
    detector : CollisionDetector or TaughtTask
        A fitted detector, or a task taught on one.
    features : CausalFeatures, default=None
        Fitted causal features, for :meth:`update_raw`.

    Attributes
    ----------
    status : MonitorStatus
        Status of the last tick (see :class:`MonitorStatus`).
    predicted : ndarray of shape (n_joints,)
        Predicted currents ``i_hat`` of the last valid tick.
    residual : ndarray of shape (n_joints,)
        ``s = i - i_hat``.
    bands : list of BandState
        One per alarm rule.
    signal, ratio, regime
        Those of the first band.
    alarms : ndarray of bool, shape (n_joints,)
        Joints that fired (in some band, or the taught task's where taught).
    task : TaughtTask or None
    taught : bool
        The last tick was decided by the taught task.
    score : float
        The batch ``score_samples`` value (``-max(ratio)`` with one band).
    n_ticks, n_faults : int
        Ticks seen and ticks rejected as sensor faults since construction.
    n_consecutive_faults : int
        Sensor faults since the last valid tick.
    fault_reason : str or None
        What made the last tick a sensor fault (e.g. ``"non-finite value in
        qd_1"``); None after a valid tick.
    last_time : float or None
        ``time`` of the last valid tick (None without time, or after
        :meth:`reset`).
    predictor_kind : str
        ``"gaussian_process"``, ``"linear"`` or ``"generic"``.

    The arrays are overwritten in place by every tick; copy them to keep
    them. After a sensor fault they hold NaN (``alarms`` all False).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.linear_model import LinearRegression
    >>> from sklearn_gpcd.detection import (CollisionDetector, StreamingMonitor,
    ...                                     stack_currents)
    >>> qd = np.linspace(-1, 1, 50)[:, None]
    >>> X = stack_currents(qd, 2.0 * qd[:, 0] + 0.01 * np.cos(40 * qd[:, 0]))
    >>> det = CollisionDetector(LinearRegression()).fit(X)
    >>> monitor = StreamingMonitor(det)
    >>> monitor.update([0.5], current=[1.0])
    <MonitorStatus.OK: 'ok'>
    >>> monitor.update([0.5], current=[3.0])     # 2 A more than expected
    <MonitorStatus.COLLISION: 'collision'>
    >>> monitor.update([np.nan], current=[1.0])
    <MonitorStatus.SENSOR_FAULT: 'sensor_fault'>
    >>> monitor.fault_reason
    'non-finite value in x[0]'
    >>> monitor.update([0.5], current=[1.0]) == "ok"     # recovered
    True
    """

    def __init__(self, detector, features=None):
        self.task = detector if isinstance(detector, TaughtTask) else None
        if self.task is not None:
            check_is_fitted(self.task, "coef_")
            detector = self.task.detector
        check_is_fitted(detector)
        self.detector = detector
        self.features = features
        n = self.n_joints = detector.n_joints
        self.n_inputs = detector.n_features_in_ - n
        self._row = np.empty(detector.n_features_in_)
        self._finite = np.empty(detector.n_features_in_, dtype=bool)
        self._wrap = _frame_maker(detector)
        _check_static_model(detector.regressor_)
        self._predictor = compile_predictor(
            detector.regressor_, self.n_inputs, n, wrap=self._wrap
        )
        self.predictor_kind = self._predictor.kind
        self._use_std = detector.normalize == "std"
        self._std_row = np.empty((1, self.n_inputs))
        self.std = np.ones(n)
        self._u = np.full(n, np.nan)
        self.residual = np.full(n, np.nan) if self._use_std else self._u
        self.bands = [BandState(rule, n) for rule in detector.rules_]
        self._events = EventHold(detector.rules_[0].event_hold_samples())
        self._motion = None
        if detector.motion_columns_ is not None:
            self._motion_columns = np.asarray(detector.motion_columns_, dtype=np.intp)
            self._motion = np.empty(self._motion_columns.size)
        self._online = None
        if features is not None:
            self._online = features.online()
            if self._online.row.shape[0] != self.n_inputs:
                raise ValueError(
                    f"features build {self._online.row.shape[0]} input columns but the "
                    f"detector's regressor takes {self.n_inputs}"
                )
            self._dt_sum, self._dt_count = 0.0, 0
        self.predicted = np.full(n, np.nan)
        self.alarms = (self.bands[0].alarms if len(self.bands) == 1 and self.task is None
                       else np.zeros(n, dtype=bool))
        self._task_stream = self.task.stream() if self.task is not None else None
        self.taught = False
        self._bind()
        self.score = np.nan
        self.status = None
        self.n_ticks = 0
        self.n_faults = 0
        self.n_consecutive_faults = 0
        self.fault_reason = None
        self.reset()

    #: A monitor saved before tasks could be taught runs untaught.
    task = None
    _task_stream = None
    taught = False
    #: Attributes rebuilt on load rather than stored: views into ``_row`` (a
    #: pickle would turn them into copies; see :meth:`_bind`), the compiled
    #: predictor and the first band's arrays.
    _REBUILT = ("_inputs", "_current", "signal", "ratio", "_wrap", "_predictor")
    #: Ticks after which update_raw compares the mean time step with sample_time_.
    _DT_CHECK_TICKS = 100

    def __getstate__(self):
        """State to pickle, without the views and the compiled predictor (rebuilt
        on load); ``status`` as its string value, which :mod:`skops.io` restores."""
        state = super().__getstate__()
        for name in self._REBUILT:
            state.pop(name, None)
        if not self._use_std:
            state.pop("residual")  # the same array as _u
        if len(self.bands) == 1 and self.task is None:
            state.pop("alarms")  # the first band's
        state["status"] = None if self.status is None else self.status.value
        return state

    def __setstate__(self, state):
        """Restore a pickled monitor; it resumes exactly where it was saved."""
        super().__setstate__(state)
        if self.status is not None:
            self.status = MonitorStatus(self.status)
        if not self._use_std:
            self.residual = self._u
        if len(self.bands) == 1 and self.task is None:
            self.alarms = self.bands[0].alarms
        self._bind()
        self._wrap = _frame_maker(self.detector)
        self._predictor = compile_predictor(
            self.detector.regressor_, self.n_inputs, self.n_joints, wrap=self._wrap
        )

    def _bind(self):
        """The views a tick reads and writes through (after construction or load)."""
        self._inputs = self._row[: self.n_inputs]
        self._current = self._row[self.n_inputs :]
        self.signal, self.ratio = self.bands[0].signal, self.bands[0].ratio

    @property
    def regime(self):
        return self.bands[0].regime

    @property
    def event(self):
        """Whether a contact event is open (:class:`EventHold`: on each joint's
        ratio over its band's level, or the taught task's)."""
        return self._events.open if self._task_stream is None else self._task_stream.event

    @property
    def event_onset(self):
        """Whether a contact event began at the last tick (:class:`EventHold`:
        a new event, or a new contact while one was open)."""
        return (self._events.onset if self._task_stream is None
                else self._task_stream.event_onset)

    @property
    def taught_joints(self):
        """Per joint, whether the taught task decided it at the last tick."""
        if self._task_stream is None:
            return np.zeros(self.n_joints, dtype=bool)
        return np.asarray(self._task_stream.joints, dtype=bool)

    @property
    def applied_thresholds(self):
        """Per joint, the threshold [A] that decided the last tick: the taught
        task's where its joint was taught, else the first band's in its regime
        (what ``protected_force`` turns into N at the tool)."""
        general = np.asarray(self.bands[0].thresholds[self.bands[0].regime], dtype=float)
        if self._task_stream is None:
            return general
        return np.where(self._task_stream.joints, self.task.thresholds_, general)

    @property
    def task_signal(self):
        """The taught task's filtered residual of the last tick [A] (None untaught)."""
        return None if self._task_stream is None else self._task_stream.signal

    def reset(self):
        """Forget the filter and debounce history and the last time stamp.

        Call it where a new recording starts (the batch ``groups``) or after
        a long outage; the counters keep running.
        """
        self.last_time = None
        self._events.step(0.0, restart=True)
        for band in self.bands:
            band.reset()
        if self._task_stream is not None:
            self._task_stream.reset()
        if self._online is not None:
            self._online.reset()

    def update(self, x, current=None, time=None):
        """Process one sample.

        Parameters
        ----------
        x : array-like of shape (n_inputs + n_joints,) or (n_inputs,), or None
            One row of the detector's input (the regressor inputs only when
            ``current`` is given). None marks a missing sample, NaN (or
            None) a missing value.
        current : array-like of shape (n_joints,), default=None
            Measured currents, when not included in ``x``.
        time : float, default=None
            Time stamp [s]; a stamp not after the last valid sample's (a
            duplicated or out-of-order packet) is a sensor fault, a gap is not.

        Returns
        -------
        status : MonitorStatus

        Raises
        ------
        ValueError
            A wiring error, not a sensor fault (state unchanged): ``x`` or
            ``current`` of the wrong length or not numeric, ``time`` not a
            number.
        """
        if x is not None:
            self._load(x, current)
        stamp = _time_stamp(time)
        self.n_ticks += 1
        if x is None:
            return self._fault("missing sample (x is None)")
        if stamp is not None and (reason := self._time_fault(stamp)):
            return self._fault(reason)
        if np.count_nonzero(np.isfinite(self._row, out=self._finite)) < self._row.size:
            return self._fault(self._non_finite_reason())
        self._predictor.predict_one(self._inputs, self.predicted)
        if self._use_std:
            np.subtract(self._current, self.predicted, out=self.residual)
            self._std_row[0] = self._inputs
            _, std = self.detector.regressor_.predict(
                self._wrap(self._std_row), return_std=True
            )
            np.maximum(np.reshape(std, (self.n_joints,)), np.finfo(float).tiny, out=self.std)
            np.divide(self.residual, self.std, out=self._u)
        else:
            np.subtract(self._current, self.predicted, out=self._u)  # the residual
        # u, z, y and z' finite in every band (u holds the residual: the prediction too)
        if not all([band._filter_step(self._u) for band in self.bands]):
            return self._fault(self._signal_reason())  # no band's state moves
        if self._motion is not None:
            np.take(self._inputs, self._motion_columns, out=self._motion, mode="clip")
        if len(self.bands) == 1:
            band = self.bands[0]
            top = band._commit(self._motion)
            self.score = -top
            alarmed = band.alarmed
        else:
            tops = [band._commit(self._motion) for band in self.bands]
            self.score = min([band.level - top for band, top in zip(self.bands, tops)])
            np.logical_or.reduce([band.alarms for band in self.bands], out=self.alarms)
            alarmed = any(band.alarmed for band in self.bands)
        over = ratio_over_level(self.bands)
        self._events.step(over)
        if self._task_stream is not None:
            alarmed = self._taught_step(over)
        self.last_time = stamp
        self.n_consecutive_faults = 0
        self.fault_reason = None
        self.status = MonitorStatus.COLLISION if alarmed else MonitorStatus.OK
        return self.status

    def _taught_step(self, over):
        """The taught decision of this tick (:class:`TaskStream`): the task's
        thresholds where the arm moves through taught states, the bands' elsewhere."""
        general = self.bands[0].alarms if len(self.bands) == 1 else self.alarms
        alarm, self.taught = self._task_stream.step(
            self._inputs, self._current, general, over,
            moving=self.regime == MOVING, predicted=self.predicted)
        self.alarms[:] = alarm
        return bool(alarm.any())

    def update_raw(self, time, q, qd, current, target_q=None, target_qd=None,
                   target_current=None):
        """Process one raw robot sample (needs ``features``).

        Parameters
        ----------
        time : float
            Time stamp [s].
        q, qd, current : array-like of shape (n_joints,)
            Measured positions, velocities and motor currents.
        target_q, target_qd, target_current : array-like of shape (n_joints,), default=None
            Controller signals, required when the features were fitted with
            them (``features.signals_``).

        Returns
        -------
        status : MonitorStatus

        Raises
        ------
        ValueError
            Without ``features``, or without a signal the model was trained
            on (a wiring error, not a sensor fault).
        """
        if self._online is None:
            raise ValueError(
                "update_raw needs StreamingMonitor(detector, features=CausalFeatures(...)"
                ".fit(recordings)); use update() for ready-made input rows"
            )
        signals = {"target_q": target_q, "target_qd": target_qd,
                   "target_current": target_current}
        values = [time, q, qd, current, *(signals[s] for s in self._online.signals)]
        if any(v is None for v in values[:4]) or not all(
            np.isfinite(_numbers(v, "sample")).all() for v in values
        ):
            for name in self._online.signals:
                if signals[name] is None:
                    raise ValueError(
                        f"{name} is missing, but the model was trained with it; pass it, "
                        "or train the model without it: gpcd train ... --signals none"
                    )
            self.n_ticks += 1
            return self._fault("missing or non-finite value in the raw sample")
        stamp = float(time)
        if (reason := self._time_fault(stamp)):
            self.n_ticks += 1
            return self._fault(reason)
        last = self._online.last_time
        row = self._online.step(stamp, q, qd, **{s: signals[s] for s in self._online.signals})
        if last is not None:
            self._check_time_step(stamp - last)
        return self.update(row, current, stamp)

    def _check_time_step(self, dt):
        """Warn once when the mean step of the first ticks is off sample_time_."""
        if self._dt_count >= self._DT_CHECK_TICKS:
            return
        self._dt_sum += dt
        self._dt_count += 1
        if self._dt_count == self._DT_CHECK_TICKS:
            mean = self._dt_sum / self._dt_count
            expected = self.detector.sample_time_
            if abs(mean - expected) > _SAMPLE_TIME_RTOL * mean:
                warnings.warn(
                    f"the stream's mean time step is {mean:g} s but the detector was "
                    f"calibrated with sample_time={expected:g} s: its filters, debounce and "
                    "delays are off by that ratio; calibrate it again on recordings at "
                    "this rate (gpcd calibrate)",
                    SampleTimeWarning, stacklevel=3,
                )

    def replay_recording(self, recordings):
        """Feed recordings through :meth:`update_raw`, sample by sample.

        :meth:`reset` is called at the start of each recording.

        Parameters
        ----------
        recordings : Recording or list of Recording
            Recordings with the signals the features were fitted with.

        Returns
        -------
        result : Bunch
            As :meth:`replay`.
        """
        if self._online is None:
            raise ValueError("replay_recording needs StreamingMonitor(detector, "
                             "features=CausalFeatures(...).fit(recordings)); use replay() "
                             "for ready-made input rows")
        recordings = as_recordings(recordings)
        signals = self._online.signals

        def ticks():
            for rec in recordings:
                self.reset()
                targets = {s: getattr(rec, s) for s in signals}
                for k in range(rec.n_samples):
                    yield self.update_raw(rec.time[k], rec.q[k], rec.qd[k], rec.current[k],
                                          **{s: v[k] for s, v in targets.items()})

        return self._record(ticks(), sum(rec.n_samples for rec in recordings))

    def _load(self, x, current):
        """Copy one sample into the preallocated row; ValueError on a wiring error."""
        if current is None:
            x = _numbers(x, "x")
            if x.shape != self._row.shape:
                raise ValueError(
                    f"x must have {self._row.shape[0]} values ({self.n_inputs} inputs + "
                    f"{self.n_joints} currents), got shape {x.shape}"
                )
            np.copyto(self._row, x)
            return
        x, current = _numbers(x, "x"), _numbers(current, "current")
        if x.shape != self._inputs.shape:
            raise ValueError(
                f"x must have {self.n_inputs} input values when current is given, "
                f"got shape {x.shape}"
            )
        if current.shape != self._current.shape:
            raise ValueError(
                f"current must have {self.n_joints} values, got shape {current.shape}"
            )
        np.copyto(self._inputs, x)
        np.copyto(self._current, current)

    def _time_fault(self, stamp):
        """Why time stamp ``stamp`` cannot be accepted, or None."""
        if not np.isfinite(stamp):
            return f"non-finite time {stamp!r}"
        if self.last_time is not None and stamp <= self.last_time:
            return f"time {stamp!r} is not after the last valid sample's {self.last_time!r}"
        return None

    def _column_name(self, index):
        """Name of column ``index`` of the detector input, for fault messages."""
        names = getattr(self.detector, "feature_names_in_", None)
        if names is not None:
            return str(names[index])
        if index >= self.n_inputs:
            return f"current[{index - self.n_inputs}]"
        if self.n_inputs in (3 * self.n_joints, 6 * self.n_joints):
            return column_names(self.n_joints, self.n_inputs == 6 * self.n_joints)[index]
        return f"x[{index}]"

    def _non_finite_reason(self):
        bad = np.flatnonzero(~self._finite)
        names = ", ".join(self._column_name(i) for i in bad[:4])
        more = f" and {bad.size - 4} more" if bad.size > 4 else ""
        return f"non-finite value in {names}{more}"

    def _signal_reason(self):
        """Why a tick with finite inputs gave a non-finite value: the first stage
        that did (prediction, std, residual, or a band's filter input, output or state)."""
        stages = (
            ("predicted", "predicted current"),
            ("std", "predictive std"),
            ("residual", "residual"),
            ("_u", "monitoring signal"),
        )
        for name, label in stages:
            bad = np.flatnonzero(~np.isfinite(getattr(self, name)))
            if bad.size:
                return f"non-finite {label} of joint(s) {bad.tolist()}"
        bad = np.unique(np.concatenate([band._non_finite_joints() for band in self.bands]))
        return f"non-finite monitoring signal of joint(s) {bad.tolist()}"

    def _fault(self, reason):
        self.n_faults += 1
        self.n_consecutive_faults += 1
        self.fault_reason = reason
        for array in (self.predicted, self.residual):
            array[:] = np.nan
        for band in self.bands:
            band._reject()
        self.alarms[:] = False
        self.score = np.nan
        self.status = MonitorStatus.SENSOR_FAULT
        return self.status

    def replay(self, X, groups=None, time=None):
        """Feed the rows of ``X`` through :meth:`update`, one by one.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
            Rows in time order (NaN rows become sensor faults).
        groups : array-like of shape (n_samples,), default=None
            Recording id per row; :meth:`reset` is called where it changes,
            matching the batch detector's ``groups``.
        time : array-like of shape (n_samples,), default=None
            Time stamp per row, passed to :meth:`update` (rows whose stamp
            does not advance become sensor faults).

        Returns
        -------
        result : Bunch
            ``status`` (ndarray of str), ``prediction`` (+1 / -1 as
            ``predict``, 0 for sensor faults), ``alarms`` (bool, (n_samples,
            n_joints)), ``score`` (the batch ``score_samples``), ``predicted``
            and ``residual``; ``bands``, one Bunch per rule with its
            ``signal``, ``ratio``, ``alarms``, ``regime`` and ``level``, the
            first band's ``signal``, ``ratio`` and ``regime`` also at the top
            level; ``taught`` (bool, rows the taught task decided),
            ``event`` (rows of an open contact event) and ``thresholds``
            (:attr:`applied_thresholds` per row). Sensor
            faults leave NaN float rows and no alarm.
        """
        X = np.asarray(X, dtype=float)
        n = X.shape[0]
        groups = None if groups is None else np.asarray(groups)
        if time is not None:
            time = np.asarray(time, dtype=float)
            if time.shape != (n,):
                raise ValueError(f"time must have shape ({n},), got {time.shape}")

        def ticks():
            for t in range(n):
                if groups is not None and t and groups[t] != groups[t - 1]:
                    self.reset()
                yield self.update(X[t], time=None if time is None else time[t])

        return self._record(ticks(), n)

    def _record(self, statuses, n):
        """Run the ticks of ``statuses`` (an iterator of n statuses); the replay Bunch."""
        shape = (n, self.n_joints)
        out = Bunch(status=np.empty(n, dtype=object), alarms=np.zeros(shape, dtype=bool),
                    score=np.empty(n), predicted=np.empty(shape), residual=np.empty(shape),
                    bands=[Bunch(signal=np.empty(shape), ratio=np.empty(shape),
                                 alarms=np.zeros(shape, dtype=bool),
                                 regime=np.zeros(n, dtype=np.intp), level=band.level)
                           for band in self.bands],
                    taught=np.zeros(n, dtype=bool), event=np.zeros(n, dtype=bool),
                    event_onset=np.zeros(n, dtype=bool), thresholds=np.empty(shape))
        for t, status in enumerate(statuses):
            out.status[t] = status.value
            out.alarms[t], out.score[t] = self.alarms, self.score
            out.predicted[t], out.residual[t] = self.predicted, self.residual
            out.taught[t], out.event[t] = self.taught, self.event
            out.event_onset[t] = self.event_onset
            out.thresholds[t] = self.applied_thresholds
            for record, band in zip(out.bands, self.bands):
                record.signal[t], record.ratio[t] = band.signal, band.ratio
                record.alarms[t], record.regime[t] = band.alarms, band.regime
        out.status = out.status.astype(str)
        out.prediction = np.select([out.status == "collision", out.status == "ok"], [-1, 1],
                                   default=0)
        first = out.bands[0]
        out.signal, out.ratio, out.regime = first.signal, first.ratio, first.regime
        return out


def _check_static_model(model):
    """ValueError for a residual model that reads the measured currents (a dynamic
    filter such as the momentum observer): its per-tick state is its own."""
    if reads_currents(model):
        raise ValueError(
            f"{type(getattr(model, 'estimator', model)).__name__} reads the measured currents "
            "of the samples before (a dynamic filter): StreamingMonitor does not run it; "
            "use the detector's batch methods, or the model's own per-tick form (e.g. "
            "MomentumObserver.stream())")
