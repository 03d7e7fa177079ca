"""Tuning of detection settings by grouped cross-validation over recordings."""

import warnings
from numbers import Integral

import numpy as np
from joblib import Parallel, delayed
from sklearn.base import BaseEstimator, MetaEstimatorMixin, clone
from sklearn.model_selection import GroupKFold, ParameterGrid
from sklearn.utils.validation import check_is_fitted

from .._persistence import VersionedStateMixin
from ..metrics import event_recall, false_alarms_per_hour, mean_detection_delay

METRICS = ("recall", "false_alarms_per_hour", "delay")


def select_candidate(recall, false_alarms, delay, max_delay=None):
    """Index of the best candidate under the detection rule.

    The rule, applied to cross-validated means:

    1. keep the candidates whose mean delay is at most ``max_delay`` (all of
       them when ``max_delay`` is None; when none qualifies, all of them,
       with a warning);
    2. among those, maximise the event recall;
    3. among the ties, minimise the false alarms per hour;
    4. among the ties, minimise the delay; then take the first.

    NaN counts as the worst value of its metric.

    Parameters
    ----------
    recall, false_alarms, delay : array-like of shape (n_candidates,)
        Mean event recall, false alarms per hour and detection delay.
    max_delay : float, default=None
        Bound on the delay, in the units of ``delay``.

    Returns
    -------
    index : int

    Examples
    --------
    >>> select_candidate([1.0, 1.0, 0.5], [3.0, 1.0, 0.0], [0.1, 0.3, 0.1])
    1
    >>> select_candidate([1.0, 1.0, 0.5], [3.0, 1.0, 0.0], [0.1, 0.3, 0.1],
    ...                  max_delay=0.2)
    0
    """
    recall = np.nan_to_num(np.asarray(recall, float), nan=-np.inf)
    false_alarms = np.nan_to_num(np.asarray(false_alarms, float), nan=np.inf)
    delay = np.nan_to_num(np.asarray(delay, float), nan=np.inf)
    keep = np.ones(recall.shape, dtype=bool)
    if max_delay is not None:
        keep = delay <= max_delay
        if not keep.any():
            warnings.warn(
                f"no candidate has a mean detection delay <= max_delay={max_delay}; "
                "selecting among all candidates",
                UserWarning,
            )
            keep[:] = True
    for values, sign in ((recall, -1.0), (false_alarms, 1.0), (delay, 1.0)):
        best = np.min(sign * values[keep])
        keep &= sign * values <= best
    return int(np.flatnonzero(keep)[0])


class DetectionRefit:
    """``refit`` callable for ``GridSearchCV`` with :func:`detection_scorers`.

    Picks the candidate by :func:`select_candidate` from ``cv_results_``
    (whose delay and false-alarm scores are negated by the scorers).

    Parameters
    ----------
    max_delay : float, default=None
        Bound on the mean detection delay in seconds.

    Examples
    --------
    >>> import numpy as np
    >>> results = {"mean_test_recall": np.array([1.0, 1.0]),
    ...            "mean_test_false_alarms_per_hour": np.array([-2.0, -1.0]),
    ...            "mean_test_delay": np.array([-0.1, -0.2])}
    >>> DetectionRefit()(results)
    1
    """

    def __init__(self, max_delay=None):
        self.max_delay = max_delay

    def __call__(self, cv_results):
        return select_candidate(
            cv_results["mean_test_recall"],
            -np.asarray(cv_results["mean_test_false_alarms_per_hour"]),
            -np.asarray(cv_results["mean_test_delay"]),
            self.max_delay,
        )


class CollisionThresholdCV(VersionedStateMixin, MetaEstimatorMixin, BaseEstimator):
    """Tune a :class:`CollisionDetector` on labelled recordings.

    Every candidate of ``param_grid`` is scored by grouped cross-validation:
    each fold trains the detector on the collision-free rows (label 0) of
    the training recordings and runs it on the held-out recordings, scored
    by :func:`~sklearn_gpcd.metrics.event_recall`,
    :func:`~sklearn_gpcd.metrics.false_alarms_per_hour` and
    :func:`~sklearn_gpcd.metrics.mean_detection_delay`. Folds never split a
    recording (``GroupKFold`` on the recording ids), so contiguous samples
    stay together and the filter and debounce restart per recording. The
    winner follows :func:`select_candidate`: **maximise recall, then minimise
    false alarms per hour, among the candidates with mean delay <=
    max_delay**.

    Candidates that differ only in their alarm rules (``rules`` or
    ``rules__...``: threshold rule and level, filter, debounce, regimes)
    share one regressor fit per fold; others, e.g. ``sigma_v`` or
    ``regressor__...``, refit it.

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
        Bound on the mean detection delay, in seconds; it is also the
        detection window of each contact (alarms up to ``max_delay`` after
        the onset count, even after the contact ended).
    n_jobs : int, default=None
        Folds x regressor settings evaluated in parallel (joblib). The jobs
        follow the active joblib backend, e.g. a dask cluster under
        ``joblib.parallel_config("dask")`` (user guide: *Running at scale*).
    refit : bool, default=True
        Refit the best detector on all collision-free rows.

    Attributes
    ----------
    cv_results_ : dict of ndarray
        ``params``, and for each metric ``split<k>_test_<metric>``,
        ``mean_test_<metric>``, ``std_test_<metric>`` with metrics
        ``recall``, ``false_alarms_per_hour`` and ``delay`` (seconds).
    best_index_ : int
        Candidate chosen by the rule.
    best_params_ : dict
        Its parameters.
    best_estimator_ : CollisionDetector
        The refitted detector (when ``refit``).
    n_splits_ : int
        Number of folds.

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

    def __init__(self, detector, param_grid, *, cv=None, max_delay=None, n_jobs=None, refit=True):
        self.detector = detector
        self.param_grid = param_grid
        self.cv = cv
        self.max_delay = max_delay
        self.n_jobs = n_jobs
        self.refit = refit

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
            Time stamps [s] of the rows. Each fold's detector checks (or,
            with ``sample_time="auto"``, takes) its sampling period from
            them, and the delays and false alarms per hour are measured on
            them; without ``time`` they use ``sample_time``.

        Returns
        -------
        self : CollisionThresholdCV
        """
        X = np.asarray(X, dtype=float)
        labels = np.asarray(y)
        groups = np.asarray(groups)
        if X.ndim != 2:
            raise ValueError(f"X must be 2-D (n_samples, n_columns), got shape {X.shape}")
        if time is not None:
            time = np.asarray(time, dtype=float)
        for name, value in (("y (labels)", labels), ("groups", groups), ("time", time)):
            if value is None:
                continue
            if value.shape != (X.shape[0],):
                raise ValueError(f"{name} must have shape ({X.shape[0]},), got {value.shape}")
        cv = self._splitter(groups)
        splits = list(cv.split(X, labels, groups))
        candidates = list(ParameterGrid(self.param_grid))
        if not candidates:
            raise ValueError("param_grid has no candidate")
        blocks = _group_by_fit(candidates)
        jobs = Parallel(n_jobs=self.n_jobs)(
            delayed(_evaluate_fold)(
                self.detector, heavy, [candidates[i] for i in members],
                X, labels, groups, train, test, self.max_delay, time,
            )
            for train, test in splits
            for heavy, members in blocks
        )
        scores = {m: np.full((len(splits), len(candidates)), np.nan) for m in METRICS}
        job = iter(jobs)
        for k in range(len(splits)):
            for _, members in blocks:
                for i, values in zip(members, next(job)):
                    for metric in METRICS:
                        scores[metric][k, i] = values[metric]
        self.cv_results_ = _results(candidates, scores)
        self.n_splits_ = len(splits)
        self.best_index_ = select_candidate(
            *(self.cv_results_[f"mean_test_{m}"] for m in METRICS), self.max_delay
        )
        self.best_params_ = candidates[self.best_index_]
        if self.refit:
            self.best_estimator_ = clone(self.detector).set_params(**self.best_params_)
            self.best_estimator_.fit(X, labels=labels, groups=groups, time=time)
        return self

    def _splitter(self, groups):
        n_groups = np.unique(groups).size
        if n_groups < 2:
            raise ValueError(
                f"groups holds {n_groups} recording id(s); grouped cross-validation "
                "needs at least 2 recordings"
            )
        if self.cv is None:
            return GroupKFold(n_splits=min(5, n_groups))
        if isinstance(self.cv, Integral):
            if not 2 <= self.cv <= n_groups:
                raise ValueError(f"cv={self.cv} folds need 2 <= cv <= {n_groups} recordings")
            return GroupKFold(n_splits=self.cv)
        return self.cv

    def _best(self):
        check_is_fitted(self, "best_estimator_")
        return self.best_estimator_

    def score_samples(self, X, groups=None):
        """``score_samples`` of the best detector.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
        groups : array-like of shape (n_samples,), default=None

        Returns
        -------
        scores : ndarray of shape (n_samples,)
        """
        return self._best().score_samples(X, groups)

    def decision_function(self, X, groups=None):
        """``decision_function`` of the best detector.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
        groups : array-like of shape (n_samples,), default=None

        Returns
        -------
        decision : ndarray of shape (n_samples,)
        """
        return self._best().decision_function(X, groups)

    def predict(self, X, groups=None):
        """``predict`` of the best detector (+1 normal, -1 collision).

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
        groups : array-like of shape (n_samples,), default=None

        Returns
        -------
        y_pred : ndarray of shape (n_samples,)
        """
        return self._best().predict(X, groups)


def _is_rule_param(name):
    """Whether a parameter acts after the regressor (an alarm rule's)."""
    return name == "rules" or name.startswith("rules__")


def _group_by_fit(candidates):
    """Blocks ``(heavy params, candidate indices)`` sharing a regressor fit."""
    blocks = []
    for i, params in enumerate(candidates):
        heavy = {k: v for k, v in params.items() if not _is_rule_param(k)}
        for block_heavy, members in blocks:
            if block_heavy.keys() == heavy.keys() and all(
                _same_param(block_heavy[k], heavy[k]) for k in heavy
            ):
                members.append(i)
                break
        else:
            blocks.append((heavy, [i]))
    return blocks


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


def _evaluate_fold(detector, heavy, lights, X, labels, groups, train, test, max_delay,
                   time=None):
    """Metrics of the candidates ``heavy | light`` for one train/test split."""
    base = clone(detector).set_params(**heavy)
    variants = [clone(base).set_params(**light) for light in lights]
    train_time = None if time is None else time[train]
    residuals = base.fit_residuals(
        X[train], labels=labels[train], groups=groups[train], time=train_time,
        return_std=any(v.needs_std(fitting=True) for v in variants))
    test_residuals = base.residuals(X[test], groups[test],
                                    return_std=any(v.needs_std() for v in variants))
    results = []
    for light in lights:
        variant = base.recalibrated(residuals, **{k: v for k, v in light.items()
                                                  if _is_rule_param(k)})
        alarms = variant.stages(test_residuals).alarms.any(axis=1)
        kwargs = dict(max_delay=max_delay, groups=groups[test])
        if time is None:
            kwargs["sample_time"] = variant.sample_time_
        else:
            kwargs["time"] = time[test]
        results.append(
            {
                "recall": event_recall(labels[test], alarms, **kwargs),
                "false_alarms_per_hour": false_alarms_per_hour(labels[test], alarms, **kwargs),
                "delay": mean_detection_delay(labels[test], alarms, **kwargs),
            }
        )
    return results


def _results(candidates, scores):
    results = {"params": candidates}
    for metric, values in scores.items():
        for k, row in enumerate(values):
            results[f"split{k}_test_{metric}"] = row
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns
            results[f"mean_test_{metric}"] = np.nanmean(values, axis=0)
            results[f"std_test_{metric}"] = np.nanstd(values, axis=0)
    return results
