"""Save and load fitted estimators with joblib (pickle) or skops.

The file extension picks the format:

- ``.joblib`` or ``.pkl``: :func:`joblib.dump` / :func:`joblib.load`. Fast
  and complete, but a pickle runs any code it carries when it is loaded:
  :func:`load` refuses it (:class:`UntrustedPickleError`) unless told
  ``trust_pickle=True`` (``gpcd ... --trust-pickle``).
- ``.skops``: :func:`skops.io.dump` / :func:`skops.io.load` (optional
  dependency, ``pip install "sklearn-gpcd[persist]"``). The file is a zip
  archive of JSON and ``.npy`` entries; loading instantiates only the types
  on an explicit allow-list (see :func:`load` and :func:`trusted_types`):
  no function, and no module is imported to decide what is trusted.

Every estimator of the package records the sklearn-gpcd and scikit-learn
versions in its saved state and warns (:class:`GPCDVersionWarning`,
:class:`~sklearn.exceptions.InconsistentVersionWarning`) when it is loaded
into other versions (see :class:`sklearn_gpcd._persistence.VersionedStateMixin`).
"""

import importlib
import json
import math
import pkgutil
import zipfile
from functools import lru_cache
from pathlib import Path

import joblib

from ._persistence import GPCDVersionWarning
from .io.npz import npy_header

__all__ = ["GPCDVersionWarning", "MalformedFileError", "UntrustedPickleError",
           "UntrustedTypesError", "load", "save", "trusted_types"]

#: Extensions saved and loaded with joblib (pickle).
PICKLE_EXTENSIONS = (".joblib", ".pkl")
#: Extension saved and loaded with skops.
SKOPS_EXTENSION = ".skops"
#: Subpackages of sklearn-gpcd whose classes a skops file may hold (estimators,
#: kernels, transformers, robots and the plain state objects they keep). Never
#: the CLI, the readers / RTDE client of ``io`` or any ``__main__`` module.
TRUSTED_SUBPACKAGES = ("gp", "kernels", "features", "dynamics", "detection", "robots",
                       "diagnosis")
#: scikit-learn / NumPy classes the package's estimators hold that skops does not
#: trust by default: scikit-learn's GP kernels (the building blocks of ours).
TRUSTED_NAMES = tuple(
    f"sklearn.gaussian_process.kernels.{name}" for name in (
        "CompoundKernel", "ConstantKernel", "DotProduct", "ExpSineSquared",
        "Exponentiation", "Matern", "PairwiseKernel", "Product", "RBF",
        "RationalQuadratic", "Sum", "WhiteKernel"))

#: Largest file :func:`load` opens [bytes] (checked before reading it).
MAX_FILE_BYTES = 1 << 30
#: Largest unpacked size of a skops archive [bytes]: the sum of its members'
#: sizes (the budget is ``min(MAX_UNPACKED_BYTES, max(64 MiB, MAX_UNPACK_RATIO x
#: the file's size))``, checked on the archive's directory before anything is
#: decompressed; zipfile never unpacks a member beyond its declared size).
MAX_UNPACKED_BYTES = 1 << 30
#: Largest ratio of unpacked to packed size of a skops archive beyond 64 MiB.
MAX_UNPACK_RATIO = 50
#: skops loaders a trusted class of the package may be rebuilt with: from its
#: saved state (``cls.__new__`` then ``__setstate__``), or the class itself.
#: Never a call of the class with arguments from the file (``ReduceNode`` /
#: ``ConstructorFromReduceNode``).
STATE_LOADERS = ("ObjectNode", "TypeNode")


class MalformedFileError(ValueError):
    """A model or detector file that cannot be loaded as it is: damaged,
    truncated, too large, or holding values a detector must not run with.

    One line: the file, what is wrong (the member or the field) and, when
    the caller knows it, the command that writes the file again.

    Parameters
    ----------
    path : str
        The file.
    reason : str
        What is wrong, in words.
    fix : str, default=None
        How to get a good file (e.g. the command that rebuilds it).

    Attributes
    ----------
    path, reason, fix : str

    Examples
    --------
    >>> from sklearn_gpcd.persistence import MalformedFileError
    >>> print(MalformedFileError("detector.skops", "field thresholds_ holds NaN",
    ...                          fix="rebuild it with gpcd calibrate"))
    detector.skops: field thresholds_ holds NaN; rebuild it with gpcd calibrate
    """

    def __init__(self, path, reason, fix=None):
        self.path, self.reason, self.fix = str(path), " ".join(str(reason).split()), fix
        sep = " " if self.reason.startswith("is ") else ": "  # "FILE is not ..."
        super().__init__(f"{self.path}{sep}{self.reason}" + (f"; {fix}" if fix else ""))


class UntrustedPickleError(ValueError):
    """A ``.joblib`` / ``.pkl`` file was given to :func:`load` without ``trust_pickle``.

    A pickle runs any code it carries while it is loaded, before anything can
    check what it holds; it is loaded only when the caller vouches for its
    source.

    Parameters
    ----------
    path : str
        The file.

    Attributes
    ----------
    path : str

    Examples
    --------
    >>> from sklearn_gpcd.persistence import UntrustedPickleError
    >>> print(UntrustedPickleError("detector.joblib"))  # doctest: +ELLIPSIS
    detector.joblib is a pickle: loading it runs any code it carries, ...
    """

    def __init__(self, path):
        self.path = str(path)
        super().__init__(
            f"{self.path} is a pickle: loading it runs any code it carries, so it is "
            "loaded only from a source you trust: pass trust_pickle=True (gpcd: "
            "--trust-pickle), or save it as .skops")


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
    ...     copy = load(save(gp, folder / name), trust_pickle=True)  # our own pickle
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


def load(path, trusted=None, *, trust_pickle=False):
    """Load an estimator written by :func:`save` (or by joblib / skops).

    A ``.joblib`` / ``.pkl`` file is a pickle, which runs any code it carries
    while it is loaded: it is refused with :class:`UntrustedPickleError`
    unless ``trust_pickle=True`` says that you trust its source (``trusted``
    does not apply to it).

    A ``.skops`` file is first audited, by name only (no module named in the
    file is imported to decide). These types are trusted:

    - those skops trusts by default (builtins, NumPy arrays and ufuncs,
      scikit-learn estimators, ...);
    - the classes of :func:`trusted_types`: sklearn-gpcd's own estimators,
      kernels, transformers, robots and the state objects they hold, and
      scikit-learn's GP kernels. No function is trusted (a function can be
      called with the estimator's data), nor any other class of NumPy,
      SciPy or scikit-learn;

    anything else (e.g. your own feature function or transformer) must be
    listed in ``trusted``, or :class:`UntrustedTypesError` is raised listing
    it. Inspect that list before passing it: an untrusted type may run its
    code when the estimator is loaded or used.

    Parameters
    ----------
    path : str or path-like
        File written by :func:`save`; the extension gives the format.
    trusted : list of str or type, default=None
        For skops files: further types to trust, by fully qualified name as
        listed by :class:`UntrustedTypesError` (or
        :func:`skops.io.get_untrusted_types`), or as the types themselves.
    trust_pickle : bool, default=False
        Load a ``.joblib`` / ``.pkl`` file (a pickle): only for a file from a
        source you trust.

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
    UntrustedPickleError
        If a ``.joblib`` / ``.pkl`` file is given without ``trust_pickle=True``.
    UntrustedTypesError
        If a skops file holds types that are not trusted.
    MalformedFileError
        If the file is larger than ``MAX_FILE_BYTES``, is no archive skops
        wrote (damaged, truncated, a schema that is not skops', an array
        missing or whose header does not match its data, more than the
        unpacking budget), would build a trusted class by calling it with
        arguments from the file, or cannot be rebuilt.
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
    >>> pickled = save(FunctionTransformer(np.sin), path.with_suffix(".joblib"))
    >>> try:
    ...     load(pickled)
    ... except UntrustedPickleError as error:
    ...     print("refused")
    refused
    >>> load(pickled, trust_pickle=True).func is np.sin
    True
    """
    path = Path(path)
    kind = _format(path)
    if kind == "joblib" and not trust_pickle:
        raise UntrustedPickleError(path)
    _check_size(path)
    if kind == "joblib":
        return _rebuild(path, joblib.load, path)
    sio = _skops()
    extra = [_type_name(t) for t in (trusted or [])]
    _check_archive(path)
    untrusted = _rebuild(path, sio.get_untrusted_types, file=path)
    allowed = trusted_types()
    implied = [name for name in untrusted if name in allowed]
    refused = sorted(set(untrusted) - set(implied) - set(extra))
    if refused:
        raise UntrustedTypesError(path, refused)
    return _rebuild(path, sio.load, path, trusted=sorted(set(implied) | set(extra)))


def _rebuild(path, function, *args, **kwargs):
    """``function(*args, **kwargs)``; any failure of a checked file is a
    :class:`MalformedFileError` (one line), never a traceback."""
    try:
        return function(*args, **kwargs)
    except (MalformedFileError, UntrustedTypesError, MemoryError):
        raise
    except Exception as exc:  # noqa: BLE001 -- whatever the file makes the loader raise
        raise MalformedFileError(path, f"cannot be rebuilt from the file "
                                 f"({type(exc).__name__}: {_first_line(exc)})") from None


def _first_line(exc):
    text = " ".join(str(exc).split()) or "no message"
    return text if len(text) <= 200 else text[:197] + "..."


def _check_size(path):
    """The file exists and is at most ``MAX_FILE_BYTES`` (before anything is read)."""
    size = path.stat().st_size
    if size > MAX_FILE_BYTES:
        raise MalformedFileError(path, f"{size / 2**20:.0f} MiB, more than the "
                                 f"{MAX_FILE_BYTES / 2**20:.0f} MiB a model or detector "
                                 "file may have")


def _check_archive(path):
    """A skops archive as skops writes it, checked on its directory and headers
    before skops reads it: the unpacking budget, ``schema.json`` a skops
    schema (a JSON object), every array it names present with a header that
    matches its size, and no trusted class built by a call."""
    try:
        archive = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise MalformedFileError(path, "is not a skops file (not the zip archive skops "
                                 "writes: the file was damaged or overwritten; "
                                 f"{_first_line(exc)})") from None
    with archive:
        members = {info.filename: info for info in archive.infolist()}
        unpacked = sum(info.file_size for info in members.values())
        budget = min(MAX_UNPACKED_BYTES, max(64 << 20, MAX_UNPACK_RATIO * path.stat().st_size))
        if unpacked > budget:
            raise MalformedFileError(path, f"unpacks to {unpacked / 2**20:.0f} MiB, more than "
                                     f"the {budget / 2**20:.0f} MiB budget for a file of "
                                     f"{path.stat().st_size / 2**20:.1f} MiB (a zip bomb?)")
        if "schema.json" not in members:
            raise MalformedFileError(path, "no schema.json in the archive (not a skops file)")
        schema = _rebuild(path, lambda: json.loads(archive.read("schema.json")))
        if not (isinstance(schema, dict) and "__loader__" in schema):
            raise MalformedFileError(path, "schema.json is not a skops schema (a JSON "
                                     f"{type(schema).__name__}, not an object with __loader__)")
        for name in _schema_files(path, schema):
            if name not in members:
                raise MalformedFileError(path, f"array {name} named in schema.json is missing "
                                         "from the archive")
            _check_npy(path, archive, members[name])


def _schema_files(path, schema):
    """Names of the archive members the schema's nodes read; refuses a trusted
    class of the package built any other way than from its saved state."""
    allowed, files, stack = trusted_types(), [], [(schema, "root")]
    while stack:
        node, where = stack.pop()
        if isinstance(node, list):
            stack.extend((value, where) for value in node)
            continue
        if not isinstance(node, dict):
            continue
        name = f"{node.get('__module__')}.{node.get('__class__')}"
        if name in allowed and node.get("__loader__") not in STATE_LOADERS:
            raise MalformedFileError(path, f"{name} would be built by calling it with "
                                     f"arguments from the file ({node.get('__loader__')}); "
                                     "only its saved state is accepted")
        if isinstance(node.get("file"), str):
            files.append(node["file"])
        stack.extend((value, where) for value in node.values()
                     if isinstance(value, (dict, list)))
    return files


def _check_npy(path, archive, info):
    """The ``.npy`` member's header: a plain dtype and a shape whose size is the member's."""
    try:
        with archive.open(info) as stream:
            shape, dtype, header = npy_header(stream)
    except Exception as exc:  # noqa: BLE001 -- a damaged header, in any way
        raise MalformedFileError(path, f"array {info.filename}: no valid .npy header "
                                 f"({_first_line(exc)})") from None
    if dtype.hasobject:
        raise MalformedFileError(path, f"array {info.filename} holds Python objects")
    claimed = math.prod(shape) * dtype.itemsize
    if claimed != info.file_size - header:
        raise MalformedFileError(path, f"array {info.filename}: its header claims {shape} "
                                 f"{dtype} ({claimed:,} bytes) but it holds "
                                 f"{info.file_size - header:,} bytes")


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


def trusted_types():
    """Names of the classes :func:`load` trusts in a skops file beyond skops' own.

    The classes defined in sklearn-gpcd's subpackages ``TRUSTED_SUBPACKAGES``
    (estimators, kernels, transformers, robots and the plain state objects
    they hold; exceptions and warnings left out) and ``TRUSTED_NAMES``
    (scikit-learn's GP kernels). Only the package's own modules are imported
    to list them, never a ``__main__`` module; a name in a file is only
    compared with this set.

    Returns
    -------
    names : frozenset of str
        Fully qualified names (``module.QualName``).

    Examples
    --------
    >>> from sklearn_gpcd.persistence import trusted_types
    >>> names = trusted_types()
    >>> "sklearn_gpcd.detection.detector.CollisionDetector" in names
    True
    >>> "sklearn_gpcd.cli.main" in names or "numpy.memmap" in names
    False
    """
    return _trusted_types()


@lru_cache(maxsize=1)
def _trusted_types():
    names = set(TRUSTED_NAMES)
    for sub in TRUSTED_SUBPACKAGES:
        package = importlib.import_module(f"{__package__}.{sub}")
        modules = [package.__name__] + [
            info.name for info in pkgutil.walk_packages(package.__path__, package.__name__ + ".")
            if info.name.rsplit(".", 1)[-1] != "__main__"]
        for name in modules:
            try:
                module = importlib.import_module(name)
            except ImportError:  # an optional dependency (e.g. matplotlib) is missing
                continue
            for obj in vars(module).values():
                if (isinstance(obj, type) and obj.__module__ == name
                        and not issubclass(obj, BaseException)):
                    names.add(f"{obj.__module__}.{obj.__qualname__}")
    return frozenset(names)
