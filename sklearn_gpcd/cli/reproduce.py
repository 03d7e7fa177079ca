"""``gpcd reproduce``, ``gpcd simulate`` and ``gpcd robots``: the built-in simulator."""

import time

from ..io import write_rtde_csv
from ._args import output_dir_arg, output_file_arg, robot_arg

#: The scenarios ``gpcd simulate --scenario`` writes.
SCENARIOS = ("d1", "d2", "joint1-cyclic", "interaction")


def add_parsers(sub):
    """Register ``reproduce``, ``simulate`` and ``robots`` on the subparsers ``sub``."""
    rep = sub.add_parser(
        "reproduce",
        help="run the paper's experiments on the built-in simulator",
        description="Simulate D1, D2, the joint-1 cyclic and the interaction tests, train "
        "P_f, SP_S and SP_P, and write DIR/report.md, figures and DIR/results.json.",
    )
    rep.add_argument("-o", "--output", type=output_dir_arg, default="gpcd-results",
                     help="output folder")
    rep.add_argument("--quick", action="store_true", help="small data sets (minutes)")
    rep.add_argument("--robot", type=robot_arg, default="ur10",
                     help="built-in name or URDF path")
    rep.add_argument("--seed", type=int, default=0, help="random seed")
    rep.add_argument("--n-jobs", type=int, default=None, help="parallel jobs (joblib)")
    rep.add_argument("-q", "--quiet", action="store_true", help="no progress output")
    rep.set_defaults(func=run_reproduce)

    sim = sub.add_parser("simulate", help="write a simulated recording as UR RTDE CSV")
    sim.add_argument("--robot", type=robot_arg, default="ur10",
                     help="built-in name or URDF path")
    sim.add_argument("--scenario", choices=SCENARIOS, default="interaction")
    sim.add_argument("--seed", type=int, default=0)
    sim.add_argument("-o", "--output", type=output_file_arg, required=True,
                     help="CSV file to write")
    sim.set_defaults(func=run_simulate)

    rob = sub.add_parser("robots", help="list the built-in robots")
    rob.set_defaults(func=run_robots)


def run_reproduce(args):
    """``gpcd reproduce``: :func:`sklearn_gpcd.experiments.reproduce`."""
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..experiments import reproduce

    reproduce(
        args.output,
        quick=args.quick,
        robot=args.robot,
        random_state=args.seed,
        n_jobs=args.n_jobs,
        verbose=not args.quiet,
    )
    return 0


def run_simulate(args):
    """``gpcd simulate``: one simulated scenario written as a UR RTDE CSV."""
    # deferred: the simulator needs pinocchio and scikit-learn
    from .. import datasets

    makers = dict(zip(SCENARIOS, (datasets.simulate_d1, datasets.simulate_d2,
                                  datasets.simulate_joint1_cyclic,
                                  datasets.simulate_interaction_test)))
    start = time.perf_counter()
    recording = makers[args.scenario](robot=args.robot, random_state=args.seed)
    write_rtde_csv(recording, args.output, robot_comment=True)  # later commands need no --robot
    print(
        f"wrote {recording.n_samples} samples ({recording.duration:.1f} s simulated) "
        f"to {args.output} in {time.perf_counter() - start:.1f} s"
    )
    return 0


def run_robots(args):
    """``gpcd robots``: the built-in robot models and their joint counts."""
    # deferred: pinocchio, loaded when a robot is (gpcd starts without it)
    from ..robots import list_robots, load_robot

    for name in list_robots():
        robot = load_robot(name)
        print(f"{name:8s} {robot.n_joints} joints")
    return 0
