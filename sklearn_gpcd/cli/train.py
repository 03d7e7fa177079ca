"""``gpcd train``: fit P_f, SP_S, SP_P or SP_C on a user's recordings
(:func:`sklearn_gpcd.workflow.train_model`, rule ``TRAIN_RULE``)."""

import os
import time

from ..workflow.training import INPUTS, MODELS, OPTIMIZERS, TRAIN_RULE
from ._args import (
    ProgressBar,
    add_recording_options,
    model_file_arg,
    n_support_arg,
    positive_float,
    read_recordings,
    robot_for,
)

#: The positional list that recordings left over after the options join.
RECORDINGS = "recordings"


def add_parser(sub):
    """Register ``train`` on the ``gpcd`` subparsers ``sub``."""
    tra = sub.add_parser(
        "train",
        help="fit P_f, SP_S, SP_P or SP_C on your own recordings",
        description="Fit the paper's estimator (one GP per joint on the residual of the "
        "rigid-body + friction model) on collision-free recordings and save it with the "
        "causal input features gpcd calibrate and gpcd monitor reuse, and a record of how "
        "it was trained (sklearn_gpcd.workflow.train_model). "
        + TRAIN_RULE,
    )
    tra.add_argument("recordings", nargs="+",
                     help="recordings (files, folders or glob patterns)")
    add_recording_options(tra, "built-in name or URDF path (default: the robot named in "
                          "the recordings' metadata; required when they name none)")
    tra.add_argument("--model", choices=MODELS, default="sp_p",
                     help="estimator: sp_p (proposed, default), sp_s, p_f, or sp_c (the "
                     "controller's target current as mean; recordings must log it)")
    tra.add_argument("--sigma-v", type=positive_float, default=None,
                     help="quasi-static velocity threshold [rad/s] (default 0.01 for sp_p; "
                     "p_f and sp_s use the paper's unmasked friction unless given)")
    tra.add_argument("--coulomb-width", type=positive_float, default=None, metavar="W",
                     help="Coulomb friction column tanh(qd / W) [rad/s] instead of the "
                     "paper's sign(qd), which flips on the velocity jitter of a still "
                     "joint (p_f, sp_s, sp_p; e.g. 0.01 on a UR10e)")
    tra.add_argument("--n-support", type=n_support_arg, default="auto",
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
    tra.add_argument("-o", "--output", type=model_file_arg, required=True,
                     help="model file to write (.skops, or .joblib / .pkl)")
    tra.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    tra.set_defaults(func=run)


def run(args):
    """``gpcd train``: fit the model on the recordings and save it with its inputs."""
    import numpy as np

    from ..workflow import save_model, train_model

    start = time.perf_counter()
    quiet = args.quiet
    recordings = read_recordings(args.recordings, args, "training recordings")
    robot = robot_for(args, recordings)
    n_recordings = len(recordings)
    n_jobs = args.n_jobs if args.n_jobs is not None else min(robot.n_joints,
                                                             os.cpu_count() or 1)
    trained = train_model(
        recordings, robot, args.model, inputs=args.inputs, n_support=args.n_support,
        optimizer=args.optimizer, sigma_v=args.sigma_v, seed=args.seed, n_jobs=n_jobs,
        progress=lambda label, total: ProgressBar(label, total, enabled=not quiet),
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
