"""Workspace geometry for the data-set generators: hemisphere, IK, circle path."""

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from sklearn.utils import check_random_state


@dataclass(frozen=True)
class Hemisphere:
    """A hemispherical shell of end-effector targets (paper Sec. V-A).

    A point ``p`` is inside when

    .. math::

        r_{in} \\le \\lVert p - c \\rVert \\le R, \\qquad
        (p - c) \\cdot a \\ge 0, \\qquad
        \\lVert (p - c) - ((p - c) \\cdot z) z \\rVert \\ge \\rho,

    with ``c`` the centre, ``a`` the (unit) axis, ``z`` the base's vertical
    axis and ``rho`` the radius of a cylinder about the base axis that is
    left out (there the arm is singular).

    Parameters
    ----------
    center : array-like of shape (3,)
        Centre ``c`` in the base frame [m].
    radius : float
        Outer radius ``R`` [m].
    inner_radius : float, default=0.0
        Inner radius ``r_in`` [m].
    axis : array-like of shape (3,), default=(0, 0, 1)
        Direction ``a`` of the dome (normalised).
    axis_clearance : float, default=0.0
        ``rho`` [m].

    Examples
    --------
    >>> from sklearn_gpcd.datasets import Hemisphere
    >>> h = Hemisphere(center=[0, 0, 0], radius=1.0, inner_radius=0.2)
    >>> h.contains([[0.5, 0.0, 0.1], [0.5, 0.0, -0.1], [0.1, 0.0, 0.0]]).tolist()
    [True, False, False]
    >>> points = h.sample(100, random_state=0)
    >>> bool(h.contains(points).all())
    True
    """

    center: np.ndarray
    radius: float
    inner_radius: float = 0.0
    axis: np.ndarray = (0.0, 0.0, 1.0)
    axis_clearance: float = 0.0

    def __post_init__(self):
        center = np.asarray(self.center, dtype=float)
        axis = np.asarray(self.axis, dtype=float)
        if center.shape != (3,) or axis.shape != (3,) or not np.linalg.norm(axis) > 0:
            raise ValueError(
                f"Hemisphere needs a 3-vector center and a non-zero 3-vector axis, got "
                f"{self.center!r}, {self.axis!r}"
            )
        if not 0 <= self.inner_radius < self.radius:
            raise ValueError(
                f"Hemisphere needs 0 <= inner_radius < radius, got {self.inner_radius}, "
                f"{self.radius}"
            )
        if not 0 <= self.axis_clearance < self.radius:
            raise ValueError(
                f"Hemisphere.axis_clearance must be in [0, radius), got {self.axis_clearance}"
            )
        object.__setattr__(self, "center", center)
        object.__setattr__(self, "axis", axis / np.linalg.norm(axis))

    def contains(self, points, tol=1e-9):
        """Whether each point lies in the shell.

        Parameters
        ----------
        points : array-like of shape (n_points, 3) or (3,)
        tol : float, default=1e-9
            Tolerance [m].

        Returns
        -------
        inside : ndarray of bool, shape (n_points,) or ()
        """
        d = np.asarray(points, dtype=float) - self.center
        r = np.linalg.norm(d, axis=-1)
        horizontal = np.linalg.norm(d[..., :2], axis=-1)
        return (
            (r >= self.inner_radius - tol)
            & (r <= self.radius + tol)
            & (d @ self.axis >= -tol)
            & (horizontal >= self.axis_clearance - tol)
        )

    def sample(self, n_points, random_state=None):
        """Points uniformly distributed in the shell (rejection sampling).

        Parameters
        ----------
        n_points : int
        random_state : int, RandomState instance or None, default=None

        Returns
        -------
        points : ndarray of shape (n_points, 3)
        """
        rng = check_random_state(random_state)
        out = np.empty((0, 3))
        while out.shape[0] < n_points:
            m = 2 * (n_points - out.shape[0]) + 16
            d = rng.uniform(-self.radius, self.radius, size=(m, 3))
            p = self.center + d
            out = np.vstack([out, p[self.contains(p)]])
        return out[:n_points]

    @classmethod
    def for_robot(cls, robot, radius=0.85, inner_radius=0.3, axis_clearance=0.2):
        """Upper hemisphere centred at the shoulder, scaled by the arm's reach.

        The centre is joint 2's origin at the neutral configuration, the
        reach the distance from there to the flange with the arm stretched
        (``q = 0`` for UR arms).

        Parameters
        ----------
        robot : Robot
        radius, inner_radius, axis_clearance : float
            As fractions of the reach.

        Returns
        -------
        hemisphere : Hemisphere

        Examples
        --------
        >>> from sklearn_gpcd.robots import load_robot
        >>> from sklearn_gpcd.datasets import Hemisphere
        >>> h = Hemisphere.for_robot(load_robot("ur10"))
        >>> bool(h.contains(h.center + [0.5, 0.0, 0.1]))
        True
        """
        model = robot.model
        data = model.createData()
        pin.forwardKinematics(model, data, pin.neutral(model))
        pin.updateFramePlacements(model, data)
        center = data.oMi[min(2, model.njoints - 1)].translation.copy()
        flange = data.oMf[model.getFrameId(robot.flange_frame)].translation
        reach = float(np.linalg.norm(flange - center))
        return cls(center=center, radius=radius * reach, inner_radius=inner_radius * reach,
                   axis=(0.0, 0.0, 1.0), axis_clearance=axis_clearance * reach)


def inverse_kinematics(robot, position, q_init, rotation=None, posture=None,
                       posture_gain=0.1, damping=1e-3, tol=1e-5, max_iter=200):
    """Closed-loop inverse kinematics of the flange (damped least squares).

    Position only (``rotation=None``):

    .. math::

        \\Delta q = J^T (J J^T + \\lambda^2 I)^{-1} e
            + (I - J^\\dagger J)\\, k (q_{post} - q),
        \\qquad e = p^* - p(q),

    with ``J`` the linear flange Jacobian in the base-aligned frame; the
    null-space term pulls the redundant orientation towards ``posture``.
    With a rotation the error is ``log6(T(q)^{-1} T^*)`` and ``J`` the
    6-D Jacobian in the flange frame (pinocchio's CLIK example).

    Parameters
    ----------
    robot : Robot
    position : array-like of shape (3,)
        Target flange position [m] in the base frame.
    q_init : array-like of shape (n_joints,)
        Start of the iteration (the previous configuration, for continuity).
    rotation : array-like of shape (3, 3), default=None
        Target flange orientation.
    posture : array-like of shape (n_joints,), default=None
        Null-space attractor; None means ``q_init``.
    posture_gain, damping, tol : float
        ``k``, ``lambda``, tolerance on the error norm.
    max_iter : int, default=200

    Returns
    -------
    q : ndarray of shape (n_joints,)
    error : float
        Final error norm (check it against ``tol``).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.robots import load_robot
    >>> from sklearn_gpcd.datasets import inverse_kinematics
    >>> robot = load_robot("ur10")
    >>> q0 = np.array([0.0, -1.57, 1.57, -1.57, -1.57, 0.0])
    >>> q, err = inverse_kinematics(robot, [-0.6, -0.3, 0.5], q0)
    >>> err < 1e-5
    True
    """
    model = robot.model
    data = model.createData()
    frame = model.getFrameId(robot.flange_frame)
    q = np.array(q_init, dtype=float)
    posture = q.copy() if posture is None else np.asarray(posture, dtype=float)
    target = pin.SE3(np.eye(3) if rotation is None else np.asarray(rotation, float),
                     np.asarray(position, dtype=float))
    eye_n = np.eye(model.nv)
    error = np.inf
    for _ in range(max_iter):
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacement(model, data, frame)
        if rotation is None:
            e = target.translation - data.oMf[frame].translation
            jac = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED)[:3]
        else:
            e = pin.log6(data.oMf[frame].actInv(target)).vector
            jac = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL)
        error = float(np.linalg.norm(e))
        if error < tol:
            break
        gram = jac @ jac.T + damping**2 * np.eye(jac.shape[0])
        pinv = jac.T @ np.linalg.inv(gram)
        dq = pinv @ e
        if rotation is None:
            dq = dq + (eye_n - pinv @ jac) @ (posture_gain * (posture - q))
        step = np.max(np.abs(dq))
        if step > 0.3:  # trust region: keep the iteration on one IK branch
            dq *= 0.3 / step
        q = q + dq
    return q, error


def circle_timing(radius, tool_speed, n_turns=1.0, ramp_time=1.0, sample_period=0.02):
    """Arc length ``s(t)`` of a constant-speed circle with smooth start and stop.

    The tool speed ``v(t) = v_tool sigma(t / T_r) sigma((T - t) / T_r)``, with
    ``sigma`` the quintic smoothstep, rises from rest in ``T_r`` seconds; the
    duration ``T = L / v_tool + T_r`` covers the arc ``L = 2 pi r n``
    (the ramps together lose ``T_r`` seconds of travel).

    Parameters
    ----------
    radius, tool_speed : float
        [m], [m/s].
    n_turns : float, default=1.0
        Turns (fractions allowed).
    ramp_time : float, default=1.0
        ``T_r`` [s].
    sample_period : float, default=0.02
        Spacing of the returned samples [s].

    Returns
    -------
    t : ndarray of shape (n_samples,)
    s : ndarray of shape (n_samples,)
        Arc length [m], from 0 to ``L``.

    Examples
    --------
    >>> from sklearn_gpcd.datasets.workspace import circle_timing
    >>> t, s = circle_timing(0.3, 0.03)
    >>> round(float(t[-1]), 1), round(float(s[-1]), 4)
    (63.8, 1.885)
    """
    length = 2.0 * np.pi * radius * n_turns
    duration = length / tool_speed + ramp_time
    fine = np.linspace(0.0, duration, int(np.ceil(duration / 1e-3)) + 1)

    def smoothstep(x):
        x = np.clip(x, 0.0, 1.0)
        return x**3 * (10 - 15 * x + 6 * x**2)

    speed = tool_speed * smoothstep(fine / ramp_time) * smoothstep((duration - fine) / ramp_time)
    s_fine = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(fine))])
    s_fine *= length / s_fine[-1]
    n = int(np.ceil(duration / sample_period)) + 1
    t = np.linspace(0.0, duration, n)
    return t, np.interp(t, fine, s_fine)
