"""Tuning of detection settings: ``GridSearchCV`` over whole recordings."""

import warnings
from numbers import Integral, Real

import numpy as np
from sklearn import config_context
from sklearn.base import BaseEstimator, MetaEstimatorMixin, _fit_context, clone
from sklearn.model_selection import GridSearchCV, GroupKFold
from sklearn.utils._param_validation import HasMethods, Interval
from sklearn.utils.validation import check_is_fitted

from .._persistence import VersionedStateMixin
from ..metrics import DetectionRefit, DetectionScorer, fold_means

METRICS = ("recall", "false_alarms_per_hour", "delay")


class CollisionThresholdCV(VersionedStateMixin, MetaEstimatorMixin, BaseEstimator):
    """Tune a :class:`CollisionDetector` on labelled recordings.

    A :class:`~sklearn.model_selection.GridSearchCV` with the detection
    scorer :class:`~sklearn_gpcd.metrics.DetectionScorer` and the refit rule
    :class:`~sklearn_gpcd.metrics.DetectionRefit`, under metadata routing
    (``labels``, ``groups`` and ``time`` reach each fold's ``fit``, the
    splitter and the scorer). Each fold trains on the collision-free rows of
    its training recordings and scores the held-out ones (folds never split
    a recording). The winner (:func:`~sklearn_gpcd.metrics.select_candidate`)
    **maximises recall, then minimises false alarms per hour, among the
    candidates with mean delay <= max_delay**; the means ignore undefined
    (NaN) folds.

    Parameters
    ----------
    detector : CollisionDetector
        Detector to tune (cloned).
    param_grid : dict or list of dicts
        Parameter names of ``detector`` mapped to lists of values, as in
        :class:`~sklearn.model_selection.GridSearchCV`.
    cv : int, cross-validation splitter or None, default=None
        ``None`` is ``GroupKFold(n_splits=min(5, n_recordings))``; an int is
        that many ``GroupKFold`` splits; a splitter gets ``groups``.
    max_delay : float, default=None
        Bound on the mean detection delay [s], also the detection window of
        each contact (alarms up to ``max_delay`` after the onset count).
    n_jobs : int, default=None
        Candidates x folds in parallel (joblib, any backend, e.g. dask).
    refit : bool, default=True
        Refit the best detector on all collision-free rows.

    Attributes
    ----------
    cv_results_ : dict of ndarray
        ``params``, and for each metric ``split<k>_test_<metric>``,
        ``mean_test_<metric>``, ``std_test_<metric>`` with metrics
        ``recall``, ``false_alarms_per_hour`` and ``delay`` (seconds, not
        negated).
    best_index_ : int
    best_params_ : dict
    best_estimator_ : CollisionDetector
        The refitted detector (when ``refit``).
    n_splits_ : int

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.linear_model import LinearRegression
    >>> from sklearn_gpcd.detection import (AlarmRule, CollisionDetector,
    ...                                     CollisionThresholdCV, stack_currents)
    >>> rng = np.random.default_rng(0)
    >>> qd = rng.normal(size=(3000, 1))
    >>> current = 2 * qd[:, 0] + 0.05 * rng.normal(size=3000)
    >>> labels = np.zeros(3000, dtype=int)
    >>> for k, start in enumerate(range(250, 3000, 500)):
    ...     current[start:start + 30] += 0.5           # six contacts
    ...     labels[start:start + 30] = k + 1
    >>> groups = np.repeat([0, 1, 2], 1000)             # three recordings
    >>> search = CollisionThresholdCV(
    ...     CollisionDetector(LinearRegression(), rules=AlarmRule()),
    ...     {"rules__contamination": [0.001, 0.05], "rules__min_duration": [1, 3]},
    ...     cv=3, max_delay=0.1)
    >>> search.fit(stack_currents(qd, current), labels, groups=groups).best_params_
    {'rules__contamination': 0.001, 'rules__min_duration': 3}
    >>> res = search.cv_results_
    >>> res["mean_test_recall"].tolist()     # every candidate finds all contacts
    [1.0, 1.0, 1.0, 1.0]
    >>> res["mean_test_false_alarms_per_hour"].round().tolist()
    [957.0, 798.0, 21223.0, 14681.0]
    """

    _parameter_constraints = {
        "detector": [HasMethods(["fit", "predict"])],
        "param_grid": [dict, list],
        "cv": [None, Interval(Integral, 2, None, closed="left"), HasMethods(["split"])],
        "max_delay": [None, Interval(Real, 0, None, closed="left")],
        "n_jobs": [None, Integral],
        "refit": ["boolean"],
    }

    def __init__(self, detector, param_grid, *, cv=None, max_delay=None, n_jobs=None, refit=True):
        self.detector = detector
        self.param_grid = param_grid
        self.cv = cv
        self.max_delay = max_delay
        self.n_jobs = n_jobs
        self.refit = refit

    @_fit_context(prefer_skip_nested_validation=False)
    def fit(self, X, y, *, groups, time=None):
        """Score every candidate and refit the best one.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
            Detector input (regressor inputs followed by the currents) of
            all recordings, stacked in time order.
        y : array-like of shape (n_samples,)
            Contact labels: 0 free, ``k > 0`` inside contact ``k``.
        groups : array-like of shape (n_samples,)
            Recording id of each row.
        time : array-like of shape (n_samples,), default=None
            Time stamps [s] of the rows, for each fold's ``sample_time``
            check (or "auto") and the delays and false alarms per hour
            (without: the detector's ``sample_time_``).

        Returns
        -------
        self : CollisionThresholdCV
        """
        X, labels, groups = np.asarray(X, dtype=float), np.asarray(y), np.asarray(groups)
        metadata = {"labels": labels, "groups": groups}
        if time is not None:
            metadata["time"] = np.asarray(time, dtype=float)
        for name, value in metadata.items():
            if value.shape != (X.shape[0],):
                raise ValueError(f"{name} must have shape ({X.shape[0]},), got {value.shape}")
        n_groups = np.unique(groups).size
        if n_groups < 2 or (isinstance(self.cv, Integral) and self.cv > n_groups):
            raise ValueError(f"groups holds {n_groups} recording id(s); cv={self.cv} needs at "
                             "least 2 recordings and one per fold")
        cv = self.cv
        if cv is None or isinstance(cv, Integral):
            cv = GroupKFold(n_splits=min(5, n_groups) if cv is None else cv)
        rule = DetectionRefit(self.max_delay)
        with config_context(enable_metadata_routing=True), warnings.catch_warnings():
            warnings.filterwarnings("ignore", "One or more of the test scores are non-finite")
            detector = clone(self.detector).set_fit_request(labels=True, groups=True, time=True)
            search = GridSearchCV(detector, self.param_grid, scoring=DetectionScorer(self.max_delay),
                                  refit=rule if self.refit else False, cv=cv, n_jobs=self.n_jobs,
                                  error_score="raise")
            search.fit(X, labels, **metadata)
        results = self.cv_results_ = {"params": search.cv_results_["params"]}
        for metric in METRICS:
            sign = 1.0 if metric == "recall" else -1.0
            for k in range(search.n_splits_):
                results[f"split{k}_test_{metric}"] = sign * search.cv_results_[
                    f"split{k}_test_{metric}"]
            results[f"mean_test_{metric}"], results[f"std_test_{metric}"] = fold_means(
                results, metric)
        self.n_splits_ = search.n_splits_
        self.best_index_ = search.best_index_ if self.refit else rule(search.cv_results_)
        self.best_params_ = results["params"][self.best_index_]
        if self.refit:
            self.best_estimator_ = search.best_estimator_
        return self

    def _best(self):
        check_is_fitted(self, "best_estimator_")
        return self.best_estimator_

    def score_samples(self, X, groups=None):
        """``score_samples`` of the best detector (see :class:`CollisionDetector`)."""
        return self._best().score_samples(X, groups)

    def decision_function(self, X, groups=None):
        """``decision_function`` of the best detector (see :class:`CollisionDetector`)."""
        return self._best().decision_function(X, groups)

    def predict(self, X, groups=None):
        """``predict`` of the best detector: +1 normal, -1 collision."""
        return self._best().predict(X, groups)
