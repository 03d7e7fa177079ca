"""ARD squared-exponential kernel on a subset of the input columns."""

import numbers

import numpy as np
from scipy.spatial.distance import cdist, pdist, squareform
from sklearn.gaussian_process.kernels import (
    Kernel,
    NormalizedKernelMixin,
    StationaryKernelMixin,
)

from .columns import (
    check_length_scale,
    column_indices,
    feature_names_of,
    is_anisotropic,
    scale_hyperparameter,
)

__all__ = ["ARDRBF"]


class ARDRBF(StationaryKernelMixin, NormalizedKernelMixin, Kernel):
    r"""Squared-exponential kernel with one length scale per selected column.

    The radial basis kernel with automatic relevance determination of the
    paper (Eq. 11, without its scale :math:`\lambda`), restricted to the
    input columns :math:`\mathcal{D}` listed in ``columns``:

    .. math::
        k(x, x') = \exp\Big(-\frac{1}{2} \sum_{d \in \mathcal{D}}
                   \frac{(x_d - x'_d)^2}{l_d^2}\Big)

    The scale :math:`\lambda` comes from composing with
    ``sklearn.gaussian_process.kernels.ConstantKernel``. Restricting the
    columns lets one input matrix carry the augmented features of Eq. 13
    while, e.g., the kinetic component :math:`f_{NP;kin}` of Eq. 14 sees only
    ``[q, qd, qdd]``.

    Parameters
    ----------
    length_scale : float or array-like of shape (n_columns,), default=1.0
        Length scales :math:`l_d`. A scalar gives an isotropic kernel; an
        array gives one length scale per selected column (its length must be
        ``len(columns)``, or ``n_features`` when ``columns`` is None).
    columns : list of int or str, default=None
        Columns of X the kernel acts on, as indices or feature names (e.g.
        ``"qd_0"``, see ``sklearn_gpcd.layout``). None selects all columns.
        Names are resolved against ``X.columns`` when the kernel is called on
        a DataFrame, or beforehand with
        :func:`~sklearn_gpcd.kernels.resolve_columns`.
    length_scale_bounds : pair of floats >= 0 or "fixed", default=(1e-5, 1e5)
        Bounds on ``length_scale``; "fixed" excludes it from ``theta``.

    See Also
    --------
    sklearn.gaussian_process.kernels.RBF : The same kernel on all columns.
    QuasiStaticGate : Switches a kernel on in quasi-static samples only.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import ConstantKernel, WhiteKernel
    >>> from sklearn_gpcd.kernels import ARDRBF
    >>> X = np.array([[0.0, 5.0, 1.0], [1.0, -5.0, 1.0]])
    >>> kernel = ARDRBF(length_scale=[1.0, 2.0], columns=[0, 2])
    >>> kernel
    ARDRBF(length_scale=[1, 2], columns=[0, 2])
    >>> kernel(X).round(4)  # column 1 is ignored
    array([[1.    , 0.6065],
           [0.6065, 1.    ]])
    >>> composed = ConstantKernel(2.0) * kernel + WhiteKernel(0.1)
    >>> [h.name for h in composed.hyperparameters]
    ['k1__k1__constant_value', 'k1__k2__length_scale', 'k2__noise_level']
    >>> composed.theta.shape
    (4,)
    """

    def __init__(self, length_scale=1.0, columns=None, length_scale_bounds=(1e-5, 1e5)):
        self.length_scale = length_scale
        self.columns = columns
        self.length_scale_bounds = length_scale_bounds

    @property
    def anisotropic(self):
        """bool: True when there is one length scale per column."""
        return is_anisotropic(self.length_scale)

    @property
    def hyperparameter_length_scale(self):
        """Hyperparameter: specification of ``length_scale``."""
        return scale_hyperparameter("length_scale", self.length_scale,
                                    self.length_scale_bounds)

    def select(self, X):
        """The columns of X this kernel acts on.

        Parameters
        ----------
        X : array-like or DataFrame of shape (n_samples, n_features)
            Inputs; str ``columns`` need a DataFrame (or
            :func:`~sklearn_gpcd.kernels.resolve_columns` beforehand).

        Returns
        -------
        X_selected : ndarray of shape (n_samples, n_columns)

        Examples
        --------
        >>> import numpy as np
        >>> ARDRBF(columns=[2, 0]).select(np.arange(6.0).reshape(2, 3))
        array([[2., 0.],
               [5., 3.]])
        """
        names = feature_names_of(X)
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if self.columns is None:
            return X
        indices = column_indices(self.columns, names, X.shape[1], "ARDRBF")
        return X[:, indices]

    def scaled(self, X):
        """Selected columns divided by their length scales, :math:`x_d / l_d`.

        Parameters
        ----------
        X : array-like or DataFrame of shape (n_samples, n_features)

        Returns
        -------
        X_scaled : ndarray of shape (n_samples, n_columns)

        Examples
        --------
        >>> import numpy as np
        >>> ARDRBF([2.0, 4.0], columns=[1, 2]).scaled(np.ones((1, 3)))
        array([[0.5 , 0.25]])
        """
        X = self.select(X)
        return X / check_length_scale(self.length_scale, X.shape[1], "ARDRBF")

    def __call__(self, X, Y=None, eval_gradient=False):
        r"""Return the kernel k(X, Y) and optionally its gradient.

        The gradient with respect to :math:`\theta_d = \log l_d` is

        .. math::
            \frac{\partial k(x, x')}{\partial \log l_d}
            = k(x, x') \, \frac{(x_d - x'_d)^2}{l_d^2}

        summed over :math:`d` for the isotropic kernel.

        Parameters
        ----------
        X : array-like of shape (n_samples_X, n_features)
            Left argument of the returned kernel k(X, Y).
        Y : array-like of shape (n_samples_Y, n_features), default=None
            Right argument; if None, k(X, X) is evaluated instead.
        eval_gradient : bool, default=False
            Whether to return the gradient with respect to the log of the
            hyperparameters. Only supported when Y is None.

        Returns
        -------
        K : ndarray of shape (n_samples_X, n_samples_Y)
            Kernel k(X, Y).
        K_gradient : ndarray of shape (n_samples_X, n_samples_X, n_dims), optional
            Gradient of k(X, X) with respect to ``theta``; only returned when
            ``eval_gradient`` is True.
        """
        Xs = self.scaled(X)
        if Y is None:
            sq_dists = pdist(Xs, metric="sqeuclidean")
            K = squareform(np.exp(-0.5 * sq_dists))
            np.fill_diagonal(K, 1.0)
        else:
            if eval_gradient:
                raise ValueError("Gradient can only be evaluated when Y is None.")
            return np.exp(-0.5 * cdist(Xs, self.scaled(Y), metric="sqeuclidean"))
        if not eval_gradient:
            return K
        n_samples = Xs.shape[0]
        if self.hyperparameter_length_scale.fixed:
            return K, np.empty((n_samples, n_samples, 0))
        if not self.anisotropic:
            return K, (K * squareform(sq_dists))[:, :, np.newaxis]
        K_gradient = np.empty((n_samples, n_samples, Xs.shape[1]))
        for d, column in enumerate(Xs.T):
            diff = np.subtract.outer(column, column)
            K_gradient[:, :, d] = diff * diff * K
        return K, K_gradient

    def __repr__(self):
        if self.anisotropic:
            length_scale = "[{}]".format(
                ", ".join(f"{value:.3g}" for value in self.length_scale)
            )
        else:
            length_scale = f"{np.ravel(self.length_scale)[0]:.3g}"
        columns = ""
        if self.columns is not None:
            values = self.columns
            if isinstance(values, (str, numbers.Integral)):
                values = [values]
            columns = ", columns=[{}]".format(", ".join(map(repr, map(_plain, values))))
        return f"{type(self).__name__}(length_scale={length_scale}{columns})"


def _plain(value):
    """numpy scalars as Python scalars, for a readable repr."""
    return value.item() if isinstance(value, np.generic) else value
