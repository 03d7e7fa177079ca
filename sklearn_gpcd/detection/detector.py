"""Collision detection by thresholding the current residual (paper Sec. II-III)."""

import inspect
import warnings
from numbers import Integral, Real

import numpy as np
from sklearn.base import BaseEstimator, OutlierMixin, clone
from sklearn.frozen import FrozenEstimator
from sklearn.utils import Bunch
from sklearn.utils.validation import _num_samples, check_is_fitted, validate_data

from .._gate import check_sigma_v
from ..layout import block_columns
from .._persistence import VersionedStateMixin
from ._regimes import regime_names, regime_pass
from ._signal import (
    debounce_segments,
    filter_segments,
    lowpass_coefficients,
    recording_index,
    segment_starts,
)
from ._thresholds import (
    contamination_level,
    false_alarm_level,
    fill_absent_regimes,
    loro_factors,
    recording_peaks,
    rms_scale,
)

_THRESHOLD_RULES = ("contamination", "false_alarm_rate", "per_joint", "std")
#: Relative deviation of ``sample_time`` from the data's median step that warns.
_SAMPLE_TIME_RTOL = 0.2
#: CollisionDetector parameters applied after the regressor: detectors that
#: differ only in these share one fitted regressor and its residuals
#: (``_post_processing_settings``; CollisionThresholdCV's candidates, the
#: bands of a MultiBandDetector, the settings chosen across recordings).
POST_PROCESSING_PARAMS = frozenset(
    {
        "threshold",
        "contamination",
        "false_alarm_rate",
        "k",
        "normalize",
        "filter_cutoff",
        "filter_order",
        "min_duration",
        "settle_time",
        "rest_reference",
    }
)


class SampleTimeWarning(UserWarning):
    """``CollisionDetector.sample_time`` differs from the data's sampling period.

    The low-pass filter, the settle time and the false-alarm rates are
    computed with ``sample_time``; when the recordings are sampled at another
    rate all three are off by the same factor. Raised by
    :meth:`CollisionDetector.fit` when ``time`` is given and the median time
    step differs by more than 20 %; pass ``sample_time="auto"`` to take it
    from the data.

    Examples
    --------
    >>> import warnings
    >>> import numpy as np
    >>> from sklearn.linear_model import LinearRegression
    >>> from sklearn_gpcd.detection import CollisionDetector, SampleTimeWarning
    >>> X = np.column_stack([np.arange(50.0), 2 * np.arange(50.0)])
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     _ = CollisionDetector(LinearRegression(), sample_time=0.008).fit(
    ...         X, time=np.arange(50) * 0.01)
    >>> [w.category.__name__ for w in caught]
    ['SampleTimeWarning']
    """


def stack_currents(X, current):
    """Append the measured currents to the model inputs, as the detector expects.

    :class:`CollisionDetector` needs the measured currents at every call, so
    they travel as the last ``n_joints`` columns of its input.

    Parameters
    ----------
    X : array-like of shape (n_samples, n_features)
        Regressor inputs, e.g. ``x^a = [q, qd, qdd, e_q, de_q, i_c]`` (Eq. 13).
    current : array-like of shape (n_samples,) or (n_samples, n_joints)
        Measured motor currents ``i``.

    Returns
    -------
    Z : ndarray of shape (n_samples, n_features + n_joints)

    Examples
    --------
    >>> import numpy as np
    >>> stack_currents(np.zeros((3, 2)), np.ones(3)).shape
    (3, 3)
    """
    X = np.asarray(X, dtype=float)
    current = np.asarray(current, dtype=float)
    if current.ndim == 1:
        current = current[:, None]
    if X.ndim != 2 or current.ndim != 2 or X.shape[0] != current.shape[0]:
        raise ValueError(
            f"X must be (n_samples, n_features) and current (n_samples, n_joints) with "
            f"the same number of rows; got X {X.shape} and current {current.shape}"
        )
    return np.hstack([X, current])


class CollisionDetector(VersionedStateMixin, OutlierMixin, BaseEstimator):
    """Proprioceptive collision detector on top of a current regressor.

    A regressor learns the motor currents of collision-free motion,
    ``i_hat = f(x)``; the monitoring signal is the residual (paper Sec. III)

    .. math:: s_l = i_l - \\hat{i}_l,

    optionally normalised by the predictive standard deviation
    (``normalize="std"``, :math:`u_l = s_l / \\sigma_l(x)`, a variance-aware
    band) and low-pass filtered (``filter_cutoff``: the moving-phase residual
    is high-frequency, Sec. IV-C). Joint ``l`` fires when its monitoring
    signal :math:`m_l` leaves the band (the paper's :math:`f_{CD}`, Sec. II)

    .. math:: |m_l| > \\sigma_{CD,l} \\quad \\text{for ``min_duration``
              consecutive samples,}

    and a sample is a collision when at least one joint fires.

    **Input layout.** The measured currents are needed whenever the detector
    is asked anything, so they are the **last** ``n_joints`` **columns of**
    ``X``; the columns before them are the regressor inputs (build ``X`` with
    :func:`stack_currents`). This keeps the scikit-learn outlier-detector API
    (``fit(X)``, ``predict(X)``) and lets the detector sit in pipelines and
    grid searches.

    **Time series.** With ``filter_cutoff=None`` and ``min_duration=1`` (the
    defaults) every row is judged on its own. Otherwise the rows are one
    time series sampled every ``sample_time`` seconds; pass ``groups``
    (recording id per row) to restart the filter and debounce state where a
    new recording begins.

    **Calibration data.** The thresholds come from the residuals on the
    collision-free training rows. A GP nearly interpolates its support
    points, so residuals there understate those on new data: condition the
    GP on a subset (``n_support``, the paper's :math:`D_{SDP}`) or tune the
    level on held-out recordings with :class:`CollisionThresholdCV`.

    **Scores** follow :class:`~sklearn.ensemble.IsolationForest`:
    ``score_samples`` is ``-max_l r_l`` with the debounced ratio
    ``r_l = |m_l| / scale_l`` (higher = more normal), ``decision_function =
    score_samples - offset_`` is negative for collisions and ``predict``
    returns -1 there and +1 elsewhere. The joint thresholds in signal units
    are ``thresholds_ = -offset_ * scale_``.

    Parameters
    ----------
    regressor : regressor, default=None
        Model of the collision-free currents, fitted on ``(X[:, :-n_joints],
        X[:, -n_joints:])`` (a clone is fitted). ``None`` builds the paper's
        SP_P estimator (:func:`default_regressor`: ``make_sp_p`` without
        robot model, 5,000 support rows), which expects the augmented inputs
        of Eq. 13 (``6 * n_joints`` columns).
        ``normalize="std"`` and ``threshold="std"`` need a regressor whose
        ``predict`` accepts ``return_std``.
    n_joints : int, default=1
        Number of joints, i.e. of trailing current columns in ``X``.
    threshold : {"contamination", "false_alarm_rate", "std"}, \
            default="contamination"
        Rule that sets ``sigma_CD`` from the training data, with the per-joint
        scale ``scale_``:

        - ``"contamination"``: ``scale_`` is the RMS of each joint's training
          signal and the level flags the fraction ``contamination`` of the
          training samples (IsolationForest convention);
        - ``"false_alarm_rate"``: same scale, smallest level whose alarm
          onsets on the training data stay within ``false_alarm_rate`` per
          hour;
        - ``"per_joint"``: a level per joint (and per regime with
          ``regimes=True``): the false-alarm budget ``false_alarm_rate`` is
          split equally across joints and regimes, and each joint's level is
          the smallest whose alarm onsets on the training data (in that
          regime) stay within its share; ``margin`` multiplies every level.
          One heavy-tailed joint then no longer inflates the others;
        - ``"std"``: ``k`` predictive standard deviations. With
          ``normalize="std"`` the band follows ``sigma_l(x)`` sample by sample
          (``scale_ = 1``); otherwise ``scale_`` is the RMS of the predictive
          std over the training inputs. Include the observation noise in the
          regressor's std (e.g. a ``WhiteKernel``) or the band is too narrow.
    contamination : float in (0, 0.5], default=0.001
        Fraction of training samples flagged by ``threshold="contamination"``.
    false_alarm_rate : float, default=1.0
        Alarm onsets per hour allowed on the training data by
        ``threshold="false_alarm_rate"``.
    k : float, default=3.0
        Width of the band in predictive standard deviations, for
        ``threshold="std"``.
    margin : float >= 1, array-like or "loro", default=1.0
        Factor on the levels of ``threshold="per_joint"``: thresholds that
        were just not crossed on the calibration data are crossed on unseen
        data by the next-largest excursion; a margin buys robustness at the
        cost of sensitivity. A scalar, or one value per joint (shape
        ``(n_joints,)``) or per regime and joint (the shape of ``scale_``).
        ``"loro"`` learns it in :meth:`fit` by leaving one recording out
        (``groups`` names the recordings, at least 2): the largest factor by
        which a recording's peak debounced ``|m|`` exceeds the level of the
        other recordings, over all regimes and joints
        (:func:`~sklearn_gpcd.detection.loro_margin`, ``rule="global"``; a
        margin per cell or per regime over-fits, see the user guide). With
        ``false_alarm_rate=0`` the thresholds then match ``gpcd calibrate``.
    normalize : {None, "std"}, default=None
        Divide the residual by the predictive std before filtering.
    filter_cutoff : float, default=None
        Cut-off frequency of the causal low-pass filter in Hz (``None``: no
        filter).
    filter_order : {1, 2}, default=1
        First-order lag or second-order Butterworth filter.
    min_duration : int, default=1
        Samples the band must be exceeded in a row before a joint fires.
    sample_time : float or "auto", default=0.008
        Sampling period in seconds (the paper's UR10 logs at 8 ms, the UR10e
        logs of Mamedov et al. at 10 ms); used by the filter, the settle time,
        the rest reference and the false-alarm rates. ``"auto"`` takes the
        median time step of ``time`` passed to :meth:`fit`; a number that
        differs from it by more than 20 % warns (:class:`SampleTimeWarning`).
    sigma_v : float, default=None
        Velocity threshold of the quasi-static gate (Sec. IV-B, the paper uses
        ``1e-2``). When set, it is passed on as the regressor's ``sigma_v``
        parameter; ``None`` keeps the regressor's own value. The regimes use
        it too (``1e-2`` when None).
    regimes : bool, default=False
        Separate thresholds for the arm's motion regimes ``moving``,
        ``settling`` and ``rest`` (see
        :mod:`sklearn_gpcd.detection._regimes`): the residual of a still arm
        is small and slow, that of a moving one large and fast, so one band
        for both is either blind at rest or noisy in motion. Needs the joint
        velocities among the regressor inputs (``velocity_columns``).
    settle_time : float, default=0.5
        Seconds the arm must be still after a motion before it is at rest;
        until then it is ``settling`` (the friction transient of a stop).
    rest_reference : float or None, default=None
        With ``regimes=True``: re-reference the monitoring signal at rest
        entry and let the reference follow it with this time constant in
        seconds (``numpy.inf``: a fixed reference). The held current of a
        still joint depends on its history (stiction); the re-reference
        removes that offset, which no pose feature predicts. Our extension
        of the paper (Eq. 13-17); see the user guide.
    brake_limit : float or None, default=None
        With ``regimes=True``: a fourth regime, ``braking``, with its own
        thresholds, from a sample where some joint's acceleration exceeds
        ``brake_limit`` [rad/s^2] until ``brake_hold`` seconds after the
        last such sample. Hard stops ring the current for about half a
        second; set it to the largest acceleration the model was trained on
        (``training["acceleration_limit"]`` of
        :func:`~sklearn_gpcd.workflow.train_model`) so that those samples no
        longer set the thresholds of motion. Reads the ``qdd`` block of the
        paper's layout (:mod:`sklearn_gpcd.layout`). Our extension.
    brake_hold : float, default=0.5
        Seconds the braking regime lasts after the last sample above
        ``brake_limit``.
    velocity_columns : list of int or None, default=None
        Columns of the regressor inputs holding the joint velocities, for
        ``regimes``. None takes the ``qd`` block of the paper's layout
        (:mod:`sklearn_gpcd.layout`) when the inputs have ``3 * n_joints``
        or ``6 * n_joints`` columns.

    Attributes
    ----------
    regressor_ : regressor
        The fitted clone of ``regressor``.
    scale_ : ndarray of shape (n_joints,) or (3, n_joints)
        Per-joint scale of the monitoring signal (see ``threshold``); one row
        per regime (``regime_names_``) when ``regimes=True``.
    offset_ : float
        ``-gamma``: a joint fires when ``|m_l| / scale_l > -offset_``.
    margin_ : ndarray of the shape of ``scale_``
        The margin applied to the levels of ``threshold="per_joint"`` (the
        given ``margin`` broadcast, or the one learned with ``"loro"``); 1
        for the other rules.
    thresholds_ : ndarray of shape (n_joints,) or (3, n_joints)
        ``sigma_CD`` per joint (and regime), in units of the monitoring
        signal (current units, or standard deviations when
        ``normalize="std"``).
    regime_names_ : tuple of str
        Rows of ``scale_`` / ``thresholds_``: ``("moving", "settling",
        "rest")`` with ``regimes=True`` (and ``"braking"`` with
        ``brake_limit``), else ``("all",)``.
    sample_time_ : float
        Sampling period used (``sample_time``, or the data's with "auto").
    velocity_columns_ : list of int or None
        Velocity columns of the regressor inputs used by the regimes.
    acceleration_columns_ : list of int or None
        Acceleration columns of the regressor inputs used by the braking
        regime (None without ``brake_limit``).
    filter_coefficients_ : tuple of ndarray or None
        ``(b, a)`` of the low-pass filter.
    n_features_in_ : int
        Columns of ``X`` seen in fit (regressor inputs plus currents).
    feature_names_in_ : ndarray of str
        Column names, when ``X`` had string column names.

    Notes
    -----
    With ``threshold="contamination"`` the fraction of flagged training
    samples is exactly ``contamination`` (up to ties), the contract that
    scikit-learn's outlier checks test. The other rules ignore
    ``contamination``.

    See Also
    --------
    StreamingMonitor : The same decisions, one sample at a time.
    CollisionThresholdCV : Tunes thresholds and filter settings on labelled
        recordings.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.linear_model import Ridge
    >>> from sklearn_gpcd.detection import CollisionDetector, stack_currents
    >>> rng = np.random.default_rng(0)
    >>> qd = rng.normal(size=(500, 1))
    >>> current = 2.0 * qd[:, 0] + 0.01 * rng.normal(size=500)
    >>> det = CollisionDetector(Ridge(), contamination=0.01)
    >>> det.fit(stack_currents(qd, current))
    CollisionDetector(contamination=0.01, regressor=Ridge())
    >>> bumped = current.copy()
    >>> bumped[100] += 1.0                    # an external torque
    >>> pred = det.predict(stack_currents(qd, bumped))
    >>> bool(pred[100] == -1)
    True
    """

    def __init__(
        self,
        regressor=None,
        *,
        n_joints=1,
        threshold="contamination",
        contamination=0.001,
        false_alarm_rate=1.0,
        k=3.0,
        margin=1.0,
        normalize=None,
        filter_cutoff=None,
        filter_order=1,
        min_duration=1,
        sample_time=0.008,
        sigma_v=None,
        regimes=False,
        settle_time=0.5,
        rest_reference=None,
        velocity_columns=None,
        brake_limit=None,
        brake_hold=0.5,
    ):
        self.regressor = regressor
        self.n_joints = n_joints
        self.threshold = threshold
        self.contamination = contamination
        self.false_alarm_rate = false_alarm_rate
        self.k = k
        self.margin = margin
        self.normalize = normalize
        self.filter_cutoff = filter_cutoff
        self.filter_order = filter_order
        self.min_duration = min_duration
        self.sample_time = sample_time
        self.sigma_v = sigma_v
        self.regimes = regimes
        self.settle_time = settle_time
        self.rest_reference = rest_reference
        self.velocity_columns = velocity_columns
        self.brake_limit = brake_limit
        self.brake_hold = brake_hold

    def fit(self, X, y=None, *, labels=None, groups=None, time=None):
        """Learn the collision-free currents and the thresholds.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
            Regressor inputs followed by the measured currents.
        y : None
            Ignored; present for API consistency.
        labels : array-like of shape (n_samples,), default=None
            Contact labels (0 free, k > 0 inside contact k). Rows with a
            non-zero label are left out, so labelled recordings can be passed
            whole. ``None`` treats all rows as collision-free.
        groups : array-like of shape (n_samples,), default=None
            Recording id of each row; the filter and debounce restart where
            it changes.
        time : array-like of shape (n_samples,), default=None
            Time stamps [s] of the rows: checks ``sample_time`` against the
            median step within each recording (or sets it, with "auto").

        Returns
        -------
        self : CollisionDetector
        """
        residual, std, starts, motion = self._fit_residuals(
            X, labels, groups, time, self._needs_std(fitting=True)
        )
        self._calibrate(residual, std, starts, motion, recording_index(groups, labels))
        return self

    def _fit_residuals(self, X, labels, groups, time, return_std):
        """The half of :meth:`fit` before the thresholds: parameters checked,
        ``sample_time_``, ``regressor_`` fitted; residuals, std, starts and
        velocities of the collision-free rows (what :meth:`_calibrate` reads)."""
        self._validate_params()
        self.sample_time_ = self._check_sample_time(time, groups, _num_samples(X))
        return self._fit_regressor(X, labels, groups, return_std)

    def _check_sample_time(self, time, groups, n_rows):
        """``sample_time_``: given, or the median step of ``time`` ("auto")."""
        if time is None:
            if self.sample_time == "auto":
                raise ValueError(
                    "sample_time='auto' takes the sampling period from the data: pass "
                    "fit(..., time=time_stamps)"
                )
            return float(self.sample_time)
        time = np.asarray(time, dtype=float)
        if time.shape != (n_rows,):
            raise ValueError(f"time must have shape ({n_rows},), got {time.shape}")
        steps = np.diff(time)
        if groups is not None:
            groups = np.asarray(groups)
            steps = steps[groups[1:] == groups[:-1]]
        steps = steps[steps > 0]
        if not steps.size:
            raise ValueError("time has no positive step within a recording")
        median = float(np.median(steps))
        if self.sample_time == "auto":
            return median
        if abs(self.sample_time - median) > _SAMPLE_TIME_RTOL * median:
            warnings.warn(
                f"sample_time={self.sample_time:g} s but the data's median time step is "
                f"{median:g} s: the filter, settle time and false-alarm rates are off "
                f"by a factor {median / self.sample_time:.2f}; pass sample_time={median:g} "
                "or sample_time='auto'",
                SampleTimeWarning, stacklevel=3,
            )
        return float(self.sample_time)

    def _fit_regressor(self, X, labels, groups, return_std):
        """Fit ``regressor_`` on the collision-free rows; residuals, starts, velocities."""
        X = validate_data(self, X, dtype=np.float64)
        n = self.n_joints
        if X.shape[1] <= n:
            raise ValueError(
                f"X has {X.shape[1]} feature(s) but CollisionDetector(n_joints={n}) "
                f"needs the regressor inputs followed by {n} current column(s), i.e. "
                f"at least {n + 1} columns"
            )
        self.velocity_columns_ = self._velocity_columns(X.shape[1] - n)
        self.acceleration_columns_ = self._acceleration_columns(X.shape[1] - n)
        keep = None
        if labels is not None:
            labels = np.asarray(labels)
            if labels.shape != (X.shape[0],):
                raise ValueError(f"labels must have shape ({X.shape[0]},), got {labels.shape}")
            keep = labels == 0
            if not keep.any():
                raise ValueError("labels: no collision-free row (label 0) to fit on")
        starts = segment_starts(X.shape[0], groups, keep)
        if keep is not None:
            X = X[keep]
        inputs, current = self._inputs(X), X[:, -n:]
        self.regressor_ = self._make_regressor(X.shape[1] - n)
        self.regressor_.fit(inputs, current[:, 0] if n == 1 else current)
        mean, std = self._predict_currents(inputs, return_std)
        return current - mean, std, starts, self._motion(X)

    def _velocity_columns(self, n_inputs):
        """Velocity columns of the regressor inputs (None when regimes are off)."""
        if not self.regimes:
            return None
        if self.velocity_columns is not None:
            columns = [int(c) for c in self.velocity_columns]
            if len(columns) != self.n_joints or not all(0 <= c < n_inputs for c in columns):
                raise ValueError(
                    f"velocity_columns must list {self.n_joints} column indices below "
                    f"{n_inputs} (the regressor inputs), got {self.velocity_columns!r}"
                )
            return columns
        return self._layout_block("qd", n_inputs, "regimes=True needs the joint velocities",
                                  "; pass velocity_columns")

    def _acceleration_columns(self, n_inputs):
        """Acceleration columns of the regressor inputs (None without ``brake_limit``)."""
        if self.brake_limit is None:
            return None
        return self._layout_block("qdd", n_inputs, "brake_limit needs the joint accelerations",
                                  ", the qdd block after q and qd")

    def _layout_block(self, block, n_inputs, need, hint):
        """Columns of ``block`` in the paper's layout of the regressor inputs, or an
        error saying what ``need`` s them."""
        if n_inputs in (3 * self.n_joints, 6 * self.n_joints):
            return block_columns(block, self.n_joints)
        raise ValueError(
            f"{need}: the {n_inputs} regressor inputs are not the paper's layout for "
            f"{self.n_joints} joints (3 or 6 columns per joint){hint}"
        )

    def _motion(self, X):
        """What the regimes read of validated rows: the joint velocities, then
        the accelerations with ``brake_limit``; None without regimes."""
        if self.velocity_columns_ is None:
            return None
        return X[:, self._motion_columns()]

    def _motion_columns(self):
        """Velocity columns, then acceleration columns (with ``brake_limit``)."""
        return list(self.velocity_columns_) + list(self.acceleration_columns_ or [])

    def fit_predict(self, X, y=None, *, labels=None, groups=None):
        """Fit, then label the same rows (+1 normal, -1 collision).

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
            Regressor inputs followed by the measured currents.
        y : None
            Ignored.
        labels : array-like of shape (n_samples,), default=None
            Contact labels used to select the training rows (see :meth:`fit`).
        groups : array-like of shape (n_samples,), default=None
            Recording id of each row.

        Returns
        -------
        y_pred : ndarray of shape (n_samples,)
        """
        return self.fit(X, labels=labels, groups=groups).predict(X, groups=groups)

    def _validate_params(self):
        checks = {
            "n_joints": isinstance(self.n_joints, Integral) and self.n_joints >= 1,
            "threshold": self.threshold in _THRESHOLD_RULES,
            "contamination": isinstance(self.contamination, Real)
            and 0.0 < self.contamination <= 0.5,
            "false_alarm_rate": isinstance(self.false_alarm_rate, Real)
            and self.false_alarm_rate >= 0.0,
            "k": isinstance(self.k, Real) and self.k > 0.0,
            "margin": _valid_margin(self.margin)
            and (not _is_loro(self.margin) or self.threshold == "per_joint"),
            "normalize": self.normalize in (None, "std"),
            "filter_cutoff": self.filter_cutoff is None
            or (isinstance(self.filter_cutoff, Real) and self.filter_cutoff > 0.0),
            "filter_order": self.filter_order in (1, 2),
            "min_duration": isinstance(self.min_duration, Integral) and self.min_duration >= 1,
            "sample_time": self.sample_time == "auto"
            or (isinstance(self.sample_time, Real) and self.sample_time > 0.0),
            "sigma_v": _valid_sigma_v(self.sigma_v),
            "regimes": isinstance(self.regimes, (bool, np.bool_))
            and not (self.regimes and self.threshold == "std"),
            "settle_time": isinstance(self.settle_time, Real) and self.settle_time >= 0.0,
            "rest_reference": self.rest_reference is None
            or (self.regimes and isinstance(self.rest_reference, Real)
                and self.rest_reference > 0.0),
            "brake_limit": self.brake_limit is None
            or (self.regimes and isinstance(self.brake_limit, Real)
                and 0.0 < self.brake_limit < np.inf),
            "brake_hold": isinstance(self.brake_hold, Real) and 0.0 <= self.brake_hold < np.inf,
        }
        allowed = {
            "n_joints": "an int >= 1",
            "threshold": f"one of {_THRESHOLD_RULES}",
            "contamination": "a float in (0, 0.5]",
            "false_alarm_rate": "a float >= 0 (alarms per hour)",
            "k": "a float > 0",
            "margin": "a float >= 1, an array of floats >= 1 or 'loro' (with "
            "threshold='per_joint')",
            "normalize": "None or 'std'",
            "filter_cutoff": "None or a float > 0 (Hz)",
            "filter_order": "1 or 2",
            "min_duration": "an int >= 1 (samples)",
            "sample_time": "a float > 0 (seconds) or 'auto'",
            "sigma_v": "None or a float > 0 (rad/s)",
            "regimes": "a bool (and not combined with threshold='std')",
            "settle_time": "a float >= 0 (seconds)",
            "rest_reference": "None, or a time constant > 0 in seconds (inf: fixed), "
            "with regimes=True",
            "brake_limit": "None, or a finite acceleration > 0 (rad/s^2), with regimes=True",
            "brake_hold": "a finite float >= 0 (seconds)",
        }
        for name, ok in checks.items():
            if not ok:
                raise ValueError(
                    f"CollisionDetector: {name} must be {allowed[name]}, "
                    f"got {getattr(self, name)!r}"
                )

    def _inputs(self, X):
        """Regressor inputs: all but the current columns, named when X had names.

        Named columns reach the regressor as a DataFrame, so kernels may
        select them by name (e.g. ``ARDRBF(columns=["qd_0"])``).
        """
        inputs = X[:, : -self.n_joints]
        names = getattr(self, "feature_names_in_", None)
        if names is None:
            return inputs
        import pandas as pd  # X was a DataFrame, so pandas is installed

        return pd.DataFrame(inputs, columns=names[: -self.n_joints])

    def _make_regressor(self, n_inputs):
        if self.regressor is None:
            _check_joint_count(n_inputs, self.n_joints, 6, "the default SP_P regressor")
            regressor = default_regressor(self.n_joints)
        else:
            regressor = clone(self.regressor)
            kernels = regressor.get_params(deep=False).get("kernel")
            if isinstance(kernels, (list, tuple)) and len(kernels) != self.n_joints:
                raise ValueError(
                    f"CollisionDetector(n_joints={self.n_joints}) but the regressor has "
                    f"{len(kernels)} kernels (one per joint): the data has "
                    f"{len(kernels)} joints, or the regressor was built for another robot; "
                    f"set n_joints={len(kernels)} or rebuild the regressor"
                )
        if self.sigma_v is not None and not isinstance(regressor, FrozenEstimator):
            # a frozen (already fitted) model keeps its own; sigma_v then sets the regimes only
            if "sigma_v" not in regressor.get_params(deep=False):
                raise ValueError(
                    f"sigma_v={self.sigma_v!r} was given but the regressor "
                    f"{type(regressor).__name__} has no sigma_v parameter"
                )
            regressor.set_params(sigma_v=self.sigma_v)
        return regressor

    def _needs_std(self, fitting=False):
        if self.normalize == "std":
            return True
        return fitting and self.threshold == "std"

    def _predict_currents(self, inputs, return_std):
        """Predicted currents and (optionally) predictive std, both (n, n_joints)."""
        n_rows = inputs.shape[0]
        regressor = self.regressor_
        if return_std:
            if "return_std" not in inspect.signature(regressor.predict).parameters:
                raise ValueError(
                    f"normalize={self.normalize!r} / threshold={self.threshold!r} need "
                    f"the predictive std, but {type(regressor).__name__}.predict has "
                    "no return_std argument; use a Gaussian process regressor"
                )
            mean, std = regressor.predict(inputs, return_std=True)
            std = np.reshape(np.asarray(std, dtype=float), (n_rows, self.n_joints))
            std = np.maximum(std, np.finfo(float).tiny)
        else:
            mean, std = regressor.predict(inputs), None
        return np.reshape(np.asarray(mean, dtype=float), (n_rows, self.n_joints)), std

    # ---------------------------------------------------------- calibration
    def _signal(self, residual, std, starts, motion):
        """Monitoring signal m, its regimes and rest reference.

        Normalised, low-pass filtered residual, re-referenced at rest
        (``rest_reference``); regimes all 0 without ``regimes``.
        """
        u = residual / std if self.normalize == "std" else residual
        if self.filter_coefficients_ is not None:
            u = filter_segments(u, *self.filter_coefficients_, starts)
        if not self.regimes:
            return u, np.zeros(u.shape[0], dtype=np.intp), None
        return regime_pass(u, motion, starts, **self._regime_settings())

    def _regime_settings(self):
        """Keyword arguments of :func:`regime_pass` (also read by StreamingMonitor)."""
        beta = None
        if self.rest_reference is not None:
            beta = float(-np.expm1(-self.sample_time_ / self.rest_reference))
        return {
            "sigma_v": 1e-2 if self.sigma_v is None else float(self.sigma_v),
            "settle": int(round(self.settle_time / self.sample_time_)),
            "beta": beta,
            "brake_limit": self.brake_limit,
            "brake_hold": int(round(self.brake_hold / self.sample_time_)),
        }

    def _ratio(self, signal, regimes, starts):
        """Debounced ratio: min of |m_l| over min_duration samples, / scale of the regime."""
        debounced = debounce_segments(np.abs(signal), self.min_duration, starts)
        return debounced / np.atleast_2d(self.scale_)[regimes]

    def _set_signal_stages(self):
        """``filter_coefficients_`` and ``regime_names_``: what :meth:`_signal` reads
        besides the parameters (``sample_time_`` set)."""
        self.filter_coefficients_ = None
        if self.filter_cutoff is not None:
            self.filter_coefficients_ = lowpass_coefficients(
                self.filter_cutoff, self.sample_time_, self.filter_order
            )
        self.regime_names_ = (regime_names(self.brake_limit is not None) if self.regimes
                              else ("all",))

    def _calibrate(self, residual, std, starts, motion, recordings=None):
        """Set filter_coefficients_, scale_, margin_, offset_ and thresholds_.

        ``recordings``: recording index of each training residual row (for
        ``margin="loro"``), or None when no ``groups`` were given.
        """
        self._set_signal_stages()
        signal, regimes, _ = self._signal(residual, std, starts, motion)
        margin = 1.0
        if self.threshold == "std":
            self.scale_ = np.ones(self.n_joints) if self.normalize == "std" else rms_scale(std)
            gamma = float(self.k)
        elif self.threshold == "per_joint":
            debounced = debounce_segments(np.abs(signal), self.min_duration, starts)
            levels = self._joint_levels(debounced, regimes, starts)
            margin = self._margin(debounced, regimes, recordings, levels.shape)
            self.scale_ = margin * levels
            gamma = 1.0
        else:
            self.scale_ = self._regime_rows(
                lambda rows: rms_scale(signal[rows]), regimes
            )
            peak = self._ratio(signal, regimes, starts).max(axis=1)
            if self.threshold == "contamination":
                gamma = contamination_level(peak, self.contamination)
            else:
                gamma = false_alarm_level(peak, starts, self.sample_time_, self.false_alarm_rate)
        self.margin_ = np.broadcast_to(margin, np.shape(self.scale_)).copy()
        self.offset_ = -gamma
        self.thresholds_ = gamma * self.scale_

    def _margin(self, debounced, regimes, recordings, shape):
        """The given margin, checked against the levels' shape, or the LORO one."""
        if not _is_loro(self.margin):
            margin = np.asarray(self.margin, dtype=float)
            if margin.shape not in ((), (self.n_joints,), shape):
                raise ValueError(
                    f"margin has shape {margin.shape}; expected a scalar, ({self.n_joints},) "
                    f"or {shape} (regimes x joints)"
                )
            return margin
        n_recordings = 0 if recordings is None else int(recordings.max()) + 1
        if n_recordings < 2:
            raise ValueError(
                "margin='loro' leaves one recording out: pass groups= naming at least 2 "
                f"recordings to fit, got {n_recordings}"
            )
        n_rows = len(self.regime_names_)
        peaks = recording_peaks(debounced, regimes, recordings, n_rows)
        return loro_factors(peaks, "global").reshape(shape)

    def _regime_rows(self, per_regime, regimes):
        """``per_regime(rows)`` for each regime, stacked (one row without regimes).

        A regime absent from the training data takes the largest value of
        the others (no data, no tighter band).
        """
        if not self.regimes:
            return per_regime(slice(None))
        n_rows = len(self.regime_names_)
        table = np.zeros((n_rows, self.n_joints))
        present = np.zeros(n_rows, dtype=bool)
        for code in range(n_rows):
            rows = regimes == code
            if rows.any():
                table[code], present[code] = per_regime(rows), True
        return fill_absent_regimes(table, present)

    def _joint_levels(self, debounced, regimes, starts):
        """Per joint (and regime) false-alarm levels of the debounced |m|.

        The budget ``false_alarm_rate`` is split equally over the joints and
        the regimes present; joint ``l``'s level in regime ``g`` is
        :func:`false_alarm_level` of its debounced ``|m_l|``, set to zero
        outside ``g``, with that share.
        """
        n_regimes = len(np.unique(regimes)) if self.regimes else 1
        share = self.false_alarm_rate / (self.n_joints * n_regimes)
        tiny = np.finfo(float).tiny

        def levels(rows):
            out = np.empty(self.n_joints)
            for joint in range(self.n_joints):
                peak = np.where(rows, debounced[:, joint], 0.0)
                out[joint] = false_alarm_level(peak, starts, self.sample_time_, share)
            return np.maximum(out, tiny)

        if not self.regimes:
            return levels(np.ones(debounced.shape[0], dtype=bool))
        return self._regime_rows(levels, regimes)

    # ------------------------------------------------------------- predict
    def monitoring_signal(self, X, groups=None):
        """Every stage of the monitoring pipeline for the rows of ``X``.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
            Regressor inputs followed by the measured currents.
        groups : array-like of shape (n_samples,), default=None
            Recording id of each row (restarts filter and debounce).

        Returns
        -------
        result : Bunch
            With arrays of shape (n_samples, n_joints):
            ``predicted`` (``i_hat``), ``std`` (predictive std, or None when
            not needed), ``residual`` (``s = i - i_hat``), ``signal`` (``m``,
            normalised, filtered and re-referenced at rest), ``reference``
            (the rest reference subtracted from the filtered residual, or
            None without ``rest_reference``), ``ratio`` (debounced ``|m|`` over
            the scale of the sample's regime) and ``alarms`` (bool, joints
            that fired); and ``regime`` of shape (n_samples,), the regime
            code of each sample (index into ``regime_names_``).

        Examples
        --------
        >>> import numpy as np
        >>> from sklearn.linear_model import LinearRegression
        >>> X = stack_currents(np.arange(6.0)[:, None], 2 * np.arange(6.0))
        >>> det = CollisionDetector(LinearRegression()).fit(X)
        >>> X[3, -1] += 1.0
        >>> out = det.monitoring_signal(X)
        >>> np.abs(out.residual[:, 0]).round(6).tolist()
        [0.0, 0.0, 0.0, 1.0, 0.0, 0.0]
        >>> out.alarms[:, 0].tolist()
        [False, False, False, True, False, False]
        """
        check_is_fitted(self)
        X = validate_data(self, X, dtype=np.float64, reset=False)
        starts = segment_starts(X.shape[0], groups)
        predicted, std, residual = self._residual(X, self._needs_std())
        return Bunch(predicted=predicted, std=std, residual=residual,
                     **self._stages(X, residual, std, starts))

    def _stages(self, X, residual, std, starts):
        """The stages after the residual: ``signal``, ``regime``, ``reference``,
        ``ratio`` and ``alarms`` of validated rows ``X`` (see
        :meth:`monitoring_signal`)."""
        signal, regimes, reference = self._signal(residual, std, starts, self._motion(X))
        ratio = self._ratio(signal, regimes, starts)
        return {"signal": signal, "regime": regimes, "reference": reference, "ratio": ratio,
                "alarms": ratio > -self.offset_}

    def _residual(self, X, return_std):
        """Predicted currents, std (or None) and residual ``s`` for validated X."""
        n = self.n_joints
        predicted, std = self._predict_currents(self._inputs(X), return_std)
        return predicted, std, X[:, -n:] - predicted

    def score_samples(self, X, groups=None):
        """Normality score ``-max_l r_l`` (higher = more normal).

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
            Regressor inputs followed by the measured currents.
        groups : array-like of shape (n_samples,), default=None
            Recording id of each row.

        Returns
        -------
        scores : ndarray of shape (n_samples,)
        """
        return -self.monitoring_signal(X, groups).ratio.max(axis=1)

    def decision_function(self, X, groups=None):
        """``score_samples - offset_``: negative for collisions.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
            Regressor inputs followed by the measured currents.
        groups : array-like of shape (n_samples,), default=None
            Recording id of each row.

        Returns
        -------
        decision : ndarray of shape (n_samples,)
        """
        return self.score_samples(X, groups) - self.offset_

    def predict(self, X, groups=None):
        """+1 for collision-free samples, -1 for collisions.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
            Regressor inputs followed by the measured currents.
        groups : array-like of shape (n_samples,), default=None
            Recording id of each row.

        Returns
        -------
        y_pred : ndarray of shape (n_samples,)
        """
        decision = self.decision_function(X, groups)
        return np.where(decision < 0, -1, 1)

    def predict_joints(self, X, groups=None):
        """Which joints fired, per sample (the paper's per-component test).

        A sample is a collision (:meth:`predict` gives -1) exactly when at
        least one of its joints fired.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
            Regressor inputs followed by the measured currents.
        groups : array-like of shape (n_samples,), default=None
            Recording id of each row.

        Returns
        -------
        fired : ndarray of bool, shape (n_samples, n_joints)
        """
        return self.monitoring_signal(X, groups).alarms


def _post_processing_settings(reference, detector):
    """The settings by which ``detector`` differs from ``reference``, when it may
    reuse its fitted regressor and residuals; None when it may not.

    It may when every parameter but the regressor and the margin is equal,
    or differs only among :data:`POST_PROCESSING_PARAMS`, the settings
    applied after the regressor. The regressor is not compared: the caller
    shares one fitted model. A detector that reads the predictive std
    (``_needs_std``) needs residuals computed with it.

    Parameters
    ----------
    reference, detector : CollisionDetector

    Returns
    -------
    settings : dict or None
        ``{name: value of detector}`` for the differing parameters (empty when
        none differ), or None when some parameter outside
        :data:`POST_PROCESSING_PARAMS` differs.

    Examples
    --------
    >>> fast = CollisionDetector(filter_cutoff=10.0, min_duration=2)
    >>> _post_processing_settings(CollisionDetector(filter_cutoff=2.0), fast)
    {'filter_cutoff': 10.0, 'min_duration': 2}
    >>> print(_post_processing_settings(CollisionDetector(), CollisionDetector(sample_time=0.01)))
    None
    """
    ours, theirs = reference.get_params(deep=False), detector.get_params(deep=False)
    settings = {}
    for name, value in theirs.items():
        if name in ("regressor", "margin") or _same_param(ours.get(name), value):
            continue
        if name not in POST_PROCESSING_PARAMS:
            return None
        settings[name] = value
    return settings


def _same_param(a, b):
    """Parameter values equal: the same object, equal arrays, or ``a == b``.

    >>> _same_param([1, 2], [1, 2]), _same_param(np.zeros(2), np.zeros(3))
    (True, False)
    """
    if a is b:
        return True
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return bool(np.shape(a) == np.shape(b) and np.array_equal(a, b))
    try:
        return bool(a == b)
    except (TypeError, ValueError):
        return False


def _is_loro(margin):
    return isinstance(margin, str) and margin == "loro"


def _valid_margin(margin):
    """"loro", or a number or an array of numbers, all finite and >= 1."""
    if _is_loro(margin):
        return True
    if isinstance(margin, str):
        return False
    try:
        values = np.asarray(margin, dtype=float)
    except (TypeError, ValueError):
        return False
    return values.size > 0 and bool(np.all(np.isfinite(values) & (values >= 1.0)))


def _check_joint_count(n_inputs, n_joints, per_joint, what):
    """ValueError naming both joint counts when the inputs do not fit ``n_joints``."""
    if n_inputs == per_joint * n_joints:
        return
    hint = ""
    if (n_inputs + n_joints) % (per_joint + 1) == 0:
        hint = (f"; the {n_inputs + n_joints} columns fit "
                f"{(n_inputs + n_joints) // (per_joint + 1)} joints")
    raise ValueError(
        f"CollisionDetector(n_joints={n_joints}): {what} expects {per_joint} input "
        f"columns per joint ({per_joint * n_joints}) followed by {n_joints} currents, "
        f"but X has {n_inputs} input columns{hint}"
    )


def default_regressor(n_joints):
    """The paper's SP_P estimator for ``n_joints`` joints, without robot model.

    Eq. 17 with a zero parametric mean (no robot model is known here), the
    paper's :math:`\\sigma_v = 10^{-2}` and a support set of at most 5,000
    training rows (the size of the paper's :math:`D_{SDP}`, Sec. V-A), drawn
    with a fixed seed so that fitting twice gives the same detector.

    Parameters
    ----------
    n_joints : int
        Number of joints.

    Returns
    -------
    regressor : SemiParametricGPRegressor
        ``make_sp_p(None, n_joints, n_support=5000, random_state=0)``.

    Examples
    --------
    >>> default_regressor(2).n_support
    5000
    """
    from ..gp import make_sp_p

    return make_sp_p(None, n_joints, n_support=5000, random_state=0)


def _valid_sigma_v(sigma_v):
    """Whether ``sigma_v`` passes :func:`~sklearn_gpcd._gate.check_sigma_v` (None allowed)."""
    try:
        check_sigma_v(sigma_v, allow_none=True)
    except ValueError:
        return False
    return True
