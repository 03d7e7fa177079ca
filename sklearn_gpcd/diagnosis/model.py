"""The refined model: nominal current plus the fitted missing effects.

:func:`joint_fit` refits the selected effects together on all training data
(weighted least squares over joints, nonlinear settings refined) and returns
a :class:`DiagnosedModel`, which predicts currents from recordings or bare
states and serves as the parametric mean of the GP
(:class:`~sklearn_gpcd.gp.ParametricMean` through :meth:`DiagnosedModel.joint_features`).

Parameter uncertainty
---------------------
With weights :math:`w_\\ell = 1/\\hat\\sigma_\\ell^2` and :math:`A = \\sum_\\ell
w_\\ell D_\\ell^T D_\\ell`, the covariance is the sandwich

.. math::

    \\mathrm{cov}(\\theta) = A^{-1}\\Big(\\sum_\\ell \\kappa_\\ell\\, w_\\ell
        D_\\ell^T D_\\ell\\Big) A^{-1},
    \\qquad \\kappa_\\ell = 1 + 2\\sum_{k=1}^{L}\\Big(1-\\frac{k}{L+1}\\Big)\\rho_\\ell(k),

where :math:`\\rho_\\ell(k)` is the residual autocorrelation of joint
:math:`\\ell` at lag ``k`` (Bartlett weights, ``L = 25``): time-series
residuals are not independent, and :math:`\\kappa_\\ell` (at least 1) is the
variance inflation of a sum of slowly varying regressors times correlated
noise.
"""

import warnings
from dataclasses import dataclass

import numpy as np
from scipy import linalg

from .._persistence import VersionedStateMixin
from .nominal import Signals

#: Lags of the Bartlett autocorrelation correction of the covariance.
AUTOCORRELATION_LAGS = 25


@dataclass
class FittedEffect:
    """A selected effect with its fitted parameters.

    Attributes
    ----------
    effect : Effect
    target : int or None
    settings : dict
        Final nonlinear settings.
    joints : tuple of int
    theta : ndarray of shape (n_params,)
        Column coefficients.
    cov : ndarray of shape (n_params, n_params)
    parameters : dict
        Physical ``{name: (value, std)}``.
    explained_variance : float
        Share of the nominal residual (sum of squares over ``joints``, on the
        training rows) this effect removes given the others: the increase of
        the residual sum of squares when it is dropped and the others are
        refitted, over the nominal residual sum of squares.
    evidence : Step or None
        Selection evidence (:class:`~sklearn_gpcd.diagnosis.selection.Step`).
    explained_ss : float
        Numerator of ``explained_variance``: increase of the residual sum of
        squares over ``joints`` when the effect is dropped and the others are
        refitted [unit of the current squared].
    nominal_ss : float
        Denominator of ``explained_variance``: sum of squares of the nominal
        residual over ``joints`` on the training rows.
    joint_share : float
        Largest share, over ``joints``, of one joint's nominal residual sum
        of squares (less what the other payload, link-mass and tilt effects
        explain there) this effect removes given the others.
        Practical significance is judged on it: an effect acting on every
        joint (a delay) is not hidden by a large effect on some of them, nor
        a joint's friction by a payload.

    Examples
    --------
    Usually made by :func:`joint_fit`; by hand, 3.6 Nm more Coulomb friction
    on joint 1:

    >>> import numpy as np
    >>> from sklearn_gpcd.diagnosis import (FittedEffect, NominalModel, Signals,
    ...                                     effect_library)
    >>> fitted = FittedEffect(effect_library("coulomb_friction")[0], target=1, settings={},
    ...                       joints=(1,), theta=np.array([3.6]), cov=np.array([[1e-4]]),
    ...                       parameters={"delta_coulomb": (3.6, 0.01)},
    ...                       explained_variance=0.9, explained_ss=9.0, nominal_ss=10.0)
    >>> fitted.name, fitted.explained_ss / fitted.nominal_ss
    ('coulomb_friction', 0.9)
    >>> nominal = NominalModel("ur10")
    >>> X = np.hstack([np.zeros((2, 6)), np.full((2, 6), -0.5), np.zeros((2, 6))])
    >>> (fitted.columns(Signals.from_states(nominal, X), nominal)[1] @ fitted.theta).shape
    (2,)
    """

    effect: object
    target: object
    settings: dict
    joints: tuple
    theta: np.ndarray
    cov: np.ndarray
    parameters: dict
    explained_variance: float = np.nan
    evidence: object = None
    explained_ss: float = 0.0
    nominal_ss: float = 0.0
    joint_share: float = np.nan

    @property
    def name(self):
        """Effect name."""
        return self.effect.name

    def columns(self, signals, nominal):
        """The effect's columns on ``signals``: ``{joint: (n, n_params)}``."""
        return self.effect.design(signals, nominal, self.target, **self.settings)


class DiagnosedModel(VersionedStateMixin):
    """Nominal current model refined by the effects a diagnosis found.

    .. math:: i_\\ell(x) = \\hat i_\\ell(x) + \\sum_e D_{e,\\ell}(x)\\,\\theta_e

    Parameters
    ----------
    nominal : NominalModel
    effects : list of FittedEffect

    Attributes
    ----------
    n_joints : int

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.diagnosis import DiagnosedModel, NominalModel
    >>> model = DiagnosedModel(NominalModel("ur10"), [])
    >>> model.predict_states(np.zeros((2, 18))).shape
    (2, 6)
    >>> model.joint_features(1)(np.zeros((2, 18))).shape  # [nominal current]
    (2, 1)
    """

    def __init__(self, nominal, effects):
        self.nominal = nominal
        self.effects = list(effects)

    @property
    def n_joints(self):
        """Number of joints."""
        return self.nominal.n_joints

    def contributions(self, signals):
        """Sum of the effects' terms on ``signals``, shape (n_samples, n_joints).

        Time-dependent effects are skipped (with a warning) when ``signals``
        has no time stamps.
        """
        out = np.zeros((signals.n_samples, signals.n_joints))
        for fitted in self._usable(signals):
            out += fitted.effect.prediction(signals, self.nominal, fitted.target, fitted.theta,
                                            fitted.settings)
        return out

    def _usable(self, signals):
        usable = [f for f in self.effects if not (f.effect.needs_time and signals.time is None)]
        skipped = [f.name for f in self.effects if f not in usable]
        if skipped:
            warnings.warn(f"effects {skipped} depend on time and are left out of a prediction "
                          "from bare states", UserWarning, stacklevel=3)
        return usable

    def predict_signals(self, signals):
        """Refined current on prepared :class:`Signals`."""
        return signals.reference + self.contributions(signals)

    def predict(self, recordings, references=None):
        """Refined currents of recordings.

        Parameters
        ----------
        recordings : Recording or list of Recording
        references : list of ndarray, default=None
            Reference currents replacing the nominal prediction (paired
            simulated runs, see :func:`align_recordings`).

        Returns
        -------
        current : ndarray of shape (n_samples, n_joints) or list of them
            One array per recording (an array for a single recording).
        """
        single = not isinstance(recordings, (list, tuple))
        recs = [recordings] if single else list(recordings)
        signals = Signals.from_recordings(self.nominal, recs, references)
        pred = self.predict_signals(signals)
        out = [pred[signals.segment == k] for k in range(len(recs))]
        return out[0] if single else out

    def predict_states(self, X):
        """Refined current from states ``X = [q, qd, qdd, ...]`` (:mod:`sklearn_gpcd.layout`).

        Parameters
        ----------
        X : array-like of shape (n_samples, >= 3 n_joints)

        Returns
        -------
        current : ndarray of shape (n_samples, n_joints)
        """
        return self.predict_signals(Signals.from_states(self.nominal, X))

    def features(self, X, joint):
        """Columns ``[nominal current, effect columns...]`` of one joint.

        ``features(X, l) @ np.r_[1, theta...]`` is the refined current of
        joint ``l`` (see :meth:`feature_coefficients`).

        Parameters
        ----------
        X : array-like of shape (n_samples, >= 3 n_joints)
        joint : int

        Returns
        -------
        Phi : ndarray of shape (n_samples, 1 + n_effect_columns)
        """
        signals = Signals.from_states(self.nominal, X)
        blocks = [signals.reference[:, [joint]]]
        for fitted in self._usable(signals):
            cols = fitted.columns(signals, self.nominal)
            if joint in cols:
                blocks.append(cols[joint])
        return np.hstack(blocks)

    def feature_coefficients(self, joint):
        """Coefficients matching :meth:`features` (1 for the nominal current)."""
        coef = [np.ones(1)]
        for fitted in self.effects:
            if fitted.effect.needs_time:
                continue
            if joint in fitted.joints:
                coef.append(fitted.theta)
        return np.concatenate(coef)

    def joint_features(self, joint):
        """Picklable ``X -> features(X, joint)`` for :class:`~sklearn_gpcd.gp.ParametricMean`.

        Parameters
        ----------
        joint : int

        Returns
        -------
        features : JointFeatures
        """
        if not 0 <= int(joint) < self.n_joints:
            raise ValueError(f"joint={joint} out of range for {self.n_joints} joints (0-based)")
        return JointFeatures(self, int(joint))

    def parametric_mean(self, joint, **params):
        """A :class:`~sklearn_gpcd.gp.ParametricMean` on :meth:`joint_features`.

        Its least-squares fit re-estimates the effect coefficients (and the
        nominal current's gain) on the GP's training data.

        Parameters
        ----------
        joint : int
        **params
            Other :class:`~sklearn_gpcd.gp.ParametricMean` parameters.

        Returns
        -------
        mean : ParametricMean
        """
        from ..gp import ParametricMean

        return ParametricMean(features=self.joint_features(joint), **params)

    def __repr__(self):
        names = [f.name for f in self.effects]
        return f"DiagnosedModel(robot={self.nominal.robot.name!r}, effects={names})"


class JointFeatures:
    """Callable ``X -> model.features(X, joint)`` (see :meth:`DiagnosedModel.joint_features`).

    Parameters
    ----------
    model : DiagnosedModel
    joint : int

    Examples
    --------
    Without effects, the only column is the nominal current of the joint:

    >>> import numpy as np
    >>> from sklearn_gpcd.diagnosis import DiagnosedModel, JointFeatures, NominalModel
    >>> model = DiagnosedModel(NominalModel("ur10"), [])
    >>> features = model.joint_features(2)
    >>> isinstance(features, JointFeatures), features.joint
    (True, 2)
    >>> X = np.random.default_rng(0).normal(size=(4, 18))
    >>> bool(np.allclose(features(X)[:, 0], model.predict_states(X)[:, 2]))
    True
    """

    def __init__(self, model, joint):
        self.model = model
        self.joint = joint

    def __call__(self, X):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            return self.model.features(np.asarray(X, dtype=float), self.joint)


def _bartlett_factor(residual, lags=AUTOCORRELATION_LAGS):
    """Variance inflation :math:`\\kappa` of a residual series (module docstring)."""
    r = residual - residual.mean()
    denom = r @ r
    if r.size <= lags + 1 or denom <= 0:
        return 1.0
    rho = np.array([(r[:-k] @ r[k:]) / denom for k in range(1, lags + 1)])
    weights = 1.0 - np.arange(1, lags + 1) / (lags + 1.0)
    return float(max(1.0, 1.0 + 2.0 * weights @ rho))


class _Design:
    """Masked per-joint design of the selected effects, for the joint fit.

    Joint ``l`` keeps its rows ``mask[:, l]``: ``X[l]`` of shape
    ``(n_l, P)`` and residual ``r[l]``; item ``k`` owns columns
    ``slices[k]``.
    """

    def __init__(self, signals, nominal, items, mask, residual):
        self.signals, self.nominal = signals, nominal
        J = signals.n_joints
        self.rows = [np.flatnonzero(mask[:, j]) for j in range(J)]
        self.r = [residual[rows, j] for j, rows in enumerate(self.rows)]
        blocks, self.slices, start = [], [], 0
        for effect, target, settings in items:
            cols = effect.design(signals, nominal, target, **settings)
            k = next(iter(cols.values())).shape[1]
            blocks.append(cols)
            self.slices.append(slice(start, start + k))
            start += k
        self.n_params = start
        self.X = [np.zeros((rows.size, start)) for rows in self.rows]
        for k, cols in enumerate(blocks):
            self.set_item(k, cols)
        self.joints = [tuple(j for j in range(J) if j in cols and np.any(cols[j]))
                       for cols in blocks]

    def set_item(self, k, cols):
        """Replace the columns of item ``k`` by ``cols`` (``{joint: (n, n_k)}``)."""
        sl = self.slices[k]
        for j, rows in enumerate(self.rows):
            self.X[j][:, sl] = cols[j][rows] if j in cols else 0.0

    def grams(self):
        """Per joint ``X^T X``, ``X^T r``, ``r^T r``."""
        G = np.stack([X.T @ X for X in self.X])
        h = np.stack([X.T @ r for X, r in zip(self.X, self.r)])
        rr = np.array([r @ r for r in self.r])
        return G, h, rr

    def trial_grams(self, k, cols, G, h):
        """Grams with item ``k``'s columns replaced by ``cols`` (others unchanged)."""
        sl = self.slices[k]
        G, h = G.copy(), h.copy()
        for j, rows in enumerate(self.rows):
            new = cols[j][rows] if j in cols else np.zeros((rows.size, sl.stop - sl.start))
            if not (j in cols or np.any(self.X[j][:, sl])):
                continue
            saved = self.X[j][:, sl].copy()
            self.X[j][:, sl] = new
            row = new.T @ self.X[j]
            self.X[j][:, sl] = saved
            G[j][sl, :] = row
            G[j][:, sl] = row.T
            h[j][sl] = new.T @ self.r[j]
        return G, h


def _solve(G, h, weights, columns=None):
    """Weighted normal equations over joints, optionally on a column subset."""
    A = np.einsum("j,jab->ab", weights, G)
    b = weights @ h
    if columns is not None:
        A, b = A[np.ix_(columns, columns)], b[columns]
    P = A.shape[0]
    if P == 0:
        return np.zeros(0), A
    theta = np.linalg.lstsq(A + 1e-12 * np.trace(A) / P * np.eye(P), b, rcond=None)[0]
    return theta, A


def _sse(G, h, rr, theta, columns=None):
    """Per-joint residual sum of squares of ``theta`` from the Grams."""
    if columns is not None:
        G, h = G[:, columns][:, :, columns], h[:, columns]
    return np.maximum(rr - 2.0 * h @ theta + np.einsum("a,jab,b->j", theta, G, theta), 0.0)


def _weights_from(sse, design):
    counts = np.array([max(rows.size, 1) for rows in design.rows])
    mse = sse / counts
    return 1.0 / np.maximum(mse, 1e-12 * max(mse.max(), 1e-300))


def joint_fit(signals, nominal, selected, mask, n_iter=3):
    """Refit the selected effects jointly and refine their nonlinear settings.

    Each iteration solves the weighted normal equations (weights
    :math:`1/\\hat\\sigma_\\ell^2` from the previous residuals), then
    updates the nonlinear settings: the payload's centre of mass in its
    ``m c c^T`` inertia term and the time delay's exact shift (fixed points)
    and the Stribeck velocity (bounded 1-D search).

    Parameters
    ----------
    signals : Signals
        Training data.
    nominal : NominalModel
    selected : list of Step or Candidate
        Effects to fit (with their selection evidence when Steps).
    mask : ndarray of bool, shape (n_samples, n_joints)
        Rows used per joint.
    n_iter : int, default=3
        Reweighting / refinement iterations.

    Returns
    -------
    model : DiagnosedModel

    Examples
    --------
    Fit 0.3 A of missing Coulomb friction on joint 1 (a
    :class:`~sklearn_gpcd.diagnosis.Candidate` without selection evidence):

    >>> import numpy as np
    >>> from sklearn_gpcd.diagnosis import Candidate, NominalModel, Signals, effect_library
    >>> from sklearn_gpcd.diagnosis import joint_fit
    >>> rng = np.random.default_rng(0)
    >>> nominal = NominalModel("ur10")
    >>> s = Signals.from_states(nominal, np.hstack([rng.uniform(-1, 1, (300, 12)),
    ...                                            np.zeros((300, 6))]))
    >>> s.current = s.reference + 0.01 * rng.normal(size=(300, 6))
    >>> s.current[:, 1] += 0.3 * np.sign(s.qd[:, 1])
    >>> coulomb = Candidate(effect_library("coulomb_friction")[0], 1, {}, (1,),
    ...                     np.array([0]), 0)
    >>> model = joint_fit(s, nominal, [coulomb], np.ones((300, 6), dtype=bool))
    >>> fitted = model.effects[0]
    >>> fitted.name, fitted.joints  # theta in Nm: columns are torques over K_1
    ('coulomb_friction', (1,))
    >>> round(float(fitted.theta[0] / s.torque_constants[1]), 2)  # back in A
    0.3
    >>> fitted.explained_variance > 0.99
    True
    """
    steps = [s if hasattr(s, "candidate") else None for s in selected]
    cands = [s.candidate if hasattr(s, "candidate") else s for s in selected]
    items = [[c.effect, c.target, dict(c.settings)] for c in cands]
    residual = signals.current - signals.reference
    design = _Design(signals, nominal, items, mask, residual)
    G, h, rr = design.grams()
    weights = _weights_from(rr, design)
    for _ in range(n_iter):
        theta, _ = _solve(G, h, weights)
        for k, (effect, target, settings) in enumerate(items):
            new = _refine(effect, settings, theta[design.slices[k]], design, k, G, h, rr,
                          weights)
            if new is not settings:
                items[k][2] = new
                design.set_item(k, effect.design(signals, nominal, target, **new))
                G, h, rr = design.grams()
        theta, _ = _solve(G, h, weights)
        weights = _weights_from(_sse(G, h, rr, theta), design)
    theta, A = _solve(G, h, weights)
    cov = _covariance(design, theta, weights, A, signals.segment)
    sse = _sse(G, h, rr, theta)

    fitted = []
    for k, (effect, target, settings) in enumerate(items):
        sl, joints = design.slices[k], design.joints[k]
        params = effect.physical(theta[sl], cov[sl, sl], target, settings, nominal)
        keep = np.setdiff1d(np.arange(design.n_params), np.arange(sl.start, sl.stop))
        theta_without, _ = _solve(G, h, weights, keep)
        sse_without = _sse(G, h, rr, theta_without, keep)
        explained_ss = float(sse_without[list(joints)].sum() - sse[list(joints)].sum())
        nominal_ss = float(rr[list(joints)].sum())
        fitted.append(FittedEffect(
            effect=effect, target=target, settings=settings, joints=joints,
            theta=theta[sl].copy(), cov=cov[sl, sl].copy(), parameters=params,
            explained_variance=explained_ss / nominal_ss if nominal_ss > 0 else np.nan,
            evidence=steps[k], explained_ss=explained_ss, nominal_ss=nominal_ss,
            joint_share=_joint_share(G, h, rr, weights, design, items, k, sse_without - sse)))
    return DiagnosedModel(nominal, fitted)


def _joint_share(G, h, rr, weights, design, items, k, explained):
    """Largest share over item ``k``'s joints of the yardstick its ``explained`` SS makes.

    The yardstick is the nominal residual less what the *other* effects with
    parameters shared by every joint and fixed by the configuration
    (payload, link mass, tilt; not a time delay) explain (see
    ``selection._yardstick``).
    """
    joints = list(design.joints[k])
    shared = [np.arange(design.slices[i].start, design.slices[i].stop)
              for i, (effect, _, _) in enumerate(items)
              if i != k and not effect.per_joint and not effect.needs_time]
    yardstick = rr
    if shared:
        keep = np.concatenate(shared)
        theta, _ = _solve(G, h, weights, keep)
        yardstick = np.minimum(_sse(G, h, rr, theta, keep), rr)
    if not np.all(yardstick[joints] > 0):
        return np.nan
    return float(np.max(explained[joints] / yardstick[joints]))


def _refine(effect, settings, theta, design, k, G, h, rr, weights):
    """New nonlinear settings of item ``k`` (``settings`` itself when unchanged)."""
    read = effect.settings_from_fit(settings, theta)
    if read is not None:  # settings the linear fit gives (a payload's centre of mass)
        return read
    if effect.settings_grid() == [{}]:
        return settings
    target = design.joints[k][0] if effect.per_joint else None

    def objective(trial):
        cols = effect.design(design.signals, design.nominal, target, **trial)
        Gt, ht = design.trial_grams(k, cols, G, h)
        th, _ = _solve(Gt, ht, weights)
        return float(weights @ _sse(Gt, ht, rr, th))

    return effect.refine(objective, settings)


def _covariance(design, theta, weights, A, segment):
    """Sandwich covariance with the Bartlett autocorrelation factor (module docstring)."""
    P = design.n_params
    if P == 0:
        return np.zeros((0, 0))
    meat = np.zeros((P, P))
    for j, (X, r, rows) in enumerate(zip(design.X, design.r, design.rows)):
        if not rows.size:
            continue
        res = r - X @ theta
        seg = segment[rows]
        kappa = max(_bartlett_factor(res[seg == s]) for s in np.unique(seg))
        meat += kappa * weights[j] ** 2 * np.mean(res ** 2) * X.T @ X
    A_inv = linalg.pinvh(A)
    return A_inv @ meat @ A_inv
