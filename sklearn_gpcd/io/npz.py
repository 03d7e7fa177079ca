"""NumPy ``.npz`` archives read through a key map."""

import zipfile
from numbers import Integral
from pathlib import Path

import numpy as np

from ._text import check_file
from ._validation import finalize_recording
from .columns import FIELDS, REQUIRED_FIELDS, SCALAR_FIELDS


def read_npz(
    path,
    key_map=None,
    *,
    n_joints=None,
    units="A",
    time_scale=1.0,
    name=None,
    max_dropped=0.05,
    max_joint_speed=10.0,
    min_samples=2,
):
    """Read a ``.npz`` archive into a :class:`Recording`.

    Rows are cleaned by the same rules as :func:`read_csv` (out-of-order
    time stamps and kinematic glitches dropped with one
    :class:`RecordingWarning`, NaN/inf an error); messages count rows from 0.

    Parameters
    ----------
    path : str or Path
        Archive written by :func:`numpy.savez` (no pickled objects).
    key_map : dict, default=None
        Recording field -> archive key, or ``(key, columns)`` to take columns
        (an index, a range or a list) of a 2-D array, e.g.
        ``{"time": ("data", 0), "q": ("data", range(1, 7)), ...}``. None maps
        every field to the key of the same name (``time``, ``q``, ``qd``,
        ``current``, ``target_current``, ...) when present.
    n_joints : int, default=None
        Joints the robot has; another count is an error.
    units : str, default="A"
        Unit of ``current``.
    time_scale : float, default=1.0
        Factor turning the time values into seconds.
    name : str, default=None
        Recording name; the file name when None.
    max_dropped, max_joint_speed, min_samples
        As for :func:`~sklearn_gpcd.io.read_csv`.

    Returns
    -------
    recording : Recording

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> from sklearn_gpcd.io import read_npz
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "log.npz"
    >>> np.savez(path, time=[0.0, 0.01, 0.02], q=np.zeros((3, 2)),
    ...          qd=np.zeros((3, 2)), current=np.ones((3, 2)))
    >>> read_npz(path).n_joints
    2
    """
    source = str(path)
    check_file(Path(path))
    try:
        _check_sizes(source, path)
        with np.load(path, allow_pickle=False) as archive:
            arrays = {key: archive[key] for key in archive.files}
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
        raise ValueError(f"{source}: not a readable .npz archive ({exc})") from None
    if not arrays:
        raise ValueError(f"{source}: file is empty (no arrays)")
    if key_map is None:
        key_map = {f: f for f in FIELDS if f in arrays}
    missing = [f for f in REQUIRED_FIELDS if key_map.get(f) is None]
    if missing:
        raise ValueError(
            f"{source}: key map lacks required field(s) {missing}; the archive holds "
            f"{sorted(arrays)}"
        )
    columns, labels = {}, {}
    for field, spec in key_map.items():
        if spec is None:
            continue
        if field not in FIELDS:
            raise ValueError(f"{source}: key map names unknown field {field!r}; valid: {FIELDS}")
        columns[field], labels[field] = _take(source, arrays, field, spec)
    n = columns["time"].shape[0]
    for field, values in columns.items():
        if values.shape[0] != n:
            spec = key_map[field]
            key = spec[0] if isinstance(spec, tuple) else spec
            raise ValueError(
                f"{source}: key {key!r} (for {field}) has {values.shape[0]} rows, time has "
                f"{n}; every array needs one row per sample")
    if n == 0:
        raise ValueError(f"{source}: file is empty (0 rows)")
    columns["time"] = columns["time"] * time_scale
    return finalize_recording(
        source, columns, np.arange(n), column_labels=labels, kind="row", n_joints=n_joints,
        units=units, name=Path(path).name if name is None else name,
        metadata={"format": "npz", "key_map": {k: v for k, v in key_map.items()}},
        max_dropped=max_dropped, max_joint_speed=max_joint_speed, min_samples=min_samples)


#: Largest ratio of uncompressed to compressed size deflate can reach (about 1032:1).
MAX_DEFLATE_RATIO = 1100


def npy_header(stream):
    """Shape, dtype and length of the header of the ``.npy`` data ``stream`` starts with.

    Reads the header only: nothing of the size it claims is allocated.

    Parameters
    ----------
    stream : file-like
        Positioned at the start of ``.npy`` data (e.g. a zip member).

    Returns
    -------
    shape : tuple of int
    dtype : numpy.dtype
    header_bytes : int
        Where the array's data starts.

    Examples
    --------
    >>> import io
    >>> import numpy as np
    >>> data = io.BytesIO()
    >>> np.save(data, np.zeros((2, 3)))
    >>> _ = data.seek(0)
    >>> npy_header(data)
    ((2, 3), dtype('float64'), 128)
    """
    version = np.lib.format.read_magic(stream)
    read = (np.lib.format.read_array_header_1_0 if version == (1, 0)
            else np.lib.format.read_array_header_2_0)
    shape, _, dtype = read(stream)
    return shape, dtype, stream.tell()


def _check_sizes(source, path):
    """Refuse arrays whose header claims more data than the archive holds.

    Reads only the zip directory and each ``.npy`` header, before NumPy
    allocates the array the header describes: a header claiming 1e9 rows
    in a small file is a ValueError, not a 45 GiB allocation.
    """
    size = Path(path).stat().st_size
    with zipfile.ZipFile(path) as archive:
        for info in archive.infolist():
            if not info.filename.endswith(".npy"):
                continue
            key = info.filename[:-4]
            if info.compress_size > size or (
                    info.file_size > MAX_DEFLATE_RATIO * info.compress_size + 1024):
                raise ValueError(f"{source}: key {key!r} claims {info.file_size} bytes, more "
                                 f"than a file of {size} bytes can hold")
            with archive.open(info) as member:
                shape, dtype, header = npy_header(member)
            claimed = int(np.prod(shape, dtype=object)) * dtype.itemsize
            if claimed > info.file_size - header:
                rows = f"{shape[0]} rows, " if shape else ""
                raise ValueError(
                    f"{source}: key {key!r} claims shape {shape} ({rows}{claimed} bytes) but "
                    f"holds {info.file_size - header} bytes; the file is truncated or forged")


def _take(source, arrays, field, spec):
    key, cols = (spec if isinstance(spec, tuple) else (spec, None))
    if key not in arrays:
        raise ValueError(
            f"{source}: missing key {key!r} (for {field}); the archive holds {sorted(arrays)}")
    values = arrays[key]
    if not np.issubdtype(values.dtype, np.number) and values.dtype != bool:
        raise ValueError(
            f"{source}: key {key!r} (for {field}) holds {values.dtype} data, not numbers")
    values = values.astype(float)
    if values.ndim == 0 or values.ndim > 2:
        raise ValueError(
            f"{source}: key {key!r} (for {field}) must be 1-D or 2-D, got shape {values.shape}")
    if cols is not None:
        if values.ndim != 2:
            raise ValueError(f"{source}: key {key!r} is 1-D; cannot take columns {cols!r}")
        cols = [int(cols)] if isinstance(cols, Integral) else [int(c) for c in cols]
        width = values.shape[1]
        bad = [c for c in cols if not -width <= c < width]
        if bad:
            raise ValueError(
                f"{source}: key {key!r} has {width} columns; missing column(s) {bad} "
                f"(for {field})")
        values = values[:, cols]
        names = [f"{key!r}[:, {c}]" for c in cols]
    else:
        names = ([f"{key!r}[:, {c}]" for c in range(values.shape[1])] if values.ndim == 2
                 else [repr(key)])
    if field in SCALAR_FIELDS:
        if values.ndim == 2 and values.shape[1] != 1:
            raise ValueError(
                f"{source}: {field} needs one column, {key!r} gives {values.shape[1]}")
        return values.reshape(-1), names
    return (values if values.ndim == 2 else values[:, None]), names
