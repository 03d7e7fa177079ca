"""The per-sample loop of a live (or offline) collision monitor: :class:`MonitorSession`."""

import math
import os
import shlex
import subprocess
import time
import warnings
from itertools import chain

import numpy as np

from ..workflow.calibration import band_label, band_settings
from .faults import MAX_FAULT_RECORDS, MONITORING, _FaultStates, stall_bound
from .report import _LogHistogram, _SessionReport
from .rtde import _RTDERunning
from .signals import LiveSignalCheck

#: Live signal findings kept for the report (the first ones; a line per kind and column).
MAX_SIGNAL_FINDINGS = 100


#: Untaught motion [s] after which a stretch is announced and counted.
UNTAUGHT_NOTICE_S = 0.25
#: Rate [Hz] of the "protected at <= X N" figure while the arm moves.
PROTECTION_RATE = 10.0


class HookWarning(UserWarning):
    """The ``--hook`` command could not be started, or exited with an error.

    Monitoring goes on; the report counts the failures (``hook_failures``).

    Examples
    --------
    >>> from sklearn_gpcd.monitoring import HookWarning
    >>> issubclass(HookWarning, UserWarning)
    True
    """


def recording_samples(recording):
    """Raw samples of a recording as ``(time, fields)`` for :meth:`MonitorSession.tick`.

    Parameters
    ----------
    recording : Recording

    Yields
    ------
    time : float
    fields : dict
        ``q``, ``qd``, ``current`` and the controller signals the recording
        has, one row each.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> rec = Recording(time=[0.0, 0.1], q=np.zeros((2, 1)), qd=np.zeros((2, 1)),
    ...                 current=np.ones((2, 1)))
    >>> [(t, sorted(f)) for t, f in recording_samples(rec)]
    [(0.0, ['current', 'q', 'qd']), (0.1, ['current', 'q', 'qd'])]
    """
    names = ("q", "qd", "current", "target_current", "target_q", "target_qd")
    columns = {n: getattr(recording, n) for n in names if getattr(recording, n) is not None}
    for k in range(recording.n_samples):
        yield float(recording.time[k]), {n: v[k] for n, v in columns.items()}


class _Protection:
    """``protected_force`` at the flange while the arm moves, every
    1/PROTECTION_RATE s: the thresholds that decided the tick, in Nm through the
    torque constants; percentiles in fixed memory, per recording."""

    def __init__(self, robot, sample_time):
        self.robot = robot
        self.torque_constants = np.asarray(robot.torque_constants, dtype=float)
        self.every = max(1, int(round(1.0 / (PROTECTION_RATE * sample_time))))
        self.start()

    def start(self):
        self.n, self.taught, self.untaught = 0, _LogHistogram(), _LogHistogram()
        self.never = 0  # moving samples where some force is never seen (X = inf)
        self.last = math.nan

    def add(self, monitor, q, units):
        """One tick; returns the last protected force [N] (NaN at rest)."""
        self.n += 1
        if monitor.regime != 0:
            self.last = math.nan
            return self.last
        if self.n % self.every:
            return self.last
        # deferred: the contact part loads pinocchio (gpcd starts without it)
        from ..contact import protected_force

        kt = 1.0 if units != "A" else self.torque_constants
        self.last = protected_force(self.robot, q, monitor.applied_thresholds * kt)
        if not math.isfinite(self.last):
            self.never += 1
        else:
            (self.taught if monitor.taught else self.untaught).add(self.last)
        return self.last

    def summary(self):
        """``protected_N``: median and 90th percentile [N], taught and untaught motion."""
        out = {}
        for name, hist in (("taught", self.taught), ("untaught", self.untaught)):
            if hist.n:
                out[name] = {"median": round(hist.percentile(50), 1),
                             "p90": round(hist.percentile(90), 1), "samples": hist.n}
        out["never_protected_samples"] = self.never
        return out


class _ContactPeaks:
    """Where and how hard, accumulated over an open event: each joint's peak
    ``|m|`` and peak ``|m| / threshold``, and the sample of the largest ratio
    (its ``q``, signal and thresholds) for the force."""

    def __init__(self, n_joints):
        self.peak = np.zeros(n_joints)
        self.rho = np.zeros(n_joints)
        self.best, self.sample = -1.0, None

    def add(self, signal, thresholds, q):
        ratio = np.abs(signal) / thresholds
        np.maximum(self.peak, np.abs(signal), out=self.peak)
        np.maximum(self.rho, ratio, out=self.rho)
        norm = float(np.sum(ratio * ratio))
        if norm > self.best:
            self.best = norm
            self.sample = (np.array(q, dtype=float), np.array(signal, dtype=float),
                           np.array(thresholds, dtype=float))

    def describe(self, robot, units):
        """The event's contact fields (see :class:`MonitorSession`'s ``events``)."""
        # deferred: the contact part loads pinocchio (gpcd starts without it)
        from ..contact import estimate_force, isolate_contact

        if self.sample is None:
            return {"link": None, "force_N": "no model"}
        found = isolate_contact(self.rho[None, :], np.ones_like(self.rho))
        out = {"peak_per_joint_A": self.peak.round(6).tolist(), "link": found.link,
               "link_group": found.group, "link_confidence": round(found.confidence, 4)}
        kt = None if robot is None else getattr(robot, "torque_constants", None)
        if robot is None or (units == "A" and kt is None):
            return {**out, "force_N": "no model"}
        kt = np.ones_like(self.rho) if units != "A" else np.asarray(kt, dtype=float)
        q, signal, thresholds = self.sample
        force = estimate_force(robot, q, kt * signal, link=found.link,
                               torque_std=kt * thresholds)
        seen = int(force.rank) > 0  # rank 0: no joint up to the link sees the point move
        return {**out, "force_N": round(float(force.magnitude), 3) if seen else None,
                "force_rank": int(force.rank),
                "force_well_conditioned": bool(force.well_conditioned)}


def paced(samples, speed, duration=None):
    """Yield ``(received, time, fields)`` at the samples' time stamps / ``speed``.

    Parameters
    ----------
    samples : iterable of (float, dict)
        E.g. :func:`recording_samples`.
    speed : float
        Time-stamp speed factor (1: real time, 0: as fast as possible).
    duration : float, default=None
        Stop after this many seconds of stream time.

    Yields
    ------
    received : float
        :func:`time.perf_counter` when the sample was handed out.
    time : float
    fields : dict

    Examples
    --------
    >>> stream = [(0.0, {}), (0.5, {}), (1.5, {})]
    >>> [t for _, t, _ in paced(stream, speed=0, duration=1.0)]
    [0.0, 0.5]
    """
    start, t0 = time.perf_counter(), None
    for t, fields in samples:
        if t0 is None and math.isfinite(t):
            t0 = t
        if duration is not None and t0 is not None and t - t0 > duration:  # stream time
            return
        if (speed > 0 and t0 is not None and math.isfinite(t)
                and (wait := start + (t - t0) / speed - time.perf_counter()) > 0):
            time.sleep(wait)
        yield time.perf_counter(), t, fields


class MonitorSession(_FaultStates, _SessionReport, _RTDERunning):
    """The fail-safe per-sample loop of a live (or offline) collision monitor.

    Wraps a :class:`~sklearn_gpcd.detection.StreamingMonitor` (one band per
    alarm rule of the detector) fed with raw samples (``update_raw``), tracks
    alarm events,
    and on a live stream (``tick(..., received=...)``) watches for the
    faults that leave it blind (see the module docstring for the states):

    - no valid decision for longer than ``stall_timeout`` (a stall, a lost
      link, a stream of rejected samples, frozen time stamps);
    - a time stamp that jumps back or forward by more than ``stall_timeout``
      (a controller clock jump, or samples lost).

    Each is one ``FAULT`` line (and the hook with ``GPCD_FAULT``) at once,
    then the monitor is reset before it trusts data again. Offline
    recordings (``received=None``) are monitored as before: rejected
    samples are counted, nothing else.

    Parameters
    ----------
    detector : CollisionDetector
        Fitted (one or several alarm rules).
    features : CausalFeatures
        Fitted causal features (the detector's inputs from raw samples).
    hook : str, default=None
        Command run (not waited for) at each alarm onset (environment
        ``GPCD_ALARM_TIME``, ``GPCD_ALARM_JOINTS``, ``GPCD_ALARM_BANDS``) and
        at each fault (``GPCD_FAULT``, ``GPCD_FAULT_TIME``). One that cannot
        start or fails is reported (:class:`HookWarning`); monitoring goes on.
    keep_series : bool, default=False
        Keep every valid tick's time from the start (``t``), time stamp,
        signal, regime and alarms in ``series`` (for figures of recordings;
        grows with the stream).
    echo : bool, default=False
        Print ``ALARM`` lines as they happen (``FAULT``, ``RECOVERING`` and
        ``MONITORING`` lines are always printed).
    band_labels : list of str, default=None
        Names of the bands in the ``ALARM`` lines (default: each band's filter
        and debounce, :func:`~sklearn_gpcd.workflow.band_label`).
    stall_timeout : float, default=None
        Stall bound [s]; None: :func:`stall_bound` of the detector's sample
        time.
    signal_check : SignalCheck, default=None
        Live streams: judge the signals every 10 s of stream time
        (:class:`~sklearn_gpcd.monitoring.signals.LiveSignalCheck`), a
        ``SIGNALS`` line per implausible column, all in the report's
        ``signal_findings``. Files are checked before the run instead
        (:func:`sklearn_gpcd.workflow.check_signals`).
    robot : Robot, default=None
        The robot model: each event's contact force at its link
        (:func:`~sklearn_gpcd.contact.estimate_force`); None: ``"no model"``.

    Attributes
    ----------
    monitor : StreamingMonitor
    state : str
        ``"monitoring"``, ``"blind"`` or ``"recovering"``.
    events : list of dict
        Contact events, one per contact (an event ends when the signal has
        stayed below the release level for the hold time, or where a new
        contact begins on joints that had let go,
        :class:`~sklearn_gpcd.detection.EventHold`): ``recording``,
        ``start_s`` (onset), ``end_s`` (last alarm), ``released_s`` (the
        event closed), ``joints`` (that fired, 1-based), ``peak_A`` and
        ``peak_per_joint_A`` (largest ``|m|``), ``delay_s``, ``link``,
        ``link_group`` and ``link_confidence``
        (:func:`~sklearn_gpcd.contact.isolate_contact` on each joint's peak
        over its threshold), ``force_N`` (``"no model"`` without a robot
        model, None when no joint sees the link's frame move), ``force_rank``
        and ``force_well_conditioned``
        (:func:`~sklearn_gpcd.contact.estimate_force` at the link's frame, at
        the sample of largest peak over threshold); ``bands`` with several
        bands.
    faults : list of dict
        Blind periods (``recording``, ``start_s``, ``kind``, ``reason``,
        ``last_stamp``: the controller time stamp of the last valid sample
        before it, ``blind_s``, ``samples_lost``, ``recovered_s`` and
        ``recovered_stamp``: the time and time stamp of the first valid
        sample after it, None while blind); the first ``MAX_FAULT_RECORDS``.
    n_blind : int
        Times the session went blind.
    recordings : list of dict
        One summary per :meth:`start` (``name``, ``n_samples``,
        ``n_sensor_faults``, ``n_events``).
    warmup_s : float
        Length of the ``recovering`` state [s].
    end_reason : str or None
        How the stream ended (set by :meth:`run_rtde` / :meth:`end`).
    exit_status : int
        0, or ``FAULT_EXIT_STATUS`` (3) when the session was blind at some
        time or the stream ended abnormally.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.linear_model import LinearRegression
    >>> from sklearn_gpcd.datasets import simulate_d1
    >>> from sklearn_gpcd.detection import AlarmRule, CollisionDetector, stack_currents
    >>> from sklearn_gpcd.features import CausalFeatures
    >>> from sklearn_gpcd.monitoring import MonitorSession, recording_samples
    >>> rec = simulate_d1("ur10e", n_targets=2, sample_rate=500.0, random_state=0)
    >>> features = CausalFeatures().fit([rec])
    >>> X = stack_currents(features.transform(rec), rec.current)
    >>> detector = CollisionDetector(LinearRegression(), n_joints=6, sample_time=0.002,
    ...                              rules=AlarmRule(filter_cutoff=2.0, min_duration=5)).fit(X)
    >>> session = MonitorSession(detector, features)
    >>> session.start("live")
    >>> for k, (t, fields) in enumerate(recording_samples(rec)):
    ...     if 1000 <= k < 1100:                 # 0.2 s of NaN currents
    ...         fields = dict(fields, current=fields["current"] * np.nan)
    ...     _ = session.tick(t, fields, received=t)  # doctest: +ELLIPSIS
    FAULT live t=2.018 s: 10 rejected samples in a row (missing or non-finite value ...
    RECOVERING live t=2.200 s: valid samples again after 0.182 s blind; monitor ...
    MONITORING live t=2.290 s: warm-up over
    >>> session.n_blind, session.state, session.exit_status
    (1, 'monitoring', 3)
    """

    def __init__(self, detector, features, *, hook=None, keep_series=False, echo=False,
                 band_labels=None, stall_timeout=None, signal_check=None, robot=None):
        # deferred: gpcd starts without scikit-learn (test_architecture.py)
        from ..detection import StreamingMonitor

        self.monitor = StreamingMonitor(detector, features=features)
        #: the taught task (gpcd teach), or None
        self.task = self.monitor.task
        detector = self.monitor.detector
        #: one BandState per alarm rule
        self.bands = self.monitor.bands
        self.multiband = len(self.bands) > 1
        self.band_labels = (list(band_labels) if band_labels is not None else
                            [band_label(band_settings(band.rule)) for band in self.bands])
        self.signals = tuple(features.signals_)
        self.units = "A"  # of the currents (the last recording run: "Nm" for torques)
        self.thresholds = [band.thresholds for band in self.bands]
        self.regime_names = tuple(self.bands[0].rule.regime_names_)
        self.sample_time = float(detector.sample_time_)
        self.stall_timeout = (stall_bound(self.sample_time) if stall_timeout is None
                              else float(stall_timeout))
        self.warmup_s = max(self._warmup(band.rule) for band in self.bands)
        self.hook, self.keep_series, self.echo = hook, keep_series, echo
        self.events, self.recordings, self.faults = [], [], []
        self.n_blind, self.hook_failures = 0, 0
        self.end_reason, self.abnormal_end = None, False
        self._hooks = []
        self._latency = _LogHistogram()
        self._n_ticks, self._behind_max = 0, -math.inf
        self._first_decided = self._first_rel = None
        self._steps, self._step, self._dropped = [], None, 0
        self._stat_stamp = None
        self.state = MONITORING
        self.name = None
        self.live_signals = (None if signal_check is None
                             else LiveSignalCheck(signal_check, self.sample_time))
        self.signal_findings = []
        self.robot = robot
        kt = None if robot is None else getattr(robot, "torque_constants", None)
        self.protection = (None if kt is None or getattr(robot, "model", None) is None
                           else _Protection(robot, self.sample_time))

    def _warmup(self, rule):
        """Debounce window plus one low-pass time constant (and the settle time) [s]."""
        seconds = rule.min_duration * self.sample_time
        if rule.filter_cutoff is not None:
            seconds += 1.0 / (2 * math.pi * rule.filter_cutoff)
        if rule.regimes is not None:
            seconds = max(seconds, float(rule.regimes.settle_time))
        return seconds

    # ------------------------------------------------------------ the stream
    def start(self, name):
        """Begin a new recording or stream ``name`` (the monitor restarts)."""
        self.monitor.reset()
        self.name, self.t0, self.cross_start, self.open = name, None, None, None
        self.n_samples = self.n_faults = 0
        self.series = {"t": [], "stamp": [], "signal": [], "regime": [], "alarms": [],
                       "protected": []}
        self.recordings.append({"name": name})
        self.state, self._warm = MONITORING, 0
        self._last_stamp = self._last_rel = None
        self._prev_stamp = self._prev_received = self._valid_stamp = None
        self._last_ok = None  # received of the last valid tick (live)
        self._last_received = None
        self._run = 0  # rejected samples in a row
        if self.live_signals is not None:
            self.live_signals.reset()
        self._lost = 0  # samples lost in the current blind period
        self._taught_n = self._untaught_n = self._untaught_run = 0
        if self.protection is not None:
            self.protection.start()
        self._untaught_stretches = []  # [start_s, end_s] of untaught motion

    def tick(self, t, fields, received=None):
        """One raw sample (``fields``: q, qd, current and the controller signals).

        Parameters
        ----------
        t : float
            Controller time stamp [s].
        fields : dict
            ``q``, ``qd``, ``current`` and the signals the features need.
        received : float, default=None
            :func:`time.perf_counter` when the sample arrived (a live
            stream: fault detection and latency statistics); None for an
            offline recording.

        Returns
        -------
        status : MonitorStatus or str
            The monitor's status, or ``"sensor_fault"`` for a sample the
            session rejected before the monitor (a time stamp that does not
            advance).
        """
        live = received is not None
        self.n_samples += 1
        if self.t0 is None and math.isfinite(t):
            self.t0 = t
        if live:
            self._last_received = received
            if self._last_ok is None:
                self._last_ok = received
            stale = self._check_stamp(t, received)
            if stale:
                return self._rejected(stale, received)
        mon = self.monitor
        status = mon.update_raw(t, fields["q"], fields["qd"], fields["current"],
                                **{s: fields.get(s) for s in self.signals})
        if live:
            decided = time.perf_counter()
            self._statistics(t, received, decided)
        if status == "sensor_fault":
            return self._rejected(self._fault_reason(), received) if live else \
                self._count_fault(status)
        self._run = 0
        if math.isfinite(t):
            self._last_stamp = t
        rel = self._rel(t)
        if live:
            self._last_ok = received
            self._valid_tick(rel, t)
            self._valid_stamp = t
        if live and self.live_signals is not None:
            for finding in self.live_signals.add(t, fields["q"], fields["qd"],
                                                 fields["current"], mon.predicted):
                self._signal_finding(rel, finding)
        if any((np.abs(band.signal) > thresholds[band.regime]).any()
               for band, thresholds in zip(self.bands, self.thresholds)):
            if self.cross_start is None:
                self.cross_start = rel
        else:
            self.cross_start = None
        if self.task is not None:
            self._count_taught(rel)
        if mon.alarms.any():
            if self.open is not None and mon.event_onset:  # a new contact (EventHold)
                self._append_event(rel)
            self._alarm(rel, [b for b, band in enumerate(self.bands) if band.alarms.any()])
        elif self.open is not None and not mon.event:  # an event holds (EventHold)
            self._close(rel)
        if self.open is not None:
            self._contact.add(*self._contact_signal(), fields["q"])
        protected = (math.nan if self.protection is None else
                     self.protection.add(mon, fields["q"], self.units))
        if self.keep_series:
            s = self.series
            s["protected"].append(protected)
            s["t"].append(rel)
            s["stamp"].append(t)
            s["signal"].append([band.signal.copy() for band in self.bands])
            s["regime"].append([band.regime for band in self.bands])
            s["alarms"].append(mon.alarms.copy())
        return status

    def _count_taught(self, rel):
        """Taught and untaught-motion time; one ``UNTAUGHT`` line (echo) per
        stretch of untaught motion longer than ``UNTAUGHT_NOTICE_S``."""
        mon = self.monitor
        if mon.taught:
            self._taught_n += 1
            self._untaught_run = 0
            return
        if mon.regime != 0:  # at rest or settling: the regimes' business, not untaught
            self._untaught_run = 0
            return
        self._untaught_n += 1
        self._untaught_run += 1
        if self._untaught_run == 1:
            self._untaught_stretches.append([rel, rel])
        self._untaught_stretches[-1][1] = rel
        if self.echo and self._untaught_run * self.sample_time >= UNTAUGHT_NOTICE_S > (
                self._untaught_run - 1) * self.sample_time:
            print(f"UNTAUGHT {self.name} t={self._untaught_stretches[-1][0]:.3f} s: motion "
                  "outside the taught task; the calibrated thresholds apply", flush=True)

    def _signal_finding(self, rel, finding):
        """A live window's implausible signal: one line per kind and column, all in the
        report (at most :data:`MAX_SIGNAL_FINDINGS`)."""
        said = any(f["kind"] == finding.kind and f["columns"] == finding.columns
                   for f in self.signal_findings)
        if len(self.signal_findings) < MAX_SIGNAL_FINDINGS:
            self.signal_findings.append({"recording": self.name, "t_s": round(rel, 3),
                                         **finding._asdict()})
        if self.echo and not said:
            print(f"SIGNALS {self.name} t={rel:.3f} s: {finding.severity}: "
                  f"{finding.sentence}", flush=True)

    def _count_fault(self, status):
        self.n_faults += 1
        return status

    def _fault_reason(self):
        return self.monitor.fault_reason

    def _rel(self, t):
        rel = t - self.t0
        self._last_rel = rel
        return rel

    def _contact_signal(self):
        """This tick's signal [A] and thresholds of the band with the largest ratio
        (the taught task's where it decides)."""
        mon = self.monitor
        ratios = [np.max(np.abs(band.signal) / thresholds[band.regime])
                  for band, thresholds in zip(self.bands, self.thresholds)]
        b = int(np.argmax(ratios))
        signal, thresholds = self.bands[b].signal, self.thresholds[b][self.bands[b].regime]
        if self.task is not None and mon.taught:   # joint by joint (stiction gate)
            joints = mon.taught_joints
            signal = np.where(joints, mon.task_signal, signal)
            thresholds = np.where(joints, self.task.thresholds_, thresholds)
        return signal, thresholds

    def _alarm(self, rel, firing):
        """A tick where the bands ``firing`` (indices) alarm: open or extend the event."""
        alarms = self.monitor.alarms
        by_task = alarms & self.monitor.taught_joints  # joints the taught task decided
        taught = bool(by_task.any())
        peaks = [float(np.abs(self.monitor.task_signal[by_task]).max())] if taught else []
        peaks += [float(np.abs(self.bands[b].signal[self.bands[b].alarms & ~by_task]).max())
                  for b in firing if (self.bands[b].alarms & ~by_task).any()]
        peak = max(peaks, default=0.0)
        if self.open is None:
            self.open = {"recording": self.name, "start_s": rel, "end_s": rel,
                         "joints": set(), "peak_A": peak,
                         "delay_s": rel - (rel if self.cross_start is None
                                           else self.cross_start)}
            if self.multiband:
                self.open["bands"] = set()
            if self.task is not None:
                self.open["taught"] = taught
            self._contact = _ContactPeaks(self.monitor.n_joints)
            self._onset(self.open, alarms, firing)
        self.open["end_s"] = rel
        self.open["joints"].update(int(j) + 1 for j in np.flatnonzero(alarms))
        self.open["peak_A"] = max(self.open["peak_A"], peak)
        if self.multiband:
            self.open["bands"].update(b + 1 for b in firing)

    def _onset(self, event, alarms, firing):
        joints = ",".join(str(int(j) + 1) for j in np.flatnonzero(alarms))
        if self.echo:
            which = "".join(f", band {b + 1} ({self.band_labels[b]})" for b in firing)
            print(f"ALARM {self.name} t={event['start_s']:.3f} s joints {joints}"
                  + (which if self.multiband else ""), flush=True)
        env = {"GPCD_ALARM_TIME": f"{event['start_s']:.6f}", "GPCD_ALARM_JOINTS": joints}
        if self.multiband:
            env["GPCD_ALARM_BANDS"] = ",".join(str(b + 1) for b in firing)
        self._run_hook(env)

    def _run_hook(self, env):
        """Start the hook (not waited for); a failure is a warning, never an exception."""
        if not self.hook:
            return
        self._reap()
        try:
            self._hooks.append(subprocess.Popen(shlex.split(self.hook),
                                                env={**os.environ, **env}))
        except (OSError, ValueError) as exc:
            self.hook_failures += 1
            warnings.warn(f"--hook {self.hook!r} could not start: {exc}; monitoring goes on",
                          HookWarning, stacklevel=2)

    def _reap(self):
        """Collect the hooks that ended; report those that failed."""
        running = []
        for process in self._hooks:
            code = process.poll()
            if code is None:
                running.append(process)
            elif code != 0:
                self.hook_failures += 1
                warnings.warn(f"--hook {self.hook!r} exited with status {code}; monitoring "
                              "goes on", HookWarning, stacklevel=3)
        self._hooks = running

    def _close(self, rel=None):
        """Record the open event, released at ``rel``; the next one starts afresh."""
        self._append_event(rel)
        self.cross_start = None

    def _append_event(self, rel=None):
        """Record the open event, released at ``rel`` (None: the last valid time)."""
        event = self.open
        if rel is None:  # the stream ended or went blind: its last valid time
            rel = event["end_s"] if self._last_rel is None else max(self._last_rel,
                                                                    event["end_s"])
        event["released_s"] = rel
        event["joints"] = sorted(event["joints"])
        event.update(self._contact.describe(self.robot, self.units))
        if self.multiband:
            event["bands"] = sorted(event["bands"])
        self.events.append(event)
        self.open = None

    def finish(self):
        """Close the open event (and the blind period, when the stream ends blind);
        the recording's summary."""
        if self.open is not None:
            self._close()
        self._end_blind(self._last_received)
        summary = self.recordings[-1]
        summary.update(n_samples=self.n_samples, n_sensor_faults=self.n_faults,
                       n_events=sum(e["recording"] == self.name for e in self.events))
        if self.task is not None:
            stretches = [s for s in self._untaught_stretches
                         if s[1] - s[0] + self.sample_time >= UNTAUGHT_NOTICE_S]
            summary.update(taught_s=self._taught_n * self.sample_time,
                           untaught_motion_s=self._untaught_n * self.sample_time,
                           untaught_stretches=stretches[:MAX_FAULT_RECORDS])
        if self.protection is not None:
            summary["protected_N"] = self.protection.summary()
        return summary

    # ------------------------------------------------------------ sources
    def run_recording(self, recording, name, speed=None, duration=None):
        """Monitor one recording: offline (``speed=None``) or paced like a live stream.

        Parameters
        ----------
        recording : Recording or iterable of Recording
            One recording, or its chunks in time order
            (:func:`~sklearn_gpcd.io.iter_recording_chunks`: memory bounded by
            a chunk).
        name : str
        speed : float, default=None
            None: offline, as fast as possible, no live fault handling; a
            number: :func:`paced` at that speed (0: unpaced), live.
        duration : float, default=None
            Stop a paced stream after this many seconds of stream time.

        Returns
        -------
        summary : dict
            What :meth:`finish` returns.

        Raises
        ------
        ValueError
            When the recording has another number of joints than the detector.
        """
        chunks = iter([recording] if hasattr(recording, "n_joints") else recording)
        first = next(chunks)
        if first.n_joints != self.monitor.n_joints:
            raise ValueError(f"{first.name}: {first.n_joints} joints but the detector "
                             f"has {self.monitor.n_joints}")
        self.start(name)
        self.units = first.units
        samples = chain.from_iterable(map(recording_samples, chain([first], chunks)))
        if speed is None:
            for t, fields in samples:
                self.tick(t, fields)
        else:
            for received, t, fields in paced(samples, speed, duration):
                self.tick(t, fields, received)
        return self.finish()
