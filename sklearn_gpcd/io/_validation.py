"""Row cleaning and checks shared by every reader.

Every loader ends in :func:`finalize_recording`, which applies one rule set
to the rows it parsed (file order, irregular sampling kept, no resampling):

1. Malformed rows (wrong field count, a non-number in a used column) found by
   the parser are dropped.
2. NaN or inf in a used column is an error: the logger wrote it on purpose,
   and dropping rows would hide a missing signal.
3. Exact duplicates (a row equal in every used column, time included, to an
   earlier row) are dropped; nothing is lost, so they do not count towards
   ``max_dropped``.
4. Rows with an absurd value, ``|x| > 1e6`` in any joint signal (no arm
   reaches that in rad, rad/s, A or Nm -- or degrees), are dropped: garbage
   from a corrupted buffer (:func:`absurd_values`).
5. Glitches are dropped (:func:`glitch_mask`): rows with
   ``|qd_j| > max_joint_speed``, and short runs of rows (< 10) cut off from
   their neighbours by a time jump of more than 50 median sampling periods
   or by a joint step faster than ``max_joint_speed``,
   ``max_j |q_j[k] - q_j[k-1]| > max_joint_speed * dt + 1e-3 rad``, unless
   they fit between the rows kept around them. Corrupted logger buffers
   write such bursts, sometimes with plausible time stamps.
6. Rows out of time order are dropped: the kept rows are the longest
   strictly increasing subsequence of the time column
   (:func:`increasing_subsequence`), so an isolated jump backwards or a
   repeated time stamp with different values costs one row; of equal time
   stamps the first is kept.

Step 1 and steps 4-6 together may each drop at most ``max_dropped`` (a
fraction, default 5 %) of the rows. Beyond that the file is not "a few bad
rows" but wrong (a mostly unsorted file, a time reset halfway, a wrong
column map, a wrong delimiter) and a ``ValueError`` names the file, the first
offending row and its column.

Everything dropped is reported in ONE :class:`RecordingWarning` per file
(count, first row numbers and why), and the row numbers are stored in
``recording.metadata["dropped_rows"]``. The same warning carries the
findings of :mod:`sklearn_gpcd.io._checks` on the kept rows, which change
nothing: gaps in time (also in ``metadata["gaps"]``), positions that look
like degrees (the glitch limits are then scaled by ``180 / pi``), and
position steps that disagree with the velocities.
"""

import warnings
from bisect import bisect_left

import numpy as np

from .plausibility import (
    degrees_note,
    gaps_note,
    looks_like_degrees,
    units_note,
)
from .recording import JOINT_SIGNALS, Recording

#: Slack [rad] on the position step allowed between two kept rows.
Q_STEP_TOLERANCE = 1e-3
#: Longest plausible time step, in median sampling periods.
GAP_FACTOR = 50
#: Shortest run of continuous rows trusted on its own.
MIN_RUN = 10
#: Row numbers quoted in messages.
N_QUOTED = 5
#: Largest plausible magnitude of a joint signal (rad, rad/s, A, Nm, or deg).
ABSURD_VALUE = 1e6


class RecordingWarning(UserWarning):
    """Rows of a recording were dropped, or its values look suspicious.

    Raised through :func:`warnings.warn` by every reader in
    :mod:`sklearn_gpcd.io`, once per file, naming the file and the first few
    line (or row / message) numbers; the full list of dropped rows is kept in
    ``recording.metadata["dropped_rows"]``.

    Examples
    --------
    >>> import warnings
    >>> from sklearn_gpcd.io import RecordingWarning
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     warnings.warn("demo.csv: dropped 1 row (line 7)", RecordingWarning)
    >>> caught[0].category.__name__
    'RecordingWarning'
    """


def quote_rows(rows, kind="line"):
    """``"lines 2, 3, 4, ... (12 in all)"`` for messages.

    Parameters
    ----------
    rows : iterable of int
        Row numbers.
    kind : str, default="line"
        What the numbers count.

    Returns
    -------
    text : str

    Examples
    --------
    >>> quote_rows([4, 9])
    'lines 4, 9'
    >>> quote_rows(range(10), kind="row")
    'rows 0, 1, 2, 3, 4, ... (10 in all)'
    """
    rows = [int(r) for r in rows]
    head = ", ".join(str(r) for r in rows[:N_QUOTED])
    more = f", ... ({len(rows)} in all)" if len(rows) > N_QUOTED else ""
    plural = "s" if len(rows) != 1 else ""
    return f"{kind}{plural} {head}{more}"


def increasing_subsequence(time):
    """Mask of the longest strictly increasing subsequence of ``time``.

    Patience sorting, ``O(n log n)``; sorted input returns all True at once.

    Parameters
    ----------
    time : ndarray of shape (n,)

    Returns
    -------
    keep : ndarray of bool, shape (n,)

    Examples
    --------
    >>> increasing_subsequence([0.0, 0.1, -5.0, 0.2, 0.3]).tolist()
    [True, True, False, True, True]
    >>> increasing_subsequence([0.0, 9e9, 0.2, 0.3]).tolist()
    [True, False, True, True]
    """
    time = np.asarray(time, dtype=float)
    n = time.shape[0]
    if n < 2 or np.all(np.diff(time) > 0):
        return np.ones(n, dtype=bool)
    tails, tail_idx = [], []
    parent = np.full(n, -1)
    for i, value in enumerate(time.tolist()):
        pos = bisect_left(tails, value)
        if pos < len(tails) and tails[pos] == value:
            continue  # a repeat of an earlier time stamp: keep the earlier row
        if pos > 0:
            parent[i] = tail_idx[pos - 1]
        if pos == len(tails):
            tails.append(value)
            tail_idx.append(i)
        else:
            tails[pos] = value
            tail_idx[pos] = i
    keep = np.zeros(n, dtype=bool)
    i = tail_idx[-1]
    while i >= 0:
        keep[i] = True
        i = parent[i]
    return keep


def continuous_runs(time, q, max_joint_speed=None, tol=Q_STEP_TOLERANCE, gap=np.inf,
                    nominal_dt=0.0):
    """Cut rows into runs joined by plausible steps.

    The step from row ``k - 1`` to row ``k`` breaks the run when time jumps
    ahead by more than ``gap``, or, if ``max_joint_speed`` is given, when a
    joint moves faster than it:

    .. math:: \\max_j |q_j[k] - q_j[k-1]| > v_{max} \\Delta t + tol,

    with :math:`\\Delta t = t_k - t_{k-1}`, or ``nominal_dt`` when time does
    not increase (time order itself is left to
    :func:`increasing_subsequence`, so a repeated or late time stamp on a
    smooth row does not break the run).

    Parameters
    ----------
    time : ndarray of shape (n,)
    q : ndarray of shape (n, n_joints)
    max_joint_speed : float, default=None
        Joint speed limit [rad/s]; None checks time gaps only.
    tol : float, default=1e-3
        Position slack [rad] (encoder quantisation, time-stamp jitter).
    gap : float, default=inf
        Longest plausible time step [s].
    nominal_dt : float, default=0.0
        Step assumed where time does not increase [s].

    Returns
    -------
    runs : list of (int, int)
        ``(start, stop)`` row ranges covering all rows in order.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.array([0.0, 0.01, 0.02, 9.0, 9.01])
    >>> continuous_runs(t, np.zeros((5, 1)), gap=1.0)
    [(0, 3), (3, 5)]
    """
    n = time.shape[0]
    dt = np.diff(time)
    ok = dt <= gap
    if max_joint_speed is not None and n > 1:
        step = np.max(np.abs(np.diff(q, axis=0)), axis=1)
        ok &= step <= max_joint_speed * np.where(dt > 0, dt, nominal_dt) + tol
    cuts = (np.flatnonzero(~ok) + 1).tolist()
    return list(zip([0] + cuts, cuts + [n]))


def glitch_mask(time, q, qd, max_joint_speed=None, tol=Q_STEP_TOLERANCE,
                gap_factor=GAP_FACTOR, min_run=MIN_RUN):
    """Mask of rows that fit in with their neighbours (False = glitch).

    1. Rows with ``|qd_j| > max_joint_speed`` are glitches.
    2. The others are cut into :func:`continuous_runs` (time steps within
       ``gap_factor`` median sampling periods, feasible joint steps).
       Rows out of time order are left to :func:`increasing_subsequence`.
    3. Runs of at least ``min_run`` rows (or of the longest run's length, if
       shorter) are kept. A shorter run is kept only if it fits between the
       kept rows around it: time increasing and joint steps feasible on both
       sides. A logger pause splits a file into long runs and loses nothing;
       garbage rows form short runs that do not fit.

    Parameters
    ----------
    time : ndarray of shape (n,)
    q, qd : ndarray of shape (n, n_joints)
    max_joint_speed : float, default=None
        Joint speed limit [rad/s]; None checks time only.
    tol : float, default=1e-3
        Position slack [rad].
    gap_factor : float, default=50
        Longest plausible time step, in median sampling periods.
    min_run : int, default=10
        Shortest run trusted on its own.

    Returns
    -------
    keep : ndarray of bool, shape (n,)

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(30) * 0.01
    >>> q = np.zeros((30, 1)); q[12] = 253.0
    >>> np.flatnonzero(~glitch_mask(t, q, np.zeros((30, 1)), 10.0)).tolist()
    [12]
    """
    keep = np.ones(time.shape[0], dtype=bool)
    if max_joint_speed is not None:
        keep &= np.all(np.abs(qd) <= max_joint_speed, axis=1)
    rows = np.flatnonzero(keep)
    if rows.size < 2:
        return keep
    t, qq = time[rows], q[rows]
    steps = np.diff(t)
    positive = steps[steps > 0]
    nominal_dt = np.median(positive) if positive.size else 0.0
    gap = gap_factor * nominal_dt if positive.size else np.inf
    runs = continuous_runs(t, qq, max_joint_speed, tol, gap, nominal_dt)
    if len(runs) == 1:
        return keep
    longest = max(stop - start for start, stop in runs)
    trusted = [stop - start >= min(min_run, longest) for start, stop in runs]

    def fits(i, k):
        if t[k] <= t[i]:
            return False
        if max_joint_speed is None:
            return True
        return np.max(np.abs(qq[k] - qq[i])) <= max_joint_speed * (t[k] - t[i]) + tol

    next_trusted = [None] * len(runs)
    upcoming = None
    for r in range(len(runs) - 1, -1, -1):
        next_trusted[r] = upcoming
        if trusted[r]:
            upcoming = runs[r][0]
    in_chain = np.zeros(rows.size, dtype=bool)
    last = None
    for r, (start, stop) in enumerate(runs):
        after = next_trusted[r]
        if trusted[r] or ((last is None or fits(last, start))
                          and (after is None or fits(stop - 1, after))):
            in_chain[start:stop] = True
            last = stop - 1
    keep[rows[~in_chain]] = False
    return keep


def check_finite(source, values, row_ids, column_labels, kind="line"):
    """Raise ValueError naming the first NaN/inf cell (row and column).

    Parameters
    ----------
    source : str
        File name for the message.
    values : ndarray of shape (n, k)
    row_ids : ndarray of int, shape (n,)
        Row numbers for the message.
    column_labels : list of str
        Column labels for the message, one per column of ``values``.
    kind : str, default="line"
        What ``row_ids`` count.

    Examples
    --------
    >>> import numpy as np
    >>> check_finite("a.csv", np.array([[1.0, np.nan]]), np.array([3]),
    ...              ["'t'", "'q_0'"])  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: a.csv, line 3, column 'q_0': value is nan; NaN and inf are not ...
    """
    bad = ~np.isfinite(values)
    if not bad.any():
        return
    row, col = np.argwhere(bad)[0]
    raise ValueError(
        f"{source}, {kind} {row_ids[row]}, column {column_labels[col]}: value is "
        f"{values[row, col]}; NaN and inf are not allowed in a recording"
    )


def _too_many(source, what, count, n_rows, max_dropped, first, hint):
    if count > max_dropped * n_rows:
        raise ValueError(
            f"{source}: {count} of {n_rows} rows ({100 * count / n_rows:.1f} %) {what}, "
            f"more than max_dropped={max_dropped:g} allows; first: {first}. {hint}"
        )


def exact_duplicates(columns):
    """Rows equal in every column to an earlier row, and that row.

    Parameters
    ----------
    columns : dict
        ``"time"`` -> (n,), other fields -> (n,) or (n, k), all finite.

    Returns
    -------
    first : ndarray of int, shape (n,)
        For each row the index of the first row equal to it (itself when
        it is not a duplicate).

    Examples
    --------
    >>> import numpy as np
    >>> cols = {"time": np.array([0.0, 0.1, 0.1, 0.1]),
    ...         "q": np.array([[1.0], [2.0], [2.0], [3.0]])}
    >>> exact_duplicates(cols).tolist()
    [0, 1, 1, 3]
    """
    table = np.column_stack([np.asarray(v).reshape(len(columns["time"]), -1)
                             for v in columns.values()])
    n = table.shape[0]
    if n < 2:
        return np.arange(n)
    _, first, inverse = np.unique(table, axis=0, return_index=True, return_inverse=True)
    return first[inverse.reshape(-1)]


def absurd_values(columns, column_labels, limit=ABSURD_VALUE):
    """Reason per row holding a joint-signal value beyond ``limit`` in magnitude.

    Time and labels are not checked (time stamps may be UNIX seconds).

    Parameters
    ----------
    columns : dict
        Field -> values, as for :func:`finalize_recording`.
    column_labels : dict
        Field -> column labels for the message.
    limit : float, default=1e6
        Largest plausible magnitude.

    Returns
    -------
    reasons : dict
        Row index -> reason naming the first such column.

    Examples
    --------
    >>> import numpy as np
    >>> cols = {"time": np.arange(3.0), "q": np.array([[0.1], [1e305], [0.2]])}
    >>> absurd_values(cols, {"time": ["'t'"], "q": ["'q_0'"]})
    {1: "column 'q_0': |value| = 1e+305 is absurd (> 1e+06)"}
    """
    reasons = {}
    for key in JOINT_SIGNALS:
        if key not in columns:
            continue
        values = columns[key]
        for row, j in np.argwhere(np.abs(values) > limit):
            if int(row) not in reasons:
                reasons[int(row)] = (f"column {column_labels[key][j]}: |value| = "
                                     f"{abs(values[row, j]):.4g} is absurd (> {limit:.0e})")
    return dict(sorted(reasons.items()))


def finalize_recording(
    source,
    columns,
    row_ids,
    *,
    column_labels,
    malformed=(),
    n_rows=None,
    kind="line",
    n_joints=None,
    units="A",
    name="",
    metadata=None,
    max_dropped=0.05,
    max_joint_speed=10.0,
    min_samples=2,
):
    """Clean parsed rows by the module rules and build a :class:`Recording`.

    Parameters
    ----------
    source : str
        File name used in messages.
    columns : dict
        ``"time"`` -> (n,), joint signals -> (n, n_joints), optional
        ``"labels"`` -> (n,), all float, rows in file order.
    row_ids : ndarray of int, shape (n,)
        Line (or row / message) number of each parsed row, for messages.
    column_labels : dict
        Same keys as ``columns``; list of column names for messages.
    malformed : sequence of (int, str)
        Rows the parser already rejected: (row number, reason).
    n_rows : int, default=None
        Data rows in the source (parsed + malformed).
    kind : {"line", "row", "message"}, default="line"
        What ``row_ids`` count.
    n_joints : int, default=None
        Expected joint count; a mismatch is a ValueError.
    units : str, default="A"
        Unit of ``current``.
    name : str, default=""
        Recording name.
    metadata : dict, default=None
        Extra metadata to store.
    max_dropped : float, default=0.05
        Largest fraction of rows each cleaning step may drop.
    max_joint_speed : float or None, default=10.0
        Plausible joint speed limit [rad/s] for the glitch filter; None
        disables it.
    min_samples : int, default=2
        Fewest samples a recording may keep.

    Returns
    -------
    recording : Recording

    Raises
    ------
    ValueError
        No rows, too many malformed or out-of-line rows, NaN/inf, a wrong
        joint count, or fewer than ``min_samples`` rows left.

    Warns
    -----
    RecordingWarning
        Once, when rows were dropped or the kept rows have gaps or look like
        other units (see the module docstring).
    """
    malformed = list(malformed)
    columns = dict(columns)
    row_ids = np.asarray(row_ids, dtype=int)
    n_rows = len(row_ids) + len(malformed) if n_rows is None else n_rows
    if n_rows == 0:
        raise ValueError(f"{source}: no data rows")
    if malformed:
        first_row, reason = malformed[0]
        _too_many(source, "are malformed", len(malformed), n_rows, max_dropped,
                  f"{kind} {first_row}: {reason}",
                  "Check the delimiter and the column map (--column-map on the command line).")
    _check_joint_count(source, columns, column_labels, n_joints)
    for key, values in columns.items():
        values2d = values if values.ndim == 2 else values[:, None]
        check_finite(source, values2d, row_ids, column_labels[key], kind)

    keep, duplicates, absurd_rows, out_of_line = _clean_rows(
        columns, row_ids, column_labels, kind, max_joint_speed)
    if absurd_rows or out_of_line:
        bad = sorted(absurd_rows + out_of_line)
        _too_many(source, "are out of line with their neighbours (time stamps not "
                  "increasing, absurd values, or joints jumping faster than "
                  "max_joint_speed)",
                  len(bad), n_rows, max_dropped, f"{kind} {bad[0][0]}, {bad[0][1]}",
                  "Sort the file or split it where time resets; for fast motion raise "
                  "max_joint_speed (--max-joint-speed on the command line; None "
                  "disables the joint check).")
    columns, row_ids = _take(columns, keep), row_ids[keep]

    if len(row_ids) < min_samples:
        raise ValueError(
            f"{source}: too short, {len(row_ids)} valid sample(s) left of {n_rows} rows; "
            f"need at least min_samples={min_samples}"
        )
    dropped = {"malformed": malformed, "exact duplicate": duplicates, "absurd": absurd_rows,
               "out of line": out_of_line}
    dropped_rows = sorted(r for rows_ in dropped.values() for r, _ in rows_)
    gaps_text, gaps = gaps_note(columns["time"], row_ids, kind)
    notes = [
        _dropped_note(n_rows, dropped, kind) if dropped_rows else None,
        gaps_text,
        degrees_note(columns["q"], column_labels["q"]),
        units_note(columns["time"], columns["q"], columns["qd"], column_labels["q"]),
    ]
    notes = [note for note in notes if note]
    if notes:
        warnings.warn(f"{source}: " + " ".join(notes), RecordingWarning, stacklevel=3)

    meta = dict(metadata or {})
    meta.update(source=str(source), t0=float(columns["time"][0]), n_rows=int(n_rows),
                dropped_rows=dropped_rows, gaps=gaps)
    labels = columns.pop("labels", None)
    if labels is not None and np.all(labels == np.round(labels)):
        labels = labels.astype(np.int64)
    return Recording(name=name, units=units, metadata=meta, labels=labels, **columns)


def _clean_rows(columns, row_ids, column_labels, kind, max_joint_speed):
    """Steps 3-6 of the module docstring: which rows to keep, and why the others go.

    Returns
    -------
    keep : ndarray of bool, shape (n,)
    duplicates, absurd, out_of_line : list of (int, str)
        Dropped rows (row number, reason) per step.
    """
    first = exact_duplicates(columns)
    duplicate = first != np.arange(first.size)
    absurd = absurd_values(columns, column_labels)
    candidate = ~duplicate
    candidate[list(absurd)] = False
    time, q, qd = columns["time"], columns["q"], columns["qd"]
    scale = 180.0 / np.pi if looks_like_degrees(q[candidate]) else 1.0
    speed = None if max_joint_speed is None else max_joint_speed * scale
    rows = np.flatnonzero(candidate)
    sub = glitch_mask(time[rows], q[rows], qd[rows], speed, tol=Q_STEP_TOLERANCE * scale)
    sub[sub] = increasing_subsequence(time[rows][sub])
    keep = np.zeros(time.shape[0], dtype=bool)
    keep[rows[sub]] = True

    duplicates = [(int(row_ids[r]), f"exact duplicate of {kind} {row_ids[first[r]]}")
                  for r in np.flatnonzero(duplicate)]
    absurd_rows = [(int(row_ids[r]), why) for r, why in absurd.items() if not duplicate[r]]
    labels = {k: column_labels[k] for k in ("time", "q", "qd")}
    steps = np.diff(time[keep])
    gap = GAP_FACTOR * np.median(steps[steps > 0]) if np.any(steps > 0) else np.inf
    out_of_line = [
        (int(row_ids[row]), _why_dropped(row, keep, time, q, qd, speed, gap, labels,
                                         row_ids, kind))
        for row in np.flatnonzero(candidate & ~keep)
    ]
    return keep, duplicates, absurd_rows, out_of_line


def _take(columns, keep):
    return {key: value[keep] for key, value in columns.items()}


def _check_joint_count(source, columns, column_labels, n_joints):
    counts = {k: columns[k].shape[1] for k in JOINT_SIGNALS if k in columns}
    expected = counts["q"] if n_joints is None else n_joints
    if counts["q"] == 0:
        raise ValueError(f"{source}: q has no joint column (an empty column selection?)")
    for key, count in counts.items():
        if count != expected:
            names = ", ".join(column_labels[key])
            origin = "n_joints" if n_joints is not None else "q"
            hint = f"{'fewer' if count < expected else 'more'} joints than the robot has?"
            if count < expected and key == "q":
                hint += (f" (keep the robot's joints the log has: gpcd --joints {count}, or "
                         f"load_robot(..., joints={count}) in Python)")
            raise ValueError(
                f"{source}: {key} has {count} joint column(s) ({names}), expected "
                f"{expected} (from {origin}); {hint}"
            )


def _why_dropped(row, keep, time, q, qd, speed, gap, labels, row_ids, kind):
    """Reason a cleaning step dropped ``row``, relative to its kept neighbour."""
    if speed is not None:
        over = np.flatnonzero(np.abs(qd[row]) > speed)
        if over.size:
            j = over[0]
            return f"column {labels['qd'][j]}: |qd| = {abs(qd[row, j]):.4g} > {speed:g}"
    before = np.flatnonzero(keep[:row])
    after = np.flatnonzero(keep[row + 1:])
    prev = int(before[-1]) if before.size else None
    nxt = int(row + 1 + after[0]) if after.size else None
    t_col = labels["time"][0]
    for ref in (prev, nxt):
        if ref is not None and time[row] == time[ref]:
            return (f"column {t_col}: t={float(time[row])!r} repeats {kind} {row_ids[ref]} "
                    "with different values")
    for ref, order in ((prev, "after"), (nxt, "before")):
        if ref is not None and (time[row] - time[ref]) * (1 if order == "after" else -1) <= 0:
            return (f"column {t_col}: t={float(time[row])!r} is not {order} "
                    f"t={float(time[ref])!r} ({kind} {row_ids[ref]})")
    ref = prev if prev is not None else nxt
    if ref is None:
        return "no valid neighbour"
    where = f"{kind} {row_ids[ref]}"
    dt = abs(time[row] - time[ref])
    step = np.abs(q[row] - q[ref])
    j = int(np.argmax(step))
    if speed is not None and step[j] > speed * dt + Q_STEP_TOLERANCE:
        return f"column {labels['q'][j]}: jumps {step[j]:.4g} in {dt:.4g} s from {where}"
    if dt > gap:
        return (f"column {t_col}: t={float(time[row])!r} jumps {dt:.4g} s from {where}, "
                f"more than {GAP_FACTOR} sampling periods")
    return f"column {t_col}: t={float(time[row])!r} isolated among glitches"


def _dropped_note(n_rows, dropped, kind):
    """``"dropped 3 of 80 rows (lines ...): 1 malformed (...); ..."`` for the warning."""
    total = sum(len(rows) for rows in dropped.values())
    parts = []
    for what, rows in dropped.items():
        if rows:
            first = "; ".join(f"{kind} {r}: {why}" for r, why in rows[:N_QUOTED])
            more = f"; ... ({len(rows)} in all)" if len(rows) > N_QUOTED else ""
            parts.append(f"{len(rows)} {what} ({first}{more})")
    numbers = quote_rows(sorted(r for rows in dropped.values() for r, _ in rows), kind)
    return (f"dropped {total} of {n_rows} rows ({numbers}): " + "; ".join(parts)
            + ". Their numbers are in recording.metadata['dropped_rows'].")
