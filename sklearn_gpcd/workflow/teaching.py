"""Teach a calibrated detector one task: the function behind ``gpcd teach``.

Train once per robot (``gpcd train``), calibrate once per robot
(``gpcd calibrate``), teach once per task (``gpcd teach``), monitor. The
taught detector file is a detector file like the one ``gpcd calibrate``
writes, whose detector is a :class:`~sklearn_gpcd.detection.TaughtTask`
wrapping the calibrated :class:`~sklearn_gpcd.detection.CollisionDetector`
(the calibration summary gains a ``"teach"`` entry).
"""

import copy
import warnings

import numpy as np

from .calibration import CalibratedDetector, untaught_detector

__all__ = ["teach_task", "teach_report", "update_task"]


def teach_task(calibrated, recordings, *, keys=None, **params):
    """Teach ``calibrated`` the task of ``recordings`` (collision-free cycles).

    Parameters
    ----------
    calibrated : CalibratedDetector
        What :func:`~sklearn_gpcd.workflow.calibrate_detector` (or
        :func:`~sklearn_gpcd.workflow.load_detector`) returned; a taught
        detector is taught anew from its calibrated detector.
    recordings : list of Recording
        At least two cycles of one task, in one or more recordings.
    keys : list of str, default=None
        Their names in the summary.
    **params
        :class:`~sklearn_gpcd.detection.TaughtTask` parameters (``cutoff``,
        ``order``, ``min_duration``, ``novelty_radius``, ...).

    Returns
    -------
    taught : CalibratedDetector
        ``detector`` is the fitted :class:`~sklearn_gpcd.detection.TaughtTask`;
        ``calibration["teach"]`` its summary (:meth:`TaughtTask.summary
        <sklearn_gpcd.detection.TaughtTask.summary>`), with the recordings
        and their seconds.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.frozen import FrozenEstimator
    >>> from sklearn.linear_model import Ridge
    >>> from sklearn_gpcd.detection import AlarmRule, CollisionDetector, stack_currents
    >>> from sklearn_gpcd.features import CausalFeatures
    >>> from sklearn_gpcd.io import Recording
    >>> t = np.arange(0, 16, 0.01)
    >>> q = np.sin(2 * np.pi * t / 4)[:, None]
    >>> rec = Recording(time=t, q=q, qd=np.gradient(q[:, 0], t)[:, None],
    ...                 current=0.2 * np.tanh(np.gradient(q[:, 0], t))[:, None])
    >>> features = CausalFeatures(signals=()).fit([rec])
    >>> X = features.transform(rec)
    >>> det = CollisionDetector(FrozenEstimator(Ridge().fit(X, rec.current)),
    ...                         rules=AlarmRule(contamination=0.01), sample_time=0.01)
    >>> det = det.fit(stack_currents(X, rec.current))
    >>> taught = teach_task(CalibratedDetector(det, features, {}), [rec])
    >>> taught.calibration["teach"]["n_cycles"]
    4
    """
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..detection import TaughtTask

    detector = untaught_detector(calibrated.detector)
    features = calibrated.features
    keys = list(keys) if keys is not None else [r.name for r in recordings]
    blocks, groups = [], []
    for k, rec in enumerate(recordings):
        blocks.append(_task_rows(calibrated, rec))
        groups.append(np.full(len(blocks[-1]), k))
    task = TaughtTask(detector, **params).fit(np.vstack(blocks), groups=np.concatenate(groups))
    summary = {**task.summary(), "recordings": keys,
               "seconds": [float(r.time[-1] - r.time[0]) for r in recordings]}
    return CalibratedDetector(task, features, {**calibrated.calibration, "teach": summary})


def _task_rows(calibrated, rec):
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..detection import stack_currents

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # missing controller signals: zeros, as calibrated
        X = calibrated.features.transform(rec)
    return stack_currents(X, rec.current)


def update_task(taught, recordings, *, keys=None):
    """Keep learning: the slow drift of a taught task from monitored recordings.

    Each recording, in order, is one :meth:`TaughtTask.partial_fit
    <sklearn_gpcd.detection.TaughtTask.partial_fit>` call (successive cycles
    of the cell): only whole cycles far from every alarm teach, the drift is
    bounded, the thresholds never rise.

    Parameters
    ----------
    taught : CalibratedDetector
        What :func:`teach_task` (or :func:`~sklearn_gpcd.workflow.load_detector`
        on a ``gpcd teach`` file) returned.
    recordings : list of Recording
        Monitored recordings of the task, in time order.
    keys : list of str, default=None
        Their names in the summary.

    Returns
    -------
    updated : CalibratedDetector
        A copy; ``calibration["teach"]["learning"]`` lists, per recording,
        the cycles accepted and rejected (with the reasons) and the drift
        [A] after it.

    Examples
    --------
    A task taught as in :func:`teach_task`'s example, then given two more logs:

    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> t = np.arange(0, 16, 0.01)
    >>> q = np.sin(np.pi * t / 2)[:, None]
    >>> from sklearn.frozen import FrozenEstimator
    >>> from sklearn.linear_model import Ridge
    >>> from sklearn_gpcd.detection import AlarmRule, CollisionDetector, stack_currents
    >>> from sklearn_gpcd.features import CausalFeatures
    >>> qd = np.gradient(q[:, 0], t)[:, None]
    >>> rec = Recording(time=t, q=q, qd=qd, current=0.2 * np.tanh(qd))
    >>> features = CausalFeatures(signals=()).fit([rec])
    >>> ridge = FrozenEstimator(Ridge().fit(features.transform(rec), rec.current))
    >>> rows = stack_currents(features.transform(rec), rec.current)
    >>> det = CollisionDetector(ridge, rules=AlarmRule(contamination=0.01), sample_time=0.01)
    >>> taught = teach_task(CalibratedDetector(det.fit(rows), features, {}), [rec])
    >>> updated = update_task(taught, [rec, rec])
    >>> [entry["cycles"] for entry in updated.calibration["teach"]["learning"]]
    [4, 4]
    """
    task = copy.deepcopy(taught.detector)
    if not hasattr(task, "partial_fit"):
        raise ValueError("the detector is not taught: run gpcd teach DETECTOR TASK_LOG... "
                         "first, then update the taught file")
    keys = list(keys) if keys is not None else [r.name for r in recordings]
    learning = list(taught.calibration.get("teach", {}).get("learning", []))
    for key, rec in zip(keys, recordings):
        task.partial_fit(_task_rows(taught, rec))
        last = task.last_learning_
        verdicts = last["verdicts"]
        learning.append({"recording": key, "cycles": len(verdicts),
                         "accepted": verdicts.count("accepted"),
                         "pending": verdicts.count("pending"),
                         "rejected": {v: verdicts.count(v) for v in sorted(set(verdicts))
                                      if v not in ("accepted", "pending")},
                         "drift_A": last["drift_A"]})
    summary = {**taught.calibration.get("teach", {}), **task.summary(), "learning": learning}
    return CalibratedDetector(task, taught.features, {**taught.calibration, "teach": summary})


def _level_lines(summary):
    bound = (f"bounds a new cycle's alarm by {summary['false_alarm_bound_per_cycle']:.2g} = "
             f"1/(cycles+1)")
    free = (f"at most {summary['false_alarms_per_hour_bound']:.0f} per hour of the task; "
            "teach more cycles to lower it")
    if summary.get("tail_level", 0.0) > summary.get("conformal_level", np.inf):
        return [f"  level {summary['level']:.2f} = the Gumbel law of the cycle scores at "
                f"{summary['false_alarm_rate']:g} false alarms per hour",
                f"  (the largest cycle score, {summary['conformal_level']:.2f}, {bound}",
                f"  without a law: {free})"]
    return [f"  level {summary['level']:.2f} = the largest cycle score: it {bound}:",
            f"  {free}"]


def teach_report(summary):
    """The lines ``gpcd teach`` prints for ``calibration["teach"]``.

    Parameters
    ----------
    summary : dict
        :meth:`TaughtTask.summary <sklearn_gpcd.detection.TaughtTask.summary>`
        with ``recordings`` and ``seconds``.

    Returns
    -------
    text : str

    Examples
    --------
    >>> print(teach_report({"recordings": ["a.csv"], "seconds": [18.0], "period_s": 6.8,
    ...     "n_cycles": 3, "repeatability": 0.96, "explained": [0.9, 0.8],
    ...     "level": 2.1, "thresholds_A": [0.5, 0.4], "deviant_cycles": [],
    ...     "filter": {"cutoff_hz": 10.0, "order": 1, "min_duration": 2},
    ...     "false_alarm_bound_per_cycle": 0.25, "false_alarms_per_hour_bound": 132.0,
    ...     "conformal_level": 1.6, "tail_level": 2.1, "false_alarm_rate": 0.1}))
    taught on 1 recording(s), 18.0 s: 3 cycles of 6.80 s (repeatability 0.96)
      the task reference removes 80-90 % of the residual's variance (cross-fitted)
      band 10 Hz, order 1, debounce 2 samples; level 2.10
      thresholds [A]     0.500     0.400
      level 2.10 = the Gumbel law of the cycle scores at 0.1 false alarms per hour
      (the largest cycle score, 1.60, bounds a new cycle's alarm by 0.25 = 1/(cycles+1)
      without a law: at most 132 per hour of the task; teach more cycles to lower it)
    """
    explained = np.asarray(summary["explained"]) * 100
    band = summary["filter"]
    out = [f"taught on {len(summary['recordings'])} recording(s), "
           f"{sum(summary['seconds']):.1f} s: {summary['n_cycles']} cycles of "
           f"{summary['period_s']:.2f} s (repeatability {summary['repeatability']:.2f})",
           f"  the task reference removes {explained.min():.0f}-{explained.max():.0f} % of "
           "the residual's variance (cross-fitted)",
           f"  band {band['cutoff_hz']:g} Hz, order {band['order']}, debounce "
           f"{band['min_duration']} samples; level {summary['level']:.2f}",
           "  thresholds [A]" + "".join(f"{v:>10.3f}" for v in summary["thresholds_A"]),
           *_level_lines(summary)]
    for entry in summary.get("learning", []):
        rejected = ", ".join(f"{n} {why}" for why, n in entry["rejected"].items()) or "none"
        drift = np.abs(np.asarray(entry["drift_A"])).sum(axis=0)
        out.append(f"  learnt from {entry['recording']}: {entry['accepted']} of "
                   f"{entry['cycles']} cycle(s) ({entry['pending']} waiting for the next; "
                   f"rejected: {rejected}); drift now <= {drift.max():.3f} A on a joint "
                   f"(bound: half its threshold)")
    for cycle in summary["deviant_cycles"]:
        out.append(f"  warning: cycle {cycle['index'] + 1} ({cycle['start_s']:.1f}-"
                   f"{cycle['end_s']:.1f} s) is unlike the others (score "
                   f"{cycle['score']:.1f}) and sets the level alone: teach without it")
    return "\n".join(out)
