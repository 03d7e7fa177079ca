"""``gpcd train``: fit P_f, SP_S, SP_P, SP_C or the GP alone on a user's recordings,
chosen by default by the thresholds its residual needs on left-out recordings (:func:`sklearn_gpcd.workflow.train_model`,
:func:`sklearn_gpcd.workflow.compare_models`, rule ``TRAIN_RULE``)."""

import argparse
import os
import time
import warnings

from ..workflow import (choose_model, input_signals, save_model, train_model,
                        training_report, training_set)
from ..workflow.model_choice import CHOICE_RULE, FEEDBACK_RULE, SIGNALS
from ..workflow.training import (
    INPUTS,
    MIN_TRAINING_SECONDS,
    MODELS,
    OPTIMIZERS,
    ROBOT_MODELS,
    TRAIN_RULE,
)
from ._args import (
    ProgressBar,
    add_recording_options,
    file_size,
    model_file_arg,
    n_support_arg,
    positive_float,
    read_recordings,
    robot_for,
)

#: The positional list that recordings left over after the options join.
RECORDINGS = "recordings"


def signals_arg(value):
    """``--signals``: auto, none, or a comma-separated list of controller signals."""
    text = value.strip().lower()
    if text in ("auto", "none"):
        return text
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    if not names or not set(names) <= set(SIGNALS) or len(set(names)) < len(names):
        raise argparse.ArgumentTypeError(
            f"expected auto, none or a comma-separated list of {', '.join(SIGNALS)}, "
            f"got {value!r}")
    return names


def add_parser(sub):
    """Register ``train`` on the ``gpcd`` subparsers ``sub``."""
    tra = sub.add_parser(
        "train",
        help="fit P_f, SP_S, SP_P, SP_C or the GP alone on your own recordings",
        description="Fit a current model on collision-free recordings and save it with the "
        "causal input features gpcd calibrate and gpcd monitor reuse, and a record of how "
        "it was trained (sklearn_gpcd.workflow.train_model). By default (--model auto) the "
        "model is chosen among those the data allow -- P_f, SP_S, SP_P need --robot, SP_C "
        "a target current that is a feed-forward -- by the detection thresholds each "
        "would need on left-out recordings, nMSE breaking near ties. "
        + CHOICE_RULE + " Target current check: " + FEEDBACK_RULE + " " + TRAIN_RULE,
    )
    tra.add_argument("recordings", nargs="+",
                     help="recordings (files, folders or glob patterns)")
    add_recording_options(tra, "built-in name or URDF path (default: the robot named in "
                          "the recordings' metadata); without one, only the models that "
                          "need no rigid-body model are fitted (sp_c, gp)")
    tra.add_argument("--model", choices=("auto",) + MODELS, default="auto",
                     help="estimator: auto (default: the smallest leave-one-recording-out "
                     "detection thresholds among those the data allow), sp_p (the paper's proposed), sp_s, "
                     "p_f (these three need --robot), sp_c (the controller's target current "
                     "as mean; recordings must log it) or gp (the GP alone, no robot model)")
    tra.add_argument("--signals", type=signals_arg, default="auto",
                     help="controller signals the inputs use: auto (default: every one the "
                     "recordings log, less a target current that follows the measured "
                     "current), none (the model then calibrates and monitors logs without "
                     "them), or a comma-separated list of target_q, target_qd, "
                     "target_current (taken as given)")
    tra.add_argument("--sigma-v", type=positive_float, default=None,
                     help="quasi-static velocity threshold [rad/s] (default 0.01 for sp_p "
                     "and gp; p_f and sp_s use the paper's unmasked friction unless given)")
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


def _robot(args, recordings):
    """``(robot or None, why none)``: ``--robot``, else the robot the recordings name."""
    # deferred: pinocchio, loaded when a robot is (gpcd starts without it)
    from ..robots import load_robot

    if args.robot is not None:
        return robot_for(args, recordings), None
    names = sorted({str(rec.metadata.get("robot") or "") for rec in recordings})
    if names == [""]:
        return None, "no --robot and the recordings name no robot"
    if "" in names or len(names) != 1:
        return None, (f"no --robot and the recordings name {', '.join(n for n in names if n)}"
                      + (" or none" if "" in names else ""))
    try:
        load_robot(names[0])
    except ValueError:
        return None, f"the recordings name robot {names[0]!r}, which gpcd cannot load"
    return robot_for(args, recordings), None


def _warn_short(recordings):
    """Warn when the training recordings last less than the recipe's 10 minutes."""
    total = sum(rec.duration for rec in recordings)
    if total < MIN_TRAINING_SECONDS:
        warnings.warn(
            f"the training recordings last {total / 60:.1f} min in all ({len(recordings)} "
            f"recording(s), the longest {max(recordings, key=lambda r: r.duration).name}); "
            f"a model needs {MIN_TRAINING_SECONDS / 60:g} min or more of varied collision-"
            "free motion (the workspace, speeds and accelerations the robot will use): "
            "record more and run gpcd train on all of them", UserWarning, stacklevel=2)


def run(args):
    """``gpcd train``: choose and fit the model on the recordings, save it with its inputs."""
    # deferred: pinocchio, loaded when a robot is (gpcd starts without it)
    from ..robots import list_robots

    start = time.perf_counter()
    quiet = args.quiet
    recordings = read_recordings(args.recordings, args, "training recordings")
    robot, no_robot = _robot(args, recordings)
    model = args.model
    if robot is None and model in ROBOT_MODELS:
        raise ValueError(f"--model {model} needs the robot's rigid-body model ({no_robot}): "
                         f"pass --robot with a built-in name ({', '.join(list_robots())}) or "
                         "a URDF path; without one use --model auto, sp_c or gp")
    signals, check = input_signals(recordings, args.signals, model)
    n_jobs = min(recordings[0].n_joints, os.cpu_count() or 1) if args.n_jobs is None else args.n_jobs
    bars = lambda label, total: ProgressBar(label, total, enabled=not quiet)  # noqa: E731
    _warn_short(recordings)  # the inputs are usable: before the fits, which take minutes
    data = training_set(recordings, args.inputs, progress=bars, signals=signals)
    notes = []  # printed before the fits, which may take minutes
    if robot is None:
        notes.append(f"no robot model ({no_robot}): fitting only the models that need none "
                     f"(SP_C, GP); P_f, SP_S and SP_P need --robot (built-in: "
                     f"{', '.join(list_robots())}, or a URDF path)")
    if check is not None:
        notes.append(check.text(sp_c_asked=model == "sp_c"))
        if not check.usable and model == "sp_c":
            notes.append("WARNING: --model sp_c asked for: its mean may absorb contacts "
                         "(--model auto leaves SP_C out)")
    for note in notes:
        print(note, flush=True)
    notes, comparison = [], None
    if model == "auto":
        model, comparison, note = choose_model(
            data, robot, check, signals=args.signals, n_support=args.n_support,
            optimizer=args.optimizer, sigma_v=args.sigma_v, seed=args.seed, n_jobs=n_jobs,
            coulomb_width=args.coulomb_width, progress=bars)
        notes += [note] if note else []
    choice_seconds = time.perf_counter() - start
    trained = train_model(
        data, robot, model, n_support=args.n_support, optimizer=args.optimizer,
        sigma_v=args.sigma_v, seed=args.seed, n_jobs=n_jobs, progress=bars,
        coulomb_width=(args.coulomb_width if args.model != "auto" or model in ROBOT_MODELS
                       else None))
    if comparison is not None:
        trained.training["model_choice"] = comparison.summary()
    if check is not None:
        trained.training["target_current_check"] = check.summary()
    fit_seconds = time.perf_counter() - start
    save_model(trained, args.output)
    for note in notes:
        print(note)
    if comparison is not None:
        print("\n".join(comparison.text()))
        print(f"  (model choice {choice_seconds:.1f} s)")
    print(training_report(trained))
    print(f"  inputs and fit {fit_seconds:.1f} s, total {time.perf_counter() - start:.1f} s; "
          f"wrote {args.output}, {file_size(args.output)} (the model, its causal input "
          "features and how it was trained)")
    return 0
