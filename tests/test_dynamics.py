"""Tests of sklearn_gpcd.dynamics: regressor, base parameters, RigidBodyFeatures."""

import pickle

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.exceptions import NotFittedError

from sklearn_gpcd.layout import column_names
from sklearn_gpcd.dynamics import (
    FrictionColumns,
    RigidBodyFeatures,
    base_parameters,
    torque_features,
    parameter_names,
    parameter_vector,
)
from sklearn_gpcd.robots import list_robots, load_robot

ROTOR = [0.6, 0.5, 0.3, 0.05, 0.04, 0.03]

# sklearn's parametrize_with_checks is not run on RigidBodyFeatures: its
# generic checks feed 1-10 feature columns, while the transformer needs the
# 3 * n_joints (18) columns [q, qd, qdd] of a robot and rightly rejects fewer
# (every check fails with our "needs at least 18" ValueError). The behaviour
# those checks cover (fit/transform, clone, pickle, n_features_in_,
# feature names, NaN and shape errors, not-fitted error, idempotent fit) is
# tested directly below.


def random_states(rng, n, n_joints=6):
    q = rng.uniform(-np.pi, np.pi, (n, n_joints))
    qd = rng.uniform(-2, 2, (n, n_joints))
    qdd = rng.uniform(-6, 6, (n, n_joints))
    return q, qd, qdd


def model_torques(robot, q, qd, qdd, fc, fv, offset=None):
    """pinocchio rnea (with armature) + Coulomb + viscous (+ offset)."""
    tau = robot.rnea(q, qd, qdd) + fc * np.sign(qd) + fv * qd
    return tau if offset is None else tau + offset


@pytest.fixture(params=list_robots())
def robot(request):
    return load_robot(request.param, rotor_inertias=ROTOR)


# ---------------------------------------------------- Phi @ pi == model
def test_full_regressor_reproduces_rnea_plus_friction(robot, rng):
    q, qd, qdd = random_states(rng, 100)
    fc, fv = rng.uniform(1, 10, 6), rng.uniform(1, 10, 6)
    pi = parameter_vector(robot, friction={"coulomb": fc, "viscous": fv})
    Phi = torque_features(robot, q, qd, qdd)
    np.testing.assert_allclose(Phi @ pi, model_torques(robot, q, qd, qdd, fc, fv),
                               atol=1e-9, rtol=0)


def test_transformer_full_base_and_per_joint_reproduce_torques(robot, rng):
    q, qd, qdd = random_states(rng, 100)
    X = np.hstack([q, qd, qdd])
    fc, fv = rng.uniform(1, 10, 6), rng.uniform(1, 10, 6)
    pi = parameter_vector(robot, friction={"coulomb": fc, "viscous": fv})
    tau = model_torques(robot, q, qd, qdd, fc, fv)

    full = RigidBodyFeatures(robot, base_parameters=False).fit(X)
    np.testing.assert_allclose(full.transform(X) @ pi, tau.ravel(order="F"), atol=1e-9, rtol=0)

    base = RigidBodyFeatures(robot).fit(X)
    beta = base.project_parameters(pi)
    assert beta.shape == (base.base_parameters_["rank"],)
    np.testing.assert_allclose(base.transform(X) @ beta, tau.ravel(order="F"), atol=1e-9, rtol=0)

    for j in range(6):
        one = RigidBodyFeatures(robot, joint=j).fit(X)
        Phi_j = one.transform(X)
        assert Phi_j.shape[0] == 100
        np.testing.assert_allclose(Phi_j @ one.project_parameters(pi), tau[:, j], atol=1e-9, rtol=0)


def test_offset_column(rng):
    robot = load_robot("ur10e")
    q, qd, qdd = random_states(rng, 50)
    X = np.hstack([q, qd, qdd])
    off = rng.normal(size=6)
    fc, fv = np.ones(6), np.ones(6)
    pi = parameter_vector(robot, friction={"coulomb": fc, "viscous": fv}, offset=off)
    est = RigidBodyFeatures(robot, offset=True).fit(X)
    assert "offset_3" in est.get_feature_names_out()
    tau = model_torques(robot, q, qd, qdd, fc, fv, off)
    np.testing.assert_allclose(est.transform(X) @ est.project_parameters(pi), tau.ravel(order="F"),
                               atol=1e-9, rtol=0)


def test_urdf_robot_through_transformer(rng, tmp_path):
    """Any URDF works: a two-link planar arm written here."""
    urdf = tmp_path / "planar.urdf"
    urdf.write_text("""<robot name="planar">
      <link name="base"/>
      <link name="l1"><inertial><mass value="2.0"/><origin xyz="0.3 0 0.01"/>
        <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.05" iyz="0" izz="0.05"/></inertial></link>
      <link name="l2"><inertial><mass value="1.0"/><origin xyz="0.2 0.01 0"/>
        <inertia ixx="0.005" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.02"/></inertial></link>
      <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
        <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="10" velocity="2"/></joint>
      <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
        <origin xyz="0.6 0 0"/><axis xyz="0 1 0"/>
        <limit lower="-3" upper="3" effort="10" velocity="2"/></joint>
    </robot>""")
    robot = load_robot(urdf, rotor_inertias=[0.1, 0.2])
    q, qd, qdd = random_states(rng, 40, n_joints=2)
    X = np.hstack([q, qd, qdd])
    est = RigidBodyFeatures(urdf, friction=("viscous",), rotor_inertia=True).fit(X)
    pi = parameter_vector(robot, friction={"viscous": [0.5, 0.7]})
    # the estimator loaded its own copy of the URDF without rotor inertias
    pi_est = parameter_vector(est.robot_, friction={"viscous": [0.5, 0.7]})
    tau = est.robot_.rnea(q, qd, qdd) + np.array([0.5, 0.7]) * qd
    np.testing.assert_allclose(est.transform(X) @ est.project_parameters(pi_est),
                               tau.ravel(order="F"), atol=1e-9, rtol=0)
    assert pi.shape == pi_est.shape == (2 * 10 + 2 + 2,)


# ------------------------------------------------------------- options
def test_joint_none_is_joint_by_joint_blocks(rng):
    X = np.hstack(random_states(rng, 7))
    stacked = RigidBodyFeatures("ur5").fit(X).transform(X)
    full = torque_features("ur5", X[:, :6], X[:, 6:12], X[:, 12:18])
    cols = RigidBodyFeatures("ur5").fit(X).columns_
    assert stacked.shape == (7 * 6, len(cols))
    for l in range(6):
        for k in range(7):
            np.testing.assert_array_equal(stacked[l * 7 + k], full[k, l, cols])


def test_sigma_v_zeroes_friction_columns_only(rng):
    q, qd, qdd = random_states(rng, 200)
    qd[::3] *= 1e-3  # some joints nearly at rest
    X = np.hstack([q, qd, qdd])
    plain = RigidBodyFeatures("ur10", joint=2).fit(X)
    gated = RigidBodyFeatures("ur10", joint=2, sigma_v=0.01).fit(X)
    A, B = plain.transform(X), gated.transform(X)
    fr = gated.friction_columns_
    names = gated.get_feature_names_out()
    assert sorted(names[fr]) == ["coulomb_2", "viscous_2"]
    other = np.setdiff1d(np.arange(A.shape[1]), fr)
    np.testing.assert_array_equal(A[:, other], B[:, other])
    still = np.abs(qd[:, 2]) < 0.01
    assert still.any() and (~still).any()
    np.testing.assert_array_equal(B[still][:, fr], 0.0)
    np.testing.assert_array_equal(B[~still][:, fr], A[~still][:, fr])
    np.testing.assert_array_equal(A[:, names == "coulomb_2"].ravel(), np.sign(qd[:, 2]))


def test_coulomb_width_smooths_the_coulomb_column_only(rng):
    """tanh(qd / w) replaces sign(qd): equal far from rest, no jump on jitter."""
    q, qd, qdd = random_states(rng, 200)
    qd[::3] *= 1e-4  # velocity jitter of a still joint
    X = np.hstack([q, qd, qdd])
    sign = RigidBodyFeatures("ur10", joint=2).fit(X)
    smooth = RigidBodyFeatures("ur10", joint=2,
                               friction=FrictionColumns(coulomb_width=0.01)).fit(X)
    names = smooth.get_feature_names_out()
    assert np.array_equal(names, sign.get_feature_names_out())
    A, B = sign.transform(X), smooth.transform(X)
    coulomb = names == "coulomb_2"
    np.testing.assert_array_equal(A[:, ~coulomb], B[:, ~coulomb])
    np.testing.assert_allclose(B[:, coulomb].ravel(), np.tanh(qd[:, 2] / 0.01), rtol=1e-15)
    jitter = np.abs(qd[:, 2]) < 1e-3
    fast = np.abs(qd[:, 2]) > 0.2
    assert jitter.any() and fast.any()
    assert np.abs(B[jitter][:, coulomb]).max() < 0.1  # the sign is +-1 there
    np.testing.assert_allclose(B[fast][:, coulomb], A[fast][:, coulomb], atol=1e-15)
    # the velocity gate (Eq. 17) still zeroes it at rest
    gated = RigidBodyFeatures("ur10", joint=2, friction=FrictionColumns(coulomb_width=0.01),
                              sigma_v=0.01).fit(X)
    np.testing.assert_array_equal(gated.transform(X)[jitter][:, coulomb], 0.0)


def test_the_friction_part_is_one_nested_parameter(rng, tmp_path):
    """FrictionColumns is reached, cloned, gridded and saved as part of the features;
    a tuple of terms is short for FrictionColumns(terms=...)."""
    pytest.importorskip("skops")
    from sklearn.base import clone

    from sklearn_gpcd.persistence import load, save

    X = np.hstack(random_states(rng, 40))
    est = RigidBodyFeatures("ur10", joint=2, friction=FrictionColumns(("viscous",)))
    assert est.get_params()["friction__terms"] == ("viscous",)
    est.set_params(friction__coulomb_width=0.02, friction__terms=("coulomb", "viscous"))
    twin = clone(est)
    assert twin.friction is not est.friction
    assert twin.get_params()["friction__coulomb_width"] == 0.02
    fitted = twin.fit(X)
    assert (fitted.friction_, fitted.coulomb_width_) == (("coulomb", "viscous"), 0.02)
    short = RigidBodyFeatures("ur10", joint=2, friction=("viscous", "coulomb")).fit(X)
    assert (short.friction_, short.coulomb_width_) == (("coulomb", "viscous"), None)
    names = fitted.get_feature_names_out()
    coulomb = names == "coulomb_2"
    np.testing.assert_allclose(fitted.transform(X)[:, coulomb].ravel(),
                               np.tanh(X[:, 8] / 0.02), rtol=1e-12)
    back = load(save(fitted, tmp_path / "phi.skops"))
    assert isinstance(back.friction, FrictionColumns)
    np.testing.assert_array_equal(back.transform(X), fitted.transform(X))


def test_a_state_from_before_the_friction_part_loads(rng):
    """A fitted state with a ``coulomb_width`` parameter (before FrictionColumns)
    loads into the split class and transforms as before."""
    X = np.hstack(random_states(rng, 20))
    now = RigidBodyFeatures("ur10", joint=1, friction=FrictionColumns(coulomb_width=0.01)).fit(X)
    old = now.__getstate__()
    old["friction"], old["coulomb_width"] = ("coulomb", "viscous"), old.pop("coulomb_width_")
    loaded = RigidBodyFeatures.__new__(RigidBodyFeatures)
    loaded.__setstate__(old)
    assert loaded.get_params()["friction__coulomb_width"] == 0.01
    np.testing.assert_array_equal(loaded.transform(X), now.transform(X))


def test_currents_divides_by_torque_constants(rng):
    X = np.hstack(random_states(rng, 30))
    robot = load_robot("ur10e", torque_constants=[10, 11, 12, 13, 14, 15])
    torque = RigidBodyFeatures(robot).fit(X).transform(X)
    current = RigidBodyFeatures(robot, currents=True).fit(X).transform(X)
    k = np.repeat([10, 11, 12, 13, 14, 15], 30)[:, None]
    np.testing.assert_allclose(current, torque / k, rtol=1e-14)
    with pytest.raises(ValueError, match="torque constants"):
        RigidBodyFeatures("ur5", currents=True).fit(X)


def test_friction_options_and_names(rng):
    X = np.hstack(random_states(rng, 10))
    est = RigidBodyFeatures("ur3", friction=("viscous",), rotor_inertia=False,
                             base_parameters=False).fit(X)
    names = list(est.get_feature_names_out())
    assert names == parameter_names(6, rotor_inertia=False, friction=("viscous",))
    assert names[:2] == ["link0_m", "link0_mx"] and names[-1] == "viscous_5"
    assert not any(n.startswith(("coulomb", "rotor")) for n in names)
    np.testing.assert_array_equal(est.friction_columns_, np.arange(60, 66))
    assert RigidBodyFeatures("ur3", friction=None).fit(X).friction_columns_.size == 0
    with pytest.raises(ValueError, match="stribeck"):
        RigidBodyFeatures("ur3", friction=("stribeck",)).fit(X)


def test_per_joint_drops_structural_zero_columns(rng):
    X = np.hstack(random_states(rng, 20))
    est = RigidBodyFeatures("ur10", joint=5, base_parameters=False).fit(X)
    names = est.get_feature_names_out()
    # joint 5 (wrist 3) only feels link 5 and its own drive terms
    assert all(n.startswith(("link5_", "rotor_5", "coulomb_5", "viscous_5")) for n in names)
    assert np.all(np.abs(est.transform(X)).max(axis=0) > 0)


# ---------------------------------------------------- base parameters
def test_base_parameters_rank_and_mapping(rng):
    X = np.hstack(random_states(rng, 20))
    est = RigidBodyFeatures("ur10e").fit(X)
    info = est.base_parameters_
    p = len(est.parameter_names_)
    assert info["mapping"].shape == (info["rank"], p)
    np.testing.assert_array_equal(info["mapping"][:, info["indices"]], np.eye(info["rank"]))
    assert info["names"] == [est.parameter_names_[i] for i in info["indices"]]
    # 36 inertial + 4 rotor + 12 friction for a UR arm (measured; the
    # independent check is the full column rank below)
    assert info["rank"] == 52
    q, qd, qdd = random_states(np.random.default_rng(5), 300)
    Phi = est.transform(np.hstack([q, qd, qdd]))
    assert np.linalg.matrix_rank(Phi) == info["rank"]
    # deterministic for a given random_state
    same = RigidBodyFeatures("ur10e").fit(X)
    np.testing.assert_array_equal(same.base_parameters_["indices"], info["indices"])
    np.testing.assert_array_equal(same.base_parameters_["mapping"], info["mapping"])
    # the dependencies are structural: another seed or a looser tolerance find
    # the same rank (which column of a dependent group is kept may differ)
    other = RigidBodyFeatures("ur10e", random_state=7, rank_tol=1e-8).fit(X)
    assert other.base_parameters_["rank"] == info["rank"]


def test_base_parameters_helper_toy_example():
    W = np.array([[1.0, 2.0, 0.0, 0.0], [3.0, 6.0, 1.0, 0.0], [0.0, 0.0, 5.0, 0.0]])
    info = base_parameters(W)
    assert info["rank"] == 2
    pi = np.array([0.3, -1.2, 2.0, 7.0])
    np.testing.assert_allclose(W[:, info["indices"]] @ (info["mapping"] @ pi), W @ pi)
    np.testing.assert_array_equal(info["dependent"], [0, 3])
    with pytest.raises(ValueError, match="NaN"):
        base_parameters(np.array([[np.nan, 1.0]]))


# ----------------------------------------------------- sklearn contract
def test_clone_pickle_and_refit_are_consistent(rng):
    X = np.hstack(random_states(rng, 25))
    est = RigidBodyFeatures("ur10", joint=1, sigma_v=0.05)
    assert clone(est).get_params() == est.get_params()
    fitted = est.fit(X)
    again = pickle.loads(pickle.dumps(fitted))
    np.testing.assert_array_equal(again.transform(X), fitted.transform(X))
    np.testing.assert_array_equal(again.get_feature_names_out(), fitted.get_feature_names_out())
    np.testing.assert_array_equal(clone(est).fit_transform(X), fitted.transform(X))
    refit = RigidBodyFeatures("ur10", joint=1, sigma_v=0.05).fit(X).fit(X)
    np.testing.assert_array_equal(refit.columns_, fitted.columns_)


def test_robot_instance_parameter_is_cloned_and_pickled(rng):
    X = np.hstack(random_states(rng, 5))
    robot = load_robot("ur5e", torque_constants=[9.0] * 6)
    est = RigidBodyFeatures(robot, currents=True)
    copy = clone(est)
    assert copy.robot is not robot
    np.testing.assert_array_equal(copy.fit(X).transform(X), est.fit(X).transform(X))
    assert pickle.loads(pickle.dumps(est)).robot_.name == "ur5e"


def test_init_stores_parameters_verbatim():
    est = RigidBodyFeatures(robot="nonsense", joint=99, friction="bad", rank_tol=-1)
    assert est.get_params()["robot"] == "nonsense"
    assert est.get_params()["joint"] == 99


def test_n_features_in_and_extra_columns_ignored(rng):
    q, qd, qdd = random_states(rng, 12)
    X18 = np.hstack([q, qd, qdd])
    X36 = np.hstack([X18, rng.normal(size=(12, 18))])  # augmented layout (Eq. 13)
    a = RigidBodyFeatures("ur10e", joint=0).fit(X18)
    b = RigidBodyFeatures("ur10e", joint=0).fit(X36)
    assert a.n_features_in_ == 18 and b.n_features_in_ == 36
    np.testing.assert_array_equal(a.transform(X18), b.transform(X36))
    with pytest.raises(ValueError, match="36 features"):
        b.transform(X18)


def test_dataframe_input_sets_feature_names(rng):
    pd = pytest.importorskip("pandas")
    X = pd.DataFrame(np.hstack(random_states(rng, 8)), columns=column_names(6, augmented=False))
    est = RigidBodyFeatures("ur5", joint=2).fit(X)
    assert list(est.feature_names_in_) == column_names(6, augmented=False)
    names_out = est.get_feature_names_out(column_names(6, augmented=False))
    assert len(names_out) == est.transform(X).shape[1]
    with pytest.raises(ValueError, match="input_features"):
        est.get_feature_names_out(["a"] * 18)


def test_not_fitted_raises():
    with pytest.raises(NotFittedError):
        RigidBodyFeatures().transform(np.zeros((2, 18)))


# ------------------------------------------------------------ bad input
def test_too_few_columns_is_named(rng):
    with pytest.raises(ValueError, match="X has 17 columns.*robot .ur10. has 6 joints"):
        RigidBodyFeatures("ur10").fit(rng.normal(size=(4, 17)))


def test_nan_is_named(rng):
    X = rng.normal(size=(4, 18))
    X[2, 7] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        RigidBodyFeatures("ur10").fit(X)
    est = RigidBodyFeatures("ur10").fit(rng.normal(size=(4, 18)))
    with pytest.raises(ValueError, match="NaN"):
        est.transform(X)


@pytest.mark.parametrize(
    "kwargs, err, match",
    [
        ({"joint": 6}, ValueError, "joint=6"),
        ({"joint": 1.5}, TypeError, "joint"),
        ({"sigma_v": -0.1}, ValueError, "sigma_v"),
        ({"rank_tol": 0.0}, ValueError, "rank_tol"),
        ({"friction": FrictionColumns(coulomb_width=0.0)}, ValueError, "coulomb_width"),
        ({"friction": FrictionColumns(coulomb_width=np.inf)}, ValueError, "coulomb_width"),
        ({"friction": FrictionColumns(coulomb_width="0.1")}, ValueError, "coulomb_width"),
        ({"friction": FrictionColumns(terms=("stribeck",))}, ValueError, "stribeck"),
        ({"friction": 3}, ValueError, "friction"),
        ({"robot": "ur99"}, ValueError, "ur99"),
        ({"robot": 3}, TypeError, "robot"),
    ],
)
def test_bad_parameters_fail_in_fit(kwargs, err, match, rng):
    est = RigidBodyFeatures(**kwargs)
    with pytest.raises(err, match=match):
        est.fit(rng.normal(size=(3, 18)))


def test_parameter_vector_checks_lengths():
    with pytest.raises(ValueError, match="coulomb"):
        parameter_vector("ur5", friction={"coulomb": [1.0] * 5})
    with pytest.raises(ValueError, match="offset"):
        parameter_vector("ur5", offset=[1.0])
    est = RigidBodyFeatures("ur5").fit(np.zeros((2, 18)))
    with pytest.raises(ValueError, match="parameter_names_"):
        est.project_parameters(np.zeros(3))


def test_joint_selection_and_batch_cache_give_the_same_rows(rng, monkeypatch):
    from sklearn_gpcd.dynamics import torque_model as reg

    reg._LAST_BATCH.clear()
    torque_features("ur10", *rng.normal(size=(3, 5, 6)))  # a few samples: not cached
    assert not reg._LAST_BATCH
    q, qd, qdd = rng.normal(size=(3, reg.CACHE_MIN_SAMPLES, 6))
    full = torque_features("ur10", q, qd, qdd)
    assert reg._LAST_BATCH["value"].shape == (reg.CACHE_MIN_SAMPLES, 6, 60)
    again = torque_features("ur10", q, qd, qdd)  # served by the one-batch cache
    assert np.array_equal(full, again)
    for joint in (0, 3, [1, 5]):
        assert np.array_equal(torque_features("ur10", q, qd, qdd, joints=joint),
                              full[:, np.atleast_1d(joint), :])
    # other states or another robot are not served from the cache
    assert not np.array_equal(torque_features("ur10", q + 0.1, qd, qdd), full)
    assert not np.array_equal(torque_features("ur5", q, qd, qdd), full)
    # batches above the cache size compute only the requested rows
    monkeypatch.setattr(reg, "CACHE_MAX_BYTES", 0)
    reg._LAST_BATCH.clear()
    assert np.array_equal(torque_features("ur10", q, qd, qdd, joints=2), full[:, [2], :])
    assert not reg._LAST_BATCH
    # the public function returns a writable copy, never the cached array
    Y = reg.inertial_features(load_robot("ur10").model, q, qd, qdd)
    Y[:] = 0.0
    assert np.array_equal(torque_features("ur10", q, qd, qdd), full)


@pytest.mark.parametrize("options", [
    {},
    {"offset": True, "sigma_v": 0.01},
    {"rotor_inertia": False, "friction": ("viscous",)},
    {"rotor_inertia": False, "friction": (), "offset": True},
    {"coulomb_width": 0.01, "sigma_v": 0.001},
])
def test_sample_regressor_equals_the_batch_one_in_place_too(options, rng):
    """One state at a time, into a fresh array or over the previous result."""
    from sklearn_gpcd.dynamics.torque_model import SampleTorqueFeatures

    sample = SampleTorqueFeatures("ur10e", **options)
    out = None
    for q, qd, qdd in rng.normal(size=(4, 3, 6)) * [[1.0], [0.005], [1.0]]:
        expected = torque_features("ur10e", q, qd, qdd, **options)[0]
        out = sample(q, qd, qdd, out=out)
        assert np.array_equal(out, expected) and out.shape == (6, sample.n_parameters)
        assert np.array_equal(sample(q, qd, qdd), expected)
