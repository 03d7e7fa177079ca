"""Collision detection by thresholding the current residual (paper Sec. II-III)."""

import inspect
from numbers import Integral, Real

import numpy as np
from sklearn.base import BaseEstimator, OutlierMixin, clone
from sklearn.utils import Bunch
from sklearn.utils.validation import check_is_fitted, validate_data

from .._persistence import VersionedStateMixin
from ._signal import (
    debounce_segments,
    filter_segments,
    lowpass_coefficients,
    segment_starts,
)
from ._thresholds import contamination_level, false_alarm_level, rms_scale

_THRESHOLD_RULES = ("contamination", "false_alarm_rate", "std")


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
    normalize : {None, "std"}, default=None
        Divide the residual by the predictive std before filtering.
    filter_cutoff : float, default=None
        Cut-off frequency of the causal low-pass filter in Hz (``None``: no
        filter).
    filter_order : {1, 2}, default=1
        First-order lag or second-order Butterworth filter.
    min_duration : int, default=1
        Samples the band must be exceeded in a row before a joint fires.
    sample_time : float, default=0.008
        Sampling period in seconds (the paper's UR10 logs at 8 ms); used by
        the filter and by ``threshold="false_alarm_rate"``.
    sigma_v : float, default=None
        Velocity threshold of the quasi-static gate (Sec. IV-B, the paper uses
        ``1e-2``). When set, it is passed on as the regressor's ``sigma_v``
        parameter; ``None`` keeps the regressor's own value.

    Attributes
    ----------
    regressor_ : regressor
        The fitted clone of ``regressor``.
    scale_ : ndarray of shape (n_joints,)
        Per-joint scale of the monitoring signal (see ``threshold``).
    offset_ : float
        ``-gamma``: a joint fires when ``|m_l| / scale_l > -offset_``.
    thresholds_ : ndarray of shape (n_joints,)
        ``sigma_CD`` per joint, in units of the monitoring signal (current
        units, or standard deviations when ``normalize="std"``).
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
        normalize=None,
        filter_cutoff=None,
        filter_order=1,
        min_duration=1,
        sample_time=0.008,
        sigma_v=None,
    ):
        self.regressor = regressor
        self.n_joints = n_joints
        self.threshold = threshold
        self.contamination = contamination
        self.false_alarm_rate = false_alarm_rate
        self.k = k
        self.normalize = normalize
        self.filter_cutoff = filter_cutoff
        self.filter_order = filter_order
        self.min_duration = min_duration
        self.sample_time = sample_time
        self.sigma_v = sigma_v

    # ------------------------------------------------------------------ fit
    def fit(self, X, y=None, *, labels=None, groups=None):
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

        Returns
        -------
        self : CollisionDetector
        """
        residual, std, starts = self._fit_regressor(
            X, labels, groups, self._needs_std(fitting=True)
        )
        self._calibrate(residual, std, starts)
        return self

    def _fit_regressor(self, X, labels, groups, return_std):
        """Fit ``regressor_`` on the collision-free rows; their residuals and starts."""
        self._validate_params()
        X = validate_data(self, X, dtype=np.float64)
        n = self.n_joints
        if X.shape[1] <= n:
            raise ValueError(
                f"X has {X.shape[1]} feature(s) but CollisionDetector(n_joints={n}) "
                f"needs the regressor inputs followed by {n} current column(s), i.e. "
                f"at least {n + 1} columns"
            )
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
        self.regressor_ = self._make_regressor()
        self.regressor_.fit(inputs, current[:, 0] if n == 1 else current)
        mean, std = self._predict_currents(inputs, return_std)
        return current - mean, std, starts

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
            "normalize": self.normalize in (None, "std"),
            "filter_cutoff": self.filter_cutoff is None
            or (isinstance(self.filter_cutoff, Real) and self.filter_cutoff > 0.0),
            "filter_order": self.filter_order in (1, 2),
            "min_duration": isinstance(self.min_duration, Integral) and self.min_duration >= 1,
            "sample_time": isinstance(self.sample_time, Real) and self.sample_time > 0.0,
            "sigma_v": self.sigma_v is None
            or (isinstance(self.sigma_v, Real) and self.sigma_v > 0.0),
        }
        allowed = {
            "n_joints": "an int >= 1",
            "threshold": f"one of {_THRESHOLD_RULES}",
            "contamination": "a float in (0, 0.5]",
            "false_alarm_rate": "a float >= 0 (alarms per hour)",
            "k": "a float > 0",
            "normalize": "None or 'std'",
            "filter_cutoff": "None or a float > 0 (Hz)",
            "filter_order": "1 or 2",
            "min_duration": "an int >= 1 (samples)",
            "sample_time": "a float > 0 (seconds)",
            "sigma_v": "None or a float > 0 (rad/s)",
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

    def _make_regressor(self):
        if self.regressor is None:
            regressor = default_regressor(self.n_joints)
        else:
            regressor = clone(self.regressor)
        if self.sigma_v is not None:
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
    def _signal(self, residual, std, starts):
        """Monitoring signal m: normalised, then low-pass filtered residual."""
        u = residual / std if self.normalize == "std" else residual
        if self.filter_coefficients_ is not None:
            u = filter_segments(u, *self.filter_coefficients_, starts)
        return u

    def _ratio(self, signal, starts):
        """Debounced ratio r_l = min over min_duration samples of |m_l| / scale_l."""
        return debounce_segments(np.abs(signal) / self.scale_, self.min_duration, starts)

    def _calibrate(self, residual, std, starts):
        """Set filter_coefficients_, scale_, offset_ and thresholds_ from training residuals."""
        self.filter_coefficients_ = None
        if self.filter_cutoff is not None:
            self.filter_coefficients_ = lowpass_coefficients(
                self.filter_cutoff, self.sample_time, self.filter_order
            )
        signal = self._signal(residual, std, starts)
        if self.threshold == "std":
            self.scale_ = np.ones(self.n_joints) if self.normalize == "std" else rms_scale(std)
            gamma = float(self.k)
        else:
            self.scale_ = rms_scale(signal)
            peak = self._ratio(signal, starts).max(axis=1)
            if self.threshold == "contamination":
                gamma = contamination_level(peak, self.contamination)
            else:
                gamma = false_alarm_level(peak, starts, self.sample_time, self.false_alarm_rate)
        self.offset_ = -gamma
        self.thresholds_ = gamma * self.scale_

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
            normalised and filtered), ``ratio`` (debounced ``|m| / scale_``)
            and ``alarms`` (bool, joints that fired).

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
        signal = self._signal(residual, std, starts)
        ratio = self._ratio(signal, starts)
        return Bunch(
            predicted=predicted,
            std=std,
            residual=residual,
            signal=signal,
            ratio=ratio,
            alarms=ratio > -self.offset_,
        )

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
