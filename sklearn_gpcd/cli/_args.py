"""What the ``gpcd`` verbs share: argument types checked at parse time, reading
recordings and resolving the robot (the progress bar is ``sklearn_gpcd._progress``)."""

import argparse
import importlib.util
import json
import math
import os
import warnings
from pathlib import Path

from .._progress import ProgressBar
from ..io import COLUMN_PRESETS, load_recordings


# ---------------------------------------------------------------- arguments
def robot_arg(value):
    """Resolve ``--robot`` at parse time so a bad name fails with usage help."""
    # deferred: pinocchio, loaded when a robot is (gpcd starts without it)
    from ..robots import load_robot

    try:
        robot = load_robot(value)
    except (ValueError, OSError) as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    robot.source = value  # for --joints, which reloads it
    return robot


def joints_arg(value):
    """``--joints``: a count (the model's first N joints) or comma-separated names."""
    text = value.strip()
    return int(text) if text.isdigit() else [name.strip() for name in text.split(",")]


def column_map_arg(value):
    """``--column-map``: a preset name, a JSON file or a JSON object."""
    text = value.strip()
    if text in COLUMN_PRESETS:
        return text
    source = "--column-map"
    if not text.startswith("{"):
        path = Path(text)
        if not path.is_file():
            raise argparse.ArgumentTypeError(
                f"{value!r} is neither a preset ({', '.join(COLUMN_PRESETS)}), a JSON file nor "
                "a JSON object such as '{\"time\": 0, \"q\": [1, 6], ...}'")
        source = str(path)
        try:
            text = path.read_text()
        except (OSError, UnicodeDecodeError) as exc:
            raise argparse.ArgumentTypeError(f"cannot read {path}: {exc}") from None
    try:
        mapping = json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"{source}: not valid JSON ({exc})") from None
    if not isinstance(mapping, dict):
        raise argparse.ArgumentTypeError(
            f"{source}: a column map is a JSON object (field -> columns), got "
            f"{type(mapping).__name__}")
    return mapping


def output_file_arg(value):
    """An output file path whose folder exists and is writable (checked at parse time)."""
    path = Path(value)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{value}: is a folder, expected a file name")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise argparse.ArgumentTypeError(f"{value}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise argparse.ArgumentTypeError(f"{value}: not writable")
    return value


#: Figure formats a ``--plot FILE`` accepts (by file suffix).
PLOT_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg", ".eps", ".ps", ".tif", ".tiff")


def figure_file_arg(value):
    """An output figure path: writable as :func:`output_file_arg`, known format."""
    value = output_file_arg(value)
    if Path(value).suffix.lower() not in PLOT_SUFFIXES:
        raise argparse.ArgumentTypeError(
            f"{value}: unknown figure format {Path(value).suffix!r}; use one of "
            f"{', '.join(PLOT_SUFFIXES)}")
    return value


def output_dir_arg(value):
    """An output folder that exists or can be created (checked at parse time)."""
    path = Path(value)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{value}: is a file, expected a folder")
    existing = path
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir() or not os.access(existing, os.W_OK):
        raise argparse.ArgumentTypeError(f"{value}: cannot write in {existing}")
    return value


def model_file_arg(value):
    """``-o`` of ``gpcd train``: a writable ``.skops``, ``.joblib`` or ``.pkl`` file."""
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..persistence import PICKLE_EXTENSIONS, SKOPS_EXTENSION

    suffixes = (SKOPS_EXTENSION,) + tuple(PICKLE_EXTENSIONS)
    suffix = Path(value).suffix.lower()
    if suffix not in suffixes:
        raise argparse.ArgumentTypeError(
            f"{value}: the extension chooses the format; use one of {', '.join(suffixes)}")
    if suffix == SKOPS_EXTENSION and importlib.util.find_spec("skops") is None:
        raise argparse.ArgumentTypeError(
            f"{value}: writing .skops files needs skops, which is not installed: pip install "
            "skops (or 'sklearn-gpcd[persist]'), or write -o with .joblib")
    return output_file_arg(value)


def _number(value, cast, ok, what):
    """``value`` cast by ``cast`` when ``ok`` of it, else an ArgumentTypeError."""
    try:
        number = cast(value)
    except ValueError:
        number = None
    if number is None or not ok(number):
        raise argparse.ArgumentTypeError(f"expected {what}, got {value!r}")
    return number


def positive_int(value):
    return _number(value, int, lambda n: n >= 1, "an integer >= 1")


def positive_float(value):
    return _number(value, float, lambda n: 0 < n < math.inf, "a number > 0")


def non_negative_float(value):
    return _number(value, float, lambda n: 0 <= n < math.inf, "a number >= 0")


def n_support_arg(value):
    return "auto" if value.strip().lower() == "auto" else positive_int(value)


# ---------------------------------------------------------------- recordings
def band_arg(value):
    """``CUTOFF,ORDER,DEBOUNCE`` as AlarmRule settings (``--band``)."""
    usage = ("expected CUTOFF,ORDER,DEBOUNCE like 10,1,2 (low-pass cut-off > 0 Hz, filter "
             f"order 1 or 2, debounce >= 1 samples), got {value!r}")
    parts = value.split(",")
    try:
        cutoff, order, debounce = float(parts[0]), int(parts[1]), int(parts[2])
    except (ValueError, IndexError):
        raise argparse.ArgumentTypeError(usage) from None
    if len(parts) != 3 or not (0 < cutoff < math.inf and order in (1, 2) and debounce >= 1):
        raise argparse.ArgumentTypeError(usage)
    return {"filter_cutoff": cutoff, "filter_order": order, "min_duration": debounce}


def reader_options(args):
    """What ``--units-confirmed``, ``--allow-short``, ``--time-scale``,
    ``--max-joint-speed`` and ``--joints`` of ``--robot`` ask of the readers."""
    kwargs = {"accept": confirmed_kinds(args) + ["short"] * bool(getattr(args, "allow_short",
                                                                          False))}
    if getattr(args, "time_scale", None) is not None:
        kwargs["time_scale"] = args.time_scale
    if getattr(args, "max_joint_speed", None) is not None:
        kwargs["max_joint_speed"] = args.max_joint_speed
    if select_joints(args) is not None:
        kwargs["n_joints"] = args.robot.n_joints
    return kwargs


def read_recordings(paths, args, what="recordings", progress=True):
    """Load ``paths`` with ``--column-map``, ``--joints`` of ``--robot``, ``--time-scale``,
    ``--units-confirmed``, ``--allow-short`` and ``--max-joint-speed``."""
    kwargs = reader_options(args)
    shown = progress and not getattr(args, "quiet", False)
    try:
        return load_recordings(paths, column_map=getattr(args, "column_map", None),
                               progress=lambda _, total: ProgressBar(
                                   f"reading {what}", total, enabled=shown), **kwargs)
    except ValueError as exc:
        if str(exc).startswith("no recordings found"):
            raise ValueError(f"no {what} found in {' '.join(map(str, paths))}") from None
        if not any(w in str(exc) for w in ("column_map", "column map", "missing column")) \
                or "--column-map" in str(exc):
            raise
        raise ValueError(f"{exc} -- on the command line: --column-map with a JSON object, "
                         "a JSON file or a preset name") from None


#: What ``--units-confirmed`` lets through: the readers' unit checks and the
#: signal checks against the model (:func:`sklearn_gpcd.workflow.check_signals`).
CONFIRMED_KINDS = ("degrees", "units", "current", "limits", "time", "range")


def confirmed_kinds(args):
    """The kinds of implausible signal ``--units-confirmed`` accepts (none without it)."""
    return list(CONFIRMED_KINDS) * bool(getattr(args, "units_confirmed", False))


def select_joints(args):
    """``--robot`` reduced to ``--joints`` (once); None without ``--robot``."""
    # deferred: pinocchio, loaded when a robot is (gpcd starts without it)
    from ..robots import load_robot

    robot, joints = getattr(args, "robot", None), getattr(args, "joints", None)
    if robot is not None and joints is not None and not getattr(args, "_joints_done", False):
        try:
            args.robot, args._joints_done = load_robot(robot.source, joints=joints), True
        except ValueError as exc:
            raise ValueError(f"--joints: {exc}") from None
    return args.robot if robot is not None else None


def robot_for(args, recordings):
    """``--robot`` when given, else the robot named in the recordings' metadata."""
    # deferred: pinocchio, loaded when a robot is (gpcd starts without it)
    from ..robots import load_robot

    names = sorted({str(rec.metadata.get("robot") or "") for rec in recordings})
    if select_joints(args) is not None:
        named = [n for n in names if n]
        if named and named != [args.robot.name]:
            warnings.warn(f"the recordings name robot {', '.join(named)}; using --robot "
                          f"{args.robot.name} as asked", UserWarning, stacklevel=2)
        robot = args.robot
    elif "" in names or len(names) != 1:
        unnamed = [rec.name for rec in recordings if not rec.metadata.get("robot")]
        reason = (f"{unnamed[0]} does not name its robot" if unnamed else
                  f"the recordings name different robots ({', '.join(names)})")
        raise ValueError(f"--robot is required: {reason} (give a built-in name such as "
                         "ur10e, or a URDF path)")
    else:
        try:
            robot = load_robot(names[0])
        except ValueError as exc:
            raise ValueError(f"the recordings name robot {names[0]!r}, which gpcd cannot "
                             f"load ({exc}); pass --robot") from None
    for rec in recordings:
        if rec.n_joints != robot.n_joints:
            raise ValueError(f"{rec.name}: {rec.n_joints} joints but robot {robot.name} has "
                             f"{robot.n_joints}; keep the robot's joints the log has with "
                             f"--joints {rec.n_joints} (its first ones) or --joints NAME,...")
    return robot


def add_check_options(parser):
    """``--time-scale``, ``--units-confirmed``, ``--allow-short``, ``--max-joint-speed``:
    what :func:`read_recordings` checks."""
    parser.add_argument("--time-scale", type=positive_float, default=None, metavar="S",
                        help="multiply the time column by S to get seconds (1e-3 for ms)")
    parser.add_argument("--units-confirmed", action="store_true",
                        help="go on when positions look like degrees, q, qd and time units "
                        "disagree (time in ms, deg/s, q and qd swapped), or the currents or "
                        "positions disagree with what the model knows (scaled, sign-flipped, "
                        "beyond the joint limits); refused by default")
    parser.add_argument("--allow-short", action="store_true",
                        help="go on with recordings shorter than 1 s (refused by default)")
    parser.add_argument("--max-joint-speed", type=positive_float, default=None, metavar="RAD_S",
                        help="drop rows where a joint moves faster than this [rad/s] (default 10)")


def add_recording_options(parser, robot_help):
    parser.add_argument("--robot", type=robot_arg, default=None, help=robot_help)
    parser.add_argument("--joints", type=joints_arg, default=None, metavar="N|NAMES",
                        help="keep only these joints of --robot (the first N, or comma-"
                        "separated joint names), e.g. 7 for a Panda URDF with its fingers")
    add_check_options(parser)
    parser.add_argument(
        "--column-map", type=column_map_arg, default=None,
        help="column layout of text/NPZ recordings: a preset name (ur10e_mamedov), a JSON "
        "file, or a JSON object mapping fields to column indices or header names, such as "
        "'{\"time\": 0, \"q\": [1, 2, 3, 4, 5, 6], \"qd\": [7, 8, 9, 10, 11, 12], "
        "\"current\": [13, 14, 15, 16, 17, 18]}' or, with a header, '{\"time\": \"t\", "
        "\"q\": \"q\", \"qd\": \"qd\", \"current\": \"i\"}' (prefixes of q_0 .. q_5; "
        "see sklearn_gpcd.io.columns)")


def add_file_options(parser, written, read):
    """``-o`` (the ``written`` file), ``--trust-pickle`` (to load the ``read`` file
    as a pickle) and ``-q``: what the verbs that read one file and write another share."""
    parser.add_argument("-o", "--output", type=model_file_arg, required=True,
                        help=f"{written} to write (.skops, or .joblib / .pkl)")
    parser.add_argument("--trust-pickle", action="store_true",
                        help=f"load a .joblib / .pkl {read} (a pickle runs any code it "
                        "carries: only for a file from a source you trust)")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bars")


def existing_file(value):
    if not Path(value).is_file():
        raise argparse.ArgumentTypeError(f"{value}: no such file")
    return value


def file_size(path):
    """The size of the file at ``path`` in words, e.g. ``"252 MB"``.

    >>> import tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "x.bin"
    >>> _ = path.write_bytes(b"0" * 2_500_000)
    >>> file_size(path)
    '2.5 MB'
    """
    size = os.path.getsize(path)
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if size >= scale:
            return f"{size / scale:.3g} {unit}"
    return f"{size} bytes"
