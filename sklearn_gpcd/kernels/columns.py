"""Input columns of the kernels: names, indices and their validation.

The kernels of this package act on chosen columns of the input layout
(``sklearn_gpcd.layout``): :class:`~sklearn_gpcd.kernels.ARDRBF` on
``columns``, :class:`~sklearn_gpcd.kernels.QuasiStaticGate` on
``velocity_column``. Both accept integer indices or feature names such as
``"qd_0"``. Names are resolved against the feature names of a pandas
DataFrame, either on the fly when a kernel is called on a DataFrame or once,
at fit time, with :func:`resolve_columns`.
"""

import numbers

import numpy as np
from sklearn.base import clone
from sklearn.gaussian_process.kernels import Hyperparameter, Kernel

from .._gate import check_sigma_v

__all__ = ["resolve_columns"]


def resolve_columns(kernel, feature_names=None, n_features=None):
    """Replace column names by indices everywhere in a kernel tree.

    Walks every kernel reachable through ``get_params(deep=True)`` (sklearn's
    ``Sum``, ``Product``, ``Exponentiation``, ``ConstantKernel``, ... and the
    kernels of this package) and, on a clone, rewrites each parameter named
    ``columns`` (a list) or ``velocity_column`` (a scalar) so that str names
    become their integer position in ``feature_names``. It also validates
    what can be checked before seeing the data: every index lies in
    ``[0, n_features)``, no column is selected twice, an anisotropic
    ``length_scale`` has one entry per selected column, and every ``sigma_v``
    is a finite threshold > 0.

    Parameters
    ----------
    kernel : Kernel
        The kernel tree; it is not modified.
    feature_names : array-like of str, default=None
        Names of the input columns, e.g. ``X.columns`` of a DataFrame or
        ``sklearn_gpcd.layout.column_names(n_joints)``. Required when the
        tree refers to a column by name.
    n_features : int, default=None
        Number of input columns. Defaults to ``len(feature_names)``; when both
        are None, indices are not range-checked.

    Returns
    -------
    resolved : Kernel
        A clone of ``kernel`` (``sklearn.base.clone``) whose columns are all
        integer indices. Note that cloning resets fitted scikit-learn
        transformers held as parameters (see
        :class:`~sklearn_gpcd.kernels.ParametricKernel`).

    Raises
    ------
    ValueError
        Naming the offending kernel parameter: an unknown column name (the
        known names are listed), a name while ``feature_names`` is None, an
        index outside ``[0, n_features)``, a duplicated column, a
        ``length_scale`` whose length differs from ``len(columns)``, or
        ``sigma_v <= 0`` / not finite.

    Examples
    --------
    >>> from sklearn.gaussian_process.kernels import ConstantKernel
    >>> from sklearn_gpcd.kernels import ARDRBF, QuasiStaticGate
    >>> names = ["q_0", "qd_0", "qdd_0"]
    >>> kernel = ConstantKernel() * QuasiStaticGate(
    ...     ARDRBF([1.0, 2.0], columns=["q_0", "qdd_0"]), velocity_column="qd_0")
    >>> resolved = resolve_columns(kernel, feature_names=names)
    >>> resolved.k2.kernel.columns, resolved.k2.velocity_column
    ([0, 2], 1)
    >>> resolve_columns(ARDRBF(columns=["tau_0"]), feature_names=names)
    ... # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: ARDRBF (columns): unknown column name 'tau_0'; known names are [...]
    """
    if feature_names is not None:
        feature_names = [str(name) for name in feature_names]
        if n_features is None:
            n_features = len(feature_names)
        elif n_features != len(feature_names):
            raise ValueError(
                f"resolve_columns: n_features={n_features} but "
                f"{len(feature_names)} feature names were given"
            )
    resolved = clone(kernel)
    for path, node in _kernel_nodes(resolved):
        _resolve_node(node, path, feature_names, n_features)
    return resolved


def _kernel_nodes(kernel):
    """Yield ``(path, node)`` for the root and every nested kernel."""
    yield "", kernel
    for key, value in kernel.get_params(deep=True).items():
        if isinstance(value, Kernel):
            yield key, value


def _resolve_node(node, path, feature_names, n_features):
    """Resolve and validate the column parameters of one kernel in place."""
    params = node.get_params(deep=False)
    owner = type(node).__name__ + (f" at {path!r}" if path else "")
    if params.get("columns") is not None:
        where = f"{owner} (columns)"
        columns = column_indices(params["columns"], feature_names, n_features, where)
        if "length_scale" in params:
            check_length_scale(params["length_scale"], len(columns), where)
        node.set_params(columns=columns)
    if "velocity_column" in params:
        index = column_position(
            params["velocity_column"],
            feature_names,
            n_features,
            f"{owner} (velocity_column)",
        )
        node.set_params(velocity_column=index)
    if "sigma_v" in params:
        check_sigma_v(params["sigma_v"], owner)


def feature_names_of(X):
    """Column names of a DataFrame-like ``X`` as a list of str, else None.

    Examples
    --------
    >>> import numpy as np
    >>> feature_names_of(np.zeros((2, 2))) is None
    True
    """
    columns = getattr(X, "columns", None)
    if columns is None:
        return None
    names = list(columns)
    if not all(isinstance(name, str) for name in names):
        return None
    return names


def column_position(column, feature_names=None, n_features=None, owner="kernel"):
    """Integer position of one column given by index or by name.

    (Not :func:`sklearn_gpcd.layout.column_index`, which places a signal of
    a joint in the input layout.)

    Parameters
    ----------
    column : int or str
        Column index or feature name.
    feature_names : list of str, default=None
        Known feature names; required when ``column`` is a str.
    n_features : int, default=None
        Number of columns of X, to range-check the index.
    owner : str, default="kernel"
        Prefix of error messages, naming the kernel parameter.

    Returns
    -------
    index : int

    Examples
    --------
    >>> column_position("qd_0", ["q_0", "qd_0"])
    1
    >>> column_position(5, n_features=2, owner="QuasiStaticGate")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: QuasiStaticGate: column index 5 is outside X with 2 features ...
    """
    if isinstance(column, str):
        if feature_names is None:
            raise ValueError(
                f"{owner}: column {column!r} is given by name but X has no "
                "feature names; pass a pandas DataFrame or resolve the names "
                "first with resolve_columns(kernel, feature_names=...)"
            )
        if column not in feature_names:
            raise ValueError(
                f"{owner}: unknown column name {column!r}; known names are "
                f"{list(feature_names)}"
            )
        index = list(feature_names).index(column)
    elif isinstance(column, numbers.Integral) and not isinstance(column, bool):
        index = int(column)
    else:
        raise TypeError(
            f"{owner}: a column must be an int index or a str name, got "
            f"{column!r} of type {type(column).__name__}"
        )
    if n_features is not None and not 0 <= index < n_features:
        raise ValueError(
            f"{owner}: column index {index} is outside X with {n_features} "
            f"features (valid indices are 0..{n_features - 1})"
        )
    return index


def column_indices(columns, feature_names=None, n_features=None, owner="kernel"):
    """Integer positions of a list of columns given by index or name.

    A single int or str is treated as a one-element list.

    Returns
    -------
    indices : list of int

    Examples
    --------
    >>> column_indices(["qd_0", 0], ["q_0", "qd_0"])
    [1, 0]
    """
    if isinstance(columns, (str, numbers.Integral)):
        columns = [columns]
    columns = list(columns)
    if not columns:
        raise ValueError(f"{owner}: columns selects no column; use None for all")
    indices = [column_position(c, feature_names, n_features, owner) for c in columns]
    if len(set(indices)) != len(indices):
        repeated = sorted({c for c in indices if indices.count(c) > 1})
        raise ValueError(f"{owner}: columns selects column(s) {repeated} twice")
    return indices


def check_length_scale(length_scale, n_columns, owner="ARDRBF"):
    """Validate a length scale against the number of selected columns.

    Returns
    -------
    length_scale : float or ndarray of shape (n_columns,)
        A scalar for the isotropic kernel, else one entry per column.

    Examples
    --------
    >>> check_length_scale([1.0, 2.0], 3)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: ARDRBF: length_scale has 2 entries but 3 columns are selected; ...
    """
    length_scale = np.squeeze(np.asarray(length_scale, dtype=float))
    if length_scale.ndim > 1:
        raise ValueError(f"{owner}: length_scale must be a scalar or 1-D")
    if length_scale.ndim == 1 and length_scale.shape[0] != n_columns:
        raise ValueError(
            f"{owner}: length_scale has {length_scale.shape[0]} entries but "
            f"{n_columns} columns are selected; give one length scale per "
            "selected column or a scalar"
        )
    return length_scale


def is_anisotropic(value):
    """True when a kernel hyperparameter holds several values (one per column or weight).

    Examples
    --------
    >>> is_anisotropic(1.0), is_anisotropic([1.0]), is_anisotropic([1.0, 2.0])
    (False, False, True)
    """
    return bool(np.iterable(value) and len(value) > 1)


def scale_hyperparameter(name, value, bounds):
    """The :class:`~sklearn.gaussian_process.kernels.Hyperparameter` ``name`` of ``value``.

    One positive number, or one per entry when :func:`is_anisotropic` (a
    length scale per column, a prior variance per weight).

    Examples
    --------
    >>> scale_hyperparameter("length_scale", [1.0, 2.0], (1e-5, 1e5)).n_elements
    2
    """
    if is_anisotropic(value):
        return Hyperparameter(name, "numeric", bounds, len(value))
    return Hyperparameter(name, "numeric", bounds)

def _take_rows(X, rows):
    """Rows ``rows`` of an array or DataFrame, keeping its type."""
    if hasattr(X, "iloc"):
        return X.iloc[rows]
    return np.asarray(X)[rows]


def _n_samples(X):
    """Number of rows of an array-like or DataFrame."""
    return X.shape[0] if hasattr(X, "shape") else len(X)
