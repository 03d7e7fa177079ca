"""``gpcd monitor``: alarm events through the causal streaming path.

Feeds raw samples through :meth:`StreamingMonitor.update_raw
<sklearn_gpcd.detection.StreamingMonitor.update_raw>` (the causal path that
runs on the robot) and reports the alarm events. Recordings are processed as
fast as possible, ``--replay`` paces one recording to its time stamps
(``--speed``), ``--rtde`` receives a live UR controller's stream (RTDE
protocol 2, :mod:`sklearn_gpcd.io._rtde_live`). All three go through the
same per-sample loop (:class:`~sklearn_gpcd.monitoring.MonitorSession`,
fail-safe on live streams: FAULT lines, reset, reconnection, exit status
3); with several bands (alarm rules) an event is a run of samples where any
band alarms, and the report names the bands.
"""

import json
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
                     help="command run (not waited for) at each alarm onset (it gets "
                     "GPCD_ALARM_TIME and GPCD_ALARM_JOINTS in its environment) and at each "
                     "fault of a live stream (GPCD_FAULT, GPCD_FAULT_TIME); one that fails "
                     "is reported and monitoring goes on")
    mon.add_argument("--json", type=output_file_arg, default=None,
                     help="write the events (and live statistics) as JSON here")
    mon.add_argument("--plot", type=output_dir_arg, default=None, metavar="DIR",
                     help="write one figure per recording here (offline and replay)")
    mon.add_argument("--trust-pickle", action="store_true",
                     help="load a .joblib / .pkl detector file (a pickle runs any code it "
                     "carries: only for a file from a source you trust)")
    mon.add_argument("--stall-timeout", type=positive_float, default=None,
                     metavar="SECONDS",
                     help="live streams: blind (a FAULT line, the hook with GPCD_FAULT, "
                     "monitor reset) after this long without a valid decision (default: "
                     "3 control periods or 20 ms, whichever is larger)")
    mon.add_argument("--reconnect-timeout", type=non_negative_float, default=30.0,
                     metavar="SECONDS",
                     help="--rtde: after a lost link, reconnect with backoff for this long, "
                     "then end (exit status 3)")
    mon.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    mon.set_defaults(func=run)


def run(args):
    """``gpcd monitor``: alarm events through the causal streaming path.

    The loop is :class:`sklearn_gpcd.monitoring.MonitorSession`; the JSON
    report is written on every exit path once monitoring started (Ctrl-C and
    errors included), and the exit status is 3 when a live stream was blind
    at some time or ended abnormally.
    """
    from ..monitoring import MonitorSession

    sources = sum([bool(args.recordings), args.replay is not None, args.rtde is not None])
    if sources != 1:
        raise ValueError("give recordings, --replay FILE or --rtde HOST (exactly one)")
    if args.plot is not None and args.rtde is not None:
        raise ValueError("--plot is for recordings and --replay, not --rtde")
    start = time.perf_counter()
    detector, features, calibration = load_detector(args.detector,
                                                    trust_pickle=args.trust_pickle)
    if args.plot is not None:
        Path(args.plot).mkdir(parents=True, exist_ok=True)
    live = args.rtde is not None or args.replay is not None
    session = MonitorSession(detector, features, hook=args.hook,
                             keep_series=args.plot is not None, echo=live,
                             stall_timeout=args.stall_timeout)
    session.band_labels = [band_label(band_settings(b.rule)) for b in session.bands]
    plots = []
    try:
        if args.rtde is not None:
            _monitor_rtde(args, session)
        else:
            paths = [args.replay] if args.replay is not None else args.recordings
            args.robot = None
            recordings = read_recordings(paths, args, "recordings",
                                          progress=not (args.quiet or live))
            keys = recording_keys(recordings)
            for key, rec in zip(keys, recordings):
                if rec.n_joints != session.monitor.n_joints:
                    raise ValueError(f"{rec.name}: {rec.n_joints} joints but the detector "
                                     f"has {session.monitor.n_joints}")
                session.run_recording(rec, key, duration=args.duration,
                                      speed=args.speed if args.replay is not None else None)
                if args.plot is not None:
                    plots.append(_plot(session, Path(args.plot), key))
    except BaseException as exc:  # the report on every exit path, then as before
        if session.recordings:
            session.finish()  # the open event, the summary so far
            session.end("interrupted" if isinstance(exc, KeyboardInterrupt)
                        else f"error: {' '.join(str(exc).split())}", abnormal=True)
            _write_report(args, session, calibration, plots)
        raise
    _print_events(session)
    stats = session.live_statistics() if live else None
    if stats is not None:
        print(f"  {stats['n_ticks']} ticks; latency receive -> decision p50 "
              f"{stats['latency_ms_p50']:.3f} ms, p99 {stats['latency_ms_p99']:.3f} ms, max "
              f"{stats['latency_ms_max']:.3f} ms; dropped samples {stats['dropped_samples']}; "
              f"decisions at most {stats['behind_stream_ms_max']:.1f} ms behind the stream's "
              "clock")
    if session.exit_status:
        blind = sum(f["blind_s"] or 0.0 for f in session.faults)
        print(f"  {session.n_blind} fault(s): blind {blind:.3f} s in total"
              + (f"; the stream ended abnormally: {session.end_reason}"
                 if session.abnormal_end else "") + f" (exit status {session.exit_status})")
    if args.json is not None:
        _write_report(args, session, calibration, plots)
        print(f"wrote {args.json}")
    for path in plots:
        if path is not None:
            print(f"wrote {path}")
    print(f"done in {time.perf_counter() - start:.1f} s")
    return session.exit_status


def _monitor_rtde(args, session):
    """``gpcd monitor --rtde``: connect, then :meth:`MonitorSession.run_rtde`."""
    from ..io import RTDEClient

    if session.monitor.n_joints != 6:
        raise ValueError(f"RTDE streams 6 joints; the detector has "
                         f"{session.monitor.n_joints}")
    frequency = args.frequency or round(1.0 / session.sample_time, 6)
    client = RTDEClient(args.rtde, args.port, frequency)
    try:
        client.connect()
    except (OSError, ConnectionError) as exc:
        raise OSError(f"cannot start an RTDE stream from {args.rtde}:{args.port}: "
                      f"{exc}") from None
    print(f"monitoring {args.rtde}:{args.port} at {frequency:g} Hz (Ctrl-C stops)",
          flush=True)
    session.run_rtde(client, f"rtde://{args.rtde}:{args.port}", duration=args.duration,
                     reconnect_timeout=args.reconnect_timeout)


def _write_report(args, session, calibration, plots):
    """The JSON report of ``gpcd monitor`` (``--json``), if asked for."""
    if args.json is None:
        return
    report = {"detector": str(args.detector), "calibration": calibration,
              **session.report(), "figures": [str(p) for p in plots if p is not None]}
    if session.multiband:
        report["bands"] = session.band_labels
    Path(args.json).write_text(json.dumps(report, indent=2))


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
    import numpy as np

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
        ratio = abs(signal[:, b]) / session.thresholds[b][regime[:, b], j]
        ax.plot(t, ratio, lw=0.7, color=_BAND_COLORS[b % len(_BAND_COLORS)],
                label=f"band {b + 1} ({label})")
    ax.axhline(1.0, lw=0.7, ls="--", color="k", label="threshold")
    return f"joint {j + 1}\n|m| / threshold"
