"""The ``gpcd`` command.

Subcommands
-----------
``gpcd reproduce [--quick] -o DIR``
    The paper's experiments end to end on the built-in simulator (the main job).
``gpcd simulate --robot ROBOT --scenario NAME -o FILE.csv``
    Write a simulated recording as a UR RTDE CSV.
``gpcd robots``
    List the built-in robot models.
``gpcd train RECORDINGS... [--robot ROBOT] --model sp_p|sp_s|p_f|sp_c -o MODEL.skops``
    Fit the paper's estimator on a user's own recordings, on causal inputs by
    default (:func:`sklearn_gpcd.workflow.train_model`, rule ``TRAIN_RULE``).
``gpcd diagnose TRAIN... [--test TEST]... [--robot ROBOT]``
    Name the physics the robot model misses in real recordings.
``gpcd calibrate MODEL COLLISION_FREE... -o DETECTOR.skops``
    Detection thresholds chosen across recordings (:mod:`sklearn_gpcd.cli_monitor`).
``gpcd monitor DETECTOR RECORDINGS... | --replay FILE | --rtde HOST``
    Alarm events through the causal streaming path, offline or live.

Every option that names a robot (``--robot``) takes a built-in name (``ur10``,
``ur10e``, ...) or the path of a URDF file. Commands that read recordings take
the robot from the recordings' metadata when they name it (the
``ur10e_mamedov`` column preset, files written by ``gpcd simulate``), else
``--robot`` is required; ``--robot`` always wins. Recordings are read with
:func:`sklearn_gpcd.io.load_recording` (``--column-map``: a JSON object, a
JSON file or a preset name) and must have the robot's number of joints.
Options that take several recordings are repeated (``--test a.csv --test
b.csv``), so they never swallow positional arguments. Output paths
(``-o``, ``--json``, ``--plot``) are checked before any work starts.

Exit status: 0 on success; 2 for bad input -- a usage error (argparse), or a
recording or option the command cannot use (``ValueError``, ``OSError``, a
missing optional package); 130 when interrupted (Ctrl-C). Bad input prints ONE
line ``gpcd COMMAND: error: MESSAGE`` on stderr (the message names the file,
and the column and line where relevant), never a traceback; Ctrl-C prints one
line ``gpcd COMMAND: interrupted``. Warnings, such as a
:class:`~sklearn_gpcd.io.RecordingWarning` for dropped rows, print one line
each, ``gpcd COMMAND: warning: MESSAGE``, and the command goes on. Progress
bars (with an ETA) go to stderr.
"""

import argparse
import contextlib
import json
import math
import os
import sys
import time
import warnings
from pathlib import Path

from .cli_monitor import add_commands as add_monitor_commands
from .workflow import INPUTS, MAX_TRAIN_ROWS, MODELS, OPTIMIZERS, TRAIN_RULE  # noqa: F401
from .workflow import training_rows as _training_rows  # noqa: F401

__all__ = ["main", "build_parser", "parse_args"]


# ---------------------------------------------------------------- arguments
def _robot_arg(value):
    """Resolve ``--robot`` at parse time so a bad name fails with usage help."""
    from .robots import load_robot

    try:
        with _quiet_c_stderr():  # urdfdom prints parse errors on fd 2 itself
            return load_robot(value)
    except (ValueError, OSError) as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


@contextlib.contextmanager
def _quiet_c_stderr():
    """Send what C/C++ libraries write on file descriptor 2 to /dev/null.

    Python's own ``sys.stderr`` is flushed first and restored after, so
    only third-party noise (e.g. urdfdom's parser messages) is dropped; the
    command reports errors itself.
    """
    try:
        fd = sys.__stderr__.fileno() if sys.__stderr__ is not None else 2
        saved = os.dup(fd)
    except (OSError, ValueError, AttributeError):
        yield  # no real stderr (embedded interpreter): nothing to silence
        return
    with contextlib.suppress(Exception):
        sys.stderr.flush()
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, fd)
        yield
    finally:
        os.dup2(saved, fd)
        os.close(saved)
        os.close(devnull)


def _column_map_arg(value):
    """``--column-map``: a preset name, a JSON file or a JSON object."""
    from .io import COLUMN_PRESETS

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


def _output_file_arg(value):
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


def _figure_file_arg(value):
    """An output figure path: writable as :func:`_output_file_arg`, known format."""
    value = _output_file_arg(value)
    if Path(value).suffix.lower() not in PLOT_SUFFIXES:
        raise argparse.ArgumentTypeError(
            f"{value}: unknown figure format {Path(value).suffix!r}; use one of "
            f"{', '.join(PLOT_SUFFIXES)}")
    return value


def _output_dir_arg(value):
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


def _model_file_arg(value):
    """``-o`` of ``gpcd train``: a writable ``.skops``, ``.joblib`` or ``.pkl`` file."""
    from .persistence import PICKLE_EXTENSIONS, SKOPS_EXTENSION

    suffixes = (SKOPS_EXTENSION,) + tuple(PICKLE_EXTENSIONS)
    if Path(value).suffix.lower() not in suffixes:
        raise argparse.ArgumentTypeError(
            f"{value}: the extension chooses the format; use one of {', '.join(suffixes)}")
    return _output_file_arg(value)


def _positive_int(value):
    try:
        number = int(value)
    except ValueError:
        number = 0
    if number < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {value!r}")
    return number


def _positive_float(value):
    try:
        number = float(value)
    except ValueError:
        number = float("nan")
    if not number > 0 or not math.isfinite(number):
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {value!r}")
    return number


def _n_support_arg(value):
    return "auto" if value.strip().lower() == "auto" else _positive_int(value)


# ---------------------------------------------------------------- progress
class _Progress:
    """A progress bar with an ETA on stderr.

    On a terminal the bar is redrawn in place; otherwise (a log, a pipe) one
    line is printed at most every ``interval`` seconds and at the end.
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
            tail = f"done in {_seconds(elapsed)}"
        elif self.done:
            tail = f"{_seconds(elapsed)} elapsed, ETA {_seconds(elapsed * (self.total / self.done - 1))}"
        else:
            tail = "ETA after the first step"
        line = f"{self.label} [{'#' * filled}{'.' * (width - filled)}] {self.done}/{self.total} {tail}"
        end = "\n" if (not self._tty or self.done == self.total) else ""
        print(("\r" if self._tty else "") + line, end=end, file=self.stream, flush=True)


def _seconds(value):
    value = int(round(value))
    return f"{value // 60}m{value % 60:02d}s" if value >= 60 else f"{value}s"


# ---------------------------------------------------------------- recordings
def _read_recordings(paths, args, what="recordings", progress=True):
    """Load ``paths`` with ``--column-map`` (and ``n_joints`` of ``--robot`` when given)."""
    from .io import load_recording
    from .io.load import recording_paths

    sources = recording_paths(paths)
    if not sources:
        raise ValueError(f"no {what} found in {' '.join(map(str, paths))}")
    kwargs = {}
    if getattr(args, "robot", None) is not None:
        kwargs["n_joints"] = args.robot.n_joints
    bar = _Progress(f"reading {what}", len(sources),
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


def _robot_for(args, recordings):
    """``--robot`` when given, else the robot named in the recordings' metadata."""
    from .robots import load_robot

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
            with _quiet_c_stderr():
                robot = load_robot(names[0])
        except ValueError as exc:
            raise ValueError(f"the recordings name robot {names[0]!r}, which gpcd cannot "
                             f"load ({exc}); pass --robot") from None
    for rec in recordings:
        if rec.n_joints != robot.n_joints:
            raise ValueError(f"{rec.name}: {rec.n_joints} joints but robot {robot.name} has "
                             f"{robot.n_joints}")
    return robot


# ---------------------------------------------------------------- commands
def _cmd_reproduce(args):
    from .experiments import reproduce

    reproduce(
        args.output,
        quick=args.quick,
        robot=args.robot,
        random_state=args.seed,
        n_jobs=args.n_jobs,
        verbose=not args.quiet,
    )
    return 0


def _cmd_simulate(args):
    from . import datasets
    from .io import write_rtde_csv

    makers = {
        "d1": datasets.make_d1,
        "d2": datasets.make_d2,
        "joint1-cyclic": datasets.make_joint1_cyclic,
        "interaction": datasets.make_interaction_test,
    }
    start = time.perf_counter()
    recording = makers[args.scenario](robot=args.robot, random_state=args.seed)
    write_rtde_csv(recording, args.output, robot_comment=True)  # later commands need no --robot
    print(
        f"wrote {recording.n_samples} samples ({recording.duration:.1f} s simulated) "
        f"to {args.output} in {time.perf_counter() - start:.1f} s"
    )
    return 0


def _cmd_robots(args):
    from .robots import list_robots, load_robot

    for name in list_robots():
        robot = load_robot(name)
        print(f"{name:8s} {robot.n_joints} joints")
    return 0


def _cmd_train(args):
    """``gpcd train``: fit P_f, SP_S, SP_P or SP_C on recordings and save it with its inputs."""
    import numpy as np

    from .workflow import save_model, train_model

    start = time.perf_counter()
    quiet = args.quiet
    recordings = _read_recordings(args.recordings, args, "training recordings")
    robot = _robot_for(args, recordings)
    n_recordings = len(recordings)
    n_jobs = args.n_jobs if args.n_jobs is not None else min(robot.n_joints,
                                                             os.cpu_count() or 1)
    trained = train_model(
        recordings, robot, args.model, inputs=args.inputs, n_support=args.n_support,
        optimizer=args.optimizer, sigma_v=args.sigma_v, seed=args.seed, n_jobs=n_jobs,
        progress=lambda label, total: _Progress(label, total, enabled=not quiet),
        coulomb_width=args.coulomb_width)
    fit_seconds = time.perf_counter() - start
    save_model(trained, args.output)
    model, info = trained.regressor, trained.training
    print(f"trained {args.model.upper()} for robot {robot.name} ({robot.n_joints} joints) on "
          f"{n_recordings} recording(s), {info['n_rows']} rows, {info['inputs']} inputs"
          + (f" (1 row in {info['step']} used: {info['n_rows_used']})"
             if info["step"] > 1 else ""))
    print(f"  GP support {info['n_support']} rows per joint, optimizer {model.optimizer_}, "
          f"iterations per joint {np.atleast_1d(model.n_iter_).tolist()}, "
          f"sigma_v {info['sigma_v'] if info['sigma_v'] is not None else '-'}, "
          + (f"Coulomb tanh(qd / {info['coulomb_width']:g}), "
             if info.get("coulomb_width") is not None else "")
          + f"seed {info['seed']}, controller signals {', '.join(info['signals']) or 'none'}")
    lml = np.atleast_1d(model.log_marginal_likelihood_value_)
    print("  log marginal likelihood per joint: " + ", ".join(f"{v:.4g}" for v in lml))
    print(f"  largest |qdd| of the training rows {info['acceleration_limit']:.3g} rad/s^2 "
          "(the braking limit of gpcd calibrate --braking)")
    print(f"  inputs and fit {fit_seconds:.1f} s, total {time.perf_counter() - start:.1f} s; "
          f"wrote {args.output} (the model, its causal input features and how it was "
          "trained)")
    return 0


def _cmd_diagnose(args):
    """``gpcd diagnose``: name the physics the robot model misses (see sklearn_gpcd.diagnosis)."""
    from .diagnosis import DynamicsDiagnosis

    def split(text, what):
        if text is None:
            return None
        try:
            return [float(v) for v in text.replace(";", ",").split(",") if v.strip()]
        except ValueError:
            raise ValueError(f"{what} must be comma-separated numbers, got {text!r}") from None

    def load(paths, what):
        if not paths:
            return None
        return _read_recordings(paths, args, what, progress=False)

    start = time.perf_counter()
    train, test = load(args.train, "training recordings"), load(args.test, "test recordings")
    simulated, test_simulated = (load(args.simulated, "simulated recordings"),
                                 load(args.test_simulated, "simulated test recordings"))
    robot = _robot_for(args, [r for group in (train, test, simulated, test_simulated)
                              for r in (group or [])])
    torque_constants = split(args.torque_constants, "--torque-constants")
    friction = None
    if args.coulomb is not None or args.viscous is not None:
        n = robot.n_joints
        friction = {"coulomb": split(args.coulomb, "--coulomb") or [0.0] * n,
                    "viscous": split(args.viscous, "--viscous") or [0.0] * n}
    effects = "all" if args.effects is None else [e.strip() for e in args.effects.split(",")]
    diagnosis = DynamicsDiagnosis(robot, torque_constants=torque_constants,
                                  friction=friction, effects=effects,
                                  check_units=not args.units_confirmed)
    diagnosis.fit(train, simulated=simulated)
    report = diagnosis.report(test, test_simulated)
    print(f"robot: {robot.name}")
    print(report.text())
    if args.json:
        report.to_json(args.json)
        print(f"\nwrote {args.json}")
    if args.plot:
        report.plot(args.plot)
        print(f"wrote {args.plot}")
    print(f"done in {time.perf_counter() - start:.1f} s")
    return 0


# ---------------------------------------------------------------- parser
def _add_recording_options(parser, robot_help):
    parser.add_argument("--robot", type=_robot_arg, default=None, help=robot_help)
    parser.add_argument(
        "--column-map", type=_column_map_arg, default=None,
        help="column layout of text/NPZ recordings: a preset name (ur10e_mamedov), a JSON "
        "file, or a JSON object mapping fields to column indices or header names, such as "
        "'{\"time\": 0, \"q\": [1, 2, 3, 4, 5, 6], \"qd\": [7, 8, 9, 10, 11, 12], "
        "\"current\": [13, 14, 15, 16, 17, 18]}' or, with a header, '{\"time\": \"t\", "
        "\"q\": \"q\", \"qd\": \"qd\", \"current\": \"i\"}' (prefixes of q_0 .. q_5; "
        "see sklearn_gpcd.io.columns)")


def build_parser():
    """The argument parser of the ``gpcd`` command.

    Returns
    -------
    parser : argparse.ArgumentParser

    Examples
    --------
    >>> from sklearn_gpcd.cli import build_parser
    >>> args = build_parser().parse_args(["reproduce", "--quick", "-o", "out"])
    >>> args.quick, args.output
    (True, 'out')
    >>> args = build_parser().parse_args(["diagnose", "--test", "held.csv", "train.csv"])
    >>> args.train, args.test
    (['train.csv'], ['held.csv'])
    """
    parser = argparse.ArgumentParser(
        prog="gpcd",
        description="Proprioceptive collision detection with Gaussian Processes.",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    rep = sub.add_parser(
        "reproduce",
        help="run the paper's experiments on the built-in simulator",
        description="Simulate D1, D2, the joint-1 cyclic and the interaction tests, train "
        "P_f, SP_S and SP_P, and write DIR/report.md, figures and DIR/results.json.",
    )
    rep.add_argument("-o", "--output", type=_output_dir_arg, default="gpcd-results",
                     help="output folder")
    rep.add_argument("--quick", action="store_true", help="small data sets (minutes)")
    rep.add_argument("--robot", type=_robot_arg, default="ur10",
                     help="built-in name or URDF path")
    rep.add_argument("--seed", type=int, default=0, help="random seed")
    rep.add_argument("--n-jobs", type=int, default=None, help="parallel jobs (joblib)")
    rep.add_argument("-q", "--quiet", action="store_true", help="no progress output")
    rep.set_defaults(func=_cmd_reproduce)

    sim = sub.add_parser("simulate", help="write a simulated recording as UR RTDE CSV")
    sim.add_argument("--robot", type=_robot_arg, default="ur10",
                     help="built-in name or URDF path")
    sim.add_argument(
        "--scenario",
        choices=["d1", "d2", "joint1-cyclic", "interaction"],
        default="interaction",
    )
    sim.add_argument("--seed", type=int, default=0)
    sim.add_argument("-o", "--output", type=_output_file_arg, required=True,
                     help="CSV file to write")
    sim.set_defaults(func=_cmd_simulate)

    rob = sub.add_parser("robots", help="list the built-in robots")
    rob.set_defaults(func=_cmd_robots)

    tra = sub.add_parser(
        "train",
        help="fit P_f, SP_S, SP_P or SP_C on your own recordings",
        description="Fit the paper's estimator (one GP per joint on the residual of the "
        "rigid-body + friction model) on collision-free recordings and save it with the "
        "causal input features gpcd calibrate and gpcd monitor reuse, and a record of how "
        "it was trained (sklearn_gpcd.workflow.train_model, the function "
        "benchmarks/real_ur10e.py trains with). "
        + TRAIN_RULE,
    )
    tra.add_argument("recordings", nargs="+",
                     help="recordings (files, folders or glob patterns)")
    _add_recording_options(tra, "built-in name or URDF path (default: the robot named in "
                           "the recordings' metadata; required when they name none)")
    tra.add_argument("--model", choices=MODELS, default="sp_p",
                     help="estimator: sp_p (proposed, default), sp_s, p_f, or sp_c (the "
                     "controller's target current as mean; recordings must log it)")
    tra.add_argument("--sigma-v", type=_positive_float, default=None,
                     help="quasi-static velocity threshold [rad/s] (default 0.01 for sp_p; "
                     "p_f and sp_s use the paper's unmasked friction unless given)")
    tra.add_argument("--coulomb-width", type=_positive_float, default=None, metavar="W",
                     help="Coulomb friction column tanh(qd / W) [rad/s] instead of the "
                     "paper's sign(qd), which flips on the velocity jitter of a still "
                     "joint (p_f, sp_s, sp_p; e.g. 0.01 on a UR10e)")
    tra.add_argument("--n-support", type=_n_support_arg, default="auto",
                     help="GP support rows per joint (default auto: at most 2000)")
    tra.add_argument("--inputs", choices=INPUTS, default=INPUTS[0],
                     help="GP inputs to fit on: causal (default; what the robot computes "
                     "sample by sample, on which gpcd calibrate and gpcd monitor run the "
                     "model) or zero-phase (the paper's offline derivatives)")
    tra.add_argument("--optimizer", choices=OPTIMIZERS, default="auto",
                     help="hyperparameter optimizer (default auto: the rule above)")
    tra.add_argument("--seed", type=int, default=0,
                     help="random seed (support rows, Adam minibatches)")
    tra.add_argument("--n-jobs", type=int, default=None,
                     help="joints fitted in parallel (default: one per core, at most one "
                     "per joint; 1 uses the least memory)")
    tra.add_argument("-o", "--output", type=_model_file_arg, required=True,
                     help="model file to write (.skops, or .joblib / .pkl)")
    tra.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    tra.set_defaults(func=_cmd_train)

    dia = sub.add_parser(
        "diagnose",
        help="find the physics the robot model misses in real recordings",
        description="Compare recordings (UR RTDE CSV, other CSV, NPZ, ROS bags) with the "
        "nominal model of --robot, name the missing effects (payload, friction terms, torque "
        "constants, ...) with their parameters, and show the nMSE before/after on --test. "
        "Options naming recordings take one file each and may be repeated.",
    )
    dia.add_argument("train", nargs="+", help="training recordings")
    _add_recording_options(dia, "built-in name or URDF path (default: the robot named in "
                           "the recordings' metadata; required when they name none)")
    dia.add_argument("--torque-constants", default=None,
                     help="comma-separated Nm/A per joint (default: the robot's)")
    dia.add_argument("--coulomb", default=None,
                     help="known nominal Coulomb friction, comma-separated Nm per joint")
    dia.add_argument("--viscous", default=None,
                     help="known nominal viscous friction, comma-separated Nm s/rad per joint")
    dia.add_argument("--effects", default=None,
                     help="comma-separated effect names to test (default: all)")
    dia.add_argument("--test", action="append", default=None, metavar="FILE",
                     help="held-out recording (repeat for several)")
    dia.add_argument("--simulated", action="append", default=None, metavar="FILE",
                     help="simulated run of a training trajectory (pair mode; repeat)")
    dia.add_argument("--test-simulated", action="append", default=None, metavar="FILE",
                     help="simulated run of a test trajectory (pair mode; repeat)")
    dia.add_argument("--json", type=_output_file_arg, default=None,
                     help="write the report as JSON here")
    dia.add_argument("--plot", type=_figure_file_arg, default=None,
                     help="write the figure here (PNG, PDF, ...)")
    dia.add_argument("--units-confirmed", action="store_true",
                     help="diagnose even when positions look like degrees or time like "
                     "milliseconds (refused by default)")
    dia.set_defaults(func=_cmd_diagnose)
    add_monitor_commands(sub)  # calibrate, monitor (sklearn_gpcd.cli_monitor)
    return parser


#: Subcommand -> its positional list of recordings (arguments left over after
#: the options, e.g. ``a.csv --test h.csv b.csv``, belong to it).
_RECORDING_POSITIONALS = {"train": "recordings", "diagnose": "train"}


def parse_args(argv=None):
    """Parse ``gpcd`` arguments; recordings may come before, between or after options.

    argparse takes one contiguous run of positionals, so ``gpcd diagnose a.csv
    --test h.csv b.csv`` would leave ``b.csv`` unrecognised; here such
    leftovers join the subcommand's list of recordings. Anything else left
    over is a usage error.

    Parameters
    ----------
    argv : list of str, default=None
        Arguments without the program name; ``None`` reads ``sys.argv``.

    Returns
    -------
    args : argparse.Namespace

    Examples
    --------
    >>> args = parse_args(["diagnose", "a.csv", "--test", "h.csv", "b.csv"])
    >>> args.train, args.test
    (['a.csv', 'b.csv'], ['h.csv'])
    """
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    dest = _RECORDING_POSITIONALS.get(args.command)
    if extra and dest is not None and not any(a.startswith("-") for a in extra):
        getattr(args, dest).extend(extra)
    elif extra:
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    return args


def main(argv=None):
    """Entry point of the ``gpcd`` command.

    Parameters
    ----------
    argv : list of str, default=None
        Arguments without the program name; ``None`` reads ``sys.argv``.

    Returns
    -------
    status : int
        Process exit status (130 after Ctrl-C).

    Examples
    --------
    >>> from sklearn_gpcd.cli import main
    >>> main(["robots"])  # doctest: +ELLIPSIS
    ur3 ...
    0
    """
    prefix = "gpcd"
    try:
        try:
            args = parse_args(argv)
        except SystemExit as exc:  # usage error or --help: argparse printed why
            return exc.code if isinstance(exc.code, int) else 2
        prefix = f"gpcd {args.command}"
        with warnings.catch_warnings():
            warnings.showwarning = _warning_printer(prefix)
            try:
                return args.func(args)
            except (ValueError, OSError, ImportError) as exc:
                print(f"{prefix}: error: {_one_line(exc)}", file=sys.stderr)
                return 2
    except KeyboardInterrupt:
        fresh_line = "\n" if getattr(sys.stderr, "isatty", lambda: False)() else ""
        print(f"{fresh_line}{prefix}: interrupted", file=sys.stderr)  # after a bar's \r
        return 130


def _one_line(message):
    """``message`` as one line: runs of whitespace, newlines included, become a space.

    Parameters
    ----------
    message : object
        An exception or warning message.

    Returns
    -------
    text : str

    Examples
    --------
    >>> _one_line(ValueError("a.csv: bad\\n  line 3"))
    'a.csv: bad line 3'
    """
    return " ".join(str(message).split())


def _warning_printer(prefix):
    """A :func:`warnings.showwarning` that prints ``PREFIX: warning: MESSAGE``."""

    def show(message, category, filename, lineno, file=None, line=None):
        print(f"{prefix}: warning: {_one_line(message)}", file=sys.stderr if file is None
              else file)

    return show


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
