"""``gpcd train`` without a robot model, ``--model auto`` and the target-current check
(issue #38, points 4 and 5)."""

import json

import numpy as np
import pytest

from sklearn_gpcd.cli import main
from sklearn_gpcd.datasets import Contact, JointTrajectory, reference_d1, simulate
from sklearn_gpcd.io import load_recording, write_rtde_csv
from sklearn_gpcd.workflow import check_target_current, load_detector, load_model

ROBOT = "ur10"
#: (start as a fraction of the motion or seconds into the final rest, peak joint-1 torque
#: [Nm]): two pushes while the arm moves, two while it rests.
PUSHES = (("moving", 0.3, 120.0), ("moving", 0.7, -120.0), ("rest", 2.0, 60.0),
          ("rest", 4.0, -60.0))


def _task(seed):
    """A D1 motion (4 random targets) and 6 s of rest: ``(reference, motion seconds)``."""
    moves = reference_d1(ROBOT, n_targets=4, random_state=seed)
    rest = JointTrajectory.rest(moves.at(moves.duration), 6.0)
    return JointTrajectory.concatenate([moves, rest]), moves.duration


def _push(start, torque, lever=0.2, duration=0.8):
    """A horizontal push on link 1 at ``lever`` from the base axis: joint 1 feels ``torque``."""
    return Contact(link=1, start=start, duration=duration, force=[0.0, torque / lever, 0.0],
                   point=[lever, 0.0, 0.0], frame="local")


def _logs(folder, target_current):
    """Anonymous logs (no robot named) of a simulated UR10 whose controller logs
    ``target_current``: two training runs of other motions, three collision-free
    repetitions of the task, and the task with four pushes."""
    folder.mkdir()
    paths = {"train": [], "calibrate": []}

    def write(rec, name):
        return write_rtde_csv(rec.replace(metadata={}), folder / f"{name}.csv")

    for seed in (0, 1):
        rec = simulate(_task(seed)[0], ROBOT, random_state=seed, target_current=target_current)
        paths["train"].append(write(rec, f"train{seed}"))
    task, moving = _task(5)
    for k in range(3):
        rec = simulate(task, ROBOT, random_state=100 + k, target_current=target_current)
        paths["calibrate"].append(write(rec, f"free{k}"))
    contacts = [_push(f * moving if phase == "moving" else moving + f, torque)
                for phase, f, torque in PUSHES]
    pushes = simulate(task, ROBOT, contacts=contacts, random_state=7,
                      target_current=target_current)
    paths["push"], paths["contacts"] = write(pushes, "pushes"), contacts
    return paths


@pytest.fixture(scope="module")
def feedforward(tmp_path_factory):
    """Logs of a controller that logs its feed-forward as the target current (as a UR)."""
    return _logs(tmp_path_factory.mktemp("train_auto") / "feedforward", "feedforward")


def test_train_without_robot_chooses_among_sp_c_and_gp_and_detects_every_push(
        feedforward, tmp_path, capsys):
    """No --robot anywhere: train (auto) / calibrate / monitor end to end; the models that
    need a rigid-body model are named as such, the choice is printed, every push alarms
    while it acts, and the collision-free motion before the first push raises none."""
    model, detector, events = (tmp_path / "model.skops", tmp_path / "detector.skops",
                               tmp_path / "events.json")
    assert main(["train", *map(str, feedforward["train"]), "--n-support", "60", "-q",
                 "-o", str(model)]) == 0
    out = capsys.readouterr().out
    assert "no robot model" in out and "P_f, SP_S and SP_P need --robot" in out
    assert "target current: a feed-forward" in out
    assert "model choice (--model auto), leave-one-recording-out over 2 fold(s)" in out
    for name in ("SP_P", "SP_S", "P_f"):
        assert f"{name:<5}  not compared: needs the robot model (--robot)" in out
    trained = load_model(model)
    choice = trained.training["model_choice"]
    assert choice["models"] == ["sp_c", "gp"] and trained.training["model"] == choice["best"]
    assert trained.training["robot"] is None
    assert f"trained {choice['best'].upper()} without a robot model" in out
    assert trained.training["target_current_check"]["follows"] is False

    assert main(["calibrate", str(model), *map(str, feedforward["calibrate"]), "-q",
                 "-o", str(detector)]) == 0
    # each regime's thresholds are at least the chosen model's level on its left-out runs
    calibrated = load_detector(detector)
    level = choice["thresholds"][choice["models"].index(choice["best"])]
    floor = calibrated.calibration["training_floor_A"]
    assert floor["moving"] == pytest.approx(level)
    assert set(floor) <= set(calibrated.calibration["regimes"])
    names, thresholds = (calibrated.calibration["regimes"],
                         np.atleast_2d(calibrated.detector.thresholds_))
    for name, row in floor.items():
        assert np.all(thresholds[names.index(name)] >= np.asarray(row) * (1 - 1e-12))
    assert main(["monitor", str(detector), str(feedforward["push"]), "-q",
                 "--json", str(events)]) == 0
    found = json.loads(events.read_text())["events"]
    starts = [e["start_s"] for e in found]
    # every push alarms while it acts: an event opens in it, or (one event per
    # contact: it ends only after 0.2 s below half the threshold) the event of
    # the push before, whose tail stays above that, alarms again during it
    for contact in feedforward["contacts"]:
        assert any(e["start_s"] <= contact.start + contact.duration
                   and e["end_s"] >= contact.start for e in found), (contact.start, found)
    assert len(found) >= len(feedforward["contacts"]) - 1
    first = min(c.start for c in feedforward["contacts"])
    assert min(starts) >= first  # no alarm on the collision-free motion before the pushes


def test_models_that_need_a_robot_name_the_flag(feedforward, tmp_path, capsys):
    for model in ("p_f", "sp_s", "sp_p"):
        assert main(["train", *map(str, feedforward["train"]), "--model", model, "-q",
                     "-o", str(tmp_path / "m.skops")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and f"--model {model} needs the robot" in err[0]
        assert "pass --robot" in err[0] and "ur10e" in err[0]  # the known robots


def test_signals_none_trains_a_model_for_logs_without_the_controller_signals(
        feedforward, tmp_path, capsys):
    """A model trained with the target current refuses logs without it and names the
    command that fixes it; --signals none trains one that calibrates on them."""
    bare = []
    for k, path in enumerate(feedforward["calibrate"]):
        rec = load_recording(path).replace(target_q=None, target_qd=None, target_current=None)
        bare.append(write_rtde_csv(rec, tmp_path / f"bare{k}.csv"))
    with_signals = tmp_path / "gp.skops"
    assert main(["train", *map(str, feedforward["train"]), "--model", "gp", "--n-support",
                 "40", "-q", "-o", str(with_signals)]) == 0
    capsys.readouterr()
    assert main(["calibrate", str(with_signals), *map(str, bare), "-q",
                 "-o", str(tmp_path / "d.skops")]) == 2
    err = capsys.readouterr().err
    assert "gpcd train ... --signals none" in err and "allow_missing" not in err
    detector = tmp_path / "d_signals.skops"  # calibrated on logs with the signals
    assert main(["calibrate", str(with_signals), *map(str, feedforward["calibrate"]), "-q",
                 "-o", str(detector)]) == 0
    assert main(["monitor", str(detector), str(bare[0]), "-q"]) == 2
    err = capsys.readouterr().err
    assert "gpcd train ... --signals none" in err and "allow_missing" not in err
    without = tmp_path / "gp_none.skops"
    assert main(["train", *map(str, feedforward["train"]), "--model", "gp", "--signals",
                 "none", "--n-support", "40", "-q", "-o", str(without)]) == 0
    assert "controller signals none" in capsys.readouterr().out
    assert load_model(without).training["signals"] == []
    assert main(["calibrate", str(without), *map(str, bare), "-q",
                 "-o", str(tmp_path / "d_none.skops")]) == 0
    # SP_C cannot do without its target current, and says which flag is in the way
    assert main(["train", *map(str, feedforward["train"]), "--model", "sp_c", "--signals",
                 "none", "-q", "-o", str(tmp_path / "c.skops")]) == 2
    assert "--signals" in capsys.readouterr().err


def test_a_target_current_that_includes_the_feedback_is_detected_and_reported(
        tmp_path, capsys):
    """The package simulator's default target current is the servo's full command: the
    measured current follows it, pushes included, so the check must refuse it as a mean
    (SP_C is not compared, the inputs leave it out) and say so; the same controller
    logging its feed-forward passes."""
    push = _push(1.0, 60.0)
    still = JointTrajectory.rest([0.0, -1.57, 1.57, -1.57, -1.57, 0.0], 2.5)
    contact = {}
    for kind in ("command", "feedforward"):
        rec = simulate(still, ROBOT, contacts=[push], random_state=1, target_current=kind)
        during = (rec.time >= push.start + 0.2) & (rec.time <= push.start + 0.6)
        contact[kind] = np.abs(rec.current - rec.target_current)[during, 0].max()
    # the premise: a push shows in i - i_target only when the target is a feed-forward
    assert contact["command"] < 0.2 < 2.0 < contact["feedforward"]

    paths = []
    for seed in (0, 1):
        rec = simulate(_task(seed)[0], ROBOT, random_state=seed)  # target_current="command"
        assert rec.metadata["target_current"] == "command"
        paths.append(write_rtde_csv(rec.replace(metadata={}), tmp_path / f"cmd{seed}.csv"))
    check = check_target_current([load_recording(p) for p in paths])
    assert check.follows and check.joints == [1, 2, 3, 4, 5, 6]
    assert np.all(check.ratio < 1.5)
    out_file = tmp_path / "m.skops"
    assert main(["train", *map(str, paths), "--n-support", "40", "-q",
                 "-o", str(out_file)]) == 0
    out = capsys.readouterr().out
    assert "target current: FOLLOWS the measured current on joint(s) 1, 2, 3, 4, 5, 6" in out
    assert "SP_C the target current follows the measured current" in out
    trained = load_model(out_file)
    assert trained.training["model"] == "gp"
    assert "target_current" not in trained.training["signals"]
    assert trained.training["target_current_check"]["follows"] is True
    # asked for explicitly, SP_C is fitted (the flag stays for experts) with a warning
    assert main(["train", *map(str, paths), "--model", "sp_c", "--n-support", "40", "-q",
                 "-o", str(tmp_path / "c.skops")]) == 0
    assert "WARNING: --model sp_c asked for: its mean may absorb contacts" in \
        capsys.readouterr().out


def test_check_needs_motion_to_judge_a_joint():
    """A joint that never moves may need no feedback at all: it is not judged."""
    rec = simulate(JointTrajectory.rest([0.0, -1.57, 1.57, -1.57, -1.57, 0.0], 3.0), ROBOT,
                   random_state=0)
    check = check_target_current([rec])
    assert not check.decided and not check.follows and not check.usable
    assert np.isnan(check.ratio).all() and "cannot tell" in check.text()


def test_one_recording_is_compared_on_three_pieces():
    from sklearn_gpcd.io import Recording
    from sklearn_gpcd.workflow import compare_models, training_set

    t = np.arange(900) * 0.01
    q = np.column_stack([np.sin(t), np.cos(0.7 * t)])
    rec = Recording(time=t, q=q, qd=np.gradient(q, t, axis=0), current=2 * q,
                    target_current=1.9 * q, name="only")
    table = compare_models(training_set([rec]), n_support=30)
    assert table.held_out == [f"only piece {k}/3" for k in (1, 2, 3)]
    assert table.models == ["sp_c", "gp"] and table.errors.shape == (2, 2)
    assert table.best == "sp_c"  # the current is a multiple of the target


@pytest.mark.parametrize("value", ["nothing", "target_q,target_q", "current"])
def test_bad_signals_are_usage_errors(value, capsys):
    assert main(["train", "a.csv", "-o", "m.skops", "--signals", value]) == 2
    assert "expected auto, none or a comma-separated list" in capsys.readouterr().err


def test_the_smallest_thresholds_win_and_nmse_breaks_near_ties():
    """Issue #46: the choice serves detection. A model with the smallest nMSE but
    unstable extremes (a large leave-one-recording-out margin, so large
    thresholds) loses; among thresholds within CHOICE_TIE the nMSE decides."""
    from sklearn_gpcd.workflow import ModelComparison
    from sklearn_gpcd.workflow.model_choice import CHOICE_TIE

    errors = np.array([[0.01, 0.01], [0.03, 0.03], [0.02, 0.02]])
    thresholds = np.array([[4.0, 4.0], [1.0, 1.0], [1.02, 1.0]])  # sp_c: margin 7.4
    table = ModelComparison(["sp_c", "p_f", "sp_s"], errors, [1.0] * 3, ["a", "b", "c"], 200,
                            thresholds=thresholds, margins=np.array([7.4, 1.5, 1.6]))
    assert 1.02 ** 0.5 < CHOICE_TIE
    assert table.best == "sp_s"  # tied with p_f on thresholds, smaller nMSE
    table.thresholds = np.array([[4.0, 4.0], [1.0, 1.0], [1.2, 1.2]])
    assert table.best == "p_f"
    assert ModelComparison(["sp_c", "p_f"], errors[:2], [1.0] * 2, ["a"], 200).best == "sp_c"
    lines = table.text()
    assert lines[2].split()[0] == "P_f" and lines[2].endswith("<- chosen")
    summary = table.summary()
    assert summary["best"] == "p_f" and summary["margin"] == [7.4, 1.5, 1.6]
