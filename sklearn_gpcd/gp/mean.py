"""Parametric mean of the semi-parametric GP: the rigid-body model (Eq. 8-10)
with deterministic parameters, option (i) of Sec. III-A."""

import numbers

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin, _fit_context, clone
from sklearn.utils._param_validation import HasMethods, Interval, StrOptions
from sklearn.utils.validation import check_is_fitted, validate_data

from .._gate import SIGMA_V_CONSTRAINT, check_sigma_v, quasi_static
from .._persistence import VersionedStateMixin


class ParametricMean(VersionedStateMixin, RegressorMixin, BaseEstimator):
    r"""Linear-in-parameters mean :math:`m(x) = \bar\phi(x)\, w`, w by least squares.

    The paper's parametric prior (Eq. 8-10) writes joint :math:`\ell`'s current
    as :math:`\phi_\ell(x) w_\ell` with :math:`\phi_\ell = [\phi^d_\ell\
    \phi^f_\ell]`, the rigid-body features plus Coulomb/viscous friction
    columns :math:`[\operatorname{sign}(\dot q_\ell)\ \dot q_\ell]`. Treating
    :math:`w` as deterministic (Sec. III-A, option (i)) it is fitted once by
    (ridge) least squares

    .. math::

        w = \arg\min_w \|y - \Phi w\|^2 + \alpha \|w\|^2 ,
        \qquad \Phi = \bar\phi(X),

    and only enters the GP through its mean. With ``friction_columns`` and
    ``sigma_v`` the features become the paper's :math:`\bar\phi_\ell`
    (Eq. 17): friction columns are zeroed where :math:`|\dot q_\ell| <
    \sigma_v`, the quasi-static regime left to the gated GP.

    Parameters
    ----------
    features : callable, transformer or None, default=None
        Map ``X -> Phi`` of shape ``(n_samples, n_params)``: a callable, or a
        scikit-learn transformer (cloned and fitted in :meth:`fit`), e.g.
        ``RigidBodyFeatures(robot, joint=l)``. None uses ``Phi = X``
        (a plain linear model).
    friction_columns : array-like of int, "auto" or None, default=None
        Columns of ``Phi`` holding friction terms. ``"auto"`` reads
        ``friction_columns_`` from the fitted ``features`` transformer (none
        if it has no such attribute).
    velocity_column : int or str, default=None
        Column of ``X`` holding :math:`\dot q_\ell` (a name needs ``X`` with
        column names). Required when friction columns and ``sigma_v`` are
        given.
    sigma_v : float > 0 or None, default=None
        Quasi-static velocity threshold; None keeps :math:`\phi` unmasked.
    alpha : float >= 0, default=0.0
        Ridge penalty. 0 gives the minimum-norm least-squares solution,
        which is well defined for the rank-deficient regressors of robot
        dynamics.
    fit_intercept : bool, default=False
        Also fit an unpenalised constant.

    Attributes
    ----------
    coef_ : ndarray of shape (n_params,) or (n_outputs, n_params)
        Parameters :math:`w`.
    intercept_ : float or ndarray of shape (n_outputs,)
        Constant term (0.0 when ``fit_intercept=False``).
    features_ : callable or transformer
        The (fitted) feature map.
    friction_columns_ : ndarray of int
        Friction columns of ``Phi`` masked by ``sigma_v``.
    velocity_column_ : int or None
        Index of the velocity column in ``X``.
    n_features_in_ : int
        Number of columns of ``X``.
    feature_names_in_ : ndarray of str
        Column names of ``X``, when it has string column names.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.gp import ParametricMean
    >>> def features(X):  # phi(x) = [x_0, sign(v), v] with v = x_1
    ...     return np.column_stack([X[:, 0], np.sign(X[:, 1]), X[:, 1]])
    >>> X = np.array([[0.0, 0.0], [1.0, 0.5], [2.0, -0.5], [3.0, 1.0]])
    >>> y = 2.0 * X[:, 0] + 0.3 * np.sign(X[:, 1]) + 0.1 * X[:, 1]
    >>> mean = ParametricMean(features).fit(X, y)
    >>> np.round(mean.coef_, 6)
    array([2. , 0.3, 0.1])
    >>> masked = ParametricMean(features, friction_columns=[1, 2],
    ...                         velocity_column=1, sigma_v=0.6).fit(X, y)
    >>> masked.design_matrix(X)[:, 1:]  # phi-bar: friction zeroed where |v| < 0.6
    array([[0., 0.],
           [0., 0.],
           [0., 0.],
           [1., 1.]])
    """

    _parameter_constraints = {
        "features": [None, callable, HasMethods(["fit", "transform"])],
        "friction_columns": [None, StrOptions({"auto"}), "array-like"],
        "velocity_column": [None, numbers.Integral, str, "array-like"],
        "sigma_v": [None, SIGMA_V_CONSTRAINT],
        "alpha": [Interval(numbers.Real, 0, None, closed="left")],
        "fit_intercept": ["boolean"],
    }

    def __init__(
        self,
        features=None,
        friction_columns=None,
        velocity_column=None,
        sigma_v=None,
        alpha=0.0,
        fit_intercept=False,
    ):
        self.features = features
        self.friction_columns = friction_columns
        self.velocity_column = velocity_column
        self.sigma_v = sigma_v
        self.alpha = alpha
        self.fit_intercept = fit_intercept

    @_fit_context(prefer_skip_nested_validation=False)
    def fit(self, X, y):
        """Fit the parameters by (ridge) least squares.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)
            Inputs, e.g. in the :mod:`sklearn_gpcd.layout` column layout.
        y : array-like of shape (n_samples,) or (n_samples, n_outputs)
            Targets.

        Returns
        -------
        self : ParametricMean
        """
        self._fit(X, y)
        return self

    def _fit(self, X, y):
        """Fit; return the design matrix of ``X`` (reused by :meth:`_fit_predict`)."""
        X, y = validate_data(self, X, y, multi_output=True, y_numeric=True, dtype=np.float64)
        self.features_ = _fit_features(self.features, X)
        Phi = _apply_features(self.features_, X)
        self.friction_columns_, self.velocity_column_ = self._check_friction(Phi.shape[1])
        Phi = self._mask_friction(X, Phi)
        self.coef_, self.intercept_ = _ridge(Phi, y, self.alpha, self.fit_intercept)
        if not (np.all(np.isfinite(self.coef_)) and np.all(np.isfinite(self.intercept_))):
            raise ValueError(
                "The least-squares parameters overflowed (features of magnitude "
                f"{np.abs(Phi).max():.3g} or below {np.abs(Phi[Phi != 0]).min(initial=np.inf):.3g}); "
                "rescale the features or set alpha > 0."
            )
        return Phi

    def _fit_predict(self, X, y):
        """``fit(X, y).predict(X)`` with the features of ``X`` computed once."""
        self._validate_params()
        return self._fit(X, y) @ self.coef_.T + self.intercept_

    def design_matrix(self, X):
        r"""Features :math:`\bar\phi(X)` the mean is linear in (Eq. 10, 17).

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)

        Returns
        -------
        Phi : ndarray of shape (n_samples, n_params)
        """
        check_is_fitted(self, "features_")
        X = validate_data(self, X, reset=False, dtype=np.float64)
        return self._mask_friction(X, _apply_features(self.features_, X))

    def predict(self, X):
        """Parametric prediction :math:`\\bar\\phi(X) w`.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_features)

        Returns
        -------
        y : ndarray of shape (n_samples,) or (n_samples, n_outputs)
        """
        check_is_fitted(self, "coef_")
        return self.design_matrix(X) @ self.coef_.T + self.intercept_

    def _mask_friction(self, X, Phi):
        """phi-bar (Eq. 17): zero the friction columns where |qd| < sigma_v."""
        if self.velocity_column_ is not None:
            at_rest = quasi_static(X[:, self.velocity_column_], self.sigma_v)
            Phi[np.ix_(at_rest, self.friction_columns_)] = 0.0
        return Phi

    def _check_friction(self, n_params):
        """Validate the phi-bar settings; return (friction columns, velocity index).

        The velocity index is None when nothing is masked.
        """
        cols = self.friction_columns
        if isinstance(cols, str) and cols == "auto":
            cols = getattr(self.features_, "friction_columns_", [])
        elif isinstance(cols, str):
            raise ValueError(f"friction_columns must be indices, 'auto' or None, got {cols!r}.")
        cols = np.asarray([] if cols is None else cols, dtype=int).ravel()
        bad = cols[(cols < -n_params) | (cols >= n_params)]
        if len(bad):
            raise ValueError(
                f"friction_columns {bad.tolist()} are outside the {n_params} feature columns."
            )
        if self.sigma_v is None:
            return cols, None
        check_sigma_v(self.sigma_v, "ParametricMean", allow_none=True)
        if len(cols) == 0:
            return cols, None
        if self.velocity_column is None:
            raise ValueError(
                "velocity_column is required when sigma_v and friction_columns are set."
            )
        return cols, _column_index(self, self.velocity_column, "velocity_column")

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.target_tags.multi_output = True
        return tags


def _fit_features(features, X):
    """Clone and fit a transformer; pass callables (and None) through."""
    if hasattr(features, "fit") and hasattr(features, "transform"):
        return clone(features).fit(X)
    if features is None or callable(features):
        return features
    raise TypeError(
        "features must be a callable X -> Phi, a transformer with fit/transform "
        f"or None, got {type(features).__name__}."
    )


def _apply_features(features, X):
    """``Phi = features(X)`` as a finite float array of shape (n_samples, n_params)."""
    if features is None:
        return X.copy()
    Phi = features.transform(X) if hasattr(features, "transform") else features(X)
    Phi = np.array(Phi, dtype=np.float64)  # a copy: the phi-bar mask writes into it
    if Phi.ndim != 2 or Phi.shape[0] != X.shape[0]:
        raise ValueError(
            f"features must return an array of shape (n_samples, n_params) = "
            f"({X.shape[0]}, p), got shape {Phi.shape}."
        )
    if not np.all(np.isfinite(Phi)):
        rows = np.flatnonzero(~np.isfinite(Phi).all(axis=1))
        raise ValueError(f"features returned NaN or inf in rows {rows[:10].tolist()}.")
    return Phi


def _column_index(estimator, column, name):
    """Index of ``column`` (int or name) in the estimator's input."""
    if isinstance(column, str):
        names = list(getattr(estimator, "feature_names_in_", []))
        if column not in names:
            raise ValueError(
                f"{name}={column!r} is not a column of X (columns: {names or 'unnamed'})."
            )
        return names.index(column)
    n = estimator.n_features_in_
    if not isinstance(column, numbers.Integral) or not -n <= column < n:
        raise ValueError(f"{name}={column!r} is not a column index of X with {n} columns.")
    return int(column)


def _ridge(Phi, y, alpha, fit_intercept):
    r"""Minimiser of :math:`\|y - \Phi w - b\|^2 + \alpha\|w\|^2` via ``lstsq``."""
    if fit_intercept:
        Phi_mean, y_mean = Phi.mean(axis=0), y.mean(axis=0)
        Phi, y = Phi - Phi_mean, y - y_mean
    if alpha > 0:  # augmented system [Phi; sqrt(alpha) I] w = [y; 0]
        p = Phi.shape[1]
        Phi = np.vstack([Phi, np.sqrt(alpha) * np.eye(p)])
        y = np.concatenate([y, np.zeros((p,) + y.shape[1:])])
    coef = np.linalg.lstsq(Phi, y, rcond=None)[0].T
    intercept = y_mean - Phi_mean @ coef.T if fit_intercept else np.zeros(coef.shape[:-1])
    return coef, (float(intercept) if np.ndim(intercept) == 0 else intercept)
