"""What the ``gpcd`` verbs share: argument types checked at parse time, the
progress bar, reading recordings and resolving the robot."""

import argparse
import json
import math
import os
import sys
import time
import warnings
from pathlib import Path


# ---------------------------------------------------------------- arguments
def robot_arg(value):
    """Resolve ``--robot`` at parse time so a bad name fails with usage help."""
    from ..robots import load_robot

    try:
        return load_robot(value)
    except (ValueError, OSError) as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def column_map_arg(value):
    """``--column-map``: a preset name, a JSON file or a JSON object."""
    from ..io import COLUMN_PRESETS

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
    from ..persistence import PICKLE_EXTENSIONS, SKOPS_EXTENSION

    suffixes = (SKOPS_EXTENSION,) + tuple(PICKLE_EXTENSIONS)
    if Path(value).suffix.lower() not in suffixes:
        raise argparse.ArgumentTypeError(
            f"{value}: the extension chooses the format; use one of {', '.join(suffixes)}")
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


# ---------------------------------------------------------------- progress
class ProgressBar:
    """A progress bar with an ETA on stderr.

    On a terminal the bar is redrawn in place; otherwise (a log, a pipe) one
    line is printed at most every ``interval`` seconds and at the end.

    Kept instead of tqdm (issue #34): written to a file that is not a
    terminal (``gpcd train ... 2> train.log``, CI), tqdm either prints
    nothing (``disable=None``) or joins every update with carriage returns
    into one line (``disable=False``), while a log needs one readable line
    per update.
    """

    def __init__(self, label, total, *, stream=None, interval=5.0, enabled=True):
        self.label, self.total, self.done = label, max(int(total), 1), 0
        self.stream = sys.stderr if stream is None else stream
        self.interval, self.enabled = interval, enabled
        self.start = self._last = time.perf_counter()
        self._tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._draw(force=True)

    def update(self, n=1):
        self.done = min(self.done + n, self.total)
        self._draw(force=self.done == self.total)

    def _draw(self, force=False):
        if not self.enabled:
            return
        now = time.perf_counter()
        if not (force or self._tty or now - self._last >= self.interval):
            return
        self._last = now
        elapsed = now - self.start
        width = 24
        filled = int(width * self.done / self.total)
        if self.done == self.total:
            tail = f"done in {seconds(elapsed)}"
        elif self.done:
            tail = f"{seconds(elapsed)} elapsed, ETA {seconds(elapsed * (self.total / self.done - 1))}"
        else:
            tail = "ETA after the first step"
        line = f"{self.label} [{'#' * filled}{'.' * (width - filled)}] {self.done}/{self.total} {tail}"
        end = "\n" if (not self._tty or self.done == self.total) else ""
        print(("\r" if self._tty else "") + line, end=end, file=self.stream, flush=True)


def seconds(value):
    value = int(round(value))
    return f"{value // 60}m{value % 60:02d}s" if value >= 60 else f"{value}s"


# ---------------------------------------------------------------- recordings
def read_recordings(paths, args, what="recordings", progress=True):
    """Load ``paths`` with ``--column-map`` (and ``n_joints`` of ``--robot`` when given)."""
    from ..io import load_recording
    from ..io.load import recording_paths

    sources = recording_paths(paths)
    if not sources:
        raise ValueError(f"no {what} found in {' '.join(map(str, paths))}")
    kwargs = {}
    if getattr(args, "robot", None) is not None:
        kwargs["n_joints"] = args.robot.n_joints
    bar = ProgressBar(f"reading {what}", len(sources),
                    enabled=progress and not getattr(args, "quiet", False))
    recordings = []
    for path in sources:
        try:
            rec = load_recording(path, column_map=getattr(args, "column_map", None), **kwargs)
        except ValueError as exc:
            if "column_map" not in str(exc):
                raise
            raise ValueError(f"{exc} -- on the command line: --column-map with a JSON object, "
                             "a JSON file or a preset name") from None
        recordings.append(rec)
        bar.update()
    return recordings


def robot_for(args, recordings):
    """``--robot`` when given, else the robot named in the recordings' metadata."""
    from ..robots import load_robot

    names = sorted({str(rec.metadata.get("robot") or "") for rec in recordings})
    if args.robot is not None:
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
                             f"{robot.n_joints}")
    return robot



def add_recording_options(parser, robot_help):
    parser.add_argument("--robot", type=robot_arg, default=None, help=robot_help)
    parser.add_argument(
        "--column-map", type=column_map_arg, default=None,
        help="column layout of text/NPZ recordings: a preset name (ur10e_mamedov), a JSON "
        "file, or a JSON object mapping fields to column indices or header names, such as "
        "'{\"time\": 0, \"q\": [1, 2, 3, 4, 5, 6], \"qd\": [7, 8, 9, 10, 11, 12], "
        "\"current\": [13, 14, 15, 16, 17, 18]}' or, with a header, '{\"time\": \"t\", "
        "\"q\": \"q\", \"qd\": \"qd\", \"current\": \"i\"}' (prefixes of q_0 .. q_5; "
        "see sklearn_gpcd.io.columns)")




def existing_file(value):
    if not Path(value).is_file():
        raise argparse.ArgumentTypeError(f"{value}: no such file")
    return value
