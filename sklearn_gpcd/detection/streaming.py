"""Tick-by-tick collision monitoring with bounded memory."""

from enum import Enum

import numpy as np
from scipy.signal import lfilter_zi
from sklearn.utils import Bunch
from sklearn.utils.validation import check_is_fitted

from ._compiled import compile_predictor


class MonitorStatus(str, Enum):
    """Outcome of one :meth:`StreamingMonitor.update` call.

    Members compare equal to their string values.

    - ``OK`` (``"ok"``): a valid sample, no joint fired.
    - ``COLLISION`` (``"collision"``): a valid sample and at least one joint
      fired (``monitor.alarms`` tells which); the batch detector's
      ``predict`` gives -1 for this sample.
    - ``SENSOR_FAULT`` (``"sensor_fault"``): the sample was missing (None)
      or held a NaN / infinite value. It is skipped: no decision is made,
      the filter and debounce state are held, and the next valid sample is
      processed as if the faulty one had never arrived.

    ``str(status)`` is the value, so statuses stored in a NumPy array or
    written to a log keep it (``np.asarray([...])`` gives ``'collision'``,
    not a truncated ``'MonitorStatu'``).

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


def _frame_maker(detector):
    """Wrap a 2-D input block as the regressor saw it in fit (named or not)."""
    names = getattr(detector, "feature_names_in_", None)
    if names is None:
        return lambda block: block
    import pandas as pd  # the detector was fitted on a DataFrame

    columns = list(names[: -detector.n_joints])
    return lambda block: pd.DataFrame(block, columns=columns)


class StreamingMonitor:
    """Run a fitted :class:`CollisionDetector` one sample at a time.

    Each :meth:`update` takes one input row and the measured currents and
    makes the same decision as the detector's batch ``predict`` on the same
    rows (in order, with ``groups`` restarts mapped to :meth:`reset`): the
    residual ``s = i - i_hat``, the optional normalisation and causal
    low-pass filter, the debounce and the threshold test are all carried
    forward in preallocated state. Memory is bounded (the debounce window is
    a ring buffer of ``min_duration`` rows) and a tick allocates no array.

    The regressor's prediction is compiled once into a single-sample path
    (see :func:`~sklearn_gpcd.detection._compiled.compile_predictor`): for a
    GP, the support points are pre-scaled per ARD block, the weights and
    parametric-mean coefficients are cached and the gated (quasi-static)
    block is skipped while every gate is closed. ``normalize="std"`` needs
    the predictive std each tick, which costs a triangular solve with the
    support set; that goes through ``regressor.predict(..., return_std=True)``
    and is much slower.

    Parameters
    ----------
    detector : CollisionDetector
        A fitted detector.

    Attributes
    ----------
    status : MonitorStatus
        Status of the last tick (see :class:`MonitorStatus`).
    predicted : ndarray of shape (n_joints,)
        Predicted currents ``i_hat`` of the last valid tick.
    residual : ndarray of shape (n_joints,)
        ``s = i - i_hat``.
    signal : ndarray of shape (n_joints,)
        Monitoring signal ``m`` (normalised, filtered).
    ratio : ndarray of shape (n_joints,)
        Debounced ``|m| / scale_``.
    alarms : ndarray of bool, shape (n_joints,)
        Joints that fired.
    score : float
        ``-max(ratio)``, the batch ``score_samples`` value.
    n_ticks, n_faults : int
        Ticks seen and ticks rejected as sensor faults since construction.
    predictor_kind : str
        ``"gaussian_process"``, ``"linear"`` or ``"generic"`` (per-tick
        ``regressor.predict``).

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
    >>> monitor.update([0.5], current=[1.0]) == "ok"
    True
    """

    def __init__(self, detector):
        check_is_fitted(detector)
        self.detector = detector
        n = self.n_joints = detector.n_joints
        self.n_inputs = detector.n_features_in_ - n
        self._row = np.empty(detector.n_features_in_)
        self._inputs = self._row[: self.n_inputs]
        self._current = self._row[self.n_inputs :]
        self._finite = np.empty(detector.n_features_in_, dtype=bool)
        self._wrap = _frame_maker(detector)
        self._predictor = compile_predictor(
            detector.regressor_, self.n_inputs, n, wrap=self._wrap
        )
        self.predictor_kind = self._predictor.kind
        self._use_std = detector.normalize == "std"
        self._std_row = np.empty((1, self.n_inputs))
        self.std = np.ones(n)
        self._scale = np.asarray(detector.scale_, dtype=float)
        self._level = -float(detector.offset_)
        if detector.filter_coefficients_ is not None:
            b, a = detector.filter_coefficients_
            self._b, self._a = b, a
            self._zi_unit = lfilter_zi(b, a)[:, None]
            self._z = np.zeros((len(b) - 1, n))
            self._t1, self._t2 = np.empty(n), np.empty(n)
        else:
            self._b = None
        self._window = np.zeros((detector.min_duration, n))
        self.predicted = np.full(n, np.nan)
        self.residual = np.full(n, np.nan)
        self.signal = np.full(n, np.nan)
        self._raw_ratio = np.empty(n)
        self.ratio = np.full(n, np.nan)
        self.alarms = np.zeros(n, dtype=bool)
        self.score = np.nan
        self.status = None
        self.n_ticks = 0
        self.n_faults = 0
        self.reset()

    def reset(self):
        """Forget the filter and debounce history (e.g. a new recording)."""
        self._fresh = True
        self._window[:] = 0.0
        self._position = 0

    def update(self, x, current=None):
        """Process one sample.

        Parameters
        ----------
        x : array-like of shape (n_inputs + n_joints,) or (n_inputs,), or None
            One row of the detector's input: regressor inputs followed by
            the measured currents, or the regressor inputs only when
            ``current`` is given. None marks a missing sample; a missing
            value inside the sample is passed as NaN.
        current : array-like of shape (n_joints,), default=None
            Measured currents, when not included in ``x``.

        Returns
        -------
        status : MonitorStatus
            ``"ok"``, ``"collision"`` or ``"sensor_fault"``.

        Raises
        ------
        ValueError
            When ``x`` or ``current`` has the wrong length (a wiring error,
            not a sensor fault).
        """
        self.n_ticks += 1
        if x is None:
            return self._fault()
        self._load(x, current)
        if not np.isfinite(self._row, out=self._finite).all():
            return self._fault()
        self._predictor.predict_one(self._inputs, self.predicted)
        np.subtract(self._current, self.predicted, out=self.residual)
        if self._use_std:
            self._std_row[0] = self._inputs
            _, std = self.detector.regressor_.predict(
                self._wrap(self._std_row), return_std=True
            )
            np.maximum(np.reshape(std, (self.n_joints,)), np.finfo(float).tiny, out=self.std)
            np.divide(self.residual, self.std, out=self.signal)
        else:
            np.copyto(self.signal, self.residual)
        if self._b is not None:
            self._filter_step(self.signal)
        np.abs(self.signal, out=self._raw_ratio)
        self._raw_ratio /= self._scale
        self._window[self._position] = self._raw_ratio
        self._position = (self._position + 1) % self._window.shape[0]
        np.min(self._window, axis=0, out=self.ratio)
        np.greater(self.ratio, self._level, out=self.alarms)
        self.score = -float(self.ratio.max())
        self.status = MonitorStatus.COLLISION if self.alarms.any() else MonitorStatus.OK
        return self.status

    def _load(self, x, current):
        if current is None:
            if np.shape(x) != self._row.shape:
                raise ValueError(
                    f"x must have {self._row.shape[0]} values ({self.n_inputs} inputs + "
                    f"{self.n_joints} currents), got shape {np.shape(x)}"
                )
            np.copyto(self._row, x)
            return
        if np.shape(x) != self._inputs.shape:
            raise ValueError(
                f"x must have {self.n_inputs} input values when current is given, "
                f"got shape {np.shape(x)}"
            )
        if np.shape(current) != self._current.shape:
            raise ValueError(
                f"current must have {self.n_joints} values, got shape {np.shape(current)}"
            )
        np.copyto(self._inputs, x)
        np.copyto(self._current, current)

    def _filter_step(self, u):
        """One step of the direct-form II transposed filter, as scipy's lfilter."""
        b, a, z = self._b, self._a, self._z
        if self._fresh:  # steady state of the first sample, as in batch
            np.multiply(self._zi_unit, u, out=z)
            self._fresh = False
        t1, t2 = self._t1, self._t2
        np.multiply(u, b[0], out=t1)
        np.add(z[0], t1, out=t2)  # t2 = y
        for n in range(len(b) - 2):
            np.multiply(u, b[n + 1], out=t1)
            np.add(z[n + 1], t1, out=z[n])
            np.multiply(t2, a[n + 1], out=t1)
            z[n] -= t1
        np.multiply(u, b[-1], out=t1)
        np.multiply(t2, a[-1], out=z[-1])
        np.subtract(t1, z[-1], out=z[-1])
        np.copyto(u, t2)

    def _fault(self):
        self.n_faults += 1
        for array in (self.predicted, self.residual, self.signal, self.ratio):
            array[:] = np.nan
        self.alarms[:] = False
        self.score = np.nan
        self.status = MonitorStatus.SENSOR_FAULT
        return self.status

    def replay(self, X, groups=None):
        """Feed the rows of ``X`` through :meth:`update`, one by one.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
            Rows in time order (NaN rows become sensor faults).
        groups : array-like of shape (n_samples,), default=None
            Recording id per row; :meth:`reset` is called where it changes,
            matching the batch detector's ``groups``.

        Returns
        -------
        result : Bunch
            ``status`` (ndarray of str), ``predicted``, ``residual``,
            ``signal``, ``ratio`` (float, (n_samples, n_joints)), ``alarms``
            (bool, (n_samples, n_joints)) and ``prediction`` (+1 / -1 as
            ``predict``, 0 for sensor faults).
        """
        X = np.asarray(X, dtype=float)
        n = X.shape[0]
        out = Bunch(
            status=np.empty(n, dtype=object),
            **{
                name: np.empty((n, self.n_joints))
                for name in ("predicted", "residual", "signal", "ratio")
            },
            alarms=np.zeros((n, self.n_joints), dtype=bool),
        )
        groups = None if groups is None else np.asarray(groups)
        for t in range(n):
            if groups is not None and t and groups[t] != groups[t - 1]:
                self.reset()
            out.status[t] = self.update(X[t]).value
            for name in ("predicted", "residual", "signal", "ratio", "alarms"):
                out[name][t] = getattr(self, name)
        out.status = out.status.astype(str)
        out.prediction = np.select(
            [out.status == "collision", out.status == "ok"], [-1, 1], default=0
        )
        return out
