"""UR RTDE CSV recordings: ur_rtde's ``startFileRecording`` and UR's ``record.py``.

Both write one header line of RTDE output names, vector outputs expanded to
``name_0 .. name_5`` (``timestamp, target_q_0, ..., actual_q_0, ...,
actual_current_5, ...``), then one line per controller cycle:

- ur_rtde (``RTDEReceiveInterface.startFileRecording``): comma-separated,
  fixed 6 decimals, every output of the receive recipe in the order
  ``timestamp, target_q, target_qd, target_qdd, target_current,
  target_moment, actual_q, actual_qd, actual_current, ...``;
- UR's RTDE client ``examples/record.py`` (``rtde.csv_writer.CSVWriter``):
  space-separated by default, Python ``str`` of each value, the outputs of
  the recipe in ``record_configuration.xml``.

The reader takes any column order and ignores outputs it does not use
(TCP pose, modes, bits, ...). Recording fields come from

=============== ===========================================
Recording       RTDE output
=============== ===========================================
time            ``timestamp`` [s]
q, qd           ``actual_q``, ``actual_qd``
current         ``actual_current`` [A] or, when absent,
                ``actual_current_as_torque`` [Nm] (PolyScope >= 5.23)
target_q/qd/qdd ``target_q``, ``target_qd``, ``target_qdd``
target_current  ``target_current`` [A]
target_torque   ``target_moment`` [Nm]
qdd             ``actual_qdd`` (extension, not an RTDE output)
labels          ``collision_label`` (extension: 0 free, k > 0 contact k)
=============== ===========================================

:func:`write_rtde_csv` writes the same layout (the two extension columns
only when the recording has them) with ``repr`` precision, so a written
file reads back to an equal recording. With ``robot_comment=True`` (as
``gpcd simulate`` writes) a first comment line ``# robot: NAME`` keeps
``metadata["robot"]``, and :func:`read_rtde_csv` reads it back, so that
``gpcd`` commands need no ``--robot`` for such files; by default the file
starts with the header line, as ur_rtde's do.
"""

from pathlib import Path

import numpy as np

from ._text import read_text_table
from .recording import Recording
from .table import recording_from_table

#: Recording field -> RTDE output name, in ur_rtde's recording order.
RTDE_OUTPUTS = {
    "target_q": "target_q",
    "target_qd": "target_qd",
    "target_qdd": "target_qdd",
    "target_current": "target_current",
    "target_torque": "target_moment",
    "q": "actual_q",
    "qd": "actual_qd",
    "current": "actual_current",
    "qdd": "actual_qdd",
}
#: RTDE output holding joint torques computed from currents (PolyScope >= 5.23).
TORQUE_OUTPUT = "actual_current_as_torque"
#: Extra column carrying :attr:`Recording.labels`.
LABEL_COLUMN = "collision_label"
TIME_COLUMN = "timestamp"


def is_rtde_header(names):
    """True for a header naming ``timestamp`` and ``actual_q_0``.

    Parameters
    ----------
    names : list of str or None
        Header fields.

    Returns
    -------
    is_rtde : bool

    Examples
    --------
    >>> is_rtde_header(["timestamp", "actual_q_0", "actual_q_1"])
    True
    >>> is_rtde_header(["t", "q0"])
    False
    """
    names = set(names or ())
    return TIME_COLUMN in names and "actual_q_0" in names


def read_rtde_csv(
    path,
    *,
    n_joints=None,
    delimiter=None,
    current="auto",
    name=None,
    max_dropped=0.05,
    max_joint_speed=10.0,
    min_samples=2,
):
    """Read a UR RTDE CSV recording (ur_rtde or UR ``record.py``).

    Comma, semicolon, tab and space delimiters are detected from the header.
    Rows are cleaned as in :func:`read_csv` (one :class:`RecordingWarning`
    for dropped rows, their line numbers in ``metadata["dropped_rows"]``).

    Parameters
    ----------
    path : str or Path
        CSV file with an RTDE header line.
    n_joints : int, default=None
        Joints the robot has (6 for a UR); None counts the ``actual_q_*``
        columns. A missing joint column is a ValueError naming it.
    delimiter : str, default=None
        Field separator; None sniffs it.
    current : {"auto", "actual_current", "actual_current_as_torque"}, default="auto"
        RTDE output read as ``current``; ``"auto"`` prefers motor currents
        [A] and falls back to torques [Nm]. Sets ``recording.units``.
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
    >>> from sklearn_gpcd.io import Recording, read_rtde_csv, write_rtde_csv
    >>> t = np.arange(3) * 0.002
    >>> rec = Recording(time=t, q=np.full((3, 6), 0.1), qd=np.zeros((3, 6)),
    ...                 current=np.ones((3, 6)))
    >>> path = write_rtde_csv(rec, pathlib.Path(tempfile.mkdtemp()) / "rtde.csv")
    >>> path.read_text().splitlines()[0][:31]
    'timestamp,actual_q_0,actual_q_1'
    >>> read_rtde_csv(path).equals(rec)
    True
    """
    source = str(path)
    table = read_text_table(path, header="infer", delimiter=delimiter)
    names = table.names
    if names is None:
        raise ValueError(
            f"{source}: no header line; a UR RTDE CSV starts with the output names "
            "(timestamp, actual_q_0, ...). For headerless files use read_csv with a column_map")
    present = set(names)
    if current == "auto":
        current = TORQUE_OUTPUT if ("actual_current_0" not in present
                                    and f"{TORQUE_OUTPUT}_0" in present) else "actual_current"
    elif current not in ("actual_current", TORQUE_OUTPUT):
        raise ValueError(
            f"current must be 'auto', 'actual_current' or '{TORQUE_OUTPUT}', got {current!r}")
    column_map = {"time": TIME_COLUMN, "q": "actual_q", "qd": "actual_qd", "current": current}
    for field, output in RTDE_OUTPUTS.items():
        if field not in column_map and f"{output}_0" in present:
            column_map[field] = output
    if LABEL_COLUMN in present:
        column_map["labels"] = LABEL_COLUMN
    metadata = {"format": "rtde_csv", "delimiter": table.delimiter or " ", "header": True}
    robot = _robot_comment(path)
    if robot:
        metadata["robot"] = robot
    return recording_from_table(
        table, column_map, n_joints=n_joints,
        units="Nm" if current == TORQUE_OUTPUT else "A",
        name=Path(path).name if name is None else name, metadata=metadata,
        max_dropped=max_dropped, max_joint_speed=max_joint_speed, min_samples=min_samples)


def _robot_comment(path, max_lines=20):
    """The robot named by a leading ``# robot: NAME`` comment line, or None."""
    with open(path, "rb") as handle:
        for _, raw in zip(range(max_lines), handle):
            line = raw.decode("utf-8", "replace").strip()
            if not line:
                continue
            if not line.startswith("#"):
                return None
            key, _, value = line.lstrip("#").partition(":")
            if key.strip().lower() == "robot" and value.strip():
                return value.strip()
    return None


def rtde_columns(recording):
    """Header names and value blocks :func:`write_rtde_csv` writes.

    Parameters
    ----------
    recording : Recording

    Returns
    -------
    names : list of str
    blocks : list of ndarray of shape (n_samples, k)

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> rec = Recording(time=[0.0, 1.0], q=np.zeros((2, 1)), qd=np.zeros((2, 1)),
    ...                 current=np.zeros((2, 1)), labels=[0, 1])
    >>> rtde_columns(rec)[0]
    ['timestamp', 'actual_q_0', 'actual_qd_0', 'actual_current_0', 'collision_label']
    """
    if recording.units not in ("A", "Nm"):
        raise ValueError(
            f"Recording {recording.name!r}: units {recording.units!r} has no RTDE output "
            "(use 'A' for actual_current or 'Nm' for actual_current_as_torque)")
    names, blocks = [TIME_COLUMN], [recording.time[:, None]]
    for field, output in RTDE_OUTPUTS.items():
        values = getattr(recording, field)
        if values is None:
            continue
        if field == "current" and recording.units == "Nm":
            output = TORQUE_OUTPUT
        names.extend(f"{output}_{j}" for j in range(values.shape[1]))
        blocks.append(values)
    if recording.labels is not None:
        names.append(LABEL_COLUMN)
        blocks.append(np.asarray(recording.labels).reshape(-1, 1))
    return names, blocks


def write_rtde_csv(recording, path, *, delimiter=",", robot_comment=False):
    """Write a recording as a UR RTDE CSV file.

    The header follows ur_rtde's names and order (see the module
    docstring), values are written with ``repr`` (shortest exact float
    round trip), labels as integers. ``delimiter=" "`` gives the flavour of
    UR's ``record.py``.

    Parameters
    ----------
    recording : Recording
        Finite values only; ``units`` must be ``"A"`` or ``"Nm"``.
    path : str or Path
        Output file (overwritten).
    delimiter : {",", " ", ";", "\\t"}, default=","
        Field separator.
    robot_comment : bool, default=False
        Start the file with ``# robot: NAME`` when ``metadata["robot"]``
        names the robot (:func:`read_rtde_csv` reads it back; tools that
        expect the header on the first line may not skip it).

    Returns
    -------
    path : Path
        The file written.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording, write_rtde_csv
    >>> rec = Recording(time=[0.0, 0.002], q=[[0.1], [0.2]], qd=[[0.0], [0.0]],
    ...                 current=[[1.0], [1.0]])
    >>> path = write_rtde_csv(rec, pathlib.Path(tempfile.mkdtemp()) / "a.csv",
    ...                       delimiter=" ")
    >>> print(path.read_text().strip())
    timestamp actual_q_0 actual_qd_0 actual_current_0
    0.0 0.1 0.0 1.0
    0.002 0.2 0.0 1.0
    """
    if not isinstance(recording, Recording):
        raise TypeError(f"write_rtde_csv needs a Recording, got {type(recording).__name__}")
    if delimiter not in (",", " ", ";", "\t"):
        raise ValueError(f"delimiter must be ',', ' ', ';' or TAB, got {delimiter!r}")
    names, blocks = rtde_columns(recording)
    has_labels = recording.labels is not None
    values = np.hstack(blocks[:-1] if has_labels else blocks).astype(float)
    bad = ~np.isfinite(values)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise ValueError(
            f"Recording {recording.name!r}: {names[col]} is {values[row, col]} at sample "
            f"{row}; RTDE files hold finite values only")
    rows = [delimiter.join(map(repr, row)) for row in values.tolist()]
    if has_labels:
        labels = np.asarray(recording.labels)
        text = (labels.astype(np.int64).tolist() if np.all(labels == np.round(labels))
                else labels.astype(float).tolist())
        rows = [f"{row}{delimiter}{label!r}" for row, label in zip(rows, text)]
    path = Path(path)
    robot = recording.metadata.get("robot")
    with open(path, "w", newline="\n") as handle:
        if robot_comment and isinstance(robot, str) and robot.strip():
            handle.write(f"# robot: {robot.strip()}\n")
        handle.write(delimiter.join(names) + "\n")
        handle.write("\n".join(rows))
        handle.write("\n")
    return path
