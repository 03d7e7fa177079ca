"""The linear-in-parameters torque model and its features :math:`\\Phi`.

The joint torques of a rigid serial arm with reflected rotor inertias,
friction and offsets are linear in the parameters (paper Eq. 8-10):

.. math::

    \\tau = \\Phi(q, \\dot q, \\ddot q)\\, \\pi,
    \\qquad
    \\Phi = [\\,Y_{rb}(q, \\dot q, \\ddot q) \\;|\\; \\mathrm{diag}(\\ddot q)
            \\;|\\; \\mathrm{diag}(\\mathrm{sign}\\,\\dot q)
            \\;|\\; \\mathrm{diag}(\\dot q) \\;|\\; I\\,],

with :math:`Y_{rb}` pinocchio's joint torque regressor (10 standard inertial
parameters per link, in the frame of the joint that moves the link, ordered
``m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz``; inertias about the joint
frame origin) and one rotor-inertia, Coulomb, viscous and offset column per
joint. Note that ``pinocchio.rnea`` adds ``model.armature * qdd`` while
``pinocchio.computeJointTorqueRegressor`` does not: the rotor-inertia block
supplies that term.

The full parameter vector is ordered

``[link_0 (10), ..., link_{n-1} (10), rotor_0..rotor_{n-1},
coulomb_0..coulomb_{n-1}, viscous_0..viscous_{n-1}, offset_0..offset_{n-1}]``

keeping only the blocks that are switched on. Joints and links are 0-based
like the columns of :mod:`sklearn_gpcd.layout` (link ``k`` is moved by
joint ``k``).
"""

import hashlib

import numpy as np
import pinocchio as pin

from .._gate import quasi_static
from ..robots.loading import resolve_robot
from ..robots.robot import as_joint_batch

#: Names of pinocchio's 10 standard inertial parameters of one link.
INERTIAL_PARAMETERS = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
#: Friction models, in the order their columns appear.
FRICTION_TERMS = ("coulomb", "viscous")


def check_friction(friction):
    """Validate a friction spec and return it in canonical column order.

    Parameters
    ----------
    friction : None, str or iterable of str
        Any of ``"coulomb"``, ``"viscous"``.

    Returns
    -------
    terms : tuple of str

    Examples
    --------
    >>> check_friction(("viscous", "coulomb"))
    ('coulomb', 'viscous')
    >>> check_friction(None)
    ()
    """
    if friction is None:
        return ()
    if isinstance(friction, str):
        friction = (friction,)
    terms = tuple(friction)
    unknown = [t for t in terms if t not in FRICTION_TERMS]
    if unknown:
        raise ValueError(f"unknown friction term(s) {unknown}; choose from {list(FRICTION_TERMS)}")
    return tuple(t for t in FRICTION_TERMS if t in terms)


def parameter_names(n_joints, rotor_inertia=True, friction=FRICTION_TERMS, offset=False):
    """Names of the full parameter vector (see module docstring for the order).

    Parameters
    ----------
    n_joints : int
    rotor_inertia : bool, default=True
    friction : iterable of str, default=("coulomb", "viscous")
    offset : bool, default=False

    Returns
    -------
    names : list of str
        ``"link{k}_{param}"``, ``"rotor_{l}"``, ``"coulomb_{l}"``,
        ``"viscous_{l}"``, ``"offset_{l}"``.

    Examples
    --------
    >>> parameter_names(1, friction=("viscous",))[:2], parameter_names(1)[-3:]
    (['link0_m', 'link0_mx'], ['rotor_0', 'coulomb_0', 'viscous_0'])
    """
    names = [f"link{k}_{p}" for k in range(n_joints) for p in INERTIAL_PARAMETERS]
    blocks = (["rotor"] if rotor_inertia else []) + list(check_friction(friction))
    blocks += ["offset"] if offset else []
    names += [f"{b}_{j}" for b in blocks for j in range(n_joints)]
    return names


def inertial_features(model, q, qd, qdd):
    """Pinocchio's joint torque regressor, the inertial block of :math:`\\Phi`, for a batch.

    Parameters
    ----------
    model : pinocchio.Model
    q, qd, qdd : ndarray of shape (n_samples, nv)

    Returns
    -------
    Y : ndarray of shape (n_samples, nv, 10 * nv)
        ``Y[k] @ pi_links`` is ``pinocchio.rnea`` of sample ``k`` without
        armature.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.robots import load_robot
    >>> model = load_robot("ur5").model
    >>> inertial_features(model, *np.zeros((3, 2, 6))).shape
    (2, 6, 60)
    """
    return _joint_torque_rows(model, q, qd, qdd).copy()


def _joint_torque_rows(model, q, qd, qdd, rows=None):
    """Rows ``rows`` (default all) of :func:`inertial_features`, read-only.

    The features of the last batch are cached when it has at most
    :data:`CACHE_MAX_BYTES` bytes; a larger batch is computed for the
    requested rows only (so the feature map of one joint of D1, 80,000
    samples, needs 38 MB instead of 230 MB).
    """
    n, nv = q.shape
    # small batches (e.g. one streaming tick) skip the cache: its key costs
    # ~30 us, as much as computing one sample
    key = _batch_key(model, q, qd, qdd) if n >= CACHE_MIN_SAMPLES else None
    if key is not None and _LAST_BATCH.get("key") == key:
        full = _LAST_BATCH["value"]
        return full if rows is None else full[:, rows, :]
    cache = key is not None and n * nv * 10 * nv * 8 <= CACHE_MAX_BYTES
    keep = np.arange(nv) if (rows is None or cache) else np.asarray(rows)
    out = np.empty((n, len(keep), 10 * nv))
    data = model.createData()
    for k in range(n):
        out[k] = pin.computeJointTorqueRegressor(model, data, q[k], qd[k], qdd[k])[keep]
    out.setflags(write=False)
    if cache:
        _LAST_BATCH.clear()
        _LAST_BATCH.update(key=key, value=out)
        return out if rows is None else out[:, rows, :]
    return out


#: The features of the last batch of states are kept when it has at most this
#: many bytes (46,000 samples of a 6-joint arm), so that the feature maps of
#: the joints of one recording, fitted one after the other, call pinocchio
#: once per sample instead of once per joint and per call.
CACHE_MAX_BYTES = 128 * 2**20
#: ... and only for batches of at least this many samples.
CACHE_MIN_SAMPLES = 256
_LAST_BATCH = {}


def _batch_key(model, q, qd, qdd):
    """Digest of a model's kinematics/inertias and of a batch of states."""
    digest = hashlib.blake2b(digest_size=16)
    digest.update(" ".join(joint.shortname() for joint in model.joints).encode())
    for inertia in model.inertias:
        digest.update(np.asarray(inertia.toDynamicParameters(), dtype=float).tobytes())
    for placement in model.jointPlacements:
        digest.update(np.asarray(placement.homogeneous, dtype=float).tobytes())
    digest.update(np.asarray(model.gravity.linear, dtype=float).tobytes())
    for array in (q, qd, qdd):
        array = np.ascontiguousarray(array, dtype=float)
        digest.update(repr(array.shape).encode())
        digest.update(array.tobytes())
    return digest.hexdigest()


def _diagonal_block(values, rows=None):
    """(n, nv) per-joint values -> (n, len(rows), nv), ``values[:, l]`` at ``[l, l]``.

    ``rows`` (default: all joints) are the joints whose rows are kept.
    """
    n, nv = values.shape
    rows = np.arange(nv) if rows is None else rows
    block = np.zeros((n, len(rows), nv))
    block[:, np.arange(len(rows)), rows] = values[:, rows]
    return block


def friction_features(qd, term, sigma_v=None, coulomb_width=None):
    """Per-joint friction regressors, gated by the velocity threshold.

    Coulomb: :math:`\\mathrm{sign}(\\dot q_l)` (the paper's Eq. 9), or with
    ``coulomb_width`` :math:`w` the smooth law :math:`\\tanh(\\dot q_l / w)`;
    viscous: :math:`\\dot q_l`. With ``sigma_v`` set they are zeroed where
    :math:`|\\dot q_l| < \\sigma_v` (the paper's :math:`\\bar\\phi`, Eq. 17),
    because friction at rest is not a function of velocity.

    The smooth law is ours, not the paper's. A logged velocity is never
    exactly zero: a still UR10e joint reads about :math:`\\pm 10^{-4}` rad/s,
    and the sign column then flips by the whole Coulomb level from one
    sample to the next (about 1.2 A predicted on joint 2 while the measured
    current stays flat). :math:`\\tanh(\\dot q / w)` turns over within
    :math:`|\\dot q| \\lesssim w` and equals the sign to within
    :math:`2 e^{-2 |\\dot q| / w}` beyond.

    Parameters
    ----------
    qd : ndarray of shape (n_samples, n_joints)
    term : {"coulomb", "viscous"}
    sigma_v : float, default=None
    coulomb_width : float > 0, default=None
        Velocity scale :math:`w` [rad/s] of the smooth Coulomb law; ``None``
        is the sign.

    Returns
    -------
    features : ndarray of shape (n_samples, n_joints)

    Examples
    --------
    >>> import numpy as np
    >>> friction_features(np.array([[0.001, -0.5]]), "coulomb", sigma_v=0.01).tolist()
    [[0.0, -1.0]]
    >>> friction_features(np.array([[1e-4, -0.5]]), "coulomb", coulomb_width=0.01).round(3)
    array([[ 0.01, -1.  ]])
    """
    if term != "coulomb":
        values = np.array(qd, dtype=float)
    elif coulomb_width is None:
        values = np.sign(qd)
    else:
        values = np.tanh(np.asarray(qd, dtype=float) / coulomb_width)
    if sigma_v is not None:
        values = np.where(quasi_static(np.asarray(qd), sigma_v), 0.0, values)
    return values


def torque_features(robot, q, qd, qdd, rotor_inertia=True, friction=FRICTION_TERMS,
                   offset=False, sigma_v=None, joints=None, coulomb_width=None):
    """Torque features :math:`\\Phi` of the full parameter vector for a batch of states.

    Parameters
    ----------
    robot : Robot or str
    q, qd, qdd : array-like of shape (n_samples, n_joints)
    rotor_inertia : bool, default=True
        Add the ``diag(qdd)`` block (reflected rotor inertias, Eq. 4).
    friction : iterable of str, default=("coulomb", "viscous")
    offset : bool, default=False
        Add a constant per-joint column.
    sigma_v : float, default=None
        Velocity threshold of the friction gate (Eq. 17).
    joints : int or sequence of int, default=None
        Keep only the rows of these joints (all by default).
    coulomb_width : float > 0, default=None
        Coulomb column :math:`\\tanh(\\dot q_l / w)` instead of the sign
        (see :func:`friction_features`).

    Returns
    -------
    Phi : ndarray of shape (n_samples, n_rows, n_parameters)
        ``Phi[k] @ parameter_vector(...)`` are the torques of sample ``k`` of
        the ``n_rows`` selected joints (all ``n_joints`` by default).

    Examples
    --------
    >>> import numpy as np
    >>> torque_features("ur10", *np.zeros((3, 4, 6))).shape
    (4, 6, 78)
    >>> torque_features("ur10", *np.zeros((3, 4, 6)), joints=2).shape
    (4, 1, 78)
    """
    robot = resolve_robot(robot)
    n = robot.n_joints
    q, _ = as_joint_batch(q, n, "q")
    qd, _ = as_joint_batch(qd, n, "qd")
    qdd, _ = as_joint_batch(qdd, n, "qdd")
    rows = np.arange(n) if joints is None else np.atleast_1d(np.asarray(joints, dtype=int))
    return _assemble(_joint_torque_rows(robot.model, q, qd, qdd, rows), qd, qdd, rows,
                     rotor_inertia, friction, offset, sigma_v, coulomb_width)


def _assemble(torque_rows, qd, qdd, rows, rotor_inertia, friction, offset, sigma_v,
              coulomb_width=None):
    """The blocks of :func:`torque_features` after pinocchio's rows ``torque_rows``."""
    blocks = [torque_rows]
    if rotor_inertia:
        blocks.append(_diagonal_block(qdd, rows))
    for term in check_friction(friction):
        blocks.append(_diagonal_block(friction_features(qd, term, sigma_v, coulomb_width), rows))
    if offset:
        blocks.append(_diagonal_block(np.ones_like(qd), rows))
    return np.concatenate(blocks, axis=2)


def parameter_vector(robot, friction=None, rotor_inertia=True, offset=None):
    """The full parameter vector :math:`\\pi` of a robot model.

    Parameters
    ----------
    robot : Robot or str
        Inertial parameters are read from ``robot.model.inertias`` (in joint
        frames) and rotor inertias from ``robot.model.armature``.
    friction : dict, default=None
        ``{"coulomb": values, "viscous": values}`` (any subset), one value per
        joint [Nm] and [Nm s/rad]. Blocks are placed in the canonical order
        ``coulomb, viscous`` whatever the dict order.
    rotor_inertia : bool, default=True
        Include the ``rotor_l`` block.
    offset : array-like of shape (n_joints,), default=None
        Constant torque offsets; ``None`` leaves the block out.

    Returns
    -------
    pi : ndarray of shape (n_parameters,)
        Ordered like :func:`parameter_names` with the same options.

    Examples
    --------
    >>> pi = parameter_vector("ur5", friction={"viscous": [1.0] * 6})
    >>> pi.shape, float(pi[0])
    ((72,), 3.7)
    """
    robot = resolve_robot(robot)
    model = robot.model
    n = robot.n_joints
    parts = [np.concatenate([model.inertias[j].toDynamicParameters() for j in range(1, n + 1)])]
    if rotor_inertia:
        parts.append(np.asarray(model.armature, dtype=float))
    friction = {} if friction is None else dict(friction)
    for term in check_friction(tuple(friction)):
        values = np.asarray(friction[term], dtype=float).reshape(-1)
        if values.shape != (n,):
            raise ValueError(f"friction[{term!r}] needs {n} values, got shape {values.shape}")
        parts.append(values)
    if offset is not None:
        values = np.asarray(offset, dtype=float).reshape(-1)
        if values.shape != (n,):
            raise ValueError(f"offset needs {n} values, got shape {values.shape}")
        parts.append(values)
    return np.concatenate(parts)


class SampleTorqueFeatures:
    """:func:`torque_features` of one state at a time, for per-tick use.

    Keeps one pinocchio ``Data`` and skips the batch validation, so one call
    costs one ``computeJointTorqueRegressor`` plus the rotor-inertia,
    friction and offset columns (the per-tick rigid-body mean of the
    streaming monitor, Eq. 10 and 17). Given ``out`` (an earlier result),
    only pinocchio's block and the diagonals of the per-joint blocks are
    written: the rest of those blocks stays zero.

    Parameters
    ----------
    robot : Robot or str
    rotor_inertia, friction, offset, sigma_v, coulomb_width
        As in :func:`torque_features`.

    Examples
    --------
    >>> import numpy as np
    >>> q, qd, qdd = np.random.default_rng(0).normal(size=(3, 6))
    >>> one = SampleTorqueFeatures("ur10", sigma_v=0.01)(q, qd, qdd)
    >>> one.shape
    (6, 78)
    >>> bool(np.allclose(one, torque_features("ur10", q, qd, qdd, sigma_v=0.01)[0]))
    True
    """

    def __init__(self, robot, rotor_inertia=True, friction=FRICTION_TERMS, offset=False,
                 sigma_v=None, coulomb_width=None):
        self.robot = resolve_robot(robot)
        self.options = (bool(rotor_inertia), tuple(check_friction(friction)), bool(offset),
                        sigma_v, coulomb_width)
        self._data = self.robot.model.createData()
        n = self.robot.n_joints
        self._rows = np.arange(n)
        self.n_parameters = n * (10 + rotor_inertia + len(self.options[1]) + offset)

    def _diagonal(self, block):
        """Flat positions of ``[l, l]`` in per-joint block ``block`` (0: the first
        after pinocchio's) of an ``(n_joints, n_parameters)`` array."""
        n = len(self._rows)
        return self._rows * (self.n_parameters + 1) + (10 + block) * n

    def __call__(self, q, qd, qdd, out=None):
        """The ``(n_joints, n_parameters)`` regressor at the state ``(q, qd, qdd)``.

        ``out``, an earlier result of this call, is overwritten and returned.
        """
        rotor_inertia, friction, offset, sigma_v, coulomb_width = self.options
        Y = pin.computeJointTorqueRegressor(self.robot.model, self._data, q, qd, qdd)
        if out is None:
            out = np.zeros((len(self._rows), self.n_parameters))
            if offset:  # constant: written once
                np.put(out, self._diagonal(int(rotor_inertia) + len(friction)), 1.0)
        out[:, : Y.shape[1]] = Y
        if rotor_inertia:
            np.put(out, self._diagonal(0), qdd)
        for block, term in enumerate(friction, start=int(rotor_inertia)):
            np.put(out, self._diagonal(block),
                   friction_features(qd, term, sigma_v, coulomb_width))
        return out
