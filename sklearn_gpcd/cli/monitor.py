"""``gpcd monitor``: alarm events through the causal streaming path.

Feeds raw samples through :meth:`StreamingMonitor.update_raw
<sklearn_gpcd.detection.StreamingMonitor.update_raw>` (the causal path that
runs on the robot) and reports the alarm events. Recordings are processed as
fast as possible, ``--replay`` paces one recording to its time stamps
(``--speed``), ``--rtde`` receives a live UR controller's stream (RTDE
protocol 2, :mod:`sklearn_gpcd.io._rtde_live`). All three go through the
same per-sample loop (:class:`_Session`); with several bands (alarm rules)
an event is a run of samples where any band alarms, and the report names
the bands.
"""

import json
import shlex
import subprocess
import sys
import time
from pathlib import Path

from ..workflow.calibration import band_label, band_settings, load_detector, recording_keys
from ._args import (
    column_map_arg,
    existing_file,
    non_negative_float,
    output_dir_arg,
    output_file_arg,
    positive_float,
    positive_int,
    read_recordings,
)

#: The positional list that recordings left over after the options join.
RECORDINGS = "recordings"


def add_parser(sub):
    """Register ``monitor`` on the ``gpcd`` subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction

    Examples
    --------
    >>> import argparse
    >>> parser = argparse.ArgumentParser(prog="gpcd")
    >>> add_parser(parser.add_subparsers(dest="command"))
    >>> sorted(parser._subparsers._group_actions[0].choices)
    ['monitor']
    """
    mon = sub.add_parser(
        "monitor",
        help="detect collisions in recordings, a real-time replay or a live UR (RTDE)",
        description="Run a detector from 'gpcd calibrate' sample by sample through the "
        "causal streaming path and report alarm events: start, end, joints (1-based), peak "
        "|m| and the delay from the first threshold crossing to the alarm; with several "
        "bands (gpcd calibrate --band), an alarm of any band, and which bands alarmed.",
    )
    mon.add_argument("detector", type=existing_file,
                     help="detector file written by gpcd calibrate")
    mon.add_argument("recordings", nargs="*", help="recordings to monitor (offline)")
    mon.add_argument("--column-map", type=column_map_arg, default=None,
                     help="column layout of the recordings (as for gpcd train)")
    mon.add_argument("--replay", default=None, metavar="FILE",
                     help="replay one recording paced to its time stamps")
    mon.add_argument("--speed", type=non_negative_float, default=1.0,
                     help="replay speed factor (1: real time, 0: as fast as possible)")
    mon.add_argument("--rtde", default=None, metavar="HOST",
                     help="monitor a live UR controller over RTDE")
    mon.add_argument("--port", type=positive_int, default=30004, help="RTDE port")
    mon.add_argument("--frequency", type=positive_float, default=None,
                     help="RTDE output frequency [Hz] (default: the detector's calibration "
                     "rate, 1 / sample time, so that its filters fit; at most 500 on "
                     "e-Series, 125 on CB3)")
    mon.add_argument("--duration", type=positive_float, default=None,
                     help="stop a live or replayed stream after this many seconds of "
                     "stream time")
    mon.add_argument("--hook", default=None, metavar="CMD",
                     help="command run (not waited for) at each alarm onset; it gets "
                     "GPCD_ALARM_TIME and GPCD_ALARM_JOINTS in its environment")
    mon.add_argument("--json", type=output_file_arg, default=None,
                     help="write the events (and live statistics) as JSON here")
    mon.add_argument("--plot", type=output_dir_arg, default=None, metavar="DIR",
                     help="write one figure per recording here (offline and replay)")
    mon.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    mon.set_defaults(func=run)


class _Session:
    """The per-sample loop every ``gpcd monitor`` source goes through.

    :meth:`tick` feeds one raw sample to :meth:`StreamingMonitor.update_raw`, then
    tracks threshold crossings and alarm events; :meth:`start` begins a new
    recording (monitor reset). With several bands an event is a run of
    samples where any band alarms, and it records which bands did
    (``"bands"``, 1-based).
    """

    def __init__(self, detector, features, hook=None, keep_series=False, echo=False):
        import numpy as np

        from ..detection import StreamingMonitor

        self.np = np
        self.monitor = StreamingMonitor(detector, features=features)
        #: one BandState per alarm rule
        self.bands = self.monitor.bands
        self.multiband = len(self.bands) > 1
        self.band_labels = [band_label(band_settings(b.rule)) for b in self.bands]
        self.signals = tuple(features.signals_)
        self.thresholds = [b.thresholds for b in self.bands]
        self.regime_names = tuple(self.bands[0].rule.regime_names_)
        self.hook, self.keep_series, self.echo = hook, keep_series, echo
        self.events, self.recordings = [], []
        self.latency, self.stamps, self.decided = [], [], []

    def start(self, name):
        self.monitor.reset()
        self.name, self.t0, self.cross_start, self.open = name, None, None, None
        self.n_samples = self.n_faults = 0
        self.series = {"t": [], "signal": [], "regime": [], "alarms": []}
        self.recordings.append({"name": name})

    def tick(self, t, fields, received=None):
        """One raw sample (``fields``: q, qd, current and the controller signals)."""
        np = self.np
        mon = self.monitor
        status = mon.update_raw(t, fields["q"], fields["qd"], fields["current"],
                                **{s: fields.get(s) for s in self.signals})
        if received is not None:
            decided = time.perf_counter()
            self.latency.append(decided - received)
            self.decided.append(decided)
            self.stamps.append(t)
        self.n_samples += 1
        if self.t0 is None:
            self.t0 = t
        if status == "sensor_fault":
            self.n_faults += 1
            return status
        rel = t - self.t0
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
            s["signal"].append([band.signal.copy() for band in self.bands])
            s["regime"].append([band.regime for band in self.bands])
            s["alarms"].append(mon.alarms.copy())
        return status

    def _alarm(self, rel, firing):
        """A tick where the bands ``firing`` (indices) alarm: open or extend the event."""
        np = self.np
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
        joints = ",".join(str(int(j) + 1) for j in self.np.flatnonzero(alarms))
        if self.echo:
            which = "".join(f", band {b + 1} ({self.band_labels[b]})" for b in firing)
            print(f"ALARM {self.name} t={event['start_s']:.3f} s joints {joints}"
                  + (which if self.multiband else ""), flush=True)
        if self.hook:
            import os

            env = {**os.environ, "GPCD_ALARM_TIME": f"{event['start_s']:.6f}",
                   "GPCD_ALARM_JOINTS": joints}
            if self.multiband:
                env["GPCD_ALARM_BANDS"] = ",".join(str(b + 1) for b in firing)
            subprocess.Popen(shlex.split(self.hook), env=env)  # not waited for

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

    def live_statistics(self):
        """Tick latency (receive -> decision) percentiles and dropped samples."""
        np = self.np
        if not self.latency:
            return None
        lat = np.asarray(self.latency) * 1e3
        steps = np.diff(np.asarray(self.stamps))
        dropped = 0
        if steps.size:
            dt = float(np.median(steps))
            dropped = int(np.sum(np.maximum(np.round(steps / dt) - 1, 0))) if dt > 0 else 0
        # how far decisions fall behind the stream's own clock (packages queued
        # in the socket buffer included), relative to the first tick
        stamps = np.asarray(self.stamps)
        behind = (np.asarray(self.decided) - self.decided[0]) - (stamps - stamps[0])
        return {"n_ticks": int(lat.size), "latency_ms_p50": float(np.percentile(lat, 50)),
                "behind_stream_ms_max": float(behind.max() * 1e3),
                "latency_ms_p99": float(np.percentile(lat, 99)),
                "latency_ms_max": float(lat.max()), "dropped_samples": dropped}


def _recording_fields(rec):
    """Raw samples of a recording as ``(time, fields)``."""
    names = ("q", "qd", "current", "target_current", "target_q", "target_qd")
    columns = {n: getattr(rec, n) for n in names if getattr(rec, n) is not None}
    for k in range(rec.n_samples):
        yield float(rec.time[k]), {n: v[k] for n, v in columns.items()}


def _paced(samples, speed, duration=None):
    """Yield ``(received, time, fields)`` at the samples' time stamps / ``speed``."""
    start, t0 = time.perf_counter(), None
    for t, fields in samples:
        if t0 is None:
            t0 = t
        if duration is not None and t - t0 > duration:  # stream time
            return
        if speed > 0 and (wait := start + (t - t0) / speed - time.perf_counter()) > 0:
            time.sleep(wait)
        yield time.perf_counter(), t, fields


def _rtde_samples(client, duration=None):
    start = time.perf_counter()
    for received, fields in client.samples():
        yield received, fields.pop("time"), fields
        if duration is not None and received - start > duration:
            return


def run(args):
    """``gpcd monitor``: alarm events through the causal streaming path."""
    sources = sum([bool(args.recordings), args.replay is not None, args.rtde is not None])
    if sources != 1:
        raise ValueError("give recordings, --replay FILE or --rtde HOST (exactly one)")
    if args.plot is not None and args.rtde is not None:
        raise ValueError("--plot is for recordings and --replay, not --rtde")
    start = time.perf_counter()
    detector, features, calibration = load_detector(args.detector)
    if args.plot is not None:
        Path(args.plot).mkdir(parents=True, exist_ok=True)
    live = args.rtde is not None or args.replay is not None
    session = _Session(detector, features, hook=args.hook, keep_series=args.plot is not None,
                       echo=live)
    plots = []
    if args.rtde is not None:
        from ..io import RTDEClient

        if session.monitor.n_joints != 6:
            raise ValueError(f"RTDE streams 6 joints; the detector has "
                             f"{session.monitor.n_joints}")
        sample_time = session.monitor.detector.sample_time_
        frequency = args.frequency or round(1.0 / float(sample_time), 6)
        client = RTDEClient(args.rtde, args.port, frequency)
        try:
            client.connect()
        except (OSError, ConnectionError) as exc:
            raise OSError(f"cannot start an RTDE stream from {args.rtde}:{args.port}: "
                          f"{exc}") from None
        print(f"monitoring {args.rtde}:{args.port} at {frequency:g} Hz (Ctrl-C stops)",
              flush=True)
        session.start(f"rtde://{args.rtde}:{args.port}")
        try:
            for received, t, fields in _rtde_samples(client, args.duration):
                session.tick(t, fields, received)
        finally:
            client.close()
        session.finish()
    else:
        paths = [args.replay] if args.replay is not None else args.recordings
        args.robot = None
        recordings = read_recordings(paths, args, "recordings",
                                      progress=not (args.quiet or live))
        keys = recording_keys(recordings)
        for key, rec in zip(keys, recordings):
            if rec.n_joints != session.monitor.n_joints:
                raise ValueError(f"{rec.name}: {rec.n_joints} joints but the detector has "
                                 f"{session.monitor.n_joints}")
            session.start(key)
            if args.replay is not None:
                for received, t, fields in _paced(_recording_fields(rec), args.speed,
                                                  args.duration):
                    session.tick(t, fields, received)
            else:
                for t, fields in _recording_fields(rec):
                    session.tick(t, fields)
            session.finish()
            if args.plot is not None:
                plots.append(_plot(session, Path(args.plot), key))
    _print_events(session)
    stats = session.live_statistics() if live else None
    if stats is not None:
        print(f"  {stats['n_ticks']} ticks; latency receive -> decision p50 "
              f"{stats['latency_ms_p50']:.3f} ms, p99 {stats['latency_ms_p99']:.3f} ms, max "
              f"{stats['latency_ms_max']:.3f} ms; dropped samples {stats['dropped_samples']}; "
              f"decisions at most {stats['behind_stream_ms_max']:.1f} ms behind the stream's "
              "clock")
    if args.json is not None:
        report = {"detector": str(args.detector), "calibration": calibration,
                  "recordings": session.recordings, "events": session.events,
                  "live": stats, "figures": [str(p) for p in plots if p is not None]}
        if session.multiband:
            report["bands"] = session.band_labels
        Path(args.json).write_text(json.dumps(report, indent=2))
        print(f"wrote {args.json}")
    for path in plots:
        if path is not None:
            print(f"wrote {path}")
    print(f"done in {time.perf_counter() - start:.1f} s")
    return 0


def _print_events(session):
    n_samples = sum(r["n_samples"] for r in session.recordings)
    n_faults = sum(r["n_sensor_faults"] for r in session.recordings)
    print(f"{len(session.events)} alarm event(s) in {len(session.recordings)} recording(s), "
          f"{n_samples} samples ({n_faults} sensor faults)")
    if session.multiband:
        for b, label in enumerate(session.band_labels, start=1):
            n_events = sum(b in e["bands"] for e in session.events)
            print(f"  band {b} ({label}) alarmed in {n_events} event(s)")
    if not session.events:
        return
    width = max(9, *(len(e["recording"]) for e in session.events))
    columns = [("recording", f"<{width}", lambda e: e["recording"]),
               ("start [s]", ">9", lambda e: f"{e['start_s']:.3f}"),
               ("end [s]", ">9", lambda e: f"{e['end_s']:.3f}"),
               ("joints", "<12", lambda e: ",".join(map(str, e["joints"]))),
               ("peak |m| [A]", ">12", lambda e: f"{e['peak_A']:.3f}"),
               ("delay [s]", ">9", lambda e: f"{e['delay_s']:.3f}")]
    if session.multiband:
        columns.insert(4, ("bands", "<6", lambda e: ",".join(map(str, e["bands"]))))
    print("  ".join(f"{name:{spec}}" for name, spec, _ in columns))
    for e in session.events:
        print("  ".join(f"{value(e):{spec}}" for _, spec, value in columns))


#: Line colours of the bands in a multi-band figure (C3, red, shades the events).
_BAND_COLORS = ("C0", "C2", "C4", "C1", "C5", "C6", "C8", "C9")


def _plot(session, folder, key):
    """One figure per recording, one axis per joint, alarm events shaded, alarms marked.

    One band: the monitoring signal and its per-regime thresholds [A]. Several
    bands: each band's ``|m|`` over its threshold (per regime), so that every
    band crosses at 1.
    """
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("gpcd monitor: warning: matplotlib is not installed; no figure",
              file=sys.stderr)
        return None
    np = session.np
    s = session.series
    t = np.asarray(s["t"])
    signal, regime = np.asarray(s["signal"]), np.asarray(s["regime"], dtype=int)
    alarms = np.asarray(s["alarms"], dtype=bool)
    n = signal.shape[2] if signal.ndim == 3 else 0
    fig, axes = plt.subplots(max(n, 1), 1, figsize=(9, 1.6 * max(n, 1) + 0.8), sharex=True,
                             squeeze=False)
    events = [e for e in session.events if e["recording"] == key]
    draw = _draw_ratios if session.multiband else _draw_signal
    for j in range(n):
        ax = axes[j, 0]
        for k, e in enumerate(events):
            ax.axvspan(e["start_s"], e["end_s"], color="C3", alpha=0.15,
                       label="alarm event" if k == 0 else None)
        ax.set_ylabel(draw(ax, session, t, signal[:, :, j], regime, j), fontsize=8)
        if alarms[:, j].any():
            ax.plot(t[alarms[:, j]], np.zeros(alarms[:, j].sum()), "|", color="k", ms=8,
                    label="alarm")
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=6, loc="upper right")
    axes[-1, 0].set_xlabel("t [s]")
    fig.suptitle(f"{key}: " + ("each band's |m| over its threshold (per regime), alarms"
                               if session.multiband else
                               "causal monitoring signal, per-regime thresholds, alarms"),
                 fontsize=9)
    fig.tight_layout()
    path = folder / f"{Path(key).stem}.png"
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path


def _draw_signal(ax, session, t, signal, regime, j):
    """One band: joint ``j``'s signal and its thresholds ``+-`` (per regime); the y label."""
    ax.plot(t, signal[:, 0], lw=0.7, color="C0", label="monitoring signal m")
    band = session.thresholds[0][regime[:, 0], j]
    ax.plot(t, band, lw=0.7, color="C1",
            label="threshold (" + "/".join(session.regime_names) + ")")
    ax.plot(t, -band, lw=0.7, color="C1")
    return f"joint {j + 1} [A]"


def _draw_ratios(ax, session, t, signal, regime, j):
    """Several bands: joint ``j``'s ``|m| / threshold`` per band, and 1; the y label."""
    for b, label in enumerate(session.band_labels):
        ratio = session.np.abs(signal[:, b]) / session.thresholds[b][regime[:, b], j]
        ax.plot(t, ratio, lw=0.7, color=_BAND_COLORS[b % len(_BAND_COLORS)],
                label=f"band {b + 1} ({label})")
    ax.axhline(1.0, lw=0.7, ls="--", color="k", label="threshold")
    return f"joint {j + 1}\n|m| / threshold"
