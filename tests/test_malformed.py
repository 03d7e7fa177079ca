"""Malformed recordings through the loaders and the ``gpcd`` command (issue #9).

One table, :data:`CASES`, of broken files. Each is fed to
:func:`sklearn_gpcd.io.load_recording` (with ``n_joints=6``: the robot is a
UR) and to ``gpcd diagnose FILE --robot ur10`` in-process. Every case must
end in a :class:`ValueError` / :class:`OSError` (or a
:class:`RecordingWarning`) whose message names the file and, where it makes
sense, the column and the line; the command must exit with status 2 and one
``error:`` line, never a traceback. The table is also the checklist of
``docs/user_guide/io.rst`` ("Every error and warning").
"""

import io
import re
import warnings
from dataclasses import dataclass, field

import numpy as np
import pytest

from sklearn_gpcd.cli import main
from sklearn_gpcd.datasets import simulate_d1
from sklearn_gpcd.features import InverseDynamicsFeatures, differentiate, make_inputs
from sklearn_gpcd.io import (
    Recording,
    RecordingWarning,
    load_recording,
    read_csv,
    read_npz,
    read_rtde_csv,
    write_rtde_csv,
)

N_JOINTS = 6
#: The command every CLI case runs, with the file as training recording.
DIAGNOSE = ["diagnose", "--robot", "ur10", "--effects", "payload"]


# --------------------------------------------------------------------------- base file
@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """A clean simulated UR10 RTDE recording: (header names, rows of fields).

    Like a real ur_rtde log it has the target signals but no ``actual_qdd``
    (accelerations are differentiated from ``qd``).
    """
    path = tmp_path_factory.mktemp("base") / "base.csv"
    write_rtde_csv(simulate_d1("ur10", n_targets=3, random_state=1).replace(qdd=None), path)
    lines = path.read_text().splitlines()
    return lines[0].split(","), [line.split(",") for line in lines[1:]]


def col(names, name):
    return names.index(name)


def join(names, rows, delimiter=","):
    return "\n".join(delimiter.join(r) for r in ([names] if names else []) + rows) + "\n"


def set_column(names, rows, prefix, func):
    """Apply ``func(values) -> values`` to the joint columns ``prefix_0..``."""
    idx = [i for i, n in enumerate(names) if re.fullmatch(rf"{prefix}_\d+", n)]
    values = np.array([[float(r[i]) for i in idx] for r in rows])
    new = func(values)
    for r, row_values in zip(rows, new):
        for i, v in zip(idx, row_values):
            r[i] = repr(float(v))
    return rows


def drop_joint(names, rows, joint):
    keep = [i for i, n in enumerate(names) if not n.endswith(f"_{joint}")]
    return [names[i] for i in keep], [[r[i] for i in keep] for r in rows]


def add_joint(names, rows):
    """A 7th joint: copy every ``*_5`` column as ``*_6`` right after it."""
    new_names, new_rows = [], [[] for _ in rows]
    for i, n in enumerate(names):
        new_names.append(n)
        for new, r in zip(new_rows, rows):
            new.append(r[i])
        if n.endswith("_5"):
            new_names.append(n[:-1] + "6")
            for new, r in zip(new_rows, rows):
                new.append(r[i])
    return new_names, new_rows


# --------------------------------------------------------------------------- the table
@dataclass
class Case:
    """One kind of malformed recording.

    ``make(base, folder) -> path`` writes it. ``error`` is a list of regular
    expressions the ValueError/OSError message must all match (None when
    the file loads with a warning); ``warn`` the same for the single
    RecordingWarning; ``dropped`` the line numbers it must report.
    """

    make: object
    error: list = None
    warn: list = None
    dropped: list = None
    cli_status: int = None  # default: 2 for errors, 0 for warnings
    #: units flagged (degrees, milliseconds): ``gpcd diagnose`` refuses the file
    #: (exit 2) unless ``--units-confirmed`` (issue #16)
    units: bool = False
    loader_kwargs: dict = field(default_factory=dict)


def _write(folder, name, text, mode="w"):
    path = folder / name
    if mode == "wb":
        path.write_bytes(text)
    else:
        path.write_text(text)
    return path


def _empty(base, folder):
    return _write(folder, "empty.csv", "")


def _blank(base, folder):
    return _write(folder, "blank.csv", "\n   \n# a comment, no data\n")


def _header_only(base, folder):
    names, _ = base
    return _write(folder, "header_only.csv", ",".join(names) + "\n")


def _missing_column(base, folder):
    names, rows = base
    i = col(names, "actual_current_3")
    return _write(folder, "no_current.csv", join(names[:i] + names[i + 1:],
                                                 [r[:i] + r[i + 1:] for r in rows]))


def _duplicate_column(base, folder):
    names, rows = base
    names = list(names)
    names[col(names, "target_q_2")] = "actual_q_2"
    return _write(folder, "dup_column.csv", join(names, rows))


def _text_cell(base, folder):
    names, rows = base
    rows = [list(r) for r in rows]
    rows[40][col(names, "actual_qd_2")] = "fast"  # line 42
    return _write(folder, "text_cell.csv", join(names, rows))


def _text_column(base, folder):
    names, rows = base
    rows = [list(r) for r in rows]
    for r in rows:
        r[col(names, "actual_qd_2")] = "n/a"
    return _write(folder, "text_column.csv", join(names, rows))


def _empty_cells(base, folder):
    names, rows = base
    rows = [list(r) for r in rows]
    for r in rows[100:]:
        r[col(names, "actual_current_1")] = ""   # the signal stopped being logged
    return _write(folder, "empty_cells.csv", join(names, rows))


def _nan_cell(base, folder):
    names, rows = base
    rows = [list(r) for r in rows]
    rows[6][col(names, "actual_current_1")] = "nan"  # line 8
    return _write(folder, "nan_cell.csv", join(names, rows))


def _inf_cell(base, folder):
    names, rows = base
    rows = [list(r) for r in rows]
    rows[3][col(names, "timestamp")] = "inf"  # line 5
    return _write(folder, "inf_cell.csv", join(names, rows))


def _overflow_cell(base, folder):
    names, rows = base
    rows = [list(r) for r in rows]
    rows[9][col(names, "actual_q_4")] = "1e400"  # line 11, overflows to inf
    return _write(folder, "overflow.csv", join(names, rows))


def _truncated_last_line(base, folder):
    names, rows = base
    text = join(names, rows)
    return _write(folder, "truncated.csv", text[:-40])  # killed mid-write


def _wrong_field_count(base, folder):
    names, rows = base
    rows = [list(r) for r in rows]
    rows[20] = rows[20] + ["0.0"]         # line 22: one field too many
    rows[30] = rows[30][:5]               # line 32: cut short
    return _write(folder, "fields.csv", join(names, rows))


def _wrong_delimiter(base, folder):
    names, rows = base
    return _write(folder, "semicolons.csv", ",".join(names) + "\n"
                  + "\n".join(";".join(r) for r in rows) + "\n")


def _unsorted(base, folder):
    names, rows = base
    return _write(folder, "reversed.csv", join(names, rows[::-1]))


def _time_reset(base, folder):
    names, rows = base
    half = len(rows) // 2
    return _write(folder, "reset.csv", join(names, rows[half:] + rows[:half]))


def _appended_run(base, folder):
    """A second run appended to the file, header and all (a restarted logger)."""
    names, rows = base
    second = set_column(names, [list(r) for r in rows[:100]], "actual_q", lambda q: q + 1e-3)
    return _write(folder, "appended.csv", join(names, rows) + join(names, second))


def _repeated_header(base, folder):
    names, rows = base
    rows = [list(r) for r in rows]
    rows[400] = list(names)                                # line 402
    return _write(folder, "header_again.csv", join(names, rows))


def _duplicate_rows(base, folder):
    names, rows = base
    rows = [list(r) for r in rows]
    rows = rows[:50] + [rows[49]] + rows[50:]              # line 52 repeats line 51
    return _write(folder, "dup_rows.csv", join(names, rows))


def _duplicate_time(base, folder):
    names, rows = base
    rows = [list(r) for r in rows]
    rows[70][col(names, "timestamp")] = rows[69][col(names, "timestamp")]  # line 72
    return _write(folder, "dup_time.csv", join(names, rows))


def _constant_time(base, folder):
    names, rows = base
    rows = [list(r) for r in rows]
    for r in rows:
        r[col(names, "timestamp")] = "12.5"
    return _write(folder, "const_time.csv", join(names, rows))


def _gap(base, folder):
    names, rows = base
    rows = [list(r) for r in rows]
    t = col(names, "timestamp")
    for r in rows[600:]:                                  # 3 s pause before line 602
        r[t] = repr(float(r[t]) + 3.0)
    return _write(folder, "gap.csv", join(names, rows))


def _too_short(base, folder):
    names, rows = base
    return _write(folder, "short.csv", join(names, rows[:8]))


def _single_row(base, folder):
    names, rows = base
    return _write(folder, "one_row.csv", join(names, rows[:1]))


def _degrees(base, folder):
    names, rows = base
    rows = [list(r) for r in rows]
    for prefix in ("actual_q", "target_q"):
        set_column(names, rows, prefix, np.rad2deg)
    for prefix in ("actual_qd", "target_qd", "target_qdd"):
        set_column(names, rows, prefix, np.rad2deg)
    return _write(folder, "degrees.csv", join(names, rows))


def _degrees_small_motion(base, folder):
    """q in degrees, qd in rad/s, all |q| < 6 deg: only dq/dt vs qd tells."""
    names, rows = base
    rows = [list(r) for r in rows]
    for prefix in ("actual_q", "target_q"):
        set_column(names, rows, prefix, lambda q: np.rad2deg(0.02 * q))
    for prefix in ("actual_qd", "target_qd"):
        set_column(names, rows, prefix, lambda qd: 0.02 * qd)
    return _write(folder, "degrees_small.csv", join(names, rows))


def _five_joints(base, folder):
    names, rows = drop_joint(*base, 5)
    return _write(folder, "five_joints.csv", join(names, rows))


def _seven_joints(base, folder):
    names, rows = add_joint(*base)
    return _write(folder, "seven_joints.csv", join(names, rows))


def _absurd_rows(base, folder):
    names, rows = base
    rows = [list(r) for r in rows]
    for k in (200, 201, 202):                              # lines 202-204
        for i, n in enumerate(names):
            if n != "timestamp":
                rows[k][i] = "1e305"
    return _write(folder, "absurd.csv", join(names, rows))


def _absurd_current(base, folder):
    names, rows = base
    rows = [list(r) for r in rows]
    rows[300][col(names, "actual_current_0")] = "-3.2e305"  # line 302
    return _write(folder, "absurd_current.csv", join(names, rows))


def _binary(base, folder):
    rng = np.random.default_rng(0)
    return _write(folder, "binary.csv", rng.integers(0, 256, 4000, dtype=np.uint8).tobytes(),
                  mode="wb")


def _latin1_garbage(base, folder):
    data = bytes(range(0x80, 0x100)) * 20          # no NUL, not UTF-8
    return _write(folder, "latin1.csv", data, mode="wb")


def _utf16(base, folder):
    names, rows = base
    return _write(folder, "utf16.csv", join(names, rows[:200]).encode("utf-16"), mode="wb")


def _utf8_bom(base, folder):
    names, rows = base
    return _write(folder, "bom.csv", b"\xef\xbb\xbf" + join(names, rows).encode(), mode="wb")


def _stray_bytes(base, folder):
    """A NUL deep in the file and a Latin-1 byte in a cell spoil only their rows."""
    names, rows = base
    rows = [list(r) for r in rows]
    rows[500][col(names, "actual_q_1")] += "\x00"          # line 502
    text = join(names, rows).encode()
    cell = ",".join(rows[800]).encode()                     # line 802
    text = text.replace(cell, cell[:-1] + b"\xb0")
    return _write(folder, "stray_bytes.csv", text, mode="wb")


def _milliseconds(base, folder):
    names, rows = base
    rows = [list(r) for r in rows]
    t = col(names, "timestamp")
    for r in rows:
        r[t] = repr(1000 * float(r[t]))
    return _write(folder, "millis.csv", join(names, rows))


def _directory(base, folder):
    path = folder / "a_folder.csv"
    path.mkdir()
    return path


def _missing_file(base, folder):
    return folder / "does_not_exist.csv"


def _headerless_wrong_width(base, folder):
    rows = [["0.0"] * 22, ["0.01"] + ["0.0"] * 21]
    return _write(folder, "width22.csv", join(None, rows))


def _npz_mismatch(base, folder):
    path = folder / "mismatch.npz"
    t = np.arange(50) * 0.01
    np.savez(path, time=t, q=np.zeros((50, 6)), qd=np.zeros((49, 6)), current=np.ones((50, 6)))
    return path


def _npz_nan(base, folder):
    path = folder / "nan.npz"
    t = np.arange(50) * 0.01
    qd = np.zeros((50, 6))
    qd[17, 3] = np.nan
    np.savez(path, time=t, q=np.zeros((50, 6)), qd=qd, current=np.ones((50, 6)))
    return path


def _npz_3d(base, folder):
    path = folder / "cube.npz"
    np.savez(path, time=np.arange(5.0), q=np.zeros((5, 6, 2)), qd=np.zeros((5, 6)),
             current=np.ones((5, 6)))
    return path


def _npz_text(base, folder):
    path = folder / "text.npz"
    np.savez(path, time=np.array(["a", "b"]), q=np.zeros((2, 6)), qd=np.zeros((2, 6)),
             current=np.ones((2, 6)))
    return path


def _not_npz(base, folder):
    return _write(folder, "broken.npz", b"PK\x03\x04 this is not a zip archive", mode="wb")


CASES = {
    "empty-file": Case(_empty, error=[r"empty\.csv", r"file is empty"]),
    "blank-and-comments": Case(_blank, error=[r"blank\.csv", r"file is empty"]),
    "header-only": Case(_header_only, error=[r"header_only\.csv", r"only a header.*line 1"]),
    "missing-column": Case(_missing_column, error=[r"no_current\.csv",
                                                   r"missing column.*'actual_current_3'"]),
    "duplicate-column-name": Case(_duplicate_column, error=[
        r"dup_column\.csv", r"'actual_q_2'.*(twice|more than once)", r"column"]),
    "text-in-one-cell": Case(_text_cell, warn=[r"text_cell\.csv", r"dropped 1 of 1324 rows",
                                               r"line 42: column 'actual_qd_2': 'fast'"],
                             dropped=[42]),
    "text-in-a-whole-column": Case(_text_column, error=[
        r"text_column\.csv", r"1324 of 1324 rows", r"line 2: column 'actual_qd_2'"]),
    "empty-cells": Case(_empty_cells, error=[
        r"empty_cells\.csv", r"line 102: column 'actual_current_1': '' is not a number"]),
    "nan-cell": Case(_nan_cell, error=[r"nan_cell\.csv, line 8, column 'actual_current_1'",
                                       r"nan"]),
    "inf-cell": Case(_inf_cell, error=[r"inf_cell\.csv, line 5, column 'timestamp'", r"inf"]),
    "overflowing-number": Case(_overflow_cell, error=[
        r"overflow\.csv, line 11, column 'actual_q_4'", r"inf"]),
    "truncated-last-line": Case(_truncated_last_line, warn=[
        r"truncated\.csv", r"dropped 1 of 1324 rows", r"line 1325: \d+ fields, the header has"],
        dropped=[1325]),
    "wrong-field-count": Case(_wrong_field_count, warn=[
        r"fields\.csv", r"dropped 2 of 1324 rows", r"line 22: \d+ fields",
        r"line 32: 5 fields"], dropped=[22, 32]),
    "wrong-delimiter": Case(_wrong_delimiter, error=[
        r"semicolons\.csv", r"malformed", r"line 2: 1 fields?, the header has", r"delimiter"]),
    "unsorted-time": Case(_unsorted, error=[r"reversed\.csv", r"column 'timestamp'",
                                            r"line \d+", r"out of line"]),
    "time-resets-halfway": Case(_time_reset, error=[r"reset\.csv", r"column 'timestamp'",
                                                    r"line \d+"]),
    "second-run-appended": Case(_appended_run, error=[
        r"appended\.csv", r"100 of 1425 rows", r"first: line 1327, column 'timestamp'"]),
    "header-repeated-mid-file": Case(_repeated_header, warn=[
        r"header_again\.csv", r"dropped 1 of 1324 rows",
        r"line 402: repeats the header \(line 1\)"], dropped=[402]),
    "duplicate-row": Case(_duplicate_rows, warn=[r"dup_rows\.csv", r"dropped 1 of 1325 rows",
                                                 r"line 52: exact duplicate of line 51"],
                          dropped=[52]),
    "duplicate-time-stamp": Case(_duplicate_time, warn=[
        r"dup_time\.csv", r"dropped 1 of 1324 rows",
        r"line 72: column 'timestamp': t=\S+ repeats line 71 with different values"],
        dropped=[72]),
    "constant-time": Case(_constant_time, error=[r"const_time\.csv", r"column 'timestamp'"]),
    "gap-in-time": Case(_gap, warn=[r"gap\.csv", r"1 gap", r"3\.0\d* s before line 602",
                                    r"t=\S+"], dropped=[]),
    "too-short-to-differentiate": Case(_too_short, error=[
        r"short\.csv", r"8 (rows|samples)", r"at least 21"]),
    "single-row": Case(_single_row, error=[r"one_row\.csv", r"too short", r"at least"]),
    "degrees": Case(_degrees, warn=[r"degrees\.csv", r"look like degrees", r"deg2rad"], units=True,
                    dropped=[]),
    "degrees-small-motion": Case(_degrees_small_motion, warn=[
        r"degrees_small\.csv", r"actual_q_\d", r"degrees", r"57"], dropped=[], units=True),
    "five-joints-robot-has-six": Case(_five_joints, error=[
        r"five_joints\.csv", r"actual_q_5", r"5 .*n_joints=6|6 joints"]),
    "seven-joints-robot-has-six": Case(_seven_joints, error=[
        r"seven_joints\.csv", r"actual_q_6", r"7 .*n_joints=6|6 joints"]),
    "absurd-rows": Case(_absurd_rows, warn=[r"absurd\.csv", r"dropped 3 of 1324 rows",
                                            r"lines 202, 203, 204", r"1e\+305"],
                        dropped=[202, 203, 204]),
    "absurd-current": Case(_absurd_current, warn=[
        r"absurd_current\.csv", r"dropped 1 of 1324 rows",
        r"line 302: column 'actual_current_0': \|value\| = 3\.2e\+305"], dropped=[302]),
    "binary-garbage": Case(_binary, error=[r"binary\.csv", r"binary"]),
    "not-utf8-text": Case(_latin1_garbage, error=[r"latin1\.csv", r"UTF-8|encoding"]),
    "utf16-encoded": Case(_utf16, warn=None, dropped=[]),
    "utf8-bom": Case(_utf8_bom, warn=None, dropped=[]),
    "stray-nul-and-latin1-bytes": Case(_stray_bytes, warn=[
        r"stray_bytes\.csv", r"dropped 2 of 1324 rows", r"line 502: column 'actual_q_1'",
        r"line 802: column '\w+': '.*\ufffd' is not a number"], dropped=[502, 802]),
    "time-in-milliseconds": Case(_milliseconds, warn=[
        r"millis\.csv", r"'actual_q_0' and qd\[0\] disagree: position steps are 0\.001 times",
        r"time_scale=1e-3"], dropped=[], units=True),
    "directory": Case(_directory, error=[r"a_folder\.csv", r"folder"]),
    "no-such-file": Case(_missing_file, error=[r"does_not_exist\.csv", r"no such file"]),
    "headerless-unknown-width": Case(_headerless_wrong_width, error=[
        r"width22\.csv", r"22 fields", r"column_map"]),
    "npz-length-mismatch": Case(_npz_mismatch, error=[r"mismatch\.npz", r"key 'qd'.* 49 rows",
                                                      r"time has 50"]),
    "npz-nan": Case(_npz_nan, error=[r"nan\.npz, row 17, column 'qd'\[:, 3\]", r"nan"]),
    "npz-3d-array": Case(_npz_3d, error=[r"cube\.npz", r"'q'", r"shape \(5, 6, 2\)"]),
    "npz-text-array": Case(_npz_text, error=[r"text\.npz", r"'time'", r"not numbers"]),
    "npz-not-a-zip": Case(_not_npz, error=[r"broken\.npz", r"not a readable \.npz"]),
}
#: Cases that load cleanly, without any warning (encodings we decode).
CLEAN = {"utf16-encoded", "utf8-bom"}


@pytest.fixture
def case_path(request, base, tmp_path):
    return CASES[request.param].make(base, tmp_path)


def _load(path, **kwargs):
    return load_recording(path, n_joints=N_JOINTS, **kwargs)


def _assert_names_all(message, patterns):
    for pattern in patterns:
        assert re.search(pattern, message), f"{pattern!r} not in {message!r}"


def test_at_least_15_kinds():
    assert len(CASES) >= 15
    assert sum(c.error is not None for c in CASES.values()) >= 15


@pytest.mark.parametrize("case_path", list(CASES), indirect=True)
def test_loader(case_path, request):
    case = CASES[request.node.callspec.params["case_path"]]
    if case.error is not None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RecordingWarning)
            with pytest.raises((ValueError, OSError)) as info:
                rec = _load(case_path, **case.loader_kwargs)
                # loaders accept what derivatives cannot use: make_inputs says so
                make_inputs(rec)
        # a plain ValueError/OSError, not numpy / dict internals dressed as one
        assert type(info.value) in (ValueError, OSError, FileNotFoundError,
                                    IsADirectoryError), type(info.value)
        _assert_names_all(str(info.value), case.error)
        return
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rec = _load(case_path, **case.loader_kwargs)
    ours = [w for w in caught if issubclass(w.category, RecordingWarning)]
    if case.warn is None:
        assert not ours, [str(w.message) for w in ours]
    else:
        assert len(ours) == 1, [str(w.message) for w in ours]
        _assert_names_all(str(ours[0].message), case.warn)
    assert rec.metadata["dropped_rows"] == case.dropped
    assert rec.n_joints == N_JOINTS
    assert np.all(np.diff(rec.time) > 0) and np.all(np.isfinite(rec.current))


@pytest.mark.parametrize("case_path", list(CASES), indirect=True)
def test_cli(case_path, request, capsys):
    case = CASES[request.node.callspec.params["case_path"]]
    status = main(DIAGNOSE + [str(case_path)])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    lines = [line for line in err.splitlines() if line.strip()]
    if case.error is not None:
        expected = 2 if case.cli_status is None else case.cli_status
        assert status == expected, err
        assert len(lines) == 1, err
        assert lines[0].startswith("gpcd diagnose: error: "), err
        assert case_path.name in lines[0]
        return
    if case.units:
        # flagged units: refused with one error line (the file's warning is left to
        # it), diagnosed once confirmed
        assert status == 2, err
        assert len(lines) == 1 and lines[0].startswith("gpcd diagnose: error: "), err
        assert case_path.name in lines[0] and "--units-confirmed" in lines[0], err
        status = main(DIAGNOSE + ["--units-confirmed", str(case_path)])
        out, err = capsys.readouterr()
        lines = [line for line in err.splitlines() if line.strip()]
    warned = [line for line in lines if line.startswith("gpcd diagnose: warning: ")]
    assert len(warned) == (0 if case.warn is None else 1), err
    if case.warn is not None:
        _assert_names_all(warned[0], case.warn)
    assert status == 0, err
    assert all(line.startswith("gpcd diagnose: warning: ") for line in lines), err


# --------------------------------------------------------------------------- other readers
def test_read_csv_reports_the_same_rows(base, tmp_path):
    """read_csv with a column map drops and reports like read_rtde_csv."""
    path = _wrong_field_count(base, tmp_path)
    column_map = {"time": "timestamp", "q": "actual_q", "qd": "actual_qd",
                  "current": "actual_current"}
    with pytest.warns(RecordingWarning, match=r"fields\.csv: dropped 2 of 1324 rows"):
        rec = read_csv(path, column_map, n_joints=N_JOINTS)
    assert rec.metadata["dropped_rows"] == [22, 32]


def test_npz_with_more_joints_than_the_robot(tmp_path):
    path = tmp_path / "seven.npz"
    np.savez(path, time=np.arange(30) * 0.01, q=np.zeros((30, 7)), qd=np.zeros((30, 7)),
             current=np.ones((30, 7)))
    with pytest.raises(ValueError, match=r"seven\.npz: q has 7 joint column.*expected 6.*"
                                         r"more joints than the robot"):
        read_npz(path, n_joints=N_JOINTS)


@pytest.mark.parametrize("reader", [
    read_rtde_csv, read_npz, lambda path: read_csv(path, "ur10e_mamedov")],
    ids=["read_rtde_csv", "read_npz", "read_csv"])
def test_readers_name_a_folder(tmp_path, reader):
    with pytest.raises(ValueError, match=rf"{re.escape(str(tmp_path))}: is a folder, not a file"):
        reader(tmp_path)


def test_too_short_for_the_filter_names_the_minimum():
    t = np.arange(8) * 0.01
    with pytest.raises(ValueError, match=r"8 samples.*at least 21"):
        differentiate(t, np.sin(t))
    with pytest.raises(ValueError, match=r"8 samples.*at least 19"):
        differentiate(t, np.sin(t), method="butter")


def test_features_name_the_short_recording():
    t = np.arange(8) * 0.01
    rec = Recording(time=t, q=np.zeros((8, 2)), qd=np.zeros((8, 2)), current=np.ones((8, 2)),
                    name="short.csv")
    with pytest.raises(ValueError, match=r"recording 'short\.csv'.*8 samples.*at least 21"):
        InverseDynamicsFeatures(augmented=False).fit_transform(rec)


def test_dropped_rows_are_never_silent(base, tmp_path):
    """Whatever a loader drops, the warning counts it and metadata lists it."""
    for make in (_text_cell, _truncated_last_line, _duplicate_rows, _absurd_rows):
        path = make(base, tmp_path)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            rec = load_recording(path)
        n_lines = len([ln for ln in path.read_text().split("\n") if ln.strip()]) - 1
        dropped = rec.metadata["dropped_rows"]
        assert rec.n_samples + len(dropped) == n_lines
        message = " ".join(str(w.message) for w in caught)
        assert f"dropped {len(dropped)} of {n_lines} rows" in message


def test_a_row_is_dropped_once_for_one_reason():
    """A duplicated garbage row is one duplicate and one absurd row, not three."""
    from sklearn_gpcd.io._validation import finalize_recording

    n = 40
    time = np.arange(n) * 0.01
    q = np.zeros((n, 2))
    q[10] = q[11] = 1e305
    time[11] = time[10]
    columns = {"time": time, "q": q, "qd": np.zeros((n, 2)), "current": np.ones((n, 2))}
    labels = {key: [f"'{key}_{j}'" for j in range(2)] for key in columns}
    labels["time"] = ["'t'"]
    with pytest.warns(RecordingWarning, match=r"x\.csv: dropped 2 of 40 rows \(lines 12, 13\):"
                                              r" 1 exact duplicate .*; 1 absurd"):
        rec = finalize_recording("x.csv", columns, np.arange(n) + 2, column_labels=labels)
    assert rec.metadata["dropped_rows"] == [12, 13] and rec.n_samples == 38


def test_npz_header_claiming_more_rows_than_the_file_holds_is_refused_cheaply(tmp_path):
    """A header claiming 1e9 rows in a small file: one ValueError naming the key, from
    the sizes alone (NumPy would allocate 45 GiB before reading)."""
    import tracemalloc
    import zipfile

    path = tmp_path / "forged.npz"
    n = 50
    np.savez(path, time=np.arange(n) * 0.002, q=np.zeros((n, 6)), qd=np.zeros((n, 6)),
             current=np.ones((n, 6)))
    with zipfile.ZipFile(path) as archive:
        entries = {name: archive.read(name) for name in archive.namelist()}
    data = entries["q.npy"]
    header = np.lib.format.header_data_from_array_1_0(np.zeros((n, 6)))
    forged = io.BytesIO()
    np.lib.format.write_array_header_1_0(forged, dict(header, shape=(10**9, 6)))
    entries["q.npy"] = forged.getvalue() + data[len(data) - n * 6 * 8:]
    with zipfile.ZipFile(path, "w") as archive:
        for name, value in entries.items():
            archive.writestr(name, value)
    tracemalloc.start()
    try:
        with pytest.raises(ValueError, match=r"key 'q' claims shape \(1000000000, 6\)"):
            read_npz(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 10 * 2**20  # nothing near the claimed 45 GiB was allocated
