"""Log marginal likelihood of a zero-mean GP and a robust Cholesky factor.

Both follow Rasmussen & Williams (2006), Algorithm 2.1 and Eq. 5.9, the same
formulas as :class:`sklearn.gaussian_process.GaussianProcessRegressor`, so the
two give equal numbers on equal inputs.
"""

import warnings

import numpy as np
from scipy.linalg import cho_solve, cholesky

from ..kernels import contract_gradient

# jitter tried, relative to the mean of diag(K), when K is not numerically PD
_JITTER_LADDER = 10.0 ** np.arange(-10, -1)


def _log_marginal_likelihood(theta, kernel, X, y, alpha, eval_gradient=False):
    r"""Log marginal likelihood of the residual GP at log-hyperparameters theta.

    .. math::

        \log p(y \mid X, \theta) = -\tfrac12 y^T K_y^{-1} y
            - \textstyle\sum_i \log L_{ii} - \tfrac n2 \log 2\pi ,
        \qquad K_y = K_\theta(X, X) + \alpha I = L L^T

    and (R&W Eq. 5.9), with :math:`a = K_y^{-1} y`,

    .. math::

        \partial_{\theta_k} \log p = \tfrac12 \operatorname{tr}\big(
            (a a^T - K_y^{-1}) \, \partial_{\theta_k} K \big),

    contracted by :func:`~sklearn_gpcd.kernels.contract_gradient` without
    forming the ``(n, n, n_theta)`` gradient array.

    Parameters
    ----------
    theta : ndarray of shape (n_theta,)
        Log-transformed kernel hyperparameters (``kernel.theta`` layout).
    kernel : Kernel
        Kernel whose hyperparameters are evaluated (not modified).
    X : ndarray of shape (n_samples, n_features)
        Training inputs.
    y : ndarray of shape (n_samples,)
        Training targets (already centred by the parametric mean and
        normalised when requested).
    alpha : float or ndarray of shape (n_samples,)
        Value added to the diagonal of the kernel matrix.
    eval_gradient : bool, default=False
        Also return the gradient with respect to theta.

    Returns
    -------
    lml : float
        Log marginal likelihood, ``-inf`` when :math:`K_y` is not positive
        definite (so that optimizers step away from that theta).
    grad : ndarray of shape (n_theta,)
        Gradient of ``lml``; only when ``eval_gradient`` is True.
    """
    kernel = kernel.clone_with_theta(theta)
    K = kernel(X)
    K[np.diag_indices_from(K)] += alpha
    try:
        L = cholesky(K, lower=True, check_finite=False)
    except np.linalg.LinAlgError:
        return (-np.inf, np.zeros_like(theta)) if eval_gradient else -np.inf
    a = cho_solve((L, True), y, check_finite=False)
    lml = -0.5 * y @ a - np.log(np.diag(L)).sum() - K.shape[0] / 2 * np.log(2 * np.pi)
    if not eval_gradient:
        return lml
    W = np.outer(a, a)
    W -= cho_solve((L, True), np.eye(K.shape[0]), check_finite=False)
    return lml, 0.5 * contract_gradient(kernel, X, W)


def _cholesky(K, what="kernel matrix"):
    """Lower Cholesky factor of ``K``, adding jitter to the diagonal if needed.

    When ``K`` is not numerically positive definite, the jitter
    ``10**-10, 10**-9, ..., 10**-2`` times ``mean(diag(K))`` is tried in turn
    and a :class:`RuntimeWarning` reports the value used.

    Parameters
    ----------
    K : ndarray of shape (n, n)
        Symmetric matrix; not modified.
    what : str, default="kernel matrix"
        Name of the matrix for messages.

    Returns
    -------
    L : ndarray of shape (n, n)
        Lower-triangular factor with ``L @ L.T == K + jitter * I``.
    jitter : float
        The jitter added (0.0 when none was needed).

    Raises
    ------
    ValueError
        If ``K`` has non-finite entries or stays indefinite with the largest
        jitter.
    """
    if not np.all(np.isfinite(K)):
        raise ValueError(f"The {what} contains NaN or infinite values.")
    try:
        return cholesky(K, lower=True, check_finite=False), 0.0
    except np.linalg.LinAlgError:
        pass
    scale = np.mean(np.abs(np.diag(K))) or 1.0
    for jitter in scale * _JITTER_LADDER:
        try:
            L = cholesky(K + jitter * np.eye(len(K)), lower=True, check_finite=False)
        except np.linalg.LinAlgError:
            continue
        warnings.warn(
            f"The {what} is not positive definite; added jitter {jitter:.3g} to "
            "its diagonal. Consider increasing `alpha`.",
            RuntimeWarning,
        )
        return L, jitter
    raise ValueError(
        f"The {what} is not positive definite even with jitter "
        f"{scale * _JITTER_LADDER[-1]:.3g} on its diagonal; increase `alpha` or "
        "check the kernel."
    )
