"""One event per contact in ``gpcd monitor``'s loop, with the link and the force.

A simulated UR10 holds a pose and is pushed on link 3 at the link's frame
with a known force: the session reports one event, names link 3 and
estimates the force; without a robot model it says so. The session's events
(streaming) start where the batch detector's ``event`` rows do.
"""

import dataclasses
import warnings

import numpy as np
import pytest

from sklearn_gpcd.contact import contact_point
from sklearn_gpcd.datasets import Contact, JointTrajectory, simulate_d1, simulate
from sklearn_gpcd.detection import stack_currents
from sklearn_gpcd.features import contiguous_segments
from sklearn_gpcd.monitoring import MonitorSession
from sklearn_gpcd.robots import load_robot
from sklearn_gpcd.workflow import calibrate_detector, train_model

Q0 = np.array([0.0, -1.3, 1.4, -1.6, -1.57, 0.0])
Q1 = Q0 + np.array([0.4, 0.3, -0.3, 0.2, 0.0, 0.0])
FORCE = np.array([0.0, 40.0, -40.0])  # N, world axes
PUSH_S = (4.0, 1.0)                   # start, duration [s]


@pytest.fixture(scope="module")
def pushed_arm():
    robot = load_robot("ur10")
    reference = JointTrajectory.concatenate([JointTrajectory.point_to_point(Q0, Q1, 2.0),
                                             JointTrajectory.rest(Q1, 6.0)])
    push = Contact(link=3, start=PUSH_S[0], duration=PUSH_S[1], force=FORCE,
                   point=contact_point(robot, 3), frame="world")
    pushed = simulate(reference, robot, contacts=[push], random_state=0, name="pushed")
    free = [simulate(reference, robot, random_state=s, name=f"free{s}") for s in (1, 2)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # small simulated runs: coverage warnings
        trained = train_model([simulate_d1("ur10", n_targets=6, random_state=0), free[0]], robot,
                              "p_f", n_support=200)
        calibrated = calibrate_detector(trained, free, robot=robot, select=False)
    return robot, calibrated, pushed


def test_one_event_names_the_link_and_the_force(pushed_arm):
    robot, calibrated, pushed = pushed_arm
    session = MonitorSession(calibrated.detector, calibrated.features, robot=robot)
    session.run_recording(pushed, "pushed")
    assert len(session.events) == 1
    event = session.events[0]
    assert PUSH_S[0] <= event["start_s"] < PUSH_S[0] + 0.5
    assert event["released_s"] >= event["end_s"] >= event["start_s"]
    assert event["link"] == 3 and event["link_group"] == "link 3"
    assert 0.5 < event["link_confidence"] <= 1.0
    # the filtered residual at the sample of the largest ratio: within 40 % of |F|
    assert event["force_rank"] == 3
    assert 0.6 * np.linalg.norm(FORCE) < event["force_N"] < 1.2 * np.linalg.norm(FORCE)
    assert len(event["peak_per_joint_A"]) == 6
    assert max(event["peak_per_joint_A"]) == pytest.approx(event["peak_A"])
    text = session.events_text()
    assert "link 3 (" in text and "force [N]" in text
    assert f"{event['force_N']:.0f}" in text.splitlines()[-1]


def test_without_a_robot_model_the_force_says_so(pushed_arm):
    _, calibrated, pushed = pushed_arm
    session = MonitorSession(calibrated.detector, calibrated.features)
    session.run_recording(pushed, "pushed")
    assert [e["force_N"] for e in session.events] == ["no model"]
    assert session.events[0]["link"] == 3
    assert "no model" in session.events_text()


def test_the_session_events_are_the_batch_events(pushed_arm):
    robot, calibrated, pushed = pushed_arm
    session = MonitorSession(calibrated.detector, calibrated.features, robot=robot)
    session.run_recording(pushed, "pushed")
    X = stack_currents(calibrated.features.transform(pushed), pushed.current)
    batch = calibrated.detector.monitoring_signal(X)
    t = pushed.time - pushed.time[0]
    segments = contiguous_segments(batch.event)
    assert [e["start_s"] for e in session.events] == pytest.approx([t[a] for a, _ in segments])
    assert [e["released_s"] for e in session.events] == pytest.approx(
        [t[b] if b < len(t) else t[-1] for _, b in segments])


def test_a_second_contact_while_the_first_holds_is_a_second_session_event(pushed_arm):
    """Joint 2 pushed, its tail held above the release level, then joint 5 pushed
    (it had let go): ``gpcd monitor``'s loop closes the first event where the
    second begins, as the batch ``event_onset`` says."""
    robot, calibrated, _ = pushed_arm
    reference = JointTrajectory.concatenate([JointTrajectory.point_to_point(Q0, Q1, 2.0),
                                             JointTrajectory.rest(Q1, 6.0)])
    rec = simulate(reference, robot, random_state=3, name="two")
    rest = calibrated.detector.thresholds_[calibrated.detector.rules_[0].regime_names_.index(
        "rest")]
    t = rec.time - rec.time[0]
    current = rec.current.copy()
    current[(t >= 4.0) & (t < 4.4), 1] += 3.0 * rest[1]
    current[(t >= 4.4) & (t < 5.6), 1] += 0.75 * rest[1]   # the tail, above release
    current[(t >= 5.0) & (t < 5.3), 4] += 3.0 * rest[4]
    rec = dataclasses.replace(rec, current=current)
    session = MonitorSession(calibrated.detector, calibrated.features, robot=robot)
    session.run_recording(rec, "two")
    X = stack_currents(calibrated.features.transform(rec), rec.current)
    batch = calibrated.detector.monitoring_signal(X)
    onsets = t[batch.event_onset]
    assert len(onsets) == 2 and 4.0 <= onsets[0] < 4.4 and 5.0 <= onsets[1] < 5.3
    assert [e["start_s"] for e in session.events] == pytest.approx(onsets.tolist())
    first, second = session.events
    assert first["released_s"] == pytest.approx(second["start_s"])
    assert first["joints"] == [2] and second["joints"] == [5]
