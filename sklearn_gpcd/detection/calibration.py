"""Thresholds chosen across recordings: leave-one-recording-out (LORO) margins.

With ``threshold="per_joint", false_alarm_rate=0`` each (regime, joint)
level is the largest debounced excursion of the calibration data, which a
new recording can exceed. The rule of ``gpcd calibrate`` and of the
real-robot benchmark (:func:`calibrate_across_recordings` does all four):

1. **levels**: the largest peak debounced ``|m|`` per (regime, joint) cell
   over the recordings (:func:`regime_excursions`, :func:`regime_levels`);
2. **margin**: the largest factor by which a left-out recording's peak
   exceeds the level of the others, at least 1 (:func:`loro_margin`);
3. **false alarms, nested**: each recording's alarm onsets with margin and
   levels chosen on the others only (:func:`nested_false_alarms`);
4. optionally, **settings chosen the same way** (``param_grid``, e.g. the
   settle time and the rest reference).
"""

import copy
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from sklearn.base import clone
from sklearn.model_selection import ParameterGrid
from sklearn.utils import Bunch

from ..metrics import alarm_onsets
from ._regimes import rest_entry_peaks
from ._thresholds import (
    _LEVEL_MARGIN,
    MARGIN_RULES,
    fading_stages,
    fill_absent_regimes,
    loro_factors,
    peak_levels,
    recording_peaks,
    rest_band,
)
from .detector import reads_currents
from .rules import AlarmRule

__all__ = [
    "MARGIN_RULES",
    "calibrate_across_recordings",
    "loro_margin",
    "nested_alarms",
    "nested_false_alarms",
    "regime_excursions",
    "regime_levels",
]


def regime_excursions(detector, blocks):
    """Debounced ``|m|``, regimes and peak per (regime, joint) of each recording.

    Parameters
    ----------
    detector : CollisionDetector
        A fitted detector whose (first) rule has ``threshold="per_joint"``.
    blocks : dict of str -> ndarray of shape (n_samples, n_inputs + n_joints)
        Detector input (:func:`~sklearn_gpcd.detection.stack_currents`) of
        each recording.

    Returns
    -------
    series : dict of str -> tuple
        ``(debounced, regime, peaks)``: debounced ``|m|`` (n_samples,
        n_joints) in the signal's unit (A), regime code per sample, and peaks
        (n_regime_rows, n_joints; zero where the regime does not occur).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.linear_model import LinearRegression
    >>> from sklearn_gpcd.detection import AlarmRule, CollisionDetector, stack_currents
    >>> rng = np.random.default_rng(0)
    >>> qd = rng.normal(size=(200, 1))
    >>> Z = stack_currents(qd, 2 * qd[:, 0] + 0.1 * rng.normal(size=200))
    >>> det = CollisionDetector(LinearRegression(), sample_time=0.01,
    ...                         rules=AlarmRule("per_joint", false_alarm_rate=0.0)).fit(Z)
    >>> debounced, regime, peaks = regime_excursions(det, {"a": Z})["a"]
    >>> debounced.shape, peaks.shape
    ((200, 1), (1, 1))
    """
    rule = detector.rules_[0]
    out = {}
    for key, block in blocks.items():
        band = detector.monitoring_signal(block).bands[0]
        out[key] = _excursion(rule, band.signal, band.regime)
    return out


def _excursion(rule, signal, regime):
    """``(debounced, regime, peaks)`` of one recording's monitoring signal."""
    debounced = rule.debounced(signal)
    recording = np.zeros(len(signal), dtype=np.intp)
    peaks = recording_peaks(debounced, regime, recording, len(rule.regime_names_))[0]
    return debounced, regime, fading_stages(peaks, rule.settling_rows())


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
    then shared. An alarm rule with ``margin="loro"``
    (:class:`~sklearn_gpcd.detection.AlarmRule`, the detector's ``rules``)
    applies this rule with ``rule="global"`` when the detector is fitted with
    ``groups``.

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


def nested_alarms(series, rule="global", floor=None):
    r"""Alarms (any joint) on each recording with margin and levels chosen without it.

    Recording ``r`` alarms where its debounced excursion exceeds the
    threshold of its regime calibrated on the other recordings,

    .. math::

        a_r(t) = \bigvee_l \; \tilde m_{r,l}(t) >
                 \max\big(\mu_{-r}\, L_{-r}(g_r(t), l),\; F(g_r(t), l)\big),

    with :math:`\mu_{-r}` the leave-one-recording-out margin,
    :math:`L_{-r}` the per-(regime, joint) levels of the others (see
    :func:`loro_margin`, :func:`regime_levels`) and :math:`F` a ``floor``
    the thresholds never go below (0 without one). The sample-level view of
    :func:`nested_false_alarms`, e.g. to OR the alarms of two bands.
    Needs at least 3 recordings.

    Parameters
    ----------
    series : dict of str -> tuple
        From :func:`regime_excursions`.
    rule : {"global", "joint", "regime", "cell"}, default="global"
        As :func:`loro_margin`.
    floor : ndarray of shape (n_regime_rows, n_joints), default=None
        Smallest thresholds, in the series' unit (e.g. the model's levels on
        its left-out training runs, which a calibration applies after the
        margin). None: no floor.

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
    return {r: _held_out_alarm(series, keys, r, rule, floor) for r in keys}


def nested_false_alarms(series, times, rule="global", floor=None):
    """Alarm onsets on each recording with margin and levels chosen without it.

    Needs at least 3 recordings (the margin of the others needs 2).

    Parameters
    ----------
    series, rule, floor
        As for :func:`nested_alarms`.
    times : dict of str -> ndarray of shape (n_samples,)
        Time stamps [s] of each recording.

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
    return _folds(nested_alarms(series, rule, floor), times)


def _folds(alarms, times):
    """Onsets, duration and first-second alarm samples of each recording's alarms."""
    out = {}
    for r, alarm in alarms.items():
        t = np.asarray(times[r], dtype=float)
        t = t - t[0]
        out[r] = {"onsets": alarm_onsets(alarm, t), "hours": float(t[-1] / 3600.0),
                  "first_second_alarm_samples": int(alarm[t < 1.0].sum())}
    return out


def calibrate_across_recordings(detector, blocks, times, rule="global", param_grid=None, *,
                                folder=None, floor=None):
    """Fit a detector with a leave-one-recording-out margin; count nested false alarms.

    Each alarm rule (band) of ``detector`` is calibrated by the rule above on
    one prediction of the recordings; the nested false alarms count the
    onsets of the union of the bands (each with margin and levels chosen
    without the recording).

    With ``param_grid``, the settings of the **last** rule are chosen too:
    each candidate is calibrated by the rule above and scored by the
    time-weighted mean log threshold at its own operating point,

    .. math::

        J = \\sum_g \\frac{n_g}{n}\\, \\frac{1}{L} \\sum_{\\ell=1}^{L}
            \\log\\big(\\mu\\, p_{g\\ell}\\big),

    with :math:`n_g` the calibration samples in regime :math:`g` under that
    candidate, :math:`p_{g\\ell}` the levels and :math:`\\mu` the margin
    (smaller is more sensitive). Every candidate raises no alarm on the
    recordings it is calibrated on, so :math:`J` alone would reward one that
    fits them tightly and transfers badly: the candidates are ranked first by
    the nested false alarms of the union on the calibration recordings, then
    by :math:`J`. The nested false alarms of each recording are counted at
    the candidate chosen without it, so the figure never saw the recording,
    even through the choice of settings. The regressor predicts each
    recording once for all bands and candidates.

    Parameters
    ----------
    detector : CollisionDetector
        Unfitted template whose rules have ``threshold="per_joint"`` and
        ``false_alarm_rate=0`` (their ``margin`` is replaced); a trained
        regressor wrapped in :class:`sklearn.frozen.FrozenEstimator` is not
        refitted.
    blocks : dict of str -> ndarray of shape (n_samples, n_inputs + n_joints)
        Detector input of each collision-free recording (at least 2).
    times : dict of str -> ndarray of shape (n_samples,)
        Time stamps [s] of each recording.
    rule : {"global", "joint", "regime", "cell"}, default="global"
        As :func:`loro_margin`.
    param_grid : dict or list of dicts, default=None
        Candidate settings of the last rule (:class:`~sklearn_gpcd.detection.AlarmRule`
        parameter names, as for :class:`sklearn.model_selection.ParameterGrid`),
        e.g. ``{"regimes__settle_time": [0.5, 1, 2], "filter_cutoff": [8, 10]}``.
        None calibrates the rules as given.
    folder : str or Path, default=None
        Stream the recordings: ``blocks`` (any mapping, e.g. one that reads
        each block from a file when asked) is read one recording at a time,
        each band's :func:`regime_excursions` go to files in this folder and
        the fitted rules take the levels from the recordings' peaks instead
        of one pass over all the residuals (:func:`_rule_from_peaks`: the
        same maxima, the same thresholds). Memory is that of one recording
        and its series. Not for ``normalize="std"``.
        ``sample_time="auto"`` takes the median step of all recordings.
    floor : callable or None, default=None
        ``floor(rule)``: the smallest thresholds (n_regime_rows, n_joints, in
        the residual's unit) of a prepared band rule, or None for none. The
        nested false alarms count each band at ``max(margin x levels,
        floor)``: the thresholds of a detector whose rows are raised to the
        floor after this calibration. The choice of settings does not read
        it (candidates are ranked on the recordings' own evidence), and the
        fitted detector is not raised: the caller applies the floor.

    Returns
    -------
    result : Bunch
        ``detector`` (fitted on all recordings at the operating point),
        ``folds`` (:func:`nested_false_alarms` of the union of the bands,
        each recording at the candidate chosen without it; empty with 2
        recordings), ``n_false_alarms`` (their total), ``hours``,
        ``false_alarms_per_hour`` (None with fewer than 3 recordings),
        ``settings`` (the chosen candidate), ``candidates`` (per candidate:
        ``params``, ``score`` :math:`J`, ``margin``, ``n_false_alarms`` of
        the union at that candidate, and ``rank``, 0 for the operating
        point), ``fold_settings`` (the candidate chosen without each
        recording) and ``bands``: per rule, ``rule`` (fitted), ``margin`` and
        ``levels`` (n_regime_rows, n_joints), ``series``
        (:func:`regime_excursions` at a unit margin), ``floor`` (what
        ``floor`` gave its rule, or None), ``folds``,
        ``n_false_alarms`` and ``false_alarms_per_hour`` of the band alone,
        and ``regime_names``; the first band's ``margin``, ``levels``,
        ``series`` and ``regime_names`` also at the top level.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.linear_model import LinearRegression
    >>> from sklearn_gpcd.detection import AlarmRule, CollisionDetector, stack_currents
    >>> rng = np.random.default_rng(0)
    >>> blocks, times = {}, {}
    >>> for name in "abc":
    ...     qd = rng.normal(size=(300, 1))
    ...     blocks[name] = stack_currents(qd, 2 * qd[:, 0] + 0.1 * rng.normal(size=300))
    ...     times[name] = np.arange(300) * 0.01
    >>> template = CollisionDetector(LinearRegression(), sample_time=0.01,
    ...                              rules=AlarmRule("per_joint", false_alarm_rate=0.0))
    >>> result = calibrate_across_recordings(template, blocks, times)
    >>> bool(result.margin.min() >= 1.0), sorted(result.folds)
    (True, ['a', 'b', 'c'])
    >>> result = calibrate_across_recordings(template, blocks, times,
    ...                                      param_grid={"filter_cutoff": [None, 2.0]})
    >>> result.settings, result.detector.rules_[0].filter_cutoff   # filtering narrows
    ({'filter_cutoff': 2.0}, 2.0)

    A second, faster band whose cut-off is chosen across the recordings:

    >>> slow = AlarmRule("per_joint", false_alarm_rate=0.0, filter_cutoff=2.0, min_duration=5)
    >>> fast = AlarmRule("per_joint", false_alarm_rate=0.0, filter_cutoff=10.0, min_duration=2)
    >>> result = calibrate_across_recordings(
    ...     template.set_params(rules=[slow, fast]), blocks, times,
    ...     param_grid={"filter_cutoff": [5.0, 10.0]})
    >>> len(result.bands), len(result.candidates), sorted(result.fold_settings)
    (2, 2, ['a', 'b', 'c'])
    """
    keys = list(blocks)
    if len(keys) < 2:
        raise ValueError("calibration across recordings needs at least 2 collision-free "
                         f"recordings, got {len(keys)}")
    base = clone(detector)
    rules = [r.set_params(margin=1.0) for r in base.alarm_rules()]
    candidates = _candidates(param_grid, rules[-1])
    base.set_params(rules=rules)
    if folder is None:
        Z = np.concatenate([blocks[k] for k in keys])
        groups = np.repeat(np.arange(len(keys)), [len(blocks[k]) for k in keys])
        time = np.concatenate([np.asarray(times[k], dtype=float) for k in keys])
        residuals = base.fit_residuals(Z, groups=groups, time=time)
        u = _recording_residuals(base, keys, groups, residuals)
        timing = (base.sample_time_, base.sigma_v)  # what the rules' signal stages need
        band_rules = _band_rules(rules, candidates, timing)
        all_series = [_band_series(r, u) for r in band_rules]
    else:
        band_rules, all_series = _streamed_series(base, rules, candidates, blocks, times,
                                                  folder)
    n_fixed = len(rules) - 1
    floors = [None if floor is None else floor(r) for r in band_rules]
    fixed = [_band_run(r, series, times, rule, f)
             for r, series, f in zip(band_rules[:n_fixed], all_series[:n_fixed], floors)]
    runs = [_band_run(r, series, times, rule, f)
            for r, series, f in zip(band_rules[n_fixed:], all_series[n_fixed:],
                                    floors[n_fixed:])]
    fixed_series = [run.series for run in fixed]
    subsets = [tuple(keys)]
    if len(keys) >= 3 and len(runs) > 1:  # the settings chosen without each recording
        subsets += [tuple(k for k in keys if k != r) for r in keys]
    onsets = _union_onsets(fixed_series, [run.series for run in runs], keys, subsets, rule)

    def ranks(subset):
        return list(zip(onsets[tuple(subset)],
                        (_selection_score(run.series, subset, rule) for run in runs)))

    table_ranks = ranks(keys)
    order = sorted(range(len(runs)), key=table_ranks.__getitem__)
    best = order[0]
    table = [{"params": params, "score": table_ranks[c][1],
              "margin": float(runs[c].margin.max()), "n_false_alarms": table_ranks[c][0],
              "rank": order.index(c)} for c, params in enumerate(candidates)]
    alarms, fold_settings = {}, {}
    if len(keys) >= 3:
        for r in keys:
            c = best
            if len(runs) > 1:
                subset = [k for k in keys if k != r]
                scored = ranks(subset)
                c = min(range(len(runs)), key=scored.__getitem__)
                fold_settings[r] = candidates[c]
            alarms[r] = _held_out_union(fixed_series + [runs[c].series], keys, r, rule,
                                        [run.floor for run in fixed + [runs[c]]])
    bands = fixed + [runs[best]]
    chosen = [clone(run.rule).set_params(  # the margin in the shape of its scale_
        margin=run.margin if run.rule.regimes is not None else run.margin.reshape(-1))
        for run in bands]
    single = detector.rules is None or isinstance(detector.rules, AlarmRule)
    fitted = copy.copy(base).set_params(rules=chosen[0] if single else chosen)
    if folder is None:
        fitted.calibrate(residuals)
    else:
        timing = (base.sample_time_, base.sigma_v)
        fitted.adopt_rules([_rule_from_peaks(r, run.series, keys, timing)
                           for r, run in zip(fitted.alarm_rules(), bands)])
    hours = float(sum((times[k][-1] - times[k][0]) for k in keys) / 3600.0)
    folds = _folds(alarms, times) if alarms else {}
    n_false = sum(len(f["onsets"]) for f in folds.values())
    for band, fitted_rule in zip(bands, fitted.rules_):
        band.rule = fitted_rule
        band.false_alarms_per_hour = (band.n_false_alarms / hours
                                      if band.folds and hours > 0 else None)
    first = bands[0]
    return Bunch(detector=fitted, bands=bands, folds=folds, n_false_alarms=n_false,
                 hours=hours,
                 false_alarms_per_hour=(n_false / hours if folds and hours > 0 else None),
                 settings=dict(candidates[best]), candidates=table,
                 fold_settings=fold_settings, margin=first.margin, levels=first.levels,
                 series=first.series, regime_names=first.regime_names)


def _candidates(param_grid, rule):
    """The candidate settings of ``param_grid`` (``[{}]`` for None), checked
    against the parameters of ``rule``."""
    if param_grid is None:
        return [{}]
    candidates = list(ParameterGrid(param_grid))
    if not candidates:
        raise ValueError("param_grid has no candidate")
    for params in candidates:
        if "margin" in params:
            raise ValueError("param_grid: the margin is chosen across recordings; it "
                             "cannot be a candidate setting")
        for key, value in params.items():
            try:
                clone(rule).set_params(**{key: value})
            except (ValueError, AttributeError):
                raise ValueError(
                    f"param_grid: {key!r} is not a setting of the last alarm rule {rule!r} "
                    "(AlarmRule parameters, regimes__settle_time and the like for its "
                    "regimes)") from None
    return candidates


def _recording_residuals(detector, keys, groups, residuals):
    """``(u, motion)`` of each recording, cut from the stacked rows (recording
    ``keys[g]`` in the rows where ``groups == g``); ``u`` the residual over the
    std where the detector normalises."""
    u = residuals.residual
    if detector.normalize == "std":
        u = u / residuals.std
    motion = residuals.motion
    return {key: (u[rows], None if motion is None else motion[rows])
            for key, rows in ((k, groups == g) for g, k in enumerate(keys))}


def _band_rules(rules, candidates, timing):
    """The fixed bands, then the last rule at each candidate setting, prepared."""
    return ([r.prepare(*timing) for r in rules[:-1]]
            + [clone(rules[-1]).set_params(**params).prepare(*timing) for params in candidates])


def _band_series(rule, residuals):
    """:func:`regime_excursions` of one band on each recording's ``(u, motion)``."""
    return {key: _excursion(rule, *rule.signal(u, motion=motion)[:2])
            for key, (u, motion) in residuals.items()}


def _band_run(rule, series, times, margin_rule, floor=None):
    """One band at its settings: series, LORO margin, levels and its own nested folds."""
    keys = list(series)
    peaks = {k: _peaks(series, k) for k in keys}
    folds = nested_false_alarms(series, times, margin_rule, floor) if len(keys) >= 3 else {}
    return Bunch(rule=rule, series=series, margin=loro_margin(peaks, keys, margin_rule),
                 levels=regime_levels(peaks, keys), folds=folds, floor=floor,
                 n_false_alarms=sum(len(f["onsets"]) for f in folds.values()),
                 regime_names=tuple(rule.regime_names_))


def _held_out_union(bands, keys, r, rule, floors):
    """Alarms of recording ``r`` where any band alarms (``bands``: each band's
    :func:`regime_excursions`), each band with margin and levels from the other
    recordings of ``keys``, at least its floor (:func:`nested_alarms` of the
    union)."""
    return np.logical_or.reduce([_held_out_alarm(series, keys, r, rule, floor)
                                 for series, floor in zip(bands, floors)])


def _loro_thresholds(series, keys, rule):
    """Thresholds at a unit scale calibrated on the recordings ``keys``: their
    leave-one-recording-out margin times their levels."""
    peaks = {k: _peaks(series, k) for k in keys}
    return loro_margin(peaks, keys, rule) * regime_levels(peaks, keys)


def _selection_score(series, keys, rule):
    """Time-weighted mean log threshold on the recordings ``keys`` (see
    :func:`calibrate_across_recordings`)."""
    thresholds = _loro_thresholds(series, keys, rule)
    counts = sum(_counts(series, k, thresholds.shape[0]) for k in keys)
    log = np.log(np.maximum(thresholds, np.finfo(float).tiny)).mean(axis=1)
    return float(counts / counts.sum() @ log)


def _held_out_alarm(series, keys, r, rule, floor=None):
    """Alarms (any joint) of recording ``r`` with margin and levels from the
    other recordings of ``keys``, at least ``floor`` (None: none)."""
    return next(_held_out_alarms(series, [keys], r, rule, floor))


def _held_out_alarms(series, subsets, r, rule, floor=None):
    """:func:`_held_out_alarm` of recording ``r`` for each of ``subsets``, its
    series read once (a generator). With several subsets the samples are
    compared once with the lowest of their thresholds (``fmin``: a NaN
    threshold alarms nowhere) and only those above it with each: a sample at
    or below the lowest is below every one."""
    debounced, regimes, _ = series[r]
    thresholds = [_loro_thresholds(series, [k for k in keys if k != r], rule)
                  for keys in subsets]
    if floor is not None:  # NaN (alarms nowhere) stays NaN
        thresholds = [np.maximum(level, floor) for level in thresholds]
    rows = slice(None)
    if len(thresholds) > 1:
        lowest = np.fmin.reduce(np.stack(thresholds))
        rows = np.flatnonzero((debounced > lowest[regimes]).any(axis=1))
    above, regimes = debounced[rows], regimes[rows]
    for level in thresholds:
        alarm = np.zeros(len(debounced), dtype=bool)
        alarm[rows] = (above > level[regimes]).any(axis=1)
        yield alarm


def _union_onsets(fixed_series, run_series, keys, subsets, rule):
    """Nested onsets of the union of the bands on each subset of ``keys``, per
    candidate: ``{subset: [onsets of candidate c]}``, the sum over the
    recordings ``r`` of ``subset`` of the onsets of the fixed bands' held-out
    alarms or candidate ``c``'s (:func:`_held_out_union`), each with margin
    and levels from ``subset`` without ``r``; 0 on a subset of fewer than 3
    (no margin without two other recordings). Recording by recording, each
    band's series read once for all the subsets (a streamed calibration
    reads them from files)."""
    table = {subset: [0] * len(run_series) for subset in subsets}
    for r in keys:
        mine = [subset for subset in subsets if len(subset) >= 3 and r in subset]
        if not mine:
            continue
        fixed = [list(_held_out_alarms(series, mine, r, rule)) for series in fixed_series]
        held = [np.logical_or.reduce([band[i] for band in fixed]) for i in range(len(mine))]
        for c, series in enumerate(run_series):
            for i, alarm in enumerate(_held_out_alarms(series, mine, r, rule)):
                table[mine[i]][c] += len(alarm_onsets(held[i] | alarm))
    return table


# ------------------------------------------------------------------ streamed
#: Rows predicted at a time when the recordings are streamed (``folder``): the
#: cross-kernel of a GP holds rows x support values per joint.
PREDICT_ROWS = 20_000


def _peaks(series, key):
    """Peaks of recording ``key`` (kept in memory by a :class:`_SeriesFiles`)."""
    return series.peaks[key] if isinstance(series, _SeriesFiles) else series[key][2]


def _counts(series, key, n_rows):
    """Samples per regime code of recording ``key``."""
    if isinstance(series, _SeriesFiles):
        return series.counts[key]
    return np.bincount(series[key][1], minlength=n_rows)


class _SeriesFiles(Mapping):
    """:func:`regime_excursions`-like series kept in ``.npy`` files of ``folder``:
    ``series[key]`` reads one recording's ``(debounced, regime, peaks)``; the
    peaks and the samples per regime stay in memory."""

    def __init__(self, folder, n_rows):
        self.folder, self.n_rows = Path(folder), n_rows
        self.folder.mkdir(parents=True, exist_ok=True)
        self.peaks, self.counts, self._files = {}, {}, {}
        self.rest_entries = {}

    def add(self, key, debounced, regime, peaks, rest_entries=None):
        stem = self.folder / f"{len(self._files)}"
        np.save(f"{stem}_m.npy", debounced)
        np.save(f"{stem}_g.npy", regime)
        self._files[key] = stem
        self.peaks[key] = peaks
        self.counts[key] = np.bincount(regime, minlength=self.n_rows)
        self.rest_entries[key] = rest_entries

    def __getitem__(self, key):
        stem = self._files[key]
        return np.load(f"{stem}_m.npy"), np.load(f"{stem}_g.npy"), self.peaks[key]

    def __iter__(self):
        return iter(self._files)

    def __len__(self):
        return len(self._files)


def _streamed_series(base, rules, candidates, blocks, times, folder):
    """Fit ``base`` on the first recording, then each recording's residual once
    and every band's series of it into files: ``(band_rules, series)``."""
    if base.normalize == "std":
        raise ValueError("normalize='std' is not streamed: calibrate on shorter recordings")
    keys = list(blocks)
    first = blocks[keys[0]]
    rows = slice(0, PREDICT_ROWS)  # fit (a frozen model stays as it is) on a few rows
    base.fit_residuals(first[rows], time=np.asarray(times[keys[0]])[rows])
    if base.sample_time == "auto":  # the median step of all recordings, as one fit has it
        steps = np.concatenate([np.diff(np.asarray(times[k], dtype=float)) for k in keys])
        base.sample_time_ = float(np.median(steps[steps > 0]))
    band_rules = _band_rules(rules, candidates, (base.sample_time_, base.sigma_v))
    stores = [_SeriesFiles(Path(folder) / f"band{b}", len(r.regime_names_))
              for b, r in enumerate(band_rules)]
    for key in keys:
        u, motion = _blocked_residuals(base, first if key == keys[0] else blocks[key])
        for r, store in zip(band_rules, stores):
            signal, regime, reference = r.signal(u, motion=motion)
            entries = None if reference is None else rest_entry_peaks(reference, regime, [0])[0]
            store.add(key, *_excursion(r, signal, regime), rest_entries=entries)
        first = None
    return band_rules, stores


def _blocked_residuals(base, block):
    """``(residual, motion)`` of one recording, predicted :data:`PREDICT_ROWS` rows
    at a time (a model that reads the currents, a sequence, all at once)."""
    step = len(block) if reads_currents(base.regressor_) else PREDICT_ROWS
    parts = [base.residuals(block[i:i + step]) for i in range(0, len(block), step)]
    motion = None if parts[0].motion is None else np.concatenate([p.motion for p in parts])
    return np.concatenate([p.residual for p in parts]), motion


def _rule_from_peaks(rule, series, keys, timing):
    """``rule`` fitted as :meth:`AlarmRule.calibrate` fits a ``per_joint`` rule at
    ``false_alarm_rate=0`` with its margin, from the recordings' peaks: the
    level of (regime ``g``, joint ``l``) is the largest debounced excursion,
    lifted by the same relative 1e-9 (``false_alarm_level``); a regime absent
    from the data takes the largest level of the others."""
    rule.prepare(*timing)
    n_rows = len(rule.regime_names_)
    top = np.stack([_peaks(series, k) for k in keys]).max(axis=0)
    levels = np.maximum(top * (1.0 + _LEVEL_MARGIN), np.finfo(float).tiny)
    if rule.regimes is None:
        levels = levels[0]
    else:
        present = sum(_counts(series, k, n_rows) for k in keys) > 0
        levels = fill_absent_regimes(levels, present)
    margin = np.asarray(rule.margin, dtype=float)
    rule.scale_ = margin * levels
    rule.margin_ = np.broadcast_to(margin, np.shape(rule.scale_)).copy()
    rule.offset_ = -1.0
    rule.thresholds_ = 1.0 * rule.scale_
    if rule.regimes is not None and rule.regimes.rest_reference is not None:
        rule.rest_band_ = rest_band(np.stack([series.rest_entries[k] for k in keys]))
    return rule
