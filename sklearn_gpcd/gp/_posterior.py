"""Posterior of a zero-mean GP given its support set, with cached factors."""

import warnings

import numpy as np
from scipy.linalg import cho_solve, solve_triangular
from sklearn import get_config
from sklearn.utils import gen_batches

from ..kernels.plan import compile_kernel, gram_matrix
from ._likelihood import _LOG_2PI, _cholesky, _upper_factor_inplace

#: Largest Cholesky factor (bytes) kept in memory after the fit: 2,048 support
#: rows (32 MiB). Larger factors are rebuilt on demand (:attr:`_Posterior.L`).
FACTOR_KEEP_BYTES = 32 * 2**20


class GPPosterior:
    r"""The fitted model of one output, in original units: a documented seam.

    The posterior mean at a query :math:`x_*` is

    .. math::

        \mathbb E[y_*] = m(x_*) + \mu_y + k(x_*, X_{train})\, \alpha,

    with :math:`m` the fitted parametric mean (or 0), :math:`k` the fitted
    kernel and :math:`\alpha` the GP weights already multiplied by the
    target scale. :attr:`SemiParametricGPRegressor.posteriors_
    <sklearn_gpcd.gp.SemiParametricGPRegressor.posteriors_>` holds one per
    output; the streaming monitor compiles its one-sample path from them and
    checks it against :meth:`predict_mean`, which uses the Kernel objects.

    Parameters
    ----------
    kernel : Kernel
        Fitted kernel (integer columns).
    X_train : ndarray of shape (n_support, n_features)
        Support inputs.
    alpha : ndarray of shape (n_support,)
        Weights of :math:`k(x_*, X_{train})` in target units.
    y_mean : float
        Target offset :math:`\mu_y` (0 unless ``normalize_y``).
    mean : estimator or None
        The fitted parametric mean (with ``predict``), or None.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import RBF
    >>> from sklearn_gpcd.gp import SemiParametricGPRegressor
    >>> X = np.linspace(0, 1, 20)[:, None]
    >>> gp = SemiParametricGPRegressor(RBF(0.3), optimizer=None).fit(X, np.sin(6 * X[:, 0]))
    >>> post = gp.posteriors_[0]
    >>> post.X_train.shape, post.alpha.shape
    ((20, 1), (20,))
    >>> bool(np.allclose(post.predict_mean(X[:3]), gp.predict(X[:3])))
    True
    """

    def __init__(self, kernel, X_train, alpha, y_mean=0.0, mean=None):
        self.kernel = kernel
        self.X_train = X_train
        self.alpha = alpha
        self.y_mean = y_mean
        self.mean = mean

    def predict_mean(self, X, X_mean=None):
        """``m(X_mean) + y_mean + kernel(X, X_train) @ alpha``, by the Kernel objects.

        Parameters
        ----------
        X : ndarray of shape (n_samples, n_features)
            Queries of the kernel.
        X_mean : array-like or DataFrame, default=None
            The same queries as the parametric mean expects them (e.g. a
            DataFrame); defaults to ``X``.

        Returns
        -------
        y_mean : ndarray of shape (n_samples,)
        """
        value = self.kernel(X, self.X_train) @ self.alpha + self.y_mean
        if self.mean is not None:
            value = value + np.ravel(self.mean.predict(X if X_mean is None else X_mean))
        return value


class _Posterior:
    r"""Zero-mean GP conditioned on ``(X, y)`` (R&W Algorithm 2.1).

    Caches :math:`L L^T = K(X, X) + \alpha I` and the weights
    :math:`w = L^{-T} L^{-1} (y - \mu_y) / s_y` so that, at a query :math:`x_*`,

    .. math::

        \mathbb E[f_*] = \mu_y + s_y\, k_*^T w, \qquad
        \mathbb V[f_*] = s_y^2 \big(k(x_*, x_*) - \|L^{-1} k_*\|^2\big).

    The kernel is compiled once (:mod:`sklearn_gpcd.kernels.plan`) with the support
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
        L, self.jitter = _cholesky(self._make_K, what=f"kernel matrix of {kernel}")
        self.weights = cho_solve((L, True), self.y_train, check_finite=False)
        self.log_det_half = float(np.log(np.diag(L)).sum())
        # the factor is kept while it is small; a large one (n_support rows
        # squared) is rebuilt on the first std/cov request, see ``L``
        self._L = L if L.nbytes <= FACTOR_KEEP_BYTES else None
        del L
        self.plan.prepare(X, y_std * self.weights)
        # the node that computes k_*^T w alone (e.g. the RBF of C * RBF + White)
        self._leaf = self.plan.row_leaf()

    def __getstate__(self):
        """What a model file stores: the support rows, targets, weights and kernel.

        The Cholesky factor (``n_support`` squared floats: 32 MB per joint at
        2,000 support rows, ~95 % of a model file) and the compiled kernel
        are left out: a mean prediction needs neither, and both are rebuilt
        exactly from what is kept -- the kernel compiled again by
        :meth:`__setstate__`, the factor on the first std or covariance
        request (:attr:`L`, with the jitter of the fit), by the very LAPACK
        call of the fit.
        """
        state = self.__dict__.copy()
        state["_L"] = None
        for derived in ("plan", "_leaf"):
            state.pop(derived, None)
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self.plan = compile_kernel(self.kernel)
        self.plan.prepare(self.X, self.y_std * self.weights)
        self._leaf = self.plan.row_leaf()

    def _make_K(self):
        K = gram_matrix(self.plan, self.X)
        K[np.diag_indices_from(K)] += self.alpha
        return K

    @property
    def L(self):
        """Lower Cholesky factor of ``K(X, X) + alpha I`` (+ the jitter used at fit).

        Kept from the fit when it has at most :data:`FACTOR_KEEP_BYTES`
        bytes; a larger one is rebuilt here once, on the first request for
        a predictive std or covariance, and cached. Means only need the
        weights, so a model trained on D1 with ``n_support=5000`` per joint
        does not hold six 200 MB factors it may never use.
        """
        if self._L is None:
            K = self._make_K()
            K[np.diag_indices_from(K)] += self.jitter
            U, info = _upper_factor_inplace(K)
            if info != 0:  # pragma: no cover - the same matrix factorised at fit
                raise ValueError(f"Cholesky factor of the kernel matrix of {self.kernel} failed.")
            self._L = U.T
        return self._L

    @property
    def log_marginal_likelihood(self):
        """Log marginal likelihood of the support targets (from the cached factor)."""
        return float(
            -0.5 * self.y_train @ self.weights
            - self.log_det_half
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
        return self.__dict__.get("_leaf", self.plan).cross_dot(X) + self.y_mean

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
