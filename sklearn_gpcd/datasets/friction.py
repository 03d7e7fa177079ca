"""Joint friction of the simulated robot: Stribeck sliding law plus stiction."""

from dataclasses import dataclass

import numpy as np

from ..dynamics.friction import stribeck_friction

#: Default friction levels as fractions of each joint's effort limit. They put
#: a UR10 base joint (330 Nm) at about 15 Nm Coulomb friction, the order of
#: magnitude of published UR friction identifications (~1.4 A of motor current
#: on joint 1). They are plausible values, not identified ones.
DEFAULT_COULOMB_RATIO = 0.045
#: Static (breakaway) friction over Coulomb friction.
DEFAULT_STATIC_OVER_COULOMB = 1.35
#: Viscous friction [Nm s/rad] per Nm of effort limit.
DEFAULT_VISCOUS_RATIO = 0.07
#: Stribeck velocity [rad/s]: width of the low-speed friction peak.
DEFAULT_STRIBECK_VELOCITY = 0.02


@dataclass(frozen=True)
class JointFriction:
    """Per-joint friction: Coulomb, viscous, Stribeck and static levels.

    While joint ``l`` slides (``qd_l != 0``) its friction torque is the
    Stribeck law

    .. math::

        \\tau_{f,l}(\\dot q_l) = \\left[F_{c,l} + (F_{s,l} - F_{c,l})
            e^{-(\\dot q_l / v_{s,l})^2}\\right] \\operatorname{sign}(\\dot q_l)
            + F_{v,l} \\dot q_l ,

    which falls from the breakaway level ``F_s`` to the Coulomb level ``F_c``
    within a few ``v_s`` (the low-speed dip that makes stick-slip possible).
    While the joint sticks (``qd_l == 0``) friction is whatever torque keeps it
    still, bounded by ``|tau_f,l| <= F_s,l`` -- the static branch of the
    paper's friction model (Sec. III-B). That torque is not a function of the
    state; :class:`~sklearn_gpcd.datasets.RobotSimulator` solves it each servo
    tick from the coupled dynamics.

    Parameters
    ----------
    coulomb : array-like of shape (n_joints,)
        Coulomb (kinetic) friction ``F_c`` [Nm].
    static : array-like of shape (n_joints,)
        Static (breakaway) friction ``F_s`` [Nm], ``F_s >= F_c``.
    viscous : array-like of shape (n_joints,)
        Viscous coefficient ``F_v`` [Nm s/rad] (the paper's ``B_eq`` lumped
        with the gear friction).
    stribeck_velocity : array-like of shape (n_joints,)
        Stribeck velocity ``v_s`` [rad/s].

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.datasets import JointFriction
    >>> f = JointFriction(coulomb=[10.0], static=[13.0], viscous=[2.0],
    ...                   stribeck_velocity=[0.02])
    >>> f.torque(np.array([1.0, 0.0, -1.0]))
    array([ 12.,   0., -12.])
    >>> float(f.torque(np.array([1e-6]))[0].round(3))  # breakaway level at low speed
    13.0
    """

    coulomb: np.ndarray
    static: np.ndarray
    viscous: np.ndarray
    stribeck_velocity: np.ndarray

    def __post_init__(self):
        values = {}
        for key in ("coulomb", "static", "viscous", "stribeck_velocity"):
            value = np.atleast_1d(np.asarray(getattr(self, key), dtype=float))
            if value.ndim != 1:
                raise ValueError(f"JointFriction.{key} must be 1-D, got shape {value.shape}")
            if not np.all(np.isfinite(value)) or np.any(value < 0):
                raise ValueError(f"JointFriction.{key} must be finite and >= 0, got {value}")
            values[key] = value
        shapes = {v.shape for v in values.values()}
        if len(shapes) != 1:
            raise ValueError(
                "JointFriction fields must have one entry per joint, got shapes "
                + ", ".join(f"{k}={v.shape}" for k, v in values.items())
            )
        if np.any(values["static"] < values["coulomb"]):
            raise ValueError(
                "JointFriction.static must be >= coulomb for every joint, got "
                f"static={values['static']}, coulomb={values['coulomb']}"
            )
        if np.any(values["stribeck_velocity"] <= 0):
            raise ValueError("JointFriction.stribeck_velocity must be > 0")
        for key, value in values.items():
            value.setflags(write=False)
            object.__setattr__(self, key, value)

    @property
    def n_joints(self):
        """Number of joints."""
        return self.coulomb.shape[0]

    def torque(self, qd):
        """Sliding friction torque at velocity ``qd`` (zero where ``qd == 0``).

        Parameters
        ----------
        qd : ndarray of shape (..., n_joints)
            Joint velocities [rad/s].

        Returns
        -------
        tau_f : ndarray of shape (..., n_joints)
            Friction torque [Nm] opposing the motion: the Stribeck law above
            (:func:`~sklearn_gpcd.dynamics.stribeck_friction`).
        """
        return stribeck_friction(qd, self.coulomb, self.static, self.viscous,
                                 self.stribeck_velocity)

    def scaled(self, coulomb=1.0, static=1.0, viscous=1.0):
        """A copy with the levels multiplied per joint (scalars broadcast).

        The static level is raised to at least the new Coulomb level so the
        result stays valid.

        Examples
        --------
        >>> from sklearn_gpcd.datasets import JointFriction
        >>> f = JointFriction([1.0], [2.0], [0.5], [0.02]).scaled(static=2.0)
        >>> float(f.static[0])
        4.0
        """
        new_coulomb = self.coulomb * coulomb
        return JointFriction(
            coulomb=new_coulomb,
            static=np.maximum(self.static * static, new_coulomb),
            viscous=self.viscous * viscous,
            stribeck_velocity=self.stribeck_velocity,
        )


def default_friction(robot):
    """Plausible friction for a robot, scaled by its joints' effort limits.

    ``F_c = 0.045 tau_max``, ``F_s = 1.35 F_c``, ``F_v = 0.07 tau_max`` [Nm
    s/rad] and ``v_s = 0.02`` rad/s (see the module constants). For a UR10
    that is 14.9 Nm Coulomb and 20 Nm breakaway friction on the base joint.

    Parameters
    ----------
    robot : Robot
        Anything with an ``effort_limits`` array [Nm].

    Returns
    -------
    friction : JointFriction

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> from sklearn_gpcd.datasets import default_friction
    >>> f = default_friction(SimpleNamespace(effort_limits=[330.0, 54.0]))
    >>> f.coulomb.round(2).tolist()
    [14.85, 2.43]
    """
    effort = np.asarray(robot.effort_limits, dtype=float)
    coulomb = DEFAULT_COULOMB_RATIO * effort
    return JointFriction(
        coulomb=coulomb,
        static=DEFAULT_STATIC_OVER_COULOMB * coulomb,
        viscous=DEFAULT_VISCOUS_RATIO * effort,
        stribeck_velocity=np.full(effort.shape, DEFAULT_STRIBECK_VELOCITY),
    )
