"""Alarm events described: where each began and ended, the link hit, the force.

The table a monitor prints after a run (``gpcd monitor``'s rows, its JSON):
one entry per alarm event -- a run of samples in which some joint fired,
runs closer than ``merge_gap`` joined -- with the isolated link
(:func:`~sklearn_gpcd.contact.isolate_contact` on the monitoring signal over
the event) and, given the configuration and the residual torques, the force
at the link's frame or a given point
(:func:`~sklearn_gpcd.contact.estimate_force`) at the event's sample of
largest whitened residual torque.
"""

import numpy as np

from ..features.masks import contiguous_segments
from .force import estimate_force
from .isolation import isolate_contact

__all__ = ["describe_alarms"]


def describe_alarms(alarms, signal, thresholds, *, time=None, merge_gap=0.0, robot=None, q=None,
                    torque=None, torque_std=None, points=None):
    """One row per alarm event: start, stop, link hit, confidence and force.

    Parameters
    ----------
    alarms : array-like of bool, shape (n_samples, n_joints) or (n_samples,)
        Which joints fired (e.g. a detector's ``monitoring_signal(X).alarms``).
    signal : array-like of shape (n_samples, n_joints)
        The monitoring signal the alarms come from.
    thresholds : array-like of shape (n_joints,) or (n_samples, n_joints)
        Its thresholds, per sample when they change with the regime (e.g.
        ``detector.thresholds_[monitoring.regime]``).
    time : array-like of shape (n_samples,), default=None
        Time stamps [s]; None numbers the samples.
    merge_gap : float, default=0.0
        Alarm runs separated by at most this long (in the units of ``time``)
        form one event.
    robot : str, path or Robot, default=None
        With ``q`` and ``torque``: estimate the force of each event.
    q : array-like of shape (n_samples, n_joints), default=None
        Joint positions [rad].
    torque : array-like of shape (n_samples, n_joints), default=None
        Residual (external) joint torques [Nm], e.g. the momentum observer's
        :math:`r`, or a residual current times the torque constants.
    torque_std : array-like of shape (n_joints,) or (n_samples, n_joints), default=None
        Their standard deviations [Nm] (see
        :func:`~sklearn_gpcd.contact.estimate_force`).
    points : dict of int -> array-like of shape (3,), default=None
        Contact point per 1-based link (in its joint frame); a link not in
        it takes its frame (:func:`~sklearn_gpcd.contact.contact_point`).

    Returns
    -------
    events : list of dict
        ``start`` and ``stop`` (sample indices, half-open), ``start_s`` and
        ``stop_s`` (the times of the first and last alarm samples),
        ``joints_fired`` (1-based), ``link`` (1-based), ``group``,
        ``confidence``, ``significance`` (peak over threshold per joint),
        and with ``robot``: ``force_N``, ``force_std_N``, ``force_rank``,
        ``force_condition``, ``force_well_conditioned`` and
        ``force_sample`` (index of the sample estimated).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.contact import describe_alarms
    >>> signal = np.zeros((10, 6))
    >>> signal[3:6, :3] = [2.0, 3.0, 1.5]          # joints 1-3 above their threshold 1
    >>> events = describe_alarms(np.abs(signal) > 1.0, signal, np.ones(6),
    ...                          time=np.arange(10) * 0.01)
    >>> [(e["start"], e["stop"], e["link"], e["group"]) for e in events]
    [(3, 6, 3, 'link 3')]
    """
    signal = np.atleast_2d(np.asarray(signal, dtype=float))
    n_samples, n_joints = signal.shape
    alarms = np.asarray(alarms, dtype=bool)
    if alarms.shape[0] != n_samples:
        raise ValueError(f"alarms has {alarms.shape[0]} rows, signal {n_samples}")
    fired = alarms.reshape(n_samples, -1)
    stamps = np.arange(n_samples, dtype=float) if time is None else np.asarray(time, float)
    if stamps.shape != (n_samples,):
        raise ValueError(f"time must have shape ({n_samples},), got {stamps.shape}")
    thresholds = np.broadcast_to(np.asarray(thresholds, dtype=float), signal.shape)
    segments = contiguous_segments(fired.any(axis=1))
    merged, gap = [], float(merge_gap)
    for start, stop in segments:
        if merged and stamps[start] - stamps[merged[-1][1] - 1] <= gap:
            merged[-1] = (merged[-1][0], stop)
        else:
            merged.append((start, stop))
    estimate = robot is not None and q is not None and torque is not None
    if estimate:
        q = np.asarray(q, dtype=float)
        torque = np.asarray(torque, dtype=float)
        std = np.ones_like(torque) if torque_std is None else np.broadcast_to(
            np.asarray(torque_std, dtype=float), torque.shape)
    events = []
    for start, stop in merged:
        out = isolate_contact(signal[start:stop], thresholds[start:stop])
        event = {
            "start": int(start), "stop": int(stop),
            "start_s": float(stamps[start]), "stop_s": float(stamps[stop - 1]),
            "joints_fired": [int(j) + 1 for j in np.flatnonzero(fired[start:stop].any(axis=0))],
            "link": out.link, "group": out.group, "confidence": out.confidence,
            "significance": out.significance.tolist(),
        }
        if estimate:
            rows = np.arange(start, stop)
            k = int(rows[np.argmax(np.linalg.norm(torque[rows] / std[rows], axis=1))])
            point = None if points is None else points.get(out.link)
            force = estimate_force(robot, q[k], torque[k], link=out.link, point=point,
                                   torque_std=std[k])
            event.update(force_N=force.magnitude, force_std_N=force.magnitude_std,
                         force_rank=force.rank, force_condition=force.condition,
                         force_well_conditioned=force.well_conditioned, force_sample=k)
        events.append(event)
    return events
