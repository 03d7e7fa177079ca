"""The per-sample loop of a live (or offline) collision monitor: :class:`MonitorSession`."""

import math
import os
import shlex
import subprocess
import time
import warnings

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

    Attributes
    ----------
    monitor : StreamingMonitor
    state : str
        ``"monitoring"``, ``"blind"`` or ``"recovering"``.
    events : list of dict
        Alarm events (``recording``, ``start_s``, ``end_s``, ``joints``
        (1-based), ``peak_A``, ``delay_s``; ``bands`` with several bands).
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
                 band_labels=None, stall_timeout=None, signal_check=None):
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
        self.series = {"t": [], "stamp": [], "signal": [], "regime": [], "alarms": []}
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
        elif self.open is None:
            self.cross_start = None
        if self.task is not None:
            self._count_taught(rel)
        if mon.alarms.any():
            self._alarm(rel, [b for b, band in enumerate(self.bands) if band.alarms.any()])
        elif self.open is not None and not mon.event:  # a taught event holds (EventHold)
            self._close()
        if self.keep_series:
            s = self.series
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

    def _alarm(self, rel, firing):
        """A tick where the bands ``firing`` (indices) alarm: open or extend the event."""
        alarms = self.monitor.alarms
        taught = self.task is not None and self.monitor.taught
        if taught:
            peak = float(np.abs(self.monitor.task_signal[alarms]).max())
        else:
            peak = max(float(np.abs(self.bands[b].signal[self.bands[b].alarms]).max())
                       for b in firing)
        if self.open is None:
            self.open = {"recording": self.name, "start_s": rel, "end_s": rel,
                         "joints": set(), "peak_A": peak,
                         "delay_s": rel - (rel if self.cross_start is None
                                           else self.cross_start)}
            if self.multiband:
                self.open["bands"] = set()
            if self.task is not None:
                self.open["taught"] = taught
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

    def _close(self):
        event = self.open
        event["joints"] = sorted(event["joints"])
        if self.multiband:
            event["bands"] = sorted(event["bands"])
        self.events.append(event)
        self.open, self.cross_start = None, None

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
        return summary

    # ------------------------------------------------------------ sources
    def run_recording(self, recording, name, speed=None, duration=None):
        """Monitor one recording: offline (``speed=None``) or paced like a live stream.

        Parameters
        ----------
        recording : Recording
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
        if recording.n_joints != self.monitor.n_joints:
            raise ValueError(f"{recording.name}: {recording.n_joints} joints but the detector "
                             f"has {self.monitor.n_joints}")
        self.start(name)
        self.units = recording.units
        if speed is None:
            for t, fields in recording_samples(recording):
                self.tick(t, fields)
        else:
            for received, t, fields in paced(recording_samples(recording), speed, duration):
                self.tick(t, fields, received)
        return self.finish()
