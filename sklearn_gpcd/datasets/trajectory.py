"""Joint-space reference trajectories for the simulated servo."""

import numpy as np
from scipy.interpolate import CubicSpline, PPoly

#: Peak |velocity| of a quintic rest-to-rest move is 15/8 * |dq| / T.
_QUINTIC_PEAK_VELOCITY = 15.0 / 8.0
#: Peak |acceleration| of a quintic rest-to-rest move is 10/sqrt(3) * |dq| / T^2.
_QUINTIC_PEAK_ACCELERATION = 10.0 / np.sqrt(3.0)


class JointTrajectory:
    """A twice-differentiable joint reference ``q_r(t)``, ``t`` in ``[0, duration]``.

    Stored as a piecewise polynomial in time (``scipy.interpolate.PPoly``),
    so ``qd_r`` and ``qdd_r`` are exact derivatives: the servo's model
    feed-forward (inverse dynamics of the reference) sees a consistent
    ``(q_r, qd_r, qdd_r)`` triple. Build pieces with :meth:`rest`,
    :meth:`point_to_point` and :meth:`from_samples`, join them with
    :meth:`concatenate`.

    Parameters
    ----------
    ppoly : scipy.interpolate.PPoly
        Positions [rad], breakpoints starting at 0, values of shape
        ``(n_joints,)``.
    phases : list of dict, default=None
        Annotations ``{"start", "stop", "kind", ...}`` in seconds (e.g. the
        rest phases); kept through :meth:`concatenate`.

    Attributes
    ----------
    duration : float
        Length in seconds.
    n_joints : int
        Number of joints.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.datasets import JointTrajectory
    >>> move = JointTrajectory.point_to_point([0.0, 0.0], [1.0, -1.0], duration=2.0)
    >>> ref = JointTrajectory.concatenate([move, JointTrajectory.rest([1.0, -1.0], 1.0)])
    >>> ref.duration
    3.0
    >>> q, qd, qdd = ref.sample([1.0])
    >>> q.round(3).tolist(), qd.round(4).tolist()
    ([[0.5, -0.5]], [[0.9375, -0.9375]])
    """

    def __init__(self, ppoly, phases=None):
        if not isinstance(ppoly, PPoly):
            raise TypeError(f"ppoly must be a scipy.interpolate.PPoly, got {type(ppoly).__name__}")
        if ppoly.c.ndim != 3:
            raise ValueError(
                "ppoly must have vector values of shape (n_joints,), got coefficient "
                f"array of shape {ppoly.c.shape}"
            )
        if abs(ppoly.x[0]) > 1e-12:
            raise ValueError(f"ppoly breakpoints must start at t=0, got {ppoly.x[0]}")
        self.ppoly = ppoly
        self.phases = list(phases or [])
        self._velocity = ppoly.derivative(1)
        self._acceleration = ppoly.derivative(2)

    @property
    def duration(self):
        """Length in seconds."""
        return float(self.ppoly.x[-1])

    @property
    def n_joints(self):
        """Number of joints."""
        return self.ppoly.c.shape[2]

    def sample(self, t):
        """Reference position, velocity and acceleration at times ``t``.

        Times are clipped to ``[0, duration]``.

        Parameters
        ----------
        t : array-like of shape (n_times,)
            Times [s].

        Returns
        -------
        q, qd, qdd : ndarray of shape (n_times, n_joints)
        """
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        return self.ppoly(t), self._velocity(t), self._acceleration(t)

    def at(self, t):
        """Reference position at one time ``t`` (clipped), shape ``(n_joints,)``."""
        return self.ppoly(min(max(float(t), 0.0), self.duration))

    @classmethod
    def rest(cls, q, duration, **info):
        """Hold configuration ``q`` for ``duration`` seconds.

        Extra keyword arguments are stored in the phase annotation.
        """
        q = _as_configuration(q, "rest: q")
        duration = _as_duration(duration, "rest")
        c = np.zeros((1, 1, q.size))
        c[0, 0] = q
        phase = {"start": 0.0, "stop": duration, "kind": "rest", **info}
        return cls(PPoly(c, np.array([0.0, duration])), [phase])

    @classmethod
    def point_to_point(cls, q_start, q_end, duration, **info):
        """Quintic rest-to-rest move (zero velocity and acceleration at both ends).

        .. math::

            q_r(t) = q_0 + \\Delta q \\,(10 s^3 - 15 s^4 + 6 s^5),
            \\quad s = t / T .

        Extra keyword arguments are stored in the phase annotation.
        """
        q0 = _as_configuration(q_start, "point_to_point: q_start")
        q1 = _as_configuration(q_end, "point_to_point: q_end")
        if q0.shape != q1.shape:
            raise ValueError(
                f"point_to_point: q_start has {q0.size} joints, q_end has {q1.size}"
            )
        T = _as_duration(duration, "point_to_point")
        dq = q1 - q0
        c = np.zeros((6, 1, q0.size))  # highest power first
        c[0, 0] = 6.0 * dq / T**5
        c[1, 0] = -15.0 * dq / T**4
        c[2, 0] = 10.0 * dq / T**3
        c[5, 0] = q0
        phase = {"start": 0.0, "stop": T, "kind": "move", **info}
        return cls(PPoly(c, np.array([0.0, T])), [phase])

    @classmethod
    def from_samples(cls, t, q, **info):
        """Cubic spline through samples, with zero velocity at both ends.

        Parameters
        ----------
        t : array-like of shape (n_samples,)
            Strictly increasing times [s]; shifted to start at 0.
        q : array-like of shape (n_samples, n_joints)
            Joint positions [rad].
        """
        t = np.asarray(t, dtype=float)
        q = np.asarray(q, dtype=float)
        if t.ndim != 1 or q.ndim != 2 or q.shape[0] != t.shape[0]:
            raise ValueError(
                f"from_samples: need t of shape (n,) and q of shape (n, n_joints), got "
                f"{t.shape} and {q.shape}"
            )
        if t.size < 2 or np.any(np.diff(t) <= 0):
            raise ValueError("from_samples: t must hold >= 2 strictly increasing times")
        if not np.all(np.isfinite(q)):
            raise ValueError("from_samples: q contains NaN or inf")
        spline = CubicSpline(t - t[0], q, bc_type="clamped")
        phase = {"start": 0.0, "stop": float(t[-1] - t[0]), "kind": "path", **info}
        return cls(PPoly(spline.c, spline.x), [phase])

    @classmethod
    def concatenate(cls, pieces):
        """Join trajectories end to start; phases are shifted accordingly.

        Each piece should start where the previous one ends (not checked
        beyond a 1e-6 rad tolerance, which raises).
        """
        pieces = list(pieces)
        if not pieces:
            raise ValueError("concatenate needs at least one trajectory")
        degree = max(p.ppoly.c.shape[0] for p in pieces)
        coefs, breaks, phases, offset = [], [np.zeros(1)], [], 0.0
        for k, piece in enumerate(pieces):
            if piece.n_joints != pieces[0].n_joints:
                raise ValueError(
                    f"concatenate: piece {k} has {piece.n_joints} joints, "
                    f"piece 0 has {pieces[0].n_joints}"
                )
            if k > 0:
                gap = np.max(np.abs(piece.at(0.0) - pieces[k - 1].at(pieces[k - 1].duration)))
                if gap > 1e-6:
                    raise ValueError(
                        f"concatenate: piece {k} starts {gap:.3g} rad away from where "
                        f"piece {k - 1} ends"
                    )
            c = piece.ppoly.c
            padded = np.zeros((degree,) + c.shape[1:])
            padded[degree - c.shape[0]:] = c
            coefs.append(padded)
            breaks.append(piece.ppoly.x[1:] + offset)
            for phase in piece.phases:
                phases.append(
                    {**phase, "start": phase["start"] + offset, "stop": phase["stop"] + offset}
                )
            offset += piece.duration
        ppoly = PPoly(np.concatenate(coefs, axis=1), np.concatenate(breaks))
        return cls(ppoly, phases)


def quintic_duration(q_start, q_end, max_velocity, max_acceleration, min_duration=0.5):
    """Shortest quintic move time within velocity and acceleration bounds.

    .. math::

        T = \\max_l \\max\\left(\\frac{15}{8}\\frac{|\\Delta q_l|}{\\dot q_{max,l}},
            \\sqrt{\\frac{10}{\\sqrt 3}\\frac{|\\Delta q_l|}{\\ddot q_{max,l}}}\\right)

    Parameters
    ----------
    q_start, q_end : array-like of shape (n_joints,)
        Start and end configurations [rad].
    max_velocity, max_acceleration : float or array-like of shape (n_joints,)
        Bounds [rad/s], [rad/s^2].
    min_duration : float, default=0.5
        Lower bound on the result [s].

    Returns
    -------
    duration : float

    Examples
    --------
    >>> from sklearn_gpcd.datasets.trajectory import quintic_duration
    >>> round(quintic_duration([0.0], [1.0], 1.0, 100.0), 3)
    1.875
    """
    dq = np.abs(np.asarray(q_end, dtype=float) - np.asarray(q_start, dtype=float))
    t_vel = _QUINTIC_PEAK_VELOCITY * dq / np.asarray(max_velocity, dtype=float)
    t_acc = np.sqrt(_QUINTIC_PEAK_ACCELERATION * dq / np.asarray(max_acceleration, dtype=float))
    return float(max(min_duration, np.max(t_vel), np.max(t_acc)))


def _as_configuration(q, what):
    q = np.atleast_1d(np.asarray(q, dtype=float))
    if q.ndim != 1:
        raise ValueError(f"{what} must be 1-D (one value per joint), got shape {q.shape}")
    if not np.all(np.isfinite(q)):
        raise ValueError(f"{what} contains NaN or inf: {q}")
    return q


def _as_duration(duration, what):
    duration = float(duration)
    if not np.isfinite(duration) or duration <= 0:
        raise ValueError(f"{what}: duration must be a positive number of seconds, got {duration}")
    return duration
