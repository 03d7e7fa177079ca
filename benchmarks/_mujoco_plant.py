"""A reference robot plant on MuJoCo, written independently of the package's simulator.

Used by ``benchmarks/second_engine.py`` and the opt-in slow tests to try the
diagnosis on physics it was not written against. Only the robot's geometry
and link inertias (the nominal model the diagnosis is given) and the joint
reference (random flange targets, :func:`sklearn_gpcd.datasets.reference_d1`)
come from the package; everything else is MuJoCo's or this module's own:

* integration: MuJoCo, 1 kHz, ``implicitfast`` integrator;
* dry friction: MuJoCo's ``frictionloss``, a constraint solved with the
  dynamics (soft near zero velocity: no ``sign(qd)`` law), viscous friction
  ``damping``, reflected rotor inertia ``armature``;
* joint servo: PD on position and velocity plus a feed-forward from MuJoCo's
  inverse dynamics of the *nominal* plant (no injected effect), at 1 kHz;
* logging at 125 Hz: position with encoder noise, velocity with noise (no
  acceleration: the diagnosis differentiates), current ``tau / K`` with
  noise;
* the injected effects (:class:`Injection`) acting on that plant.

MuJoCo is not a dependency of the package: install it with
``pip install mujoco`` to run this.
"""

from dataclasses import dataclass, field

import numpy as np

from sklearn_gpcd.datasets import reference_d1
from sklearn_gpcd.dynamics import stribeck_peak
from sklearn_gpcd.io import Recording

#: Plant friction of every run [Nm] and [Nm s/rad] (UR10-like levels).
FRICTIONLOSS = np.array([12.0, 12.0, 6.0, 2.5, 2.5, 2.5])
DAMPING = np.array([20.0, 20.0, 9.0, 3.5, 3.5, 3.5])
#: Servo gains [Nm/rad], [Nm s/rad].
KP = np.array([6000.0, 6000.0, 3000.0, 600.0, 600.0, 300.0])
KD = np.array([300.0, 300.0, 150.0, 30.0, 30.0, 15.0])
STEP = 0.001
LOG_EVERY = 8
CURRENT_NOISE = 0.02  # A
VELOCITY_NOISE = 1e-3  # rad/s
POSITION_NOISE = 2e-5  # rad


@dataclass
class Injection:
    """Effects injected into the MuJoCo plant (all zero: the control run).

    Joints are 0-based here (as in the package's arrays).
    """

    coulomb: dict = field(default_factory=dict)  # joint -> extra frictionloss [Nm]
    viscous: dict = field(default_factory=dict)  # joint -> extra damping [Nm s/rad]
    stribeck: dict = field(default_factory=dict)  # joint -> (peak [Nm], velocity [rad/s])
    rotor: dict = field(default_factory=dict)  # joint -> extra armature [kg m^2]
    payload: tuple = None  # (mass [kg], com in the flange frame [m])
    link_mass: tuple = None  # (joint index of the link, extra mass [kg] at its com)
    tilt: tuple = None  # (roll, pitch) [rad]
    torque_scale: dict = field(default_factory=dict)  # joint -> true K / nominal K
    offset: dict = field(default_factory=dict)  # joint -> current offset [A]
    delay: float = 0.0  # logged current lags by this [s]
    spring: dict = field(default_factory=dict)  # joint -> (stiffness, rest position)
    drift: dict = field(default_factory=dict)  # joint -> frictionloss rate [Nm/s]


def _quat(R):
    import mujoco

    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.asarray(R, dtype=float).ravel())
    return q


def mjcf(robot, armature, injection=None):
    """MJCF text of ``robot`` (a package Robot) with plant friction and injections."""
    inj = injection or Injection()
    model = robot.model
    frame = model.frames[robot.flange_frame_id]
    lines = ['<mujoco model="plant">',
             '<compiler angle="radian"/>',
             f'<option timestep="{STEP}" integrator="implicitfast"/>',
             "<worldbody>"]
    closing = []
    for i in range(1, model.njoints):
        j = i - 1
        placement = model.jointPlacements[i]
        inertia = model.inertias[i]
        mass = float(inertia.mass)
        if inj.link_mass is not None and inj.link_mass[0] == j:
            mass += float(inj.link_mass[1])  # point mass at the nominal centre of mass
        I = inertia.inertia
        pos = " ".join(f"{v:.9g}" for v in placement.translation)
        quat = " ".join(f"{v:.12g}" for v in _quat(placement.rotation))
        lines.append(f'<body name="link{i}" pos="{pos}" quat="{quat}">')
        full = f"{I[0, 0]:.9g} {I[1, 1]:.9g} {I[2, 2]:.9g} {I[0, 1]:.9g} {I[0, 2]:.9g} " \
               f"{I[1, 2]:.9g}"
        lever = " ".join(f"{v:.9g}" for v in inertia.lever)
        lines.append(f'<inertial pos="{lever}" mass="{mass:.9g}" fullinertia="{full}"/>')
        stiffness, ref = inj.spring.get(j, (0.0, 0.0))
        lines.append(
            f'<joint name="j{j}" type="hinge" axis="0 0 1" '
            f'armature="{armature[j] + inj.rotor.get(j, 0.0):.9g}" '
            f'damping="{DAMPING[j] + inj.viscous.get(j, 0.0):.9g}" '
            f'frictionloss="{FRICTIONLOSS[j] + inj.coulomb.get(j, 0.0):.9g}" '
            f'stiffness="{stiffness:.9g}" springref="{ref:.9g}"/>')
        closing.append("</body>")
        if i == int(frame.parentJoint) and inj.payload is not None:
            m, com = inj.payload
            p = frame.placement.translation + frame.placement.rotation @ np.asarray(com)
            lines.append(f'<body name="payload" pos="{p[0]:.9g} {p[1]:.9g} {p[2]:.9g}">'
                         f'<inertial pos="0 0 0" mass="{m:.9g}" diaginertia="1e-9 1e-9 1e-9"/>'
                         "</body>")
    lines += closing[::-1] + ["</worldbody>", "</mujoco>"]
    return "\n".join(lines)


def simulate(robot, torque_constants, armature, injection=None, n_targets=8,
             random_state=0, name=None, *, reference=None, contacts=(), log_targets=False):
    """One logged run of the plant following a D1-like reference.

    Parameters
    ----------
    robot : Robot
        The package's robot (geometry and link inertias).
    torque_constants, armature : ndarray of shape (6,)
        Nominal torque constants [Nm/A] and rotor inertias [kg m^2].
    injection : Injection, default=None
    n_targets : int, default=8
    random_state : int, default=0
        Seeds the reference and the noise.
    reference : JointTrajectory, default=None
        The joint reference to follow instead of the D1-like one (then
        ``n_targets`` is ignored; ``random_state`` still seeds the noise).
    contacts : sequence of sklearn_gpcd.datasets.Contact, default=()
        External pushes: each one's force (frame "world") acts at its
        ``point`` of link ``link`` (the MuJoCo body ``link{k}``, whose frame
        is the package's joint frame) with its time profile, through
        MuJoCo's ``mj_applyFT``; ``labels`` then mark them (0 free, k in the
        k-th contact) and ``metadata["contacts"]`` gives their start and
        stop in the recording's time.
    log_targets : bool, default=False
        Also log the controller's signals, as a UR does: ``target_q``,
        ``target_qd`` (the reference) and ``target_current``, the servo's
        feed-forward over the nominal torque constants (no feedback).

    Returns
    -------
    recording : Recording
        Current in A; ``qdd`` is None.
    """
    import mujoco

    inj = injection or Injection()
    plant = mujoco.MjModel.from_xml_string(mjcf(robot, armature, inj))
    nominal = mujoco.MjModel.from_xml_string(mjcf(robot, armature, None))
    if inj.tilt is not None:
        roll, pitch = inj.tilt
        g = 9.81
        # gravity (0, 0, -g) of the world seen in the base frame rotated by roll then pitch
        Rx = np.array([[1, 0, 0], [0, np.cos(roll), -np.sin(roll)],
                       [0, np.sin(roll), np.cos(roll)]])
        Ry = np.array([[np.cos(pitch), 0, np.sin(pitch)], [0, 1, 0],
                       [-np.sin(pitch), 0, np.cos(pitch)]])
        plant.opt.gravity[:] = (Rx @ Ry).T @ np.array([0.0, 0.0, -g])
    data, ff_data = mujoco.MjData(plant), mujoco.MjData(nominal)
    nominal.dof_frictionloss[:] = 0.0  # the servo's feed-forward has no friction model
    rng = np.random.default_rng(random_state)
    ref = (reference_d1(robot, n_targets=n_targets, random_state=random_state)
           if reference is None else reference)
    n_steps = int(ref.duration / STEP)
    t_all = np.arange(n_steps) * STEP
    q_ref, qd_ref, qdd_ref = ref.sample(t_all)
    data.qpos[:] = q_ref[0]
    base_loss = plant.dof_frictionloss.copy()
    scale = np.ones(6)
    for j, s in inj.torque_scale.items():
        scale[j] = s
    offset = np.zeros(6)
    for j, o in inj.offset.items():
        offset[j] = o
    log_t, log_q, log_qd, cur_t, cur_i = [], [], [], [], []
    log_k, ff_i = [], []
    bodies = [mujoco.mj_name2id(plant, mujoco.mjtObj.mjOBJ_BODY, f"link{c.link}")
              for c in contacts]
    for k in range(n_steps):
        t = t_all[k]
        for j, rate in inj.drift.items():
            plant.dof_frictionloss[j] = base_loss[j] + rate * t
        ff_data.qpos[:], ff_data.qvel[:], ff_data.qacc[:] = q_ref[k], qd_ref[k], qdd_ref[k]
        mujoco.mj_inverse(nominal, ff_data)
        tau = (ff_data.qfrc_inverse + KP * (q_ref[k] - data.qpos)
               + KD * (qd_ref[k] - data.qvel))
        applied = np.zeros(6)
        for j, (peak, vs) in inj.stribeck.items():
            v = data.qvel[j]
            applied[j] = -peak * stribeck_peak(v, vs)
        data.qfrc_applied[:] = applied
        data.ctrl[:] = 0.0
        data.qfrc_actuator[:] = 0.0
        data.qfrc_applied[:] += tau
        for contact, body in zip(contacts, bodies):
            s = float(contact.profile(t))
            if s > 0.0:  # kinematics of the last step (1 ms old)
                point = data.xpos[body] + data.xmat[body].reshape(3, 3) @ contact.point
                mujoco.mj_applyFT(plant, data, s * contact.force, s * contact.moment, point,
                                  body, data.qfrc_applied)
        # the logged current drives the joints: i = tau / K_true
        cur_t.append(t)
        cur_i.append(tau / (torque_constants * scale) + offset)
        if log_targets:
            ff_i.append(ff_data.qfrc_inverse / torque_constants)
        if k % LOG_EVERY == 0:
            log_t.append(t)
            log_q.append(data.qpos.copy())
            log_qd.append(data.qvel.copy())
            log_k.append(k)
        mujoco.mj_step(plant, data)
    rec = logged(log_t, log_q, log_qd, cur_t, cur_i, inj.delay, rng, name)
    if not (log_targets or len(contacts)):
        return rec
    # the samples logged() kept: the last rec.n_samples, shifted to start at 0
    kept = np.array(log_k[len(log_k) - rec.n_samples:])
    t0 = t_all[kept[0]]
    extra = {}
    if log_targets:
        extra.update(target_q=q_ref[kept], target_qd=qd_ref[kept],
                     target_current=np.array(ff_i)[kept])
    if len(contacts):
        from sklearn_gpcd.datasets import contact_labels

        extra["labels"] = contact_labels(t_all[kept], contacts)
        extra["metadata"] = {**rec.metadata, "contacts": [
            {"link": c.link, "start": c.start - t0, "stop": c.stop - t0,
             "force": c.force.tolist()} for c in contacts]}
    return rec.replace(**extra)


def logged(log_t, log_q, log_qd, cur_t, cur_i, delay, rng, name=None):
    """The logged recording: current delayed by ``delay``, sensor noise, start dropped.

    Shared by the plants of the blind protocol (``_pybullet_plant.py``).
    """
    log_t = np.array(log_t)
    cur_t, cur_i = np.array(cur_t), np.array(cur_i)
    current = np.column_stack([np.interp(log_t - delay, cur_t, cur_i[:, j])
                               for j in range(cur_i.shape[1])])
    q = np.array(log_q) + POSITION_NOISE * rng.normal(size=(len(log_t), cur_i.shape[1]))
    qd = np.array(log_qd) + VELOCITY_NOISE * rng.normal(size=(len(log_t), cur_i.shape[1]))
    current = current + CURRENT_NOISE * rng.normal(size=current.shape)
    keep = log_t >= max(delay, 0.0) + 0.1  # drop the start (servo settling)
    return Recording(time=log_t[keep] - log_t[keep][0], q=q[keep], qd=qd[keep],
                     current=current[keep], units="A", name=name)
