"""A second reference robot plant, on PyBullet (Bullet's Featherstone multibody).

Used by ``benchmarks/blind_protocol.py`` next to the MuJoCo plant
(``benchmarks/_mujoco_plant.py``) so that the blind cases come from two
engines the package does not use. Only the robot's geometry and link
inertias come from the package; the rest is PyBullet's or this module's:

* the robot is written out as a URDF (:func:`urdf`) that PyBullet loads
  with its inertias; the reflected rotor inertia of each joint is added to
  its link's inertia as a thin disc on the joint axis (Bullet has no
  armature: ``J`` about the axis, ``J / 2`` across it), and the
  *same* URDF is the nominal model the diagnosis gets (:func:`nominal_robot`,
  rotor inertias zero), so the nominal model is exact but for the injected
  effects;
* integration: PyBullet ``stepSimulation`` at 1 kHz (semi-implicit Euler,
  constraint solver);
* dry friction: each joint's velocity motor held at zero velocity with a
  maximum force equal to the Coulomb level (a constraint solved with the
  dynamics, not a ``sign(qd)`` law), viscous friction applied as a torque;
* joint servo: the MuJoCo plant's PD gains on position and velocity plus a
  feed-forward from PyBullet's inverse dynamics of the *nominal* URDF in a
  second physics client (plus the nominal viscous friction), at 1 kHz;
* logging at 125 Hz with the MuJoCo plant's sensor noise
  (``_mujoco_plant.logged``);
* the injected effects (:class:`Injection` of ``_mujoco_plant``; the fields
  used here are ``coulomb``, ``viscous``, ``stribeck``, ``payload``,
  ``torque_scale``, ``offset``, ``delay`` and ``drift``).

PyBullet is not a dependency of the package: install it with
``pip install pybullet`` (the ``second-engine`` extra) to run this.
"""

import os
import tempfile

import numpy as np
from _mujoco_plant import KD, KP, LOG_EVERY, STEP, logged

from sklearn_gpcd.datasets import reference_d1
from sklearn_gpcd.robots import load_robot

#: Plant friction of every run [Nm] and [Nm s/rad] (other levels than the MuJoCo plant's).
COULOMB = np.array([9.0, 9.0, 5.0, 2.0, 2.0, 2.0])
VISCOUS = np.array([15.0, 15.0, 7.0, 3.0, 3.0, 3.0])


def _rpy(R):
    """URDF roll-pitch-yaw of a rotation matrix (R = Rz(y) Ry(p) Rx(r))."""
    R = np.asarray(R, dtype=float)
    pitch = np.arcsin(-np.clip(R[2, 0], -1.0, 1.0))
    if abs(np.cos(pitch)) > 1e-9:
        roll = np.arctan2(R[2, 1], R[2, 2])
        yaw = np.arctan2(R[1, 0], R[0, 0])
    else:  # gimbal lock
        roll, yaw = np.arctan2(-R[1, 2], R[1, 1]), 0.0
    return roll, pitch, yaw


def _v(values):
    return " ".join(f"{v:.12g}" for v in values)


#: Inertial of the massless frames (Bullet gives a link without one 1 kg).
_TINY = ('<inertial><origin xyz="0 0 0" rpy="0 0 0"/><mass value="1e-9"/>'
         '<inertia ixx="1e-12" ixy="0" ixz="0" iyy="1e-12" iyz="0" izz="1e-12"/></inertial>')


def urdf(robot, armature, payload=None):
    """URDF text of ``robot``: link inertias plus ``armature`` about each joint axis.

    ``payload`` is ``(mass, com in the flange frame)`` or None.
    """
    model = robot.model
    frame = model.frames[robot.flange_frame_id]
    lines = ['<?xml version="1.0"?>', '<robot name="ur10">',
             f'<link name="base_link">{_TINY}</link>']
    for i in range(1, model.njoints):
        j = i - 1
        inertia = model.inertias[i]
        I = np.array(inertia.inertia, dtype=float)
        # the rotor as a thin disc on the joint axis (z of the joint frame): J about the
        # axis, J / 2 across it (keeps the triangle inequality Bullet checks)
        I += np.diag([0.5, 0.5, 1.0]) * armature[j]
        lines.append(
            f'<link name="link{i}"><inertial><origin xyz="{_v(inertia.lever)}" rpy="0 0 0"/>'
            f'<mass value="{float(inertia.mass):.12g}"/>'
            f'<inertia ixx="{I[0, 0]:.12g}" ixy="{I[0, 1]:.12g}" ixz="{I[0, 2]:.12g}" '
            f'iyy="{I[1, 1]:.12g}" iyz="{I[1, 2]:.12g}" izz="{I[2, 2]:.12g}"/>'
            '</inertial></link>')
        placement = model.jointPlacements[i]
        parent = "base_link" if i == 1 else f"link{i - 1}"
        lines.append(
            f'<joint name="j{j}" type="revolute"><parent link="{parent}"/>'
            f'<child link="link{i}"/><origin xyz="{_v(placement.translation)}" '
            f'rpy="{_v(_rpy(placement.rotation))}"/><axis xyz="0 0 1"/><limit lower="-12.6" upper="12.6" effort="1000" velocity="10"/></joint>')
    last = model.njoints - 1
    assert int(frame.parentJoint) == last
    lines.append(f'<link name="flange">{_TINY}</link>')
    lines.append(
        f'<joint name="flange_joint" type="fixed"><parent link="link{last}"/>'
        f'<child link="flange"/><origin xyz="{_v(frame.placement.translation)}" '
        f'rpy="{_v(_rpy(frame.placement.rotation))}"/></joint>')
    if payload is not None:
        m, com = payload
        lines.append(
            f'<link name="payload"><inertial><origin xyz="{_v(com)}" rpy="0 0 0"/>'
            f'<mass value="{m:.12g}"/><inertia ixx="1e-6" ixy="0" ixz="0" iyy="1e-6" '
            'iyz="0" izz="1e-6"/></inertial></link>')
        lines.append('<joint name="payload_joint" type="fixed"><parent link="flange"/>'
                     '<child link="payload"/><origin xyz="0 0 0" rpy="0 0 0"/></joint>')
    lines.append("</robot>")
    return "\n".join(lines)


def _write(text, directory):
    fd, path = tempfile.mkstemp(suffix=".urdf", dir=directory)
    with os.fdopen(fd, "w") as fh:
        fh.write(text)
    return path


def nominal_robot(robot, torque_constants, armature):
    """The nominal model of this plant: its own URDF, rotor inertias in the links."""
    with tempfile.TemporaryDirectory() as tmp:
        path = _write(urdf(robot, armature), tmp)
        return load_robot(path, torque_constants=torque_constants,
                          rotor_inertias=np.zeros(len(armature)), flange_frame="flange",
                          name="ur10")


def _client(text, tmp):
    import pybullet as pb

    client = pb.connect(pb.DIRECT)
    pb.setGravity(0.0, 0.0, -9.81, physicsClientId=client)
    pb.setTimeStep(STEP, physicsClientId=client)
    body = pb.loadURDF(_write(text, tmp), useFixedBase=True,
                       flags=pb.URDF_USE_INERTIA_FROM_FILE, physicsClientId=client)
    joints = [k for k in range(pb.getNumJoints(body, physicsClientId=client))
              if pb.getJointInfo(body, k, physicsClientId=client)[2] == pb.JOINT_REVOLUTE]
    for k in range(-1, pb.getNumJoints(body, physicsClientId=client)):
        pb.changeDynamics(body, k, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0,
                          physicsClientId=client)
    return client, body, joints


def simulate(robot, torque_constants, armature, injection, n_targets=8, random_state=0,
             name=None, *, reference=None):
    """One logged run of the PyBullet plant following a D1-like reference (or ``reference``).

    Same arguments and outputs as ``_mujoco_plant.simulate``.
    """
    import pybullet as pb

    inj = injection
    rng = np.random.default_rng(random_state)
    ref = (reference_d1(robot, n_targets=n_targets, random_state=random_state)
           if reference is None else reference)
    n_steps = int(ref.duration / STEP)
    t_all = np.arange(n_steps) * STEP
    q_ref, qd_ref, qdd_ref = ref.sample(t_all)
    coulomb, viscous = COULOMB.copy(), VISCOUS.copy()
    for j, d in inj.coulomb.items():
        coulomb[j] += d
    for j, d in inj.viscous.items():
        viscous[j] += d
    scale, offset = np.ones(6), np.zeros(6)
    for j, s in inj.torque_scale.items():
        scale[j] = s
    for j, o in inj.offset.items():
        offset[j] = o
    with tempfile.TemporaryDirectory() as tmp:
        plant, body, joints = _client(urdf(robot, armature, inj.payload), tmp)
        nom, nbody, _ = _client(urdf(robot, armature), tmp)
        try:
            for k, j in enumerate(joints):
                pb.resetJointState(body, j, q_ref[0, k], 0.0, physicsClientId=plant)
            log_t, log_q, log_qd, cur_i = [], [], [], []
            for n in range(n_steps):
                t = t_all[n]
                loss = coulomb.copy()
                for j, rate in inj.drift.items():
                    loss[j] = coulomb[j] + rate * t
                # dry friction: the velocity motor at zero speed, force-limited
                pb.setJointMotorControlArray(body, joints, pb.VELOCITY_CONTROL,
                                             targetVelocities=[0.0] * 6,
                                             forces=np.maximum(loss, 0.0).tolist(),
                                             physicsClientId=plant)
                states = pb.getJointStates(body, joints, physicsClientId=plant)
                q = np.array([s[0] for s in states])
                qd = np.array([s[1] for s in states])
                ff = np.array(pb.calculateInverseDynamics(
                    nbody, q_ref[n].tolist(), qd_ref[n].tolist(), qdd_ref[n].tolist(),
                    physicsClientId=nom)) + VISCOUS * qd_ref[n]
                tau = ff + KP * (q_ref[n] - q) + KD * (qd_ref[n] - qd)
                applied = tau - viscous * qd
                for j, (peak, vs) in inj.stribeck.items():
                    applied[j] -= peak * np.sign(qd[j]) * np.exp(-(qd[j] / vs) ** 2)
                pb.setJointMotorControlArray(body, joints, pb.TORQUE_CONTROL,
                                             forces=applied.tolist(), physicsClientId=plant)
                cur_i.append(tau / (torque_constants * scale) + offset)
                if n % LOG_EVERY == 0:
                    log_t.append(t)
                    log_q.append(q)
                    log_qd.append(qd)
                pb.stepSimulation(physicsClientId=plant)
        finally:
            pb.disconnect(plant)
            pb.disconnect(nom)
    return logged(log_t, log_q, log_qd, t_all, cur_i, inj.delay, rng, name)
