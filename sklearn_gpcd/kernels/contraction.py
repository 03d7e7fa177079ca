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
directly by recursion over the kernel tree.
"""

import numpy as np
from scipy.spatial.distance import pdist, squareform
from sklearn.gaussian_process.kernels import (
    RBF,
    ConstantKernel,
    Exponentiation,
    Product,
    Sum,
    WhiteKernel,
)

from .ard import ARDRBF
from .columns import _n_samples, _take_rows, check_length_scale
from .gate import QuasiStaticGate
from .parametric import ParametricKernel

__all__ = ["contract_gradient"]


def contract_gradient(kernel, X, W):
    r"""Contract the kernel gradient with W, without the (n, n, n_theta) array.

    Computes

    .. math::
        g_k = \sum_{ij} W_{ij} \, \frac{\partial k(x_i, x_j)}{\partial \theta_k},

    i.e. ``np.einsum("ij,ijk->k", W, kernel(X, eval_gradient=True)[1])``, by
    recursion over the kernel tree:

    * ``Sum`` :math:`k_1 + k_2`: concatenate the children's contractions;
    * ``Product`` :math:`k_1 k_2`: contract :math:`k_1` with :math:`W \circ K_2`
      and :math:`k_2` with :math:`W \circ K_1`;
    * ``Exponentiation`` :math:`k^p`: contract :math:`k` with
      :math:`W \circ p K^{p-1}`;
    * ``ConstantKernel`` :math:`c`: :math:`c \sum_{ij} W_{ij}`;
      ``WhiteKernel`` :math:`s`: :math:`s \, \mathrm{tr}(W)`;
    * ``RBF`` / :class:`ARDRBF` (Eq. 11): per dimension
      :math:`\sum_{ij} W_{ij} K_{ij} (x_{id} - x_{jd})^2 / l_d^2`, summed
      over the pairs :math:`i < j` of ``pdist`` (the direct sum, as accurate
      as the einsum);
    * :class:`QuasiStaticGate` (Eq. 16): contract the inner kernel with W
      restricted to the gated rows and columns;
    * :class:`ParametricKernel`:
      :math:`\sigma^2_j \sum_{i} (W \Phi)_{ij} \Phi_{ij}`.

    Fixed hyperparameters contribute nothing, matching the layout of
    ``kernel.theta``. Any other kernel (or a subclass of the above) falls
    back to the einsum over its full gradient. Memory is O(n^2) for trees of
    supported kernels.

    Parameters
    ----------
    kernel : Kernel
        The kernel tree.
    X : array-like of shape (n_samples, n_features)
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
    if not hasattr(X, "iloc"):
        X = np.atleast_2d(np.asarray(X, dtype=float))
    W = np.asarray(W, dtype=float)
    n_samples = _n_samples(X)
    if W.shape != (n_samples, n_samples):
        raise ValueError(
            f"contract_gradient: W must have shape (n_samples, n_samples) = "
            f"{(n_samples, n_samples)}, got {W.shape}"
        )
    return _contract(kernel, X, W)


def _contract(kernel, X, W):
    """Dispatch on the exact kernel type (subclasses may change __call__)."""
    if kernel.n_dims == 0:
        return np.empty(0)
    handler = _HANDLERS.get(type(kernel), _contract_dense)
    return handler(kernel, X, W)


def _contract_dense(kernel, X, W):
    """Fallback: the full (n, n, n_theta) gradient, then einsum."""
    _, K_gradient = kernel(X, eval_gradient=True)
    return np.einsum("ij,ijk->k", W, K_gradient)


def _contract_sum(kernel, X, W):
    return np.concatenate([_contract(kernel.k1, X, W), _contract(kernel.k2, X, W)])


def _contract_product(kernel, X, W):
    k1, k2 = kernel.k1, kernel.k2
    g1 = _contract(k1, X, W * k2(X)) if k1.n_dims else np.empty(0)
    g2 = _contract(k2, X, W * k1(X)) if k2.n_dims else np.empty(0)
    return np.concatenate([g1, g2])


def _contract_exponentiation(kernel, X, W):
    p = kernel.exponent
    return _contract(kernel.kernel, X, W * p * kernel.kernel(X) ** (p - 1))


def _contract_constant(kernel, X, W):
    return np.array([kernel.constant_value * W.sum()])


def _contract_white(kernel, X, W):
    return np.array([kernel.noise_level * np.trace(W)])


def _contract_rbf(kernel, X, W):
    X = np.atleast_2d(np.asarray(X, dtype=float))
    X_scaled = X / check_length_scale(kernel.length_scale, X.shape[1], "RBF")
    return _squared_exponential(X_scaled, W, kernel.anisotropic)


def _contract_ardrbf(kernel, X, W):
    return _squared_exponential(kernel.scaled(X), W, kernel.anisotropic)


def _squared_exponential(X_scaled, W, anisotropic):
    r"""Contraction of :math:`K \circ (x_d - x'_d)^2 / l_d^2` for scaled X.

    Works on condensed (upper-triangle) vectors: the diagonal has zero
    distance, and :math:`\sum_{ij} W_{ij} K_{ij} D_{ij} = \sum_{i<j}
    (W_{ij} + W_{ji}) K_{ij} D_{ij}` for the symmetric K and D. Each
    dimension costs one ``pdist`` and one dot product; peak memory is a few
    n(n-1)/2 vectors, never n^2 d.
    """
    sq_dists = pdist(X_scaled, metric="sqeuclidean")
    weights = squareform(W + W.T, checks=False)
    weights *= np.exp(-0.5 * sq_dists)  # (W_ij + W_ji) K_ij, i < j
    if not anisotropic:
        return np.array([weights @ sq_dists])
    del sq_dists
    return np.array(
        [weights @ pdist(column[:, np.newaxis], metric="sqeuclidean")
         for column in X_scaled.T]
    )


def _contract_gate(kernel, X, W):
    rows = np.flatnonzero(kernel.gate(X))
    if rows.size == 0:
        return np.zeros(kernel.n_dims)
    return _contract(kernel.kernel, _take_rows(X, rows), W[np.ix_(rows, rows)])


def _contract_parametric(kernel, X, W):
    Phi = kernel.design_matrix(X)
    prior_cov = kernel.weight_variances(Phi.shape[1])
    per_feature = prior_cov * np.einsum("ij,ij->j", W @ Phi, Phi)
    if kernel.anisotropic:
        return per_feature
    return np.array([per_feature.sum()])


_HANDLERS = {
    Sum: _contract_sum,
    Product: _contract_product,
    Exponentiation: _contract_exponentiation,
    ConstantKernel: _contract_constant,
    WhiteKernel: _contract_white,
    RBF: _contract_rbf,
    ARDRBF: _contract_ardrbf,
    QuasiStaticGate: _contract_gate,
    ParametricKernel: _contract_parametric,
}
