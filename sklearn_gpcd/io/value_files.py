"""Logs written one value per line, one file per signal (e.g. the Panda logs).

Some robot logs keep each signal in a file of its own with a single number
per line, sample-major: the time file has one line per sample, a joint
signal ``n_joints`` lines per sample (``values.reshape(-1, n_joints)``). The
Franka Emika Panda logs of Gaz et al. (RA-L 2019) are written this way; the
preset ``panda_gaz`` of :data:`~sklearn_gpcd.io.COLUMN_PRESETS` names their
files.
"""

from pathlib import Path

import numpy as np

from ._validation import finalize_recording
from .columns import COLUMN_PRESETS, REQUIRED_FIELDS, get_preset, split_units


def value_files_preset(folder):
    """The preset whose file patterns all match exactly one file of ``folder``.

    Parameters
    ----------
    folder : str or Path

    Returns
    -------
    preset : ColumnPreset or None

    Examples
    --------
    >>> import tempfile, pathlib
    >>> root = pathlib.Path(tempfile.mkdtemp())
    >>> for signal in ("time", "positions", "velocity", "torques"):
    ...     _ = (root / f"log_{signal}.txt").write_text("0.0\\n")
    >>> value_files_preset(root).name
    'panda_gaz'
    """
    folder = Path(folder)
    if not folder.is_dir():
        return None
    for preset in COLUMN_PRESETS.values():
        if preset.files and all(len(list(folder.glob(pattern))) == 1
                                for pattern in preset.files.values()):
            return preset
    return None


def _read_values(path):
    """The numbers of a one-value-per-line file (ValueError naming file and line)."""
    values = []
    with open(path, encoding="utf-8", errors="replace") as handle:
        for number, line in enumerate(handle, start=1):
            text = line.strip()
            if not text or text.startswith("#"):
                continue
            try:
                values.append(float(text))
            except ValueError:
                raise ValueError(f"{path}: line {number} is {text[:40]!r}, expected one "
                                 "number per line") from None
    return np.asarray(values, dtype=float)


def read_value_files(folder, column_map="panda_gaz", *, n_joints=None, units=None,
                     time_scale=1.0, name=None, max_dropped=0.05, max_joint_speed=10.0,
                     min_samples=2):
    """Read a log written one value per line and one file per signal.

    The time file gives the number of samples ``n``; every joint-signal file
    must hold ``n * n_joints`` values, sample-major. Rows are then cleaned
    like every reader's (:func:`~sklearn_gpcd.io.read_csv`), with sample
    numbers (1-based) in the messages.

    Parameters
    ----------
    folder : str or Path
        Folder holding the files (file names in ``column_map`` are relative
        to it).
    column_map : str or dict, default="panda_gaz"
        A preset with file patterns, or a dict field -> file name (fields as
        in :mod:`sklearn_gpcd.io.columns`, ``time``, ``q``, ``qd``,
        ``current`` required) with an optional ``"units"``.
    n_joints : int, default=None
        Joints the robot has; a log with another count (the ``q`` file's
        length over the time file's) is an error. None accepts any.
    units : {"A", "Nm"}, default=None
        What the ``current`` file holds; None takes the map's (else ``"A"``).
    time_scale : float, default=1.0
        Factor turning the time values into seconds.
    name : str, default=None
        Recording name; the folder name when None.
    max_dropped, max_joint_speed, min_samples
        As for :func:`~sklearn_gpcd.io.read_csv`.

    Returns
    -------
    recording : Recording

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> root = pathlib.Path(tempfile.mkdtemp()) / "rbt_log"
    >>> root.mkdir()
    >>> t = np.arange(5) * 0.001
    >>> q = np.outer(t, np.arange(1.0, 8.0))                 # 5 samples x 7 joints
    >>> files = {"time": t, "positions": q, "velocity": q * 0 + np.arange(1.0, 8.0),
    ...          "torques": q + 1.0}
    >>> for signal, values in files.items():
    ...     np.savetxt(root / f"traj_{signal}.txt", values.reshape(-1))
    >>> rec = read_value_files(root)
    >>> rec.n_samples, rec.n_joints, rec.units, rec.metadata["column_map"]
    (5, 7, 'Nm', 'panda_gaz')
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ValueError(f"{folder}: not a folder (one-value-per-line logs are read from the "
                         "folder holding one file per signal)")
    metadata = {"format": "value_files"}
    if isinstance(column_map, str):
        preset = get_preset(column_map)
        if not preset.files:
            raise ValueError(f"column preset {preset.name!r} describes delimited text, not "
                             "one-value-per-line files (use read_csv)")
        files = {}
        for field, pattern in preset.files.items():
            found = sorted(folder.glob(pattern))
            if len(found) != 1:
                raise ValueError(f"{folder}: preset {preset.name!r} needs exactly one file "
                                 f"{pattern} for {field}, found {len(found)}")
            files[field] = found[0]
        metadata.update(column_map=preset.name, robot=preset.robot)
        map_units = preset.units
    elif isinstance(column_map, dict):
        column_map, map_units = split_units(column_map, source=str(folder))
        missing = [f for f in REQUIRED_FIELDS if f not in column_map]
        if missing:
            raise ValueError(f"{folder}: column map lacks required field(s) {missing}")
        files = {field: folder / file for field, file in column_map.items()}
    else:
        raise TypeError(
            f"column_map must be a dict or a preset name, got {type(column_map).__name__}")
    metadata["files"] = {field: path.name for field, path in files.items()}
    units = map_units if units is None else units
    time = _read_values(files["time"]) * time_scale
    n = time.shape[0]
    width = {"labels": 1}
    width["q"] = len(q_values := _read_values(files["q"])) // max(n, 1)
    columns, labels = {"time": time}, {"time": [repr(files["time"].name)]}
    for field, path in files.items():
        if field == "time":
            continue
        values = q_values if field == "q" else _read_values(path)
        per_sample = width.get(field, width["q"])
        if values.shape[0] != n * per_sample or per_sample == 0:
            raise ValueError(
                f"{path}: {values.shape[0]} values, expected {n} samples x {per_sample} "
                f"(the time file {files['time'].name} has {n} lines)")
        columns[field] = values if field == "labels" else values.reshape(n, per_sample)
        labels[field] = ([repr(path.name)] if field == "labels" else
                         [f"{path.name}[{j}]" for j in range(per_sample)])
    return finalize_recording(
        str(folder), columns, np.arange(1, n + 1), column_labels=labels, n_rows=n,
        kind="sample", n_joints=n_joints, units=units,
        name=folder.name if name is None else name, metadata=metadata,
        max_dropped=max_dropped, max_joint_speed=max_joint_speed, min_samples=min_samples)
