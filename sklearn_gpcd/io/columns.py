"""Column maps: which file columns hold which :class:`Recording` field.

A *column map* is a dict from Recording field names (``"time"``, ``"q"``,
``"qd"``, ``"current"``, ``"qdd"``, ``"target_q"``, ``"target_qd"``,
``"target_qdd"``, ``"target_current"``, ``"target_torque"``, ``"labels"``)
to columns, each given as

- a 0-based index (``0``) or a header name (``"timestamp"``);
- a sequence of them (``range(1, 7)``, ``[1, 2, 3]``, ``["q0", "q1"]``);
- a name *prefix* (``"actual_q"``) that expands to the header's consecutive
  ``actual_q_0, actual_q_1, ...`` columns, as UR RTDE names vector entries.

``time``, ``q``, ``qd`` and ``current`` are required. The optional key
``"units"`` says what ``current`` (and ``target_current``) hold: ``"A"``
(motor currents, the default) or ``"Nm"`` (joint torques); it becomes
``recording.units``. A column map can also be the name of a preset from
:data:`COLUMN_PRESETS`, which picks its layout from the file's field count,
or, for logs written one file per signal (``panda_gaz``), names the files of
a folder.
"""

from dataclasses import dataclass, field
from numbers import Integral

from .recording import JOINT_SIGNALS

#: Fields a column map may name.
FIELDS = ("time",) + JOINT_SIGNALS + ("labels",)
#: Fields every column map must name.
REQUIRED_FIELDS = ("time", "q", "qd", "current")
#: Fields that are one column, not one per joint.
SCALAR_FIELDS = ("time", "labels")
#: Units a column map's ``"units"`` may give for the current columns.
CURRENT_UNITS = ("A", "Nm")


def split_units(column_map, default="A", source=""):
    """``column_map`` without its ``"units"`` key, and the units it gives.

    Parameters
    ----------
    column_map : dict
        A column map, possibly with ``"units": "A"`` or ``"Nm"``.
    default : str, default="A"
        Units when the map gives none.
    source : str, default=""
        File name for the error message.

    Returns
    -------
    column_map : dict
    units : str

    Examples
    --------
    >>> split_units({"time": 0, "q": 1, "qd": 2, "current": 3, "units": "Nm"})
    ({'time': 0, 'q': 1, 'qd': 2, 'current': 3}, 'Nm')
    """
    column_map = dict(column_map)
    units = column_map.pop("units", None) or default
    if units not in CURRENT_UNITS:
        raise ValueError(f"{source}: column map units must be one of {CURRENT_UNITS} (A for "
                         f"motor currents, Nm for joint torques), got {units!r}")
    return column_map, units


@dataclass(frozen=True)
class ColumnPreset:
    """A named family of headerless layouts, chosen by the field count.

    Parameters
    ----------
    name : str
        Preset name, the key in :data:`COLUMN_PRESETS`.
    layouts : dict
        Field count -> column map (0-based indices).
    robot : str, default=""
        Robot the files come from (stored in ``metadata["robot"]``).
    description : str, default=""
        Where the layout is documented.
    ignored : dict, default={}
        Field count -> columns deliberately left unread (stored in
        ``metadata["ignored_columns"]``).
    units : {"A", "Nm"}, default="A"
        What the current columns hold.
    files : dict, default={}
        For logs written one value per line and one file per signal: field
        -> file name pattern in the log's folder (``layouts`` is then
        empty); see :func:`~sklearn_gpcd.io.read_value_files`.
    n_joints : int, default=None
        Values per sample in the files of a ``files`` preset.

    Examples
    --------
    >>> from sklearn_gpcd.io import COLUMN_PRESETS
    >>> preset = COLUMN_PRESETS["ur10e_mamedov"]
    >>> sorted(preset.layouts)
    [19, 25, 31]
    >>> preset.layout(19, "f.csv")["current"]
    range(13, 19)
    """

    name: str
    layouts: dict
    robot: str = ""
    description: str = ""
    ignored: dict = field(default_factory=dict)
    units: str = "A"
    files: dict = field(default_factory=dict)
    n_joints: int = None

    def layout(self, n_fields, source=""):
        """Column map for a file with ``n_fields`` fields per line.

        Parameters
        ----------
        n_fields : int
            Fields per line of the file.
        source : str, default=""
            File name for the error message.

        Returns
        -------
        column_map : dict
        """
        if self.files:
            raise ValueError(
                f"{source}: column preset {self.name!r} reads a folder of one-value-per-line "
                f"files ({', '.join(self.files.values())}); give the folder, not one file")
        if n_fields not in self.layouts:
            known = ", ".join(str(n) for n in sorted(self.layouts))
            raise ValueError(
                f"{source}: column preset {self.name!r} has no layout for {n_fields} fields "
                f"per line (known: {known})"
            )
        return self.layouts[n_fields]


_UR_BASE = {"time": 0, "q": range(1, 7), "qd": range(7, 13), "current": range(13, 19)}

#: UR10e logs of Mamedov et al. (github.com/shamilmamedov/dynamic_calibration),
#: headerless comma-separated: t, q(6), qd(6), i(6) [, i_des(6), tau_des(6)].
#: The 25-field files (collision_detection_data_2020) end with 6 columns of
#: unknown meaning, which are ignored.
UR10E_MAMEDOV = ColumnPreset(
    name="ur10e_mamedov",
    layouts={
        31: {**_UR_BASE, "target_current": range(19, 25), "target_torque": range(25, 31)},
        25: dict(_UR_BASE),
        19: dict(_UR_BASE),
    },
    robot="ur10e",
    description=(
        "UR10e, headerless: t [s], q [rad], qd [rad/s], i [A], then either nothing (19 "
        "fields), 6 unknown columns that are ignored (25 fields) or i_des [A] and "
        "tau_des [Nm] (31 fields)"
    ),
    ignored={25: list(range(19, 25))},
)

#: Franka Emika Panda logs of Gaz et al. (RA-L 2019, github.com/marcocognetti/
#: FrankaEmikaPandaDynModel, matlab/data/Exciting_Traj/*/rbt_log): one value
#: per line, sample-major (7 lines per sample), one file per signal; the
#: "current" file holds the link-side joint torques [Nm].
PANDA_GAZ = ColumnPreset(
    name="panda_gaz",
    layouts={},
    robot="panda",
    description=("Franka Emika Panda (7 joints), a folder with *_time.txt [s], "
                 "*_positions.txt [rad], *_velocity.txt [rad/s], *_torques.txt [Nm], one "
                 "value per line"),
    units="Nm",
    files={"time": "*_time.txt", "q": "*_positions.txt", "qd": "*_velocity.txt",
           "current": "*_torques.txt"},
    n_joints=7,
)

#: Named column maps for :func:`sklearn_gpcd.io.read_csv` and, for logs
#: written one file per signal, :func:`sklearn_gpcd.io.read_value_files`.
COLUMN_PRESETS = {preset.name: preset for preset in (UR10E_MAMEDOV, PANDA_GAZ)}


def get_preset(name):
    """The :class:`ColumnPreset` called ``name``.

    Parameters
    ----------
    name : str
        A key of :data:`COLUMN_PRESETS`.

    Returns
    -------
    preset : ColumnPreset

    Examples
    --------
    >>> get_preset("ur10e_mamedov").robot
    'ur10e'
    """
    try:
        return COLUMN_PRESETS[name]
    except KeyError:
        known = ", ".join(repr(k) for k in COLUMN_PRESETS)
        raise ValueError(f"unknown column preset {name!r}; known: {known}") from None


def _as_items(spec, key):
    if isinstance(spec, (str, Integral)):
        return [spec], True
    if isinstance(spec, slice):
        if spec.stop is None:
            raise TypeError(f"column map entry {key!r}: a slice needs an explicit stop")
        return list(range(*spec.indices(spec.stop))), False
    try:
        items = list(spec)
    except TypeError:
        raise TypeError(
            f"column map entry {key!r} must be an int, a str or a sequence of them, "
            f"got {type(spec).__name__}"
        ) from None
    for item in items:
        if not isinstance(item, (str, Integral)):
            raise TypeError(
                f"column map entry {key!r} holds {item!r}; expected column indices or names")
    return items, False


def resolve_column_map(column_map, n_fields, names=None, source="", n_joints=None):
    """Column indices and labels of every field in ``column_map``.

    Parameters
    ----------
    column_map : dict
        Field -> column spec (see the module docstring).
    n_fields : int
        Fields per line in the file.
    names : list of str, default=None
        Header names; None for a headerless file.
    source : str, default=""
        File name for messages.
    n_joints : int, default=None
        Joints a name prefix must expand to; None takes the count found for
        ``q``.

    Returns
    -------
    indices : dict
        Field -> list of 0-based column indices.
    labels : dict
        Field -> list of column labels for messages: the quoted header name,
        or ``"9 (qd[2])"`` (index and field) without a header.

    Examples
    --------
    >>> idx, lab = resolve_column_map({"time": "timestamp", "q": "actual_q",
    ...                                "qd": [3, 4], "current": range(5, 7)},
    ...                               7, names=["timestamp", "actual_q_0", "actual_q_1",
    ...                                         "x", "y", "i0", "i1"])
    >>> idx["q"], lab["qd"]
    ([1, 2], ["'x'", "'y'"])
    """
    unknown = [k for k in column_map if k not in FIELDS]
    if unknown:
        raise ValueError(
            f"{source}: column map names unknown field(s) {unknown}; valid fields: "
            f"{', '.join(FIELDS)}"
        )
    missing_fields = [k for k in REQUIRED_FIELDS if column_map.get(k) is None]
    if missing_fields:
        raise ValueError(
            f"{source}: column map lacks required field(s) {missing_fields} "
            f"(every recording needs {', '.join(REQUIRED_FIELDS)})"
        )
    lookup = {name: i for i, name in enumerate(names)} if names is not None else None
    repeated = _repeated_names(names)
    order = ["q"] + [k for k in column_map if k != "q" and column_map[k] is not None]
    indices, labels, missing, counts = {}, {}, [], []
    given = n_joints is not None
    for key in order:
        items, scalar = _as_items(column_map[key], key)
        cols = []
        for item in items:
            if isinstance(item, Integral):
                item = int(item)
                if not -n_fields <= item < n_fields:
                    raise ValueError(
                        f"{source}: column map asks for column {item} ({key}) but the file "
                        f"has {n_fields} columns (0-based indices 0..{n_fields - 1})"
                    )
                cols.append(item % n_fields)
            elif lookup is None:
                raise ValueError(
                    f"{source}: column map names column {item!r} ({key}) but the file has "
                    "no header; use 0-based column indices"
                )
            elif item in lookup:
                cols.append(lookup[item])
            elif scalar and key not in SCALAR_FIELDS:
                found = _expand_prefix(item, lookup, n_joints, source)
                cols.extend(lookup[n] for n in found if n in lookup)
                missing.extend((n, key) for n in found if n not in lookup)
                if any(n not in lookup for n in found):
                    counts.append(_joint_count_note(item, lookup, len(found), given))
            else:
                missing.append((item, key))
        if key in SCALAR_FIELDS and len(cols) + sum(k == key for _, k in missing) != 1:
            raise ValueError(f"{source}: column map entry {key!r} must name exactly one column")
        for c in cols:
            if names is not None and names[c] in repeated:
                where = ", ".join(str(i) for i in repeated[names[c]])
                raise ValueError(
                    f"{source}: column {names[c]!r} ({key}) appears more than once in the "
                    f"header (0-based columns {where}); rename the copies or give column "
                    "indices")
        if key == "q" and n_joints is None and not missing:
            n_joints = len(cols)
        indices[key] = cols
        labels[key] = [
            repr(names[c]) if names is not None else _default_label(key, j, c)
            for j, c in enumerate(cols)
        ]
    if missing:
        listed = ", ".join(f"{name!r} ({key})" for name, key in missing)
        shown = ", ".join(names[:8]) + (", ..." if len(names) > 8 else "")
        counts = [c for c in counts if c]
        note = f" ({counts[0]})" if counts else ""
        raise ValueError(
            f"{source}: missing column(s) {listed}{note}; the header has: {shown}")
    return indices, labels


def _repeated_names(names):
    """Header names that occur more than once -> their 0-based columns."""
    if names is None:
        return {}
    where = {}
    for i, name in enumerate(names):
        where.setdefault(name, []).append(i)
    return {name: cols for name, cols in where.items() if len(cols) > 1}


def _count_prefixed(prefix, lookup):
    """How many consecutive ``prefix_0, prefix_1, ...`` the header has."""
    count = 0
    while f"{prefix}_{count}" in lookup:
        count += 1
    return count


def _joint_count_note(prefix, lookup, n_joints, given):
    """Why ``prefix_*`` columns are missing: too few joints, or a hole."""
    count = _count_prefixed(prefix, lookup)
    if any(f"{prefix}_{j}" in lookup for j in range(count + 1, n_joints)):
        return None  # a hole in the numbering, the listed names say it all
    if given:
        return (f"the file has {count} {prefix}_* column(s) but n_joints={n_joints}: "
                f"fewer joints than the robot has? (keep the robot's joints the log has: gpcd "
                f"--joints {count}, or load_robot(..., joints={count}) in Python)")
    return f"the file has {count} {prefix}_* column(s) but q has {n_joints}"


def _expand_prefix(prefix, lookup, n_joints, source=""):
    """Names ``prefix_0 .. prefix_{n-1}``; n from the header when not given.

    With ``n_joints`` given, a header with more consecutive columns
    (``prefix_{n_joints}`` exists) is an error: the file has more joints
    than the robot.
    """
    count = _count_prefixed(prefix, lookup)
    if n_joints is None:
        return [f"{prefix}_{j}" for j in range(max(count, 1))]
    if count > n_joints:
        raise ValueError(
            f"{source}: the file has {count} {prefix}_* columns ({prefix}_0 .. "
            f"{prefix}_{count - 1}) but n_joints={n_joints}: more joints than the robot has? "
            f"(keep the robot's joints the log has: gpcd --joints {count}, or "
            f"load_robot(..., joints={count}) in Python)")
    return [f"{prefix}_{j}" for j in range(n_joints)]


def _default_label(key, joint, column):
    if key in SCALAR_FIELDS:
        return f"{column} ({key})"
    return f"{column} ({key}[{joint}])"
