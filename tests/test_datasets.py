"""Tests of the built-in simulator and the paper's data-set generators."""

import numpy as np
import pinocchio as pin
import pytest

from sklearn_gpcd.datasets import (
    Contact,
    CurrentDelay,
    CurrentOffset,
    FrictionChange,
    Hemisphere,
    JointFriction,
    JointSpring,
    JointTrajectory,
    Payload,
    RobotSimulator,
    TorqueConstantError,
    default_friction,
    simulate_d1,
    simulate_d2,
    simulate_interaction_test,
    simulate_joint1_cyclic,
    reference_d1,
    reference_d2,
    reference_interaction_test,
    simulate,
)
from sklearn_gpcd.datasets.plant import drive_parameters, plant_model
from sklearn_gpcd.io import Recording
from sklearn_gpcd.robots import load_robot

NOISE = 0.03  # default current noise std [A]
HOME = np.array([0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, 0.0])


@pytest.fixture(scope="module")
def ur10():
    return load_robot("ur10")


def model_current(robot, rec):
    """i_model = (M_eq qdd + C qd + g + f_slide(qd)) / K_eq on the logged signals."""
    model = plant_model(robot)
    data = model.createData()
    k, _ = drive_parameters(robot)
    qd = rec.metadata["truth"]["qd"]
    tau = np.array([pin.rnea(model, data, q, v, a) for q, v, a in zip(rec.q, qd, rec.qdd)])
    return (tau + default_friction(robot).torque(qd)) / k


def rest_windows(rec, tail=2.0):
    """(visit, q1, mask of the last `tail` seconds) for every rest phase."""
    out = []
    for phase in rec.metadata["phases"]:
        if phase["kind"] == "rest":
            mask = (rec.time >= phase["stop"] - tail) & (rec.time < phase["stop"])
            out.append((phase["visit"], phase["q1"], mask))
    return out


def longest_run(flags):
    best = run = 0
    for flag in flags:
        run = run + 1 if flag else 0
        best = max(best, run)
    return best


# ----------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def cyclic():
    return simulate_joint1_cyclic("ur10", rest_duration=4.0, random_state=0)


@pytest.fixture(scope="module")
def interaction():
    return simulate_interaction_test("ur10", n_turns=0.2, rest_duration=12.0, random_state=0)


@pytest.fixture(scope="module")
def d1_small():
    return simulate_d1("ur10", n_targets=4, random_state=1)


# ------------------------------------------------------------- trajectories
def test_point_to_point_is_rest_to_rest_and_consistent():
    move = JointTrajectory.point_to_point([0.0, 1.0], [1.0, -1.0], duration=2.0)
    q, qd, qdd = move.sample([0.0, 2.0])
    np.testing.assert_allclose(q, [[0.0, 1.0], [1.0, -1.0]], atol=1e-12)
    np.testing.assert_allclose(qd, 0.0, atol=1e-12)
    np.testing.assert_allclose(qdd, 0.0, atol=1e-12)
    t = np.linspace(0.1, 1.9, 50)
    q, qd, qdd = move.sample(t)
    h = 1e-6
    np.testing.assert_allclose((move.sample(t + h)[0] - move.sample(t - h)[0]) / (2 * h), qd,
                               atol=1e-6)
    np.testing.assert_allclose((move.sample(t + h)[1] - move.sample(t - h)[1]) / (2 * h), qdd,
                               atol=1e-5)


def test_concatenate_shifts_phases_and_rejects_gaps():
    a = JointTrajectory.rest([0.0], 1.0)
    b = JointTrajectory.point_to_point([0.0], [1.0], 2.0)
    ref = JointTrajectory.concatenate([a, b, JointTrajectory.rest([1.0], 0.5)])
    assert ref.duration == pytest.approx(3.5)
    assert [(p["kind"], p["start"]) for p in ref.phases] == [
        ("rest", 0.0), ("move", 1.0), ("rest", 3.0)]
    with pytest.raises(ValueError, match="piece 1 starts"):
        JointTrajectory.concatenate([a, JointTrajectory.rest([0.5], 1.0)])


# ----------------------------------------------------------- input checking
@pytest.mark.parametrize(
    "build, message",
    [
        (lambda: JointFriction([2.0], [1.0], [0.1], [0.02]), "static must be >= coulomb"),
        (lambda: Contact(link=0, start=0.0, duration=1.0, force=[1, 0, 0]), "link"),
        (lambda: Contact(link=1, start=0.0, duration=-1.0, force=[1, 0, 0]), "duration"),
        (lambda: Contact(link=1, start=0.0, duration=1.0, force=[1, 0]), "force"),
        (lambda: JointTrajectory.rest([0.0, np.nan], 1.0), "NaN"),
        (lambda: JointTrajectory.point_to_point([0.0], [1.0], 0.0), "duration"),
    ],
)
def test_bad_building_blocks_raise_named_errors(build, message):
    with pytest.raises(ValueError, match=message):
        build()


def test_simulator_rejects_bad_configuration():
    ref = JointTrajectory.rest(HOME, 0.1)
    with pytest.raises(ValueError, match="must divide servo_rate"):
        RobotSimulator(sample_rate=300.0).run(ref)
    with pytest.raises(ValueError, match="reference has 2 joints"):
        RobotSimulator().run(JointTrajectory.rest([0.0, 0.0], 0.1))
    with pytest.raises(TypeError, match="JointTrajectory"):
        RobotSimulator().run(np.zeros((10, 6)))
    with pytest.raises(ValueError, match="link=7"):
        RobotSimulator().run(ref, contacts=[Contact(link=7, start=0.0, duration=0.1,
                                                    force=[1.0, 0.0, 0.0])])
    with pytest.raises(ValueError, match="FrictionChange.static"):
        RobotSimulator().run(ref, effects=[FrictionChange(static=[1.0, 2.0])])


# ------------------------------------------------------- stick-slip physics
def test_holding_current_depends_on_history(cyclic):
    """Paper Fig. 2: at q1 = pi/2 joint 1 holds different currents per visit."""
    windows = rest_windows(cyclic)
    at_half_pi = [(visit, cyclic.current[mask, 0]) for visit, q1, mask in windows
                  if abs(q1 - np.pi / 2) < 1e-9]
    assert [visit for visit, _ in at_half_pi] == [1, 3]  # from below, then from above
    (_, first), (_, second) = at_half_pi
    noise_std = max(first.std(), second.std())  # joint stuck: only sensor noise is left
    assert noise_std < 1.5 * NOISE
    difference = abs(first.mean() - second.mean())
    print(f"\nholding current joint 1 at pi/2: visit 1 {first.mean():.3f} A, "
          f"visit 3 {second.mean():.3f} A, difference {difference:.3f} A, "
          f"noise std {noise_std:.4f} A")
    assert difference > 3 * noise_std
    # same configuration: q1 agrees to well below a milliradian
    q_first = cyclic.q[windows[1][2], 0].mean()
    q_second = cyclic.q[windows[3][2], 0].mean()
    assert abs(q_first - q_second) < 1e-3


def test_joints_really_stick_at_rest(cyclic, ur10):
    truth = cyclic.metadata["truth"]
    k, _ = drive_parameters(ur10)
    static = default_friction(ur10).static
    model = plant_model(ur10)
    data = model.createData()
    for visit, q1, mask in rest_windows(cyclic):
        # velocity exactly zero (before noise) for the whole window, all joints
        assert longest_run((truth["qd"][mask] == 0.0).all(axis=1)) == mask.sum()
        assert (cyclic.qd[mask] == 0.0).all()  # default: no velocity noise
        assert (cyclic.qdd[mask] == 0.0).all()
        # holding torque K i - g(q) inside the static friction band
        gravity = np.array([pin.computeGeneralizedGravity(model, data, q)
                            for q in cyclic.q[mask]])
        holding = k * truth["current"][mask] - gravity
        assert (np.abs(holding) <= static * (1 + 1e-6) + 1e-6).all(), (visit, q1)
        measured = k * cyclic.current[mask] - gravity
        assert (np.abs(measured) <= static + 6 * NOISE * k).all()


def test_stuck_joints_keep_position_when_neighbours_move(cyclic):
    """In the joint-1 test joints 2-6 stay stuck (same q) while joint 1 turns."""
    truth = cyclic.metadata["truth"]
    moving = np.abs(truth["qd"][:, 0]) > 0.05
    assert moving.sum() > 100
    assert truth["stuck"][moving, 3:].mean() > 0.9
    assert np.ptp(cyclic.q[:, 5]) < 1e-3


def test_moving_current_tracks_rigid_body_model(d1_small, ur10):
    truth = d1_small.metadata["truth"]
    residual = d1_small.current - model_current(ur10, d1_small)
    for joint in range(6):
        moving = np.abs(truth["qd"][:, joint]) > 0.05
        assert moving.sum() > 100
        rms = np.sqrt(np.mean(residual[moving, joint] ** 2))
        assert rms < 0.2 * d1_small.current[moving, joint].std()
        assert rms < 1.5 * NOISE  # the rest is sensor noise
    # the noise-free current obeys Eq. 4 to rounding while sliding
    clean = truth["current"] - model_current(ur10, d1_small)
    sliding = np.abs(truth["qd"]) > 0.05
    assert np.abs(clean[sliding]).max() < 5e-3


# ------------------------------------------------------------------ contacts
def test_pushes_are_labelled_and_visible(interaction, ur10):
    contacts = interaction.metadata["contacts"]
    assert len(contacts) == 4 and all(c.link == 1 for c in contacts)
    for k, contact in enumerate(contacts, start=1):
        inside = (interaction.time >= contact.start) & (interaction.time < contact.stop)
        np.testing.assert_array_equal(interaction.labels == k, inside)
    residual = np.abs(interaction.current - model_current(ur10, interaction))[:, 0]
    circle = next(p for p in interaction.metadata["phases"] if p["kind"] == "circle")
    at_rest = interaction.time >= circle["stop"] + 0.5
    free_rest = at_rest & (interaction.labels == 0)
    k_eq, _ = drive_parameters(ur10)
    stiction_band = default_friction(ur10).static[0] / k_eq[0]  # what friction can hold
    for k in (3, 4):  # the pushes at rest
        push = interaction.labels == k
        assert at_rest[push].all()
        peak = residual[push].max()
        print(f"\npush {k} at rest: max |i - i_model| = {peak:.2f} A; free rest: median "
              f"{np.median(residual[free_rest]):.2f} A, stiction band {stiction_band:.2f} A")
        assert peak > 10 * NOISE
        assert peak > stiction_band + 10 * NOISE
        assert np.mean(residual[push] > stiction_band + 3 * NOISE) > 0.3
    truth = interaction.metadata["truth"]
    assert np.abs(truth["external_torque"][interaction.labels == 0]).max() == 0.0
    assert np.abs(truth["external_torque"][interaction.labels > 0, 0]).max() > 50.0
    # a force on link 1 loads joint 1 only
    assert np.abs(truth["external_torque"][:, 1:]).max() < 1e-9


@pytest.mark.parametrize("frame", ["world", "local"])
def test_contact_torque_is_moment_about_each_joint_axis(frame, ur10):
    """tau_j = z_j . ((p - o_j) x F) for the joints before the link, 0 after."""
    model = plant_model(ur10)
    data = model.createData()
    q = HOME + 0.3
    contact = Contact(link=3, start=0.0, duration=1.0, force=[10.0, -5.0, 20.0],
                      point=[0.1, 0.0, 0.05], frame=frame)
    tau = contact.joint_torque(model, model.createData(), q)  # fresh data: no stale kinematics
    pin.forwardKinematics(model, data, q)
    point = data.oMi[3].act(contact.point)
    force = contact.force if frame == "world" else data.oMi[3].rotation @ contact.force
    expected = [data.oMi[j].rotation[:, 2] @ np.cross(point - data.oMi[j].translation, force)
                if j <= 3 else 0.0 for j in range(1, 7)]
    np.testing.assert_allclose(tau, expected, atol=1e-10)


# ------------------------------------------------------------------- effects
def test_payload_raises_shoulder_holding_current(ur10):
    ref = JointTrajectory.rest(HOME, 1.5)
    base = simulate(ref, ur10, random_state=0, current_noise_std=0.0)
    loaded = simulate(ref, ur10, effects=[Payload(5.0, start=0.2)], random_state=0,
                      current_noise_std=0.0)
    k, _ = drive_parameters(ur10)
    data = ur10.model.createData()
    pin.forwardKinematics(ur10.model, data, HOME)
    pin.updateFramePlacements(ur10.model, data)
    # gravity torque of 5 kg at the flange about joint 2's axis
    arm = data.oMf[ur10.flange_frame_id].translation - data.oMi[2].translation
    torque = data.oMi[2].rotation[:, 2] @ np.cross(arm, [0.0, 0.0, -5.0 * 9.81])
    expected = abs(torque) / k[1]
    extra = np.abs(loaded.current[-20:, 1].mean() - base.current[-20:, 1].mean())
    # the servo holds the extra gravity torque, up to what static friction takes
    band = default_friction(ur10).static[1] / k[1]
    assert expected - band - 0.05 <= extra <= expected + band + 0.05
    # the truth is exact: extra motor torque = extra gravity + change of friction
    truth_base, truth = base.metadata["truth"], loaded.metadata["truth"]
    d_motor = truth["motor_torque"][-1, 1] - truth_base["motor_torque"][-1, 1]
    d_friction = truth["friction_torque"][-1, 1] - truth_base["friction_torque"][-1, 1]
    assert d_motor - d_friction == pytest.approx(-torque, rel=1e-3)


@pytest.mark.parametrize(
    "effect",
    [FrictionChange(static=2.0, coulomb=1.5), CurrentDelay(0.005), TorqueConstantError(0.8),
     JointSpring(stiffness=[200.0, 0, 0, 0, 0, 0])],
)
def test_effects_change_the_current(effect, ur10):
    q1 = HOME + np.array([0.4, 0.2, -0.3, 0.3, 0.3, 0.3])
    ref = JointTrajectory.concatenate([JointTrajectory.point_to_point(HOME, q1, 1.0),
                                       JointTrajectory.rest(q1, 0.5)])
    base = simulate(ref, ur10, random_state=0, current_noise_std=0.0)
    changed = simulate(ref, ur10, effects=[effect], random_state=0, current_noise_std=0.0)
    assert np.abs(changed.current - base.current).max() > 10 * NOISE


def test_current_offset_is_a_sensor_bias_only(ur10):
    ref = JointTrajectory.rest(HOME, 1.0)
    base = simulate(ref, ur10, random_state=0)
    biased = simulate(ref, ur10, effects=[CurrentOffset(0.25, start=0.4, stop=0.8)],
                      random_state=0)
    inside = (base.time >= 0.4) & (base.time < 0.8)
    np.testing.assert_allclose(biased.current[inside] - base.current[inside], 0.25, atol=1e-12)
    np.testing.assert_allclose(biased.current[~inside], base.current[~inside])
    np.testing.assert_array_equal(biased.target_current, base.target_current)


def test_same_seed_same_recording(ur10):
    ref = JointTrajectory.point_to_point(HOME, HOME + 0.2, 0.5)
    a = simulate(ref, ur10, random_state=3)
    b = simulate(ref, ur10, random_state=3)
    c = simulate(ref, ur10, random_state=4)
    np.testing.assert_array_equal(a.current, b.current)
    assert not np.array_equal(a.current, c.current)
    np.testing.assert_array_equal(a.q, c.q)  # noise is on the current only


# ---------------------------------------------------------------- generators
def test_d1_plan_size_targets_and_limits(ur10):
    ref = reference_d1(ur10, n_targets=200, random_state=0)
    n_samples = int(round(ref.duration * 125)) + 1
    print(f"\nD1 planned samples: {n_samples}")
    assert 0.9 * 80_000 <= n_samples <= 1.1 * 80_000
    hemisphere = Hemisphere.for_robot(ur10)
    rests = [p for p in ref.phases if p["kind"] == "rest" and p.get("target") is not None]
    assert len(rests) == 200
    targets = np.array([p["target"] for p in rests])
    assert hemisphere.contains(targets).all()
    reached = ur10.forward_kinematics(np.array([ref.at(p["stop"]) for p in rests]))[:, :3, 3]
    np.testing.assert_allclose(reached, targets, atol=1e-4)
    q, qd, qdd = ref.sample(np.arange(0.0, ref.duration, 0.008))
    assert np.isfinite(q).all() and np.isfinite(qd).all() and np.isfinite(qdd).all()
    assert (q >= ur10.lower).all() and (q <= ur10.upper).all()
    assert (np.abs(qd) <= ur10.velocity_limits + 1e-9).all()


def test_d2_plan_size_and_circle(ur10):
    ref = reference_d2(ur10, random_state=0)
    n_samples = int(round(ref.duration * 125)) + 1
    print(f"\nD2 planned samples: {n_samples}")
    assert 0.85 * 22_000 <= n_samples <= 1.15 * 22_000
    circle = next(p for p in ref.phases if p["kind"] == "circle")
    t = np.arange(circle["start"], circle["stop"], 0.008)
    q, _, _ = ref.sample(t)
    assert (q >= ur10.lower).all() and (q <= ur10.upper).all()
    position = ur10.forward_kinematics(q)[:, :3, 3]
    radius = np.linalg.norm(position[:, :2] - np.array(circle["center"][:2]), axis=1)
    np.testing.assert_allclose(radius, 0.3, atol=1e-4)
    speed = np.linalg.norm(np.diff(position, axis=0), axis=1) / 0.008
    assert np.median(speed) == pytest.approx(0.03, rel=0.01)
    assert Hemisphere.for_robot(ur10).contains(position).all()


def test_interaction_plan_has_two_pushes_moving_two_at_rest(ur10):
    ref, contacts = reference_interaction_test(ur10, n_turns=0.2, rest_duration=12.0,
                                               random_state=0)
    circle = next(p for p in ref.phases if p["kind"] == "circle")
    during = [circle["start"] <= c.start and c.stop <= circle["stop"] for c in contacts]
    assert during == [True, True, False, False]
    assert all(c.stop <= ref.duration for c in contacts)


def test_small_generators_produce_clean_recordings(d1_small, ur10):
    d2 = simulate_d2(ur10, n_targets=2, n_turns=0.05, random_state=0)
    for rec in (d1_small, d2):
        assert isinstance(rec, Recording)
        for key in rec.available():
            assert np.isfinite(getattr(rec, key)).all(), key
        assert (rec.q >= ur10.lower).all() and (rec.q <= ur10.upper).all()
        assert (rec.labels == 0).all()
        assert np.allclose(np.diff(rec.time), 0.008)
        # the servo tracks the reference to within a few milliradians
        assert np.abs(rec.q - rec.target_q).max() < 0.02


def test_rtde_csv_round_trip(interaction, tmp_path):
    from sklearn_gpcd.io import read_rtde_csv, write_rtde_csv

    path = write_rtde_csv(interaction, tmp_path / "interaction.csv")
    back = read_rtde_csv(path)
    np.testing.assert_array_equal(back.labels, interaction.labels)
    for key in ("q", "qd", "qdd", "current", "target_current", "target_torque"):
        np.testing.assert_array_equal(getattr(back, key), getattr(interaction, key))


# ------------------------------------------------------------------ full size
@pytest.mark.slow
def test_full_size_d1_and_d2():
    d1 = simulate_d1("ur10", random_state=0)
    d2 = simulate_d2("ur10", random_state=0)
    print(f"\nD1 {d1.n_samples} samples, real-time factor "
          f"{d1.metadata['real_time_factor']:.1f}; D2 {d2.n_samples} samples, "
          f"real-time factor {d2.metadata['real_time_factor']:.1f}")
    assert 0.9 * 80_000 <= d1.n_samples <= 1.1 * 80_000
    assert 0.85 * 22_000 <= d2.n_samples <= 1.15 * 22_000
    for rec in (d1, d2):
        assert all(np.isfinite(getattr(rec, key)).all() for key in rec.available())
