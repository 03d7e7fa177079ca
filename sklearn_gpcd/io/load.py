"""One entry point for every recording format: :func:`load_recording`."""

import contextlib
import re
import warnings
from glob import glob, has_magic
from pathlib import Path

from .plausibility import recording_problems
from ._text import decode_text, is_number, sniff_delimiter, split_fields
from ._validation import RecordingWarning
from .columns import UR10E_MAMEDOV
from .npz import read_npz
from .rosbag import ROS2_SUFFIXES, read_rosbag
from .rtde import is_rtde_header, read_rtde_csv
from .table import read_csv
from .value_files import read_value_files, value_files_preset

#: Formats :func:`load_recording` knows.
FORMATS = ("rtde", "csv", "npz", "rosbag", "value_files")
#: File suffixes :func:`load_recordings` collects from a folder.
RECORDING_SUFFIXES = (".csv", ".tsv", ".npz", ".bag")


def _first_line(path, limit=1 << 16):
    with open(path, "rb") as handle:
        raw = handle.read(limit)
    head = decode_text(raw, path)  # empty, binary or non-UTF-8: a clear error here
    for line in head.split("\n"):
        line = line.strip()
        if line and not line.startswith("#"):
            return line
    return ""


def _is_ros2_bag(path):
    return path.is_dir() and ((path / "metadata.yaml").is_file()
                              or any(p.suffix in ROS2_SUFFIXES for p in path.iterdir()))


def detect_format(path):
    """Guess the format of ``path`` from its suffix and first line.

    ``.npz`` -> ``"npz"``; ``.bag``, ``.db3``, ``.mcap`` or a ROS 2 bag
    folder -> ``"rosbag"``; a folder with the files of a one-value-per-line
    preset (``panda_gaz``) -> ``"value_files"``; text whose header names
    ``timestamp`` and ``actual_q_0`` -> ``"rtde"``; any other text ->
    ``"csv"``.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    format : {"rtde", "csv", "npz", "rosbag", "value_files"}

    Examples
    --------
    >>> import tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "a.csv"
    >>> _ = path.write_text("timestamp actual_q_0\\n0.0 0.1\\n")
    >>> detect_format(path)
    'rtde'
    """
    path = Path(path)
    if path.is_dir():
        if _is_ros2_bag(path):
            return "rosbag"
        if value_files_preset(path) is not None:
            return "value_files"
        raise ValueError(f"{path}: a folder, not a recording (use load_recordings for folders)")
    if not path.exists():
        raise ValueError(f"{path}: no such file")
    suffix = path.suffix.lower()
    if suffix == ".npz":
        return "npz"
    if suffix == ".bag" or suffix in ROS2_SUFFIXES:
        return "rosbag"
    line = _first_line(path)
    if is_rtde_header(split_fields(line, sniff_delimiter(line))):
        return "rtde"
    return "csv"


def load_recording(path, format="auto", column_map=None, **kwargs):
    """Load a recording from any supported source.

    ``format="auto"`` dispatches by :func:`detect_format`. A text file is
    read by :func:`read_rtde_csv` when it has an RTDE header and no
    ``column_map`` is given, else by :func:`read_csv`; a headerless numeric
    file with 19, 25 or 31 fields and no ``column_map`` is taken as the UR
    layout ``t, q(6), qd(6), i(6)[, ...]`` of the ``"ur10e_mamedov"`` preset
    and a folder of one-value-per-line files as the preset whose file names
    it has (:func:`~sklearn_gpcd.io.read_value_files`); either guess is said
    once per layout in a :class:`RecordingWarning` with the map it used.

    Parameters
    ----------
    path : str or Path
        File (or ROS 2 bag folder).
    format : {"auto", "rtde", "csv", "npz", "rosbag", "value_files"}, \
default="auto"
        Source format.
    column_map : dict or str, default=None
        Column map or preset name for ``"csv"`` (see
        :mod:`sklearn_gpcd.io.columns`), key map for ``"npz"``.
    **kwargs
        Passed to the reader (``n_joints``, ``max_dropped``, ``topic``, ...).

    Returns
    -------
    recording : Recording

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from sklearn_gpcd.io import load_recording
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "ur.csv"
    >>> row = lambda t: ",".join([str(t)] + ["0.5"] * 6 + ["0.0"] * 6 + ["1.0"] * 6)
    >>> _ = path.write_text(row(0.0) + "\\n" + row(0.01) + "\\n")
    >>> import warnings
    >>> with warnings.catch_warnings(record=True) as guessed:
    ...     warnings.simplefilter("always")
    ...     rec = load_recording(path)
    >>> str(guessed[0].message)[:69]
    'headerless text with 19 fields read with the column map ur10e_mamedov'

    >>> rec.n_joints, rec.metadata["column_map"]
    (6, 'ur10e_mamedov')
    """
    fmt = detect_format(path) if format == "auto" else format
    if fmt not in FORMATS:
        raise ValueError(f"format must be 'auto' or one of {FORMATS}, got {format!r}")
    if fmt == "npz":
        return read_npz(path, key_map=column_map, **kwargs)
    if fmt == "value_files":
        if column_map is None:
            preset = value_files_preset(path)
            column_map = preset.name
            files = ", ".join(f"{k}: {v}" for k, v in preset.files.items())
            _say_guess(f"a folder of one-value-per-line files read with the column map "
                       f"{column_map} ({files}; current in {preset.units})")
        return read_value_files(path, column_map, **kwargs)
    if fmt == "rosbag":
        if column_map is not None:
            raise ValueError(f"{path}: column_map does not apply to ROS bags (use joint_names)")
        return read_rosbag(path, **kwargs)
    if fmt == "rtde" and column_map is None:
        return read_rtde_csv(path, **kwargs)
    if column_map is None:
        column_map = _default_column_map(path)
    return read_csv(path, column_map, **kwargs)


def _default_column_map(path):
    line = _first_line(path)
    if not line:
        raise ValueError(f"{path}: file is empty")
    fields = split_fields(line, sniff_delimiter(line))
    if all(is_number(f) for f in fields) and len(fields) in UR10E_MAMEDOV.layouts:
        layout = UR10E_MAMEDOV.layout(len(fields))
        shown = ", ".join(f"{k}: {_columns(v)}" for k, v in layout.items())
        _say_guess(f"headerless text with {len(fields)} fields read with the column map "
                   f"{UR10E_MAMEDOV.name} ({shown}; current in {UR10E_MAMEDOV.units})")
        return UR10E_MAMEDOV.name
    kind = "headerless" if all(is_number(f) for f in fields) else "non-RTDE header"
    raise ValueError(
        f"{path}: {kind} text with {len(fields)} fields; pass column_map={{'time': ..., "
        "'q': ..., 'qd': ..., 'current': ...} (column indices or names) or a preset name")


def _columns(spec):
    """``range(1, 7)`` -> ``"1-6"``; an index as is."""
    return f"{spec.start}-{spec.stop - 1}" if isinstance(spec, range) else str(spec)


def _say_guess(text):
    """One :class:`RecordingWarning` per guessed layout (the text names no file)."""
    warnings.warn(f"{text}. If that is not the layout, give the map: --column-map on the "
                  "command line, column_map= in Python.", RecordingWarning, stacklevel=4)


def recording_paths(paths):
    """Expand files, folders and glob patterns into a sorted list of sources.

    A folder contributes its ``.csv``, ``.tsv``, ``.npz`` and ``.bag`` files
    and ROS 2 bag folders, recursively, sorted by path (``.txt`` files are
    left out: folders often hold a README.txt; name them explicitly).

    Parameters
    ----------
    paths : str, Path or iterable of them
        Files, folders or glob patterns.

    Returns
    -------
    sources : list of Path

    Examples
    --------
    >>> import tempfile, pathlib
    >>> root = pathlib.Path(tempfile.mkdtemp())
    >>> for n in ("b.csv", "a.csv", "notes.txt"):
    ...     _ = (root / n).write_text("x")
    >>> [p.name for p in recording_paths(root)]
    ['a.csv', 'b.csv']
    """
    if isinstance(paths, (str, Path)):
        paths = [paths]
    found = []
    for item in paths:
        item = Path(item)
        if has_magic(str(item)) and not item.exists():
            found.extend(Path(p) for p in sorted(glob(str(item), recursive=True)))
            continue
        if item.is_dir() and not _is_ros2_bag(item) and value_files_preset(item) is None:
            bags = sorted(p.parent for p in item.rglob("metadata.yaml"))
            files = sorted(p for p in item.rglob("*") if p.suffix.lower() in RECORDING_SUFFIXES
                           and p.is_file() and not any(b in p.parents for b in bags))
            found.extend(sorted(files + bags))
        else:
            found.append(item)
    return found


def load_recordings(paths, format="auto", column_map=None, *, accept=None, progress=None,
                    **kwargs):
    """Load many recordings with :func:`load_recording`.

    Parameters
    ----------
    paths : str, Path or iterable of them
        Files, folders (searched recursively, see :func:`recording_paths`)
        or glob patterns.
    format, column_map, **kwargs
        As for :func:`load_recording`, applied to every source.
    accept : collection of str, default=None
        None only warns about suspect recordings (the readers'
        :class:`RecordingWarning`). Otherwise each problem that
        :func:`~sklearn_gpcd.io.recording_problems` finds (``"degrees"``,
        ``"units"``, ``"short"``) is a ValueError naming the file, unless its
        kind is in ``accept`` (``gpcd --units-confirmed`` accepts degrees and
        units, ``--allow-short`` short recordings); the file's warnings are
        then left to that error, which says it all.
    progress : callable, default=None
        ``progress(label, total)`` returning an object whose ``update()`` is
        called after each source (e.g. a progress bar).

    Returns
    -------
    recordings : list of Recording
        In sorted path order.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording, load_recordings, write_rtde_csv
    >>> root = pathlib.Path(tempfile.mkdtemp())
    >>> rec = Recording(time=[0.0, 0.01], q=np.zeros((2, 6)), qd=np.zeros((2, 6)),
    ...                 current=np.ones((2, 6)))
    >>> _ = write_rtde_csv(rec, root / "a.csv"); _ = write_rtde_csv(rec, root / "b.csv")
    >>> [r.name for r in load_recordings(root)]
    ['a.csv', 'b.csv']
    """
    sources = recording_paths(paths)
    if not sources:
        raise ValueError(f"no recordings found in {paths!r}")
    bar = progress("reading recordings", len(sources)) if progress is not None else None
    recordings, said = [], set()
    for path in sources:
        if kwargs.get("time_scale", 1.0) != 1.0 and detect_format(path) in ("rtde", "rosbag"):
            raise ValueError(f"{path}: time_scale (--time-scale) applies to CSV, NPZ and "
                             "one-value-per-line logs only")
        with (warnings.catch_warnings(record=True) if accept is not None
              else contextlib.nullcontext()) as caught:
            if accept is not None:  # said by the error, if there is one
                warnings.simplefilter("always")
            rec = load_recording(path, format=format, column_map=column_map, **kwargs)
        if accept is not None:
            check_problems(path, rec, accept)
        for caught_warning in caught or ():
            if str(caught_warning.message) not in said:  # a guessed layout: once
                said.add(str(caught_warning.message))
                warnings.warn(caught_warning.message, caught_warning.category, stacklevel=2)
        recordings.append(rec)
        if bar is not None:
            bar.update()
    return recordings


def check_problems(path, recording, accept):
    """Raise the first problem :func:`recording_problems` finds whose kind is
    not in ``accept``, naming ``path`` and the option that accepts it."""
    for kind, note in recording_problems(recording):
        if kind not in accept:
            scale = re.search(r"time_scale=(\S+?)\)", note)
            fix = f"--time-scale {scale[1]} (time_scale=), " if scale else ""
            flag = "--allow-short" if kind == "short" else "--units-confirmed"
            raise ValueError(f"{path}: {note} Fix it ({fix}or convert the file), or accept "
                             f"it as it is: {flag} (accept=[{kind!r}] in Python)")
