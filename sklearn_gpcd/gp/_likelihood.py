"""Log marginal likelihood of a zero-mean GP and a robust Cholesky factor.

Both follow Rasmussen & Williams (2006), Algorithm 2.1 and Eq. 5.9, the same
formulas as :class:`sklearn.gaussian_process.GaussianProcessRegressor`, so the
two give equal numbers on equal inputs. The kernel is evaluated through its
compiled tree (:mod:`sklearn_gpcd.kernels.plan`): no ``(n, n, n_theta)`` gradient array
is formed, and the Cholesky factorisation and inverse run in place.
"""

import threading
import warnings
from contextlib import contextmanager

import numpy as np
from scipy.linalg import cho_solve
from scipy.linalg.blas import dsyr
from scipy.linalg.lapack import dpotrf, dpotri
from threadpoolctl import ThreadpoolController

from ..kernels.plan import compile_kernel, gram_matrix, mirror_upper

# jitter tried, relative to the mean of diag(K), when K is not numerically PD
_JITTER_LADDER = 10.0 ** np.arange(-10, -1)
_LOG_2PI = np.log(2 * np.pi)
_BLAS_CONTROLLER = []  # one ThreadpoolController, created on first use
_BLAS_LOCK = threading.Lock()
_BLAS_STATE = {"depth": 0, "limiter": None}


@contextmanager
def single_threaded_blas():
    """Context manager limiting BLAS/LAPACK to one thread (threadpoolctl).

    Like scikit-learn's ``KMeans``: parallelism comes from fitting outputs
    side by side (``n_jobs``), so serial BLAS avoids oversubscribing the
    cores, and makes results independent of the thread count. The limit is
    process-wide, so nested and concurrent uses (outputs fitted in threads)
    share it: the first to enter sets it, the last to leave restores it.
    """
    with _BLAS_LOCK:
        if _BLAS_STATE["depth"] == 0:
            if not _BLAS_CONTROLLER:
                _BLAS_CONTROLLER.append(ThreadpoolController())
            _BLAS_STATE["limiter"] = _BLAS_CONTROLLER[0].limit(limits=1, user_api="blas")
        _BLAS_STATE["depth"] += 1
    try:
        yield
    finally:
        with _BLAS_LOCK:
            _BLAS_STATE["depth"] -= 1
            if _BLAS_STATE["depth"] == 0:
                _BLAS_STATE["limiter"].restore_original_limits()


def _log_marginal_likelihood(theta, kernel, X, y, alpha, eval_gradient=False, plan=None):
    r"""Log marginal likelihood of the residual GP at log-hyperparameters theta.

    .. math::

        \log p(y \mid X, \theta) = -\tfrac12 y^T K_y^{-1} y
            - \textstyle\sum_i \log L_{ii} - \tfrac n2 \log 2\pi ,
        \qquad K_y = K_\theta(X, X) + \alpha I = L L^T

    and (R&W Eq. 5.9), with :math:`a = K_y^{-1} y`,

    .. math::

        \partial_{\theta_k} \log p = \tfrac12 \operatorname{tr}\big(
            (a a^T - K_y^{-1}) \, \partial_{\theta_k} K \big),

    contracted node by node by the compiled kernel (per length scale, one
    matrix product), without the ``(n, n, n_theta)`` gradient array.

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
    plan : compiled kernel, default=None
        ``compile_kernel(kernel)``, to reuse across calls (its theta is set).

    Returns
    -------
    lml : float
        Log marginal likelihood, ``-inf`` when :math:`K_y` is not positive
        definite (so that optimizers step away from that theta).
    grad : ndarray of shape (n_theta,)
        Gradient of ``lml``; only when ``eval_gradient`` is True.
    """
    if plan is None:
        plan = compile_kernel(kernel)
    plan.set_theta(np.asarray(theta, dtype=float))
    K = gram_matrix(plan, X, keep=eval_gradient and plan.n_dims > 0)
    K[np.diag_indices_from(K)] += alpha
    U, info = _upper_factor_inplace(K)
    if info != 0:
        return (-np.inf, np.zeros(len(theta))) if eval_gradient else -np.inf
    a = cho_solve((U, False), y, check_finite=False)
    lml = -0.5 * y @ a - np.log(np.diag(U)).sum() - 0.5 * len(y) * _LOG_2PI
    if not eval_gradient:
        return lml
    if plan.n_dims == 0:
        return lml, np.empty(0)
    # W = a a^T - K^{-1} = -V; the contraction is linear in W
    # written over U, which is not needed any more; a lower plan reads the
    # lower triangle only (the factor's clean=1 left zeros above it)
    V = _negated_weight_matrix(U, a, mirror=not plan.lower)
    return lml, -0.5 * plan.contract(V, 1.0)


def _negated_weight_matrix(U, a, mirror=True):
    """:math:`V = K^{-1} - a a^T` from the upper factor ``U`` of ``K``, over ``U``.

    LAPACK ``potri`` gives the upper triangle of :math:`K^{-1}`; BLAS ``syr``
    subtracts :math:`a a^T` from it (upper triangle only, no ``(n, n)``
    temporary) and the triangle is mirrored, unless ``mirror`` is False:
    then the returned C-ordered array holds V in its lower triangle and
    whatever ``U`` held above it (zeros after :func:`_upper_factor_inplace`).
    """
    inv, info = dpotri(U, lower=0, overwrite_c=1)
    if info != 0:  # pragma: no cover - U comes from a successful potrf
        raise ValueError("Cholesky inverse failed.")
    V = dsyr(-1.0, a, a=inv, lower=0, overwrite_a=1)
    if mirror:
        mirror_upper(V)
    return V.T  # symmetric: the transpose of the Fortran-ordered result is C-ordered


def _upper_factor_inplace(K):
    """Cholesky factor of the symmetric ``K``, written over ``K``.

    ``K.T`` (the same matrix, Fortran-ordered) is factorised as
    :math:`U^T U` by LAPACK ``potrf`` without a copy.

    Returns
    -------
    U : ndarray of shape (n, n)
        Upper factor, Fortran-ordered, sharing memory with ``K``;
        ``U.T`` is the lower factor :math:`L`.
    info : int
        0 on success, > 0 when ``K`` is not positive definite.
    """
    U, info = dpotrf(K.T, lower=0, clean=1, overwrite_a=1)
    return U, info


def _cholesky(make_K, what="kernel matrix"):
    """Lower Cholesky factor of ``make_K()``, adding jitter to the diagonal if needed.

    When the matrix is not numerically positive definite, the jitter
    ``10**-10, 10**-9, ..., 10**-2`` times ``mean(diag(K))`` is tried in turn
    and a :class:`RuntimeWarning` reports the value used. The factor is
    computed in place, in the memory of a matrix built by ``make_K``.

    Parameters
    ----------
    make_K : callable
        Returns a new symmetric array of shape (n, n) (called again for
        every jitter tried).
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
        If the matrix has non-finite entries or stays indefinite with the
        largest jitter.
    """
    K = make_K()
    if not np.all(np.isfinite(K)):
        raise ValueError(f"The {what} contains NaN or infinite values.")
    scale = np.mean(np.abs(np.diag(K))) or 1.0
    U, info = _upper_factor_inplace(K)
    if info == 0:
        return U.T, 0.0
    for jitter in scale * _JITTER_LADDER:
        K = make_K()
        K[np.diag_indices_from(K)] += jitter
        U, info = _upper_factor_inplace(K)
        if info != 0:
            continue
        warnings.warn(
            f"The {what} is not positive definite; added jitter {jitter:.3g} to "
            "its diagonal. Consider increasing `alpha`.",
            RuntimeWarning,
        )
        return U.T, jitter
    raise ValueError(
        f"The {what} is not positive definite even with jitter "
        f"{scale * _JITTER_LADDER[-1]:.3g} on its diagonal; increase `alpha` or "
        "check the kernel."
    )
