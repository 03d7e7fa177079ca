"""``gpcd diagnose``: name the physics the robot model misses in real recordings
(:class:`sklearn_gpcd.diagnosis.DynamicsDiagnosis`)."""

import time

from ._args import add_recording_options, figure_file_arg, output_file_arg, read_recordings, robot_for

#: The positional list that recordings left over after the options join.
RECORDINGS = "train"


def add_parser(sub):
    """Register ``diagnose`` on the ``gpcd`` subparsers ``sub``."""
    dia = sub.add_parser(
        "diagnose",
        help="find the physics the robot model misses in real recordings",
        description="Compare recordings (UR RTDE CSV, other CSV, NPZ, ROS bags) with the "
        "nominal model of --robot, name the missing effects (payload, friction terms, torque "
        "constants, ...) with their parameters, and show the nMSE before/after on --test. "
        "Options naming recordings take one file each and may be repeated.",
    )
    dia.add_argument("train", nargs="+", help="training recordings")
    add_recording_options(dia, "built-in name or URDF path (default: the robot named in "
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
    dia.add_argument("--json", type=output_file_arg, default=None,
                     help="write the report as JSON here")
    dia.add_argument("--plot", type=figure_file_arg, default=None,
                     help="write the figure here (PNG, PDF, ...)")
    dia.add_argument("--plan", type=output_file_arg, default=None, metavar="CSV",
                     help="write the recording to make next here: a smooth excitation (CSV "
                     "timestamp,target_q_0,...; s, rad; <= 180 s) for what these recordings "
                     "could not show; diagnose again with its recording added")
    dia.set_defaults(func=run)


def _numbers(text, what):
    """Comma-separated numbers of an option, or None."""
    if text is None:
        return None
    try:
        return [float(v) for v in text.replace(";", ",").split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"{what} must be comma-separated numbers, got {text!r}") from None


def run(args):
    """``gpcd diagnose``: fit the diagnosis on the recordings and print its report."""
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..diagnosis import DynamicsDiagnosis

    def load(paths, what):
        if not paths:
            return None
        return read_recordings(paths, args, what, progress=False)

    start = time.perf_counter()
    train, test = load(args.train, "training recordings"), load(args.test, "test recordings")
    simulated, test_simulated = (load(args.simulated, "simulated recordings"),
                                 load(args.test_simulated, "simulated test recordings"))
    robot = robot_for(args, [r for group in (train, test, simulated, test_simulated)
                             for r in (group or [])])
    torque_constants = _numbers(args.torque_constants, "--torque-constants")
    friction = None
    if args.coulomb is not None or args.viscous is not None:
        n = robot.n_joints
        friction = {"coulomb": _numbers(args.coulomb, "--coulomb") or [0.0] * n,
                    "viscous": _numbers(args.viscous, "--viscous") or [0.0] * n}
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
    if args.plan:
        plan = diagnosis.plan()
        plan.to_csv(args.plan)
        print(f"\n{plan.text()}\nwrote {args.plan}")
    print(f"done in {time.perf_counter() - start:.1f} s")
    return 0
