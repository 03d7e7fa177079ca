"""Rules that turn training residuals into collision thresholds sigma_CD.

The paper leaves the design of the threshold ``sigma_CD`` open ("might be set
using standard rules, like cross-validation", Sec. III). Every rule here
works on the ratio ``r_l = |m_l| / scale_l`` of the monitoring signal ``m_l``
of joint ``l`` to a per-joint scale, and returns a common level ``gamma``:
a joint fires when ``r_l > gamma``, i.e. ``|m_l| > gamma * scale_l =
sigma_CD,l``. The detector stores ``offset_ = -gamma``.
"""

import numpy as np


def rms_scale(signal):
    """Root mean square of each column, 1 where the column is all zero."""
    scale = np.sqrt(np.mean(np.square(signal), axis=0))
    return np.where(scale > 0.0, scale, 1.0)


def contamination_level(peak, contamination):
    """Level ``gamma`` that flags a fraction ``contamination`` of the samples.

    Follows :class:`sklearn.ensemble.IsolationForest`: the offset is the
    ``100 * contamination`` percentile of the training scores ``-peak``, so
    that exactly that fraction of the training samples has a negative
    decision function (up to ties). ``peak``: the largest debounced ratio
    over the joints, per sample.
    """
    return -float(np.percentile(-peak, 100.0 * contamination))


#: relative margin added above the chosen level (see false_alarm_level)
_LEVEL_MARGIN = 1e-9


def false_alarm_level(peak, starts, sample_time, rate):
    """Smallest level ``gamma`` whose alarm-onset rate stays within ``rate``.

    An alarm onset is a sample with ``peak > gamma`` whose predecessor in the
    same segment has ``peak <= gamma`` (or that opens a segment). Sample
    ``t`` is an onset exactly when ``gamma`` lies in ``[prev_t, peak_t)``, so
    the onset count at every level is a difference of two counts found by
    binary search. The returned level is the smallest candidate (0 or a
    value of ``peak``) such that this level and every higher one give at most
    ``rate`` onsets per hour of training data (``peak``: non-negative,
    ``sample_time`` in s); the count is not monotone in the level (raising
    it can split one alarm into two), hence "every higher one".
    """
    prev = np.empty_like(peak)
    prev[1:] = peak[:-1]
    prev[starts] = 0.0
    rising = prev < peak
    lows = np.sort(prev[rising])
    highs = np.sort(peak[rising])
    candidates = np.unique(np.append(peak, 0.0))
    onsets = np.searchsorted(lows, candidates, side="right") - np.searchsorted(
        highs, candidates, side="right"
    )
    hours = peak.shape[0] * sample_time / 3600.0
    too_many = np.flatnonzero(onsets > rate * hours)
    level = candidates[0] if too_many.size == 0 else candidates[too_many[-1] + 1]
    # a training sample sits exactly on the candidate level: lift the level by
    # a relative 1e-9 so that the same ratio recomputed a few ulps higher
    # (e.g. tick by tick in StreamingMonitor) is not an alarm either
    return float(level) * (1.0 + _LEVEL_MARGIN)


# --------------------------------------------------- levels across recordings
#: How far the leave-one-recording-out margin is shared: one per (regime,
#: joint) cell, one per regime (largest over the joints), one per joint
#: (largest over the regimes), or one for all.
MARGIN_RULES = ("cell", "regime", "joint", "global")


def fill_absent_regimes(table, present):
    """Rows of regimes absent from the data take the largest present value.

    The rule of every per-regime table (n_regime_rows, n_joints) of the
    detector: no data, no tighter band. With no regime present at all the
    table becomes 1. Returns a copy.
    """
    table = np.array(table, dtype=float, copy=True)
    present = np.asarray(present, dtype=bool)
    table[~present] = table[present].max(axis=0) if present.any() else 1.0
    return table


def recording_peaks(debounced, regimes, recordings, n_regime_rows):
    """Peak debounced ``|m|`` per recording, regime and joint.

    ``recordings`` holds the index ``0 .. n_recordings - 1`` of each sample;
    the peaks, of shape (n_recordings, n_regime_rows, n_joints), are zero
    where a recording lacks the regime.
    """
    n_recordings = int(recordings.max()) + 1 if recordings.size else 0
    peaks = np.zeros((n_recordings, n_regime_rows, debounced.shape[1]))
    for r in range(n_recordings):
        mine = recordings == r
        for g in range(n_regime_rows):
            rows = mine & (regimes == g)
            if rows.any():
                peaks[r, g] = debounced[rows].max(axis=0)
    return peaks


def fading_stages(table, rows):
    """Each settling stage at least every later one: the ring of a stop fades.

    ``table``: (..., n_regime_rows, n_joints) peaks or levels; ``rows``: the
    settling stages' rows in time order (:meth:`AlarmRule.settling_rows`).
    Row ``rows[i]`` becomes the largest of the rows ``rows[i:]``, so a stage
    is never tighter than a later one: where the calibration data's largest
    ring fell in a later stage (a short log, few stops), the earlier stages
    do not drop below it. Returns a copy.

    Examples
    --------
    >>> import numpy as np
    >>> table = np.array([[5.0], [1.0], [0.2], [2.0], [0.5]])   # rows 1, 3, 4: stages
    >>> fading_stages(table, [1, 3, 4])[:, 0].tolist()
    [5.0, 2.0, 0.2, 2.0, 0.5]
    """
    out = np.array(table, dtype=float, copy=True)
    rows = list(rows)
    for i in range(len(rows) - 2, -1, -1):
        out[..., rows[i], :] = np.maximum(out[..., rows[i], :], out[..., rows[i + 1], :])
    return out


def peak_levels(peaks):
    """Level per (regime, joint) of ``false_alarm_rate=0``: the largest peak (positive).

    ``peaks`` as :func:`recording_peaks`; a regime absent from every
    recording takes the largest level of the others.
    """
    present = peaks.any(axis=(0, 2))
    table = fill_absent_regimes(peaks.max(axis=0), present)
    return np.maximum(table, np.finfo(float).tiny)


def loro_factors(peaks, rule="global"):
    """:func:`~sklearn_gpcd.detection.loro_margin` on peaks stacked per recording.

    ``peaks`` has shape (n_recordings, n_regime_rows, n_joints), at least 2
    recordings; see that function for the rule.
    """
    if rule not in MARGIN_RULES:
        raise ValueError(f"rule must be one of {MARGIN_RULES}, got {rule!r}")
    n = peaks.shape[0]
    if n < 2:
        raise ValueError(f"leave-one-recording-out needs at least 2 recordings, got {n}")
    factors = [peaks[r] / peak_levels(np.delete(peaks, r, axis=0)) for r in range(n)]
    return shared_margin(factors, rule)


def shared_margin(factors, rule="global"):
    """The margin from left-out factors: at least 1, shared by ``rule``.

    ``factors``: per left-out recording, its peaks over the others' levels,
    each of shape (n_regime_rows, n_joints).
    """
    margin = np.maximum(np.max(factors, axis=0), 1.0)
    if rule == "regime":
        return np.repeat(margin.max(axis=1, keepdims=True), margin.shape[1], axis=1)
    if rule == "joint":
        return np.repeat(margin.max(axis=0, keepdims=True), margin.shape[0], axis=0)
    if rule == "global":
        return np.full_like(margin, margin.max())
    return margin


def rest_band(peaks):
    """The rest band :math:`B_\\ell`: the largest reference at a rest entry, per joint,
    times the leave-one-recording-out factor of those peaks (shared by the joints).

    ``peaks``: :func:`~sklearn_gpcd.detection._regimes.rest_entry_peaks`, one row
    per recording. None (no bound) with fewer than 2 recordings that enter
    rest: a band needs a recording left out to be checked against.
    """
    peaks = peaks[peaks.any(axis=1)]
    if peaks.shape[0] < 2:
        return None
    factor = float(loro_factors(peaks[:, None, :], "global").max())
    return np.maximum(factor * peaks.max(axis=0), np.finfo(float).tiny)
