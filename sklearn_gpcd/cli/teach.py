"""``gpcd teach``: a calibrated detector taught one task from a few
collision-free cycles, a thin layer over :func:`sklearn_gpcd.workflow.teach_task`
(:class:`~sklearn_gpcd.detection.TaughtTask`), saved for ``gpcd monitor``."""

import time

from ..workflow import (load_detector, recording_keys, save_detector, teach_report,
                        teach_task, update_task)
from ._args import (
    add_file_options,
    add_recording_options,
    band_arg,
    existing_file,
    file_size,
    positive_float,
    read_recordings,
)


def add_parser(sub):
    """Register ``teach`` on the ``gpcd`` subparsers ``sub``."""
    teach = sub.add_parser(
        "teach",
        help="teach a calibrated detector one task from a few collision-free cycles",
        description="Learn the residual the model leaves in one task's own states (a ridge "
        "on the state with a local correction, cross-fitted cycle by cycle) and thresholds "
        "for it: each cycle scored against the others, one level for all joints. Where the "
        "arm moves through taught states, the monitor subtracts the reference and uses "
        "these thresholds with a fast band; at rest, settling or in untaught motion the "
        "calibrated detector decides, and the monitor says so. Record at least two cycles "
        "(more cycles, a lower false-alarm bound).",
    )
    teach.add_argument("detector", type=existing_file,
                       help="detector file written by gpcd calibrate (or gpcd teach: taught "
                       "anew)")
    teach.add_argument("recordings", nargs="+",
                       help="collision-free recordings of the task (files, folders or glob "
                       "patterns), two cycles or more in all")
    add_recording_options(teach, "built-in name or URDF path (default: the robot named in "
                                 "the recordings' metadata)")
    teach.add_argument("--band", type=band_arg, default=None, metavar="CUTOFF,ORDER,DEBOUNCE",
                       help="the taught band's causal low-pass (cut-off [Hz], order 1 or 2) "
                       "and debounce [samples] (default 10,1,2)")
    teach.add_argument("--novelty-radius", type=positive_float, default=1.0, metavar="R",
                       help="a state farther than R from every taught one, in units of "
                       "0.1 rad and 0.5 rad/s, is untaught (default 1)")
    teach.add_argument("--false-alarm-rate", type=positive_float, default=0.1, metavar="PER_H",
                       help="target false alarms per hour of the task: the level is at least "
                       "the Gumbel quantile of the cycle scores at this rate (default 0.1)")
    teach.add_argument("--update", action="store_true",
                       help="keep learning: DETECTOR is a taught file and the recordings are "
                       "monitored runs of its task, in time order; the slow drift (warm-up) "
                       "is learnt from whole cycles far from every alarm, bounded by half "
                       "the thresholds, which never rise")
    add_file_options(teach, "taught detector file", "detector file")
    teach.set_defaults(func=run)


def run(args):
    """``gpcd teach``: the task reference and its thresholds, saved with the detector."""
    start = time.perf_counter()
    calibrated = load_detector(args.detector, trust_pickle=args.trust_pickle)
    recordings = read_recordings(args.recordings, args, "task recordings")
    if args.update:
        updated = update_task(calibrated, recordings, keys=recording_keys(recordings))
        save_detector(updated, args.output)
        print(teach_report(updated.calibration["teach"]))
        print(f"  {time.perf_counter() - start:.1f} s; wrote {args.output}, "
              f"{file_size(args.output)}")
        return 0
    band = args.band or {}
    params = {"novelty_radius": args.novelty_radius,
              "false_alarm_rate": args.false_alarm_rate}
    params.update({k: band[b] for k, b in (("cutoff", "filter_cutoff"),
                                           ("order", "filter_order"),
                                           ("min_duration", "min_duration")) if b in band})
    taught = teach_task(calibrated, recordings, keys=recording_keys(recordings), **params)
    save_detector(taught, args.output)
    print(teach_report(taught.calibration["teach"]))
    print(f"  {time.perf_counter() - start:.1f} s; wrote {args.output}, "
          f"{file_size(args.output)}")
    return 0
