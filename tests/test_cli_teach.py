"""``gpcd teach`` then ``gpcd monitor`` (issue 45): train once per robot,
calibrate once per robot, teach once per task, monitor.

Data: the package's own simulator (UR10). The model is P_f on the state
(``--signals none``) trained on a few point-to-point moves; the task is a
cycle between two poses that the model never saw at this speed.
"""

import json

import numpy as np
import pytest

from sklearn_gpcd.cli import main
from sklearn_gpcd.datasets import Contact, JointTrajectory, simulate
from sklearn_gpcd.detection import TaughtTask
from sklearn_gpcd.io import write_rtde_csv
from sklearn_gpcd.workflow import load_detector

Q0 = np.array([0.0, -1.57, 1.57, -1.57, -1.57, 0.0])
Q1 = Q0 + [0.6, 0.3, -0.4, 0.5, 0.4, 0.8]
#: Rows of the first cycle: a simulation's first motion starts from the
#: servo's initial state, unlike every later cycle.
FIRST = 575
PUSH = Contact(link=3, start=10.1, duration=0.8, force=[0.0, 0.0, -60.0])


def _task(n):
    cycle = [JointTrajectory.point_to_point(Q0, Q1, 2.0), JointTrajectory.rest(Q1, 0.3),
             JointTrajectory.point_to_point(Q1, Q0, 2.0), JointTrajectory.rest(Q0, 0.3)]
    return JointTrajectory.concatenate(cycle * n)


def _moves(targets, seconds):
    poses = [Q0, *(Q0 + np.asarray(t) for t in targets), Q0]
    return JointTrajectory.concatenate([JointTrajectory.point_to_point(a, b, seconds)
                                        for a, b in zip(poses[:-1], poses[1:])])


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    folder = tmp_path_factory.mktemp("teach")
    general = [_moves([[0.6, 0.3, -0.4, 0.5, 0.4, 0.8], [0.2, 0.4, -0.2, 0.3, 0.6, 0.2]], 3.5),
               _moves([[0.5, 0.1, -0.5, 0.6, 0.2, 1.0], [0.3, 0.3, -0.3, 0.2, 0.5, 0.4]], 3.0),
               _moves([[0.4, 0.2, -0.3, 0.4, 0.3, 0.6], [0.1, 0.1, -0.1, 0.1, 0.1, 0.1]], 4.0)]
    runs = []
    for k, ref in enumerate(general):
        runs.append(write_rtde_csv(simulate(ref, "ur10", random_state=k), folder / f"g{k}.csv",
                                   robot_comment=True))
    task = simulate(_task(4), "ur10", random_state=10).slice(FIRST)
    taught = write_rtde_csv(task, folder / "task.csv", robot_comment=True)
    pushed = simulate(_task(4), "ur10", contacts=[PUSH], random_state=11).slice(FIRST)
    push = write_rtde_csv(pushed, folder / "push.csv", robot_comment=True)
    model, detector = folder / "model.skops", folder / "detector.skops"
    assert main(["train", *map(str, runs[:2]), "--model", "p_f", "--signals", "none",
                 "--n-support", "100", "-q", "-o", str(model)]) == 0
    assert main(["calibrate", str(model), *map(str, runs), "-q", "-o", str(detector)]) == 0
    return {"folder": folder, "detector": detector, "task": taught, "push": push,
}


def test_teach_writes_a_taught_detector_and_says_what_it_learnt(work, capsys):
    out = work["folder"] / "taught.skops"
    assert main(["teach", str(work["detector"]), str(work["task"]), "-q",
                 "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "3 cycles of 4.5" in text or "3 cycles of 4.6" in text
    # the level: the Gumbel law at the target rate, beside the distribution-free bound
    assert "at 0.1 false alarms per hour" in text and "per hour of the task" in text
    detector, features, calibration = load_detector(out)
    assert isinstance(detector, TaughtTask)
    assert calibration["teach"]["n_cycles"] == 3
    assert calibration["teach"]["recordings"] == ["task.csv"]


def test_one_cycle_is_refused_in_one_line(work, capsys, tmp_path):
    short = tmp_path / "short.csv"
    from sklearn_gpcd.io import load_recording

    rec = load_recording(work["task"])
    write_rtde_csv(rec.slice(0, 600), short, robot_comment=True)
    assert main(["teach", str(work["detector"]), str(short), "-q",
                 "-o", str(tmp_path / "x.skops")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "at least two cycles" in err[0]


def test_monitor_with_the_taught_detector_catches_the_push(work, capsys):
    taught = work["folder"] / "taught2.skops"
    assert main(["teach", str(work["detector"]), str(work["task"]), "-q",
                 "-o", str(taught)]) == 0
    report = work["folder"] / "report.json"
    main(["monitor", str(taught), str(work["push"]), "-q", "--json", str(report)])
    text = capsys.readouterr().out
    assert "taught task:" in text
    result = json.loads(report.read_text())
    events = result["events"]
    start = PUSH.start - FIRST * 0.008
    inside = [e for e in events if start - 0.1 <= e["start_s"] <= start + PUSH.duration]
    assert inside and inside[0]["taught"] is True
    # every other event is the calibrated detector's, at rest (this detector was
    # calibrated on other motions and rings at the task's stops)
    assert all(not e["taught"] for e in events if e not in inside)
    assert result["recordings"][0]["taught_s"] > 0
    # how well it protects, in N at the flange (the UR10 model the files name):
    # finer in taught motion than where the calibrated thresholds decide
    protected = result["recordings"][0]["protected_N"]
    assert 0 < protected["taught"]["median"] < protected["untaught"]["median"]
    assert "protected at <=" in text
    plots = work["folder"] / "plots"
    assert main(["monitor", str(taught), str(work["push"]), "-q", "--plot", str(plots)]) in (0, 1)
    assert (plots / "push.png").stat().st_size > 0
    # a detector that was not taught says so
    main(["monitor", str(work["detector"]), str(work["push"]), "-q", "--json", str(report)])
    assert "not taught any task" in capsys.readouterr().out


def test_a_taught_file_edited_to_nan_is_refused_in_one_line(work, capsys):
    """Fail closed: a taught threshold edited to NaN would never alarm."""
    from sklearn_gpcd.workflow import save_detector
    from sklearn_gpcd.workflow.calibration import CalibratedDetector

    taught = work["folder"] / "taught3.skops"
    assert main(["teach", str(work["detector"]), str(work["task"]), "-q",
                 "-o", str(taught)]) == 0
    task, features, calibration = load_detector(taught)
    task.thresholds_[2] = np.nan
    broken = work["folder"] / "broken.skops"
    save_detector(CalibratedDetector(task, features, calibration), broken)
    capsys.readouterr()
    assert main(["monitor", str(broken), str(work["push"]), "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "thresholds_" in err[0] and "gpcd" in err[0], err


def test_update_keeps_learning_and_says_what_it_took(work, capsys):
    taught, updated = work["folder"] / "t.skops", work["folder"] / "u.skops"
    assert main(["teach", str(work["detector"]), str(work["task"]), "-q",
                 "-o", str(taught)]) == 0
    capsys.readouterr()
    assert main(["teach", str(taught), str(work["task"]), str(work["push"]), "--update", "-q",
                 "-o", str(updated)]) == 0
    text = capsys.readouterr().out
    assert "learnt from task.csv" in text and "learnt from push.csv" in text
    learning = load_detector(updated)[2]["teach"]["learning"]
    assert [e["recording"] for e in learning] == ["task.csv", "push.csv"]
    # this detector rings at the task's stops (calibrated on other motions): every
    # cycle holds an alarm, so nothing is learnt (test_task.py learns a warm-up)
    assert learning[1]["rejected"].get("alarm", 0) >= 1
    assert all(e["accepted"] == e["pending"] == 0 for e in learning)
    assert not np.any(learning[-1]["drift_A"])


def test_update_needs_a_taught_file(work, capsys):
    assert main(["teach", str(work["detector"]), str(work["task"]), "--update", "-q",
                 "-o", str(work["folder"] / "x.skops")]) == 2
    assert "run gpcd teach DETECTOR TASK_LOG" in capsys.readouterr().err
