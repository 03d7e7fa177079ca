r"""Kernel gradients contracted with a weight matrix, in O(n^2) memory.

The gradient of the log marginal likelihood of a GP (Rasmussen & Williams,
Eq. 5.9) is

.. math::
    \frac{\partial \log p(y \mid X, \theta)}{\partial \theta_k}
    = \frac{1}{2} \sum_{ij} W_{ij} \frac{\partial K_{ij}}{\partial \theta_k},
    \qquad W = \alpha \alpha^T - K^{-1}, \quad \alpha = K^{-1} y.

scikit-learn builds the (n, n, n_theta) array :math:`\partial K / \partial
\theta` first; for the 36-dimensional ARD kernels of the paper and n = 5000
samples that is 7 GB. :func:`contract_gradient` computes the contraction
with the compiled kernel (:mod:`sklearn_gpcd.kernels.plan`), node by node,
the code the regressor's fit runs.
"""

import numpy as np

from .columns import _n_samples, feature_names_of, resolve_columns
from .plan import compile_kernel

__all__ = ["contract_gradient"]


def contract_gradient(kernel, X, W):
    r"""Contract the kernel gradient with W, without the (n, n, n_theta) array.

    Computes

    .. math::
        g_k = \sum_{ij} W_{ij} \, \frac{\partial k(x_i, x_j)}{\partial \theta_k},

    i.e. ``np.einsum("ij,ijk->k", W, kernel(X, eval_gradient=True)[1])``,
    with the nodes of the compiled kernel
    (:func:`sklearn_gpcd.kernels.plan.compile_kernel`), the contraction the
    fit of :class:`~sklearn_gpcd.gp.SemiParametricGPRegressor` uses:
    per node, ``Sum`` concatenates, ``Product`` contracts each factor with
    :math:`W` times the other factor, ``ConstantKernel`` gives
    :math:`c \sum_{ij} W_{ij}`, ``WhiteKernel`` :math:`s\,\mathrm{tr}(W)`,
    a squared exponential (Eq. 11) one matrix product per row block,
    :class:`~sklearn_gpcd.kernels.QuasiStaticGate` (Eq. 16) its inner
    kernel on the gated rows and columns, and
    :class:`~sklearn_gpcd.kernels.ParametricKernel` its design matrix.
    Since :math:`\partial K / \partial \theta_k` is symmetric, only the
    symmetric part of ``W`` matters.

    Fixed hyperparameters contribute nothing, matching the layout of
    ``kernel.theta``. A kernel without a compiled node (or a subclass of a
    registered kernel) falls back to the einsum over its full gradient.
    Memory is O(n^2) for trees of registered kernels.

    Parameters
    ----------
    kernel : Kernel
        The kernel tree.
    X : array-like or DataFrame of shape (n_samples, n_features)
        Inputs at which k(X, X) is differentiated.
    W : array-like of shape (n_samples, n_samples)
        Weights, e.g. :math:`\alpha\alpha^T - K^{-1}`.

    Returns
    -------
    gradient : ndarray of shape (n_theta,)
        The contraction, ordered like ``kernel.theta``.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel, WhiteKernel
    >>> from sklearn_gpcd.kernels import ARDRBF, contract_gradient
    >>> rng = np.random.default_rng(0)
    >>> X, W = rng.normal(size=(50, 4)), rng.normal(size=(50, 50))
    >>> kernel = ConstantKernel(2.0) * ARDRBF([1.0, 2.0, 3.0, 4.0]) + WhiteKernel()
    >>> reference = np.einsum("ij,ijk->k", W, kernel(X, eval_gradient=True)[1])
    >>> bool(np.allclose(contract_gradient(kernel, X, W), reference, rtol=1e-10))
    True
    """
    names = feature_names_of(X)
    if names is not None:  # columns given by name become indices
        kernel = resolve_columns(kernel, feature_names=names)
    n_samples = _n_samples(X)
    X = np.atleast_2d(np.asarray(X, dtype=float))
    W = np.asarray(W, dtype=float)
    if W.shape != (n_samples, n_samples):
        raise ValueError(
            f"contract_gradient: W must have shape (n_samples, n_samples) = "
            f"{(n_samples, n_samples)}, got {W.shape}"
        )
    if kernel.n_dims == 0:
        return np.empty(0)
    W = 0.5 * (W + W.T)  # the node contractions assume a symmetric W
    plan = compile_kernel(kernel, lower=False)
    plan.gram(X, keep=True)
    return plan.contract(W, 1.0)
