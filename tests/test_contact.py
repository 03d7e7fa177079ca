"""Isolation and force estimation after an alarm, on simulated pushes on known links."""

import numpy as np
import pinocchio as pin
import pytest

from sklearn_gpcd.contact import (
    LINK_GROUPS,
    contact_point,
    describe_alarms,
    estimate_force,
    isolate_contact,
    link_group,
)
from sklearn_gpcd.dynamics import MomentumObserver
from sklearn_gpcd.robots import load_robot

from _pushes import inputs, push_runs, training_run


@pytest.fixture(scope="module")
def simulated():
    """Observer residuals on 30 pushes (5 per link), thresholds from the twin run."""
    train = training_run()
    obs = MomentumObserver("ur10", identify="friction").fit(inputs(train), train.current,
                                                            time=train.time)
    pushes, twin, contacts = push_runs(seed=3, n_per_link=5)
    free = obs.external_torque(inputs(twin), twin.current, time=twin.time)
    thresholds = 1.2 * np.abs(free).max(axis=0)  # largest collision-free excursion, margin
    r = obs.external_torque(inputs(pushes), pushes.current, time=pushes.time)
    return obs, pushes, contacts, r, thresholds


def test_isolation_on_simulated_pushes_on_each_link(simulated):
    _, pushes, contacts, r, thresholds = simulated
    found = {link: [] for link in range(1, 7)}
    for k, contact in enumerate(contacts, start=1):
        out = isolate_contact(r[pushes.labels == k], thresholds)
        found[contact.link].append(out.link == contact.link)
        assert 0.0 <= out.confidence <= 1.0
    hits = sum(sum(v) for v in found.values())
    assert hits >= 0.95 * len(contacts), found
    assert all(sum(v) >= 4 for v in found.values()), found  # >= 80 % on every link


def test_force_magnitude_in_well_conditioned_poses(simulated):
    """Pushes of known force: the estimate at the samples where the whitened
    residual is within 80 % of its peak, against the true force there."""
    obs, pushes, contacts, r, _ = simulated
    robot = obs.robot_
    std = obs.residual_std_ * obs.torque_constants_
    checked, errors = 0, []
    for k, contact in enumerate(contacts, start=1):
        rows = np.flatnonzero(pushes.labels == k)
        whitened = np.linalg.norm(r[rows] / std, axis=1)
        rows = rows[whitened >= 0.8 * whitened.max()]
        out = estimate_force(robot, pushes.q[rows], r[rows], link=contact.link,
                             point=contact.point, torque_std=std)
        estimated = np.median(out.magnitude)
        if not (out.well_conditioned.all() and np.median(out.magnitude_std) <= 0.1 * estimated):
            continue
        true = np.median(np.linalg.norm(contact.force) * contact.profile(pushes.time[rows]))
        checked += 1
        errors.append(abs(estimated / true - 1))
    assert checked >= 15, checked
    assert max(errors) <= 0.2, errors


def test_isolation_rule():
    thresholds = np.ones(6)
    # joints beyond the link quiet, the link's joint loud: that link
    out = isolate_contact([[2.0, 5.0, 0.2, 0.1, 0.1, 0.1]], thresholds)
    assert (out.link, out.group) == (2, "link 2") and out.confidence > 0.9
    # the most distal significant joint wins, whatever the magnitudes
    assert isolate_contact([[9.0, 9.0, 9.0, 0.1, 1.5, 0.1]], thresholds).link == 5
    # nothing significant: the largest ratio, with a low confidence
    out = isolate_contact([[0.2, 0.5, 0.3, 0.1, 0.1, 0.1]], thresholds)
    assert out.link == 2 and out.confidence < 0.5
    # per-sample thresholds (regimes) and a peak over the event
    signal = np.zeros((5, 6))
    signal[2, 3] = 0.5
    per_sample = np.ones((5, 6))
    per_sample[2, 3] = 0.25
    assert isolate_contact(signal, per_sample).link == 4
    out = isolate_contact(signal, per_sample)
    np.testing.assert_allclose(out.probabilities.sum() + out.no_contact, 1.0)
    with pytest.raises(ValueError, match="thresholds"):
        isolate_contact(signal, np.zeros(6))
    assert [link_group(k) for k in range(1, 7)] == [
        "link 1", "link 2", "link 3", "wrist", "wrist", "wrist"]
    assert sorted(sum(LINK_GROUPS.values(), ())) == [1, 2, 3, 4, 5, 6]


def test_force_is_exact_without_noise_and_flags_ill_conditioning():
    robot = load_robot("ur10")
    model, data = robot.model, robot.model.createData()
    rng = np.random.default_rng(0)
    for link in (3, 4, 5, 6):
        q = np.array([0.3, -1.2, 1.4, -1.5, -1.4, 0.2]) + rng.uniform(-0.3, 0.3, 6)
        point = contact_point(robot, link) * 0.5 + [0.05, 0.03, 0.0]
        pin.forwardKinematics(model, data, q)
        J = pin.computeJointJacobian(model, data, q, link)
        force_world = rng.normal(size=3) * 50
        local = data.oMi[link].rotation.T @ force_world
        tau = J[:3].T @ local + J[3:].T @ np.cross(point, local)
        out = estimate_force(robot, q, tau, link=link, point=point,
                             torque_std=np.full(6, 0.5))
        np.testing.assert_allclose(out.force, force_world, rtol=1e-8, atol=1e-8)
        assert out.rank == 3 and np.isfinite(out.condition) and out.magnitude_std > 0
    # link 2: two joints see the force, three unknowns -> rank 2, flagged
    q = np.array([0.3, -1.2, 1.4, -1.5, -1.4, 0.2])
    out = estimate_force(robot, q, [5.0, 20.0, 0, 0, 0, 0], link=2)
    assert out.rank == 2 and not out.well_conditioned and out.condition == np.inf
    # batch form: one row per sample
    batch = estimate_force(robot, np.tile(q, (3, 1)), np.tile([5.0, 20.0, 0, 0, 0, 0], (3, 1)),
                           link=2)
    np.testing.assert_allclose(batch.magnitude, out.magnitude)
    # the default point is the link's frame; a point on joint 1's axis gives it no torque
    np.testing.assert_allclose(contact_point(robot, 3), model.frames[
        model.getFrameId("forearm_link")].placement.translation)
    assert estimate_force(robot, q, [10.0, 0, 0, 0, 0, 0], link=1).rank == 0


def test_describe_alarms_on_the_simulated_pushes(simulated):
    """The alarms of the thresholds themselves, as a monitor would raise them:
    one event per push, each on its link, with a force."""
    obs, pushes, contacts, r, thresholds = simulated
    alarms = np.abs(r) > thresholds
    events = describe_alarms(alarms, r, thresholds, time=pushes.time, merge_gap=0.3,
                             robot=obs.robot_, q=pushes.q, torque=r,
                             torque_std=obs.residual_std_ * obs.torque_constants_,
                             points={c.link: c.point for c in contacts[:6]})
    found = set()
    for event in events:  # every event lies in one push and names its link
        k = pushes.labels[event["start"]:event["stop"]].max()
        assert k > 0 and k not in found, event
        found.add(k)
        assert event["link"] == contacts[k - 1].link
        assert event["force_N"] > 0 and event["force_sample"] in range(event["start"],
                                                                        event["stop"])
    assert len(found) >= 0.9 * len(contacts)  # raw thresholds: no filter, no debounce
    # a sample-index run without time, merged runs
    fired = np.zeros((8, 6), dtype=bool)
    fired[[1, 2, 4], 1] = True
    signal = np.where(fired, 2.0, 0.0)
    assert [(e["start"], e["stop"]) for e in describe_alarms(fired, signal, 1.0)] == [(1, 3),
                                                                                        (4, 5)]
    assert [(e["start"], e["stop"]) for e in describe_alarms(fired, signal, 1.0,
                                                             merge_gap=2)] == [(1, 5)]
