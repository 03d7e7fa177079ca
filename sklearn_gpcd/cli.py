"""The ``gpcd`` command.

Subcommands
-----------
``gpcd reproduce [--quick] -o DIR``
    The paper's experiments end to end on the built-in simulator (the main job).
``gpcd simulate --robot ROBOT --scenario NAME -o FILE.csv``
    Write a simulated recording as a UR RTDE CSV.
``gpcd robots``
    List the built-in robot models.
``gpcd diagnose TRAIN... [--test TEST...] --robot ROBOT``
    Name the physics the robot model misses in real recordings.

Every option that names a robot (``--robot``) takes a built-in name (``ur10``,
``ur10e``, ...) or the path of a URDF file. Recordings are read with
:func:`sklearn_gpcd.io.load_recording` and must have the robot's number of
joints.

Exit status: 0 on success; 2 for bad input -- a usage error (argparse), or a
recording or option the command cannot use (``ValueError``, ``OSError``, a
missing optional package). Bad input prints ONE line
``gpcd COMMAND: error: MESSAGE`` on stderr (the message names the file, and
the column and line where relevant), never a traceback. Warnings, such as a
:class:`~sklearn_gpcd.io.RecordingWarning` for dropped rows, print one line
each, ``gpcd COMMAND: warning: MESSAGE``, and the command goes on.
"""

import argparse
import sys
import time
import warnings

__all__ = ["main", "build_parser"]


def _robot_arg(value):
    """Resolve ``--robot`` at parse time so a bad name fails with usage help."""
    from .robots import load_robot

    try:
        return load_robot(value)
    except (ValueError, OSError) as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


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
    write_rtde_csv(recording, args.output)
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


def _cmd_diagnose(args):
    """``gpcd diagnose``: name the physics the robot model misses (see sklearn_gpcd.diagnosis)."""
    from .diagnosis import DynamicsDiagnosis
    from .io import load_recording

    def split(text, what):
        if text is None:
            return None
        try:
            return [float(v) for v in text.replace(";", ",").split(",") if v.strip()]
        except ValueError:
            raise ValueError(f"{what} must be comma-separated numbers, got {text!r}") from None

    def load(paths):
        if not paths:
            return None
        return [load_recording(path, n_joints=args.robot.n_joints) for path in paths]

    for option, path in (("--json", args.json), ("--plot", args.plot)):
        _check_output_path(option, path)
    torque_constants = split(args.torque_constants, "--torque-constants")
    friction = None
    if args.coulomb is not None or args.viscous is not None:
        n = args.robot.n_joints
        friction = {"coulomb": split(args.coulomb, "--coulomb") or [0.0] * n,
                    "viscous": split(args.viscous, "--viscous") or [0.0] * n}
    effects = "all" if args.effects is None else [e.strip() for e in args.effects.split(",")]
    start = time.perf_counter()
    train, test = load(args.train), load(args.test)
    diagnosis = DynamicsDiagnosis(args.robot, torque_constants=torque_constants,
                                  friction=friction, effects=effects,
                                  check_units=not args.units_confirmed)
    diagnosis.fit(train, simulated=load(args.simulated))
    report = diagnosis.report(test, load(args.test_simulated))
    print(report.text())
    if args.json:
        report.to_json(args.json)
        print(f"\nwrote {args.json}")
    if args.plot:
        report.plot(args.plot)
        print(f"wrote {args.plot}")
    print(f"done in {time.perf_counter() - start:.1f} s")
    return 0


#: Figure formats ``--plot`` accepts (by file suffix).
PLOT_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg", ".eps", ".ps", ".tif", ".tiff")


def _check_output_path(option, path):
    """Fail before any work when ``path`` cannot be written (missing folder, bad suffix)."""
    import os
    from pathlib import Path

    if path is None:
        return
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise ValueError(f"{option} {path}: is a folder, give a file name")
    if not folder.is_dir():
        raise ValueError(f"{option} {path}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise ValueError(f"{option} {path}: folder {folder} is not writable")
    if option == "--plot" and path.suffix.lower() not in PLOT_SUFFIXES:
        raise ValueError(f"{option} {path}: unknown figure format {path.suffix!r}; use one "
                         f"of {', '.join(PLOT_SUFFIXES)}")


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
    rep.add_argument("-o", "--output", default="gpcd-results", help="output folder")
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
    sim.add_argument("-o", "--output", required=True, help="CSV file to write")
    sim.set_defaults(func=_cmd_simulate)

    rob = sub.add_parser("robots", help="list the built-in robots")
    rob.set_defaults(func=_cmd_robots)

    dia = sub.add_parser(
        "diagnose",
        help="find the physics the robot model misses in real recordings",
        description="Compare recordings (UR RTDE CSV, other CSV, NPZ, ROS bags) with the "
        "nominal model of --robot, name the missing effects (payload, friction terms, torque "
        "constants, ...) with their parameters, and show the nMSE before/after on --test.",
    )
    dia.add_argument("train", nargs="+", help="training recordings")
    dia.add_argument("--robot", type=_robot_arg, default="ur10",
                     help="built-in name or URDF path")
    dia.add_argument("--torque-constants", default=None,
                     help="comma-separated Nm/A per joint (default: the robot's)")
    dia.add_argument("--coulomb", default=None,
                     help="known nominal Coulomb friction, comma-separated Nm per joint")
    dia.add_argument("--viscous", default=None,
                     help="known nominal viscous friction, comma-separated Nm s/rad per joint")
    dia.add_argument("--effects", default=None,
                     help="comma-separated effect names to test (default: all)")
    dia.add_argument("--test", nargs="+", default=None, help="held-out recordings")
    dia.add_argument("--simulated", nargs="+", default=None,
                     help="simulated runs of the training trajectories (pair mode)")
    dia.add_argument("--test-simulated", nargs="+", default=None,
                     help="simulated runs of the test trajectories (pair mode)")
    dia.add_argument("--json", default=None, help="write the report as JSON here")
    dia.add_argument("--plot", default=None, help="write the figure here (PNG, PDF, ...)")
    dia.add_argument("--units-confirmed", action="store_true",
                     help="diagnose even when positions look like degrees or time like "
                     "milliseconds (refused by default)")
    dia.set_defaults(func=_cmd_diagnose)
    return parser


def main(argv=None):
    """Entry point of the ``gpcd`` command.

    Parameters
    ----------
    argv : list of str, default=None
        Arguments without the program name; ``None`` reads ``sys.argv``.

    Returns
    -------
    status : int
        Process exit status.

    Examples
    --------
    >>> from sklearn_gpcd.cli import main
    >>> main(["robots"])  # doctest: +ELLIPSIS
    ur3 ...
    0
    """
    args = build_parser().parse_args(argv)
    prefix = f"gpcd {args.command}"
    with warnings.catch_warnings():
        warnings.showwarning = _warning_printer(prefix)
        try:
            return args.func(args)
        except (ValueError, OSError, ImportError) as exc:
            print(f"{prefix}: error: {_one_line(exc)}", file=sys.stderr)
            return 2


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
