"""More effects to inject into the simulated robot, for the diagnosis tests and studies.

Not public, except :class:`FrictionDelta`, which the gallery uses
(``sklearn_gpcd.datasets.FrictionDelta``); the others are imported from here.

They follow the protocol of :mod:`sklearn_gpcd.datasets.effects` (a frozen
dataclass with ``start``/``stop`` and ``apply(plant)`` returning an undo
function), except :class:`LoggedCurrentDelay` (:func:`delay_logged_current`),
which acts on a finished recording (a logging delay is not part of the plant), and
:func:`friction_drift`, which returns a staircase of small friction steps
(the plant's friction is refreshed only when an effect starts or stops).

Note that the simulator's :class:`~sklearn_gpcd.datasets.CurrentDelay` delays
the *command* of the current loop: the logged current still drives the
joints at the same instant, so it does not change the relation between
logged current and motion. A delayed *log* does, see
:func:`delay_logged_current`.
"""

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .effects import _FrictionEffect, _per_joint
from .friction import JointFriction


@dataclass(frozen=True)
class FrictionDelta(_FrictionEffect):
    """Add to the true friction levels (additive, unlike :class:`FrictionChange`).

    ``coulomb`` and ``static`` raised by the same amount add a pure Coulomb
    term :math:`\\Delta F_c\\,\\mathrm{sign}(\\dot q)`; ``static`` alone adds
    a Stribeck peak :math:`\\Delta F_s\\,\\mathrm{sign}(\\dot q)
    e^{-(\\dot q/v_s)^2}`.

    Parameters
    ----------
    coulomb, static, viscous : float or array-like of shape (n_joints,), default=0.0
        Added to ``F_c`` [Nm], ``F_s`` [Nm] and ``F_v`` [Nm s/rad].
    stribeck_velocity : float or array-like, default=None
        New Stribeck velocity [rad/s]; None keeps it.
    start, stop : float, default=0.0, None
        Active interval [s].

    Examples
    --------
    >>> from sklearn_gpcd.datasets import FrictionDelta
    >>> FrictionDelta(static=[3.0, 0, 0, 0, 0, 0]).coulomb
    0.0
    """

    coulomb: float = 0.0
    static: float = 0.0
    viscous: float = 0.0
    stribeck_velocity: float = None
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
            Static level kept at least the new Coulomb level.

        Examples
        --------
        >>> from sklearn_gpcd.datasets import FrictionDelta, JointFriction
        >>> before = JointFriction([1.0, 1.0], [2.0, 2.0], [0.5, 0.5], [0.02, 0.02])
        >>> FrictionDelta(static=[3.0, 0.0]).changed(before).static.tolist()
        [5.0, 2.0]
        """
        n = friction.n_joints
        coulomb = friction.coulomb + _per_joint(self.coulomb, n, "FrictionDelta.coulomb")
        static = friction.static + _per_joint(self.static, n, "FrictionDelta.static")
        vs = friction.stribeck_velocity if self.stribeck_velocity is None else _per_joint(
            self.stribeck_velocity, n, "FrictionDelta.stribeck_velocity")
        return JointFriction(
            coulomb=coulomb, static=np.maximum(static, coulomb),
            viscous=friction.viscous + _per_joint(self.viscous, n, "FrictionDelta.viscous"),
            stribeck_velocity=vs)


def friction_drift(coulomb_rate=0.0, viscous_rate=0.0, duration=60.0, step=0.5, start=0.0):
    """Friction rising linearly with time, as a staircase of :class:`FrictionDelta` steps.

    Step ``k`` starts at ``start + (k + 1/2) step`` and adds ``rate * step``,
    so the level follows ``rate * (t - start)`` within half a step.

    Parameters
    ----------
    coulomb_rate : float or array-like of shape (n_joints,), default=0.0
        Coulomb (and static) level increase [Nm/s].
    viscous_rate : float or array-like, default=0.0
        Viscous coefficient increase [Nm s/rad per s].
    duration : float, default=60.0
        Length of the drift [s] (use the recording's duration).
    step : float, default=0.5
        Staircase step [s].
    start : float, default=0.0
        Start of the drift [s].

    Returns
    -------
    effects : list of FrictionDelta

    Examples
    --------
    >>> from sklearn_gpcd.datasets._extra_effects import friction_drift
    >>> steps = friction_drift(coulomb_rate=0.1, duration=2.0, step=0.5)
    >>> len(steps), steps[0].start, round(steps[0].coulomb, 3)
    (4, 0.25, 0.05)
    """
    if not (step > 0 and duration > 0):
        raise ValueError(f"step and duration must be > 0, got {step}, {duration}")
    n_steps = int(np.floor(duration / step))
    c = np.asarray(coulomb_rate, dtype=float) * step
    v = np.asarray(viscous_rate, dtype=float) * step
    c = float(c) if c.ndim == 0 else tuple(c.tolist())
    v = float(v) if v.ndim == 0 else tuple(v.tolist())
    return [FrictionDelta(coulomb=c, static=c, viscous=v, start=start + (k + 0.5) * step)
            for k in range(n_steps)]


@dataclass(frozen=True)
class RotorInertiaChange:
    """Add to the true reflected rotor inertias ``K_r^2 J_m`` (model armature).

    Parameters
    ----------
    delta : float or array-like of shape (n_joints,)
        Added inertia [kg m^2].
    start, stop : float, default=0.0, None
        Active interval [s].

    Examples
    --------
    >>> from sklearn_gpcd.datasets._extra_effects import RotorInertiaChange
    >>> RotorInertiaChange([0.5, 0, 0, 0, 0, 0]).start
    0.0
    """

    delta: float
    start: float = 0.0
    stop: float = None

    def apply(self, plant):
        """Change the plant's armature; return the undo function."""
        saved = np.array(plant.model.armature, dtype=float)
        new = saved + _per_joint(self.delta, plant.n_joints, "RotorInertiaChange.delta")
        if np.any(new < 0):
            raise ValueError(f"RotorInertiaChange makes a rotor inertia negative: {new}")
        plant.model.armature = new

        def undo():
            plant.model.armature = saved

        return undo


@dataclass(frozen=True)
class LinkMass:
    """Add a point mass to a link at its nominal centre of mass (e.g. cables, a bracket).

    Parameters
    ----------
    link : int
        0-based link index (link ``k`` is moved by joint ``k``).
    mass : float
        Added mass [kg] (may be negative, keeping the link's mass > 0).
    offset : array-like of shape (3,), default=(0, 0, 0)
        Position of the mass relative to the link's centre of mass [m],
        link frame.
    start, stop : float, default=0.0, None
        Active interval [s].

    Examples
    --------
    >>> from sklearn_gpcd.datasets._extra_effects import LinkMass
    >>> LinkMass(link=2, mass=1.5).mass
    1.5
    """

    link: int
    mass: float
    offset: tuple = (0.0, 0.0, 0.0)
    start: float = 0.0
    stop: float = None

    def apply(self, plant):
        """Add the mass to the plant's link; return the undo function."""
        if not 0 <= int(self.link) < plant.n_joints:
            raise ValueError(f"LinkMass.link={self.link} out of range for {plant.n_joints} links")
        joint = int(self.link) + 1
        saved = pin.Inertia(plant.model.inertias[joint])
        position = saved.lever + np.asarray(self.offset, dtype=float)
        plant.model.inertias[joint] = saved + pin.Inertia(
            float(self.mass), position, np.zeros((3, 3)))
        if plant.model.inertias[joint].mass <= 0:
            plant.model.inertias[joint] = saved
            raise ValueError(f"LinkMass makes link {self.link}'s mass <= 0")

        def undo():
            plant.model.inertias[joint] = saved

        return undo


@dataclass(frozen=True)
class GravityTilt:
    """The base is mounted tilted: gravity in the base frame is ``R^T g``.

    ``R = R_x(roll) R_y(pitch)`` rotates the base frame in the world.

    Parameters
    ----------
    roll, pitch : float
        Tilt angles about the base x and y axes [rad].
    start, stop : float, default=0.0, None
        Active interval [s].

    Examples
    --------
    >>> from sklearn_gpcd.datasets._extra_effects import GravityTilt
    >>> GravityTilt(roll=0.02, pitch=-0.01).roll
    0.02
    """

    roll: float = 0.0
    pitch: float = 0.0
    start: float = 0.0
    stop: float = None

    def apply(self, plant):
        """Rotate the plant's gravity vector; return the undo function."""
        saved = pin.Motion(plant.model.gravity)
        rotation = pin.rpy.rpyToMatrix(float(self.roll), 0.0, 0.0) @ pin.rpy.rpyToMatrix(
            0.0, float(self.pitch), 0.0)
        plant.model.gravity = pin.Motion(rotation.T @ saved.linear, saved.angular)

        def undo():
            plant.model.gravity = saved

        return undo


@dataclass(frozen=True)
class LoggedCurrentDelay:
    """The logged current lags the motion by ``delay`` seconds (a logging delay).

    Unlike the plant effects it acts on the finished recording, through
    :meth:`apply_to_recording` (:func:`delay_logged_current`); the joints
    are still driven by the current of the same instant. The simulator's
    :class:`~sklearn_gpcd.datasets.CurrentDelay` delays the *command*
    instead, which the logged current does not show.

    Parameters
    ----------
    delay : float
        Delay [s], >= 0.

    Examples
    --------
    >>> from sklearn_gpcd.datasets import simulate_d1
    >>> from sklearn_gpcd.datasets._extra_effects import LoggedCurrentDelay
    >>> recording = simulate_d1("ur10", n_targets=1, random_state=0)
    >>> delayed = LoggedCurrentDelay(0.016).apply_to_recording(recording)
    >>> recording.n_samples - delayed.n_samples  # the first 16 ms have no logged current
    2
    """

    delay: float

    def apply_to_recording(self, recording):
        """The recording with its logged current delayed (:func:`delay_logged_current`)."""
        return delay_logged_current(recording, self.delay)


def delay_logged_current(recording, delay):
    """The recording with its logged current lagging by ``delay`` seconds.

    ``current(t) <- current(t - delay)`` by linear interpolation; samples
    with ``t - delay`` before the first time stamp are dropped.

    Parameters
    ----------
    recording : Recording
    delay : float
        Delay [s], >= 0.

    Returns
    -------
    recording : Recording

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> from sklearn_gpcd.datasets._extra_effects import delay_logged_current
    >>> t = np.arange(5) * 0.01
    >>> rec = Recording(time=t, q=np.zeros((5, 1)), qd=np.zeros((5, 1)), current=t[:, None])
    >>> delay_logged_current(rec, 0.02).current.ravel().round(3).tolist()
    [0.0, 0.01, 0.02]
    """
    if not (np.isfinite(delay) and delay >= 0):
        raise ValueError(f"delay must be >= 0 seconds, got {delay}")
    t = recording.time
    keep = t - delay >= t[0] - 1e-12
    current = np.column_stack([np.interp(t[keep] - delay, t, recording.current[:, j])
                               for j in range(recording.n_joints)])
    out = recording.slice(int(np.argmax(keep)), None)
    return out.replace(current=current, metadata={**recording.metadata,
                                                  "logged_current_delay": float(delay)})
