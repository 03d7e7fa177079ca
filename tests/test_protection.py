"""Protected at <= X N (issue 45): the smallest force at a point that the joint
thresholds always catch, exact from the vertices of the silent-force polytope."""

import numpy as np
import pinocchio as pin
import pytest

from sklearn_gpcd.contact import contact_point, protected_force
from sklearn_gpcd.robots import load_robot

Q = np.array([0.3, -1.2, 1.4, -1.5, -1.4, 0.2])


def _sampled(robot, q, thresholds, link, n=100_000):
    """``max over directions u of min_l thr_l / |J_l u|``, by sampling directions."""
    model, data = robot.model, robot.model.createData()
    p = contact_point(robot, link)
    pin.forwardKinematics(model, data, q)
    J = pin.computeJointJacobian(model, data, q, link)
    skew = np.array([[0, -p[2], p[1]], [p[2], 0, -p[0]], [-p[1], p[0], 0]])
    Jp = data.oMi[link].rotation @ (J[:3] - skew @ J[3:])
    u = np.random.default_rng(0).normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    with np.errstate(divide="ignore"):
        return float((thresholds / np.abs(u @ Jp)).min(axis=1).max())


@pytest.mark.parametrize("link", [3, 4, 6])
def test_the_vertex_is_the_worst_direction(link):
    robot = load_robot("ur10")
    thresholds = np.array([5.0, 6.0, 4.0, 3.0, 2.0, 2.0])
    exact = protected_force(robot, Q, thresholds, link=link)
    sampled = _sampled(robot, Q, thresholds, link)
    # sampling directions can only find a smaller worst case, and comes close
    assert sampled <= exact * (1 + 1e-9)
    assert sampled > 0.97 * exact


def test_a_force_above_x_is_seen_in_every_direction():
    robot = load_robot("ur10")
    thresholds = np.array([5.0, 6.0, 4.0, 3.0, 2.0, 2.0])
    x = protected_force(robot, Q, thresholds)
    model, data = robot.model, robot.model.createData()
    p = contact_point(robot, 6)
    pin.forwardKinematics(model, data, Q)
    J = pin.computeJointJacobian(model, data, Q, 6)
    skew = np.array([[0, -p[2], p[1]], [p[2], 0, -p[0]], [-p[1], p[0], 0]])
    Jp = data.oMi[6].rotation @ (J[:3] - skew @ J[3:])
    u = np.random.default_rng(1).normal(size=(20_000, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    tau = 1.01 * x * u @ Jp
    assert np.all((np.abs(tau) > thresholds).any(axis=1))


def test_scales_with_the_thresholds_and_batches():
    robot = load_robot("ur10")
    thresholds = np.array([5.0, 6.0, 4.0, 3.0, 2.0, 2.0])
    one = protected_force(robot, Q, thresholds)
    assert protected_force(robot, Q, 2 * thresholds) == pytest.approx(2 * one)
    batch = protected_force(robot, np.vstack([Q, Q + 0.1]), np.vstack([thresholds] * 2))
    assert batch.shape == (2,) and batch[0] == pytest.approx(one)
    # a joint that cannot alarm (inf) can only make the reach worse
    blind = thresholds.copy()
    blind[4] = np.inf
    assert protected_force(robot, Q, blind) >= one


def test_a_point_the_joints_cannot_see_in_3d_is_never_protected():
    # link 1 and 2 points: one and two joints for three force directions
    assert protected_force("ur10", Q, np.full(6, 5.0), link=1) == np.inf
    assert protected_force("ur10", Q, np.full(6, 5.0), link=2) == np.inf
    with pytest.raises(ValueError, match="thresholds must be > 0"):
        protected_force("ur10", Q, np.zeros(6))
