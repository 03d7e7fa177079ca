"""Thresholds chosen across recordings: leave-one-recording-out (LORO) margins.

A detector calibrated with ``threshold="per_joint", false_alarm_rate=0`` sets
each (regime, joint) level to the largest debounced excursion of its
collision-free calibration data. On a recording it never saw, the excursions
can be larger. The rule here (the one of ``gpcd calibrate``, which the
real-robot benchmark applies too):

1. **levels**: per recording ``r``, the peak debounced ``|m|`` per (regime,
   joint) cell (:func:`regime_excursions`); the level of a set of recordings
   is the largest of their peaks (:func:`regime_levels`);
2. **margin**: the largest factor by which a left-out recording's peak
   exceeds the level of the others (:func:`loro_margin`), at least 1,
   shared by all cells (``rule="global"``), per regime or per cell;
3. **false alarms, nested**: for each ``r``, margin and levels chosen on the
   other recordings only, alarm onsets counted on ``r``
   (:func:`nested_false_alarms`): the figure never saw ``r``;
4. the operating point: the detector refitted on all recordings with that
   margin (:func:`calibrate_across_recordings` does 1-4);
5. optionally, **settings chosen the same way** (``param_grid``: e.g. the
   settle time and the rest reference): the candidate with the fewest nested
   false alarms (3.) on the calibration recordings, then the smallest
   time-weighted thresholds at its own operating point, and, for the nested
   false alarms, the candidate chosen without the recording they are counted
   on (:func:`calibrate_across_recordings` with ``param_grid``).
"""

import copy

import numpy as np
from sklearn.base import clone
from sklearn.model_selection import ParameterGrid
from sklearn.utils import Bunch

from ..metrics import alarm_onsets
from ._signal import debounce_segments, recording_index, segment_starts
from ._thresholds import MARGIN_RULES, loro_factors, peak_levels, recording_peaks
from .detector import _post_processing_settings

__all__ = [
    "MARGIN_RULES",
    "SELECTABLE_PARAMS",
    "calibrate_across_recordings",
    "loro_margin",
    "nested_false_alarms",
    "regime_excursions",
    "regime_levels",
]

#: CollisionDetector parameters ``calibrate_across_recordings(param_grid=...)``
#: may vary: they act after the regressor, so its predictions are computed once.
SELECTABLE_PARAMS = ("settle_time", "rest_reference", "filter_cutoff", "filter_order",
                     "min_duration")


def regime_excursions(detector, blocks):
    """Debounced ``|m|``, regimes and peak per (regime, joint) of each recording.

    Parameters
    ----------
    detector : CollisionDetector
        A fitted detector with ``threshold="per_joint"``.
    blocks : dict of str -> ndarray of shape (n_samples, n_inputs + n_joints)
        Detector input (:func:`~sklearn_gpcd.detection.stack_currents`) of
        each recording.

    Returns
    -------
    series : dict of str -> tuple
        ``(debounced, regime, peaks)``: debounced ``|m|`` of shape
        (n_samples, n_joints) in the signal's unit (A), regime code per
        sample, and peaks of shape (n_regime_rows, n_joints) (zero where the
        regime does not occur).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.linear_model import LinearRegression
    >>> from sklearn_gpcd.detection import CollisionDetector, stack_currents
    >>> rng = np.random.default_rng(0)
    >>> qd = rng.normal(size=(200, 1))
    >>> Z = stack_currents(qd, 2 * qd[:, 0] + 0.1 * rng.normal(size=200))
    >>> det = CollisionDetector(LinearRegression(), threshold="per_joint",
    ...                         false_alarm_rate=0.0, sample_time=0.01).fit(Z)
    >>> debounced, regime, peaks = regime_excursions(det, {"a": Z})["a"]
    >>> debounced.shape, peaks.shape
    ((200, 1), (1, 1))
    """
    out = {}
    for key, block in blocks.items():
        mon = detector.monitoring_signal(block)
        out[key] = _excursion(detector, mon.signal, mon.regime)
    return out


def _excursion(detector, signal, regime):
    """``(debounced, regime, peaks)`` of one recording's monitoring signal."""
    starts = segment_starts(len(signal))
    debounced = debounce_segments(np.abs(signal), detector.min_duration, starts)
    recording = np.zeros(len(signal), dtype=np.intp)
    peaks = recording_peaks(debounced, regime, recording, len(detector.regime_names_))[0]
    return debounced, regime, peaks


def regime_levels(peaks, keys):
    """Per (regime, joint) level of ``threshold="per_joint"`` on the recordings ``keys``.

    The largest excursion; a regime absent from them takes the largest level
    of the others, as :class:`~sklearn_gpcd.detection.CollisionDetector` does.

    Parameters
    ----------
    peaks : dict of str -> ndarray of shape (n_regime_rows, n_joints)
        Peaks per recording (from :func:`regime_excursions`).
    keys : list of str
        Recordings to take the level over.

    Returns
    -------
    levels : ndarray of shape (n_regime_rows, n_joints)

    Examples
    --------
    >>> import numpy as np
    >>> peaks = {"a": np.array([[1.0, 2.0], [0.0, 0.0], [0.5, 0.2]])}
    >>> regime_levels(peaks, ["a"])[1].tolist()
    [1.0, 2.0]
    """
    return peak_levels(np.stack([peaks[k] for k in keys]))


def loro_margin(peaks, keys, rule="global"):
    """The largest factor by which a left-out recording exceeds the others' level.

    .. math::

        \\mu_{g\\ell} = \\max\\Big(1,\\; \\max_r
        \\frac{p^{(r)}_{g\\ell}}{\\max_{r' \\ne r} p^{(r')}_{g\\ell}}\\Big)

    for regime ``g`` and joint ``l`` (peaks ``p`` of the recordings ``r``),
    then shared. ``CollisionDetector(margin="loro")`` applies this rule with
    ``rule="global"`` in its ``fit``.

    Parameters
    ----------
    peaks : dict of str -> ndarray of shape (n_regime_rows, n_joints)
        Peaks per recording (from :func:`regime_excursions`).
    keys : list of str
        At least two recordings.
    rule : {"global", "joint", "regime", "cell"}, default="global"
        Share the margin over all cells, per joint (largest over the
        regimes), per regime (largest over the joints), or not at all.

    Returns
    -------
    margin : ndarray of shape (n_regime_rows, n_joints)
        At least 1 everywhere.

    Examples
    --------
    >>> import numpy as np
    >>> peaks = {"a": np.ones((3, 2)), "b": np.full((3, 2), 2.0)}
    >>> loro_margin(peaks, ["a", "b"]).tolist()[0]
    [2.0, 2.0]
    """
    return loro_factors(np.stack([peaks[k] for k in keys]), rule)


def nested_alarms(series, rule="global"):
    r"""Alarms (any joint) on each recording with margin and levels chosen without it.

    Recording ``r`` alarms where its debounced excursion exceeds the
    threshold of its regime calibrated on the other recordings,

    .. math::

        a_r(t) = \bigvee_l \; \tilde m_{r,l}(t) > \mu_{-r}\, L_{-r}(g_r(t), l),

    with :math:`\mu_{-r}` the leave-one-recording-out margin and
    :math:`L_{-r}` the per-(regime, joint) levels of the others (see
    :func:`loro_margin`, :func:`regime_levels`). The sample-level view of
    :func:`nested_false_alarms`, e.g. to OR the alarms of two bands.
    Needs at least 3 recordings.

    Parameters
    ----------
    series : dict of str -> tuple
        From :func:`regime_excursions`.
    rule : {"global", "joint", "regime", "cell"}, default="global"
        As :func:`loro_margin`.

    Returns
    -------
    alarms : dict of str -> ndarray of bool, shape (n_samples,)

    Examples
    --------
    >>> import numpy as np
    >>> flat = (np.ones((5, 1)), np.zeros(5, dtype=int), np.ones((1, 1)))
    >>> bump = (np.array([[1.0], [3.0], [1.0], [1.0], [1.0]]), np.zeros(5, dtype=int),
    ...         np.array([[3.0]]))
    >>> alarms = nested_alarms({"a": flat, "b": flat, "c": bump})
    >>> alarms["c"].tolist(), bool(alarms["a"].any())
    ([False, True, False, False, False], False)
    """
    keys = list(series)
    return {r: _held_out_alarm(series, keys, r, rule) for r in keys}


def nested_false_alarms(series, times, rule="global"):
    """Alarm onsets on each recording with margin and levels chosen without it.

    Needs at least 3 recordings (the margin of the others needs 2).

    Parameters
    ----------
    series : dict of str -> tuple
        From :func:`regime_excursions`.
    times : dict of str -> ndarray of shape (n_samples,)
        Time stamps [s] of each recording.
    rule : {"global", "joint", "regime", "cell"}, default="global"
        As :func:`loro_margin`.

    Returns
    -------
    folds : dict of str -> dict
        ``onsets`` (alarm start times [s] from the recording's start),
        ``hours`` (duration) and ``first_second_alarm_samples``.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(5) * 1.0
    >>> flat = (np.ones((5, 1)), np.zeros(5, dtype=int), np.ones((1, 1)))
    >>> bump = (np.array([[1.0], [3.0], [1.0], [1.0], [1.0]]), np.zeros(5, dtype=int),
    ...         np.array([[3.0]]))
    >>> folds = nested_false_alarms({"a": flat, "b": flat, "c": bump},
    ...                             {"a": t, "b": t, "c": t})
    >>> folds["c"]["onsets"], folds["a"]["onsets"]
    ([1.0], [])
    """
    return _folds(nested_alarms(series, rule), times)


def _folds(alarms, times):
    """Onsets, duration and first-second alarm samples of each recording's alarms."""
    out = {}
    for r, alarm in alarms.items():
        t = np.asarray(times[r], dtype=float)
        t = t - t[0]
        out[r] = {"onsets": alarm_onsets(alarm, t), "hours": float(t[-1] / 3600.0),
                  "first_second_alarm_samples": int(alarm[t < 1.0].sum())}
    return out


def calibrate_across_recordings(detector, blocks, times, rule="global", param_grid=None):
    """Fit a detector with a leave-one-recording-out margin; count nested false alarms.

    With ``param_grid``, the detector's post-processing settings are chosen
    too. Each candidate is calibrated by the rule above and scored by the
    time-weighted mean log threshold at its own operating point,

    .. math::

        J = \\sum_g \\frac{n_g}{n}\\, \\frac{1}{L} \\sum_{\\ell=1}^{L}
            \\log\\big(\\mu\\, p_{g\\ell}\\big),

    with :math:`n_g` the calibration samples in regime :math:`g` under that
    candidate, :math:`p_{g\\ell}` the levels and :math:`\\mu` the margin: the
    band the arm spends its time in, smaller is more sensitive (each joint's
    scale adds the same constant to every candidate). By construction of the
    margin every candidate raises no alarm on the recordings it is calibrated
    on, so :math:`J` alone rewards a candidate that fits them tightly and
    transfers badly. The candidates are therefore ranked first by their
    nested false alarms on the calibration recordings (each recording scored
    with margin and levels from the others, step 3 above), then by
    :math:`J`: the operating point is the most sensitive candidate among those
    that transferred best between the calibration recordings. The nested
    false alarms of each recording are counted at the candidate chosen
    without it (ranked on the other recordings alone, its margin and levels
    also chosen without it), so the figure never saw the recording even
    through the choice of settings. The regressor predicts each recording
    once for all candidates.

    Parameters
    ----------
    detector : CollisionDetector
        Unfitted template with ``threshold="per_joint"`` and
        ``false_alarm_rate=0`` (its ``margin`` is replaced); wrap a trained
        regressor in :class:`sklearn.frozen.FrozenEstimator` so it is not
        refitted.
    blocks : dict of str -> ndarray of shape (n_samples, n_inputs + n_joints)
        Detector input of each collision-free recording (at least 2).
    times : dict of str -> ndarray of shape (n_samples,)
        Time stamps [s] of each recording.
    rule : {"global", "joint", "regime", "cell"}, default="global"
        As :func:`loro_margin`.
    param_grid : dict or list of dicts, default=None
        Candidate settings, as for :class:`sklearn.model_selection.ParameterGrid`,
        with keys in :data:`SELECTABLE_PARAMS`, e.g. ``{"settle_time": [0.5,
        1, 2, 3], "rest_reference": [None, 2, 5]}``. None calibrates the
        template's own settings.

    Returns
    -------
    result : Bunch
        ``detector`` (fitted on all recordings at the operating point),
        ``margin`` and ``levels`` (n_regime_rows, n_joints), ``folds`` (from
        :func:`nested_false_alarms`, empty with 2 recordings), ``n_false_alarms``
        (their total), ``hours`` and ``false_alarms_per_hour`` (None with
        fewer than 3 recordings), ``series`` (from :func:`regime_excursions`
        at a unit margin, e.g. to compare rules with
        :func:`nested_false_alarms`), ``settings`` (the chosen candidate,
        ``{}`` without ``param_grid``), ``candidates`` (per candidate:
        ``params``, ``score`` :math:`J`, ``margin``, ``n_false_alarms``,
        nested at that fixed candidate, and ``rank``: 0 for the operating
        point, which has the fewest ``n_false_alarms``, then the smallest
        ``score``) and ``fold_settings`` (the candidate chosen without each
        recording).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.linear_model import LinearRegression
    >>> from sklearn_gpcd.detection import CollisionDetector, stack_currents
    >>> rng = np.random.default_rng(0)
    >>> blocks, times = {}, {}
    >>> for name in "abc":
    ...     qd = rng.normal(size=(300, 1))
    ...     blocks[name] = stack_currents(qd, 2 * qd[:, 0] + 0.1 * rng.normal(size=300))
    ...     times[name] = np.arange(300) * 0.01
    >>> template = CollisionDetector(LinearRegression(), threshold="per_joint",
    ...                              false_alarm_rate=0.0, sample_time=0.01)
    >>> result = calibrate_across_recordings(template, blocks, times)
    >>> bool(result.margin.min() >= 1.0), sorted(result.folds)
    (True, ['a', 'b', 'c'])
    >>> result = calibrate_across_recordings(template, blocks, times,
    ...                                      param_grid={"filter_cutoff": [None, 2.0]})
    >>> result.settings, result.detector.filter_cutoff   # filtering narrows the band
    ({'filter_cutoff': 2.0}, 2.0)
    """
    runs = _CandidateRuns(detector, blocks, times, rule, _candidates(param_grid))
    return _calibration_result(runs, rule)


def _calibration_result(runs, rule):
    """The Bunch of :func:`calibrate_across_recordings` from its candidate runs:
    the candidates ranked, the operating point, and the nested folds (each
    recording at the candidate chosen without it)."""
    keys = runs.keys
    # ranked on all recordings from what the runs already hold: the nested onsets
    # of each run's folds and its score (as _best_candidate computes them on a subset)
    table = [{"params": params, "score": _selection_score(series, keys, rule),
              "margin": float(margin.max()),
              "n_false_alarms": sum(len(f["onsets"]) for f in folds.values())}
             for params, (series, margin, folds) in zip(runs.candidates, runs.runs)]
    order = sorted(range(len(table)), key=lambda c: (table[c]["n_false_alarms"],
                                                     table[c]["score"]))
    for rank, c in enumerate(order):
        table[c]["rank"] = rank
    best = order[0]
    folds = runs.runs[best][2]
    fold_settings = {}
    if len(keys) >= 3 and len(runs.candidates) > 1:  # the settings, too, chosen without r
        chosen = {r: _best_candidate(runs.runs, [k for k in keys if k != r], rule)
                  for r in keys}
        folds = {r: runs.runs[c][2][r] for r, c in chosen.items()}
        fold_settings = {r: runs.candidates[c] for r, c in chosen.items()}
    return runs.result(best, folds, fold_settings, table)


class _CandidateRuns:
    """Every candidate of a calibration across recordings, from one prediction.

    ``clone(detector)`` is fitted on all recordings at a unit margin and its
    residuals kept: the regressor predicts each calibration row once, for
    every candidate setting and for the operating point. ``runs[c]`` is
    ``(series, margin, folds)`` of candidate ``c``: its
    :func:`regime_excursions`, its :func:`loro_margin` and its
    :func:`nested_false_alarms` (empty with fewer than 3 recordings).

    With ``shared`` (the runs of another detector on the same recordings,
    e.g. another band of one model), its prediction is reused when
    ``detector`` differs from that detector only in settings applied after
    the regressor (``POST_PROCESSING_PARAMS`` of the detector module; the
    margin is replaced anyway) and the prediction holds the std where
    ``detector`` reads it: the regressor then predicts nothing again.
    Otherwise ``detector`` predicts on its own.
    """

    def __init__(self, detector, blocks, times, rule, candidates, shared=None):
        keys = list(blocks)
        if len(keys) < 2:
            raise ValueError("calibration across recordings needs at least 2 collision-free "
                             f"recordings, got {len(keys)}")
        self.keys, self.times, self.candidates = keys, times, candidates
        self.detector = detector
        settings = None
        if shared is not None and (shared.residuals[1] is not None
                                   or not detector._needs_std(fitting=True)):
            settings = _post_processing_settings(shared.detector, detector)
        if settings is None:
            Z = np.concatenate([blocks[k] for k in keys])
            self.groups = np.repeat(np.arange(len(keys)), [len(blocks[k]) for k in keys])
            time = np.concatenate([np.asarray(times[k], dtype=float) for k in keys])
            base = clone(detector).set_params(margin=1.0)
            self.residuals = base._fit_residuals(Z, None, self.groups, time,
                                                 base._needs_std(fitting=True))
        else:
            self.groups, self.residuals = shared.groups, shared.residuals
            base = copy.copy(shared.base).set_params(regressor=detector.regressor, **settings)
            base._validate_params()
        base._calibrate(*self.residuals, recording_index(self.groups))
        self.base = base
        per_recording = _recording_residuals(base, keys, self.groups, *self.residuals[:2],
                                             self.residuals[3])
        self.runs = []
        for params in candidates:
            series = _candidate_series(base, params, per_recording)
            peaks = {k: v[2] for k, v in series.items()}
            folds = nested_false_alarms(series, times, rule) if len(keys) >= 3 else {}
            self.runs.append((series, loro_margin(peaks, keys, rule), folds))

    def result(self, c, folds, fold_settings, table):
        """The Bunch of :func:`calibrate_across_recordings` at candidate ``c``,
        its detector refitted at that candidate's margin (from the residuals
        already predicted), with the nested ``folds`` given."""
        series, margin = self.runs[c][:2]
        keys = self.keys
        peaks = {k: v[2] for k, v in series.items()}
        shaped = margin.reshape(np.shape(self.base.scale_))  # (n_joints,) without regimes
        fitted = copy.copy(self.base).set_params(**self.candidates[c], margin=shaped)
        fitted._validate_params()
        fitted._calibrate(*self.residuals, recording_index(self.groups))
        times = self.times
        hours = float(sum((times[k][-1] - times[k][0]) for k in keys) / 3600.0)
        n_false = sum(len(f["onsets"]) for f in folds.values())
        return Bunch(detector=fitted, margin=margin, levels=regime_levels(peaks, keys),
                     folds=folds, n_false_alarms=n_false, hours=hours,
                     false_alarms_per_hour=(n_false / hours if folds and hours > 0 else None),
                     regime_names=tuple(fitted.regime_names_), series=series,
                     settings=dict(self.candidates[c]), candidates=table,
                     fold_settings=fold_settings)


def _candidates(param_grid):
    """The candidate settings of ``param_grid`` (``[{}]`` for None), checked."""
    if param_grid is None:
        return [{}]
    candidates = list(ParameterGrid(param_grid))
    unknown = sorted({k for c in candidates for k in c} - set(SELECTABLE_PARAMS))
    if unknown:
        raise ValueError(f"param_grid: {unknown[0]!r} cannot be chosen across recordings; "
                         f"the settings that can are {SELECTABLE_PARAMS}")
    if not candidates:
        raise ValueError("param_grid has no candidate")
    return candidates


def _recording_residuals(detector, keys, groups, residual, std, motion):
    """``(residual, std, motion)`` of each recording, cut from the stacked
    rows (recording ``keys[g]`` in the rows where ``groups == g``); ``std``
    only where the detector's monitoring signal reads it."""
    std = std if detector._needs_std() else None
    return {key: (residual[rows], None if std is None else std[rows],
                  None if motion is None else motion[rows])
            for key, rows in ((k, groups == g) for g, k in enumerate(keys))}


def _candidate_series(base, params, residuals):
    """:func:`regime_excursions` of ``base`` with the post-processing ``params``,
    from residuals already predicted."""
    det = copy.copy(base).set_params(**params)
    det._validate_params()
    det._set_signal_stages()
    out = {}
    for key, (residual, std, motion) in residuals.items():
        signal, regime, _ = det._signal(residual, std, segment_starts(len(residual)), motion)
        out[key] = _excursion(det, signal, regime)
    return out


def _loro_thresholds(series, keys, rule):
    """Thresholds at a unit scale calibrated on the recordings ``keys``: their
    leave-one-recording-out margin times their levels."""
    peaks = {k: series[k][2] for k in keys}
    return loro_margin(peaks, keys, rule) * regime_levels(peaks, keys)


def _selection_score(series, keys, rule):
    """Time-weighted mean log threshold on the recordings ``keys`` (see
    :func:`calibrate_across_recordings`)."""
    thresholds = _loro_thresholds(series, keys, rule)
    counts = sum(np.bincount(series[k][1], minlength=thresholds.shape[0]) for k in keys)
    log = np.log(np.maximum(thresholds, np.finfo(float).tiny)).mean(axis=1)
    return float(counts / counts.sum() @ log)


def _held_out_alarm(series, keys, r, rule):
    """Alarms (any joint) of recording ``r`` with margin and levels from the
    other recordings of ``keys``."""
    thresholds = _loro_thresholds(series, [k for k in keys if k != r], rule)
    debounced, regimes, _ = series[r]
    return (debounced > thresholds[regimes]).any(axis=1)


def _nested_onset_count(series, keys, rule):
    """Nested alarm onsets on the recordings ``keys``, each recording scored with
    margin and levels from the other ``keys`` (0 with fewer than 3)."""
    if len(keys) < 3:
        return 0
    return sum(len(alarm_onsets(_held_out_alarm(series, keys, r, rule))) for r in keys)


def _best_candidate(runs, keys, rule):
    """Index of the run with the fewest nested onsets on ``keys``, then the
    smallest score on ``keys`` (the first on ties)."""
    ranks = [(_nested_onset_count(run[0], keys, rule), _selection_score(run[0], keys, rule))
             for run in runs]
    return min(range(len(runs)), key=ranks.__getitem__)
