"""Collision detection by thresholding the current residual (paper Sec. II-III)."""

import inspect
import warnings
from numbers import Integral, Real

import numpy as np
from sklearn.base import BaseEstimator, OutlierMixin, _fit_context, clone
from sklearn.frozen import FrozenEstimator
from sklearn.utils import Bunch
from sklearn.utils._param_validation import HasMethods, Interval, StrOptions
from sklearn.utils.validation import _num_samples, check_is_fitted, validate_data

from ..layout import block_columns
from .._gate import SIGMA_V_CONSTRAINT
from .._persistence import VersionedStateMixin
from ..gp import make_sp_p
from ._regimes import event_rows, ratio_over_level
from ._signal import recording_index, segment_starts
from .rules import AlarmRule

#: Relative deviation of ``sample_time`` from the data's median step that warns.
_SAMPLE_TIME_RTOL = 0.2


class SampleTimeWarning(UserWarning):
    """``CollisionDetector.sample_time`` differs from the data's sampling period.

    The filter, settle time and false-alarm rates are then all off by the
    same factor. Raised by :meth:`CollisionDetector.fit` when the median step
    of ``time`` differs by more than 20 %; ``sample_time="auto"`` takes it
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
    """Append the measured currents to the model inputs: the detector's input.

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
    """Proprioceptive collision detector: a residual model and alarm rules.

    **The residual model.** A regressor learns the motor currents of
    collision-free motion, ``i_hat = f(x)`` (the paper's estimator, Eq. 17);
    the residual :math:`s_l = i_l - \\hat{i}_l` (Sec. III) is optionally
    normalised by the predictive standard deviation (``normalize="std"``,
    :math:`u_l = s_l / \\sigma_l(x)`, a variance-aware band).

    **The alarm rules.** An :class:`~sklearn_gpcd.detection.AlarmRule`
    (filter, debounce, motion regimes, thresholds calibrated on the
    collision-free rows) fires joint ``l`` when its monitoring signal
    satisfies :math:`|m_l| > \\sigma_{CD,l}` for ``min_duration`` samples in
    a row (:math:`f_{CD}`, Sec. II). Several rules are several *bands* on one
    model (e.g. 2 Hz for pushes, 10 Hz for short taps): a sample is a
    collision when some joint fires in some band.

    **Input layout.** The measured currents are the **last** ``n_joints``
    **columns of** ``X``, after the regressor inputs (:func:`stack_currents`),
    so the detector keeps the outlier-detector API and sits in pipelines and
    grid searches (e.g. over ``sigma_v`` or ``rules__min_duration``).

    **Time series.** With no filter and ``min_duration=1`` (the default) each
    row is judged on its own; otherwise the rows are a time series sampled
    every ``sample_time`` seconds, restarted at each recording of ``groups``.

    **Calibration data.** A GP nearly interpolates its support points, so
    the residuals on the training rows understate those on new data:
    condition the GP on a subset (``n_support``, the paper's
    :math:`D_{SDP}`), or choose the thresholds on other recordings with
    :func:`~sklearn_gpcd.detection.calibrate_across_recordings`.

    **Scores** follow :class:`~sklearn.ensemble.IsolationForest`: with the
    debounced ratio ``r_l = |m_l| / scale_l`` of each band ``b`` and its level
    :math:`\\gamma_b`, ``decision_function`` is
    :math:`\\min_b (\\gamma_b - \\max_l r^{(b)}_l)`, negative for collisions,
    ``predict`` returns -1 there and +1 elsewhere, and ``score_samples =
    decision_function + offset_`` (with one rule, ``-max_l r_l``).

    Parameters
    ----------
    regressor : regressor, default=None
        Model of the collision-free currents, fitted (a clone) on
        ``(X[:, :-n_joints], X[:, -n_joints:])``. ``None``: the paper's SP_P
        estimator (:func:`default_regressor`), on the augmented inputs of
        Eq. 13 (``6 * n_joints`` columns). ``normalize="std"`` and
        ``threshold="std"`` need ``predict(..., return_std=True)``. Wrap a
        fitted model in :class:`sklearn.frozen.FrozenEstimator` to calibrate
        on it as it is.
    rules : AlarmRule or list of AlarmRule, default=None
        How the residual becomes alarms; a list for several bands. None is
        ``AlarmRule()``: no filter, no debounce, a contamination threshold.
    n_joints : int, default=1
        Number of joints, i.e. of trailing current columns in ``X``.
    normalize : {None, "std"}, default=None
        Divide the residual by the predictive std before the rules.
    sample_time : float or "auto", default=0.008
        Sampling period [s] of the filters, regimes and false-alarm rates
        (the paper's UR10 logs at 8 ms, the UR10e logs of Mamedov et al. at
        10 ms). ``"auto"`` takes the median time step of ``time`` passed to
        :meth:`fit`; a number more than 20 % off it warns
        (:class:`SampleTimeWarning`).
    sigma_v : float, default=None
        Velocity threshold of the quasi-static gate (Sec. IV-B, the paper
        uses ``1e-2``), passed on as the regressor's ``sigma_v`` (a frozen
        model keeps its own; None keeps the regressor's value) and used by
        the regimes (``1e-2`` when None). ``gpcd calibrate`` sets it to the
        value the model was trained with (``gpcd train --sigma-v``).
    velocity_columns : list of int or None, default=None
        Columns of the regressor inputs holding the joint velocities, for
        rules with regimes. None: the ``qd`` block of the paper's layout
        (:mod:`sklearn_gpcd.layout`), with ``3`` or ``6 * n_joints`` inputs.

    Attributes
    ----------
    regressor_ : regressor
        The fitted clone of ``regressor``.
    rules_ : list of AlarmRule
        The fitted rules, one per band.
    thresholds_ : ndarray of shape (n_joints,) or (n_regimes, n_joints)
        :math:`\\sigma_{CD}` per joint (and regime) of the first rule, in
        units of the monitoring signal (A, or standard deviations with
        ``normalize="std"``); likewise ``scale_``, ``margin_``,
        ``regime_names_`` and ``filter_coefficients_``.
    offset_ : float
        ``score_samples - decision_function``: :math:`-\\gamma` of the rule
        with one rule, 0 with several.
    sample_time_ : float
        Sampling period used (``sample_time``, or the data's with "auto").
    velocity_columns_, acceleration_columns_ : list of int or None
        Columns of the regressor inputs that the regimes read (accelerations
        with a braking limit).
    motion_columns_ : list of int or None
        Both, velocities first.
    n_features_in_ : int
        Columns of ``X`` seen in fit (regressor inputs plus currents).
    feature_names_in_ : ndarray of str
        Column names, when ``X`` had string column names.

    See Also
    --------
    AlarmRule : Filter, debounce, regimes and threshold rule.
    StreamingMonitor : The same decisions, one sample at a time.
    calibrate_across_recordings : Thresholds chosen across recordings.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.linear_model import Ridge
    >>> from sklearn_gpcd.detection import AlarmRule, CollisionDetector, stack_currents
    >>> rng = np.random.default_rng(0)
    >>> qd = rng.normal(size=(500, 1))
    >>> current = 2.0 * qd[:, 0] + 0.01 * rng.normal(size=500)
    >>> det = CollisionDetector(Ridge(), rules=AlarmRule(contamination=0.01))
    >>> det.fit(stack_currents(qd, current))
    CollisionDetector(regressor=Ridge(), rules=AlarmRule(contamination=0.01))
    >>> bumped = current.copy()
    >>> bumped[100] += 1.0                    # an external torque
    >>> pred = det.predict(stack_currents(qd, bumped))
    >>> bool(pred[100] == -1)
    True
    """

    _parameter_constraints = {
        "regressor": [None, HasMethods(["fit", "predict"])],
        "rules": [None, AlarmRule, list, tuple],
        "n_joints": [Interval(Integral, 1, None, closed="left")],
        "normalize": [None, StrOptions({"std"})],
        "sample_time": [StrOptions({"auto"}), Interval(Real, 0, None, closed="neither")],
        "sigma_v": [None, SIGMA_V_CONSTRAINT],
        "velocity_columns": [None, "array-like"],
    }

    def __init__(self, regressor=None, *, rules=None, n_joints=1, normalize=None,
                 sample_time=0.008, sigma_v=None, velocity_columns=None):
        self.regressor = regressor
        self.rules = rules
        self.n_joints = n_joints
        self.normalize = normalize
        self.sample_time = sample_time
        self.sigma_v = sigma_v
        self.velocity_columns = velocity_columns

    def alarm_rules(self):
        """The alarm rules of ``rules`` as a list, each checked (unfitted).

        Returns
        -------
        rules : list of AlarmRule
            Clones; ``[AlarmRule()]`` for ``rules=None``.

        Examples
        --------
        >>> from sklearn_gpcd.detection import AlarmRule, CollisionDetector
        >>> CollisionDetector().alarm_rules()
        [AlarmRule()]
        """
        rules = self.rules
        if rules is None:
            rules = [AlarmRule()]
        elif isinstance(rules, AlarmRule):
            rules = [rules]
        rules = list(rules)
        if not rules or not all(isinstance(rule, AlarmRule) for rule in rules):
            raise ValueError(f"rules must be an AlarmRule or a non-empty list of AlarmRule, "
                             f"got {self.rules!r}")
        return [clone(rule).check() for rule in rules]

    # ------------------------------------------------------------------ fit
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
        return self.calibrate(self.fit_residuals(X, labels=labels, groups=groups, time=time))

    @_fit_context(prefer_skip_nested_validation=False)
    def fit_residuals(self, X, *, labels=None, groups=None, time=None, return_std=None):
        """The residual model's half of :meth:`fit`: the regressor, on collision-free rows.

        Sets ``sample_time_`` and ``regressor_``; the residuals it returns are
        what :meth:`calibrate` turns into thresholds, once per setting when
        several rules are compared on one fitted model.

        Parameters
        ----------
        X, labels, groups, time
            As for :meth:`fit`.
        return_std : bool, default=None
            Also return the predictive std (None: where the calibration or
            the monitoring signal reads it).

        Returns
        -------
        residuals : Bunch
            ``residual`` and ``std`` (or None) of shape (n_rows, n_joints),
            ``starts`` (segment starts), ``motion`` (what the regimes read:
            velocities, then accelerations with a braking regime; None
            without regimes) and ``recordings`` (recording index of each row,
            None without ``groups``), for the collision-free rows.
        """
        rules = self.alarm_rules()
        self.sample_time_ = self._check_sample_time(time, groups, _num_samples(X))
        if return_std is None:
            return_std = self._needs_std(fitting=True)
        X = validate_data(self, X, dtype=np.float64)
        n = self.n_joints
        if X.shape[1] <= n:
            raise ValueError(
                f"X has {X.shape[1]} feature(s) but CollisionDetector(n_joints={n}) "
                f"needs the regressor inputs followed by {n} current column(s), i.e. "
                f"at least {n + 1} columns"
            )
        self._set_motion_columns(rules, X.shape[1] - n)
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
        mean, std = self._predict_currents(inputs, return_std, current=current, starts=starts)
        return Bunch(residual=current - mean, std=std, starts=starts, motion=self._motion(X),
                     recordings=recording_index(groups, labels))

    def calibrate(self, residuals):
        """The alarm rules' half of :meth:`fit`: thresholds from collision-free residuals.

        ``regressor_`` and ``sample_time_`` must be set, by :meth:`fit` or
        :meth:`fit_residuals` (possibly on a copy with other ``rules``).

        Parameters
        ----------
        residuals : Bunch
            What :meth:`fit_residuals` returned.

        Returns
        -------
        self : CollisionDetector
        """
        check_is_fitted(self, "regressor_")
        rules = self.alarm_rules()
        self._check_motion(rules)
        u = self._normalized(residuals.residual, residuals.std)
        return self.adopt_rules([
            rule.calibrate(u, residuals.starts, residuals.motion, sample_time=self.sample_time_,
                           sigma_v=self.sigma_v, std=residuals.std,
                           normalized=self.normalize == "std", recordings=residuals.recordings)
            for rule in rules])

    def adopt_rules(self, rules):
        """Take calibrated alarm rules as the detector's (``rules_``).

        What :meth:`calibrate` ends with; a calibration that fits the rules
        another way (from recordings' peaks, one recording at a time:
        :func:`~sklearn_gpcd.detection.calibrate_across_recordings` with
        ``folder``) hands them over here. ``regressor_`` and
        ``sample_time_`` must be set.

        Parameters
        ----------
        rules : list of AlarmRule
            Calibrated (``thresholds_`` and the rest set), one per band.

        Returns
        -------
        self : CollisionDetector
            With ``rules_``, and the first rule's thresholds as its own.

        Examples
        --------
        >>> import numpy as np
        >>> from sklearn.linear_model import LinearRegression
        >>> from sklearn_gpcd.detection import AlarmRule, CollisionDetector, stack_currents
        >>> qd = np.random.default_rng(0).normal(size=(200, 1))
        >>> det = CollisionDetector(LinearRegression(), sample_time=0.01,
        ...                         rules=AlarmRule("per_joint", false_alarm_rate=0.0))
        >>> det = det.fit(stack_currents(qd, 2 * qd[:, 0]))
        >>> det.adopt_rules(det.rules_).thresholds_ is det.rules_[0].thresholds_
        True
        """
        self.rules_ = list(rules)
        first = self.rules_[0]
        for name in ("filter_coefficients_", "regime_names_", "scale_", "margin_",
                     "thresholds_"):
            setattr(self, name, getattr(first, name))
        self.offset_ = first.offset_ if len(self.rules_) == 1 else 0.0
        return self

    def _normalized(self, residual, std):
        """The residual over the predictive std with ``normalize="std"``."""
        return residual / std if self.normalize == "std" else residual

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

    def _set_motion_columns(self, rules, n_inputs):
        """``velocity_columns_``, ``acceleration_columns_`` and ``motion_columns_``:
        what the rules' regimes read of the regressor inputs."""
        regimes = [rule.regimes for rule in rules if rule.regimes is not None]
        self.velocity_columns_ = self.acceleration_columns_ = self.motion_columns_ = None
        if not regimes:
            return
        if self.velocity_columns is not None:
            columns = [int(c) for c in self.velocity_columns]
            if len(columns) != self.n_joints or not all(0 <= c < n_inputs for c in columns):
                raise ValueError(
                    f"velocity_columns must list {self.n_joints} column indices below "
                    f"{n_inputs} (the regressor inputs), got {self.velocity_columns!r}"
                )
            self.velocity_columns_ = columns
        else:
            self.velocity_columns_ = self._layout_block(
                "qd", n_inputs, "regimes need the joint velocities", "; pass velocity_columns")
        if any(r.reads_accelerations for r in regimes):
            self.acceleration_columns_ = self._layout_block(
                "qdd", n_inputs, "brake_limit needs the joint accelerations",
                ", the qdd block after q and qd")
        self.motion_columns_ = self.velocity_columns_ + list(self.acceleration_columns_ or [])

    def _check_motion(self, rules):
        """ValueError when some rule reads motion that the fit did not keep."""
        for rule in rules:
            if rule.regimes is None:
                continue
            if self.velocity_columns_ is None or (rule.regimes.reads_accelerations
                                                  and self.acceleration_columns_ is None):
                raise ValueError("a rule with regimes (or a braking limit) was added after "
                                 "fit_residuals; fit the detector with it")

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
        """What the regimes read of validated rows (None without regimes)."""
        if self.motion_columns_ is None:
            return None
        return X[:, self.motion_columns_]

    def fit_predict(self, X, y=None, *, labels=None, groups=None):
        """Fit, then label the same rows (+1 normal, -1 collision).

        Parameters
        ----------
        X, y, labels, groups
            As for :meth:`fit`.

        Returns
        -------
        y_pred : ndarray of shape (n_samples,)
        """
        return self.fit(X, labels=labels, groups=groups).predict(X, groups=groups)

    def _inputs(self, X):
        """Regressor inputs: all but the current columns, as a DataFrame when X had
        names (kernels may select columns by name, e.g. ``ARDRBF(columns=["qd_0"])``)."""
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
        """Whether the monitoring signal (or, ``fitting``, the calibration, where
        rules with ``threshold="std"`` read it) reads the predictive std."""
        if self.normalize == "std":
            return True
        return fitting and any(rule.needs_std for rule in self.alarm_rules())

    def _predict_currents(self, inputs, return_std, current=None, starts=None):
        """Predicted currents and (optionally) predictive std, both (n, n_joints); a
        model that :func:`reads_currents` gets them and each row's recording (``starts``)."""
        n_rows = inputs.shape[0]
        regressor = self.regressor_
        extra = {}
        if reads_currents(regressor):
            extra = _dynamic_model_arguments(current, starts, n_rows)
        if return_std:
            if "return_std" not in inspect.signature(regressor.predict).parameters:
                raise ValueError(
                    f"normalize={self.normalize!r} / threshold='std' need "
                    f"the predictive std, but {type(regressor).__name__}.predict has "
                    "no return_std argument; use a Gaussian process regressor"
                )
            mean, std = regressor.predict(inputs, return_std=True, **extra)
            std = np.reshape(np.asarray(std, dtype=float), (n_rows, self.n_joints))
            std = np.maximum(std, np.finfo(float).tiny)
        else:
            mean, std = regressor.predict(inputs, **extra), None
        return np.reshape(np.asarray(mean, dtype=float), (n_rows, self.n_joints)), std

    # ------------------------------------------------------------- predict
    def residuals(self, X, groups=None, *, return_std=None):
        """The residual model on new rows: predicted currents and residuals.

        Parameters
        ----------
        X, groups
            As for :meth:`monitoring_signal`.
        return_std : bool, default=None
            Also the predictive std (None: where the monitoring signal reads
            it).

        Returns
        -------
        residuals : Bunch
            ``predicted``, ``std`` (or None) and ``residual`` of shape
            (n_samples, n_joints), ``starts`` (segment starts) and ``motion``
            (see :meth:`fit_residuals`).
        """
        check_is_fitted(self)
        X = validate_data(self, X, dtype=np.float64, reset=False)
        if return_std is None:
            return_std = self._needs_std()
        starts = segment_starts(X.shape[0], groups)
        predicted, std = self._predict_currents(self._inputs(X), return_std,
                                                current=X[:, -self.n_joints:], starts=starts)
        return Bunch(predicted=predicted, std=std, residual=X[:, -self.n_joints:] - predicted,
                     starts=starts, motion=self._motion(X))

    def stages(self, residuals):
        """Every rule's stages on residuals already predicted (see :meth:`residuals`).

        Parameters
        ----------
        residuals : Bunch
            From :meth:`residuals` (or :meth:`fit_residuals`).

        Returns
        -------
        result : Bunch
            ``bands``: one Bunch per rule with ``signal`` (``m``: normalised,
            filtered, re-referenced at rest), ``regime`` (code per sample),
            ``reference`` (the rest reference subtracted, or None), ``ratio``
            (debounced ``|m|`` over the scale of the sample's regime),
            ``alarms`` and ``level`` (the rule's :math:`\\gamma`); ``alarms``
            (bool, (n_samples, n_joints): joints that fired in some band),
            ``score`` and ``decision`` (the :meth:`score_samples` and
            :meth:`decision_function` values), ``event`` (bool,
            (n_samples,): the rows of a contact event, one per contact:
            :class:`~sklearn_gpcd.detection.EventHold` on each joint's ratio
            over its band's level) and ``event_onset`` (bool, (n_samples,):
            where an event begins; two contacts can follow with no row
            between them). With one rule its stages are also at the top
            level.
        """
        u = self._normalized(residuals.residual, residuals.std)
        bands = [Bunch(level=-float(rule.offset_),
                       **rule.stages(u, residuals.starts, residuals.motion))
                 for rule in self.rules_]
        alarms = np.logical_or.reduce([band.alarms for band in bands])
        event, onset = self._events(bands, residuals.starts)
        if len(bands) == 1:
            score = -bands[0].ratio.max(axis=1)
            out = Bunch(bands=bands, alarms=alarms, score=score,
                        decision=score - self.offset_, event=event, event_onset=onset)
            out.update({k: v for k, v in bands[0].items() if k not in ("level", "alarms")})
            return out
        decision = np.min([band.level - band.ratio.max(axis=1) for band in bands], axis=0)
        return Bunch(bands=bands, alarms=alarms, score=decision, decision=decision, event=event,
                     event_onset=onset)

    def _events(self, bands, starts):
        """Rows of a contact event and rows where one begins: :func:`event_rows`
        on each joint's largest ratio over its band's level (1: at its threshold)."""
        return event_rows(ratio_over_level(bands), starts,
                          self.rules_[0].event_hold_samples())

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
            ``predicted`` (``i_hat``), ``std`` (predictive std, or None when
            not needed) and ``residual`` (``s = i - i_hat``), of shape
            (n_samples, n_joints), and what :meth:`stages` returns.

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
        r = self.residuals(X, groups)
        return Bunch(predicted=r.predicted, std=r.std, residual=r.residual,
                     **self.stages(r))

    def decision_function(self, X, groups=None):
        """:math:`\\min_b (\\gamma_b - \\max_l r^{(b)}_l)`: negative for collisions.

        Parameters
        ----------
        X, groups
            As for :meth:`monitoring_signal`.

        Returns
        -------
        decision : ndarray of shape (n_samples,)
        """
        return self.monitoring_signal(X, groups).decision

    def score_samples(self, X, groups=None):
        """Normality score ``decision_function + offset_`` (higher = more normal).

        With one rule, ``-max_l r_l``.

        Parameters
        ----------
        X, groups
            As for :meth:`monitoring_signal`.

        Returns
        -------
        scores : ndarray of shape (n_samples,)
        """
        return self.monitoring_signal(X, groups).score

    def predict(self, X, groups=None):
        """+1 for collision-free samples, -1 for collisions.

        Parameters
        ----------
        X, groups
            As for :meth:`monitoring_signal`.

        Returns
        -------
        y_pred : ndarray of shape (n_samples,)
            -1 where some joint fired in some band: where
            :meth:`decision_function` is negative (the rows of a contact
            *event*, which outlasts its alarms by the release hold, are
            :meth:`monitoring_signal`'s ``event``).
        """
        return np.where(self.monitoring_signal(X, groups).alarms.any(axis=1), -1, 1)

    def predict_joints(self, X, groups=None):
        """Which joints fired (in some band), per sample (the paper's per-component test).

        A sample is a collision (:meth:`predict` gives -1) exactly when at
        least one of its joints fired.

        Parameters
        ----------
        X, groups
            As for :meth:`monitoring_signal`.

        Returns
        -------
        fired : ndarray of bool, shape (n_samples, n_joints)
        """
        return self.monitoring_signal(X, groups).alarms


def reads_currents(model):
    """Whether a residual model's ``predict`` reads the measured currents.

    A dynamic residual model (the momentum observer,
    :class:`~sklearn_gpcd.dynamics.MomentumObserver`) computes a sample's
    expected current from the measured currents up to it in its recording:
    its ``predict`` takes them as ``current`` and the recording of each row
    as ``groups``, which :class:`CollisionDetector` passes (a gap left by
    ``labels`` starts a new recording). :class:`StreamingMonitor` does not
    run such a model (it has its own per-tick state).

    Parameters
    ----------
    model : estimator
        A regressor, possibly wrapped in :class:`sklearn.frozen.FrozenEstimator`.

    Returns
    -------
    reads : bool
        True when ``model.predict`` has a ``current`` parameter.

    Examples
    --------
    >>> from sklearn.linear_model import Ridge
    >>> from sklearn_gpcd.dynamics import MomentumObserver
    >>> reads_currents(Ridge()), reads_currents(MomentumObserver())
    (False, True)
    """
    predict = getattr(model, "predict", None)
    if predict is None:
        return False
    try:
        return "current" in inspect.signature(predict).parameters
    except (TypeError, ValueError):
        return False


def _dynamic_model_arguments(current, starts, n_rows):
    """``current`` and ``groups`` (recording of each row, from the segment starts) for
    a model that :func:`reads_currents`."""
    if current is None:
        raise ValueError("this residual model reads the measured currents; call it "
                         "through CollisionDetector, which passes them")
    groups = np.zeros(n_rows, dtype=np.intp)
    if starts is not None and len(starts) > 1:
        groups[np.asarray(starts[1:], dtype=np.intp)] = 1
        groups = np.cumsum(groups)
    return {"current": np.asarray(current, dtype=float), "groups": groups}


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

    Eq. 17 with a zero parametric mean, the paper's :math:`\\sigma_v =
    10^{-2}` and at most 5,000 support rows (the size of the paper's
    :math:`D_{SDP}`, Sec. V-A), drawn with a fixed seed.

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
    return make_sp_p(None, n_joints, n_support=5000, random_state=0)
