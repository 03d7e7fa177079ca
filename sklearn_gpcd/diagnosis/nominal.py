"""The nominal model ("the simulation") and the signals a diagnosis works on.

The nominal model predicts the motor currents of a recording from its joint
states (paper Eq. 4 with the friction of Eq. 8-10):

.. math::

    \\hat i_\\ell = \\frac{1}{K_\\ell}\\left[M_{eq}(q)\\ddot q + C(q,\\dot q)\\dot q
        + g(q) + \\tau_{f}(\\dot q)\\right]_\\ell ,

with :math:`K_\\ell` the torque constants (``robot.torque_constants`` unless
given), :math:`M_{eq}` including the reflected rotor inertias
(``robot.model.armature``) and :math:`\\tau_f` the optional nominal friction.
Its error on a recording is the *residual* the diagnosis explains.

:class:`Signals` stacks one or more recordings into the arrays every effect
of :mod:`~sklearn_gpcd.diagnosis.effects` needs: time since the start of each
recording, ``q``, ``qd``, ``qdd`` (logged, else differentiated), measured
current and the reference (nominal) current with its time derivative.
"""

from dataclasses import dataclass, field

import numpy as np

from ..dynamics import inertial_features
from ..features import differentiate
from ..io import Recording
from ..robots.loading import resolve_robot

#: Options of :func:`sklearn_gpcd.features.differentiate` used for missing
#: accelerations and for the time derivative of the reference current.
DIFFERENTIATION = {"method": "savgol", "window_length": 21, "polyorder": 3}



def _as_friction(friction, n_joints):
    """Normalise the nominal friction to a callable ``qd -> tau_f`` (or None)."""
    if friction is None:
        return None
    if hasattr(friction, "torque") and callable(friction.torque):
        return friction.torque
    if isinstance(friction, dict):
        unknown = sorted(set(friction) - {"coulomb", "viscous"})
        if unknown:
            raise ValueError(
                f"friction dict accepts keys 'coulomb' and 'viscous', got {unknown}"
            )
        values = {}
        for key in ("coulomb", "viscous"):
            value = np.asarray(friction.get(key, np.zeros(n_joints)), dtype=float).reshape(-1)
            if value.shape != (n_joints,) or not np.all(np.isfinite(value)):
                raise ValueError(
                    f"friction[{key!r}] needs {n_joints} finite values, got {friction.get(key)!r}"
                )
            values[key] = value
        return lambda qd: values["coulomb"] * np.sign(qd) + values["viscous"] * qd
    if callable(friction):
        return friction
    raise TypeError(
        "friction must be None, a dict {'coulomb': ..., 'viscous': ...}, an object with a "
        f"torque(qd) method (e.g. JointFriction) or a callable, got {type(friction).__name__}"
    )


class NominalModel:
    """The nominal (simulated) current model of a robot.

    Parameters
    ----------
    robot : str, path or Robot
        Built-in robot name, URDF path or :class:`~sklearn_gpcd.robots.Robot`.
        Its ``model.armature`` holds the nominal rotor inertias.
    torque_constants : array-like of shape (n_joints,), default=None
        ``K`` [Nm/A] with ``tau = K * current``; None reads
        ``robot.torque_constants``. Ignored (ones) for recordings in ``"Nm"``.
    friction : None, dict, JointFriction-like or callable, default=None
        Known nominal friction torque :math:`\\tau_f(\\dot q)` [Nm]: an object
        with a ``torque(qd)`` method (e.g.
        :class:`~sklearn_gpcd.datasets.JointFriction`), a dict
        ``{"coulomb": [...], "viscous": [...]}`` or a callable ``qd -> tau``.

    Attributes
    ----------
    robot : Robot
    n_joints : int
    torque_constants : ndarray of shape (n_joints,)
    friction : callable or None

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.diagnosis import NominalModel
    >>> nominal = NominalModel("ur10", friction={"coulomb": [10.0] * 6})
    >>> q = np.zeros((1, 6))
    >>> nominal.torque(q, q, q).shape
    (1, 6)
    """

    def __init__(self, robot, torque_constants=None, friction=None):
        self.robot = resolve_robot(robot)
        n = self.n_joints = self.robot.n_joints
        k = self.robot.torque_constants if torque_constants is None else torque_constants
        if k is None:
            raise ValueError(
                f"robot {self.robot.name!r} has no torque constants: pass torque_constants "
                f"(one value per joint, Nm/A) or load_robot(..., torque_constants=[...])"
            )
        k = np.asarray(k, dtype=float).reshape(-1)
        if k.shape != (n,) or not np.all(np.isfinite(k)) or np.any(k <= 0):
            raise ValueError(
                f"torque_constants needs {n} positive values (Nm/A), got {np.asarray(k).tolist()}"
            )
        self.torque_constants = k
        self.friction = _as_friction(friction, n)
        self.friction_spec = friction

    def torque(self, q, qd, qdd):
        """Nominal joint torques :math:`M_{eq}\\ddot q + C\\dot q + g + \\tau_f` [Nm].

        Parameters
        ----------
        q, qd, qdd : ndarray of shape (n_samples, n_joints)

        Returns
        -------
        tau : ndarray of shape (n_samples, n_joints)
        """
        tau = self.robot.rnea(q, qd, qdd)
        tau = np.atleast_2d(tau)
        if self.friction is not None:
            tau = tau + np.asarray(self.friction(np.asarray(qd, dtype=float)), dtype=float)
        return tau

    def constants(self, units="A"):
        """Torque constants for a recording whose ``current`` is in ``units``."""
        return np.ones(self.n_joints) if units == "Nm" else self.torque_constants

    def current(self, q, qd, qdd, units="A"):
        """Nominal current :math:`\\hat i = \\tau / K` (torque for ``units="Nm"``).

        Parameters
        ----------
        q, qd, qdd : ndarray of shape (n_samples, n_joints)
        units : {"A", "Nm"}, default="A"

        Returns
        -------
        current : ndarray of shape (n_samples, n_joints)
        """
        return self.torque(q, qd, qdd) / self.constants(units)


def check_recordings(recordings, n_joints, what="recordings"):
    """Validate a recording or a list of them; return a list.

    Parameters
    ----------
    recordings : Recording or sequence of Recording
    n_joints : int
        Joints of the robot model.
    what : str, default="recordings"
        Used in error messages.

    Returns
    -------
    recordings : list of Recording
    """
    if isinstance(recordings, Recording):
        recordings = [recordings]
    recordings = list(recordings)
    if not recordings:
        raise ValueError(f"{what}: need at least one recording")
    for k, rec in enumerate(recordings):
        if not isinstance(rec, Recording):
            raise TypeError(f"{what}[{k}] must be a Recording, got {type(rec).__name__}")
        label = rec.name or f"#{k}"
        if rec.n_joints != n_joints:
            raise ValueError(
                f"{what}: recording {label!r} has {rec.n_joints} joints, the robot has {n_joints}"
            )
        if rec.n_samples < 30:
            raise ValueError(
                f"{what}: recording {label!r} has {rec.n_samples} samples; at least 30 needed"
            )
        if rec.units not in ("A", "Nm"):
            raise ValueError(f"{what}: recording {label!r} has units {rec.units!r}, not A or Nm")
        for key in ("q", "qd", "current"):
            bad = np.argwhere(~np.isfinite(getattr(rec, key)))
            if bad.size:
                raise ValueError(
                    f"{what}: recording {label!r}: {key} is NaN or inf at row {bad[0][0]}, "
                    f"joint {bad[0][1]}"
                )
    units = {rec.units for rec in recordings}
    if len(units) > 1:
        raise ValueError(f"{what}: recordings mix current units {sorted(units)}")
    return recordings


@dataclass
class Signals:
    """Recordings stacked into the arrays the effect library reads.

    Build it with :meth:`from_recordings` (or :meth:`from_states` for bare
    states without time).

    Parameters
    ----------
    time : ndarray of shape (n_samples,)
        Seconds since the start of each sample's recording.
    q, qd, qdd : ndarray of shape (n_samples, n_joints)
    current : ndarray of shape (n_samples, n_joints) or None
        Measured current (None for prediction only).
    reference : ndarray of shape (n_samples, n_joints)
        Reference current: the nominal model's prediction (or an aligned
        simulated run's current).
    reference_rate : ndarray of shape (n_samples, n_joints) or None
        :math:`d\\,\\mathrm{reference}/dt` per recording; None without time.
    segment : ndarray of int, shape (n_samples,)
        Index of the recording of each sample.
    torque_constants : ndarray of shape (n_joints,)
        Constants the columns are divided by (ones for torque logs).
    names : list of str
        Recording names.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.diagnosis import NominalModel, Signals
    >>> s = Signals.from_states(NominalModel("ur10"), np.zeros((4, 18)))
    >>> s.n_samples, s.n_joints, s.reference_rate is None
    (4, 6, True)
    """

    time: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    current: np.ndarray
    reference: np.ndarray
    reference_rate: np.ndarray
    segment: np.ndarray
    torque_constants: np.ndarray
    names: list = field(default_factory=list)
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def n_samples(self):
        """Number of stacked samples."""
        return self.q.shape[0]

    @property
    def n_joints(self):
        """Number of joints."""
        return self.q.shape[1]

    @classmethod
    def from_recordings(cls, nominal, recordings, references=None):
        """Stack recordings and compute the reference current.

        Parameters
        ----------
        nominal : NominalModel
        recordings : list of Recording
        references : list of ndarray or None, default=None
            Per recording, a reference current of shape ``(n_samples,
            n_joints)`` replacing the nominal model's prediction (the aligned
            current of a simulated run, see :func:`align_recordings`).

        Returns
        -------
        signals : Signals
        """
        recordings = check_recordings(recordings, nominal.n_joints)
        units = recordings[0].units
        parts = {k: [] for k in ("time", "q", "qd", "qdd", "current", "ref", "rate", "seg")}
        for k, rec in enumerate(recordings):
            qdd = rec.qdd
            if qdd is None:
                qdd = differentiate(rec.time, rec.qd, **DIFFERENTIATION)
            if references is None or references[k] is None:
                ref = nominal.current(rec.q, rec.qd, qdd, units)
            else:
                ref = np.asarray(references[k], dtype=float)
                if ref.shape != rec.q.shape:
                    raise ValueError(
                        f"reference current of recording {rec.name!r} has shape {ref.shape}, "
                        f"expected {rec.q.shape}"
                    )
            parts["time"].append(rec.time - rec.time[0])
            parts["q"].append(rec.q)
            parts["qd"].append(rec.qd)
            parts["qdd"].append(qdd)
            parts["current"].append(rec.current)
            parts["ref"].append(ref)
            parts["rate"].append(differentiate(rec.time, ref, **DIFFERENTIATION))
            parts["seg"].append(np.full(rec.n_samples, k))
        return cls(
            time=np.concatenate(parts["time"]), q=np.concatenate(parts["q"]),
            qd=np.concatenate(parts["qd"]), qdd=np.concatenate(parts["qdd"]),
            current=np.concatenate(parts["current"]), reference=np.concatenate(parts["ref"]),
            reference_rate=np.concatenate(parts["rate"]),
            segment=np.concatenate(parts["seg"]),
            torque_constants=nominal.constants(units),
            names=[rec.name or f"recording {k}" for k, rec in enumerate(recordings)],
        )

    @classmethod
    def from_states(cls, nominal, X, units="A"):
        """Signals of bare states ``X = [q, qd, qdd, ...]`` (layout of :mod:`sklearn_gpcd.layout`).

        There is no time, so time-dependent effects (``time_delay``,
        ``friction_drift``) cannot be evaluated on them.

        Parameters
        ----------
        nominal : NominalModel
        X : ndarray of shape (n_samples, >= 3 n_joints)
        units : {"A", "Nm"}, default="A"

        Returns
        -------
        signals : Signals
        """
        n = nominal.n_joints
        X = np.asarray(X, dtype=float)
        if X.ndim != 2 or X.shape[1] < 3 * n:
            raise ValueError(
                f"X must have at least {3 * n} columns [q, qd, qdd] of {n} joints, got shape "
                f"{X.shape}"
            )
        q, qd, qdd = X[:, :n], X[:, n:2 * n], X[:, 2 * n:3 * n]
        return cls(
            time=None, q=q, qd=qd, qdd=qdd, current=None,
            reference=nominal.current(q, qd, qdd, units), reference_rate=None,
            segment=np.zeros(X.shape[0], dtype=int), torque_constants=nominal.constants(units),
        )

    def rigid_body_features(self, model):
        """Pinocchio's joint torque regressor of every sample, cached.

        Returns
        -------
        Y : ndarray of shape (n_samples, n_joints, 10 n_joints)
        """
        if "regressor" not in self._cache:
            self._cache["regressor"] = inertial_features(model, self.q, self.qd, self.qdd)
        return self._cache["regressor"]

