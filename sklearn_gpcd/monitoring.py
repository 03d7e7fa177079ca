"""Live collision monitoring you can leave running: :class:`MonitorSession`.

The per-sample loop behind ``gpcd monitor`` (recordings, a paced replay, a
live UR controller over RTDE), fail-safe: a monitor that cannot see says so
at once. A session is always in one of three states:

``monitoring``
    Valid samples arrive and every decision is that of the detector (the
    batch ``predict`` on the same rows).
``blind``
    No valid decision for longer than the stall bound ``max(3 control
    periods, 20 ms)``: the link is lost, the stream stalled, every sample is
    rejected (NaN currents, frozen or backward time stamps, malformed or
    unknown packages) or the controller clock jumped. Entering it prints one
    ``FAULT`` line, runs the hook with ``GPCD_FAULT``, ends the open alarm
    event and resets the monitor (:meth:`StreamingMonitor.reset
    <sklearn_gpcd.detection.StreamingMonitor.reset>`), so no decision is
    ever made on state from before the fault. RTDE reconnects with backoff.
``recovering``
    Valid samples again, the monitor restarted from the first of them (a
    ``RECOVERING`` line): its decisions equal the batch detector's on the
    valid rows from there on, but during the warm-up (the debounce window
    and one low-pass time constant, ``warmup_s``) a contact that began
    earlier may be missed. After it, a ``MONITORING`` line.

Statistics (tick latency percentiles, dropped samples, how far decisions
fall behind the stream) live in fixed-size structures, so memory does not
grow with the length of a shift; a report (:meth:`MonitorSession.report`)
is available on every exit path, and :attr:`MonitorSession.exit_status` is
non-zero when the session was ever blind or the stream ended abnormally.
"""

import gc
import math
import os
import shlex
import subprocess
import time
import warnings

from pathlib import Path

import numpy as np

from .workflow.calibration import band_label, band_settings

__all__ = ["BLIND", "MONITORING", "RECOVERING", "HookWarning", "MonitorSession",
           "paced", "recording_samples", "stall_bound"]

#: State of a session whose decisions are those of the detector.
MONITORING = "monitoring"
#: State of a session without a valid decision for longer than the stall bound.
BLIND = "blind"
#: State of a session restarted after a blind period, during its warm-up.
RECOVERING = "recovering"
#: Control periods without a valid decision after which a session is blind.
STALL_PERIODS = 3
#: Shortest stall bound [s] (OS scheduling makes shorter bounds meaningless).
MIN_STALL = 0.02
#: Exit status of a session that was blind at some time or ended abnormally.
FAULT_EXIT_STATUS = 3
#: Fault records kept in full in the report (later ones are only counted).
MAX_FAULT_RECORDS = 1000
#: Line colours of the bands in a multi-band figure (C3, red, shades the events).
BAND_COLORS = ("C0", "C2", "C4", "C1", "C5", "C6", "C8", "C9")


class HookWarning(UserWarning):
    """The ``--hook`` command could not be started, or exited with an error.

    Monitoring goes on; the report counts the failures (``hook_failures``).

    Examples
    --------
    >>> from sklearn_gpcd.monitoring import HookWarning
    >>> issubclass(HookWarning, UserWarning)
    True
    """


def stall_bound(sample_time):
    """Longest time without a valid decision before a session is blind [s].

    ``max(STALL_PERIODS * sample_time, MIN_STALL)``: 3 control periods, or
    20 ms, whichever is larger.

    Parameters
    ----------
    sample_time : float
        Control period [s].

    Returns
    -------
    bound : float

    Examples
    --------
    >>> stall_bound(0.002), stall_bound(0.008), stall_bound(0.1)
    (0.02, 0.024, 0.30000000000000004)
    """
    return max(STALL_PERIODS * float(sample_time), MIN_STALL)


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


class _LogHistogram:
    """Percentiles of positive values in fixed memory: geometric bins (1 % wide)."""

    LOW, HIGH, RATIO = 1e-7, 1e3, 1.01

    def __init__(self):
        self._log_ratio = math.log(self.RATIO)
        n = math.ceil(math.log(self.HIGH / self.LOW) / self._log_ratio) + 2
        self.counts = np.zeros(n, dtype=np.int64)
        self.n, self.max, self.min = 0, -math.inf, math.inf

    def add(self, value):
        if not value > 0:  # 0, negative or NaN: the lowest bin
            index = 0
        else:
            index = int(math.log(value / self.LOW) / self._log_ratio) + 1
            index = min(max(index, 0), self.counts.size - 1)
        self.counts[index] += 1
        self.n += 1
        self.max, self.min = max(self.max, value), min(self.min, value)

    def percentile(self, q):
        """The ``q``-th percentile (the bin's centre, clipped to the values seen)."""
        rank = q / 100.0 * (self.n - 1)
        index = int(np.searchsorted(np.cumsum(self.counts), math.floor(rank) + 1))
        centre = self.LOW * self.RATIO ** (index - 0.5) if index > 0 else 0.0
        return min(max(centre, self.min), self.max)


class MonitorSession:
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
    >>> from sklearn_gpcd.datasets import make_d1
    >>> from sklearn_gpcd.detection import AlarmRule, CollisionDetector, stack_currents
    >>> from sklearn_gpcd.features import CausalFeatures
    >>> from sklearn_gpcd.monitoring import MonitorSession, recording_samples
    >>> rec = make_d1("ur10e", n_targets=2, sample_rate=500.0, random_state=0)
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
                 band_labels=None, stall_timeout=None):
        from .detection import StreamingMonitor

        self.monitor = StreamingMonitor(detector, features=features)
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

    def _warmup(self, rule):
        """Debounce window plus one low-pass time constant (and the settle time) [s]."""
        seconds = rule.min_duration * self.sample_time
        if rule.filter_cutoff is not None:
            seconds += 1.0 / (2 * math.pi * rule.filter_cutoff)
        if rule.regimes is not None:
            seconds = max(seconds, float(rule.regimes.settle_time))
        return seconds

    def events_text(self):
        """The events in words: counts, per band, and one row per event.

        Returns
        -------
        text : str
        """
        n_samples = sum(r["n_samples"] for r in self.recordings)
        n_faults = sum(r["n_sensor_faults"] for r in self.recordings)
        out = [f"{len(self.events)} alarm event(s) in {len(self.recordings)} recording(s), "
               f"{n_samples} samples ({n_faults} sensor faults)"]
        if self.multiband:
            for b, label in enumerate(self.band_labels, start=1):
                n_events = sum(b in e["bands"] for e in self.events)
                out.append(f"  band {b} ({label}) alarmed in {n_events} event(s)")
        if not self.events:
            return "\n".join(out)
        width = max(9, *(len(e["recording"]) for e in self.events))
        columns = [("recording", f"<{width}", lambda e: e["recording"]),
                   ("start [s]", ">9", lambda e: f"{e['start_s']:.3f}"),
                   ("end [s]", ">9", lambda e: f"{e['end_s']:.3f}"),
                   ("joints", "<12", lambda e: ",".join(map(str, e["joints"]))),
                   (f"peak |m| [{self.units}]", ">12", lambda e: f"{e['peak_A']:.3f}"),
                   ("delay [s]", ">9", lambda e: f"{e['delay_s']:.3f}")]
        if self.multiband:
            columns.insert(4, ("bands", "<6", lambda e: ",".join(map(str, e["bands"]))))
        out.append("  ".join(f"{name:{spec}}" for name, spec, _ in columns))
        for e in self.events:
            out.append("  ".join(f"{value(e):{spec}}" for _, spec, value in columns))
        return "\n".join(out)

    def summary_text(self, live=False):
        """:meth:`events_text`, then (``live``) the tick latency and drops, and the
        faults and how the stream ended when the exit status is not 0.

        Parameters
        ----------
        live : bool, default=False
            A live or replayed stream: add :meth:`live_statistics`.

        Returns
        -------
        text : str
        """
        out = [self.events_text()]
        stats = self.live_statistics() if live else None
        if stats is not None:
            out.append(f"  {stats['n_ticks']} ticks; latency receive -> decision p50 "
                       f"{stats['latency_ms_p50']:.3f} ms, p99 {stats['latency_ms_p99']:.3f} "
                       f"ms, max {stats['latency_ms_max']:.3f} ms; dropped samples "
                       f"{stats['dropped_samples']}; decisions at most "
                       f"{stats['behind_stream_ms_max']:.1f} ms behind the stream's clock")
        if self.exit_status:
            blind = sum(f["blind_s"] or 0.0 for f in self.faults)
            out.append(f"  {self.n_blind} fault(s): blind {blind:.3f} s in total"
                       + (f"; the stream ended abnormally: {self.end_reason}"
                          if self.abnormal_end else "")
                       + f" (exit status {self.exit_status})")
        return "\n".join(out)

    def plot(self, key, folder):
        """One figure of recording ``key`` (``keep_series``): one axis per joint,
        alarm events shaded, alarms marked.

        One band: the monitoring signal and its per-regime thresholds [A].
        Several bands: each band's ``|m|`` over its threshold (per regime), so
        that every band crosses at 1.

        Parameters
        ----------
        key : str
            The recording (its name in :meth:`start`).
        folder : path-like
            Where to write ``<key stem>.png``.

        Returns
        -------
        path : Path or None
            None (with a warning) when matplotlib is not installed.
        """
        try:
            import matplotlib

            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
        except ImportError:
            warnings.warn("matplotlib is not installed; no figure: pip install matplotlib "
                          "(or 'sklearn-gpcd[plot]'), or drop --plot", UserWarning,
                          stacklevel=2)
            return None
        s = self.series
        t = np.asarray(s["t"])
        signal, regime = np.asarray(s["signal"]), np.asarray(s["regime"], dtype=int)
        alarms = np.asarray(s["alarms"], dtype=bool)
        n = signal.shape[2] if signal.ndim == 3 else 0
        fig, axes = plt.subplots(max(n, 1), 1, figsize=(9, 1.6 * max(n, 1) + 0.8),
                                 sharex=True, squeeze=False)
        events = [e for e in self.events if e["recording"] == key]
        draw = self._draw_ratios if self.multiband else self._draw_signal
        for j in range(n):
            ax = axes[j, 0]
            for k, e in enumerate(events):
                ax.axvspan(e["start_s"], e["end_s"], color="C3", alpha=0.15,
                           label="alarm event" if k == 0 else None)
            ax.set_ylabel(draw(ax, t, signal[:, :, j], regime, j), fontsize=8)
            if alarms[:, j].any():
                ax.plot(t[alarms[:, j]], np.zeros(alarms[:, j].sum()), "|", color="k", ms=8,
                        label="alarm")
            ax.tick_params(labelsize=7)
            ax.legend(fontsize=6, loc="upper right")
        axes[-1, 0].set_xlabel("t [s]")
        fig.suptitle(f"{key}: " + ("each band's |m| over its threshold (per regime), alarms"
                                   if self.multiband else
                                   "causal monitoring signal, per-regime thresholds, alarms"),
                     fontsize=9)
        fig.tight_layout()
        path = Path(folder) / f"{Path(key).stem}.png"
        fig.savefig(path, dpi=80)
        plt.close(fig)
        return path

    def _draw_signal(self, ax, t, signal, regime, j):
        """One band: joint ``j``'s signal and its thresholds ``+-`` (per regime); the y label."""
        ax.plot(t, signal[:, 0], lw=0.7, color="C0", label="monitoring signal m")
        band = self.thresholds[0][regime[:, 0], j]
        ax.plot(t, band, lw=0.7, color="C1",
                label="threshold (" + "/".join(self.regime_names) + ")")
        ax.plot(t, -band, lw=0.7, color="C1")
        return f"joint {j + 1} [{self.units}]"

    def _draw_ratios(self, ax, t, signal, regime, j):
        """Several bands: joint ``j``'s ``|m| / threshold`` per band, and 1; the y label."""
        for b, label in enumerate(self.band_labels):
            ratio = np.abs(signal[:, b]) / self.thresholds[b][regime[:, b], j]
            ax.plot(t, ratio, lw=0.7, color=BAND_COLORS[b % len(BAND_COLORS)],
                    label=f"band {b + 1} ({label})")
        ax.axhline(1.0, lw=0.7, ls="--", color="k", label="threshold")
        return f"joint {j + 1}\n|m| / threshold"

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
        self._lost = 0  # samples lost in the current blind period

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
        if any((np.abs(band.signal) > thresholds[band.regime]).any()
               for band, thresholds in zip(self.bands, self.thresholds)):
            if self.cross_start is None:
                self.cross_start = rel
        elif self.open is None:
            self.cross_start = None
        if mon.alarms.any():
            self._alarm(rel, [b for b, band in enumerate(self.bands) if band.alarms.any()])
        elif self.open is not None:
            self._close()
        if self.keep_series:
            s = self.series
            s["t"].append(rel)
            s["stamp"].append(t)
            s["signal"].append([band.signal.copy() for band in self.bands])
            s["regime"].append([band.regime for band in self.bands])
            s["alarms"].append(mon.alarms.copy())
        return status

    def _count_fault(self, status):
        self.n_faults += 1
        return status

    def _fault_reason(self):
        return self.monitor.fault_reason

    def _rel(self, t):
        rel = t - self.t0
        self._last_rel = rel
        return rel

    def _check_stamp(self, t, received):
        """Why a live sample's time stamp is stale (None if it may go to the monitor).

        A jump back or forward by more than the stall bound from the
        previous sample's stamp is a fault of its own (the monitor restarts
        on the new clock at once); a stamp that is not after the last valid
        one (frozen, repeated, out of order) is rejected here, so that no
        monitor reset lets it through.
        """
        previous, before = self._prev_stamp, self._prev_received
        if not math.isfinite(t):
            return None  # the monitor rejects it
        self._prev_stamp, self._prev_received = t, received
        if previous is not None and abs(t - previous) > self.stall_timeout:
            step = t - previous
            wall = received - before
            if step < 0 or wall < step - self.stall_timeout:
                self.fault(f"controller clock jumped {step:+.3f} s", kind="clock_jump",
                           received=received)
                last_rel = self._last_rel if self._last_rel is not None else 0.0
                self.t0 = t - (last_rel + max(wall, self.sample_time))  # rel goes on
                self._stat_stamp = None  # a new clock: no samples dropped
            else:
                lost = round(step / self.sample_time) - 1
                self.fault(f"time stamps jump {step:+.3f} s: about {lost} samples lost",
                           kind="gap", received=received)
            self._last_stamp = None  # the monitor restarts on this stamp
            return None
        last = self._last_stamp
        if last is not None and t <= last:
            return f"time stamp {t!r} does not advance (last valid {last!r})"
        return None

    def _rejected(self, reason, received):
        """A live sample that gave no decision; blind when they last too long."""
        self.n_faults += 1
        self._run += 1
        if self.state == BLIND:
            self._lost += 1
            return "sensor_fault"
        waited = received - self._last_ok if self._last_ok is not None else 0.0
        bound = self.stall_timeout - 1e-9  # the bound itself included
        if waited >= bound or self._run * self.sample_time >= bound:
            run = self._run
            self.fault(f"{run} rejected samples in a row ({reason})", kind="rejected",
                       received=received)
            self._lost = run
        return "sensor_fault"

    def _valid_tick(self, rel, t):
        """State after a valid live tick: blind -> recovering -> monitoring."""
        if self.state == BLIND:
            record = self._open_fault
            blind = (self._last_ok - self._blind_since) if self._last_ok is not None else 0.0
            if record is not None:
                record.update(blind_s=blind, samples_lost=self._lost, recovered_s=rel,
                              recovered_stamp=t)
            self.state, self._warm = RECOVERING, 0
            print(f"RECOVERING {self.name} t={rel:.3f} s: valid samples again after "
                  f"{blind:.3f} s blind; monitor restarted, full sensitivity after "
                  f"{self.warmup_s:.3f} s", flush=True)
        elif self.state == RECOVERING:
            self._warm += 1
            if self._warm * self.sample_time >= self.warmup_s:
                self.state = MONITORING
                print(f"MONITORING {self.name} t={rel:.3f} s: warm-up over", flush=True)

    def fault(self, reason, kind="link", received=None):
        """Enter the blind state now: ``FAULT`` line, hook, event closed, monitor reset.

        Nothing happens when the session is blind already (one line per
        blind period).

        Parameters
        ----------
        reason : str
            One line saying what happened.
        kind : str, default="link"
            ``"link"``, ``"stall"``, ``"rejected"``, ``"clock_jump"``,
            ``"gap"`` or ``"protocol"``.
        received : float, default=None
            :func:`time.perf_counter` of the fault (now when None).
        """
        if self.state == BLIND:
            return
        now = time.perf_counter() if received is None else received
        rel = self._last_rel if self._last_rel is not None else 0.0
        if self._last_ok is not None:
            rel += max(now - self._last_ok, 0.0)  # stream time of the fault, roughly
        self.state, self._blind_since, self._lost = BLIND, now, 0
        self.n_blind += 1
        self._open_fault = None
        if len(self.faults) < MAX_FAULT_RECORDS:
            self._open_fault = {"recording": self.name, "start_s": rel, "kind": kind,
                                "reason": reason, "last_stamp": self._valid_stamp,
                                "blind_s": None, "samples_lost": None,
                                "recovered_s": None, "recovered_stamp": None}
            self.faults.append(self._open_fault)
        if self.open is not None:
            self._close()
        self.cross_start = None
        self.monitor.reset()
        self._run = 0
        print(f"FAULT {self.name} t={rel:.3f} s: {reason}; blind, monitor reset", flush=True)
        self._run_hook({"GPCD_FAULT": reason, "GPCD_FAULT_TIME": f"{rel:.6f}"})

    def _alarm(self, rel, firing):
        """A tick where the bands ``firing`` (indices) alarm: open or extend the event."""
        alarms = self.monitor.alarms
        peak = max(float(np.abs(self.bands[b].signal[self.bands[b].alarms]).max())
                   for b in firing)
        if self.open is None:
            self.open = {"recording": self.name, "start_s": rel, "end_s": rel,
                         "joints": set(), "peak_A": peak,
                         "delay_s": rel - (rel if self.cross_start is None
                                           else self.cross_start)}
            if self.multiband:
                self.open["bands"] = set()
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
        """Close the open event; the recording's summary."""
        if self.open is not None:
            self._close()
        summary = self.recordings[-1]
        summary.update(n_samples=self.n_samples, n_sensor_faults=self.n_faults,
                       n_events=sum(e["recording"] == self.name for e in self.events))
        return summary

    # ------------------------------------------------------------ statistics
    def _statistics(self, t, received, decided):
        """Fixed-size live statistics: latency histogram, drops, lag behind the stream."""
        self._n_ticks += 1
        self._latency.add(decided - received)
        if not math.isfinite(t):
            return
        previous, self._stat_stamp = self._stat_stamp, t
        if previous is not None:
            step = t - previous
            if step > 0:
                if self._step is None:
                    self._steps.append(step)
                    if len(self._steps) == 100:
                        self._fix_step()
                else:
                    self._count_drops(step)
        rel = t - self.t0 if self.t0 is not None else 0.0
        if self._first_decided is None:
            self._first_decided, self._first_rel = decided, rel
        else:
            behind = (decided - self._first_decided) - (rel - self._first_rel)
            self._behind_max = max(self._behind_max, behind)

    def _fix_step(self):
        self._step = float(np.median(self._steps))
        for step in self._steps:
            self._count_drops(step)
        self._steps = []

    def _count_drops(self, step):
        if self._step > 0:
            self._dropped += max(round(step / self._step) - 1, 0)

    def live_statistics(self):
        """Tick latency (receive -> decision) percentiles and dropped samples.

        Returns
        -------
        stats : dict or None
            ``n_ticks``, ``latency_ms_p50``, ``latency_ms_p99``,
            ``latency_ms_max``, ``behind_stream_ms_max``, ``dropped_samples``
            (None without live ticks). Percentiles come from a histogram
            with 1 % wide bins (fixed memory).
        """
        if not self._n_ticks:
            return None
        if self._step is None and self._steps:
            self._fix_step()
        behind = self._behind_max if math.isfinite(self._behind_max) else 0.0
        return {"n_ticks": int(self._n_ticks),
                "latency_ms_p50": self._latency.percentile(50) * 1e3,
                "behind_stream_ms_max": behind * 1e3,
                "latency_ms_p99": self._latency.percentile(99) * 1e3,
                "latency_ms_max": self._latency.max * 1e3,
                "dropped_samples": int(self._dropped)}

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

    def connect_rtde(self, host, port=30004, frequency=None):
        """A connected RTDE client of a live UR controller, for :meth:`run_rtde`.

        Parameters
        ----------
        host : str
        port : int, default=30004
        frequency : float or None, default=None
            Output rate [Hz]; None: the detector's, ``1 / sample_time``.

        Returns
        -------
        client : RTDEClient

        Raises
        ------
        ValueError
            When the detector does not have the 6 joints RTDE streams.
        OSError
            When no stream can be started.
        """
        from .io import RTDEClient

        if self.monitor.n_joints != 6:
            raise ValueError(f"RTDE streams 6 joints; the detector has {self.monitor.n_joints}")
        client = RTDEClient(host, port, frequency or round(1.0 / self.sample_time, 6))
        try:
            return client.connect()
        except (OSError, ConnectionError) as exc:
            raise OSError(f"cannot start an RTDE stream from {host}:{port}: {exc} (check "
                          "--rtde HOST and --port)") from None

    def run_rtde(self, client, name, duration=None, reconnect_timeout=30.0):
        """Monitor a connected :class:`~sklearn_gpcd.io.RTDEClient` until the stream ends.

        Ends when the controller pauses the stream, after ``duration``
        seconds, or when the link stays lost for ``reconnect_timeout``
        seconds (then abnormally). A stall, a lost link (then reconnection
        with backoff: 50 ms doubling up to 2 s), a broken byte stream or a
        stream of rejected packages makes the session blind (:meth:`fault`).
        The client is closed on every exit path.

        Parameters
        ----------
        client : RTDEClient
            Connected (``client.connect()``).
        name : str
            Name of the stream in the events and lines.
        duration : float, default=None
            Wall-clock seconds to monitor; None until the stream ends.
        reconnect_timeout : float, default=30.0
            Give up after the link was lost this long [s].

        Returns
        -------
        summary : dict
            What :meth:`finish` returns.
        """
        from .io import MalformedPackage, StreamPaused

        self.start(name)
        begin = time.perf_counter()
        end = math.inf if duration is None else begin + float(duration)
        connected, lost_at, backoff = True, None, 0.05
        self._last_ok = begin  # a connection that never sends data is a stall
        # the objects of the setup (modules, model) leave the garbage collector's
        # generations: a full collection then takes no longer than a tick's garbage
        gc.freeze()
        try:
            while True:
                now = time.perf_counter()
                if now >= end:
                    self.end(self.end_reason or "duration")
                    break
                if not connected:
                    if now - lost_at > reconnect_timeout:
                        self.end(f"link lost for more than {reconnect_timeout:g} s",
                                 abnormal=True)
                        break
                    time.sleep(max(min(backoff, end - now), 0.0))
                    backoff = min(backoff * 2, 2.0)
                    try:
                        client.connect()
                    except OSError:
                        continue
                    connected, backoff = True, 0.05
                    self._last_ok = time.perf_counter()
                    print(f"RECONNECTED {self.name}: stream restarted after "
                          f"{self._last_ok - lost_at:.3f} s", flush=True)
                    continue
                deadline = (now + 0.25 if self.state == BLIND
                            else self._last_ok + self.stall_timeout)
                try:
                    received, fields = client.receive(min(deadline, end))
                except TimeoutError:
                    now = time.perf_counter()
                    if now < end and self.state != BLIND:
                        unknown = getattr(client, "n_unknown", 0)
                        self.fault(f"no valid data for {(now - self._last_ok) * 1e3:.0f} ms "
                                   f"(stall; {unknown} packages of unknown type so far)",
                                   kind="stall", received=now)
                    continue
                except StreamPaused:
                    self.end("the controller paused the stream")
                    break
                except MalformedPackage as exc:
                    now = time.perf_counter()
                    self.n_samples += 1
                    self._rejected(str(exc), now)
                    continue
                except ConnectionError as exc:  # lost link or broken byte stream
                    lost_at = time.perf_counter()
                    kind = "protocol" if "RTDE package" in str(exc) else "link"
                    self.fault(f"link lost: {exc}", kind=kind, received=lost_at)
                    client.close()
                    connected = False
                    continue
                self.tick(fields.pop("time"), fields, received)
        finally:
            client.close()
            gc.unfreeze()
        return self.finish()

    def end(self, reason, abnormal=False):
        """Record how the stream ended (``abnormal``: the exit status is non-zero).

        Parameters
        ----------
        reason : str
        abnormal : bool, default=False
        """
        self.end_reason = reason
        self.abnormal_end = self.abnormal_end or abnormal

    @property
    def exit_status(self):
        return FAULT_EXIT_STATUS if (self.n_blind or self.abnormal_end) else 0

    def report(self):
        """What the session saw, for the JSON report (on every exit path).

        Returns
        -------
        report : dict
            ``recordings``, ``events``, ``live`` (:meth:`live_statistics`),
            ``faults``, ``n_blind``, ``hook_failures``, ``state`` and ``end``
            (``reason``, ``abnormal``, ``exit_status``).
        """
        self._reap()
        return {"recordings": self.recordings, "events": self.events,
                "live": self.live_statistics(), "faults": self.faults,
                "n_blind": self.n_blind, "hook_failures": self.hook_failures,
                "state": self.state,
                "end": {"reason": self.end_reason, "abnormal": bool(self.abnormal_end),
                        "exit_status": self.exit_status}}
