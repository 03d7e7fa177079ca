"""Tests of sklearn_gpcd.robots: built-in UR models, URDF loading, real data."""


import numpy as np
import pinocchio as pin
import pytest

from sklearn_gpcd.robots import UR_PARAMETERS, Robot, list_robots, load_robot

ALL_ROBOTS = ["ur3", "ur5", "ur10", "ur3e", "ur5e", "ur10e", "ur16e"]
G = 9.81


# ---------------------------------------------------------------- helpers
def standard_dh(theta, d, a, alpha):
    """Rz(theta) Tz(d) Tx(a) Rx(alpha), written out independently of the package."""
    rz = np.eye(4)
    rz[:2, :2] = [[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]]
    tz = np.eye(4)
    tz[2, 3] = d
    tx = np.eye(4)
    tx[0, 3] = a
    rx = np.eye(4)
    rx[1:3, 1:3] = [[np.cos(alpha), -np.sin(alpha)], [np.sin(alpha), np.cos(alpha)]]
    return rz @ tz @ tx @ rx


def dh_chain(q, params, upto=None):
    """0T_i for i = upto (default: flange) from the published table."""
    T = np.eye(4)
    rows = zip(q, params["d"], params["a"], params["alpha"])
    for i, (qi, d, a, alpha) in enumerate(rows):
        if upto is not None and i == upto:
            break
        T = T @ standard_dh(qi, d, a, alpha)
    return T


# ----------------------------------------------------------- loading API
def test_list_robots_names_all_builtins():
    assert list_robots() == ALL_ROBOTS


@pytest.mark.parametrize("name", ["UR10e", " ur10e ", "Ur10E"])
def test_load_robot_is_case_insensitive(name):
    robot = load_robot(name)
    assert robot.name == "ur10e"
    assert robot.n_joints == 6


def test_unknown_robot_lists_known_names():
    with pytest.raises(ValueError, match="ur16e") as err:
        load_robot("ur99")
    assert "ur99" in str(err.value)


def test_missing_urdf_is_named(tmp_path):
    missing = tmp_path / "nope.urdf"
    with pytest.raises(ValueError, match="nope.urdf"):
        load_robot(missing)


def test_broken_urdf_raises_value_error(tmp_path):
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'/><joint></robot>")
    with pytest.raises(ValueError, match="bad.urdf"):
        load_robot(bad)


def test_unknown_override_is_type_error():
    with pytest.raises(TypeError, match="torque_constant"):
        load_robot("ur5", torque_constant=[1.0] * 6)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"torque_constants": [1.0] * 5}, "torque_constants"),
        ({"torque_constants": [1.0, 1, 1, 1, 1, -1]}, "positive"),
        ({"rotor_inertias": [np.nan] * 6}, "rotor_inertias"),
        ({"flange_frame": "no_such_frame"}, "no_such_frame"),
    ],
)
def test_bad_overrides_raise(kwargs, match):
    with pytest.raises(ValueError, match=match):
        load_robot("ur10", **kwargs)


def test_overrides_are_stored_and_armature_set():
    robot = load_robot("ur10e", torque_constants=[13.5] * 6, gear_ratios=[101] * 6,
                       rotor_inertias=[0.1, 0.2, 0.3, 0.01, 0.02, 0.03])
    np.testing.assert_array_equal(robot.torque_constants, [13.5] * 6)
    np.testing.assert_array_equal(robot.gear_ratios, [101] * 6)
    np.testing.assert_array_equal(robot.model.armature, [0.1, 0.2, 0.3, 0.01, 0.02, 0.03])
    # rnea includes the armature: M(q) qdd grows by armature * qdd
    q, qd = np.zeros(6), np.zeros(6)
    qdd = np.ones(6)
    plain = load_robot("ur10e")
    diff = robot.rnea(q, qd, qdd) - plain.rnea(q, qd, qdd)
    np.testing.assert_allclose(diff, [0.1, 0.2, 0.3, 0.01, 0.02, 0.03], atol=1e-12)


def test_ur10e_has_default_torque_constants_and_small_arms_none():
    constants = load_robot("ur10e").torque_constants
    assert constants.shape == (6,)
    assert np.all((constants > 5) & (constants < 20))
    assert load_robot("ur5").torque_constants is None


def test_robot_attributes():
    robot = load_robot("ur5e")
    assert isinstance(robot, Robot)
    assert robot.joint_names == list(UR_PARAMETERS["ur5e"]["joint_names"])
    np.testing.assert_allclose(robot.upper, 2 * np.pi)
    np.testing.assert_allclose(robot.lower, -2 * np.pi)
    np.testing.assert_allclose(robot.effort_limits, [150, 150, 150, 28, 28, 28])
    np.testing.assert_allclose(robot.velocity_limits, np.pi)
    assert robot.model.frames[robot.flange_frame_id].name == "flange"
    np.testing.assert_allclose(robot.dh[:, 0], UR_PARAMETERS["ur5e"]["d"])


def test_batch_shapes_and_input_errors(rng):
    robot = load_robot("ur3")
    q = rng.uniform(-3, 3, (7, 6))
    assert robot.forward_kinematics(q).shape == (7, 4, 4)
    assert robot.gravity(q).shape == (7, 6)
    assert robot.rnea(q, q, q).shape == (7, 6)
    np.testing.assert_allclose(robot.gravity(q)[3], robot.gravity(q[3]))
    with pytest.raises(ValueError, match="q must have shape"):
        robot.gravity(np.zeros(5))
    bad = q.copy()
    bad[2, 4] = np.nan
    with pytest.raises(ValueError, match="row 2, joint 4"):
        robot.gravity(bad)
    with pytest.raises(ValueError, match="same number of samples"):
        robot.rnea(q, q[:3], q)


def test_robot_pickles():
    import pickle

    robot = load_robot("ur10e")
    again = pickle.loads(pickle.dumps(robot))
    q = np.linspace(-1, 1, 6)
    np.testing.assert_allclose(again.gravity(q), robot.gravity(q))
    np.testing.assert_array_equal(again.torque_constants, robot.torque_constants)


def _round_trip(robot, fmt, tmp_path):
    """``robot`` through pickle, or through sklearn_gpcd.persistence (joblib/skops)."""
    import pickle

    if fmt == "pickle":
        return pickle.loads(pickle.dumps(robot))
    if fmt == "skops":
        pytest.importorskip("skops.io")
    from sklearn_gpcd.persistence import load, save

    # skops: no trusted= needed; joblib: our own pickle, trusted explicitly
    return load(save(robot, tmp_path / f"robot.{fmt}"), trust_pickle=fmt == "joblib")


def _assert_bit_identical(copy, robot, rng):
    """Same fields; pinocchio.rnea, Robot.rnea and the regressors agree bit for bit."""
    from sklearn_gpcd.dynamics import torque_features
    from sklearn_gpcd.dynamics import torque_model as regressor_module

    assert isinstance(copy, Robot) and isinstance(copy.model, pin.Model)
    assert copy.model is not robot.model and copy.model == robot.model
    assert (copy.name, copy.flange_frame, copy.citation) == (
        robot.name, robot.flange_frame, robot.citation)
    for name in ("torque_constants", "gear_ratios", "rotor_inertias", "dh"):
        a, b = getattr(copy, name), getattr(robot, name)
        assert (a is None and b is None) or np.array_equal(a, b), name
    assert np.array_equal(copy.model.armature, robot.model.armature)
    assert copy.joint_names == robot.joint_names
    assert copy.flange_frame_id == robot.flange_frame_id
    n = robot.n_joints
    q = rng.uniform(-np.pi, np.pi, (20, n))
    qd, qdd = rng.normal(size=(2, 20, n))
    data, data_copy = robot.model.createData(), copy.model.createData()
    for k in range(len(q)):
        tau = pin.rnea(robot.model, data, q[k], qd[k], qdd[k])
        assert np.array_equal(pin.rnea(copy.model, data_copy, q[k], qd[k], qdd[k]), tau)
        Y = pin.computeJointTorqueRegressor(robot.model, data, q[k], qd[k], qdd[k])
        Y_copy = pin.computeJointTorqueRegressor(copy.model, data_copy, q[k], qd[k], qdd[k])
        assert np.array_equal(Y_copy, Y)
    assert np.array_equal(copy.rnea(q, qd, qdd), robot.rnea(q, qd, qdd))
    assert np.array_equal(copy.forward_kinematics(q), robot.forward_kinematics(q))
    phis = []
    for r in (robot, copy):
        regressor_module._LAST_BATCH.clear()  # no cache hit: compute from each model
        phis.append(torque_features(r, q, qd, qdd, sigma_v=0.01))
    assert np.array_equal(phis[1], phis[0])


@pytest.mark.parametrize("fmt", ["pickle", "joblib", "skops"])
def test_builtin_robot_round_trip_is_bit_identical(fmt, tmp_path, rng):
    robot = load_robot("ur10e", gear_ratios=[101] * 6,
                       rotor_inertias=[0.1, 0.2, 0.3, 0.01, 0.02, 0.03])
    _assert_bit_identical(_round_trip(robot, fmt, tmp_path), robot, rng)


@pytest.mark.parametrize("fmt", ["pickle", "joblib", "skops"])
def test_urdf_robot_round_trip_is_bit_identical(fmt, ur10_urdf, tmp_path, rng):
    robot = load_robot(ur10_urdf, torque_constants=[10.0] * 6)
    _assert_bit_identical(_round_trip(robot, fmt, tmp_path), robot, rng)


def test_robot_state_stores_the_model_as_text():
    robot = load_robot("ur5")
    state = robot.__getstate__()
    assert isinstance(state["model"], str)
    assert robot.model is vars(robot)["model"]  # saving does not touch the robot
    legacy = dict(state, model=robot.model)  # pickles written before: the Model itself
    again = Robot.__new__(Robot)
    again.__setstate__(legacy)
    assert again.model is robot.model
    with pytest.raises(TypeError, match="'model' as a pinocchio.Model"):
        Robot.__new__(Robot).__setstate__(dict(state, model=3))


# ------------------------------------------------- published parameters
@pytest.mark.parametrize("name", ALL_ROBOTS)
def test_flange_matches_independent_dh_product(name, rng):
    """Model FK == product of standard DH transforms of the published table."""
    robot = load_robot(name)
    params = UR_PARAMETERS[name]
    Q = rng.uniform(-np.pi, np.pi, size=(50, 6))
    T = robot.forward_kinematics(Q)
    for q, Tq in zip(Q, T):
        np.testing.assert_allclose(Tq, dh_chain(q, params), atol=1e-9, rtol=0)


@pytest.mark.parametrize("name", ALL_ROBOTS)
def test_link_masses_and_coms_match_published(name, rng):
    """Each body carries the published mass, its COM sits at the published point
    of its DH frame, and its inertia is physically consistent."""
    robot = load_robot(name)
    params = UR_PARAMETERS[name]
    model, data = robot.model, robot.model.createData()
    q = rng.uniform(-np.pi, np.pi, 6)
    pin.forwardKinematics(model, data, q)
    for i in range(6):
        body = model.inertias[i + 1]
        assert body.mass == pytest.approx(params["mass"][i], rel=1e-12)
        com_world = data.oMi[i + 1].act(body.lever)
        expected = dh_chain(q, params, upto=i + 1) @ np.append(params["com"][i], 1.0)
        np.testing.assert_allclose(com_world, expected[:3], atol=1e-12)
        eig = np.linalg.eigvalsh(body.inertia)  # about the COM
        assert eig.min() > 0
        assert eig.sum() - 2 * eig.max() >= -1e-12  # triangle inequality


# ------------------------------------------------------------------ URDF
def test_urdf_path_loads(ur10_urdf):
    robot = load_robot(ur10_urdf)
    assert robot.n_joints == 6
    assert robot.flange_frame == "tool0"
    assert robot.joint_names[0] == "shoulder_pan_joint"
    assert robot.torque_constants is None


def _urdf_in_ur_base(urdf_robot, q):
    """URDF frame poses re-expressed in UR's 'base' frame (base_link rotated
    by pi about z, see the URDF's base_link-base_fixed_joint)."""
    model, data = urdf_robot.model, urdf_robot.model.createData()
    pin.framesForwardKinematics(model, data, q)
    base_inv = data.oMf[model.getFrameId("base")].inverse()
    return base_inv, data


def test_builtin_ur10_flange_equals_urdf_tool0(ur10_urdf, rng):
    urdf, builtin = load_robot(ur10_urdf), load_robot("ur10")
    for q in rng.uniform(-np.pi, np.pi, size=(50, 6)):
        base_inv, data = _urdf_in_ur_base(urdf, q)
        tool0 = (base_inv * data.oMf[urdf.flange_frame_id]).homogeneous
        # URDF rounds pi/2 to 11 digits, hence 1e-9 rather than 1e-12
        np.testing.assert_allclose(builtin.forward_kinematics(q), tool0, atol=1e-9, rtol=0)


def _transplant_urdf_inertias(urdf, builtin):
    """Built-in kinematics with the URDF's link inertias, moved into the
    built-in joint frames by the (constant) relative joint placement."""
    model = builtin.model.copy()
    q0 = np.zeros(6)
    base_inv, data_u = _urdf_in_ur_base(urdf, q0)
    data_b = model.createData()
    pin.forwardKinematics(model, data_b, q0)
    for j in range(1, 7):
        rel = data_b.oMi[j].inverse() * (base_inv * data_u.oMi[j])
        model.inertias[j] = rel.act(urdf.model.inertias[j])
    return model


def test_builtin_kinematics_with_urdf_inertias_reproduce_urdf_gravity(ur10_urdf, rng):
    """Exact check of frames and conventions: same links -> same gravity."""
    urdf, builtin = load_robot(ur10_urdf), load_robot("ur10")
    model = _transplant_urdf_inertias(urdf, builtin)
    data = model.createData()
    Q = rng.uniform(-np.pi, np.pi, size=(100, 6))
    g_urdf = urdf.gravity(Q)
    g_mixed = np.array([pin.computeGeneralizedGravity(model, data, q) for q in Q])
    np.testing.assert_allclose(g_mixed, g_urdf, atol=1e-9, rtol=0)


def test_builtin_ur10_gravity_close_to_urdf(ur10_urdf, rng):
    """Published UR10 masses/COMs vs the older ur_description values in the
    URDF (e.g. upper arm 12.7 vs 12.93 kg, COM at mid-link in the URDF).

    Gravity is linear in each link's mass m_k and first moment h_k = m_k c_k,
    so with both sets expressed in the same joint frames
    |tau_j - tau'_j| <= g * sum_{k>=j} (|h_k - h'_k| + |m_k - m'_k| * r_jk),
    r_jk bounding the distance from joint j's axis to link k's frame origin.
    That bound is the tolerance; it is tight only if the conventions agree."""
    urdf, builtin = load_robot(ur10_urdf), load_robot("ur10")
    mixed = _transplant_urdf_inertias(urdf, builtin)
    dh = builtin.dh
    reach = np.abs(dh[:, :2]).sum(axis=1)  # |d| + |a| per link
    bound = np.zeros(6)
    for j in range(6):
        for k in range(j, 6):
            a, b = builtin.model.inertias[k + 1], mixed.inertias[k + 1]
            dh_k = np.linalg.norm(a.mass * a.lever - b.mass * b.lever)
            bound[j] += G * (dh_k + abs(a.mass - b.mass) * reach[j:k].sum())
    Q = rng.uniform(-np.pi, np.pi, size=(200, 6))
    diff = np.abs(builtin.gravity(Q) - urdf.gravity(Q))
    assert np.all(diff <= bound + 1e-9)
    # and the bound is informative: shoulder/elbow within 25 % of their range
    scale = np.abs(urdf.gravity(Q)).max(axis=0)
    assert np.all(diff.max(axis=0)[1:3] < 0.25 * scale[1:3])
    print("UR10 gravity |builtin - URDF| max [Nm]:", diff.max(axis=0).round(2),
          "bound:", bound.round(2), "URDF max |tau_g|:", scale.round(1))


# ------------------------------------------------------------- real data
def _still_poses(ur10e_dir):
    paths = [ur10e_dir / "validation_data" / f"ur-20_01_17-p{k}.csv" for k in range(1, 11)]
    missing = [p.name for p in paths if not p.is_file()]
    if missing:
        pytest.skip(f"still-pose files missing: {missing}")
    poses = []
    for path in paths:
        rows = np.loadtxt(path, delimiter=",", ndmin=2)
        poses.append({"q": rows[:, 1:7], "qd": rows[:, 7:13], "current": rows[:, 13:19],
                      "target_torque": rows[:, 25:31] if rows.shape[1] >= 31 else None})
    return poses


@pytest.mark.realdata
def test_ur10e_gravity_explains_still_pose_currents(ur10e_dir, record_property):
    robot = load_robot("ur10e")
    poses = _still_poses(ur10e_dir)
    assert max(np.abs(p["qd"]).max() for p in poses) < 1e-2  # the robot is at rest
    tau_g = np.array([robot.gravity(p["q"]).mean(axis=0) for p in poses])
    current = np.array([p["current"].mean(axis=0) for p in poses])
    for j in (1, 2):
        corr = np.corrcoef(tau_g[:, j], current[:, j])[0, 1]
        slope, intercept = np.polyfit(current[:, j], tau_g[:, j], 1)
        record_property(f"corr_joint{j}", corr)
        record_property(f"torque_constant_joint{j}", slope)
        print(f"joint {j}: corr(mean current, gravity torque) = {corr:.4f}, "
              f"implied torque constant {slope:.2f} Nm/A (intercept {intercept:.2f} Nm), "
              f"default {robot.torque_constants[j]:.2f} Nm/A")
        assert corr > 0.95
        # the default constant is within 10 % of what the data imply
        assert abs(slope - robot.torque_constants[j]) < 0.1 * slope


@pytest.mark.realdata
def test_ur10e_gravity_matches_controller_target_torque(ur10e_dir):
    """At rest the UR controller's target torque is its own gravity model:
    the published UR10e parameters reproduce it on joints 2-5 (0-based 1-4)."""
    poses = _still_poses(ur10e_dir)
    if poses[0]["target_torque"] is None:
        pytest.skip("target torque not logged")
    robot = load_robot("ur10e")
    tau_g = np.array([robot.gravity(p["q"]).mean(axis=0) for p in poses])
    target = np.array([p["target_torque"].mean(axis=0) for p in poses])
    err = np.abs(tau_g - target).max(axis=0)
    print("max |gravity - controller target torque| per joint [Nm]:", err.round(3))
    assert np.all(err[1:3] < 0.02 * np.abs(target[:, 1:3]).max(axis=0))
    assert np.all(err[3:5] < 0.1)
