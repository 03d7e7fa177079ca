"""Simulated pushes on known links of the UR10, shared by the observer and contact tests.

Each push acts on link ``k`` at a point about 9 cm off the joint axis, in a
direction within a cone around the one that loads joint ``k`` most, with a
peak torque on joint ``k`` of ``TARGET_TORQUE[k]`` (times 0.8-1.2): pushes
that joint ``k`` can see above the observer's thresholds (joint 1's are
about 24 Nm in this simulation, the wrist's about 4.5 Nm). The arm moves
slowly through random configurations meanwhile (at rest, a push below the
static friction does not change the current at all).
"""

import numpy as np
import pinocchio as pin

from sklearn_gpcd.contact import contact_point
from sklearn_gpcd.datasets import Contact, JointTrajectory, simulate_d1, simulate
from sklearn_gpcd.robots import load_robot

#: Peak torque [Nm] of a push on link k on joint k.
TARGET_TORQUE = {1: 30.0, 2: 40.0, 3: 30.0, 4: 10.0, 5: 10.0, 6: 10.0}
Q0 = np.array([0.0, -1.3, 1.4, -1.6, -1.57, 0.0])
PERIOD = 1.6  # s between push onsets
DURATION = 0.8  # s per push


def inputs(rec):
    """``[q, qd, qdd]`` of a simulated recording (the simulator logs the true qdd)."""
    return np.hstack([rec.q, rec.qd, rec.qdd])


def training_run(seed=0, n_targets=12):
    """Collision-free D1-like run to fit the observer on."""
    return simulate_d1("ur10", n_targets=n_targets, random_state=seed)


def design(seed, n_per_link=5):
    """The reference trajectory and the contacts (links 1..6 in turn)."""
    robot = load_robot("ur10")
    model, data = robot.model, robot.model.createData()
    rng = np.random.default_rng(seed)
    n_push = 6 * n_per_link
    duration = 2.0 + n_push * PERIOD
    points = Q0 + rng.uniform(-0.6, 0.6, size=(10, 6))
    points[0] = Q0
    reference = JointTrajectory.from_samples(np.linspace(0, duration, 10), points)
    contacts = []
    for i in range(n_push):
        link, start = 1 + i % 6, 1.0 + i * PERIOD
        q = reference.at(start + DURATION / 2)
        angle = rng.uniform(0, 2 * np.pi)
        point = (contact_point(robot, link) * rng.uniform(0.3, 0.9)
                 + 0.09 * np.array([np.cos(angle), np.sin(angle), 0.0]))
        pin.forwardKinematics(model, data, q)
        J = pin.computeJointJacobian(model, data, q, link)
        skew = np.array([[0, -point[2], point[1]], [point[2], 0, -point[0]],
                         [-point[1], point[0], 0]])
        column = (data.oMi[link].rotation @ (J[:3] - skew @ J[3:]))[:, link - 1]
        direction = column / np.linalg.norm(column) + 0.3 * rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        direction *= np.sign(column @ direction) * rng.choice([-1, 1])
        force = direction * TARGET_TORQUE[link] * rng.uniform(0.8, 1.2) / abs(column @ direction)
        contacts.append(Contact(link=link, start=start, duration=DURATION, force=force,
                                point=point, frame="world"))
    return reference, contacts


def push_runs(seed, n_per_link=5):
    """``(pushes, twin, contacts)``: the recording with the pushes and the same
    motion without them (another noise seed), for the thresholds."""
    reference, contacts = design(seed, n_per_link)
    pushes = simulate(reference, "ur10", contacts=contacts, random_state=seed)
    twin = simulate(reference, "ur10", random_state=seed + 100)
    return pushes, twin, contacts
