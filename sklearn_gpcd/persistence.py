"""Save and load fitted estimators with joblib (pickle) or skops.

The file extension picks the format:

- ``.joblib`` or ``.pkl``: :func:`joblib.dump` / :func:`joblib.load`. Fast
  and complete, but a pickle runs code when it is loaded: only load files
  you trust.
- ``.skops``: :func:`skops.io.dump` / :func:`skops.io.load` (optional
  dependency, ``pip install "sklearn-gpcd[persist]"``). The file is a zip
  archive of JSON and ``.npy`` entries; loading instantiates only the types
  it is allowed to (see :func:`load`).

Every estimator of the package records the sklearn-gpcd and scikit-learn
versions in its saved state and warns (:class:`GPCDVersionWarning`,
:class:`~sklearn.exceptions.InconsistentVersionWarning`) when it is loaded
into other versions (see :class:`sklearn_gpcd._persistence.VersionedStateMixin`).
"""

import importlib
from pathlib import Path
from zipfile import BadZipFile

import joblib
import numpy as np

from ._persistence import GPCDVersionWarning

__all__ = ["GPCDVersionWarning", "UntrustedTypesError", "load", "save"]

#: Extensions saved and loaded with joblib (pickle).
PICKLE_EXTENSIONS = (".joblib", ".pkl")
#: Extension saved and loaded with skops.
SKOPS_EXTENSION = ".skops"
#: Packages whose classes :func:`load` trusts in a skops file (all of
#: sklearn-gpcd's own classes and functions are trusted too).
TRUSTED_PACKAGES = ("sklearn", "numpy", "scipy")


class UntrustedTypesError(ValueError):
    """A skops file holds types that :func:`load` was not told to trust.

    Parameters
    ----------
    path : str
        The file.
    types : list of str
        Fully qualified names of the types (or functions) not trusted.

    Attributes
    ----------
    path : str
    types : list of str

    Examples
    --------
    >>> from sklearn_gpcd.persistence import UntrustedTypesError
    >>> error = UntrustedTypesError("model.skops", ["mymodule.Features"])
    >>> error.types
    ['mymodule.Features']
    """

    def __init__(self, path, types):
        self.path = str(path)
        self.types = list(types)
        super().__init__(
            f"{self.path} contains types that are not trusted: {self.types}. Loading "
            "them may run their code; if you trust them, pass "
            f"load({self.path!r}, trusted={self.types!r})."
        )


def save(estimator, path):
    """Save a (fitted) estimator, in the format given by the file extension.

    Parameters
    ----------
    estimator : object
        Typically a fitted estimator of the package, a pipeline containing
        one, or a :class:`~sklearn_gpcd.detection.StreamingMonitor`.
    path : str or path-like
        Destination; its extension chooses the format: ``.joblib`` / ``.pkl``
        (joblib) or ``.skops`` (skops, optional dependency).

    Returns
    -------
    path : pathlib.Path
        The file written.

    Raises
    ------
    ValueError
        If the extension is none of ``.joblib``, ``.pkl``, ``.skops``.
    ImportError
        If a ``.skops`` file is asked for and skops is not installed.

    See Also
    --------
    load : The reverse.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> from sklearn_gpcd.gp import SemiParametricGPRegressor
    >>> from sklearn_gpcd.persistence import load, save
    >>> X = np.linspace(0, 1, 10)[:, None]
    >>> gp = SemiParametricGPRegressor(random_state=0).fit(X, np.sin(6 * X[:, 0]))
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> for name in ("gp.joblib", "gp.skops"):
    ...     copy = load(save(gp, folder / name))
    ...     print(name, np.array_equal(copy.predict(X), gp.predict(X)))
    gp.joblib True
    gp.skops True
    """
    path = Path(path)
    if _format(path) == "joblib":
        joblib.dump(estimator, path)
    else:
        _skops().dump(estimator, path)
    return path


def load(path, trusted=None):
    """Load an estimator written by :func:`save` (or by joblib / skops).

    A ``.joblib`` / ``.pkl`` file is unpickled: this can run arbitrary code,
    so only load files from a source you trust (``trusted`` does not apply).

    A ``.skops`` file is first audited. These types are trusted:

    - those skops trusts by default (builtins, NumPy arrays and ufuncs,
      scikit-learn estimators, ...);
    - every class and function of sklearn-gpcd;
    - every class of scikit-learn, NumPy and SciPy (e.g. kernels, internal
      classes); their *functions* are not trusted, as they can be called
      with the estimator's data;

    anything else (e.g. your own feature function or transformer) must be
    listed in ``trusted``, or :class:`UntrustedTypesError` is raised listing
    it. Inspect that list before passing it: an untrusted type may run its
    code when the estimator is used.

    Parameters
    ----------
    path : str or path-like
        File written by :func:`save`; the extension gives the format.
    trusted : list of str or type, default=None
        For skops files: further types to trust, by fully qualified name as
        listed by :class:`UntrustedTypesError` (or
        :func:`skops.io.get_untrusted_types`), or as the types themselves.

    Returns
    -------
    estimator : object
        The loaded object. A :class:`GPCDVersionWarning` is raised when it was
        saved by another sklearn-gpcd version.

    Raises
    ------
    ValueError
        If the extension is none of ``.joblib``, ``.pkl``, ``.skops``, or a
        ``.skops`` file is not a skops archive.
    UntrustedTypesError
        If a skops file holds types that are not trusted.
    ImportError
        If a ``.skops`` file is given and skops is not installed.

    See Also
    --------
    save : The reverse.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> from sklearn.preprocessing import FunctionTransformer
    >>> from sklearn_gpcd.persistence import UntrustedTypesError, load, save
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "transformer.skops"
    >>> _ = save(FunctionTransformer(np.linalg.norm), path)
    >>> try:
    ...     load(path)
    ... except UntrustedTypesError as error:
    ...     print(error.types)
    ['numpy.linalg.norm']
    >>> load(path, trusted=["numpy.linalg.norm"]).func is np.linalg.norm
    True
    """
    path = Path(path)
    if _format(path) == "joblib":
        return joblib.load(path)
    sio = _skops()
    extra = [_type_name(t) for t in (trusted or [])]
    try:
        untrusted = sio.get_untrusted_types(file=path)
    except BadZipFile as exc:
        raise ValueError(f"{path} is not a skops file (not a zip archive): {exc}") from exc
    implied = [name for name in untrusted if _implicitly_trusted(name)]
    refused = sorted(set(untrusted) - set(implied) - set(extra))
    if refused:
        raise UntrustedTypesError(path, refused)
    return sio.load(path, trusted=sorted(set(implied) | set(extra)))


def _format(path):
    """``"joblib"`` or ``"skops"`` from the extension of ``path``."""
    suffix = path.suffix.lower()
    if suffix in PICKLE_EXTENSIONS:
        return "joblib"
    if suffix == SKOPS_EXTENSION:
        return "skops"
    raise ValueError(
        f"Cannot tell the format of {str(path)!r} from its extension {suffix!r}: use "
        f"one of {PICKLE_EXTENSIONS + (SKOPS_EXTENSION,)}."
    )


def _skops():
    """Import :mod:`skops.io` or say how to install it."""
    try:
        return importlib.import_module("skops.io")
    except ImportError as exc:
        raise ImportError(
            "Saving or loading .skops files needs the optional dependency skops: "
            "pip install 'sklearn-gpcd[persist]' (or pip install skops), or use a "
            ".joblib file."
        ) from exc


def _type_name(item):
    """Fully qualified name of a type given as a type or as its name."""
    if isinstance(item, str):
        return item
    if isinstance(item, type):
        return f"{item.__module__}.{item.__qualname__}"
    raise TypeError(f"trusted must hold type names (str) or types, got {item!r}.")


def _implicitly_trusted(name):
    """Whether :func:`load` trusts ``name`` without being told.

    Anything in sklearn-gpcd; classes and NumPy ufuncs in the packages of
    ``TRUSTED_PACKAGES``. Only modules of those packages are imported to
    tell a class from a function.
    """
    package = name.split(".", 1)[0]
    if package == "sklearn_gpcd":
        return True
    if package not in TRUSTED_PACKAGES:
        return False
    obj = _resolve(name)
    return isinstance(obj, (type, np.ufunc))


def _resolve(name):
    """The object named ``module.attr[.attr...]``, or None if it does not exist."""
    parts = name.split(".")
    for split in range(len(parts) - 1, 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:split]))
        except ImportError:
            continue
        for attr in parts[split:]:
            obj = getattr(obj, attr, None)
        return obj
    return None
