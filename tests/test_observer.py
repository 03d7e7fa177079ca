"""The generalized-momentum observer on data the package simulates."""

import pickle

import numpy as np
import pytest

from sklearn_gpcd.datasets import Contact, JointTrajectory, simulate
from sklearn_gpcd.dynamics import UR_OBSERVER_GAINS, MomentumObserver

from _pushes import inputs, push_runs, training_run


@pytest.fixture(scope="module")
def training():
    return training_run()


@pytest.fixture(scope="module")
def observer(training):
    return MomentumObserver("ur10", identify="friction").fit(
        inputs(training), training.current, time=training.time)


@pytest.fixture(scope="module")
def pushes():
    return push_runs(seed=3, n_per_link=2)


def test_batch_equals_streaming_with_restarts_and_time_stamps(observer, pushes):
    rec = pushes[0]
    X, current = inputs(rec), rec.current
    groups = (np.arange(rec.n_samples) >= rec.n_samples // 2).astype(int)
    jitter = rec.time + np.random.default_rng(0).uniform(0, 0.003, rec.n_samples)
    batch = observer.residual(X, current, groups=groups, time=jitter)
    stream = observer.stream()
    rows = []
    for k in range(rec.n_samples):
        if k and groups[k] != groups[k - 1]:
            stream.reset()
        rows.append(stream.update(X[k], current[k], time=jitter[k]).copy())
    np.testing.assert_array_equal(np.array(rows), batch)
    # a pickled stream resumes where it was
    stream.reset()
    for k in range(10):
        stream.update(X[k], current[k])
    copy = pickle.loads(pickle.dumps(stream))
    np.testing.assert_array_equal(copy.update(X[10], current[10]),
                                  stream.update(X[10], current[10]))


def test_residual_follows_the_applied_external_torque(observer, pushes):
    """During the pushes the observer's r matches the simulator's true external
    torque (its first-order lag aside): peak error per joint small against the
    push, and r small in free motion."""
    rec = pushes[0]
    r = observer.external_torque(inputs(rec), rec.current, time=rec.time)
    truth = rec.metadata["truth"]["external_torque"]
    noise = np.sqrt(np.mean(r[rec.labels == 0] ** 2, axis=0))
    for k in range(1, rec.labels.max() + 1):
        rows = rec.labels == k
        peak = np.abs(truth[rows]).max(axis=0)
        loaded = peak > 5.0
        estimated = np.abs(r[rows]).max(axis=0)
        # peak of each loaded joint within 15 % (or 3 noise levels)
        error = np.abs(estimated - peak)[loaded]
        assert np.all(error <= np.maximum(0.15 * peak[loaded], 3 * noise[loaded])), (k, peak,
                                                                                     estimated)
    # correlation with the truth over all contact samples, per heavily loaded joint
    inside = rec.labels > 0
    for joint in range(6):
        if np.abs(truth[inside, joint]).max() > 10.0:
            corr = np.corrcoef(truth[inside, joint], r[inside, joint])[0, 1]
            assert corr > 0.9, (joint, corr)


def test_residual_is_exact_on_the_nominal_model_without_friction():
    """A frictionless plant with the nominal model: the observer is the
    external torque through its first-order filter, to integration error."""
    from sklearn_gpcd.datasets import JointFriction

    n = 6
    friction = JointFriction(coulomb=np.zeros(n), static=np.zeros(n), viscous=np.zeros(n),
                             stribeck_velocity=np.full(n, 0.01))
    q0 = [0.0, -1.3, 1.4, -1.6, -1.57, 0.0]
    move = JointTrajectory.point_to_point(q0, [0.4, -1.0, 1.1, -1.3, -1.2, 0.3], 3.0)
    push = Contact(link=3, start=1.0, duration=1.0, force=[0.0, 0.0, -80.0],
                   point=[-0.3, 0.0, 0.0])
    rec = simulate(move, "ur10", contacts=[push], friction=friction, current_noise_std=0.0,
                   sample_rate=1000.0, random_state=0)
    from sklearn_gpcd.datasets.plant import drive_parameters
    from sklearn_gpcd.robots import load_robot

    robot = load_robot("ur10", rotor_inertias=drive_parameters(load_robot("ur10"))[1])
    obs = MomentumObserver(robot, identify="none", gains=200.0, sample_time=0.001).fit(
        inputs(rec), rec.current)
    r = obs.external_torque(inputs(rec), rec.current)
    truth = rec.metadata["truth"]["external_torque"]
    # the filter lag: compare with the truth through the same first-order filter
    a = np.exp(-200.0 * 0.001)
    filtered = np.zeros_like(truth)
    for k in range(1, len(truth)):
        filtered[k] = a * filtered[k - 1] + (1 - a) * truth[k - 1]
    assert np.abs(r - filtered).max() < 0.02 * np.abs(truth).max()


def test_parameters_and_errors(training):
    X = inputs(training)[:200]
    obs = MomentumObserver("ur10", identify="none").fit(X, training.current[:200])
    np.testing.assert_array_equal(obs.gains_, UR_OBSERVER_GAINS)
    assert obs.get_params()["identify"] == "none"
    with pytest.raises(ValueError, match="identify"):
        MomentumObserver("ur10", identify="bogus").fit(X, training.current[:200])
    with pytest.raises(ValueError, match="gains"):
        MomentumObserver("ur10", gains=-1.0).fit(X, training.current[:200])
    with pytest.raises(ValueError, match="at least 18"):
        MomentumObserver("ur10").fit(X[:, :12], training.current[:200])
    with pytest.raises(ValueError, match="increase"):
        obs.residual(X[:3], training.current[:3], time=[0.0, 0.0, 0.1])
    predicted = obs.predict(X, training.current[:200])
    np.testing.assert_allclose(training.current[:200] - predicted,
                               obs.residual(X, training.current[:200]))


@pytest.mark.parametrize("identify", ["friction", "all"])
def test_identification_lowers_the_residual(training, identify):
    X, current = inputs(training), training.current
    none = MomentumObserver("ur10", identify="none").fit(X, current, time=training.time)
    fitted = MomentumObserver("ur10", identify=identify).fit(X, current, time=training.time)
    assert np.all(fitted.residual_std_ < none.residual_std_)


@pytest.mark.realdata
def test_batch_equals_streaming_on_a_real_ur10e_push_recording(ur10e_dir):
    """Jittered real time stamps (2-34 ms), an observer identified on a real
    collision-free run: batch and per-tick residuals are identical, and the
    labelled pushes stand out of the quiet hold."""
    import json
    import warnings
    from pathlib import Path

    from sklearn_gpcd.features import CausalFeatures
    from sklearn_gpcd.io import load_recording

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        free = load_recording(ur10e_dir / "validation_data" / "ur-20_01_17-ptp_10_points.csv")
        push = load_recording(ur10e_dir / "collision_push_pose" / "ur-20_01_22-push_pose_1.csv")
    features = CausalFeatures().fit(free)
    obs = MomentumObserver("ur10e").fit(features.transform(free), free.current, time=free.time)
    X = features.transform(push)
    batch = obs.residual(X, push.current, time=push.time)
    stream = obs.stream()
    rows = np.array([stream.update(x, i, time=t).copy()
                     for x, i, t in zip(X, push.current, push.time)])
    np.testing.assert_array_equal(rows, batch)
    labels = Path(__file__).resolve().parents[1] / "benchmarks" / "labels" / "ur10e_events.json"
    events = json.loads(labels.read_text())["files"][
        "collision_push_pose/ur-20_01_22-push_pose_1.csv"]["events"]
    t = push.time - push.time[0]
    inside = np.zeros(len(t), dtype=bool)
    for event in events:
        inside |= (t >= event["start_s"]) & (t <= event["tail_stop_s"])
    peak_in = np.abs(batch[inside]).max(axis=0)
    peak_out = np.abs(batch[~inside]).max(axis=0)
    assert peak_in[1] > 3 * peak_out[1]  # joint 2, the most pushed
