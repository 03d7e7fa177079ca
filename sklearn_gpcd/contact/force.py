r"""How hard: the contact force from the joint residual torques.

With the contact at a known point :math:`p` on link :math:`k` and a pure
force :math:`F` there (no moment: a point contact), the external joint
torques are

.. math:: \tau_{ext} = J_p(q)^T F, \qquad J_p \in \mathbb{R}^{3 \times n},

with :math:`J_p` the linear Jacobian of the point (world axes; its columns
beyond :math:`k` are zero). Given the residual torques :math:`\hat\tau` and
their standard deviations :math:`\sigma_\ell` (e.g. a GP's predictive std
times the torque constants, or the observer's noise level), the weighted
least-squares estimate and its covariance are

.. math::

    \hat F = (A^T A)^{+} A^T W \hat\tau, \quad A = W J_p^T, \quad
    W = \mathrm{diag}(1/\sigma_\ell), \qquad
    \mathrm{Cov}(\hat F) = (A^T A)^{+},

and the magnitude's standard deviation is propagated to first order,
:math:`\sigma_{|F|} = \sqrt{u^T \mathrm{Cov}(\hat F)\, u}` with
:math:`u = \hat F / |\hat F|`.

**Assumptions.** One contact, on the given link, at the given point, a pure
force (a moment or a second contact is read as a different force); the
residual is the external torque (the model error is inside
:math:`\sigma`); the residual and the configuration are taken at the same
sample (the observer's and the filter's lag are small against the push).

**When it is ill-conditioned.** Only the joints up to :math:`k` see the
force, so a contact on link 1 or 2 gives one or two equations for three
unknowns: the estimate is then the minimum-norm force (a lower bound of the
magnitude) and ``rank < 3``. A point on a joint's axis gives no torque on
that joint; near a kinematic singularity two rows of :math:`J_p^T` become
parallel. ``condition`` (the ratio of the largest to the smallest singular
value of :math:`A` over the force directions) says how much the noise of
the best-seen direction is amplified in the worst-seen one; above
``max_condition`` or with ``rank < 3`` the result is flagged
``well_conditioned=False``.
"""

import numpy as np
import pinocchio as pin
from sklearn.utils import Bunch

from ..robots.loading import resolve_robot
from ..robots.robot import as_joint_batch

__all__ = ["contact_point", "estimate_force", "protected_force"]


def _body_frame(model, link):
    """Id of the first BODY frame on joint ``link`` (else the joint's frame)."""
    for fid, frame in enumerate(model.frames):
        if frame.parentJoint == link and frame.type == pin.FrameType.BODY:
            return fid
    for fid, frame in enumerate(model.frames):
        if frame.parentJoint == link and frame.type == pin.FrameType.JOINT:
            return fid
    raise ValueError(f"no frame on joint {link}")


def contact_point(robot, link, point=None):
    """A contact point on a link, in the frame of the joint that moves it.

    Parameters
    ----------
    robot : str, path or Robot
    link : int
        1-based link.
    point : array-like of shape (3,), default=None
        The point in the joint frame (pinocchio ``LOCAL`` of joint ``link``,
        as :class:`~sklearn_gpcd.datasets.Contact` takes it); None takes the
        origin of the link's body frame (for the built-in UR models, the DH
        frame of the link: the elbow for link 2, the wrist for link 3).

    Returns
    -------
    point : ndarray of shape (3,)

    Examples
    --------
    >>> from sklearn_gpcd.contact import contact_point
    >>> contact_point("ur10", 2).round(3).tolist()
    [-0.612, 0.0, 0.0]
    """
    robot = resolve_robot(robot)
    n = robot.n_joints
    if not 1 <= int(link) <= n:
        raise ValueError(f"link must be in 1..{n}, got {link!r}")
    if point is not None:
        point = np.asarray(point, dtype=float)
        if point.shape != (3,) or not np.all(np.isfinite(point)):
            raise ValueError(f"point must be 3 finite numbers, got {point!r}")
        return point
    model = robot.model
    frame = model.frames[_body_frame(model, int(link))]
    return np.asarray(frame.placement.translation, dtype=float).copy()


def estimate_force(robot, q, torque, *, link, point=None, torque_std=None,
                   max_condition=10.0):
    """External force magnitude at a contact point from the joint residual torques.

    Parameters
    ----------
    robot : str, path or Robot
    q : array-like of shape (n_joints,) or (n_samples, n_joints)
        Joint positions [rad] at the sample(s).
    torque : array-like of the shape of ``q``
        Residual (external) joint torques [Nm], e.g. the momentum
        observer's :math:`r` or a current residual times the torque
        constants (mind the sign: only the magnitude is returned).
    link : int
        1-based link of the contact (e.g. from
        :func:`~sklearn_gpcd.contact.isolate_contact`).
    point : array-like of shape (3,), default=None
        Contact point in the joint frame of ``link``; see
        :func:`contact_point`.
    torque_std : array-like of shape (n_joints,) or the shape of ``q``, default=None
        Standard deviation of each residual torque [Nm] (a GP's predictive
        std times the torque constants); None weighs the joints equally
        with a unit std (then ``magnitude_std`` is in units of it).
    max_condition : float, default=10.0
        Largest ``condition`` still flagged ``well_conditioned``.

    Returns
    -------
    result : Bunch
        ``force`` (ndarray (..., 3) [N], world axes), ``magnitude`` [N],
        ``magnitude_std`` [N], ``covariance`` (..., 3, 3), ``condition``,
        ``rank`` (of the 3 force directions the joints see) and
        ``well_conditioned`` (bool: ``rank == 3`` and ``condition <=
        max_condition``); scalars for one sample, arrays for several.

    Examples
    --------
    >>> import numpy as np
    >>> import pinocchio as pin
    >>> from sklearn_gpcd.robots import load_robot
    >>> from sklearn_gpcd.contact import estimate_force
    >>> robot = load_robot("ur10")
    >>> q = np.array([0.3, -1.2, 1.4, -1.5, -1.4, 0.2])
    >>> point = [0.0, 0.05, 0.16]                         # on link 4
    >>> model, data = robot.model, robot.model.createData()
    >>> pin.forwardKinematics(model, data, q)
    >>> J = pin.computeJointJacobian(model, data, q, 4)   # LOCAL frame of joint 4
    >>> F_local = np.array([40.0, -20.0, 30.0])           # N, in that frame
    >>> tau = J[:3].T @ F_local + J[3:].T @ np.cross(point, F_local)
    >>> out = estimate_force(robot, q, tau, link=4, point=point)
    >>> round(out.magnitude, 3), out.rank
    (53.852, 3)
    """
    robot = resolve_robot(robot)
    n = robot.n_joints
    q, single = as_joint_batch(q, n, "q")
    torque, _ = as_joint_batch(torque, n, "torque")
    if torque.shape != q.shape:
        raise ValueError(f"torque must have the shape of q, got {torque.shape} and {q.shape}")
    link = int(link)
    p = contact_point(robot, link, point)
    std = np.ones_like(q) if torque_std is None else np.broadcast_to(
        np.asarray(torque_std, dtype=float), q.shape)
    if not np.all(std > 0):
        raise ValueError("torque_std must be > 0")
    model = robot.model
    data = model.createData()
    m = len(q)
    force = np.zeros((m, 3))
    covariance = np.zeros((m, 3, 3))
    condition = np.zeros(m)
    rank = np.zeros(m, dtype=int)
    for k in range(m):
        pin.forwardKinematics(model, data, q[k])
        J = pin.computeJointJacobian(model, data, q[k], link)  # LOCAL frame of joint `link`
        rotation = data.oMi[link].rotation
        # linear velocity of the point, in world axes: R (v + w x p)
        Jp = rotation @ (J[:3] - _skew(p) @ J[3:])
        A = Jp.T / std[k][:, None]
        U, s, Vt = np.linalg.svd(A, full_matrices=False)
        tol = max(A.shape) * np.finfo(float).eps * (s[0] if s.size else 0.0)
        keep = s > max(tol, 1e-12)
        rank[k] = int(keep.sum())
        condition[k] = s[0] / s[keep][-1] if rank[k] == 3 else np.inf
        inverse = (Vt[keep].T / s[keep]) @ U[:, keep].T
        force[k] = inverse @ (torque[k] / std[k])
        covariance[k] = (Vt[keep].T / s[keep] ** 2) @ Vt[keep]
    magnitude = np.linalg.norm(force, axis=1)
    unit = force / np.maximum(magnitude, np.finfo(float).tiny)[:, None]
    magnitude_std = np.sqrt(np.einsum("ki,kij,kj->k", unit, covariance, unit))
    well = (rank == 3) & (condition <= max_condition)
    out = Bunch(force=force, magnitude=magnitude, magnitude_std=magnitude_std,
                covariance=covariance, condition=condition, rank=rank, well_conditioned=well)
    if single:
        out = Bunch(**{key: (value[0] if key in ("force", "covariance") else value[0].item())
                       for key, value in out.items()})
    return out


def _skew(p):
    """The matrix of ``p x .``."""
    return np.array([[0.0, -p[2], p[1]], [p[2], 0.0, -p[0]], [-p[1], p[0], 0.0]])


def protected_force(robot, q, thresholds, *, link=None, point=None):
    r"""The smallest force at a point that the thresholds always catch [N].

    A force :math:`F` at the point loads the joints with
    :math:`\tau = J_p(q)^T F`; an alarm needs some joint over its threshold,
    :math:`|\tau_\ell| > \bar\tau_\ell`. The forces that stay silent form the
    polytope :math:`P = \{F : |a_\ell^T F| \le 1\}`, :math:`a_\ell =
    J_{p,\ell} / \bar\tau_\ell`, and the monitor is *protected at*
    :math:`X = \max_{F \in P} |F|`: every force above :math:`X` N, in any
    direction, raises an alarm. The maximum of :math:`|F|` over a polytope
    is at a vertex, where three of the planes :math:`a_\ell^T F = \pm 1`
    meet: ``X`` is exact, from the :math:`\binom{n}{3} \cdot 8` candidate
    vertices. Where the joints see fewer than three force directions (a
    point on link 1 or 2, a singular pose), some force is never seen:
    ``X = inf``.

    This is the threshold's reach alone: the normal residual at the moment
    adds to or subtracts from a contact's torque (a margin of
    :math:`|m_\ell|` per joint).

    Parameters
    ----------
    robot : str, path or Robot
    q : array-like of shape (n_joints,) or (n_samples, n_joints)
        Joint positions [rad].
    thresholds : array-like of shape (n_joints,) or the shape of ``q``
        Joint torque thresholds [Nm] (current thresholds [A] times the
        torque constants); ``inf`` for a joint that cannot alarm.
    link : int, default=None
        1-based link of the point; None takes the last (the flange).
    point : array-like of shape (3,), default=None
        The point in the joint frame of ``link`` (:func:`contact_point`).

    Returns
    -------
    force : float or ndarray of shape (n_samples,)
        ``X`` [N].

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.contact import protected_force
    >>> q = np.array([0.3, -1.2, 1.4, -1.5, -1.4, 0.2])
    >>> x = protected_force("ur10", q, np.full(6, 5.0))     # 5 Nm on every joint
    >>> round(x, 1), bool(protected_force("ur10", q, np.full(6, 10.0)) > x)
    (20.4, True)
    """
    robot = resolve_robot(robot)
    n = robot.n_joints
    q, single = as_joint_batch(q, n, "q")
    thresholds = np.broadcast_to(np.asarray(thresholds, dtype=float), q.shape)
    if np.any(~(thresholds > 0)):
        raise ValueError("thresholds must be > 0 (inf for a joint that cannot alarm)")
    link = n if link is None else int(link)
    p = contact_point(robot, link, point)
    model = robot.model
    data = model.createData()
    triples = np.array([t for t in _triples(n)])
    signs = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)], float)
    out = np.empty(len(q))
    for k in range(len(q)):
        pin.forwardKinematics(model, data, q[k])
        J = pin.computeJointJacobian(model, data, q[k], link)
        Jp = data.oMi[link].rotation @ (J[:3] - _skew(p) @ J[3:])
        out[k] = _farthest_vertex(Jp.T / thresholds[k][:, None], triples, signs)
    return float(out[0]) if single else out


def _triples(n):
    for i in range(n):
        for j in range(i + 1, n):
            for k in range(j + 1, n):
                yield (i, j, k)


def _farthest_vertex(A, triples, signs):
    """``max |F|`` over ``{F : |A F| <= 1}`` (rows ``a_l``), inf if unbounded."""
    scale = max(float(np.abs(A).max()), 1e-300)
    if np.linalg.matrix_rank(A / scale, tol=1e-9) < 3:
        return np.inf
    M = A[triples] / scale                               # (n_triples, 3, 3)
    ok = np.abs(np.linalg.det(M)) > 1e-12
    F = np.linalg.solve(M[ok], np.broadcast_to(signs.T, (ok.sum(), 3, 8)))  # (t, 3, 8)
    F = F.transpose(0, 2, 1).reshape(-1, 3) / scale      # every candidate vertex
    feasible = np.all(np.abs(F @ A.T) <= 1.0 + 1e-9, axis=1)
    return float(np.linalg.norm(F[feasible], axis=1).max()) if feasible.any() else 0.0
