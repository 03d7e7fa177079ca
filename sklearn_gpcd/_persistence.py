"""Versioned pickling state shared by the package's estimators.

Every public estimator and stateful object of the package lists
:class:`VersionedStateMixin` first among its bases. Its ``__getstate__``
records the versions of sklearn-gpcd and scikit-learn that wrote the state,
and its ``__setstate__`` warns when either differs from the running one. This
works for :mod:`pickle`, :mod:`joblib` and :mod:`skops.io` alike, which all go
through ``__getstate__`` / ``__setstate__``.
"""

import warnings

import sklearn
from sklearn.exceptions import InconsistentVersionWarning

from ._version import __version__

#: Key of the sklearn-gpcd version in a pickled state.
VERSION_KEY = "_sklearn_gpcd_version"
#: Key of the scikit-learn version in a pickled state.
SKLEARN_VERSION_KEY = "_sklearn_version"
#: Version reported for a state written before versions were recorded.
UNKNOWN_VERSION = "unknown (saved before sklearn-gpcd recorded its version)"


class GPCDVersionWarning(UserWarning):
    """An object was unpickled with another sklearn-gpcd version than it was saved with.

    The fitted state of an estimator is an implementation detail: loading it
    into another version of the package may fail later or give different
    results. Refit the estimator, or load it with the version that saved it
    (``original_version``).

    Parameters
    ----------
    estimator_name : str
        Class name of the unpickled object.
    current_version : str
        sklearn-gpcd version running now.
    original_version : str
        sklearn-gpcd version that saved the object.

    Attributes
    ----------
    estimator_name, current_version, original_version : str
        The parameters, for programmatic checks.

    Examples
    --------
    >>> from sklearn_gpcd._persistence import GPCDVersionWarning
    >>> warning = GPCDVersionWarning(estimator_name="CollisionDetector",
    ...                              current_version="0.2.0", original_version="0.1.0")
    >>> str(warning).startswith("Unpickling CollisionDetector saved with sklearn-gpcd 0.1.0")
    True
    """

    def __init__(self, *, estimator_name, current_version, original_version):
        self.estimator_name = estimator_name
        self.current_version = current_version
        self.original_version = original_version

    def __str__(self):
        return (
            f"Unpickling {self.estimator_name} saved with sklearn-gpcd "
            f"{self.original_version} into sklearn-gpcd {self.current_version}. "
            "Its fitted state may not work or may give different results; refit it, "
            "or load it with the version that saved it."
        )


class VersionedStateMixin:
    """Record the package versions in the pickled state; warn on a mismatch.

    Put it first among the bases (``class Est(VersionedStateMixin,
    RegressorMixin, BaseEstimator)``): it chains to the next
    ``__getstate__`` / ``__setstate__`` in the MRO (scikit-learn's
    :class:`~sklearn.base.BaseEstimator`, or ``object``), adding the keys
    ``_sklearn_gpcd_version`` and ``_sklearn_version`` to the state and
    removing them again on load. Loading warns with
    :class:`GPCDVersionWarning` when the stored sklearn-gpcd version differs
    from :data:`sklearn_gpcd.__version__`, and with scikit-learn's
    :class:`~sklearn.exceptions.InconsistentVersionWarning` when the stored
    scikit-learn version differs (scikit-learn itself only checks its own
    estimators, but ours hold its kernels and estimators).

    Examples
    --------
    >>> import warnings
    >>> from sklearn_gpcd._persistence import VersionedStateMixin
    >>> class Thing(VersionedStateMixin):
    ...     pass
    >>> state = Thing().__getstate__()
    >>> sorted(state)
    ['_sklearn_gpcd_version', '_sklearn_version']
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     Thing().__setstate__(dict(state, _sklearn_gpcd_version="0.0.1"))
    >>> [w.category.__name__ for w in caught]
    ['GPCDVersionWarning']
    """

    def __getstate__(self):
        try:
            state = super().__getstate__()
        except AttributeError:  # Python < 3.11: object has no __getstate__
            state = None
        if state is None:  # no __dict__ entries (or Python < 3.11)
            state = self.__dict__
        return dict(
            state, **{VERSION_KEY: __version__, SKLEARN_VERSION_KEY: sklearn.__version__}
        )

    def __setstate__(self, state):
        state = dict(state)
        name = type(self).__name__
        saved = state.pop(VERSION_KEY, UNKNOWN_VERSION)
        if saved != __version__:
            warnings.warn(
                GPCDVersionWarning(
                    estimator_name=name, current_version=__version__, original_version=saved
                ),
                stacklevel=2,
            )
        saved_sklearn = state.pop(SKLEARN_VERSION_KEY, None)
        if saved_sklearn is not None and saved_sklearn != sklearn.__version__:
            warnings.warn(
                InconsistentVersionWarning(
                    estimator_name=name,
                    current_sklearn_version=sklearn.__version__,
                    original_sklearn_version=saved_sklearn,
                ),
                stacklevel=2,
            )
        try:
            super().__setstate__(state)
        except AttributeError:  # object has no __setstate__
            self.__dict__.update(state)
