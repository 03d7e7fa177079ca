"""Posterior of a zero-mean GP given its support set, with cached factors."""

import warnings

import numpy as np
from scipy.linalg import cho_solve, solve_triangular
from sklearn import get_config
from sklearn.utils import gen_batches

from ._likelihood import _cholesky


class _Posterior:
    r"""Zero-mean GP conditioned on ``(X, y)`` (R&W Algorithm 2.1).

    Caches :math:`L L^T = K(X, X) + \alpha I` and the weights
    :math:`w = L^{-T} L^{-1} (y - \mu_y) / s_y` so that, at a query :math:`x_*`,

    .. math::

        \mathbb E[f_*] = \mu_y + s_y\, k_*^T w, \qquad
        \mathbb V[f_*] = s_y^2 \big(k(x_*, x_*) - \|L^{-1} k_*\|^2\big).

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
        K = kernel(X)
        K[np.diag_indices_from(K)] += alpha
        self.L, self.jitter = _cholesky(K, what=f"kernel matrix of {kernel}")
        self.weights = cho_solve((self.L, True), self.y_train, check_finite=False)

    def predict(self, X, return_std=False, return_cov=False):
        """Posterior mean, and std or covariance, in original units.

        Rows are processed in chunks sized by scikit-learn's
        ``working_memory`` (except for ``return_cov``, whose output is
        ``(n, n)`` anyway).
        """
        if return_cov:
            K_trans = self.kernel(X, self.X)
            V = solve_triangular(self.L, K_trans.T, lower=True, check_finite=False)
            cov = self.kernel(X) - V.T @ V
            return self._mean(K_trans), cov * self.y_std**2
        mean = np.empty(X.shape[0])
        std = np.empty(X.shape[0]) if return_std else None
        chunk = _chunk_rows(row_bytes=16 * max(len(self.X), 1))
        for rows in gen_batches(X.shape[0], chunk):
            K_trans = self.kernel(X[rows], self.X)
            mean[rows] = self._mean(K_trans)
            if return_std:
                std[rows] = self._std(X[rows], K_trans)
        return (mean, std) if return_std else mean

    def _mean(self, K_trans):
        return self.y_std * (K_trans @ self.weights) + self.y_mean

    def _std(self, X, K_trans):
        V = solve_triangular(self.L, K_trans.T, lower=True, check_finite=False)
        var = self.kernel.diag(X) - np.einsum("ij,ij->j", V, V)
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
