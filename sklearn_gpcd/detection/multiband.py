"""Several signal chains on one model: alarm when any band does.

A collision shows in the current residual as a pulse whose length depends
on the contact: a push lasts a second, a tap on a link a tenth of one. The
paper's monitoring signal is one low-pass filtered, debounced residual
(Sec. III); a low cut-off (2 Hz) keeps the band quiet but halves a
0.1-0.2 s pulse, a high one catches the pulse but passes more of the
collision-free transients. On the UR10e's ``collision_detection_data_2020``
four of the six collisions the 2 Hz rule misses are such taps on link 2
(:ref:`results-real-ur10e`, "Short contacts need a faster band").

:class:`MultiBandDetector` runs the same detector rule several times on one
fitted model -- each band with its own filter, debounce and calibrated
thresholds (``bands``: parameter overrides of a
:class:`~sklearn_gpcd.detection.CollisionDetector`) -- and a sample is a
collision when any band says so. The regressor is fitted once; the other
bands calibrate on it frozen (:class:`sklearn.frozen.FrozenEstimator`), from
its one prediction of the training rows when they differ from the first band
only in settings applied after the regressor.
:class:`MultiBandMonitor` makes the same decisions one sample at a time with
one prediction per tick. This composition is ours, not the paper's.
"""

import copy

import numpy as np
from sklearn.base import BaseEstimator, OutlierMixin, clone
from sklearn.frozen import FrozenEstimator
from sklearn.utils import Bunch
from sklearn.utils.validation import check_is_fitted, validate_data

from .._persistence import VersionedStateMixin
from ._signal import recording_index, segment_starts
from ..metrics import alarm_onsets
from .calibration import (
    _calibration_result,
    _CandidateRuns,
    _candidates,
    _folds,
    _held_out_alarm,
    _selection_score,
)
from .detector import CollisionDetector, _post_processing_settings
from .streaming import MonitorStatus, StreamingMonitor

__all__ = ["MultiBandDetector", "MultiBandMonitor", "calibrate_bands_across_recordings"]


class MultiBandDetector(VersionedStateMixin, OutlierMixin, BaseEstimator):
    """Alarm when any of several bands of one collision detector does.

    Band :math:`b` is ``clone(detector).set_params(**bands[b])``: the same
    model of the collision-free currents, its own monitoring signal
    :math:`m^{(b)}` (filter, debounce, regimes) and thresholds
    :math:`\\gamma_b\\, \\sigma^{(b)}_{g\\ell}` calibrated on the training
    rows by the detector's own rule. Sample :math:`k` is a collision when

    .. math::

        \\exists\\, b, \\ell: \\quad
        r^{(b)}_{k\\ell} = \\frac{\\min_{j \\in \\text{debounce}_b}
        |m^{(b)}_{j\\ell}|}{\\sigma^{(b)}_{g_k \\ell}} > \\gamma_b,

    so ``score_samples`` is :math:`\\min_b (\\gamma_b - \\max_\\ell
    r^{(b)}_{k\\ell})` and ``offset_`` is 0: negative exactly when some band
    alarms.

    Parameters
    ----------
    detector : CollisionDetector, default=None
        The template: regressor, joints and every setting the bands do not
        override. ``None`` is ``CollisionDetector()``.
    bands : list of dict, default=({}, {"filter_cutoff": 10.0, \
"filter_order": 1, "min_duration": 2})
        Parameter overrides per band (any :class:`CollisionDetector`
        parameter but ``regressor`` and ``n_joints``). The default adds a
        10 Hz first-order band with a 2-sample debounce to the template's
        own settings (2 Hz, 5 samples by default). The first band's
        regressor is fitted; the others use it frozen.

    Attributes
    ----------
    detectors_ : list of CollisionDetector
        The fitted bands, in the order of ``bands``.
    regressor_ : regressor
        The fitted model (the first band's), shared by all.
    n_features_in_ : int
    feature_names_in_ : ndarray of str
        Defined when ``X`` has string column names.
    offset_ : float
        0.0 (see above).

    See Also
    --------
    CollisionDetector : One band.
    MultiBandMonitor : The same decisions one sample at a time.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.linear_model import LinearRegression
    >>> from sklearn_gpcd.detection import CollisionDetector, stack_currents
    >>> rng = np.random.default_rng(0)
    >>> x = rng.normal(size=(2000, 1))
    >>> current = 2.0 * x[:, 0] + 0.05 * rng.normal(size=2000)
    >>> template = CollisionDetector(LinearRegression(), sample_time=0.01,
    ...                              filter_cutoff=2.0, min_duration=5)
    >>> det = MultiBandDetector(template).fit(stack_currents(x, current))
    >>> [d.filter_cutoff for d in det.detectors_]
    [2.0, 10.0]
    >>> tap = current.copy()
    >>> tap[1000:1010] += 1.0                      # a 0.1 s pulse of 1 A
    >>> out = det.monitoring_signal(stack_currents(x, tap))
    >>> [int(band.alarms.any(axis=1).sum()) for band in out.bands]   # samples per band
    [32, 17]
    >>> bool(np.array_equal(out.alarms, out.bands[0].alarms | out.bands[1].alarms))
    True
    """

    def __init__(self, detector=None, bands=({}, {"filter_cutoff": 10.0, "filter_order": 1,
                                                   "min_duration": 2})):
        self.detector = detector
        self.bands = bands

    def _band_templates(self):
        """One unfitted CollisionDetector per band (parameters checked)."""
        template = CollisionDetector() if self.detector is None else self.detector
        if not isinstance(template, CollisionDetector):
            raise TypeError(f"detector must be a CollisionDetector, got "
                            f"{type(template).__name__}")
        bands = self.bands
        if (not isinstance(bands, (list, tuple)) or not bands
                or not all(isinstance(b, dict) for b in bands)):
            raise ValueError(f"bands must be a non-empty list of dicts of CollisionDetector "
                             f"parameters, got {bands!r}")
        known = set(template.get_params(deep=False)) - {"regressor", "n_joints"}
        for band in bands:
            if (unknown := sorted(set(band) - known)):
                raise ValueError(
                    f"bands: {unknown[0]!r} is not a parameter a band may set (one of "
                    f"{sorted(known)}; the regressor and n_joints are shared)"
                )
        return [clone(template).set_params(**band) for band in bands]

    def fit(self, X, y=None, *, labels=None, groups=None, time=None):
        """Fit the model once (first band) and calibrate every band on it.

        The regressor predicts the training rows once: a band whose settings
        differ from the first band's only in settings applied after the
        regressor (threshold rule and level, filter, debounce, settle time,
        rest reference) calibrates on the first band's residuals; one that
        differs before it (e.g. ``sample_time``, ``brake_limit``) predicts
        them again.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
            Regressor inputs followed by the measured currents.
        y : None
            Ignored.
        labels, groups, time
            As in :meth:`CollisionDetector.fit`, passed to every band.

        Returns
        -------
        self : MultiBandDetector
        """
        first, *others = self._band_templates()
        need_std = any(band._needs_std(fitting=True) for band in (first, *others))
        fitted = first._fit_residuals(X, labels, groups, time, need_std)
        recordings = recording_index(groups, labels)
        first._calibrate(*fitted, recordings)
        frozen = FrozenEstimator(first.regressor_)
        bands = [first]
        for band in others:
            band.set_params(regressor=frozen)
            settings = _post_processing_settings(first, band)
            if settings is None:  # differs before the regressor: its own prediction
                band.fit(X, labels=labels, groups=groups, time=time)
            else:  # the first band's residuals, this band's post-processing
                band = copy.copy(first).set_params(regressor=frozen, **settings)
                band.regressor_ = frozen
                band._validate_params()
                band._calibrate(*fitted, recordings)
            bands.append(band)
        return self._adopt(bands)

    def _adopt(self, detectors):
        """Set the fitted attributes from fitted bands (one model)."""
        first = detectors[0]
        self.detectors_ = list(detectors)
        self.regressor_ = first.regressor_
        self.n_features_in_ = first.n_features_in_
        if hasattr(first, "feature_names_in_"):
            self.feature_names_in_ = first.feature_names_in_
        self.offset_ = 0.0
        return self

    def monitoring_signal(self, X, groups=None):
        """Every stage of every band for the rows of ``X`` (one prediction).

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
        groups : array-like of shape (n_samples,), default=None

        Returns
        -------
        result : Bunch
            ``predicted``, ``std`` and ``residual`` (shared), ``bands`` (one
            Bunch per band with ``signal``, ``regime``, ``reference``,
            ``ratio``, ``alarms`` and ``level``, the band's :math:`\\gamma_b`)
            and ``alarms`` (bool, shape (n_samples, n_joints): joints that
            fired in some band).
        """
        check_is_fitted(self)
        first = self.detectors_[0]
        X = validate_data(self, X, dtype=np.float64, reset=False)
        starts = segment_starts(X.shape[0], groups)
        need_std = any(d._needs_std() for d in self.detectors_)
        predicted, std, residual = first._residual(X, need_std)
        bands = [Bunch(level=-float(det.offset_), **det._stages(X, residual, std, starts))
                 for det in self.detectors_]
        alarms = np.logical_or.reduce([band.alarms for band in bands])
        return Bunch(predicted=predicted, std=std, residual=residual, bands=bands,
                     alarms=alarms)

    def score_samples(self, X, groups=None):
        """Normality score :math:`\\min_b (\\gamma_b - \\max_\\ell r^{(b)}_\\ell)`.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
        groups : array-like of shape (n_samples,), default=None

        Returns
        -------
        scores : ndarray of shape (n_samples,)
        """
        out = self.monitoring_signal(X, groups)
        return np.min([band.level - band.ratio.max(axis=1) for band in out.bands], axis=0)

    def decision_function(self, X, groups=None):
        """``score_samples - offset_``: negative for collisions.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
        groups : array-like of shape (n_samples,), default=None

        Returns
        -------
        decision : ndarray of shape (n_samples,)
        """
        return self.score_samples(X, groups) - self.offset_

    def predict(self, X, groups=None):
        """+1 for collision-free samples, -1 where some band alarms.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
        groups : array-like of shape (n_samples,), default=None

        Returns
        -------
        y_pred : ndarray of shape (n_samples,)
        """
        return np.where(self.monitoring_signal(X, groups).alarms.any(axis=1), -1, 1)

    def predict_joints(self, X, groups=None):
        """Joints that fired in some band, per sample.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs + n_joints)
        groups : array-like of shape (n_samples,), default=None

        Returns
        -------
        fired : ndarray of bool, shape (n_samples, n_joints)
        """
        return self.monitoring_signal(X, groups).alarms


def calibrate_bands_across_recordings(detector, blocks, times, rule="global",
                                      band_grid=None):
    """:func:`~sklearn_gpcd.detection.calibrate_across_recordings` for every band;
    nested false alarms of their union.

    Each band of ``detector`` is calibrated across the recordings on its own
    (leave-one-recording-out margin, levels on all of them). Recording ``r``
    is then scored as the monitor will run: it alarms where **any** band
    alarms with that band's margin and levels chosen without ``r``
    (:func:`~sklearn_gpcd.detection.nested_alarms`), and the onsets of that
    union are its nested false alarms. Counting each band's onsets apart
    would miss that a second band adds alarms where the first is quiet, and
    count twice an excursion both see.

    With ``band_grid`` the settings of the **last** band are chosen too, the
    way :func:`~sklearn_gpcd.detection.calibrate_across_recordings` chooses
    settings, but for the union: the candidate with the fewest nested onsets
    of the union on the calibration recordings, then the smallest
    time-weighted mean log threshold of the last band, :math:`J`. A fast
    band picked by looking at the recordings it is scored on would promise
    fewer false alarms than it delivers; here recording ``r`` is scored with
    the candidate chosen on the other recordings alone (ranked there, its
    margins and levels calibrated there), so the nested figure never saw
    ``r`` even through the choice of band.

    The regressor predicts each recording once for every band and candidate
    whose settings differ from the first band's only in settings applied
    after the regressor (threshold rule and level, filter, debounce, settle
    time, rest reference); a band that differs before it (e.g.
    ``sample_time``, ``brake_limit``) predicts on its own.

    Parameters
    ----------
    detector : MultiBandDetector
        Unfitted; its template has ``threshold="per_joint"``,
        ``false_alarm_rate=0`` and a regressor wrapped in
        :class:`sklearn.frozen.FrozenEstimator` (as for
        :func:`~sklearn_gpcd.detection.calibrate_across_recordings`).
    blocks, times, rule
        As for :func:`~sklearn_gpcd.detection.calibrate_across_recordings`.
    band_grid : dict or list of dicts, default=None
        Candidate settings of the last band, as for
        :class:`sklearn.model_selection.ParameterGrid`, with keys in
        :data:`~sklearn_gpcd.detection.SELECTABLE_PARAMS` (they override the
        last band's own), e.g. ``[{"filter_cutoff": [8.0, 10.0, 20.0],
        "filter_order": [1], "min_duration": [2, 3]}]``. None keeps every
        band as given.

    Returns
    -------
    result : Bunch
        ``detector`` (the fitted MultiBandDetector, its last band at the
        chosen settings), ``bands`` (each band's
        :func:`~sklearn_gpcd.detection.calibrate_across_recordings` result),
        ``folds`` (onsets of the union per left-out recording, empty with 2
        recordings), ``n_false_alarms``, ``hours`` and
        ``false_alarms_per_hour`` (None with fewer than 3 recordings). With
        ``band_grid``: ``band_settings`` (the chosen candidate),
        ``fold_band_settings`` (the candidate chosen without each recording,
        with which its ``folds`` are counted) and ``band_candidates`` (per
        candidate: ``params``, ``n_false_alarms`` of the union and ``score``
        :math:`J` on all recordings, ``rank``: 0 for the chosen one); empty
        without.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.frozen import FrozenEstimator
    >>> from sklearn.linear_model import LinearRegression
    >>> from sklearn_gpcd.detection import CollisionDetector, stack_currents
    >>> rng = np.random.default_rng(0)
    >>> blocks, times = {}, {}
    >>> for name in "abcd":
    ...     qd = rng.normal(size=(600, 1))
    ...     blocks[name] = stack_currents(qd, 2 * qd[:, 0] + 0.1 * rng.normal(size=600))
    ...     times[name] = np.arange(600) * 0.01
    >>> model = FrozenEstimator(LinearRegression().fit(blocks["a"][:, :1], blocks["a"][:, 1]))
    >>> template = CollisionDetector(model, threshold="per_joint", false_alarm_rate=0.0,
    ...                              sample_time=0.01, filter_cutoff=2.0, min_duration=5)
    >>> result = calibrate_bands_across_recordings(MultiBandDetector(template), blocks, times)
    >>> [d.filter_cutoff for d in result.detector.detectors_], sorted(result.folds)
    ([2.0, 10.0], ['a', 'b', 'c', 'd'])
    >>> result.n_false_alarms >= max(band.n_false_alarms for band in result.bands)
    True

    The fast band's cut-off chosen across the recordings:

    >>> result = calibrate_bands_across_recordings(
    ...     MultiBandDetector(template), blocks, times,
    ...     band_grid={"filter_cutoff": [5.0, 10.0], "min_duration": [2, 3]})
    >>> sorted(result.band_settings), len(result.band_candidates), sorted(result.fold_band_settings)
    (['filter_cutoff', 'min_duration'], 4, ['a', 'b', 'c', 'd'])
    >>> result.detector.detectors_[1].filter_cutoff == result.band_settings["filter_cutoff"]
    True
    """
    templates = detector._band_templates()
    keys = list(blocks)
    if band_grid is None:
        results = _fixed_bands(templates, blocks, times, rule)[0]
        series = [result.series for result in results]
        alarms = ({r: _held_out_union(series, keys, r, rule) for r in keys}
                  if len(keys) >= 3 else {})
        band_settings, fold_band_settings, table = {}, {}, []
    else:
        results, alarms, band_settings, fold_band_settings, table = _choose_last_band(
            templates, blocks, times, rule, band_grid)
    folds = _folds(alarms, times) if alarms else {}
    n_false = sum(len(fold["onsets"]) for fold in folds.values())
    hours = results[0].hours
    fitted = clone(detector)._adopt([result.detector for result in results])
    return Bunch(detector=fitted, bands=results, folds=folds, n_false_alarms=n_false,
                 hours=hours,
                 false_alarms_per_hour=(n_false / hours if folds and hours > 0 else None),
                 band_settings=band_settings, band_candidates=table,
                 fold_band_settings=fold_band_settings)


def _fixed_bands(templates, blocks, times, rule):
    """:func:`~sklearn_gpcd.detection.calibrate_across_recordings` of each band,
    and the first band's candidate runs (None without bands). The regressor
    predicts the recordings once: every band whose settings differ from the
    first band's only after the regressor reuses that prediction."""
    results, first = [], None
    for template in templates:
        runs = _CandidateRuns(template, blocks, times, rule, [{}], shared=first)
        first = first or runs
        results.append(_calibration_result(runs, rule))
    return results, first


def _choose_last_band(templates, blocks, times, rule, band_grid):
    """The fixed bands calibrated, the last band's settings chosen from
    ``band_grid``: calibrations, nested alarms of the union, the chosen
    settings, those chosen without each recording, and the candidate table."""
    keys = list(blocks)
    fixed, shared = _fixed_bands(templates[:-1], blocks, times, rule)
    runs = _CandidateRuns(templates[-1], blocks, times, rule, _candidates(band_grid),
                          shared=shared)
    candidates = [run[0] for run in runs.runs]
    fixed_series = [result.series for result in fixed]

    def union_onsets(subset):
        """Nested onsets of the union on ``subset``, per candidate (the fixed
        bands' held-out alarms computed once for all candidates)."""
        if len(subset) < 3:  # no margin without two other recordings
            return [0] * len(candidates)
        held_out = {r: _held_out_union(fixed_series, subset, r, rule) for r in subset}
        return [sum(len(alarm_onsets(held_out[r] | _held_out_alarm(series, subset, r, rule)))
                    for r in subset) for series in candidates]

    def choose(subset):
        ranks = list(zip(union_onsets(subset),
                         (_selection_score(series, subset, rule) for series in candidates)))
        return min(range(len(candidates)), key=ranks.__getitem__), ranks

    best, ranks = choose(keys)
    order = sorted(range(len(ranks)), key=ranks.__getitem__)
    table = [{"params": runs.candidates[c], "n_false_alarms": ranks[c][0],
              "score": ranks[c][1], "rank": order.index(c)} for c in range(len(ranks))]
    alarms, fold_settings = {}, {}
    if len(keys) >= 3:
        for r in keys:
            c = choose([k for k in keys if k != r])[0] if len(runs.candidates) > 1 else best
            alarms[r] = _held_out_union(fixed_series + [candidates[c]], keys, r, rule)
            fold_settings[r] = runs.candidates[c]
    last = runs.result(best, runs.runs[best][2], {}, [])
    return (fixed + [last], alarms, dict(runs.candidates[best]), fold_settings, table)


def _held_out_union(bands, keys, r, rule):
    """Alarms of recording ``r`` where any band alarms (``bands``: each band's
    :func:`~sklearn_gpcd.detection.regime_excursions`), each band with margin
    and levels from the other recordings of ``keys``
    (:func:`~sklearn_gpcd.detection.nested_alarms` of the union)."""
    return np.logical_or.reduce([_held_out_alarm(series, keys, r, rule) for series in bands])


class _TeePredictor:
    """The first band's compiled predictor, keeping a copy of each prediction."""

    def __init__(self, predictor, n_outputs):
        self.predictor = predictor
        self.kind = predictor.kind
        self.last = np.full(n_outputs, np.nan)

    def predict_one(self, x, out):
        self.predictor.predict_one(x, out)
        np.copyto(self.last, out)
        return out


class _CopiedPrediction:
    """The other bands' predictor: this tick's prediction of the first band."""

    def __init__(self, tee):
        self.tee = tee
        self.kind = tee.kind

    def predict_one(self, x, out):
        np.copyto(out, self.tee.last)
        return out


class MultiBandMonitor(VersionedStateMixin):
    """Run a fitted :class:`MultiBandDetector` one sample at a time.

    One :class:`~sklearn_gpcd.detection.StreamingMonitor` per band, sharing
    one prediction per tick (and, for raw samples, one causal feature row):
    the decisions equal the batch ``predict`` of the detector, sample for
    sample, including sensor faults (a faulty sample is dropped by every
    band). :meth:`replay` and :meth:`replay_recording` run whole arrays or
    recordings and keep every band's signal, ratio, alarms and regime.

    Parameters
    ----------
    detector : MultiBandDetector
        Fitted.
    features : CausalFeatures, default=None
        For :meth:`update_raw`, as in :class:`StreamingMonitor`.

    Attributes
    ----------
    monitors : list of StreamingMonitor
        One per band; ``monitors[0]`` predicts (and builds raw rows).
    status : MonitorStatus
        ``"collision"`` when some band alarms, ``"sensor_fault"`` when the
        sample was rejected, else ``"ok"``.
    alarms : ndarray of bool, shape (n_joints,)
        Joints that fired in some band.
    score : float
        The batch ``score_samples`` value of the last tick.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.linear_model import LinearRegression
    >>> from sklearn_gpcd.detection import CollisionDetector, stack_currents
    >>> rng = np.random.default_rng(0)
    >>> x = rng.normal(size=(2000, 1))
    >>> current = 2.0 * x[:, 0] + 0.05 * rng.normal(size=2000)
    >>> det = MultiBandDetector(CollisionDetector(LinearRegression(), sample_time=0.01,
    ...                                           filter_cutoff=2.0)).fit(
    ...     stack_currents(x, current))
    >>> tap = current.copy()
    >>> tap[1000:1010] += 1.0
    >>> X = stack_currents(x, tap)
    >>> monitor = MultiBandMonitor(det)
    >>> streamed = [monitor.update(row) == "collision" for row in X]
    >>> bool(np.array_equal(streamed, det.predict(X) == -1))
    True
    """

    def __init__(self, detector, features=None):
        check_is_fitted(detector)
        self.detector = detector
        self.features = features
        self.monitors = [StreamingMonitor(band, features=features if b == 0 else None)
                         for b, band in enumerate(detector.detectors_)]
        self._link()
        self.n_joints = self.monitors[0].n_joints
        self.alarms = np.zeros(self.n_joints, dtype=bool)
        self.score = np.nan
        self.status = None

    def _link(self):
        """One prediction per tick: the first band predicts, the others copy it."""
        first = self.monitors[0]
        tee = first._predictor = _TeePredictor(first._predictor, first.n_joints)
        for monitor in self.monitors[1:]:
            monitor._predictor = _CopiedPrediction(tee)

    def __setstate__(self, state):
        super().__setstate__(state)
        self._link()  # the band monitors rebuilt their own predictors on load

    def reset(self):
        """A new recording: every band forgets its filter and debounce history."""
        for monitor in self.monitors:
            monitor.reset()

    def update(self, x, current=None, time=None):
        """Process one sample (see :meth:`StreamingMonitor.update`).

        Returns
        -------
        status : MonitorStatus
        """
        statuses = [monitor.update(x, current, time) for monitor in self.monitors]
        return self._combine(statuses)

    def update_raw(self, time, q, qd, current, target_q=None, target_qd=None,
                   target_current=None):
        """Process one raw robot sample (see :meth:`StreamingMonitor.update_raw`).

        Returns
        -------
        status : MonitorStatus
        """
        first, *others = self.monitors
        status = first.update_raw(time, q, qd, current, target_q=target_q,
                                  target_qd=target_qd, target_current=target_current)
        # a sample the first band rejects is dropped by all (the same input gives the
        # same fault); else the others take the row it built, at the same time stamp
        row = None if status == MonitorStatus.SENSOR_FAULT else first._row
        statuses = [status] + [monitor.update(row, time=time if row is not None else None)
                               for monitor in others]
        return self._combine(statuses)

    def replay(self, X, groups=None, time=None):
        """Feed the rows of ``X`` through :meth:`update`, one by one.

        The streaming twin of :meth:`MultiBandDetector.monitoring_signal
        <sklearn_gpcd.detection.MultiBandDetector.monitoring_signal>`, as
        :meth:`StreamingMonitor.replay
        <sklearn_gpcd.detection.StreamingMonitor.replay>` is that of one
        band.

        Parameters
        ----------
        X, groups, time
            As for :meth:`StreamingMonitor.replay
            <sklearn_gpcd.detection.StreamingMonitor.replay>`: the rows in
            time order (NaN rows become sensor faults), the recording id per
            row (:meth:`reset` where it changes, as the batch ``groups``)
            and the time stamp per row (None for no stamps).

        Returns
        -------
        result : Bunch
            What the bands share or decide together: ``status`` (ndarray of
            str: ``"collision"`` when some band alarms), ``prediction`` (+1 /
            -1 as ``predict``, 0 for sensor faults), ``alarms`` (bool,
            (n_samples, n_joints): joints that fired in some band),
            ``score`` (the batch ``score_samples``, NaN for faults),
            ``predicted`` and ``residual`` (float, (n_samples, n_joints); one
            prediction for all bands); and ``bands``, one Bunch per band
            with its ``signal``, ``ratio`` (float, (n_samples, n_joints)),
            ``alarms`` (bool), ``regime`` (int, (n_samples,)) and ``level``
            (the band's :math:`\\gamma_b`: the band alarms where
            ``ratio > level``). After a sensor fault the float rows are NaN
            and the alarms False, as in :class:`StreamingMonitor`.

        Examples
        --------
        Two recordings whose currents carry a slow model error of 0.2 A,
        which raises the thresholds of the 2 Hz band: a 30 ms tap of 1 A
        that only the fast band sees, and a sensor fault.

        >>> import numpy as np
        >>> from sklearn.linear_model import LinearRegression
        >>> from sklearn_gpcd.detection import CollisionDetector, stack_currents
        >>> qd = np.random.default_rng(1).normal(size=(1000, 1))
        >>> slow = 0.2 * np.sin(np.arange(1000) * 0.01)
        >>> noise = 0.05 * np.random.default_rng(2).normal(size=1000)
        >>> X = stack_currents(qd, 2.0 * qd[:, 0] + slow + noise)
        >>> template = CollisionDetector(LinearRegression(), threshold="per_joint",
        ...                              false_alarm_rate=0.0, sample_time=0.01,
        ...                              filter_cutoff=2.0, min_duration=5)
        >>> det = MultiBandDetector(template).fit(X)
        >>> X[300:303, -1] += 1.0
        >>> X[700, 0] = np.nan
        >>> out = MultiBandMonitor(det).replay(X, groups=np.repeat([0, 1], 500))
        >>> [int(band.alarms.any(axis=1).sum()) for band in out.bands]   # samples per band
        [0, 3]
        >>> str(out.status[700]), int(out.prediction[700])
        ('sensor_fault', 0)
        >>> kept = np.arange(1000) != 700
        >>> bool(np.array_equal(out.prediction[kept],
        ...                     det.predict(X[kept], groups=np.repeat([0, 1], 500)[kept])))
        True
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

    def replay_recording(self, recordings):
        """Feed recordings through :meth:`update_raw`, sample by sample.

        Each recording starts with :meth:`reset`. The batch equivalent is
        the detector's ``monitoring_signal`` on
        ``stack_currents(features.transform(recording), recording.current)``.

        Parameters
        ----------
        recordings : Recording or list of Recording
            They log the signals ``features`` was fitted with.

        Returns
        -------
        result : Bunch
            As :meth:`replay`.

        Raises
        ------
        ValueError
            Without ``features``.
        """
        from ..features.inputs import _as_recordings

        if self.features is None:
            raise ValueError("replay_recording needs MultiBandMonitor(detector, "
                             "features=CausalFeatures(...).fit(recordings)); use replay() "
                             "for ready-made input rows")
        recordings = _as_recordings(recordings)
        signals = self.monitors[0]._online.signals

        def ticks():
            for rec in recordings:
                self.reset()
                targets = {s: getattr(rec, s) for s in signals}
                for k in range(rec.n_samples):
                    yield self.update_raw(rec.time[k], rec.q[k], rec.qd[k], rec.current[k],
                                          **{s: v[k] for s, v in targets.items()})

        return self._record(ticks(), sum(rec.n_samples for rec in recordings))

    def _record(self, statuses, n):
        """Run the ticks of ``statuses`` (an iterator of n statuses); the replay Bunch."""
        first = self.monitors[0]
        shape = (n, self.n_joints)
        out = Bunch(status=np.empty(n, dtype=object), alarms=np.zeros(shape, dtype=bool),
                    score=np.empty(n), predicted=np.empty(shape), residual=np.empty(shape),
                    bands=[Bunch(signal=np.empty(shape), ratio=np.empty(shape),
                                 alarms=np.zeros(shape, dtype=bool),
                                 regime=np.zeros(n, dtype=np.intp), level=monitor._level)
                           for monitor in self.monitors])
        for t, status in enumerate(statuses):
            out.status[t] = status.value
            out.alarms[t], out.score[t] = self.alarms, self.score
            out.predicted[t], out.residual[t] = first.predicted, first.residual
            for band, monitor in zip(out.bands, self.monitors):
                band.signal[t], band.ratio[t] = monitor.signal, monitor.ratio
                band.alarms[t], band.regime[t] = monitor.alarms, monitor.regime
        out.status = out.status.astype(str)
        out.prediction = np.select([out.status == "collision", out.status == "ok"], [-1, 1],
                                   default=0)
        return out

    def _combine(self, statuses):
        if MonitorStatus.SENSOR_FAULT in statuses:
            self.alarms[:] = False
            self.score = np.nan
            self.status = MonitorStatus.SENSOR_FAULT
            return self.status
        np.logical_or.reduce([m.alarms for m in self.monitors], out=self.alarms)
        self.score = min(m.score + m._level for m in self.monitors)
        collision = MonitorStatus.COLLISION in statuses
        self.status = MonitorStatus.COLLISION if collision else MonitorStatus.OK
        return self.status
