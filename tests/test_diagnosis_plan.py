"""The recording a diagnosis asks for (``DynamicsDiagnosis.plan``, ``gpcd diagnose --plan``)."""

import numpy as np
import pytest

from sklearn_gpcd.cli import main
from sklearn_gpcd.datasets import JointTrajectory, Payload, simulate_d1, simulate
from sklearn_gpcd.diagnosis import DynamicsDiagnosis, NominalModel
from sklearn_gpcd.diagnosis.identifiability import identifiability, needs
from sklearn_gpcd.diagnosis.plan import (PLAN_SECONDS, excitation_plan, robot_limits,
                                         smooth_window)
from sklearn_gpcd.io import write_rtde_csv
from sklearn_gpcd.robots import load_robot

CENTER = np.array([0.0, -1.6, 1.6, -1.6, -1.6, 0.0])
ALL_NEEDS = [{"effect": "torque_constant", "joints": [4, 5], "reason": "weak"},
             {"effect": "stribeck_friction", "joints": [1], "reason": ""},
             {"effect": "time_delay", "joints": [], "reason": ""},
             {"effect": "friction_drift", "joints": [2], "reason": ""}]


@pytest.fixture(scope="module")
def robot():
    return load_robot("ur10")


def _within(plan, limits, tol=1e-9):
    assert np.all(plan.q >= limits.lower - tol) and np.all(plan.q <= limits.upper + tol)
    assert np.all(np.abs(plan.qd) <= limits.velocity + tol)
    assert np.all(np.abs(plan.qdd) <= limits.acceleration + tol)


def test_window_is_c2_at_both_ends():
    t = np.linspace(0, 10, 10001)
    w, wd, wdd = smooth_window(t, 10.0, ramp=2.0)
    assert w[0] == w[-1] == 0 and wd[0] == wd[-1] == 0 and abs(wdd[0]) + abs(wdd[-1]) < 1e-12
    # the derivatives are the derivatives (so the plan's qd, qdd are its q's)
    assert np.allclose(np.gradient(w, t), wd, atol=1e-3)
    assert np.allclose(np.gradient(wd, t), wdd, atol=1e-2)


def test_plan_within_limits_smooth_and_at_most_180_s(robot):
    limits = robot_limits(robot)
    plan = excitation_plan(ALL_NEEDS, NominalModel(robot), CENTER, 0.008, limits)
    assert plan.duration <= PLAN_SECONDS
    assert [s["kind"] for s in plan.segments][:4] == ["gravity_load", "low_speed", "chirp",
                                                       "steady"]
    _within(plan, limits)
    assert np.allclose(np.diff(plan.time), 0.008)
    # continuous acceleration: consecutive samples differ by at most a bounded jerk
    assert np.abs(np.diff(plan.qdd, axis=0)).max() < 0.5
    # q, qd, qdd agree (finite differences)
    assert np.abs(np.gradient(plan.q, plan.time, axis=0) - plan.qd).max() < 2e-3
    # starts and ends at rest at the centre pose
    assert np.allclose(plan.q[0], CENTER) and np.allclose(plan.q[-1], CENTER)
    assert np.abs(plan.qd[[0, -1]]).max() < 1e-12
    header, first = plan.to_csv().splitlines()[:2]
    assert header == "timestamp," + ",".join(f"target_q_{j}" for j in range(6))
    assert first.split(",")[0] == "0.000000"


def test_low_speed_segment_sweeps_through_zero_slowly(robot):
    limits = robot_limits(robot)
    plan = excitation_plan([{"effect": "stribeck_friction", "joints": [3], "reason": ""}],
                           NominalModel(robot), CENTER, 0.008, limits)
    seg = plan.segments[0]
    rows = (plan.time >= seg["start"]) & (plan.time <= seg["stop"])
    qd = plan.qd[rows, 3]
    assert np.abs(qd).max() <= 0.2
    assert np.sum(np.diff(np.sign(qd[np.abs(qd) > 1e-4])) != 0) >= 8  # reversals
    others = np.delete(np.arange(6), 3)
    assert np.abs(plan.qd[rows][:, others]).max() < 1e-12


def test_gravity_pose_loads_the_wrist_more(robot):
    nominal = NominalModel(robot)
    plan = excitation_plan([{"effect": "torque_constant", "joints": [4], "reason": ""}],
                           nominal, CENTER, 0.008, robot_limits(robot))
    seg = plan.segments[0]
    pose = plan.q[np.searchsorted(plan.time, seg["start"])]
    zero = np.zeros((1, 6))
    load = lambda q: abs(float(robot.rnea(q[None], zero, zero)[0, 4]))  # noqa: E731
    assert load(pose) > 2 * load(CENTER)


def test_short_plan_runs_on_the_built_in_simulator_within_limits(robot):
    limits = robot_limits(robot)
    plan = excitation_plan([{"effect": "time_delay", "joints": [], "reason": ""}],
                           NominalModel(robot), CENTER, 0.008, limits, max_seconds=30)
    rec = simulate(JointTrajectory.from_samples(plan.time, plan.q), robot, random_state=0)
    assert rec.duration == pytest.approx(plan.duration, abs=0.1)
    assert np.all(rec.q >= robot.lower) and np.all(rec.q <= robot.upper)
    assert np.all(np.abs(rec.qd) <= robot.velocity_limits)
    # the servo follows the plan
    ref = np.interp(rec.time, plan.time, plan.q[:, 0])
    assert np.abs(rec.q[:, 0] - ref).max() < 0.05


@pytest.mark.slow
def test_full_plan_runs_on_the_built_in_simulator_within_limits(robot):
    limits = robot_limits(robot)
    plan = excitation_plan(ALL_NEEDS, NominalModel(robot), CENTER, 0.008, limits)
    rec = simulate(JointTrajectory.from_samples(plan.time, plan.q), robot, random_state=0)
    assert rec.duration == pytest.approx(plan.duration, abs=0.1)
    assert np.all(rec.q >= robot.lower) and np.all(rec.q <= robot.upper)
    assert np.all(np.abs(rec.qd) <= robot.velocity_limits)


def test_identifiability_confounds_a_duplicate_column(robot):
    """Two candidates with the same columns: confounded, and neither detectable given both."""
    from sklearn_gpcd.diagnosis import Candidate, effect_library

    coulomb, viscous = effect_library(["coulomb_friction", "viscous_friction"])
    gram = np.zeros((6, 2, 2))
    gram[0] = [[4.0, 4.0], [4.0, 4.0 + 1e-6]]
    cands = [Candidate(coulomb, 0, {}, (0,), np.array([0]), 0),
             Candidate(viscous, 0, {}, (0,), np.array([1]), 1)]
    nominal = NominalModel(robot, friction={"coulomb": [1.0] * 6, "viscous": [1.0] * 6})
    table = identifiability(cands, gram, np.ones(6), [], nominal)
    assert table[0]["confounded_with"][0]["label"] == "viscous_friction[joint 1]"
    assert not np.isfinite(table[0]["detectable"]) or table[0]["detectable"] > 1.0
    assert needs(table)[0]["reason"].startswith("cannot tell coulomb_friction[joint 1] from")
    # well separated columns: small detectable size, no need
    gram[0] = [[1e4, 0.0], [0.0, 1e4]]
    table = identifiability(cands, gram, np.ones(6), [], nominal)
    assert table[0]["confounded_with"] == [] and table[0]["detectable"] < 0.2
    assert needs(table) == []


def test_fitted_diagnosis_writes_its_plan(robot, tmp_path):
    rec = simulate_d1("ur10", n_targets=5, effects=[Payload(3.0)], random_state=1)
    diag = DynamicsDiagnosis(robot, effects=["payload", "torque_constant", "time_delay"])
    diag.fit(rec)
    assert {"effect", "detectable", "confounded_with"} <= set(diag.identifiability_[0])
    plan = diag.plan()
    assert plan.duration <= PLAN_SECONDS and plan.segments
    period = float(np.median(np.diff(rec.time)))
    assert np.allclose(np.diff(plan.time), period)
    limits = robot_limits(robot)
    _within(plan, limits)
    path = tmp_path / "plan.csv"
    plan.to_csv(path)
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    assert data.shape == (len(plan.time), 7)


def test_cli_plan(tmp_path, capsys):
    train = tmp_path / "train.csv"
    write_rtde_csv(simulate_d1("ur10", n_targets=5, effects=[Payload(3.0)], random_state=1), train)
    plan = tmp_path / "plan.csv"
    assert main(["diagnose", "--robot", "ur10", str(train), "--effects",
                 "payload,time_delay", "--plan", str(plan)]) == 0
    assert plan.read_text().startswith("timestamp,target_q_0,")
    assert "excitation plan:" in capsys.readouterr().out
