"""``gpcd calibrate``: detection thresholds chosen across collision-free
recordings, a thin layer over :func:`sklearn_gpcd.workflow.calibrate_detector`
(rule :data:`~sklearn_gpcd.workflow.DETECTOR_RULE`), saved with
:func:`~sklearn_gpcd.workflow.save_detector` for ``gpcd monitor``."""

import argparse
import math
import tempfile
import time
from pathlib import Path

from ..io.chunks import streamed
from ..io.load import recording_paths
from ..workflow.calibration import SELECT_GRID, check_recordings, resolve_select
from ..workflow.streamed import calibrate_detector_streamed, check_fits_streamed
from ..workflow import (
    calibrate_detector,
    calibration_report,
    check_calibration_options,
    load_model,
    recording_keys,
    save_detector,
)
from ._args import (
    ProgressBar,
    add_file_options,
    add_recording_options,
    band_arg,
    existing_file,
    file_size,
    non_negative_float,
    positive_float,
    confirmed_kinds,
    read_recordings,
    reader_options,
    robot_for,
)

#: The positional list that recordings left over after the options join.
RECORDINGS = "recordings"


def _braking_arg(value):
    """``--braking [LIMIT]``: "model", or a finite acceleration > 0 [rad/s^2]."""
    if value == "model":
        return value
    try:
        limit = float(value)
    except ValueError:
        limit = float("nan")
    if not (0.0 < limit < float("inf")):
        raise argparse.ArgumentTypeError(
            f"expected an acceleration > 0 in rad/s^2 (or nothing: the model's own "
            f"limit), got {value!r}")
    return limit


def _grid_text(name):
    """The candidates of ``--select`` for one setting, in words: "none, 2, 5 s"."""
    values = SELECT_GRID[f"regimes__{name}"]
    return ", ".join("none" if v is None else f"{v:g}" for v in values) + " s"


def add_parser(sub):
    """Register ``calibrate`` on the ``gpcd`` subparsers ``sub``."""
    cal = sub.add_parser(
        "calibrate",
        help="choose detection thresholds on collision-free recordings",
        description="Wrap a model saved by 'gpcd train' in a collision detector on causal "
        "inputs (2 Hz causal low-pass, 5-sample debounce, a threshold per joint and per "
        "regime of the arm: moving, settling, rest). Each level is the largest excursion of "
        "the calibration recordings, times a margin chosen by leave-one-recording-out: the "
        "largest factor by which a left-out recording exceeds the levels of the others. The "
        "expected false alarms per hour come from the nested version (margin and levels "
        "chosen without the recording they are counted on).",
    )
    cal.add_argument("model", type=existing_file, help="model file written by gpcd train")
    cal.add_argument("recordings", nargs="+",
                     help="collision-free recordings (files, folders or glob patterns; at "
                     "least 2, 3 for the false-alarm figure)")
    add_recording_options(cal, "built-in name or URDF path, for thresholds in Nm "
                               "(default: the robot named in the recordings' metadata)")
    cal.add_argument("--rest-reference", type=non_negative_float, default=None,
                     help="time constant [s] of the rest re-reference (0: none; default: "
                     f"chosen across the recordings among {_grid_text('rest_reference')} "
                     "(--select), 5 with --no-select)")
    cal.add_argument("--settle-time", type=non_negative_float, default=None,
                     metavar="SECONDS",
                     help="seconds the arm must be still after a motion before it is at "
                     f"rest (default: chosen across the recordings among "
                     f"{_grid_text('settle_time')} (--select), 0.5 with --no-select)")
    cal.add_argument("--select", action=argparse.BooleanOptionalAction, default="auto",
                     help=f"choose the settle time ({_grid_text('settle_time')}) and the "
                     f"rest reference ({_grid_text('rest_reference')}) across the "
                     "recordings: of the pairs with the fewest "
                     "nested alarm onsets on the recordings, the one with the smallest "
                     "time-weighted thresholds at its own leave-one-recording-out margin; "
                     "the expected false alarms then count each recording at the pair "
                     "chosen without it. The default unless --settle-time, "
                     "--rest-reference, --band, --band-candidate or --no-regimes fix the "
                     "settings; --no-select keeps settle 0.5 s and rest reference 5 s")
    cal.add_argument("--no-regimes", action="store_true",
                     help="one threshold per joint for every regime (no rest reference)")
    cal.add_argument("--band", type=band_arg, action="append", default=None,
                     metavar="CUTOFF,ORDER,DEBOUNCE",
                     help="add a band: the same detector with its own causal low-pass "
                     "(cut-off [Hz], order 1 or 2) and debounce [samples], calibrated by the "
                     "same rule on the same model; a sample is a collision when any band "
                     "alarms (repeatable; e.g. --band 10,1,2 for short taps the 2 Hz main "
                     "band smooths away). The false-alarm figure counts the union")
    cal.add_argument("--band-candidate", type=band_arg, action="append", default=None,
                     metavar="CUTOFF,ORDER,DEBOUNCE", dest="band_candidates",
                     help="a candidate for one more band whose settings are chosen across "
                     "the recordings (repeatable: give two or more): of the candidates, the "
                     "one with the fewest nested alarm onsets of the union of all bands, "
                     "then the smallest time-weighted thresholds; the expected false alarms "
                     "then count each recording with the band chosen without it")
    cal.add_argument("--braking", nargs="?", const="model", default=None, metavar="LIMIT",
                     type=_braking_arg,
                     help="a fourth regime with its own thresholds, braking: the 0.5 s after "
                     "a sample where some joint's |qdd| exceeds LIMIT [rad/s^2] (hard stops "
                     "ring the current); without LIMIT, the largest |qdd| the model was "
                     "trained on (recorded by gpcd train)")
    cal.add_argument("--split", type=positive_float, default=None, metavar="SECONDS",
                     help="cut every recording into pieces of at least SECONDS, each left "
                     "out in turn like a recording of its own (for one long collision-free "
                     "log; pieces of one log are less independent than separate runs, so "
                     "the margin and the false-alarm figure are less safe)")
    add_file_options(cal, "detector file", "model file")
    cal.set_defaults(func=run)


def _optional_robot(args, recordings):
    """The robot for Nm figures: --robot, else the recordings' metadata, else None."""
    try:
        return robot_for(args, recordings)
    except ValueError:
        if args.robot is not None:
            raise
        return None


def _calibrate_streamed(args, trained, paths, options):
    """Files larger than :data:`~sklearn_gpcd.io.chunks.STREAM_BYTES`: read in
    chunks into a temporary work folder (``TMPDIR``), one piece in memory at a
    time (:mod:`sklearn_gpcd.workflow.streamed`); what would not fit is refused
    from each file's first chunk, before the work."""
    select = resolve_select(options["select"], **{k: options[k] for k in (
        "regimes", "rest_reference", "settle_time", "bands", "band_candidates")})
    n_bands = len(options["bands"]) + (
        len(options["band_candidates"]) or (math.prod(map(len, SELECT_GRID.values())) if select else 1))
    reader = dict(reader_options(args), column_map=args.column_map)
    with tempfile.TemporaryDirectory(prefix="gpcd-calibrate-") as work:
        firsts = check_fits_streamed(paths, args.split, Path(work), n_bands, reader)
        bar = ProgressBar("reading calibration recordings", len(paths),
                          enabled=not args.quiet)
        return calibrate_detector_streamed(
            trained, paths, work, reader=reader, split=args.split,
            robot=_optional_robot(args, firsts), accept=confirmed_kinds(args),
            on_read=bar.update, **options)


def run(args):
    """``gpcd calibrate``: thresholds across the recordings, saved with the model's features."""
    start = time.perf_counter()
    paths = [Path(p).resolve() for p in recording_paths(args.recordings)]
    if (twice := sorted({str(p) for p in paths if paths.count(p) > 1})):
        raise ValueError(f"{twice[0]} is given twice; a left-out recording must not stay in "
                         "the others (check overlapping patterns)")
    if len(paths) < 2 and args.split is None:  # before any work
        raise ValueError("thresholds are chosen across recordings (leave-one-recording-out): "
                         f"give at least 2 collision-free recordings, got {len(paths)} "
                         "(or cut a long one into pieces with --split SECONDS)")
    options = dict(regimes=not args.no_regimes, rest_reference=args.rest_reference,
                   settle_time=args.settle_time, select=args.select,
                   bands=args.band or (), band_candidates=args.band_candidates or (),
                   braking=args.braking)
    check_calibration_options(**options)
    trained = load_model(args.model, trust_pickle=args.trust_pickle)
    if streamed(paths):
        calibrated = _calibrate_streamed(args, trained, paths, options)
    else:
        recordings = read_recordings(args.recordings, args, "calibration recordings")
        if trained.features is not None:
            check_recordings(recordings, f"the model {args.model}",
                             n_joints=trained.features.n_joints_,
                             units=trained.training.get("units"))
        robot = _optional_robot(args, recordings)
        calibrated = calibrate_detector(
            trained, recordings, keys=recording_keys(recordings), split=args.split,
            robot=robot, accept=confirmed_kinds(args), **options,
            progress=lambda label, total: ProgressBar(label, total, enabled=not args.quiet))
    save_detector(calibrated, args.output)
    print(calibration_report(calibrated.calibration))
    print(f"  {time.perf_counter() - start:.1f} s; wrote {args.output}, "
          f"{file_size(args.output)}")
    return 0
