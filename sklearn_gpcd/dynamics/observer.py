r"""The generalized-momentum observer: the field's standard collision monitor.

De Luca and Mattone (ICRA 2005; Haddadin, De Luca and Albu-Schäffer, IEEE
T-RO 2017, Sec. IV) monitor the generalized momentum :math:`p = M(q)\dot q`
of the rigid arm. With the motor torque :math:`\tau_m = K_\tau i` (the
robot's ``torque_constants`` times the measured currents), the friction
:math:`\tau_f(\dot q)` and the external torque :math:`\tau_{ext}`, the
dynamics :math:`M\ddot q + C\dot q + g + \tau_f = \tau_m + \tau_{ext}` and
:math:`\dot M = C + C^T` give

.. math::

    \dot p = \tau_m + \tau_{ext} - \tau_f(\dot q) + C(q, \dot q)^T \dot q - g(q),

and the residual

.. math::

    r(t) = K_O \Big[ p(t) - p(0) - \int_0^t \big(\tau_m - \tau_f + C^T\dot q
        - g + r\big)\, ds \Big]
    \quad\Longrightarrow\quad \dot r = K_O\,(\tau_{ext} - r)

is the external torque seen through a first-order low-pass filter of
bandwidth :math:`K_O` per joint (a diagonal gain), with no acceleration
and no inversion of the inertia matrix. The same principle sits in KDL's
``ChainExternalWrenchEstimator`` and in ``mikhel1984/ext_observer``, the
companion code of the UR10e recordings of Mamedov and Mikhel (2020).

**Discrete time.** Between samples :math:`k-1` and :math:`k`
(:math:`\Delta t_k` apart, from the time stamps or ``sample_time``) the
external torque is taken constant, equal to its mean
:math:`\bar\tau_k = \big(p_k - p_{k-1} - \tfrac{\Delta t_k}{2}(\beta_k +
\beta_{k-1})\big) / \Delta t_k` with :math:`\beta = \tau_m - \tau_f + C^T
\dot q - g` (trapezoidal rule), and the filter is integrated exactly:

.. math:: r_k = a_k r_{k-1} + (1 - a_k)\,\bar\tau_k, \qquad a_k = e^{-K_O \Delta t_k}.

It is causal (sample :math:`k` uses samples :math:`k` and :math:`k-1`),
stable for any gain and any time step (the UR10e logs jitter from 2 to
34 ms) and starts at :math:`r_0 = 0` at the first sample of a recording.

**Model.** :math:`M(q)`, :math:`C(q, \dot q)` and :math:`g(q)` are
pinocchio's (``crba``, ``computeCoriolisMatrix``,
``computeGeneralizedGravity``) on the package's robot model, with the
inertial parameters, reflected rotor inertias and friction identified by
:meth:`MomentumObserver.fit` from collision-free recordings (the linear
model of :class:`~sklearn_gpcd.dynamics.RigidBodyFeatures`). The friction
law is :math:`\tau_{f,\ell} = F_{c,\ell}\tanh(\dot q_\ell / w) + F_{v,\ell}
\dot q_\ell + o_\ell` (smooth Coulomb, viscous, offset).
"""

import numbers
import os

import numpy as np
import pinocchio as pin
from sklearn.base import BaseEstimator, _fit_context
from sklearn.utils._param_validation import Interval, StrOptions
from sklearn.utils.validation import check_is_fitted, validate_data

from .._persistence import VersionedStateMixin
from ..layout import block_columns
from ..robots import Robot
from ..robots.loading import resolve_robot
from .torque_model import torque_features, parameter_vector
from .rigid_body import FrictionColumns, RigidBodyFeatures

__all__ = ["MomentumObserver", "MomentumObserverStream", "UR_OBSERVER_GAINS"]

#: Observer gains :math:`K_O` [1/s] per joint of a six-joint UR arm: those of
#: the UR10 test of ``mikhel1984/ext_observer`` (the UR10e data authors'
#: companion code), i.e. residual bandwidths of 6-14 Hz.
UR_OBSERVER_GAINS = (90.0, 50.0, 50.0, 90.0, 90.0, 40.0)

_IDENTIFY = ("all", "friction", "none")


class MomentumObserverStream(VersionedStateMixin):
    """Per-tick form of a fitted :class:`MomentumObserver`.

    Built by :meth:`MomentumObserver.stream`. Each :meth:`update` takes one
    sample and returns the residual current of that sample; the sequence of
    updates on a recording equals :meth:`MomentumObserver.residual` on it
    (the batch form runs the same recursion). :meth:`reset` starts a new
    recording (the batch form's ``groups``).

    Parameters
    ----------
    observer : MomentumObserver
        A fitted observer.

    Attributes
    ----------
    external_torque : ndarray of shape (n_joints,)
        The observer state :math:`r` of the last sample [Nm].
    residual : ndarray of shape (n_joints,)
        :math:`-r / K_\\tau` [A], the residual current of the last sample.
    last_time : float or None
        Time stamp of the last sample.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.dynamics import MomentumObserver
    >>> rng = np.random.default_rng(0)
    >>> X, current = rng.normal(size=(20, 18)) * 0.1, rng.normal(size=(20, 6))
    >>> obs = MomentumObserver("ur10", identify="none").fit(X, current)
    >>> stream = obs.stream()
    >>> rows = [stream.update(x, i).copy() for x, i in zip(X, current)]
    >>> bool(np.allclose(rows, obs.residual(X, current)))
    True
    """

    def __init__(self, observer):
        check_is_fitted(observer)
        self.observer = observer
        self._bind()
        self.reset()

    def _bind(self):
        obs = self.observer
        self._model = obs.model_
        self._data = self._model.createData()
        n = obs.n_joints_
        self._q = slice(0, n)
        self._qd = slice(n, 2 * n)
        self._k_tau = obs.torque_constants_
        self._gains = obs.gains_
        self._coulomb, self._viscous = obs.friction_["coulomb"], obs.friction_["viscous"]
        self._offset, self._width = obs.friction_["offset"], obs.coulomb_width

    def __getstate__(self):
        state = super().__getstate__()
        for name in ("_model", "_data", "_q", "_qd", "_k_tau", "_gains", "_coulomb",
                     "_viscous", "_offset", "_width"):
            state.pop(name, None)
        return state

    def __setstate__(self, state):
        super().__setstate__(state)
        self._bind()

    def reset(self):
        """Start a new recording: the next sample restarts the observer at ``r = 0``.

        Examples
        --------
        >>> import numpy as np
        >>> from sklearn_gpcd.dynamics import MomentumObserver
        >>> X = np.zeros((3, 18))
        >>> stream = MomentumObserver("ur10", identify="none").fit(X, np.zeros((3, 6))).stream()
        >>> stream.reset()
        >>> stream.last_time is None
        True
        """
        n = self.observer.n_joints_
        self.external_torque = np.zeros(n)
        self.residual = np.zeros(n)
        self._momentum = None
        self._beta = None
        self.last_time = None

    def _terms(self, q, qd, current):
        """Momentum ``M qd`` and ``beta = tau_m - tau_f + C^T qd - g`` of one sample."""
        model, data = self._model, self._data
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        C = pin.computeCoriolisMatrix(model, data, q, qd)
        g = pin.computeGeneralizedGravity(model, data, q)
        friction = self._coulomb * np.tanh(qd / self._width) + self._viscous * qd + self._offset
        return M @ qd, self._k_tau * current - friction + C.T @ qd - g

    def update(self, x, current, time=None):
        """Process one sample; return its residual current.

        Parameters
        ----------
        x : array-like of shape (n_features,)
            One row in the :mod:`sklearn_gpcd.layout` order (``q`` and
            ``qd`` are read).
        current : array-like of shape (n_joints,)
            Measured motor currents [A].
        time : float, default=None
            Time stamp [s]; None advances by the observer's ``sample_time``.

        Returns
        -------
        residual : ndarray of shape (n_joints,)
            :math:`-r / K_\\tau` [A] (the attribute ``residual``, overwritten
            by the next call).
        """
        x = np.asarray(x, dtype=float)
        current = np.asarray(current, dtype=float)
        momentum, beta = self._terms(x[self._q], x[self._qd], current)
        if self._momentum is not None:
            if time is None or self.last_time is None:
                dt = float(self.observer.sample_time)
            else:
                dt = float(time) - self.last_time
            if not dt > 0:
                raise ValueError(f"time must increase from sample to sample, got a step of {dt}")
            mean_torque = (momentum - self._momentum - 0.5 * dt * (beta + self._beta)) / dt
            a = np.exp(-self._gains * dt)
            self.external_torque = a * self.external_torque + (1.0 - a) * mean_torque
        self._momentum, self._beta = momentum, beta
        self.last_time = None if time is None else float(time)
        np.divide(-self.external_torque, self._k_tau, out=self.residual)
        return self.residual


class MomentumObserver(VersionedStateMixin, BaseEstimator):
    """Generalized-momentum observer (De Luca and Mattone 2005) as a residual model.

    ``fit`` identifies the rigid-body and friction parameters from
    collision-free recordings; :meth:`external_torque` then returns the
    observer residual :math:`r` [Nm] (see the module docstring for the
    equations and the discretisation) and :meth:`residual` the same in motor
    current units, :math:`-r / K_\\tau` [A], with the sign of the package's
    residuals ``i - i_hat`` (a push the motors resist raises ``i``). The
    per-tick form is :meth:`stream`; both give identical numbers.

    Unlike the package's regressors, the observer is a dynamic filter: the
    residual of a sample depends on the samples before it in the same
    recording, so its methods take the measured currents and the recording
    boundaries (``groups``) besides the inputs. A
    :class:`~sklearn_gpcd.detection.CollisionDetector` passes both (see
    :meth:`predict`), so the observer is a detector's residual model under
    the same alarm rules and calibration as any regressor.

    Parameters
    ----------
    robot : str, path or Robot, default="ur10"
        The arm (see :func:`~sklearn_gpcd.robots.load_robot`); needs
        ``torque_constants``.
    gains : float or array-like of shape (n_joints,), default=None
        Observer gains :math:`K_O` [1/s]; None takes
        :data:`UR_OBSERVER_GAINS` for six joints (else 50 per joint).
    identify : {"all", "friction", "none"}, default="all"
        What ``fit`` identifies by weighted least squares on the
        collision-free rows (torque ``K_tau y`` against the regressor of
        :class:`~sklearn_gpcd.dynamics.RigidBodyFeatures`): ``"all"``, the
        base inertial parameters, rotor inertias and friction (the full
        parameter vector is the nominal one plus the minimum-norm correction
        that reproduces the identified base parameters); ``"friction"``, only
        rotor inertia, Coulomb, viscous and offset per joint on top of the
        nominal rigid body; ``"none"``, the nominal model without friction.
    coulomb_width : float > 0, default=0.01
        Velocity scale :math:`w` [rad/s] of the smooth Coulomb law
        :math:`\\tanh(\\dot q / w)`.
    offset : bool, default=True
        Identify a constant torque per joint.
    alpha : float >= 0, default=1e-3
        Ridge weight pulling the identified parameters towards the nominal
        ones, relative to each column's norm.
    sample_time : float > 0, default=0.008
        Time step [s] used when no time stamps are given.
    random_state : int, default=0
        Seed of the base-parameter reduction
        (:class:`~sklearn_gpcd.dynamics.RigidBodyFeatures`).

    Attributes
    ----------
    robot_ : Robot
    n_joints_ : int
    n_features_in_ : int
    gains_ : ndarray of shape (n_joints,)
    torque_constants_ : ndarray of shape (n_joints,)
    model_ : pinocchio.Model
        The robot model with the identified inertias and rotor inertias
        (``armature``).
    parameters_ : ndarray
        The full parameter vector used, ordered like
        :func:`~sklearn_gpcd.dynamics.parameter_names` (rotor, Coulomb,
        viscous and offset blocks).
    friction_ : dict
        ``coulomb``, ``viscous``, ``offset``: ndarrays of shape (n_joints,)
        [Nm], [Nm s/rad], [Nm].
    residual_std_ : ndarray of shape (n_joints,)
        RMS of :meth:`residual` on the fitted rows [A] (each recording of
        ``groups`` run on its own): the observer's noise level, returned as
        the std by ``residual(..., return_std=True)``.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.dynamics import MomentumObserver
    >>> rng = np.random.default_rng(0)
    >>> q = np.tile([0.0, -1.57, 1.57, -1.57, -1.57, 0.0], (50, 1))
    >>> X = np.hstack([q, np.zeros((50, 12))])          # [q, qd, qdd], arm at rest
    >>> obs = MomentumObserver("ur10", identify="none").fit(X, np.zeros((50, 6)))
    >>> current = obs.robot_.gravity(q[0]) / obs.torque_constants_    # holds the arm
    >>> r = obs.external_torque(X, np.tile(current, (50, 1)))
    >>> float(np.abs(r).max()) < 1e-9
    True
    """

    _parameter_constraints = {
        "robot": [str, os.PathLike, Robot],
        "gains": [None, numbers.Real, "array-like"],
        "identify": [StrOptions(set(_IDENTIFY))],
        "coulomb_width": [Interval(numbers.Real, 0, np.inf, closed="neither")],
        "offset": ["boolean"],
        "alpha": [Interval(numbers.Real, 0, np.inf, closed="left")],
        "sample_time": [Interval(numbers.Real, 0, np.inf, closed="neither")],
        "random_state": ["random_state"],
    }

    def __init__(self, robot="ur10", *, gains=None, identify="all", coulomb_width=0.01,
                 offset=True, alpha=1e-3, sample_time=0.008, random_state=0):
        self.robot = robot
        self.gains = gains
        self.identify = identify
        self.coulomb_width = coulomb_width
        self.offset = offset
        self.alpha = alpha
        self.sample_time = sample_time
        self.random_state = random_state

    # ------------------------------------------------------------- fitting
    def _gains(self, n):
        if self.gains is None:
            return np.array(UR_OBSERVER_GAINS if n == 6 else [50.0] * n)
        gains = np.broadcast_to(np.asarray(self.gains, dtype=float), (n,)).copy()
        if not np.all(np.isfinite(gains) & (gains > 0)):
            raise ValueError(f"gains must be finite and > 0, got {self.gains!r}")
        return gains

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X, y, *, groups=None, time=None):
        """Identify the model on collision-free rows and measure the residual's spread.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            Inputs in the :mod:`sklearn_gpcd.layout` order, at least
            ``[q, qd, qdd]`` (the identification uses ``qdd``; the observer
            itself does not).
        y : array-like of shape (n_samples, n_joints)
            Measured motor currents [A].
        groups : array-like of shape (n_samples,), default=None
            Recording of each row (for ``residual_std_``).
        time : array-like of shape (n_samples,), default=None
            Time stamps [s] (for ``residual_std_``).

        Returns
        -------
        self : MomentumObserver
        """
        X, y = validate_data(self, X, y, multi_output=True, dtype=np.float64)
        robot = self.robot_ = resolve_robot(self.robot)
        n = self.n_joints_ = robot.n_joints
        y = np.reshape(y, (len(y), -1))
        if X.shape[1] < 3 * n or y.shape[1] != n:
            raise ValueError(
                f"MomentumObserver needs X with at least {3 * n} columns ([q, qd, qdd]) and y "
                f"with {n} currents; got X {X.shape}, y {y.shape}"
            )
        if robot.torque_constants is None:
            raise ValueError(f"robot {robot.name!r} has no torque_constants")
        self.gains_ = self._gains(n)
        k_tau = self.torque_constants_ = np.asarray(robot.torque_constants, dtype=float)
        q, qd, qdd = (X[:, block_columns(b, n)] for b in ("q", "qd", "qdd"))
        tau = y * k_tau
        zeros = np.zeros(n)
        terms = {"coulomb": zeros, "viscous": zeros}
        pi0 = parameter_vector(robot, friction=terms, offset=zeros)
        if self.identify == "all":
            pi = self._identify_all(X, tau, pi0)
        elif self.identify == "friction":
            pi = self._identify_friction(q, qd, qdd, tau, pi0)
        else:
            pi = pi0
        self.parameters_ = pi
        links = 10 * n
        self.model_ = _model_with(robot.model, pi[:links].reshape(n, 10), pi[links:links + n])
        self.friction_ = {"coulomb": pi[links + n:links + 2 * n],
                          "viscous": pi[links + 2 * n:links + 3 * n],
                          "offset": pi[links + 3 * n:links + 4 * n]}
        residual = self.residual(X, y, groups=groups, time=time)
        self.residual_std_ = np.sqrt(np.mean(residual ** 2, axis=0))
        return self

    def _weighted_solve(self, Phi, tau, beta0):
        """Ridge least squares of ``Phi beta = tau`` (rows joint by joint), each
        joint weighted by the inverse of its residual spread (two passes)."""
        n = self.n_joints_
        rows = tau.shape[0]
        target = tau.ravel(order="F")
        weight = np.repeat(1.0 / np.maximum(tau.std(axis=0), 1e-6), rows)
        beta = beta0
        for _ in range(2):
            A, b = Phi * weight[:, None], target * weight
            scale = np.sum(A ** 2, axis=0) + 1e-12
            beta = np.linalg.solve(A.T @ A + self.alpha * np.diag(scale),
                                   A.T @ b + self.alpha * scale * beta0)
            spread = (target - Phi @ beta).reshape(n, rows).std(axis=1)
            weight = np.repeat(1.0 / np.maximum(spread, 1e-6), rows)
        return beta

    def _identify_all(self, X, tau, pi0):
        n = self.n_joints_
        friction = FrictionColumns(("coulomb", "viscous"), self.coulomb_width)
        phi = RigidBodyFeatures(self.robot_, friction=friction, offset=self.offset,
                                random_state=self.random_state).fit(X[:, :3 * n])
        K = phi.parameter_mapping_
        start = pi0 if self.offset else pi0[:-n]
        beta = self._weighted_solve(phi.transform(X[:, :3 * n]), tau, K @ start)
        pi = start + np.linalg.pinv(K) @ (beta - K @ start)
        return pi if self.offset else np.concatenate([pi, np.zeros(n)])

    def _identify_friction(self, q, qd, qdd, tau, pi0):
        n = self.n_joints_
        Phi = torque_features(self.robot_, q, qd, qdd, friction=("coulomb", "viscous"),
                             offset=True, coulomb_width=self.coulomb_width)
        links = 10 * n
        rigid = Phi[:, :, :links] @ pi0[:links]
        pi = pi0.copy()
        for joint in range(n):
            cols = links + joint + n * np.arange(4 if self.offset else 3)
            A = Phi[:, joint, cols]
            b = tau[:, joint] - rigid[:, joint]
            scale = np.sum(A ** 2, axis=0) + 1e-12
            pi[cols] = np.linalg.solve(A.T @ A + self.alpha * np.diag(scale), A.T @ b)
        return pi

    # ------------------------------------------------------------- outputs
    def stream(self):
        """A per-tick observer, :class:`MomentumObserverStream`, at ``r = 0``.

        Returns
        -------
        stream : MomentumObserverStream

        Examples
        --------
        >>> import numpy as np
        >>> from sklearn_gpcd.dynamics import MomentumObserver
        >>> obs = MomentumObserver("ur10", identify="none").fit(np.zeros((2, 18)), np.zeros((2, 6)))
        >>> obs.stream().update(np.zeros(18), np.zeros(6)).shape
        (6,)
        """
        check_is_fitted(self)
        return MomentumObserverStream(self)

    def external_torque(self, X, current, *, groups=None, time=None):
        """The observer residual :math:`r` [Nm] of every row (batch form).

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            Inputs in the :mod:`sklearn_gpcd.layout` order (``q``, ``qd``).
        current : array-like of shape (n_samples, n_joints)
            Measured motor currents [A].
        groups : array-like of shape (n_samples,), default=None
            Recording of each row: the observer restarts where it changes.
        time : array-like of shape (n_samples,), default=None
            Time stamps [s]; None steps by ``sample_time``.

        Returns
        -------
        r : ndarray of shape (n_samples, n_joints)
            Estimated external joint torques, low-passed at ``gains_`` [Nm].
        """
        check_is_fitted(self)
        X = validate_data(self, X, dtype=np.float64, reset=False)
        current = np.reshape(np.asarray(current, dtype=float), (X.shape[0], self.n_joints_))
        if not np.all(np.isfinite(current)):
            raise ValueError("current contains NaN or inf")
        stream = MomentumObserverStream(self)
        out = np.empty_like(current)
        groups = None if groups is None else np.asarray(groups)
        stamps = None if time is None else np.asarray(time, dtype=float)
        for k in range(X.shape[0]):
            if k and groups is not None and groups[k] != groups[k - 1]:
                stream.reset()
            stream.update(X[k], current[k], None if stamps is None else stamps[k])
            out[k] = stream.external_torque
        return out

    def residual(self, X, current, *, groups=None, time=None, return_std=False):
        """The residual current :math:`-r / K_\\tau` [A] of every row (batch form).

        Parameters
        ----------
        X, current, groups, time
            As in :meth:`external_torque`.
        return_std : bool, default=False
            Also return ``residual_std_`` broadcast to every row.

        Returns
        -------
        residual : ndarray of shape (n_samples, n_joints)
        std : ndarray of shape (n_samples, n_joints)
            Only with ``return_std``.
        """
        r = self.external_torque(X, current, groups=groups, time=time)
        residual = -r / self.torque_constants_
        if return_std:
            return residual, np.broadcast_to(self.residual_std_, residual.shape).copy()
        return residual

    def predict(self, X, current, *, groups=None, time=None, return_std=False):
        """The current the collision-free model expects: ``current - residual``.

        What a regressor's ``predict`` gives in a detector: a
        :class:`~sklearn_gpcd.detection.CollisionDetector` with the observer
        as its ``regressor`` thresholds ``current - predict`` and passes the
        measured currents and the recording of each row (the ``current``
        parameter marks a model that reads them,
        :func:`~sklearn_gpcd.detection.reads_currents`), so the detector's
        residual is the observer's, under the same alarm rules as any
        monitor. Inside a detector the observer steps by ``sample_time``
        (the detector passes no time stamps): set it to the data's period.

        Parameters
        ----------
        X, current, groups, time
            As in :meth:`external_torque`.
        return_std : bool, default=False
            Also return ``residual_std_`` broadcast to every row (the
            observer's noise level, constant).

        Returns
        -------
        i_hat : ndarray of shape (n_samples, n_joints)
        std : ndarray of shape (n_samples, n_joints)
            Only with ``return_std``.

        Examples
        --------
        >>> import numpy as np
        >>> from sklearn.frozen import FrozenEstimator
        >>> from sklearn_gpcd.detection import AlarmRule, CollisionDetector, stack_currents
        >>> from sklearn_gpcd.dynamics import MomentumObserver
        >>> q = np.tile([0.0, -1.57, 1.57, -1.57, -1.57, 0.0], (200, 1))
        >>> X = np.hstack([q, np.zeros((200, 12))])              # arm at rest
        >>> obs = MomentumObserver("ur10", identify="none", sample_time=0.01)
        >>> current = obs.fit(X, np.zeros((200, 6))).robot_.gravity(q[0]) / obs.torque_constants_
        >>> rng = np.random.default_rng(0)
        >>> free = stack_currents(X, current + 0.01 * rng.normal(size=(200, 6)))
        >>> det = CollisionDetector(FrozenEstimator(obs), n_joints=6, sample_time=0.01,
        ...                         rules=AlarmRule("per_joint", false_alarm_rate=0.0)).fit(free)
        >>> hit = free.copy()
        >>> hit[100:, -6 + 1] += 1.0                             # joint 2 resists a push
        >>> bool(det.predict(free).min() == 1), bool(det.predict(hit)[150] == -1)
        (True, True)
        """
        residual = self.residual(X, current, groups=groups, time=time, return_std=return_std)
        if return_std:
            residual, std = residual
            return np.asarray(current, dtype=float) - residual, std
        return np.asarray(current, dtype=float) - residual

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.target_tags.required = True
        return tags


def _model_with(model, link_parameters, rotor):
    """A copy of ``model`` with the links' 10 dynamic parameters and armature replaced.

    pinocchio's algorithms are linear in each link's spatial inertia, so an
    identified parameter set that is not physically consistent still gives
    the model's ``M``, ``C`` and ``g`` (only a zero mass is nudged, as the
    lever ``h / m`` is stored).
    """
    out = pin.Model(model)
    for joint, values in enumerate(link_parameters, start=1):
        values = np.array(values, dtype=float)
        if abs(values[0]) < 1e-9:
            values[0] = 1e-9
        out.inertias[joint] = pin.Inertia.FromDynamicParameters(values)
    out.armature = np.asarray(rotor, dtype=float).copy()
    return out
