"""Thresholds chosen across recordings: leave-one-recording-out (LORO) margins.

A detector calibrated with ``threshold="per_joint", false_alarm_rate=0`` sets
each (regime, joint) level to the largest debounced excursion of its
collision-free calibration data. On a recording it never saw, the excursions
can be larger. The rule here (the one of ``benchmarks/real_ur10e.py`` and of
``gpcd calibrate``):

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
   margin (:func:`calibrate_across_recordings` does 1-4).
"""

import numpy as np
from sklearn.base import clone
from sklearn.utils import Bunch

from ..features.masks import contiguous_segments
from ._signal import debounce_segments, segment_starts
from ._thresholds import MARGIN_RULES, loro_factors, peak_levels, recording_peaks

__all__ = [
    "MARGIN_RULES",
    "calibrate_across_recordings",
    "loro_margin",
    "nested_false_alarms",
    "regime_excursions",
    "regime_levels",
]

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
    n_rows = len(detector.regime_names_)
    out = {}
    for key, block in blocks.items():
        mon = detector.monitoring_signal(block)
        starts = segment_starts(len(block))
        debounced = debounce_segments(np.abs(mon.signal), detector.min_duration, starts)
        recording = np.zeros(len(block), dtype=np.intp)
        peaks = recording_peaks(debounced, mon.regime, recording, n_rows)[0]
        out[key] = (debounced, mon.regime, peaks)
    return out


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


def _alarm_onsets(alarm, t):
    """Start times of the alarm episodes (any joint)."""
    return [float(t[a]) for a, _ in contiguous_segments(alarm)]


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
    peaks = {k: v[2] for k, v in series.items()}
    keys = list(series)
    out = {}
    for r in keys:
        rest = [k for k in keys if k != r]
        thr = loro_margin(peaks, rest, rule) * regime_levels(peaks, rest)
        debounced, regimes, _ = series[r]
        alarm = (debounced > thr[regimes]).any(axis=1)
        t = np.asarray(times[r], dtype=float)
        t = t - t[0]
        out[r] = {"onsets": _alarm_onsets(alarm, t), "hours": float(t[-1] / 3600.0),
                  "first_second_alarm_samples": int(alarm[t < 1.0].sum())}
    return out


def calibrate_across_recordings(detector, blocks, times, rule="global"):
    """Fit a detector with a leave-one-recording-out margin; count nested false alarms.

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

    Returns
    -------
    result : Bunch
        ``detector`` (fitted on all recordings at the operating point),
        ``margin`` and ``levels`` (n_regime_rows, n_joints), ``folds`` (from
        :func:`nested_false_alarms`, empty with 2 recordings), ``n_false_alarms``
        (their total), ``hours`` and ``false_alarms_per_hour`` (None with
        fewer than 3 recordings), and ``series`` (from
        :func:`regime_excursions` at a unit margin, e.g. to compare rules
        with :func:`nested_false_alarms`).

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
    """
    keys = list(blocks)
    if len(keys) < 2:
        raise ValueError("calibration across recordings needs at least 2 collision-free "
                         f"recordings, got {len(keys)}")
    Z = np.concatenate([blocks[k] for k in keys])
    groups = np.repeat(np.arange(len(keys)), [len(blocks[k]) for k in keys])
    time = np.concatenate([np.asarray(times[k], dtype=float) for k in keys])
    base = clone(detector).set_params(margin=1.0).fit(Z, groups=groups, time=time)
    series = regime_excursions(base, blocks)
    peaks = {k: v[2] for k, v in series.items()}
    margin = loro_margin(peaks, keys, rule)
    folds = nested_false_alarms(series, times, rule) if len(keys) >= 3 else {}
    shaped = margin.reshape(np.shape(base.scale_))  # (n_joints,) without regimes
    fitted = clone(detector).set_params(margin=shaped).fit(Z, groups=groups, time=time)
    hours = float(sum((times[k][-1] - times[k][0]) for k in keys) / 3600.0)
    n_false = sum(len(f["onsets"]) for f in folds.values())
    return Bunch(detector=fitted, margin=margin, levels=regime_levels(peaks, keys),
                 folds=folds, n_false_alarms=n_false, hours=hours,
                 false_alarms_per_hour=(n_false / hours if folds and hours > 0 else None),
                 regime_names=tuple(fitted.regime_names_), series=series)

