"""scikit-learn transformer from joint states to rigid-body features."""

import hashlib
import os
from collections import OrderedDict
from numbers import Integral, Real

import numpy as np
from sklearn.base import BaseEstimator, TransformerMixin, _fit_context
from sklearn.utils import Bunch, check_random_state
from sklearn.utils._param_validation import Interval, validate_parameter_constraints
from sklearn.utils.validation import check_is_fitted, validate_data

from ..layout import block_columns
from .._gate import SIGMA_V_CONSTRAINT
from .._persistence import VersionedStateMixin
from ..robots import Robot
from ..robots.loading import resolve_robot
from .base_parameters import base_parameters
from .torque_model import (
    FRICTION_TERMS,
    SampleTorqueFeatures,
    check_friction,
    torque_features,
    parameter_names,
)

#: Random states stacked in ``fit`` to find the structural parameter
#: dependencies: at least this many, and enough for 3 rows per parameter.
_MIN_IDENTIFICATION_STATES = 20


def _random_states(robot, n_states, random_state):
    """Random ``(q, qd, qdd)`` spanning the joint space, for rank detection."""
    rng = check_random_state(random_state)
    n = robot.n_joints
    lo = np.clip(robot.lower, -np.pi, np.pi)
    hi = np.clip(robot.upper, -np.pi, np.pi)
    wide = hi - lo < 1e-3  # unset or tiny limits: use a full turn
    lo, hi = np.where(wide, -np.pi, lo), np.where(wide, np.pi, hi)
    q = rng.uniform(lo, hi, size=(n_states, n))
    qd = rng.uniform(-2.0, 2.0, size=(n_states, n))
    qdd = rng.uniform(-5.0, 5.0, size=(n_states, n))
    return q, qd, qdd


#: Number of base-parameter reductions kept by :func:`_identification`.
_IDENTIFICATION_CACHE_SIZE = 32
_IDENTIFICATION_CACHE = OrderedDict()


def _robot_key(robot):
    """Hashable identity of everything the identification reads from a robot.

    The robot's name and a SHA-1 of its kinematic tree (parents, joint
    types, placements), inertias, rotor inertias, gravity and position
    limits (the random states are drawn inside the limits).
    """
    model = robot.model
    digest = hashlib.sha1()
    digest.update(repr([robot.name, list(model.parents),
                        [j.shortname() for j in model.joints]]).encode())
    arrays = [np.asarray(model.jointPlacements[j].homogeneous) for j in range(model.njoints)]
    arrays += [np.asarray(model.inertias[j].toDynamicParameters()) for j in range(model.njoints)]
    arrays += [np.asarray(model.armature), np.asarray(model.gravity.linear),
               robot.lower, robot.upper]
    for values in arrays:
        digest.update(np.ascontiguousarray(values, dtype=float).tobytes())
    return robot.name, digest.hexdigest()


def _identify(robot, p, regressor, n_states, random_state, reduce, rank_tol):
    """Regressor on random states and its base-parameter reduction (uncached)."""
    Phi = regressor(*_random_states(robot, n_states, random_state), None)
    if reduce:
        info = base_parameters(Phi.reshape(-1, p), rank_tol)
    else:
        info = {"indices": np.arange(p), "dependent": np.array([], dtype=int),
                "mapping": np.eye(p), "rank": p, "tol": 0.0}
    return Phi, info


def _copies(Phi, info):
    return Phi.copy(), {k: v.copy() if isinstance(v, np.ndarray) else v for k, v in info.items()}


def _identification(robot, p, regressor, n_states, random_state, reduce, rank_tol, options):
    """:func:`_identify`, cached when ``random_state`` is an int.

    The result depends only on the robot (:func:`_robot_key`), the column
    options, ``rank_tol`` and the seed, never on the data, so repeated fits
    (cross-validation, one transformer per joint) reuse it. A RandomState
    instance or None draws fresh states and is not cached. Callers get
    copies: mutating them cannot change the cache.
    """
    if not isinstance(random_state, (int, np.integer)) or isinstance(random_state, bool):
        return _identify(robot, p, regressor, n_states, random_state, reduce, rank_tol)
    key = (_robot_key(robot), options, n_states, int(random_state), bool(reduce),
           None if rank_tol is None else float(rank_tol))
    if key in _IDENTIFICATION_CACHE:
        _IDENTIFICATION_CACHE.move_to_end(key)
    else:
        _IDENTIFICATION_CACHE[key] = _identify(robot, p, regressor, n_states, random_state,
                                               reduce, rank_tol)
        while len(_IDENTIFICATION_CACHE) > _IDENTIFICATION_CACHE_SIZE:
            _IDENTIFICATION_CACHE.popitem(last=False)
    return _copies(*_IDENTIFICATION_CACHE[key])


class FrictionColumns(VersionedStateMixin, BaseEstimator):
    """The friction part of :class:`RigidBodyFeatures`: which columns, which Coulomb law.

    Per joint :math:`l`, a Coulomb column :math:`\\mathrm{sign}(\\dot q_l)`
    (or its smooth form) and/or a viscous column :math:`\\dot q_l` (paper
    Eq. 10), always in that order. Pass it as ``RigidBodyFeatures(friction=...)``;
    a tuple of terms there is short for ``FrictionColumns(terms=...)``. Its
    parameters are reached as ``friction__terms`` and ``friction__coulomb_width``
    (``get_params``, ``set_params``, ``GridSearchCV``).

    Parameters
    ----------
    terms : tuple of str or None, default=("coulomb", "viscous")
        Any of ``"coulomb"``, ``"viscous"``; None or ``()`` adds no friction column.
    coulomb_width : float > 0, default=None
        Smooth Coulomb column :math:`\\tanh(\\dot q_l / w)` with this
        velocity scale :math:`w` [rad/s] instead of the sign (ours, not the
        paper's: a still joint's logged velocity jitters around zero and
        flips the sign; see
        :func:`~sklearn_gpcd.dynamics.torque_model.friction_features`).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.dynamics import FrictionColumns, RigidBodyFeatures
    >>> X = np.random.default_rng(0).normal(size=(5, 18))
    >>> smooth = FrictionColumns(coulomb_width=0.01)
    >>> phi = RigidBodyFeatures("ur10", joint=2, friction=smooth).fit(X)
    >>> phi.get_feature_names_out()[-2:].tolist()
    ['coulomb_2', 'viscous_2']
    >>> phi.get_params()["friction__coulomb_width"]
    0.01
    """

    _parameter_constraints = {
        "terms": [None, str, list, tuple],
        "coulomb_width": [None, Interval(Real, 0, np.inf, closed="neither")],
    }

    def __init__(self, terms=FRICTION_TERMS, coulomb_width=None):
        self.terms = terms
        self.coulomb_width = coulomb_width


def _friction_part(friction):
    """``(terms in column order, coulomb_width)`` of a ``friction`` parameter, checked."""
    if not isinstance(friction, FrictionColumns):
        return check_friction(friction), None
    validate_parameter_constraints(FrictionColumns._parameter_constraints,
                                   friction.get_params(deep=False), "FrictionColumns")
    return check_friction(friction.terms), friction.coulomb_width


class RigidBodyFeatures(VersionedStateMixin, TransformerMixin, BaseEstimator):
    """Torque features :math:`\\phi(x)` of the physical torque model.

    Maps joint states ``x = [q, qd, qdd]`` to the rows of the linear model
    :math:`\\tau = \\Phi(x)\\,\\pi` (paper Eq. 8-10; see
    :mod:`sklearn_gpcd.dynamics.torque_model`): pinocchio's rigid-body features
    plus per-joint rotor-inertia, Coulomb, viscous and offset columns,
    optionally reduced to the base (identifiable) parameters and expressed
    in motor-current units (Eq. 4). These are the features of the parametric
    kernel and mean of the semi-parametric GP.

    Parameters
    ----------
    robot : str, path or Robot, default="ur10"
        Built-in name, URDF path or :class:`~sklearn_gpcd.robots.Robot`.
    joint : int, default=None
        0-based joint whose torque rows to return, shape ``(n, p_l)``
        (columns identically zero for that joint are dropped, decided in
        ``fit``). ``None`` returns every joint stacked joint by joint:
        shape ``(n * n_joints, p)``, row ``l * n + k`` is joint ``l`` of
        sample ``k`` (pair it with ``Y.ravel(order="F")`` for a target array
        ``Y`` of shape ``(n, n_joints)``).
    friction : FrictionColumns, tuple of str or None, default=("coulomb", "viscous")
        Friction columns per joint (:class:`FrictionColumns`: the terms and
        the Coulomb law); a tuple of terms is short for
        ``FrictionColumns(terms=...)``, None adds no friction column.
    rotor_inertia : bool, default=True
        Add a :math:`\\ddot q_l` column per joint (reflected rotor inertia,
        Eq. 4). pinocchio's regressor lacks this term, ``rnea`` includes it.
    offset : bool, default=False
        Add a constant column per joint.
    base_parameters : bool, default=True
        Keep only independent columns (QR with column pivoting of the
        regressor stacked over random states drawn in ``fit``); see
        ``base_parameters_``.
    rank_tol : float, default=None
        Relative rank tolerance: pivot ``i`` is independent when
        :math:`|R_{ii}| > \\text{rank\\_tol}\\,|R_{00}|`; ``None`` means
        ``max(W.shape) * eps``.
    sigma_v : float, default=None
        If set, friction columns are zeroed where :math:`|\\dot q_l| <
        \\sigma_v` (the paper's :math:`\\bar\\phi`, Eq. 17).
    currents : bool, default=False
        Divide joint ``l``'s rows by ``robot.torque_constants[l]`` so the
        model predicts motor currents [A] (Eq. 4).
    random_state : int, RandomState or None, default=0
        Seed of the random states used for the base-parameter reduction.

    Attributes
    ----------
    robot_ : Robot
        The resolved robot.
    n_joints_ : int
    n_features_in_ : int
        Columns of ``X`` seen in ``fit``: ``3 * n_joints`` (``[q, qd, qdd]``)
        or ``6 * n_joints`` (the augmented inputs, whose last three blocks
        are ignored). Any other count is refused: it is the layout of
        another joint count (e.g. 7-joint logs against a 9-joint URDF).
    feature_names_in_ : ndarray of str
        Defined when ``X`` has string column names.
    parameter_names_ : list of str
        Names of the full parameter vector :math:`\\pi` (see
        :func:`~sklearn_gpcd.dynamics.parameter_names`).
    base_parameters_ : dict
        ``indices`` (independent columns of the full torque features),
        ``mapping`` ``K`` of shape ``(n_base, n_parameters)`` with
        :math:`\\Phi_{base}\\,(K\\pi) = \\Phi\\,\\pi`, ``names``, ``rank`` and
        ``tol`` (absolute threshold on :math:`|R_{ii}|`). Identity mapping
        when ``base_parameters=False``.
    columns_ : ndarray of int
        Columns of the full torque features returned by ``transform``.
    parameter_mapping_ : ndarray of shape (n_features_out, n_parameters)
        Rows of ``K`` for ``columns_``: ``transform(X) @ (parameter_mapping_
        @ pi)`` are the torques (currents) of the selected joint(s).
    friction_columns_ : ndarray of int
        Output columns holding friction terms (to apply Eq. 17 elsewhere).
    friction_ : tuple of str
        The friction terms, in column order.
    coulomb_width_ : float or None
        The smooth Coulomb law's velocity scale (None: the sign).

    Notes
    -----
    The estimator needs ``3 * n_joints`` or ``6 * n_joints`` (18 or 36 for
    UR arms) input columns in the :mod:`sklearn_gpcd.layout` order.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.dynamics import RigidBodyFeatures
    >>> X = np.random.default_rng(0).normal(size=(5, 18))
    >>> phi = RigidBodyFeatures("ur10e", joint=1).fit(X)
    >>> phi.transform(X).shape[0]
    5
    >>> phi.get_feature_names_out()[:2].tolist()
    ['link1_mx', 'link1_my']
    """

    _parameter_constraints = {
        "robot": [str, os.PathLike, Robot],
        "joint": [None, Interval(Integral, 0, None, closed="left")],
        "friction": [None, str, list, tuple, FrictionColumns],
        "rotor_inertia": ["boolean"],
        "offset": ["boolean"],
        "base_parameters": ["boolean"],
        "rank_tol": [None, Interval(Real, 0, np.inf, closed="neither")],
        "sigma_v": [None, SIGMA_V_CONSTRAINT],
        "currents": ["boolean"],
        "random_state": ["random_state"],
    }

    def __init__(self, robot="ur10", joint=None, friction=FRICTION_TERMS, rotor_inertia=True,
                 offset=False, base_parameters=True, rank_tol=None, sigma_v=None,
                 currents=False, random_state=0):
        self.robot = robot
        self.joint = joint
        self.friction = friction
        self.rotor_inertia = rotor_inertia
        self.offset = offset
        self.base_parameters = base_parameters
        self.rank_tol = rank_tol
        self.sigma_v = sigma_v
        self.currents = currents
        self.random_state = random_state

    # ------------------------------------------------------------ helpers
    def _check_params(self, robot):
        """What ``_parameter_constraints`` cannot say: checks against the robot."""
        n = robot.n_joints
        if self.joint is not None and self.joint >= n:
            raise ValueError(f"joint={self.joint} out of range for {n} joints (0-based)")
        if self.currents and robot.torque_constants is None:
            raise ValueError(
                f"currents=True needs torque constants, robot {robot.name!r} has none: "
                "use load_robot(name, torque_constants=[...])"
            )
        return _friction_part(self.friction)

    def _check_columns(self, X, n):
        if X.shape[1] in (3 * n, 6 * n):
            return
        width = X.shape[1]
        logged = width // 6 if width % 6 == 0 else width // 3 if width % 3 == 0 else None
        fix = ("" if not logged else
               f" (the inputs of {logged} joints); select the robot's joints the data has: "
               f"--joints {logged} on the command line, load_robot(urdf, joints={logged}) "
               "in Python")
        raise ValueError(
            f"X has {width} columns{fix}, but robot {self.robot_.name!r} has {n} joints and "
            f"needs [q, qd, qdd] ({3 * n} columns) or x^a ({6 * n}; see sklearn_gpcd.layout)")

    def _split(self, X):
        n = self.n_joints_
        return (X[:, block_columns("q", n)], X[:, block_columns("qd", n)],
                X[:, block_columns("qdd", n)])

    def _regressor(self, q, qd, qdd, sigma_v, joints=None):
        return torque_features(self.robot_, q, qd, qdd, rotor_inertia=self.rotor_inertia,
                              friction=self.friction_, offset=self.offset, sigma_v=sigma_v,
                              joints=joints, coulomb_width=self.coulomb_width_)

    # ---------------------------------------------------------------- API
    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X, y=None):
        """Resolve the robot and find the output columns.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            Joint states in the :mod:`sklearn_gpcd.layout` order (only used
            for validation; the column selection uses random states).
        y : None
            Ignored.

        Returns
        -------
        self : RigidBodyFeatures
        """
        X = validate_data(self, X, dtype=np.float64)
        self.robot_ = resolve_robot(self.robot)
        self.friction_, self.coulomb_width_ = self._check_params(self.robot_)
        n = self.n_joints_ = self.robot_.n_joints
        self._check_columns(X, n)
        self.parameter_names_ = parameter_names(n, self.rotor_inertia, self.friction_, self.offset)
        p = len(self.parameter_names_)

        n_states = max(_MIN_IDENTIFICATION_STATES, -(-3 * p // n))
        options = (bool(self.rotor_inertia), self.friction_, bool(self.offset),
                   self.coulomb_width_)
        Phi, info = _identification(self.robot_, p, self._regressor, n_states,
                                    self.random_state, self.base_parameters, self.rank_tol,
                                    options)
        info["names"] = [self.parameter_names_[i] for i in info["indices"]]
        self.base_parameters_ = info

        keep = np.arange(info["rank"])
        if self.joint is not None:
            rows = Phi[:, self.joint, info["indices"]]
            scale = np.abs(Phi).max()
            keep = np.flatnonzero(np.abs(rows).max(axis=0) > 1e-12 * scale)
        self.columns_ = info["indices"][keep]
        self.parameter_mapping_ = info["mapping"][keep]
        names = np.asarray(self.parameter_names_, dtype=object)[self.columns_]
        self._feature_names_out = names
        is_friction = np.array([name.split("_")[0] in FRICTION_TERMS for name in names], dtype=bool)
        self.friction_columns_ = np.flatnonzero(is_friction)
        return self

    def transform(self, X):
        """Torque-feature rows of the selected joint(s).

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            Joint states; columns ``[q, qd, qdd]`` are used.

        Returns
        -------
        Phi : ndarray of shape (n_samples, n_features_out) or \
(n_samples * n_joints, n_features_out)
            One row per sample for ``joint=l``; joint-by-joint blocks of
            ``n_samples`` rows for ``joint=None``.
        """
        check_is_fitted(self)
        X = validate_data(self, X, dtype=np.float64, reset=False)
        Phi = self._regressor(*self._split(X), self.sigma_v, self.joint)[:, :, self.columns_]
        if self.currents:
            k_tau = self.robot_.torque_constants
            Phi /= (k_tau if self.joint is None else k_tau[[self.joint]])[None, :, None]
        if self.joint is not None:
            return Phi[:, 0, :]
        return Phi.transpose(1, 0, 2).reshape(-1, Phi.shape[2])

    def sample_features(self):
        """The per-tick path of :meth:`transform`: one sample, no validation.

        Returns
        -------
        features : Bunch
            ``full``, a :class:`~sklearn_gpcd.dynamics.torque_model.SampleTorqueFeatures`
            mapping ``(q, qd, qdd)`` of one sample to the regressor of every
            joint and parameter; ``key``, equal for estimators whose ``full``
            agree (several joints of one robot share one evaluation per tick);
            ``rows``, ``columns`` and ``scale``, this estimator's selection:
            ``transform(x[None])`` equals
            ``full(q, qd, qdd)[rows][:, columns] * scale[:, None]``;
            ``q``, ``qd``, ``qdd``, the input columns of the state (slices).

        Examples
        --------
        >>> import numpy as np
        >>> from sklearn_gpcd.dynamics import RigidBodyFeatures
        >>> X = np.random.default_rng(0).normal(size=(4, 18))
        >>> est = RigidBodyFeatures("ur10", joint=2, sigma_v=0.01).fit(X)
        >>> f = est.sample_features()
        >>> x = X[0]
        >>> one = f.full(x[f.q], x[f.qd], x[f.qdd])[f.rows][:, f.columns] * f.scale[:, None]
        >>> bool(np.allclose(one, est.transform(X[:1])))
        True
        """
        check_is_fitted(self)
        n = self.n_joints_
        rows = np.arange(n) if self.joint is None else np.array([self.joint])
        scale = np.ones(len(rows))
        if self.currents:
            scale = 1.0 / np.asarray(self.robot_.torque_constants, dtype=float)[rows]
        options = (bool(self.rotor_inertia), tuple(self.friction_), bool(self.offset),
                   self.sigma_v, self.coulomb_width_)
        return Bunch(
            full=SampleTorqueFeatures(self.robot_, *options),
            key=(_robot_key(self.robot_),) + options,
            rows=rows,
            columns=np.asarray(self.columns_),
            scale=scale,
            **{name: _as_slice(block_columns(name, n)) for name in ("q", "qd", "qdd")},
        )

    def __setstate__(self, state):
        """Load a state; one written before the friction part (a ``coulomb_width``
        parameter beside ``friction``) gets its :class:`FrictionColumns`."""
        if "coulomb_width" in state:
            width = state.pop("coulomb_width")
            if width is not None:
                state["friction"] = FrictionColumns(state.get("friction"), width)
            if "friction_" in state:
                state["coulomb_width_"] = width
        super().__setstate__(state)

    def get_feature_names_out(self, input_features=None):
        """Names of the output columns (full-parameter names, e.g. ``link2_mx``).

        A base-parameter column is named after the independent parameter it
        keeps; the others it absorbs are in ``base_parameters_["mapping"]``.

        Parameters
        ----------
        input_features : array-like of str, default=None
            Only checked for length against ``n_features_in_``.

        Returns
        -------
        names : ndarray of str
        """
        check_is_fitted(self)
        if input_features is not None:
            input_features = np.asarray(input_features)
            if len(input_features) != self.n_features_in_:
                raise ValueError(
                    f"input_features has {len(input_features)} names, expected "
                    f"{self.n_features_in_}"
                )
            if hasattr(self, "feature_names_in_") and not np.array_equal(
                input_features, self.feature_names_in_
            ):
                raise ValueError("input_features differ from feature_names_in_")
        return self._feature_names_out.copy()

    def project_parameters(self, pi):
        """Map a full parameter vector to this transformer's output columns.

        Parameters
        ----------
        pi : array-like of shape (n_parameters,)
            Ordered like ``parameter_names_`` (see
            :func:`~sklearn_gpcd.dynamics.parameter_vector`).

        Returns
        -------
        beta : ndarray of shape (n_features_out,)
            ``transform(X) @ beta`` reproduces the model torques (currents).
        """
        check_is_fitted(self)
        pi = np.asarray(pi, dtype=float).reshape(-1)
        if pi.shape != (len(self.parameter_names_),):
            raise ValueError(
                f"pi needs {len(self.parameter_names_)} values ordered like parameter_names_, "
                f"got {pi.shape[0]}"
            )
        return self.parameter_mapping_ @ pi

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.target_tags.required = False
        return tags


def _as_slice(columns):
    """Consecutive column indices as a slice (a view when indexing a row)."""
    return slice(columns[0], columns[-1] + 1)
