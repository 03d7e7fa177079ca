"""Quasi-static gate: a kernel switched on only at low joint velocity."""

import numbers

import numpy as np
from sklearn.gaussian_process.kernels import Hyperparameter, Kernel

from .._gate import DEFAULT_SIGMA_V, check_sigma_v, quasi_static
from .columns import (
    _n_samples,
    _take_rows,
    column_position,
    feature_names_of,
)

__all__ = ["QuasiStaticGate"]


class QuasiStaticGate(Kernel):
    r"""Vertical rescaling of a kernel by the quasi-static indicator of a joint.

    Implements the static-friction component of the paper (Eq. 14-17): with
    the indicator of joint :math:`\ell` (Eq. 15)

    .. math::
        a_\ell(x) = \begin{cases} 1 & |\dot q_\ell| < \sigma_v \\
                                  0 & |\dot q_\ell| \geq \sigma_v
                    \end{cases}

    the gated kernel is the vertical rescaling (Eq. 16)

    .. math::
        k_g(x, x') = a_\ell(x) \, k(x, x') \, a_\ell(x'),

    the covariance of the process :math:`a_\ell(x) f_{NP;stc}(x)`. Rows and
    columns of samples with :math:`a_\ell(x) = 0` are exact zeros, for K, its
    gradient and its diagonal, and the inner kernel is evaluated on the gated
    samples only.

    The hyperparameters of the inner kernel are exposed with the prefix
    ``kernel__`` (as in ``sklearn.gaussian_process.kernels.Exponentiation``).
    ``sigma_v`` is a plain parameter, not a hyperparameter: it is not part of
    ``theta`` (the gate is not differentiable in it) but can be tuned by
    cross-validation, e.g. ``GridSearchCV`` over ``..._kernel__sigma_v``.

    Parameters
    ----------
    kernel : Kernel
        The inner kernel :math:`k`, typically
        ``ConstantKernel() * ARDRBF(columns=...)`` on the augmented inputs
        (Eq. 13).
    velocity_column : int or str
        Column of X holding the joint velocity :math:`\dot q_\ell`, as an
        index or a feature name such as ``"qd_0"``.
    sigma_v : float, default=1e-2
        Velocity threshold between quasi-static and dynamic configurations
        (the paper uses :math:`10^{-2}` rad/s); must be finite and > 0.

    See Also
    --------
    ARDRBF : The squared-exponential kernel usually gated.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import RBF
    >>> from sklearn_gpcd.kernels import QuasiStaticGate
    >>> X = np.array([[0.0, 0.001], [0.5, 0.2], [1.0, -0.005]])
    >>> kernel = QuasiStaticGate(RBF(1.0), velocity_column=1, sigma_v=0.01)
    >>> kernel.gate(X)
    array([1., 0., 1.])
    >>> kernel(X).round(3)
    array([[1.   , 0.   , 0.607],
           [0.   , 0.   , 0.   ],
           [0.607, 0.   , 1.   ]])
    >>> [h.name for h in kernel.hyperparameters]
    ['kernel__length_scale']
    >>> kernel.set_params(sigma_v=1.0).gate(X)
    array([1., 1., 1.])
    """

    def __init__(self, kernel, velocity_column, sigma_v=DEFAULT_SIGMA_V):
        self.kernel = kernel
        self.velocity_column = velocity_column
        self.sigma_v = sigma_v

    def get_params(self, deep=True):
        """Get parameters of this kernel.

        Parameters
        ----------
        deep : bool, default=True
            If True, also return the parameters of the inner kernel, prefixed
            with ``kernel__``.

        Returns
        -------
        params : dict
            Parameter names mapped to their values.
        """
        params = dict(
            kernel=self.kernel,
            velocity_column=self.velocity_column,
            sigma_v=self.sigma_v,
        )
        if deep:
            deep_items = self.kernel.get_params().items()
            params.update(("kernel__" + k, value) for k, value in deep_items)
        return params

    @property
    def hyperparameters(self):
        """list of Hyperparameter: those of the inner kernel, ``kernel__`` prefixed."""
        return [
            Hyperparameter(
                "kernel__" + h.name, h.value_type, h.bounds, h.n_elements, h.fixed
            )
            for h in self.kernel.hyperparameters
        ]

    @property
    def theta(self):
        """ndarray of shape (n_dims,): log hyperparameters of the inner kernel."""
        return self.kernel.theta

    @theta.setter
    def theta(self, theta):
        self.kernel.theta = theta

    @property
    def bounds(self):
        """ndarray of shape (n_dims, 2): log bounds of the inner kernel."""
        return self.kernel.bounds

    def __eq__(self, b):
        if type(self) is not type(b):
            return False
        return (
            self.kernel == b.kernel
            and self.velocity_column == b.velocity_column
            and self.sigma_v == b.sigma_v
        )

    def gate(self, X):
        r"""The quasi-static indicator :math:`a_\ell(x)` of each sample (Eq. 15).

        Parameters
        ----------
        X : array-like or DataFrame of shape (n_samples, n_features)
            Inputs; a str ``velocity_column`` needs a DataFrame (or
            :func:`~sklearn_gpcd.kernels.resolve_columns` beforehand).

        Returns
        -------
        a : ndarray of shape (n_samples,)
            1.0 where ``|X[:, velocity_column]| < sigma_v``, else 0.0.

        Examples
        --------
        >>> import numpy as np
        >>> from sklearn.gaussian_process.kernels import RBF
        >>> QuasiStaticGate(RBF(), 0, sigma_v=0.1).gate([[0.05], [-0.2]])
        array([1., 0.])
        """
        check_sigma_v(self.sigma_v, "QuasiStaticGate")
        names = feature_names_of(X)
        X = np.atleast_2d(np.asarray(X, dtype=float))
        column = column_position(
            self.velocity_column, names, X.shape[1], "QuasiStaticGate (velocity_column)"
        )
        return quasi_static(X[:, column], self.sigma_v).astype(float)

    def __call__(self, X, Y=None, eval_gradient=False):
        """Return the kernel k(X, Y) and optionally its gradient.

        The gradient is that of the inner kernel on the gated block and
        exactly zero elsewhere (``sigma_v`` is not differentiated).

        Parameters
        ----------
        X, Y, eval_gradient
            As for :meth:`ARDRBF.__call__ <sklearn_gpcd.kernels.ARDRBF.__call__>`.

        Returns
        -------
        K, K_gradient
            As for :meth:`ARDRBF.__call__ <sklearn_gpcd.kernels.ARDRBF.__call__>`.
        """
        X = _as_2d(X)
        rows = np.flatnonzero(self.gate(X))
        if Y is not None:
            if eval_gradient:
                raise ValueError("Gradient can only be evaluated when Y is None.")
            Y = _as_2d(Y)
            cols = np.flatnonzero(self.gate(Y))
            K = np.zeros((_n_samples(X), _n_samples(Y)))
            if rows.size and cols.size:
                block = self.kernel(_take_rows(X, rows), _take_rows(Y, cols))
                K[np.ix_(rows, cols)] = block
            return K
        n_samples = _n_samples(X)
        K = np.zeros((n_samples, n_samples))
        if not eval_gradient:
            if rows.size:
                K[np.ix_(rows, rows)] = self.kernel(_take_rows(X, rows))
            return K
        K_gradient = np.zeros((n_samples, n_samples, self.kernel.n_dims))
        if rows.size:
            block, block_gradient = self.kernel(_take_rows(X, rows), eval_gradient=True)
            K[np.ix_(rows, rows)] = block
            K_gradient[np.ix_(rows, rows)] = block_gradient
        return K, K_gradient

    def diag(self, X):
        """Return the diagonal of the kernel k(X, X).

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            Argument to the kernel.

        Returns
        -------
        K_diag : ndarray of shape (n_samples,)
            The inner kernel's diagonal on gated samples, 0 elsewhere.
        """
        X = _as_2d(X)
        rows = np.flatnonzero(self.gate(X))
        K_diag = np.zeros(_n_samples(X))
        if rows.size:
            K_diag[rows] = self.kernel.diag(_take_rows(X, rows))
        return K_diag

    def is_stationary(self):
        """Return False: the gate depends on the absolute velocity."""
        return False

    @property
    def requires_vector_input(self):
        """bool: True, the gate reads a column of a feature vector."""
        return True

    def __repr__(self):
        sigma_v = self.sigma_v
        if isinstance(sigma_v, numbers.Real):
            sigma_v = f"{sigma_v:.3g}"
        velocity_column = self.velocity_column
        if isinstance(velocity_column, np.generic):
            velocity_column = velocity_column.item()
        return (
            f"{type(self).__name__}({self.kernel}, "
            f"velocity_column={velocity_column!r}, sigma_v={sigma_v})"
        )


def _as_2d(X):
    """Keep DataFrames (for column names), make other inputs 2-D arrays."""
    if hasattr(X, "iloc"):
        return X
    return np.atleast_2d(np.asarray(X, dtype=float))
