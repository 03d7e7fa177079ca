"""Metrics for current prediction (nMSE, paper Eq. 18) and collision detection.

Event-level detection metrics take per-sample contact ``labels`` (0 free,
``k > 0`` inside contact ``k``, as in :class:`~sklearn_gpcd.io.Recording`)
and per-sample boolean ``alarms``. An *event* is a maximal run of samples
with the same non-zero label. Its *detection window* is the event itself or,
with ``max_delay``, the samples from its onset up to ``max_delay`` later
(shorter or longer than the contact, never reaching into the next event); an
alarm in the window detects the event, with delay = time from the onset.

To score a :class:`~sklearn_gpcd.detection.CollisionDetector`, pass
``alarms = detector.predict(X) == -1``, or use :class:`DetectionScorer`
and :class:`DetectionRefit` in a grid search.
"""

import warnings

import numpy as np
from scipy.stats import chi2
from sklearn.utils.metadata_routing import MetadataRequest

__all__ = [
    "alarm_onsets",
    "contact_events",
    "DetectionRefit",
    "DetectionScorer",
    "detection_delay",
    "event_recall",
    "false_alarms_per_hour",
    "fold_means",
    "rate_upper_bound",
    "mean_detection_delay",
    "nmse",
    "select_candidate",
]


# --------------------------------------------------------------- validation
def _check_labels_alarms(labels, alarms):
    labels = np.asarray(labels)
    if labels.ndim != 1:
        raise ValueError(f"labels must be 1-D (one per sample), got shape {labels.shape}")
    alarms = np.asarray(alarms)
    if alarms.shape != labels.shape:
        raise ValueError(
            f"alarms must have the shape of labels {labels.shape}, got {alarms.shape}"
        )
    return labels, _check_alarm_values(alarms)


def _check_alarm_values(alarms):
    """``alarms`` as bool; 0 / 1 accepted, anything else is an error."""
    if alarms.dtype != bool:
        values = np.unique(alarms)
        if not np.isin(values, (0, 1)).all():
            raise ValueError(
                f"alarms must be boolean (True = alarm), got values {values[:5].tolist()}; "
                "from CollisionDetector.predict pass `predict(X) == -1`"
            )
        alarms = alarms.astype(bool)
    return alarms


def _check_groups(groups, n):
    if groups is None:
        return None
    groups = np.asarray(groups)
    if groups.shape != (n,):
        raise ValueError(f"groups must have shape ({n},), got {groups.shape}")
    return groups


def _check_time(time, sample_time, n, required):
    """Per-sample time stamps in seconds, or None (metrics in samples)."""
    if time is not None:
        time = np.asarray(time, dtype=float)
        if time.shape != (n,):
            raise ValueError(f"time must have shape ({n},), got {time.shape}")
        return time
    if sample_time is not None:
        if not sample_time > 0:
            raise ValueError(f"sample_time must be > 0 seconds, got {sample_time!r}")
        return np.arange(n) * float(sample_time)
    if required:
        raise ValueError("pass time (seconds per sample) or sample_time (seconds)")
    return None


def _new_segment(n, groups):
    new = np.zeros(n, dtype=bool)
    if n:
        new[0] = True
    if groups is not None:
        new[1:] |= groups[1:] != groups[:-1]
    return new


# ------------------------------------------------------------------- alarms
def alarm_onsets(alarms, time=None, new=None):
    """Times at which alarm episodes start.

    An onset is a sample with an alarm whose predecessor has none (the first
    sample counts when it alarms), or an alarm sample marked ``new`` (a
    contact event that begins while the one before is still open: the
    ``event_onset`` of the monitoring signal). With one column per joint, a sample alarms
    when any joint does, so overlapping alarms on several joints are one
    episode. On one recording, these are the onsets that
    :func:`false_alarms_per_hour` counts before it leaves out those that
    belong to a contact.

    Parameters
    ----------
    alarms : array-like of bool, shape (n_samples,) or (n_samples, n_joints)
        True where the detector raised an alarm (per joint, or any joint).
    time : array-like of shape (n_samples,), default=None
        Time stamp of each sample; None gives the sample indices.
    new : array-like of bool, shape (n_samples,), default=None
        Samples where an episode begins even with an alarm before them.

    Returns
    -------
    onsets : list of float, or list of int when ``time`` is None
        ``time[k]`` (or ``k``) of each onset, in increasing order.

    Examples
    --------
    >>> from sklearn_gpcd.metrics import alarm_onsets
    >>> alarm_onsets([0, 1, 1, 0, 1])
    [1, 4]
    >>> alarm_onsets([0, 1, 1, 1, 0], new=[0, 0, 0, 1, 0])
    [1, 3]
    >>> alarm_onsets([[0, 0], [1, 0], [0, 1], [0, 0]], time=[0.0, 0.01, 0.02, 0.03])
    [0.01]
    """
    alarms = np.asarray(alarms)
    if alarms.ndim not in (1, 2):
        raise ValueError(
            f"alarms must be 1-D (n_samples,) or 2-D (n_samples, n_joints), got shape "
            f"{alarms.shape}"
        )
    n = alarms.shape[0]
    alarms = _check_alarm_values(alarms)
    any_joint = alarms.any(axis=1) if alarms.ndim == 2 else alarms
    first = ~np.concatenate([[False], any_joint[:-1]])
    if new is not None:
        first |= _check_alarm_values(np.asarray(new)).reshape(n)
    starts = np.flatnonzero(any_joint & first)
    if time is None:
        return starts.tolist()
    time = _check_time(time, None, n, required=True)
    return time[starts].tolist()


# ------------------------------------------------------------------- events
def contact_events(labels, groups=None):
    """Start and stop (exclusive) of every contact event.

    Parameters
    ----------
    labels : array-like of shape (n_samples,)
        0 for free motion, ``k > 0`` inside contact ``k``.
    groups : array-like of shape (n_samples,), default=None
        Recording id per sample; an event never spans two recordings.

    Returns
    -------
    starts, stops : ndarray of int
        Row ranges ``[start, stop)`` of the events, in time order.

    Examples
    --------
    >>> starts, stops = contact_events([0, 1, 1, 0, 2, 2, 3, 0])
    >>> starts.tolist(), stops.tolist()
    ([1, 4, 6], [3, 6, 7])
    """
    labels = np.asarray(labels)
    n = labels.shape[0]
    groups = _check_groups(groups, n)
    boundary = _new_segment(n, groups)
    boundary[1:] |= labels[1:] != labels[:-1]
    run_starts = np.flatnonzero(boundary)
    run_stops = np.append(run_starts[1:], n)
    contact = labels[run_starts] != 0
    return run_starts[contact], run_stops[contact]


def _windows(labels, time, max_delay, groups):
    """Detection window ``[start, end)`` of every event, within its recording."""
    starts, stops = contact_events(labels, groups)
    if max_delay is None:
        return starts, stops
    n = labels.shape[0]
    segment_ends = np.append(np.flatnonzero(_new_segment(n, groups))[1:], n)
    ends = np.empty_like(stops)
    for e, start in enumerate(starts):
        limit = segment_ends[np.searchsorted(segment_ends, start, side="right")]
        if e + 1 < len(starts):
            limit = min(limit, starts[e + 1])
        if time is None:
            end = start + int(np.floor(max_delay)) + 1
        else:
            # 1 ns slack so that a delay of exactly max_delay survives rounding
            horizon = time[start] + max_delay + 1e-9
            end = start + int(np.searchsorted(time[start:limit], horizon, side="right"))
        ends[e] = min(end, limit)
    return starts, ends


def detection_delay(
    labels, alarms, *, max_delay=None, time=None, sample_time=None, groups=None
):
    """Delay from each contact onset to the first alarm in its window.

    Parameters
    ----------
    labels : array-like of shape (n_samples,)
        Contact labels (0 free, ``k > 0`` in contact ``k``).
    alarms : array-like of bool, shape (n_samples,)
        True where the detector raised an alarm.
    max_delay : float, default=None
        Longest accepted delay, in the units of the result; ``None`` accepts
        alarms during the contact only.
    time : array-like of shape (n_samples,), default=None
        Time stamps in seconds (increasing within each recording).
    sample_time : float, default=None
        Sampling period in seconds, when ``time`` is not given.
    groups : array-like of shape (n_samples,), default=None
        Recording id per sample.

    Returns
    -------
    delays : ndarray of shape (n_events,)
        Delay per event: seconds when ``time`` or ``sample_time`` is given,
        samples otherwise; NaN for a missed event.

    Examples
    --------
    >>> labels = [0, 1, 1, 1, 0, 0, 2, 2, 0, 0]
    >>> alarms = [0, 0, 1, 1, 0, 0, 0, 0, 0, 0]
    >>> detection_delay(labels, alarms).tolist()
    [1.0, nan]
    >>> detection_delay(labels, alarms, sample_time=0.008).tolist()
    [0.008, nan]
    """
    labels, alarms = _check_labels_alarms(labels, alarms)
    groups = _check_groups(groups, labels.shape[0])
    time = _check_time(time, sample_time, labels.shape[0], required=False)
    starts, ends = _windows(labels, time, max_delay, groups)
    delays = np.full(starts.shape, np.nan)
    for e, (start, end) in enumerate(zip(starts, ends)):
        hits = np.flatnonzero(alarms[start:end])
        if hits.size:
            first = start + hits[0]
            delays[e] = hits[0] if time is None else time[first] - time[start]
    return delays


def event_recall(labels, alarms, *, max_delay=None, time=None, sample_time=None, groups=None):
    """Fraction of contact events with an alarm in their detection window.

    Parameters
    ----------
    labels : array-like of shape (n_samples,)
        Contact labels (0 free, ``k > 0`` in contact ``k``).
    alarms : array-like of bool, shape (n_samples,)
        True where the detector raised an alarm.
    max_delay : float, default=None
        Longest accepted delay (seconds with ``time`` / ``sample_time``,
        samples otherwise); ``None`` accepts alarms during the contact only.
    time : array-like of shape (n_samples,), default=None
        Time stamps in seconds.
    sample_time : float, default=None
        Sampling period in seconds, when ``time`` is not given.
    groups : array-like of shape (n_samples,), default=None
        Recording id per sample.

    Returns
    -------
    recall : float
        Detected events / events; NaN when there is no event.

    Examples
    --------
    >>> labels = [0, 1, 1, 0, 2, 2, 0, 3, 0, 0]
    >>> alarms = [0, 0, 1, 0, 0, 0, 0, 0, 1, 0]
    >>> event_recall(labels, alarms)
    0.3333333333333333
    >>> event_recall(labels, alarms, max_delay=1)      # late alarm on event 3
    0.6666666666666666
    """
    delays = detection_delay(
        labels, alarms, max_delay=max_delay, time=time, sample_time=sample_time, groups=groups
    )
    if delays.size == 0:
        return float("nan")
    return float(np.mean(~np.isnan(delays)))


def mean_detection_delay(
    labels, alarms, *, max_delay=None, time=None, sample_time=None, groups=None
):
    """Mean delay with missed events counted at their full window length.

    A missed event is charged the longest delay it could have had: its
    detection window (``max_delay`` or the contact duration). This keeps the
    mean finite and penalises misses, so it can rank detectors.

    Parameters
    ----------
    labels, alarms, max_delay, time, sample_time, groups
        As in :func:`detection_delay`.

    Returns
    -------
    delay : float
        NaN when there is no event.

    Examples
    --------
    >>> labels = [0, 1, 1, 1, 0, 2, 2, 0]
    >>> alarms = [0, 0, 1, 0, 0, 0, 0, 0]
    >>> mean_detection_delay(labels, alarms)    # (1 + 2) / 2
    1.5
    """
    labels, alarms = _check_labels_alarms(labels, alarms)
    groups = _check_groups(groups, labels.shape[0])
    t = _check_time(time, sample_time, labels.shape[0], required=False)
    delays = detection_delay(labels, alarms, max_delay=max_delay, time=t, groups=groups)
    if delays.size == 0:
        return float("nan")
    if max_delay is not None:
        censored = np.full(delays.shape, float(max_delay))
    else:
        starts, stops = contact_events(labels, groups)
        if t is None:
            censored = (stops - starts).astype(float)
        else:
            uniform = sample_time if time is None else None
            dt = _sample_durations(t, _new_segment(t.shape[0], groups), uniform)
            censored = np.array([dt[start:stop].sum() for start, stop in zip(starts, stops)])
    return float(np.mean(np.where(np.isnan(delays), censored, delays)))


def false_alarms_per_hour(
    labels, alarms, *, max_delay=None, time=None, sample_time=None, groups=None
):
    """Alarm onsets outside contact events, per hour of collision-free data.

    An alarm onset is a sample with an alarm whose predecessor (in the same
    recording) has none. Onsets inside a contact or inside an event's
    detection window belong to that event; all others are false alarms. The
    rate divides their number by the duration of the collision-free (label 0)
    samples.

    Parameters
    ----------
    labels : array-like of shape (n_samples,)
        Contact labels (0 free, ``k > 0`` in contact ``k``).
    alarms : array-like of bool, shape (n_samples,)
        True where the detector raised an alarm.
    max_delay : float, default=None
        Extends each event's window to ``max_delay`` seconds after its onset.
    time : array-like of shape (n_samples,), default=None
        Time stamps in seconds; a sample lasts until the next one (the last
        sample of each recording lasts the median sampling period).
    sample_time : float, default=None
        Sampling period in seconds, when ``time`` is not given.
    groups : array-like of shape (n_samples,), default=None
        Recording id per sample.

    Returns
    -------
    rate : float
        False alarms per hour; NaN when there is no collision-free sample.

    Examples
    --------
    >>> labels = [0, 0, 0, 1, 1, 0, 0, 0, 0, 0]
    >>> alarms = [1, 1, 0, 0, 1, 1, 0, 1, 0, 0]
    >>> false_alarms_per_hour(labels, alarms, sample_time=450.0)  # 2 in 1 h
    2.0
    """
    labels, alarms = _check_labels_alarms(labels, alarms)
    n = labels.shape[0]
    groups = _check_groups(groups, n)
    time_given = time
    time = _check_time(time, sample_time, n, required=True)
    starts, ends = _windows(labels, time, max_delay, groups)
    attributed = labels != 0
    for start, end in zip(starts, ends):
        attributed[start:end] = True
    new = _new_segment(n, groups)
    previous = np.zeros(n, dtype=bool)
    previous[1:] = alarms[:-1]
    previous[new] = False
    onsets = alarms & ~previous & ~attributed
    uniform = sample_time if time_given is None else None
    duration = _sample_durations(time, new, uniform)
    free_hours = duration[labels == 0].sum() / 3600.0
    if free_hours <= 0:
        return float("nan")
    return float(onsets.sum() / free_hours)


def rate_upper_bound(count, hours, confidence=0.95):
    """Upper confidence bound of an event rate from a count (Poisson, exact).

    ``count`` alarm onsets seen in ``hours`` of data bound the true rate by

    .. math:: \\lambda_{up} = \\frac{\\chi^2_{c}(2n + 2)}{2T}

    (the one-sided Garwood bound at confidence :math:`c`): with no onset in
    ``T`` hours the rate is below ``3.0 / T`` per hour at 95 %, so a short
    calibration cannot promise a low false-alarm rate, whatever it saw.

    Parameters
    ----------
    count : int
        Events seen (e.g. nested false-alarm onsets).
    hours : float
        Duration of the data they were counted on [h].
    confidence : float, default=0.95
        One-sided confidence level.

    Returns
    -------
    bound : float
        Events per hour (inf without data).

    Examples
    --------
    >>> round(rate_upper_bound(0, 1.0), 2)      # nothing seen in one hour
    3.0
    >>> round(rate_upper_bound(0, 20 / 3600), 0)  # nothing seen in 20 s
    539.0
    """
    if hours <= 0:
        return float("inf")
    return float(chi2.ppf(confidence, 2 * int(count) + 2) / (2.0 * hours))


def _sample_durations(time, new, sample_time=None):
    """Seconds each sample lasts: until the next sample of its recording.

    With a uniform ``sample_time`` every sample lasts exactly that long.
    """
    if sample_time is not None:
        return np.full(time.shape, float(sample_time))
    dt = np.empty_like(time)
    dt[:-1] = np.diff(time)
    last = np.append(np.flatnonzero(new[1:]), time.shape[0] - 1)
    inner = np.ones(time.shape[0], dtype=bool)
    inner[last] = False
    dt[last] = np.median(dt[inner]) if inner.any() else 0.0
    return dt


# --------------------------------------------------------------- regression
def nmse(y_true, y_pred, *, mask=None, multioutput="raw_values"):
    """Normalised mean squared error per joint (paper Eq. 18).

    .. math:: \\mathrm{nMSE}_l = \\frac{\\frac{1}{N}\\sum_{k=1}^{N}
              (i_l(x_k) - \\hat{i}_l(x_k))^2}{\\mathrm{Var}(i_l)}

    with the variance (``ddof=0``) of the target over the same samples.
    0 is a perfect fit; 1 is no better than the target's mean.

    Parameters
    ----------
    y_true : array-like of shape (n_samples,) or (n_samples, n_joints)
        Measured currents.
    y_pred : array-like of the same shape
        Predicted currents.
    mask : array-like of bool, shape (n_samples,) or (n_samples, n_joints), \
            default=None
        Samples to score, e.g. ``|qd_l| < sigma_v`` for the quasi-static
        nMSE of joint ``l`` (paper Fig. 5) or its negation for the dynamic
        one (Fig. 4). ``None`` scores all samples.
    multioutput : {"raw_values", "uniform_average"}, default="raw_values"
        Return one value per joint, or their mean.

    Returns
    -------
    nmse : float or ndarray of shape (n_joints,)
        A float for 1-D targets or ``"uniform_average"``. NaN for a joint
        whose target is constant (or has no sample) under the mask.

    Examples
    --------
    >>> nmse([1.0, 2.0, 3.0], [1.0, 2.0, 4.0])   # (1/3) / (2/3)
    0.5
    """
    y_true = np.asarray(y_true, dtype=float)
    y_pred = np.asarray(y_pred, dtype=float)
    if y_true.shape != y_pred.shape or y_true.ndim not in (1, 2):
        raise ValueError(
            f"y_true and y_pred must have the same shape (n_samples,) or "
            f"(n_samples, n_joints); got {y_true.shape} and {y_pred.shape}"
        )
    one_d = y_true.ndim == 1
    yt = y_true.reshape(y_true.shape[0], -1)
    yp = y_pred.reshape(yt.shape)
    if mask is None:
        m = np.ones(yt.shape, dtype=bool)
    else:
        m = np.asarray(mask, dtype=bool)
        if m.ndim == 1 and m.shape[0] == yt.shape[0]:
            m = np.repeat(m[:, None], yt.shape[1], axis=1)
        if m.shape != yt.shape:
            raise ValueError(
                f"mask must have shape ({yt.shape[0]},) or {yt.shape}, got {np.shape(mask)}"
            )
    if multioutput not in ("raw_values", "uniform_average"):
        raise ValueError(
            f"multioutput must be 'raw_values' or 'uniform_average', got {multioutput!r}"
        )
    values = np.full(yt.shape[1], np.nan)
    for j in range(yt.shape[1]):
        t, p = yt[m[:, j], j], yp[m[:, j], j]
        # a constant target is NaN even when round-off makes np.var(t) > 0
        var = np.var(t) if t.size and np.ptp(t) > 0 else 0.0
        if var > 0:
            values[j] = np.mean((t - p) ** 2) / var
    if multioutput == "uniform_average":
        return float(np.mean(values))
    return float(values[0]) if one_d else values


# ------------------------------------------------------------------ scorers
class DetectionScorer:
    """Scorer of an outlier detector on labelled recordings, for ``GridSearchCV``.

    Called as ``scorer(estimator, X, labels, groups=None, time=None)``, it
    takes the alarms ``estimator.predict(X, groups) == -1`` and returns the
    three detection metrics at once (one ``predict`` per fold):
    ``"recall"`` (:func:`event_recall`), ``"false_alarms_per_hour"``
    (:func:`false_alarms_per_hour`) and ``"delay"``
    (:func:`mean_detection_delay`, seconds), the last two negated (the
    scikit-learn convention: greater is better). Pair it with
    :class:`DetectionRefit` as ``refit``.

    It requests the metadata ``groups`` (recording id per row: filters and
    debounce restart, events and alarms never span two recordings) and
    ``time`` (time stamps [s]), so under scikit-learn's metadata routing
    (``sklearn.config_context(enable_metadata_routing=True)``) a grid search
    hands it the held-out fold's rows of both.

    Parameters
    ----------
    max_delay : float, default=None
        Longest accepted detection delay in seconds (also the detection
        window of each contact).
    sample_time : float, default=None
        Sampling period [s] when no ``time`` is given; None takes the
        estimator's ``sample_time_``.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.base import BaseEstimator, OutlierMixin
    >>> class AlarmEverywhere(OutlierMixin, BaseEstimator):
    ...     sample_time_ = 1.0
    ...     def predict(self, X, groups=None):
    ...         return -np.ones(len(X), dtype=int)
    >>> DetectionScorer()(AlarmEverywhere(), np.zeros((4, 2)), [0, 1, 1, 0])
    {'recall': 1.0, 'false_alarms_per_hour': -1800.0, 'delay': -0.0}
    """

    def __init__(self, max_delay=None, sample_time=None):
        self.max_delay = max_delay
        self.sample_time = sample_time

    def __call__(self, estimator, X, labels, groups=None, time=None):
        alarms = (estimator.predict(X) if groups is None else estimator.predict(X, groups)) == -1
        kwargs = {"max_delay": self.max_delay, "groups": groups}
        if time is None:
            kwargs["sample_time"] = (estimator.sample_time_ if self.sample_time is None
                                     else self.sample_time)
        else:
            kwargs["time"] = time
        return {"recall": event_recall(labels, alarms, **kwargs),
                "false_alarms_per_hour": -false_alarms_per_hour(labels, alarms, **kwargs),
                "delay": -mean_detection_delay(labels, alarms, **kwargs)}

    def get_metadata_routing(self):
        """The metadata this scorer asks for: ``groups`` and ``time``.

        Returns
        -------
        request : sklearn.utils.metadata_routing.MetadataRequest
        """
        request = MetadataRequest(owner=type(self).__name__)
        for name in ("groups", "time"):
            request.score.add_request(param=name, alias=True)
        return request


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


def fold_means(cv_results, metric):
    """Mean and std over the folds of a metric, ignoring NaN folds.

    A fold without contacts has no recall or delay (NaN); the mean is over
    the folds that have one (NaN when none has).

    Parameters
    ----------
    cv_results : dict
        ``cv_results_`` of a search with ``split<k>_test_<metric>`` keys.
    metric : str

    Returns
    -------
    mean, std : ndarray of shape (n_candidates,)

    Examples
    --------
    >>> import numpy as np
    >>> fold_means({"split0_test_recall": np.array([1.0, 0.5]),
    ...             "split1_test_recall": np.array([np.nan, 1.0])}, "recall")
    (array([1.  , 0.75]), array([0.  , 0.25]))
    """
    suffix = f"_test_{metric}"
    folds = np.array([v for k, v in cv_results.items()
                      if k.startswith("split") and k.endswith(suffix)], dtype=float)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns
        return np.nanmean(folds, axis=0), np.nanstd(folds, axis=0)


class DetectionRefit:
    """``refit`` callable for ``GridSearchCV`` with :class:`DetectionScorer`.

    Picks the candidate by :func:`select_candidate` from the NaN-ignoring
    fold means (:func:`fold_means`) of ``cv_results_`` (whose delay and
    false-alarm scores are negated by the scorer).

    Parameters
    ----------
    max_delay : float, default=None
        Bound on the mean detection delay in seconds.

    Examples
    --------
    >>> import numpy as np
    >>> results = {"split0_test_recall": np.array([1.0, 1.0]),
    ...            "split0_test_false_alarms_per_hour": np.array([-2.0, -1.0]),
    ...            "split0_test_delay": np.array([-0.1, -0.2])}
    >>> DetectionRefit()(results)
    1
    """

    def __init__(self, max_delay=None):
        self.max_delay = max_delay

    def __call__(self, cv_results):
        recall, false_alarms, delay = (fold_means(cv_results, m)[0]
                                       for m in ("recall", "false_alarms_per_hour", "delay"))
        return select_candidate(recall, -false_alarms, -delay, self.max_delay)
