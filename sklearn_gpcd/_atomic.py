"""Atomic file writes: the old file stays whole until the new one is complete.

A detector, model or report is written to a temporary file in the same folder
(so that the rename stays on one file system), flushed, ``fsync``-ed and then
renamed over the destination (:func:`os.replace`, atomic on POSIX and
Windows). A write that fails half-way (disk full, a file-size limit, an
interrupt) removes the temporary file and leaves the previous file as it was;
the error says so in one line.
"""

import os
import tempfile
from pathlib import Path


def atomic_write(path, write, mode="wb"):
    """Write ``path`` through ``write(handle)`` into a temporary file, then rename.

    Parameters
    ----------
    path : str or path-like
        Destination.
    write : callable
        Called with the open temporary file (binary with ``mode="wb"``, text
        with ``mode="w"``); writes the whole content.
    mode : {"wb", "w"}, default="wb"

    Returns
    -------
    path : Path

    Raises
    ------
    OSError
        When the content cannot be written (one line naming the file and
        saying that the previous file is intact).

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from sklearn_gpcd._atomic import atomic_write
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "report.json"
    >>> _ = path.write_text("old")
    >>> def fail(handle):
    ...     handle.write("{")
    ...     raise OSError(28, "No space left on device")
    >>> atomic_write(path, fail, mode="w")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    OSError: ...report.json: not written (No space left on device); the previous file is intact
    >>> path.read_text()
    'old'
    >>> atomic_write(path, lambda handle: handle.write("new"), mode="w").read_text()
    'new'
    """
    path = Path(path)
    existed = path.exists()
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part",
                                         dir=path.parent)
    try:
        with os.fdopen(handle, mode, **({"encoding": "utf-8"} if "b" not in mode else {})) \
                as stream:
            write(stream)
            stream.flush()
            os.fsync(stream.fileno())
        os.chmod(temporary, 0o666 & ~_umask())
        os.replace(temporary, path)
    except BaseException as exc:
        try:
            os.unlink(temporary)
        except OSError:
            pass
        if isinstance(exc, OSError):
            kept = "the previous file is intact" if existed else "no file was left"
            raise OSError(f"{path}: not written ({exc.strerror or exc}); {kept}") from None
        raise
    return path


def _umask():
    mask = os.umask(0)
    os.umask(mask)
    return mask
