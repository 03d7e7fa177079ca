"""Gains of the simulated 1 kHz joint servo (PID + model feed-forward)."""

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .plant import drive_parameters, plant_model


@dataclass(frozen=True)
class ServoGains:
    """Per-joint gains and limits of the joint servo, in current units.

    The servo runs at the simulator's ``servo_rate`` and computes the
    commanded current (the paper's ``i_c``, Eq. 13)

    .. math::

        u &= i_{ff} + K_p e_q + K_d \\dot e_q + I, \\qquad
        e_q = q_r - q_m,\\; \\dot e_q = \\dot q_r - \\dot q, \\\\
        i_c &= \\operatorname{clip}(u, -i_{max}, i_{max}), \\\\
        I &\\leftarrow \\operatorname{clip}(I + K_i\\, e_q\\, \\Delta t,
              -I_{max}, I_{max}) \\quad \\text{if } |e_q| > e_{db}
              \\text{ and not } (u \\ne i_c \\text{ and } e_q u > 0),

    with ``q_m`` the quantised encoder position. The integrator stops inside
    a small deadband ``e_db`` (otherwise PI control against stiction hunts
    forever) and stops winding up while the output saturates in the
    direction it would push (conditional integration). ``i_ff`` is the model feed-forward current, see
    :func:`feedforward_torque`.

    Parameters
    ----------
    kp : ndarray of shape (n_joints,)
        Proportional gain [A/rad].
    kd : ndarray of shape (n_joints,)
        Derivative gain [A s/rad].
    ki : ndarray of shape (n_joints,)
        Integral gain [A/(rad s)].
    current_limit : ndarray of shape (n_joints,)
        Output saturation ``i_max`` [A].
    integral_limit : ndarray of shape (n_joints,)
        Integrator clamp ``I_max`` [A].
    integral_deadband : float, default=2e-4
        ``e_db`` [rad].
    friction_compensation : float, default=0.85
        Fraction of the nominal Coulomb + viscous friction added to the
        feed-forward (0 disables it).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.datasets import ServoGains
    >>> g = ServoGains(kp=np.ones(2), kd=np.ones(2), ki=np.ones(2),
    ...                current_limit=np.full(2, 10.0), integral_limit=np.full(2, 5.0),
    ...                integral_deadband=1e-4, friction_compensation=1.0)
    >>> g.n_joints
    2
    """

    kp: np.ndarray
    kd: np.ndarray
    ki: np.ndarray
    current_limit: np.ndarray
    integral_limit: np.ndarray
    integral_deadband: float = 2e-4
    friction_compensation: float = 0.85

    def __post_init__(self):
        n = None
        for key in ("kp", "kd", "ki", "current_limit", "integral_limit"):
            value = np.atleast_1d(np.asarray(getattr(self, key), dtype=float))
            if value.ndim != 1 or not np.all(np.isfinite(value)) or np.any(value < 0):
                raise ValueError(f"ServoGains.{key} must be finite values >= 0, got {value}")
            if n is None:
                n = value.size
            elif value.size != n:
                raise ValueError(f"ServoGains.{key} has {value.size} joints, kp has {n}")
            value.setflags(write=False)
            object.__setattr__(self, key, value)
        if not self.integral_deadband >= 0:
            raise ValueError(
                f"ServoGains.integral_deadband must be >= 0, got {self.integral_deadband}"
            )

    @property
    def n_joints(self):
        """Number of joints."""
        return self.kp.size


def servo_gains(robot, bandwidth=25.0, damping=1.0, integral_time=0.15,
                integral_deadband=2e-4, integral_fraction=0.25, friction_compensation=0.85):
    """Pole-placement PID gains from the robot's stretched-arm inertia.

    With ``m_l`` the diagonal of ``M_eq = M(q_0) + K_r^2 J_m`` (paper Eq. 4)
    at the stretched configuration ``q_0 = 0`` (the largest inertia of the
    proximal joints) and ``K_l`` the torque constant,

    .. math::

        K_p = m \\omega^2 / K,\\quad K_d = 2 \\zeta m \\omega / K,\\quad
        K_i = K_p / T_i ,

    a critically damped second-order loop of bandwidth ``omega`` for each
    decoupled joint; at 1 kHz ``omega dt << 1`` keeps the discrete loop
    stable.

    Parameters
    ----------
    robot : Robot
        Drive-train data from :func:`~sklearn_gpcd.datasets.plant.drive_parameters`
        (documented defaults where the robot has none).
    bandwidth : float, default=25.0
        ``omega`` [rad/s].
    damping : float, default=1.0
        ``zeta``.
    integral_time : float, default=0.15
        ``T_i`` [s].
    integral_deadband : float, default=2e-4
        Position error [rad] below which the integrator holds (0.24 mm at
        the flange of a UR10).
    integral_fraction : float, default=0.25
        Integrator clamp as a fraction of the current limit.
    friction_compensation : float, default=0.85
        Fraction of nominal friction in the feed-forward (servos compensate
        friction conservatively; full compensation invites limit cycles).

    Returns
    -------
    gains : ServoGains
        ``current_limit`` is ``effort_limits / torque_constants``.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.datasets import servo_gains
    >>> from sklearn_gpcd.robots import load_robot
    >>> robot = load_robot("ur10")
    >>> gains = servo_gains(robot, bandwidth=25.0)
    >>> gains.kp.shape
    (6,)
    >>> bool(np.allclose(gains.current_limit, robot.effort_limits / robot.torque_constants))
    True
    """
    model = plant_model(robot)
    inertia = np.diag(pin.crba(model, model.createData(), pin.neutral(model))).copy()
    k = drive_parameters(robot)[0]
    kp = inertia * bandwidth**2 / k
    current_limit = np.asarray(robot.effort_limits, dtype=float) / k
    return ServoGains(
        kp=kp,
        kd=2.0 * damping * inertia * bandwidth / k,
        ki=kp / integral_time,
        current_limit=current_limit,
        integral_limit=integral_fraction * current_limit,
        integral_deadband=integral_deadband,
        friction_compensation=friction_compensation,
    )


def feedforward_torque(model, data, q, qd, qdd, friction=None, friction_compensation=1.0,
                       smoothing_velocity=0.01):
    """Model feed-forward: inverse dynamics of the reference, row by row.

    .. math::

        \\tau_{ff} = M_{eq}(q_r) \\ddot q_r + C(q_r, \\dot q_r) \\dot q_r
            + g(q_r) + c \\left[F_c \\tanh(\\dot q_r / v_0) + F_v \\dot q_r\\right]

    (paper Eq. 4 without the unknown terms; ``M_eq`` includes the reflected
    rotor inertias when they are in ``model.armature``; the friction term uses
    a smooth sign with ``v_0 = smoothing_velocity``).

    Parameters
    ----------
    model, data : pinocchio.Model, pinocchio.Data
        The servo's (nominal) model.
    q, qd, qdd : ndarray of shape (n_times, n_joints)
        Reference trajectory samples.
    friction : JointFriction, default=None
        Nominal friction; None means no friction term.
    friction_compensation : float, default=1.0
        ``c``.
    smoothing_velocity : float, default=0.01
        ``v_0`` [rad/s].

    Returns
    -------
    tau_ff : ndarray of shape (n_times, n_joints)

    Examples
    --------
    Without friction, the feed-forward of a state at rest is the gravity
    torque, pinocchio's inverse dynamics:

    >>> import numpy as np
    >>> import pinocchio as pin
    >>> from sklearn_gpcd.datasets import feedforward_torque
    >>> from sklearn_gpcd.robots import load_robot
    >>> model = load_robot("ur10").model
    >>> data = model.createData()
    >>> q = np.array([[0.0, -1.57, 1.57, -1.57, -1.57, 0.0]])
    >>> tau = feedforward_torque(model, data, q, np.zeros_like(q), np.zeros_like(q))
    >>> bool(np.allclose(tau[0], pin.computeGeneralizedGravity(model, data, q[0])))
    True
    """
    tau = np.empty_like(q)
    rnea = pin.rnea
    for k in range(q.shape[0]):
        tau[k] = rnea(model, data, q[k], qd[k], qdd[k])
    if friction is not None and friction_compensation:
        tau += friction_compensation * (
            friction.coulomb * np.tanh(qd / smoothing_velocity) + friction.viscous * qd
        )
    return tau
