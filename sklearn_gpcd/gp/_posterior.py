"""Posterior of a zero-mean GP given its support set, with cached factors."""

import warnings

import numpy as np
from scipy.linalg import cho_solve, solve_triangular
from sklearn import get_config
from sklearn.utils import gen_batches

from ._kernel_plan import compile_kernel, gram_matrix
from ._likelihood import _LOG_2PI, _cholesky


class _Posterior:
    r"""Zero-mean GP conditioned on ``(X, y)`` (R&W Algorithm 2.1).

    Caches :math:`L L^T = K(X, X) + \alpha I` and the weights
    :math:`w = L^{-T} L^{-1} (y - \mu_y) / s_y` so that, at a query :math:`x_*`,

    .. math::

        \mathbb E[f_*] = \mu_y + s_y\, k_*^T w, \qquad
        \mathbb V[f_*] = s_y^2 \big(k(x_*, x_*) - \|L^{-1} k_*\|^2\big).

    The kernel is compiled once (:mod:`._kernel_plan`) with the support
    points of every squared-exponential block already scaled, so a mean
    prediction evaluates only :math:`k_*^T w`, block by block, and skips the
    gated block of Eq. 16 for queries whose gate is 0.

    Parameters
    ----------
    kernel : Kernel
        Fitted kernel.
    X : ndarray of shape (n_support, n_features)
        Support inputs (stored).
    y : ndarray of shape (n_support,)
        Support targets in original units.
    alpha : float or ndarray of shape (n_support,)
        Value added to the diagonal.
    y_mean, y_std : float
        Standardisation of ``y`` (:math:`\mu_y`, :math:`s_y`), see
        :func:`target_scaling`.
    """

    def __init__(self, kernel, X, y, alpha, y_mean=0.0, y_std=1.0):
        self.kernel = kernel
        self.X = X
        self.y_mean, self.y_std = y_mean, y_std
        self.y_train = (y - y_mean) / y_std
        self.alpha = alpha
        self.plan = compile_kernel(kernel)

        def make_K():
            K = gram_matrix(self.plan, X)
            K[np.diag_indices_from(K)] += alpha
            return K

        self.L, self.jitter = _cholesky(make_K, what=f"kernel matrix of {kernel}")
        self.weights = cho_solve((self.L, True), self.y_train, check_finite=False)
        self.plan.prepare(X, y_std * self.weights)

    @property
    def log_marginal_likelihood(self):
        """Log marginal likelihood of the support targets (from the cached factor)."""
        return float(
            -0.5 * self.y_train @ self.weights
            - np.log(np.diag(self.L)).sum()
            - 0.5 * len(self.y_train) * _LOG_2PI
        )

    def predict(self, X, return_std=False, return_cov=False):
        """Posterior mean, and std or covariance, in original units.

        Rows are processed in chunks sized by scikit-learn's
        ``working_memory`` (except for ``return_cov``, whose output is
        ``(n, n)`` anyway).
        """
        if return_cov:
            K_trans = self._cross(X)
            V = solve_triangular(self.L, K_trans.T, lower=True, check_finite=False)
            cov = gram_matrix(self.plan, X) - V.T @ V
            return self._mean(X), cov * self.y_std**2
        if X.shape[0] == 1 and not return_std:  # single sample: no chunking
            return self._mean(X)
        mean = np.empty(X.shape[0])
        std = np.empty(X.shape[0]) if return_std else None
        row_bytes = (24 if return_std else 8) * max(len(self.X), 1)
        for rows in gen_batches(X.shape[0], _chunk_rows(row_bytes)):
            mean[rows] = self._mean(X[rows])
            if return_std:
                std[rows] = self._std(X[rows], self._cross(X[rows]))
        return (mean, std) if return_std else mean

    def _cross(self, X):
        """``k(X, support)`` as a dense array."""
        K = self.plan.cross(X)
        if not isinstance(K, np.ndarray):  # e.g. a constant kernel
            K = np.full((X.shape[0], len(self.X)), float(K))
        return K

    def _mean(self, X):
        """``mu_y + s_y k(X, support) w``, block by block (gates skipped where 0)."""
        return self.plan.cross_dot(X) + self.y_mean

    def _std(self, X, K_trans):
        V = solve_triangular(self.L, K_trans.T, lower=True, check_finite=False)
        var = self.plan.diag(X) - np.einsum("ij,ij->j", V, V)
        if np.any(var < 0):
            warnings.warn(
                "Predicted variances smaller than 0. Setting those variances to 0.",
                RuntimeWarning,
            )
            var = np.maximum(var, 0.0)
        return np.sqrt(var) * self.y_std


def _chunk_rows(row_bytes):
    """Rows per chunk so that a chunk fits sklearn's ``working_memory`` (MiB)."""
    return max(1, int(get_config()["working_memory"] * 2**20 // row_bytes))


def target_scaling(y, normalize_y):
    """Mean and (non-zero) standard deviation used to standardise ``y``."""
    if not normalize_y:
        return 0.0, 1.0
    std = np.std(y)
    return np.mean(y), (std if std > 10 * np.finfo(float).eps else 1.0)
