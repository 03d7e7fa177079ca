"""Generic delimited text files read through a column map."""

from pathlib import Path

from ._text import parse_columns, read_text_table
from ._validation import finalize_recording
from .columns import get_preset, resolve_column_map, split_units


def read_csv(
    path,
    column_map,
    header="infer",
    delimiter=None,
    *,
    n_joints=None,
    units=None,
    time_scale=1.0,
    name=None,
    max_dropped=0.05,
    max_joint_speed=10.0,
    min_samples=2,
):
    """Read a delimited text file into a :class:`Recording`.

    Sampling is kept as logged (no resampling; the UR10e files jitter
    between 2 and 34 ms) and time is not shifted: ``metadata["t0"]`` holds
    the first time stamp. Row cleaning follows
    :mod:`sklearn_gpcd.io._validation`: malformed lines (wrong field count, a
    non-number in a used column, a repeated header), exact duplicates,
    absurd values (``|x| > 1e6``), out-of-order time stamps and kinematic
    glitches are dropped with one :class:`RecordingWarning` when they are at
    most ``max_dropped`` of the rows each, and their line numbers go to
    ``metadata["dropped_rows"]``; more than that, NaN/inf, missing or
    repeated columns or a wrong joint count raise ValueError naming file,
    column and line. Gaps in time (``metadata["gaps"]``) and values that
    look like degrees or milliseconds are reported in the same warning.

    Parameters
    ----------
    path : str or Path
        Text file, comma / semicolon / tab / whitespace delimited.
    column_map : dict or str
        Recording field -> column indices or header names (see
        :mod:`sklearn_gpcd.io.columns`), or a preset name such as
        ``"ur10e_mamedov"`` (layout picked from the field count).
    header : {"infer", True, None}, default="infer"
        Whether the first line holds column names; ``"infer"`` decides from
        its content.
    delimiter : str, default=None
        Field separator; None sniffs it from the first line.
    n_joints : int, default=None
        Joints the robot has; a column map giving another count is an error.
    units : {"A", "Nm"}, default=None
        Unit of the ``current`` columns (``"Nm"`` for torques); None takes
        the column map's ``"units"`` (or the preset's), else ``"A"``.
    time_scale : float, default=1.0
        Factor turning the time column into seconds (``1e-3`` for ms).
    name : str, default=None
        Recording name; the file name when None.
    max_dropped : float, default=0.05
        Largest fraction of rows each cleaning step may drop.
    max_joint_speed : float or None, default=10.0
        Joint speed [rad/s] above which rows count as glitches; None
        disables the glitch filter.
    min_samples : int, default=2
        Fewest valid samples accepted.

    Returns
    -------
    recording : Recording

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from sklearn_gpcd.io import read_csv
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "log.csv"
    >>> _ = path.write_text("t,q,qd,i\\n0.00,0.1,0,1.5\\n0.01,0.1,0,1.6\\n")
    >>> rec = read_csv(path, {"time": "t", "q": "q", "qd": "qd", "current": "i"})
    >>> rec.n_samples, rec.n_joints, float(rec.current[1, 0])
    (2, 1, 1.6)
    """
    source = str(path)
    table = read_text_table(path, header=header, delimiter=delimiter)
    metadata = {"format": "csv", "delimiter": table.delimiter or " ",
                "header": table.names is not None}
    if isinstance(column_map, str):
        preset = get_preset(column_map)
        metadata.update(column_map=preset.name, robot=preset.robot)
        if table.n_fields in preset.ignored:
            metadata["ignored_columns"] = list(preset.ignored[table.n_fields])
        column_map = {**preset.layout(table.n_fields, source), "units": preset.units}
    elif not isinstance(column_map, dict):
        raise TypeError(
            f"column_map must be a dict or a preset name, got {type(column_map).__name__}")
    column_map, map_units = split_units(column_map, source=source)
    units = map_units if units is None else units
    return recording_from_table(
        table, column_map, n_joints=n_joints, units=units, time_scale=time_scale,
        name=Path(path).name if name is None else name, metadata=metadata,
        max_dropped=max_dropped, max_joint_speed=max_joint_speed, min_samples=min_samples)


def recording_from_table(table, column_map, *, n_joints=None, time_scale=1.0, **kwargs):
    """Resolve ``column_map`` on a parsed table and build the recording.

    Shared by :func:`read_csv` and :func:`sklearn_gpcd.io.read_rtde_csv`;
    ``kwargs`` go to the row-cleaning step (units, name, metadata, limits).
    """
    indices, labels = resolve_column_map(column_map, table.n_fields, names=table.names,
                                         source=table.source, n_joints=n_joints)
    flat = [c for key in indices for c in indices[key]]
    flat_labels = [lab for key in indices for lab in labels[key]]
    values, line_numbers, malformed = parse_columns(table, flat, flat_labels)
    columns, start = {}, 0
    for key, cols in indices.items():
        block = values[:, start:start + len(cols)]
        start += len(cols)
        columns[key] = block[:, 0] if key in ("time", "labels") else block
    columns["time"] = columns["time"] * time_scale
    return finalize_recording(
        table.source, columns, line_numbers, column_labels=labels, malformed=malformed,
        n_rows=table.n_rows, kind="line", n_joints=n_joints, **kwargs)
