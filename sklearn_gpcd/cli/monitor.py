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
import warnings
from pathlib import Path
from types import SimpleNamespace

from .._atomic import atomic_write
from ..io import RecordingWarning, iter_recording_chunks
from ..io.chunks import STREAM_BYTES, streamed
from ..io.load import recording_paths
from ..monitoring.stops import StopSignal, hold_stop_signals, stop_signals
from ..monitoring import MonitorSession
from ..workflow.calibration import (check_recordings, check_signals, detector_robot,
                                    load_detector, recording_keys, signal_check)
from ._args import (
    column_map_arg,
    confirmed_kinds,
    existing_file,
    non_negative_float,
    output_dir_arg,
    output_file_arg,
    positive_float,
    positive_int,
    add_check_options,
    read_recordings,
    reader_options,
)

#: The positional list that recordings left over after the options join.
RECORDINGS = "recordings"


def add_parser(sub):
    """Register ``monitor`` on the ``gpcd`` subparsers ``sub``."""
    mon = sub.add_parser(
        "monitor",
        help="detect collisions in recordings, a real-time replay or a live UR (RTDE)",
        description="Run a detector from 'gpcd calibrate' sample by sample through the "
        "causal streaming path and report one event per contact (it ends when the signal "
        "has stayed below half its threshold for 0.2 s): start, end, joints (1-based), peak "
        "|m| per joint, the delay from the first threshold crossing to the alarm, the link "
        "hit and the force (with the robot's model); with several bands (gpcd calibrate "
        "--band), an alarm of any band, and which bands alarmed.",
    )
    mon.add_argument("detector", type=existing_file,
                     help="detector file written by gpcd calibrate")
    mon.add_argument("recordings", nargs="*", help="recordings to monitor (offline)")
    mon.add_argument("--column-map", type=column_map_arg, default=None,
                     help="column layout of the recordings (as for gpcd train)")
    add_check_options(mon)
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
    sources = sum([bool(args.recordings), args.replay is not None, args.rtde is not None])
    if sources != 1:
        raise ValueError("give recordings, --replay FILE or --rtde HOST (exactly one)")
    if args.plot is not None and args.rtde is not None:
        raise ValueError("--plot is for recordings and --replay, not --rtde")
    start = time.perf_counter()
    calibrated = load_detector(args.detector, trust_pickle=args.trust_pickle)
    detector, features, calibration = calibrated
    if args.plot is not None:
        Path(args.plot).mkdir(parents=True, exist_ok=True)
    live = args.rtde is not None or args.replay is not None
    session = MonitorSession(detector, features, hook=args.hook,
                             keep_series=args.plot is not None, echo=live,
                             stall_timeout=args.stall_timeout,
                             signal_check=(signal_check(calibrated) if args.rtde is not None
                                           else None),  # files: checked before the run
                             robot=detector_robot(calibrated))
    plots = []
    with stop_signals():  # SIGTERM and SIGHUP end the run like Ctrl-C
        try:
            _monitor(args, session, plots, live, calibrated)
        except BaseException as exc:  # the report on every exit path, then as before
            hold_stop_signals()
            stopped = isinstance(exc, StopSignal)
            if session.recordings or stopped:  # a stop is reported, even before any sample
                if session.recordings:
                    session.finish()  # the open event, the summary so far
                session.end(_end_reason(exc), abnormal=True)
                _write_report(args, session, calibration, plots)
            if not stopped:
                raise
            print(f"gpcd monitor: {exc}" + (f"; wrote {args.json}" if args.json else ""),
                  file=sys.stderr)
            return exc.exit_status
    print(session.summary_text(live))
    if "teach" not in calibration:
        print(f"  {args.detector} is not taught any task: the calibrated thresholds applied "
              "everywhere (gpcd teach DETECTOR TASK_LOG... -o TAUGHT learns one)")
    if args.json is not None:
        _write_report(args, session, calibration, plots)
        print(f"wrote {args.json}")
    for path in plots:
        if path is not None:
            print(f"wrote {path}")
    print(f"done in {time.perf_counter() - start:.1f} s")
    return session.exit_status


def _monitor(args, session, plots, live, calibrated):
    """The run: a live RTDE stream, or recordings (offline or one paced replay)."""
    if args.rtde is not None:
        client = session.connect_rtde(args.rtde, args.port, args.frequency)
        print(f"monitoring {args.rtde}:{args.port} at {client.frequency:g} Hz (Ctrl-C "
              "stops)", flush=True)
        session.run_rtde(client, f"rtde://{args.rtde}:{args.port}",
                         duration=args.duration, reconnect_timeout=args.reconnect_timeout)
        return
    paths = [args.replay] if args.replay is not None else args.recordings
    args.robot = None
    if streamed(recording_paths(paths)):
        _monitor_streamed(args, session, paths, calibrated)
        return
    recordings = read_recordings(paths, args, "recordings",
                                 progress=not (args.quiet or live))
    check_recordings(recordings, f"the detector {args.detector}",
                     units=calibrated.calibration.get("units"))
    for rec in recordings:  # every file before any event: one refusal, no half run
        check_signals(rec, calibrated, accept=confirmed_kinds(args))
    keys = recording_keys(recordings)
    for key, rec in zip(keys, recordings):
        session.run_recording(rec, key, duration=args.duration,
                              speed=args.speed if args.replay is not None else None)
        if args.plot is not None:
            plots.append(session.plot(key, Path(args.plot)))


def _monitor_streamed(args, session, paths, calibrated):
    """Files larger than :data:`~sklearn_gpcd.io.chunks.STREAM_BYTES`: read in
    chunks twice, the signal checks of every file first (one refusal, no half
    run), then the run; memory is that of a chunk, whatever the files' length."""
    if args.plot is not None:
        raise ValueError(f"--plot keeps every sample of a recording in memory; "
                         f"{' '.join(map(str, paths))} holds files larger than "
                         f"{STREAM_BYTES // 2**20} MiB: drop --plot, or cut the file into "
                         "shorter recordings (e.g. split -l)")
    sources = recording_paths(paths)
    if not sources:
        raise ValueError(f"no recordings found in {' '.join(map(str, paths))}")
    options = dict(reader_options(args), column_map=args.column_map)
    detector = f"the detector {args.detector}"
    for path in sources:
        for chunk in iter_recording_chunks(path, **options):
            check_recordings([chunk], detector, units=calibrated.calibration.get("units"))
            check_signals(chunk, calibrated, accept=confirmed_kinds(args), name=str(path))
    keys = recording_keys([SimpleNamespace(name=Path(p).name) for p in sources])
    for key, path in zip(keys, sources):
        with warnings.catch_warnings():  # the readers' warnings were said in the checks
            warnings.simplefilter("ignore", RecordingWarning)
            session.run_recording(iter_recording_chunks(path, **options), key,
                                  duration=args.duration,
                                  speed=args.speed if args.replay is not None else None)


def _end_reason(exc):
    """The report's ``end.reason`` of a run that ended with ``exc``."""
    if isinstance(exc, KeyboardInterrupt):
        return "interrupted"
    if isinstance(exc, StopSignal):
        return str(exc)  # "stopped by SIGTERM"
    return f"error: {' '.join(str(exc).split())}"


def _write_report(args, session, calibration, plots):
    """The JSON report of ``gpcd monitor`` (``--json``), if asked for."""
    if args.json is None:
        return
    report = {"detector": str(args.detector), "calibration": calibration,
              **session.report(), "figures": [str(p) for p in plots if p is not None]}
    if session.multiband:
        report["bands"] = session.band_labels
    text = json.dumps(report, indent=2)
    atomic_write(args.json, lambda handle: handle.write(text), mode="w")
