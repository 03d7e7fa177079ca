"""A UR-like joint-servo simulator on pinocchio, with real stiction.

The simulated plant is the rigid robot with motors behind rigid gears,
written in joint space and motor current (paper Eq. 4):

.. math::

    M_{eq}(q)\\ddot q + C(q,\\dot q)\\dot q + g(q) + \\tau_f
        = K_{eq}\\, i + \\tau_{ext} + \\tau_{spring},
    \\qquad M_{eq} = M + K_r^2 J_m,\\; K_{eq} = K_\\tau K_r ,

with the reflected rotor inertias ``K_r^2 J_m`` in ``model.armature`` (so
pinocchio's ABA/CRBA/RNEA include them), the viscous term ``B_eq`` inside the
friction law (:class:`~sklearn_gpcd.datasets.JointFriction`) and ``K_eq`` the
robot's ``torque_constants``.

Time stepping (servo period ``dt``, 1 ms by default) is semi-implicit Euler
with a Karnopp-type stick-slip scheme solved on the coupled dynamics:

1. Sliding friction ``tau_f = f_k(qd)`` for every joint with ``qd_l != 0``
   (zero for stuck joints) and the free velocity update
   ``v* = qd + dt M_eq^{-1} (K_eq i + tau_ext - C qd - g - f_k)``
   (``M_eq^{-1}`` from ``pinocchio.computeMinverse``).
2. Candidate stuck set ``S = {l : qd_l v*_l <= 0}``: joints at rest or whose
   velocity would cross zero in this tick. Their sliding friction is removed
   and replaced by the unknown holding friction ``f_S``, the one that makes
   their new velocity exactly zero,

   .. math::

       v^+ = v^* - \\Delta t\\, M_{eq}^{-1}[:, S] f_S,\\qquad
       v^+_S = 0 \\iff (\\Delta t\\, M_{eq}^{-1})_{SS}\\, f_S = v^*_S

   (when every joint is stuck, ``(M^{-1})_{SS}^{-1} = M_eq`` from CRBA; when
   every joint already rests, ``qd = 0``, this is the static balance
   ``f = K_eq i + tau_ext - g(q)`` and needs no inertia at all).
3. Static limit: if some ``|f_l| > F_s,l`` the joint with the largest excess
   breaks away -- its friction saturates at ``F_s,l sign(f_l)`` (the
   Stribeck law's value at zero speed, so the transition is continuous),
   it leaves ``S`` and ``f_S`` is solved again; repeat until the remaining
   joints hold. This is the mixed complementarity condition
   ``|f_l| < F_s => v+_l = 0``, ``v+_l != 0 => f_l = F_s sign(v+_l)``.
4. Stuck joints get ``qd_l = 0`` exactly; ``q <- q + dt v+``.

Semi-implicit Euler is stable here because the servo's bandwidth times
``dt`` is small (25 rad/s * 1 ms) and the reflected rotor inertias keep
``F_v dt / M_eq`` far below 1; the stick-slip projection removes the only
stiff element (the friction discontinuity) from the explicit update.

So at rest a joint truly sticks (zero velocity while the torque it must hold
stays inside ``+-F_s``) and the current holding it is whatever the servo's
integrator happened to reach -- it depends on the approach direction and
history, the behaviour the paper's quasi-static kernel is for (Sec. III-C).

Sensors: positions quantised to ``position_resolution`` (the servo sees them),
velocity from the motor-side encoder modelled exact (optionally noisy in the
log), current from a first-order current loop ``i <- i + dt/(tau_i + dt)
(i_c - i)`` plus Gaussian noise and offsets in the log only.
"""

import os
import time as _time

import numpy as np
import pinocchio as pin
from sklearn.utils import check_random_state

from ..dynamics.friction import stribeck_friction
from ..io import Recording
from ..robots import Robot, resolve_robot
from .contacts import Contact, contact_labels
from .friction import JointFriction, default_friction
from .plant import Plant, drive_parameters, plant_model
from .servo import ServoGains, feedforward_torque, servo_gains
from .trajectory import JointTrajectory

#: Servo ticks per reference/feed-forward chunk (memory vs. overhead).
_CHUNK = 2000
#: What a simulated log's ``target_current`` can be (``RobotSimulator(target_current=...)``).
TARGET_CURRENTS = ("command", "feedforward")


class RobotSimulator:
    """Simulate a built-in robot under a UR-like 1 kHz joint servo.

    See the module docstring for the dynamics and the stick-slip scheme.
    ``run`` drives the robot along a :class:`JointTrajectory` and returns a
    :class:`~sklearn_gpcd.io.Recording` sampled at ``sample_rate`` with the
    RTDE-like signals

    ``q``
        measured (quantised) positions;
    ``qd``
        velocities (exact motor-encoder velocity, exactly 0 while stuck, plus
        ``velocity_noise_std`` noise);
    ``qdd``
        true accelerations ``(qd[k+1] - qd[k]) / dt`` of the servo tick
        (noise free; UR does not log them);
    ``current``
        actual motor current plus noise and any :class:`CurrentOffset`;
    ``target_q``, ``target_qd``, ``target_qdd``
        the reference;
    ``target_current``
        with ``target_current="command"`` (the default) the servo's
        commanded current ``i_c`` (paper Eq. 13): feed-forward *and*
        feedback, so the current loop makes the measured current follow it
        within the sensor noise, contacts included; with
        ``"feedforward"`` only the model feed-forward current
        ``i_ff = tau_ff / K_eq`` (what a UR logs as its target current: a
        contact shows in ``current - target_current``);
    ``target_torque``
        the model feed-forward torque ``tau_ff`` (like UR's
        ``target_moment``);
    ``labels``
        0 in free motion, ``k`` during the k-th :class:`Contact`.

    ``metadata["truth"]`` holds noise-free signals at the same samples:
    ``qd``, ``current``, ``external_torque``, ``friction_torque``,
    ``motor_torque``, ``stuck`` (bool). Note that ``Recording.slice`` does not
    cut metadata.

    Parameters
    ----------
    robot : str, path or Robot, default="ur10"
        Built-in robot name, URDF path or a Robot. Missing torque
        constants or rotor inertias take the documented defaults of
        :func:`~sklearn_gpcd.datasets.plant.drive_parameters`.
    friction : JointFriction, default=None
        True friction; None means :func:`default_friction`.
    gains : ServoGains, default=None
        Servo gains; None means :func:`servo_gains` defaults.
    current_noise_std : float or array-like, default=0.03
        Std of the current sensor noise [A].
    velocity_noise_std : float or array-like, default=0.0
        Std of noise added to the logged velocity [rad/s].
    position_resolution : float, default=2*pi/2**20
        Encoder quantum [rad]; 0 disables quantisation.
    current_time_constant : float, default=0.002
        Time constant of the current loop [s].
    servo_rate : float, default=1000.0
        Servo and integration rate [Hz].
    sample_rate : float, default=125.0
        Log rate [Hz] (UR RTDE: 125 Hz); must divide ``servo_rate``.
    target_current : {"command", "feedforward"}, default="command"
        What the log's ``target_current`` is: the servo's full command
        (feedback included) or its model feed-forward part only.
    random_state : int, RandomState instance or None, default=None
        Seeds the sensor noise.

    Attributes
    ----------
    robot_ : Robot
        The simulated robot.
    friction_ : JointFriction
        Friction used (before effects).
    gains_ : ServoGains
        Servo gains used.
    real_time_factor_ : float
        Simulated seconds per wall-clock second of the last ``run``.

    Examples
    --------
    >>> from sklearn_gpcd.datasets import JointTrajectory, RobotSimulator
    >>> sim = RobotSimulator("ur10", random_state=0)
    >>> q0 = [0.0, -1.57, 1.57, -1.57, -1.57, 0.0]
    >>> rec = sim.run(JointTrajectory.rest(q0, 0.2))
    >>> rec.n_samples, rec.n_joints
    (26, 6)
    >>> bool((rec.qd == 0).all())
    True
    """

    def __init__(self, robot="ur10", *, friction=None, gains=None, current_noise_std=0.03,
                 velocity_noise_std=0.0, position_resolution=2 * np.pi / 2**20,
                 current_time_constant=0.002, servo_rate=1000.0, sample_rate=125.0,
                 target_current="command", random_state=None):
        self.robot = robot
        self.friction = friction
        self.gains = gains
        self.current_noise_std = current_noise_std
        self.velocity_noise_std = velocity_noise_std
        self.position_resolution = position_resolution
        self.current_time_constant = current_time_constant
        self.servo_rate = servo_rate
        self.sample_rate = sample_rate
        self.target_current = target_current
        self.random_state = random_state

    # ------------------------------------------------------------------ setup
    def _validate(self, reference, contacts, effects):
        if not isinstance(self.robot, (str, os.PathLike, Robot)):
            raise TypeError(
                f"robot must be a robot name, a URDF path or a Robot, got "
                f"{type(self.robot).__name__}"
            )
        robot = resolve_robot(self.robot)
        n = robot.n_joints
        if robot.model.nq != robot.model.nv or robot.model.nv != n:
            raise ValueError(
                f"robot {getattr(robot, 'name', '')!r}: simulator needs nq == nv == n_joints, got "
                f"nq={robot.model.nq}, nv={robot.model.nv}, n_joints={n}"
            )
        if not isinstance(reference, JointTrajectory):
            raise TypeError(f"reference must be a JointTrajectory, got {type(reference).__name__}")
        if reference.n_joints != n:
            raise ValueError(f"reference has {reference.n_joints} joints, robot has {n}")
        friction = default_friction(robot) if self.friction is None else self.friction
        if not isinstance(friction, JointFriction) or friction.n_joints != n:
            raise ValueError(f"friction must be a JointFriction with {n} joints, got {friction!r}")
        gains = servo_gains(robot) if self.gains is None else self.gains
        if not isinstance(gains, ServoGains) or gains.n_joints != n:
            raise ValueError(f"gains must be ServoGains with {n} joints, got {gains!r}")
        servo_rate, sample_rate = float(self.servo_rate), float(self.sample_rate)
        if not (servo_rate > 0 and sample_rate > 0):
            raise ValueError(
                f"servo_rate and sample_rate must be > 0, got {servo_rate}, {sample_rate}"
            )
        decimation = servo_rate / sample_rate
        if abs(decimation - round(decimation)) > 1e-9 or decimation < 1:
            raise ValueError(
                f"sample_rate ({sample_rate} Hz) must divide servo_rate ({servo_rate} Hz)"
            )
        for name in ("current_noise_std", "velocity_noise_std"):
            value = np.asarray(getattr(self, name), dtype=float)
            if value.ndim > 1 or (value.ndim == 1 and value.size != n) or np.any(value < 0):
                raise ValueError(f"{name} must be >= 0, scalar or one per joint, got {value}")
        if self.target_current not in TARGET_CURRENTS:
            raise ValueError(f"target_current must be one of {TARGET_CURRENTS}, got "
                             f"{self.target_current!r}")
        if not self.position_resolution >= 0:
            raise ValueError(f"position_resolution must be >= 0, got {self.position_resolution}")
        if not self.current_time_constant >= 0:
            raise ValueError(
                f"current_time_constant must be >= 0, got {self.current_time_constant}"
            )
        contacts = list(contacts)
        for k, contact in enumerate(contacts):
            if not isinstance(contact, Contact):
                raise TypeError(f"contacts[{k}] must be a Contact, got {type(contact).__name__}")
            if contact.link > n:
                raise ValueError(f"contacts[{k}].link={contact.link} but the robot has {n} links")
        effects = list(effects)
        for k, effect in enumerate(effects):
            if not callable(getattr(effect, "apply", None)) or not hasattr(effect, "start"):
                raise TypeError(
                    f"effects[{k}] ({type(effect).__name__}) needs start/stop and apply(plant)"
                )
        return robot, friction, gains, int(round(decimation)), contacts, effects

    # -------------------------------------------------------------------- run
    def run(self, reference, *, contacts=(), effects=(), name="simulation"):
        """Simulate tracking ``reference`` and log it.

        Parameters
        ----------
        reference : JointTrajectory
            Joint reference; the robot starts at rest at ``reference.at(0)``.
        contacts : sequence of Contact, default=()
            External forces; they define the ``labels``.
        effects : sequence of effects, default=()
            Injected plant changes (:class:`Payload`, :class:`FrictionChange`,
            ...), each active on ``[start, stop)``.
        name : str, default="simulation"
            Name of the recording.

        Returns
        -------
        recording : Recording
        """
        robot, friction, gains, decimation, contacts, effects = self._validate(
            reference, contacts, effects
        )
        rng = check_random_state(self.random_state)
        self.robot_, self.friction_, self.gains_ = robot, friction, gains
        wall = _time.perf_counter()
        log = _simulate(
            robot, reference, friction, gains, contacts, effects,
            dt=1.0 / float(self.servo_rate), decimation=decimation,
            resolution=float(self.position_resolution),
            current_time_constant=float(self.current_time_constant),
            feedforward_target=self.target_current == "feedforward",
        )
        wall = _time.perf_counter() - wall
        self.real_time_factor_ = reference.duration / wall if wall > 0 else np.inf

        n_samples, n = log["q"].shape
        current_noise = np.asarray(self.current_noise_std, dtype=float)
        velocity_noise = np.asarray(self.velocity_noise_std, dtype=float)
        current = log["current"] + log["current_offset"] + current_noise * rng.standard_normal(
            (n_samples, n)
        )
        qd = log["qd"]
        if np.any(velocity_noise > 0):
            qd = qd + velocity_noise * rng.standard_normal((n_samples, n))
        truth = {key: log[key] for key in
                 ("qd", "current", "external_torque", "friction_torque", "motor_torque", "stuck")}
        metadata = {
            "robot": getattr(robot, "name", type(robot).__name__),
            "sample_rate": float(self.sample_rate),
            "servo_rate": float(self.servo_rate),
            "current_noise_std": current_noise.tolist(),
            "target_current": self.target_current,
            "contacts": contacts,
            "effects": effects,
            "phases": reference.phases,
            "real_time_factor": self.real_time_factor_,
            "truth": truth,
        }
        return Recording(
            time=log["time"], q=log["q"], qd=qd, current=current, qdd=log["qdd"],
            target_q=log["target_q"], target_qd=log["target_qd"],
            target_qdd=log["target_qdd"], target_current=log["target_current"],
            target_torque=log["target_torque"], labels=contact_labels(log["time"], contacts),
            name=name, units="A", metadata=metadata,
        )


def simulate(reference, robot="ur10", *, contacts=(), effects=(), name="simulation",
             random_state=None, **params):
    """Simulate one run; shorthand for ``RobotSimulator(robot, ...).run(...)``.

    Parameters
    ----------
    reference : JointTrajectory
        Joint reference.
    robot : str or Robot, default="ur10"
        Built-in robot name or a Robot.
    contacts, effects : sequences, default=()
        See :meth:`RobotSimulator.run`.
    name : str, default="simulation"
        Name of the recording.
    random_state : int, RandomState instance or None, default=None
        Seeds the sensor noise.
    **params
        Other :class:`RobotSimulator` parameters.

    Returns
    -------
    recording : Recording

    Examples
    --------
    >>> from sklearn_gpcd.datasets import JointTrajectory, simulate
    >>> q0 = [0.0, -1.57, 1.57, -1.57, -1.57, 0.0]
    >>> move = JointTrajectory.point_to_point(q0, [0.3, -1.57, 1.57, -1.57, -1.57, 0.0], 1.0)
    >>> rec = simulate(move, "ur10", random_state=0)
    >>> bool(abs(rec.q[-1, 0] - 0.3) < 0.01)
    True
    """
    simulator = RobotSimulator(robot, random_state=random_state, **params)
    return simulator.run(reference, contacts=contacts, effects=effects, name=name)


def _events(effects, dt, n_steps):
    """(tick, order, effect) for every effect start and stop, sorted by tick."""
    events = []
    for k, effect in enumerate(effects):
        start = int(np.ceil(float(effect.start) / dt - 1e-9))
        events.append((max(start, 0), 1, k))
        stop = getattr(effect, "stop", None)
        if stop is not None and np.ceil(stop / dt - 1e-9) <= n_steps:
            events.append((int(np.ceil(float(stop) / dt - 1e-9)), 0, k))  # stops first
    return sorted(events)


def _hold_friction(v, v_free, f_slide, minv, dt, static, model, data, q):
    """Karnopp stick-slip projection (module docstring, steps 2-4).

    Parameters
    ----------
    v : ndarray of shape (n,)
        Velocity at the start of the tick.
    v_free : ndarray of shape (n,)
        Velocity after the tick with sliding friction ``f_slide`` only.
    f_slide : ndarray of shape (n,)
        Sliding friction used for ``v_free`` (zero where ``v == 0``).
    minv : ndarray of shape (n, n)
        ``M_eq^{-1}(q)``.
    dt : float
        Servo period.
    static : ndarray of shape (n,)
        Static friction limits ``F_s``.
    model, data, q
        For ``M_eq`` (CRBA) when every joint sticks.

    Returns
    -------
    v_new : ndarray of shape (n,)
        Velocity after the tick, exactly 0 on stuck joints.
    friction : ndarray of shape (n,)
        Friction torque acting in the tick.
    """
    stuck = (v * v_free <= 0.0).nonzero()[0]
    friction = f_slide.copy()
    if f_slide[stuck].any():  # replace their sliding friction by the unknown one
        v_free = v_free + dt * (minv[:, stuck] @ f_slide[stuck])
        friction[stuck] = 0.0
    n = v.size
    while stuck.size:
        if stuck.size == 1:  # scalar fast path (one joint resting)
            joint = int(stuck[0])
            f_hold = float(v_free[joint]) / (dt * float(minv[joint, joint]))
            if abs(f_hold) > static[joint]:  # breaks away
                f_hold = float(static[joint]) * (1.0 if f_hold > 0.0 else -1.0)
                friction[joint] = f_hold
                return v_free - (dt * f_hold) * minv[:, joint], friction
            friction[joint] = f_hold
            v_new = v_free - (dt * f_hold) * minv[:, joint]
            v_new[joint] = 0.0
            return v_new, friction
        if stuck.size == n:  # ((M^-1)_SS)^-1 = M
            f_hold = pin.crba(model, data, q) @ v_free / dt
        else:
            f_hold = np.linalg.solve(minv[stuck][:, stuck], v_free[stuck]) / dt
        excess = np.abs(f_hold) - static[stuck]
        worst = int(np.argmax(excess))
        if excess[worst] <= 0.0:  # all remaining joints hold
            friction[stuck] = f_hold
            v_new = v_free - dt * (minv[:, stuck] @ f_hold)
            v_new[stuck] = 0.0
            return v_new, friction
        joint = stuck[worst]  # breaks away: friction saturates at the static level
        friction[joint] = static[joint] * np.sign(f_hold[worst])
        v_free = v_free - (dt * friction[joint]) * minv[:, joint]
        stuck = np.delete(stuck, worst)
    return v_free, friction


def _simulate(robot, reference, friction, gains, contacts, effects, *, dt, decimation,
              resolution, current_time_constant, feedforward_target=False):
    """The servo loop. Returns a dict of logged arrays (noise free).

    Lean on purpose (about 30 small numpy operations and two or three
    pinocchio calls per tick): the reference and the feed-forward are
    evaluated per chunk of ticks, and when every joint is at rest the
    stick test reduces to the static balance ``|K i + tau_ext - g(q)| <= F_s``.
    """
    n = robot.n_joints
    model = plant_model(robot)  # plant (true robot): effects may change it
    data = model.createData()
    nominal = plant_model(robot)  # the servo's model
    nominal_data = nominal.createData()
    k_nominal = drive_parameters(robot)[0]

    n_steps = int(round(reference.duration / dt))
    log_steps = np.arange(0, n_steps + 1, decimation)
    n_log = log_steps.size
    names = ("q", "qd", "qdd", "current", "target_q", "target_qd", "target_qdd",
             "target_current", "target_torque", "external_torque", "friction_torque",
             "motor_torque", "current_offset")
    out = {key: np.empty((n_log, n)) for key in names}
    out["stuck"] = np.zeros((n_log, n), dtype=bool)
    out["time"] = log_steps * dt

    q = reference.at(0.0).copy()
    v = np.zeros(n)
    at_rest = True  # every joint has v == 0
    plant = Plant(robot, model, friction, dt, q)
    integral = np.zeros(n)
    kp, kd, ki_dt = gains.kp, gains.kd, gains.ki * dt
    i_max, int_max, deadband = gains.current_limit, gains.integral_limit, gains.integral_deadband
    alpha = dt / (current_time_constant + dt)
    inv_res = 1.0 / resolution if resolution > 0 else 0.0
    events = _events(effects, dt, n_steps)
    next_event = events[0][0] if events else n_steps + 1
    undo = {}
    history = None  # commanded currents, newest first, while a delay is active
    current = None
    zeros = np.zeros(n)
    tau_ext = zeros

    def refresh():
        fr = plant.friction
        return (plant.torque_constants, fr.coulomb, fr.viscous, fr.stribeck_velocity, fr.static,
                plant.spring_stiffness, plant.spring_rest, bool(np.any(plant.spring_stiffness)),
                plant.current_delay)

    (k_true, f_c, f_v, v_s, f_s, k_spring, q_spring, has_spring,
     delay) = refresh()
    minverse, gravity_and_coriolis, hold = pin.computeMinverse, pin.nonLinearEffects, _hold_friction
    minimum, maximum, absolute = np.minimum, np.maximum, np.abs
    log_i = 0

    for chunk_start in range(0, n_steps + 1, _CHUNK):
        ticks = np.arange(chunk_start, min(chunk_start + _CHUNK, n_steps + 1))
        q_ref, qd_ref, qdd_ref = reference.sample(ticks * dt)
        tau_ff = feedforward_torque(nominal, nominal_data, q_ref, qd_ref, qdd_ref, friction,
                                    gains.friction_compensation)
        i_ff = tau_ff / k_nominal
        scales = np.zeros((len(contacts), ticks.size))
        for c, contact in enumerate(contacts):
            scales[c] = contact.profile(ticks * dt)
        touching = scales.any(axis=0).tolist()

        for j, k in enumerate(ticks.tolist()):
            while k >= next_event:  # effects start/stop
                _, starting, index = events.pop(0)
                if starting:
                    plant.q = q
                    undo[index] = effects[index].apply(plant)
                elif index in undo:
                    undo.pop(index)()
                (k_true, f_c, f_v, v_s, f_s, k_spring, q_spring, has_spring,
                 delay) = refresh()
                next_event = events[0][0] if events else n_steps + 1

            # sensing: quantised encoder; exact motor-side velocity
            q_meas = np.rint(q * inv_res) * resolution if inv_res else q
            # servo (ServoGains docstring): PID + feed-forward, deadband, anti-windup
            e = q_ref[j] - q_meas
            u_pd = i_ff[j] + kp * e + kd * (qd_ref[j] - v)
            integral_new = integral + ki_dt * e * (absolute(e) > deadband)
            integral_new = minimum(maximum(integral_new, -int_max), int_max)
            i_c = u_pd + integral_new
            saturated = absolute(i_c) > i_max
            if saturated.any():
                winding = saturated & (e * i_c > 0.0)
                integral = np.where(winding, integral, integral_new)
                i_c = minimum(maximum(u_pd + integral, -i_max), i_max)
            else:
                integral = integral_new
            # current loop, optionally fed with a delayed command
            if current is None:
                current = i_c.copy()
            command = i_c
            if delay:
                if history is None or history.shape[0] < delay + 1:
                    history = np.repeat(i_c[None], delay + 1, axis=0)
                history = np.roll(history, 1, axis=0)
                history[0] = i_c
                command = history[delay]
            current = current + alpha * (command - current)
            tau_motor = k_true * current
            tau = tau_motor
            if has_spring:
                tau = tau - k_spring * (q - q_spring)
            if touching[j]:
                tau_ext = zeros
                for c, contact in enumerate(contacts):
                    if scales[c, j] > 0.0:
                        tau_ext = tau_ext + contact.joint_torque(model, data, q, scales[c, j])
                tau = tau + tau_ext
            else:
                tau_ext = zeros
            # dynamics: sliding friction, free step, stick-slip projection
            if at_rest:  # all stuck: static balance decides, no inertia needed
                f_total = tau - gravity_and_coriolis(model, data, q, v)
                if (absolute(f_total) <= f_s).all():
                    v_new = v
                else:
                    minv = minverse(model, data, q)
                    v_new, f_total = hold(v, dt * (minv @ f_total), zeros, minv, dt, f_s,
                                          model, data, q)
            else:
                minv = minverse(model, data, q)
                f_slide = stribeck_friction(v, f_c, f_s, f_v, v_s)
                v_free = v + dt * (minv @ (tau - gravity_and_coriolis(model, data, q, v) - f_slide))
                if (v * v_free).min() <= 0.0:
                    v_new, f_total = hold(v, v_free, f_slide, minv, dt, f_s, model, data, q)
                else:
                    v_new, f_total = v_free, f_slide

            if k % decimation == 0:
                out["q"][log_i] = q_meas
                out["qd"][log_i] = v
                out["qdd"][log_i] = (v_new - v) / dt
                out["current"][log_i] = current
                out["target_q"][log_i] = q_ref[j]
                out["target_qd"][log_i] = qd_ref[j]
                out["target_qdd"][log_i] = qdd_ref[j]
                out["target_current"][log_i] = i_ff[j] if feedforward_target else i_c
                out["target_torque"][log_i] = tau_ff[j]
                out["external_torque"][log_i] = tau_ext
                out["friction_torque"][log_i] = f_total
                out["motor_torque"][log_i] = tau_motor
                out["current_offset"][log_i] = plant.current_offset
                out["stuck"][log_i] = v_new == 0.0
                log_i += 1
            if v_new is not v:
                v = v_new
                at_rest = not v.any()
                q = q + dt * v
    return out
