"""The paper's three estimators P_f, SP_S and SP_P, built from a feature layout.

All three take the same input ``X`` in the column layout of
:mod:`sklearn_gpcd.layout` (joint-major blocks ``[q, qd, qdd, e_q, de_q,
i_c]``, Eq. 13) and predict the currents of all ``n_joints`` joints, one GP
per joint. P_f and SP_S only read the state columns ``[q, qd, qdd]``, so they
also accept the 3 n-column layout. Velocities must stay in their physical
units (rad/s) because ``sigma_v`` thresholds them: do not rescale the
``qd`` columns in front of SP_P.

Safe on any number of rows: the factories default to ``n_support="auto"``
(the GP is conditioned on at most ``AUTO_SUPPORT = 2000`` rows, see
:class:`SemiParametricGPRegressor`), so a fit never builds an exact GP on
tens of thousands of rows; pass ``n_support=None`` for the exact GP.
"""

import numpy as np
from sklearn.gaussian_process.kernels import ConstantKernel, WhiteKernel

from .._gate import DEFAULT_SIGMA_V
from ..dynamics import ControllerFeatures
from ..layout import column_index, state_columns
from ..kernels import ARDRBF, QuasiStaticGate
from .mean import ParametricMean
from .regressor import SemiParametricGPRegressor


def make_p_f(features, n_joints, *, sigma_v=None, friction_columns="auto", **gp_params):
    r"""P_f: the parametric estimator with friction (Eq. 8-10).

    Joint :math:`\ell`'s current is :math:`\phi_\ell(x) w_\ell` with the
    rigid-body features and the friction columns
    :math:`[\operatorname{sign}(\dot q_\ell)\ \dot q_\ell]` (Eq. 10), ``w``
    fitted by least squares (:class:`ParametricMean`). It is still a
    :class:`SemiParametricGPRegressor`, whose GP has only a ``WhiteKernel``:
    the white kernel has no cross-covariance between distinct samples, so the
    GP adds nothing to the predicted mean, while its fitted noise level (the
    residual variance) gives the predictive standard deviation.

    Parameters
    ----------
    features : list of n_joints callables or transformers, or None
        Per-joint regressors :math:`\phi_\ell`, e.g.
        ``[RigidBodyFeatures(robot, joint=l) for l in range(n_joints)]``.
        None gives a zero mean (pure noise model).
    n_joints : int
        Number of joints (outputs).
    sigma_v : float > 0 or None, default=None
        None uses :math:`\phi_\ell` as in the paper's P_f; a threshold zeroes
        the friction columns where :math:`|\dot q_\ell| < \sigma_v`
        (:math:`\bar\phi_\ell` of Eq. 17).
    friction_columns : "auto", array-like of int or None, default="auto"
        Friction columns of :math:`\phi_\ell`; "auto" reads
        ``friction_columns_`` of the fitted transformer.
    **gp_params
        Other :class:`SemiParametricGPRegressor` parameters. ``normalize_y``
        defaults to False here, so that the prediction is exactly
        :math:`\phi_\ell(x) w_\ell` (with True it would add the mean residual);
        ``n_support`` defaults to "auto".

    Returns
    -------
    estimator : SemiParametricGPRegressor

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.gp import make_p_f
    >>> def phi(X):  # one joint: [qdd, sign(qd), qd]
    ...     return np.column_stack([X[:, 2], np.sign(X[:, 1]), X[:, 1]])
    >>> rng = np.random.RandomState(0)
    >>> X = rng.normal(size=(50, 6))
    >>> y = phi(X) @ [2.0, 0.5, 0.1]
    >>> make_p_f([phi], 1, friction_columns=[1, 2]).fit(X, y).mean_.coef_.round(3)
    array([2. , 0.5, 0.1])
    """
    means = _means(features, n_joints, sigma_v, friction_columns)
    kernels = [WhiteKernel(1.0) for _ in range(n_joints)]
    gp_params.setdefault("normalize_y", False)  # predictions are exactly phi w
    return _estimator(kernels, means, gp_params)


def make_sp_s(features, n_joints, *, sigma_v=None, friction_columns="auto", **gp_params):
    r"""SP_S: the standard semi-parametric estimator (Sec. III-A, option (i)).

    .. math::

        y_\ell = \phi_\ell(x) w_\ell + f_\ell(x) + e, \qquad
        f_\ell \sim \mathcal{GP}(0, \lambda\, k_{RBK}(x, x')),

    with deterministic :math:`w_\ell` (the mean, Eq. 10) and the ARD RBF
    kernel of Eq. 11 on the state :math:`x = [q, \dot q, \ddot q]` only,
    plus a ``WhiteKernel`` for the noise :math:`e`.

    Parameters
    ----------
    features : list of n_joints callables or transformers, or None
        Per-joint regressors :math:`\phi_\ell`; None drops the parametric part.
    n_joints : int
        Number of joints (outputs).
    sigma_v : float > 0 or None, default=None
        None uses :math:`\phi_\ell` as in the paper's SP_S; a threshold masks
        the friction columns at rest as in :math:`\bar\phi_\ell` (Eq. 17).
    friction_columns : "auto", array-like of int or None, default="auto"
        Friction columns of :math:`\phi_\ell`.
    **gp_params
        Other :class:`SemiParametricGPRegressor` parameters
        (``normalize_y`` defaults to True, ``n_support`` to "auto": at most
        2,000 support rows).

    Returns
    -------
    estimator : SemiParametricGPRegressor

    Examples
    --------
    >>> from sklearn_gpcd.gp import make_sp_s
    >>> gp = make_sp_s(None, 2)
    >>> gp.kernel[0]
    1**2 * ARDRBF(length_scale=[1, 1, 1, 1, 1, 1], columns=[0, 1, 2, 3, 4, 5]) + WhiteKernel(noise_level=1)
    """
    means = _means(features, n_joints, sigma_v, friction_columns)
    kernels = [_kinetic(n_joints) + WhiteKernel(1.0) for _ in range(n_joints)]
    return _estimator(kernels, means, gp_params)


def make_sp_p(features, n_joints, *, sigma_v=DEFAULT_SIGMA_V, friction_columns="auto",
              **gp_params):
    r"""SP_P: the proposed estimator (Eq. 17).

    .. math::

        y_\ell = \bar\phi_\ell(x) w_\ell
            + a_\ell(x)\, f_{NP_\ell;stc}(x^a) + f_{NP_\ell;kin}(x) + e,
        \qquad a_\ell(x) = [\,|\dot q_\ell| < \sigma_v\,],

    with deterministic :math:`w_\ell` fitted on :math:`\bar\phi_\ell`
    (friction columns zeroed at rest), the static component an ARD RBF on the
    augmented inputs :math:`x^a` (Eq. 13) gated by
    :class:`~sklearn_gpcd.kernels.QuasiStaticGate` (Eq. 14-16), the kinetic
    component an ARD RBF on :math:`x = [q, \dot q, \ddot q]` (Eq. 11), and a
    ``WhiteKernel`` for :math:`e`. The kernel of joint :math:`\ell` is

    ``C * QuasiStaticGate(ARDRBF(x^a), qd_l, sigma_v) + C * ARDRBF(x) + White``.

    Parameters
    ----------
    features, friction_columns, **gp_params
        As for :func:`make_sp_s`.
    n_joints : int
        Number of joints (outputs); ``X`` needs the ``6 * n_joints`` columns
        of the augmented layout.
    sigma_v : float > 0, default=1e-2
        Quasi-static velocity threshold (rad/s) of the gates and of
        :math:`\bar\phi_\ell`; the paper uses :math:`10^{-2}`. Tune it for
        all joints at once with ``GridSearchCV`` over ``sigma_v`` of the
        returned estimator.

    Returns
    -------
    estimator : SemiParametricGPRegressor

    Examples
    --------
    >>> from sklearn_gpcd.gp import make_sp_p
    >>> gp = make_sp_p(None, 1)
    >>> for h in gp.kernel[0].hyperparameters:
    ...     print(h.name, h.n_elements)
    k1__k1__k1__constant_value 1
    k1__k1__k2__kernel__length_scale 6
    k1__k2__k1__constant_value 1
    k1__k2__k2__length_scale 3
    k2__noise_level 1
    >>> gp.kernel[0].k1.k1.k2.sigma_v
    0.01
    """
    means = _means(features, n_joints, sigma_v, friction_columns)
    kernels = [
        _static(n_joints, joint, sigma_v) + _kinetic(n_joints) + WhiteKernel(1.0)
        for joint in range(n_joints)
    ]
    return _estimator(kernels, means, gp_params)


def make_sp_c(n_joints, **gp_params):
    r"""SP_C: the controller's current model as the mean, a GP correction on top.

    .. math::

        y_\ell = w_\ell\, i_{c,\ell} + f_\ell(x) + e, \qquad
        f_\ell \sim \mathcal{GP}(0, \lambda\, k_{RBK}(x, x')),

    SP_S (Sec. III-A) with the feature map :math:`\phi_\ell = [i_{c,\ell}]`
    (:class:`~sklearn_gpcd.dynamics.ControllerFeatures`): the robot vendor's
    model of the current, logged as the target current (UR ``i_des``),
    replaces the rigid-body features, and the GP on :math:`x = [q, \dot q,
    \ddot q]` learns what it misses. Our extension of the paper, for logs
    that have :math:`i_c`; pair it with an alarm rule with
    ``Regimes(rest_reference=...)`` for the history-dependent current at rest.

    Parameters
    ----------
    n_joints : int
        Number of joints; ``X`` needs the augmented layout (``6 * n_joints``
        columns) with the target current in its last block.
    **gp_params
        Other :class:`SemiParametricGPRegressor` parameters
        (``normalize_y`` defaults to True).

    Returns
    -------
    estimator : SemiParametricGPRegressor

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.gp import make_sp_c
    >>> rng = np.random.default_rng(0)
    >>> X = rng.normal(size=(200, 6))                    # 1 joint, augmented
    >>> y = 1.1 * X[:, 5] + 0.3 * np.sin(X[:, 0])        # i = 1.1 i_c + f(q)
    >>> gp = make_sp_c(1).fit(X, y)
    >>> round(float(gp.mean_.coef_[0]), 1)
    1.1
    """
    features = [ControllerFeatures(joint, n_joints) for joint in range(n_joints)]
    return make_sp_s(features, n_joints, **gp_params)


def _kinetic(n_joints):
    """``C * ARDRBF`` on the state columns [q, qd, qdd] (Eq. 11)."""
    columns = state_columns(n_joints)
    return ConstantKernel(1.0) * ARDRBF(np.ones(len(columns)), columns=columns)


def _static(n_joints, joint, sigma_v):
    """``C * a_l(x) ARDRBF(x^a) a_l(x')`` on all augmented columns (Eq. 13-16)."""
    columns = list(range(6 * n_joints))
    gate = QuasiStaticGate(
        ARDRBF(np.ones(len(columns)), columns=columns),
        velocity_column=column_index("qd", joint, n_joints),
        sigma_v=sigma_v,
    )
    return ConstantKernel(1.0) * gate


def _means(features, n_joints, sigma_v, friction_columns):
    """One :class:`ParametricMean` per joint (None when ``features`` is None)."""
    if features is None:
        return None
    features = list(features)
    if len(features) != n_joints:
        raise ValueError(
            f"features has {len(features)} entries but n_joints={n_joints}; give "
            "one feature map per joint."
        )
    return [
        ParametricMean(
            phi,
            friction_columns=friction_columns,
            velocity_column=column_index("qd", joint, n_joints),
            sigma_v=sigma_v,
        )
        for joint, phi in enumerate(features)
    ]


def _estimator(kernels, means, gp_params):
    gp_params.setdefault("normalize_y", True)
    gp_params.setdefault("n_support", "auto")  # never an exact GP on all rows by default
    return SemiParametricGPRegressor(kernel=kernels, mean=means, **gp_params)
