"""Linear-in-the-parameters kernel of a parametric (model-based) prior."""

import numbers

import numpy as np
from scipy import sparse
from sklearn.base import clone
from sklearn.exceptions import NotFittedError
from sklearn.gaussian_process.kernels import Kernel
from sklearn.utils.validation import check_is_fitted

from .columns import _n_samples, is_anisotropic, scale_hyperparameter

__all__ = ["ParametricKernel"]


class ParametricKernel(Kernel):
    r"""Kernel of a linear model with Gaussian weights, :math:`\phi \Sigma \phi^T`.

    If :math:`f(x) = \phi(x) w` with :math:`w \sim N(m_w, \Sigma)`, the
    covariance of :math:`f` is the kernel of the parametric prior (paper,
    Sec. III-A "Parametric priors" and option (ii) of "Semi-Parametric
    priors"; :math:`\phi` is e.g. the rigid-body features with the friction
    columns of Eq. 8-10):

    .. math::
        k(x, x') = \phi(x) \, \Sigma \, \phi(x')^T, \qquad
        \Sigma = \mathrm{diag}(\sigma^2_1, \ldots, \sigma^2_p),

    where :math:`\sigma^2` is ``prior_cov`` (a scalar gives
    :math:`\Sigma = \sigma^2 I`). Adding it to a non-parametric kernel gives
    the semi-parametric prior. The gradient with respect to
    :math:`\theta_j = \log \sigma^2_j` is
    :math:`\sigma^2_j \, \phi_j(x) \phi_j(x')`.

    Parameters
    ----------
    features : callable or scikit-learn transformer
        The feature map :math:`\phi`: a callable ``X -> Phi`` with ``Phi`` of
        shape (n_samples, n_params), or a transformer whose ``transform`` is
        used. A transformer that is not fitted yet is fitted, as a clone, on
        the left argument X of each call (fine for stateless transformers such
        as ``PolynomialFeatures``). Note that ``sklearn.base.clone`` (used by
        GP regressors and ``clone_with_theta``) resets fitted transformers:
        to keep a data-dependent fit, pass its bound method, e.g.
        ``scaler.transform``, which is copied with its state. Use
        module-level functions rather than lambdas so the kernel pickles.
    prior_cov : float or array-like of shape (n_params,), default=1.0
        Prior variances :math:`\sigma^2_j` of the weights; a scalar is shared
        by all weights.
    prior_cov_bounds : pair of floats >= 0 or "fixed", default=(1e-5, 1e5)
        Bounds on ``prior_cov``; "fixed" excludes it from ``theta``.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.preprocessing import PolynomialFeatures
    >>> from sklearn_gpcd.kernels import ParametricKernel
    >>> X = np.array([[0.0], [1.0], [2.0]])
    >>> kernel = ParametricKernel(PolynomialFeatures(1), prior_cov=[4.0, 1.0])
    >>> kernel(X)  # 4 * 1 * 1 + 1 * x * x'
    array([[4., 4., 4.],
           [4., 5., 6.],
           [4., 6., 8.]])
    >>> [h.name for h in kernel.hyperparameters], kernel.theta.round(3)
    (['prior_cov'], array([1.386, 0.   ]))
    >>> kernel.diag(X)
    array([4., 5., 8.])
    """

    def __init__(self, features, prior_cov=1.0, prior_cov_bounds=(1e-5, 1e5)):
        self.features = features
        self.prior_cov = prior_cov
        self.prior_cov_bounds = prior_cov_bounds

    @property
    def anisotropic(self):
        """bool: True when each weight has its own prior variance."""
        return is_anisotropic(self.prior_cov)

    @property
    def hyperparameter_prior_cov(self):
        """Hyperparameter: specification of ``prior_cov``."""
        return scale_hyperparameter("prior_cov", self.prior_cov, self.prior_cov_bounds)

    def feature_map(self, X):
        r"""The callable :math:`\phi` used for a call on ``X``.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            Data an unfitted transformer is fitted on (as a clone).

        Returns
        -------
        phi : callable
            ``features`` itself, or the ``transform`` of a fitted transformer.

        Raises
        ------
        TypeError
            If ``features`` is neither callable nor a transformer.
        """
        features = self.features
        if hasattr(features, "transform"):
            if hasattr(features, "fit") and not _is_fitted(features):
                features = clone(features).fit(X)
            return features.transform
        if callable(features):
            return features
        raise TypeError(
            "ParametricKernel: features must be a callable X -> Phi or a "
            f"scikit-learn transformer, got {type(features).__name__}"
        )

    def design_matrix(self, X, phi=None):
        r"""The feature matrix :math:`\Phi(X)`, validated.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            Inputs.
        phi : callable, default=None
            Feature map; default ``self.feature_map(X)``.

        Returns
        -------
        Phi : ndarray of shape (n_samples, n_params)

        Raises
        ------
        ValueError
            If the features are not 2-D with one row per sample, or not finite.

        Examples
        --------
        >>> import numpy as np
        >>> ParametricKernel(np.sign).design_matrix([[-2.0, 3.0]])
        array([[-1.,  1.]])
        """
        if phi is None:
            phi = self.feature_map(X)
        Phi = phi(X)
        if sparse.issparse(Phi):
            Phi = Phi.toarray()
        Phi = np.asarray(Phi, dtype=float)
        n_samples = _n_samples(X)
        if Phi.ndim != 2 or Phi.shape[0] != n_samples:
            raise ValueError(
                f"ParametricKernel: features returned an array of shape "
                f"{Phi.shape} for {n_samples} samples; expected "
                "(n_samples, n_params)"
            )
        bad = ~np.isfinite(Phi)
        if bad.any():
            row, col = np.argwhere(bad)[0]
            raise ValueError(
                f"ParametricKernel: features returned a non-finite value "
                f"{Phi[row, col]} at row {row}, column {col}"
            )
        return Phi

    def weight_variances(self, n_params):
        r"""The diagonal of :math:`\Sigma`, checked against ``n_params``.

        Parameters
        ----------
        n_params : int
            Number of feature columns.

        Returns
        -------
        prior_cov : ndarray of shape (n_params,)

        Examples
        --------
        >>> ParametricKernel(abs, prior_cov=2.0).weight_variances(3)
        array([2., 2., 2.])
        """
        prior_cov = np.squeeze(np.asarray(self.prior_cov, dtype=float))
        if prior_cov.ndim > 1 or (prior_cov.ndim == 1 and prior_cov.size != n_params):
            raise ValueError(
                f"ParametricKernel: prior_cov has shape {np.shape(self.prior_cov)} "
                f"but features returned {n_params} columns; give a scalar or "
                "one variance per feature"
            )
        return np.broadcast_to(prior_cov, (n_params,)).copy()

    def __call__(self, X, Y=None, eval_gradient=False):
        """Return the kernel k(X, Y) and optionally its gradient.

        Parameters
        ----------
        X, Y, eval_gradient
            As for :meth:`ARDRBF.__call__ <sklearn_gpcd.kernels.ARDRBF.__call__>`.

        Returns
        -------
        K, K_gradient
            As for :meth:`ARDRBF.__call__ <sklearn_gpcd.kernels.ARDRBF.__call__>`.
        """
        phi = self.feature_map(X)
        Phi = self.design_matrix(X, phi)
        root = np.sqrt(self.weight_variances(Phi.shape[1]))
        A = Phi * root  # Phi Sigma^(1/2)
        if Y is not None:
            if eval_gradient:
                raise ValueError("Gradient can only be evaluated when Y is None.")
            B = self.design_matrix(Y, phi) * root
            return A @ B.T
        K = A @ A.T
        if not eval_gradient:
            return K
        if self.hyperparameter_prior_cov.fixed:
            return K, np.empty((K.shape[0], K.shape[0], 0))
        if not self.anisotropic:
            return K, K[:, :, np.newaxis].copy()
        return K, A[:, np.newaxis, :] * A[np.newaxis, :, :]

    def diag(self, X):
        r"""Return the diagonal of the kernel, :math:`\sum_j \sigma^2_j \phi_j(x)^2`.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            Argument to the kernel.

        Returns
        -------
        K_diag : ndarray of shape (n_samples,)
        """
        Phi = self.design_matrix(X)
        return (Phi * Phi) @ self.weight_variances(Phi.shape[1])

    def is_stationary(self):
        """Return False: a feature map is not translation invariant in general."""
        return False

    def __repr__(self):
        features = getattr(self.features, "__name__", None)
        if features is None:
            features = type(self.features).__name__ + "()"
        if self.anisotropic:
            prior_cov = "[{}]".format(", ".join(f"{v:.3g}" for v in self.prior_cov))
        elif isinstance(self.prior_cov, numbers.Real):
            prior_cov = f"{self.prior_cov:.3g}"
        else:
            prior_cov = f"{np.ravel(self.prior_cov)[0]:.3g}"
        return f"{type(self).__name__}(features={features}, prior_cov={prior_cov})"


def _is_fitted(estimator):
    """Whether ``check_is_fitted`` accepts ``estimator``."""
    try:
        check_is_fitted(estimator)
    except NotFittedError:
        return False
    return True
