"""Effects injected into the simulated robot: payloads, friction drift, sensor faults.

Each effect acts on the *plant* (the simulated physics and sensors) from
``start`` to ``stop`` and never on the servo's model, so the controller does
not know about it -- exactly the situation a diagnosis tool must recognise.
An effect is a small frozen dataclass with an ``apply(plant)`` method that
changes the plant and returns a function restoring it. The plant exposes

``model``
    pinocchio.Model of the true robot (payload goes into its last link);
``torque_constants``
    true ``K_eq`` [Nm/A] mapping motor current to joint torque;
``friction``
    true :class:`~sklearn_gpcd.datasets.JointFriction`;
``current_offset``
    bias added to the measured current [A];
``current_delay``
    servo ticks between the commanded current and the current loop;
``spring_stiffness``, ``spring_rest``
    joint springs ``tau = -k (q - q_rest)``;
``q``
    the joint positions now (read only);
``flange_joint``, ``flange_placement``
    parent joint id and placement of the flange frame.

To add an effect, write a dataclass with ``start``/``stop`` fields and an
``apply(plant)`` that returns the undo function, and register it in
:data:`~sklearn_gpcd.datasets.EFFECT_REGISTRY` with the diagnosis effect
that names it (or in :data:`~sklearn_gpcd.datasets.SIMULATOR_ONLY` with the
reason): ``tests/test_effect_registry.py`` fails on an unregistered one.
"""

from dataclasses import dataclass

import numpy as np
import pinocchio as pin


def _per_joint(value, n_joints, what):
    value = np.asarray(value, dtype=float)
    if value.ndim == 0:
        value = np.full(n_joints, float(value))
    if value.shape != (n_joints,) or not np.all(np.isfinite(value)):
        raise ValueError(
            f"{what} must be a finite scalar or one value per joint ({n_joints}), got {value!r}"
        )
    return value


@dataclass(frozen=True)
class Payload:
    """A rigid payload mounted on the flange.

    Adds the spatial inertia of a body of ``mass`` with centre of mass
    ``com`` (flange frame) to the last link, so gravity and inertia of the
    true robot change while the servo's feed-forward keeps the nominal model.

    Parameters
    ----------
    mass : float
        Payload mass [kg].
    com : array-like of shape (3,), default=(0, 0, 0)
        Centre of mass in the flange frame [m].
    inertia : array-like of shape (3, 3), default=None
        Rotational inertia about the centre of mass [kg m^2]; None means a
        5 cm solid sphere.
    start, stop : float, default=0.0, None
        Active interval [s]; ``stop=None`` lasts to the end.

    Examples
    --------
    >>> from sklearn_gpcd.datasets import Payload
    >>> Payload(mass=2.0, com=[0.0, 0.0, 0.05]).mass
    2.0
    """

    mass: float
    com: tuple = (0.0, 0.0, 0.0)
    inertia: np.ndarray = None
    start: float = 0.0
    stop: float = None

    def apply(self, plant):
        """Add the payload to the plant's last link; return the undo function."""
        if not (np.isfinite(self.mass) and self.mass > 0):
            raise ValueError(f"Payload.mass must be > 0 kg, got {self.mass}")
        com = np.asarray(self.com, dtype=float)
        if com.shape != (3,):
            raise ValueError(f"Payload.com must be 3 numbers, got {self.com!r}")
        if self.inertia is None:
            body = pin.Inertia.FromSphere(float(self.mass), 0.05)
            body = pin.Inertia(body.mass, com, body.inertia)
        else:
            body = pin.Inertia(float(self.mass), com, np.asarray(self.inertia, dtype=float))
        joint = plant.flange_joint
        saved = pin.Inertia(plant.model.inertias[joint])
        plant.model.inertias[joint] = saved + plant.flange_placement.act(body)

        def undo():
            plant.model.inertias[joint] = saved

        return undo


class _FrictionEffect:
    """A change of the plant's friction levels: :meth:`apply` swaps them for
    those of ``changed(friction)`` until undone (:class:`FrictionChange`,
    ``FrictionDelta``)."""

    def apply(self, plant):
        """Change the plant's friction; return the undo function."""
        saved = plant.friction
        plant.friction = self.changed(saved)

        def undo():
            plant.friction = saved

        return undo


@dataclass(frozen=True)
class FrictionChange(_FrictionEffect):
    """Scale the true friction levels (e.g. a Stribeck/static level change).

    Parameters
    ----------
    coulomb, static, viscous : float or array-like of shape (n_joints,), default=1.0
        Multipliers of ``F_c``, ``F_s``, ``F_v`` (static is kept >= Coulomb).
    start, stop : float, default=0.0, None
        Active interval [s].

    Examples
    --------
    >>> from sklearn_gpcd.datasets import FrictionChange
    >>> FrictionChange(static=1.5, start=10.0).static
    1.5
    """

    coulomb: float = 1.0
    static: float = 1.0
    viscous: float = 1.0
    start: float = 0.0
    stop: float = None

    def changed(self, friction):
        """The friction levels ``friction`` becomes under this change.

        Parameters
        ----------
        friction : JointFriction

        Returns
        -------
        friction : JointFriction

        Examples
        --------
        >>> from sklearn_gpcd.datasets import FrictionChange, JointFriction
        >>> before = JointFriction([1.0], [2.0], [0.5], [0.02])
        >>> FrictionChange(viscous=1.5).changed(before).viscous.tolist()
        [0.75]
        """
        n = friction.n_joints
        return friction.scaled(
            coulomb=_per_joint(self.coulomb, n, "FrictionChange.coulomb"),
            static=_per_joint(self.static, n, "FrictionChange.static"),
            viscous=_per_joint(self.viscous, n, "FrictionChange.viscous"),
        )


@dataclass(frozen=True)
class CurrentDelay:
    """A transport delay between the commanded and the actual motor current.

    Parameters
    ----------
    delay : float
        Delay [s], rounded to whole servo ticks.
    start, stop : float, default=0.0, None
        Active interval [s].

    Examples
    --------
    >>> from sklearn_gpcd.datasets import CurrentDelay
    >>> CurrentDelay(0.004).delay
    0.004
    """

    delay: float
    start: float = 0.0
    stop: float = None

    def apply(self, plant):
        """Set the plant's current delay; return the undo function."""
        if not (np.isfinite(self.delay) and self.delay >= 0):
            raise ValueError(f"CurrentDelay.delay must be >= 0 seconds, got {self.delay}")
        saved = plant.current_delay
        plant.current_delay = int(round(self.delay / plant.servo_period))

        def undo():
            plant.current_delay = saved

        return undo


@dataclass(frozen=True)
class TorqueConstantError:
    """The true torque constants differ from the ones the servo assumes.

    Parameters
    ----------
    scale : float or array-like of shape (n_joints,)
        True ``K_eq`` = nominal ``K_eq`` * ``scale``.
    start, stop : float, default=0.0, None
        Active interval [s].

    Examples
    --------
    >>> from sklearn_gpcd.datasets import TorqueConstantError
    >>> TorqueConstantError(0.9).scale
    0.9
    """

    scale: float
    start: float = 0.0
    stop: float = None

    def apply(self, plant):
        """Scale the plant's torque constants; return the undo function."""
        scale = _per_joint(self.scale, plant.n_joints, "TorqueConstantError.scale")
        if np.any(scale <= 0):
            raise ValueError(f"TorqueConstantError.scale must be > 0, got {scale}")
        saved = plant.torque_constants
        plant.torque_constants = saved * scale

        def undo():
            plant.torque_constants = saved

        return undo


@dataclass(frozen=True)
class CurrentOffset:
    """A bias on the measured current (sensor offset, not a physical torque).

    Parameters
    ----------
    offset : float or array-like of shape (n_joints,)
        Added to the logged current [A].
    start, stop : float, default=0.0, None
        Active interval [s].

    Examples
    --------
    >>> from sklearn_gpcd.datasets import CurrentOffset
    >>> CurrentOffset([0.1, 0, 0, 0, 0, 0]).offset
    [0.1, 0, 0, 0, 0, 0]
    """

    offset: float
    start: float = 0.0
    stop: float = None

    def apply(self, plant):
        """Add the offset to the plant's current sensor; return the undo function."""
        saved = plant.current_offset
        offset = _per_joint(self.offset, plant.n_joints, "CurrentOffset.offset")
        plant.current_offset = saved + offset

        def undo():
            plant.current_offset = saved

        return undo


@dataclass(frozen=True)
class JointSpring:
    """A torsional spring on the joints, ``tau = -k (q - q_rest)``.

    Parameters
    ----------
    stiffness : float or array-like of shape (n_joints,)
        Spring constants [Nm/rad].
    rest : array-like of shape (n_joints,), default=None
        Rest positions [rad]; None means the positions when the effect starts.
    start, stop : float, default=0.0, None
        Active interval [s].

    Examples
    --------
    >>> from sklearn_gpcd.datasets import JointSpring
    >>> JointSpring(stiffness=[50.0, 0, 0, 0, 0, 0]).rest is None
    True
    """

    stiffness: float
    rest: np.ndarray = None
    start: float = 0.0
    stop: float = None

    def apply(self, plant):
        """Add the spring to the plant; return the undo function."""
        n = plant.n_joints
        stiffness = _per_joint(self.stiffness, n, "JointSpring.stiffness")
        rest = plant.q.copy() if self.rest is None else _per_joint(self.rest, n, "JointSpring.rest")
        saved = plant.spring_stiffness, plant.spring_rest
        total = saved[0] + stiffness
        # two springs k1 (q - r1) + k2 (q - r2) = (k1 + k2) (q - r), r the weighted rest
        with np.errstate(invalid="ignore", divide="ignore"):
            plant.spring_rest = np.where(
                total > 0, (saved[0] * saved[1] + stiffness * rest) / total, rest
            )
        plant.spring_stiffness = total

        def undo():
            plant.spring_stiffness, plant.spring_rest = saved

        return undo

