"""Tests for sklearn_gpcd.io: readers, writer, row cleaning, error messages."""

import builtins
import re
import warnings
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sklearn_gpcd.io import (
    COLUMN_PRESETS,
    Recording,
    RecordingWarning,
    detect_format,
    load_recording,
    load_recordings,
    read_csv,
    read_npz,
    read_rosbag,
    read_rtde_csv,
    write_rtde_csv,
)
from sklearn_gpcd.io._validation import glitch_mask, increasing_subsequence

N_JOINTS = 6


# --------------------------------------------------------------------------- helpers
def make_recording(rng, n=60, n_joints=N_JOINTS, full=True, units="A"):
    """A smooth synthetic recording with jittered (irregular) sampling."""
    time = 1234.5 + np.cumsum(rng.uniform(0.002, 0.034, n))
    phase = rng.uniform(0, 2 * np.pi, n_joints)
    q = 0.8 * np.sin(time[:, None] + phase)
    qd = 0.8 * np.cos(time[:, None] + phase)
    fields = dict(time=time, q=q, qd=qd, current=rng.normal(size=(n, n_joints)),
                  units=units, name="synthetic")
    if full:
        fields.update(
            qdd=-q + rng.normal(scale=1e-3, size=q.shape),
            target_q=q + 1e-4, target_qd=qd, target_qdd=-q,
            target_current=rng.normal(size=(n, n_joints)),
            target_torque=rng.normal(scale=30, size=(n, n_joints)),
            labels=(np.arange(n) // 20) % 2 * np.arange(n) // 20,
        )
    return Recording(**fields)


def ur_rows(rec, n_fields):
    """Headerless UR10e-style rows (t, q, qd, i, [extra])."""
    blocks = [rec.time[:, None], rec.q, rec.qd, rec.current]
    extra = n_fields - 19
    if extra:
        blocks.append(np.zeros((rec.n_samples, extra)) + 0.5)
    data = np.hstack(blocks)
    return [",".join(f"{v:.6f}" for v in row) for row in data]


def write_lines(path, lines):
    path.write_text("\n".join(lines) + "\n")
    return path


def rtde_text(rec, delimiter=","):
    """Header and rows of a minimal RTDE file as lists of field lists."""
    names = (["timestamp"] + [f"actual_q_{j}" for j in range(rec.n_joints)]
             + [f"actual_qd_{j}" for j in range(rec.n_joints)]
             + [f"actual_current_{j}" for j in range(rec.n_joints)])
    data = np.hstack([rec.time[:, None], rec.q, rec.qd, rec.current])
    rows = [[repr(v) for v in row] for row in data.tolist()]
    return names, rows


def fmt(value):
    return repr(float(value))


def write_table(path, names, rows, delimiter=","):
    lines = ([delimiter.join(names)] if names else []) + [delimiter.join(r) for r in rows]
    return write_lines(path, lines)


# --------------------------------------------------------------------------- real data
@pytest.mark.realdata
def test_every_ur10e_file_loads(ur10e_dir):
    files = sorted(ur10e_dir.rglob("*.csv"))
    assert len(files) == 45  # 4 + 2 + 22 + 6 + 11 (the README's "44" is off by one)
    per_folder = defaultdict(lambda: [0, 0])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for path in files:
            auto = load_recording(path)
            preset = load_recording(path, column_map="ur10e_mamedov")
            assert auto.equals(preset)
            assert auto.n_joints == N_JOINTS
            assert np.all(np.diff(auto.time) > 0)
            assert np.all(np.abs(auto.q) < 2 * np.pi + 0.25)
            assert np.all(np.abs(auto.qd) < 10)
            assert auto.metadata["t0"] == auto.time[0]
            assert auto.metadata["robot"] == "ur10e"
            n_fields = len(path.read_text().split("\n", 1)[0].split(","))
            assert (auto.target_torque is not None) == (n_fields == 31)
            n_lines = len([ln for ln in path.read_text().split("\n") if ln.strip()])
            assert auto.n_samples + len(auto.metadata["dropped_rows"]) == n_lines
            per_folder[path.parent.name][0] += 1
            per_folder[path.parent.name][1] += auto.n_samples
    assert dict(per_folder) == {
        "collision_detection_data_2020": [4, 15584],
        "collision_push_pose": [2, 3466],
        "identification_data": [22, 65878],
        "jointwise_motion": [6, 38327],
        "validation_data": [11, 14692],
    }
    warned = {Path(str(w.message).split(":")[0]).name for w in caught
              if issubclass(w.category, RecordingWarning)
              and not str(w.message).startswith("headerless")}
    assert warned == {"ur-20_02_19_15harm50secLoad.csv", "ur-19_09_27-11_32_02.csv"}
    guessed = {str(w.message).split(" fields")[0] for w in caught
               if str(w.message).startswith("headerless")}   # said per layout, not per file
    assert guessed == {f"headerless text with {n}" for n in (19, 25, 31)}


@pytest.mark.realdata
def test_ur10e_corrupt_rows_are_dropped_with_one_warning(ur10e_dir):
    path = ur10e_dir / "identification_data" / "ur-20_02_19_15harm50secLoad.csv"
    with pytest.warns(RecordingWarning) as record:
        rec = load_recording(path, column_map="ur10e_mamedov")
    assert len(record) == 1
    message = str(record[0].message)
    assert "ur-20_02_19_15harm50secLoad.csv" in message
    assert "line 2:" in message and "line 6107: 20 fields" in message
    # lines 2-10 are a garbage burst (bad time stamps / huge values), 6107 is truncated
    assert rec.metadata["dropped_rows"] == list(range(2, 11)) + [6107]
    assert rec.time[0] == 3047.693  # line 1 is valid and kept
    assert rec.n_samples == 6107 - 10


@pytest.mark.realdata
def test_ur10e_numeric_garbage_with_plausible_time_is_dropped(ur10e_dir):
    path = ur10e_dir / "identification_data" / "ur-19_09_27-11_32_02.csv"
    with pytest.warns(RecordingWarning, match=r"ur-19_09_27-11_32_02\.csv.*line 2"):
        rec = load_recording(path)
    assert rec.metadata["dropped_rows"] == list(range(2, 21))
    assert np.abs(rec.q).max() < np.pi and np.abs(rec.current).max() < 50


@pytest.mark.realdata
def test_ur10e_irregular_sampling_is_kept(ur10e_dir):
    rec = load_recording(ur10e_dir / "identification_data" / "ur-20_02_05-20sec_12harm.csv")
    dt = np.diff(rec.time)
    assert dt.min() < 0.009 and dt.max() > 0.03  # logged 8-34 ms, not resampled
    assert rec.metadata["t0"] > 100  # time not shifted to zero


# --------------------------------------------------------------------------- RTDE CSV
@pytest.mark.parametrize("delimiter", [",", " "])
@pytest.mark.parametrize("units", ["A", "Nm"])
def test_rtde_round_trip_is_exact(tmp_path, rng, delimiter, units):
    rec = make_recording(rng, units=units)
    path = write_rtde_csv(rec, tmp_path / "log.csv", delimiter=delimiter)
    header = path.read_text().split("\n", 1)[0]
    assert (delimiter in header) and header.startswith("timestamp")
    assert ("actual_current_as_torque_0" in header) == (units == "Nm")
    back = read_rtde_csv(path)
    assert back.equals(rec)  # atol=0: repr floats round-trip exactly
    assert back.labels.dtype.kind == "i"
    assert back.metadata["dropped_rows"] == []
    assert back.metadata["delimiter"] == delimiter
    assert load_recording(path).equals(rec)


@given(values=st.lists(st.floats(-6.0, 6.0, allow_nan=False), min_size=24, max_size=24),
       steps=st.lists(st.floats(1e-4, 1.0), min_size=4, max_size=4))
@settings(max_examples=30, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_rtde_round_trip_any_float(tmp_path, values, steps):
    values = np.array(values).reshape(4, 6)
    rec = Recording(time=np.cumsum(steps), q=values, qd=values[::-1], current=-values)
    path = write_rtde_csv(rec, tmp_path / "h.csv")
    assert read_rtde_csv(path, max_joint_speed=None).equals(rec)


def test_rtde_header_in_ur_rtde_style(tmp_path, rng):
    """ur_rtde startFileRecording: all recipe outputs, commas, 6 decimals."""
    rec = make_recording(rng, n=30, full=False)
    vec = {  # ur_rtde's default recording order (subset), vectors of 6
        "timestamp": rec.time[:, None], "target_q": rec.q, "target_qd": rec.qd,
        "target_qdd": -rec.q, "target_current": rec.current, "target_moment": 10 * rec.current,
        "actual_q": rec.q, "actual_qd": rec.qd, "actual_current": rec.current,
        "joint_control_output": rec.current, "actual_TCP_pose": rec.q,
        "actual_digital_input_bits": np.full((30, 1), 65536.0),
        "joint_temperatures": np.full((30, 6), 31.5), "robot_mode": np.full((30, 1), 7.0),
        "joint_mode": np.full((30, 6), 253.0), "speed_scaling": np.ones((30, 1)),
    }
    names = [k if v.shape[1] == 1 else f"{k}_{j}" for k, v in vec.items()
             for j in range(v.shape[1])]
    data = np.hstack(list(vec.values()))
    rows = [[f"{x:.6f}" for x in row] for row in data]
    path = write_table(tmp_path / "ur_rtde.csv", names, rows)
    assert detect_format(path) == "rtde"
    back = load_recording(path)
    np.testing.assert_allclose(back.q, rec.q, atol=5e-7)
    np.testing.assert_allclose(back.target_torque, 10 * rec.current, atol=5e-7)
    np.testing.assert_allclose(back.target_qdd, -rec.q, atol=5e-7)
    assert back.qdd is None and back.labels is None and back.units == "A"


def test_rtde_header_in_record_py_style(tmp_path, rng):
    """UR's record.py: recipe order, space-separated, Python str values."""
    rec = make_recording(rng, n=30, full=False)
    names = (["timestamp"] + [f"actual_current_{j}" for j in range(6)]
             + [f"actual_q_{j}" for j in range(6)] + ["actual_digital_input_bits"]
             + [f"actual_qd_{j}" for j in range(6)] + ["robot_mode"])
    data = np.hstack([rec.time[:, None], rec.current, rec.q, np.zeros((30, 1)), rec.qd,
                      np.full((30, 1), 7)])
    rows = [[str(v) for v in row] for row in data.tolist()]
    rows = [r[:13] + [str(int(float(r[13])))] + r[14:-1] + ["7"] for r in rows]
    path = write_table(tmp_path / "robot_data.csv", names, rows, delimiter=" ")
    back = read_rtde_csv(path)
    assert back.equals(rec.replace(name="x"))
    assert back.metadata["delimiter"] == " "


def test_rtde_torque_column_is_used_when_no_current(tmp_path, rng):
    rec = make_recording(rng, n=20, full=False, units="Nm")
    path = write_rtde_csv(rec, tmp_path / "torque.csv")
    assert read_rtde_csv(path).units == "Nm"
    with pytest.raises(ValueError, match=r"torque\.csv.*'actual_current_0'"):
        read_rtde_csv(path, current="actual_current")


def test_write_rtde_rejects_nan_and_unknown_units(tmp_path, rng):
    rec = make_recording(rng, n=10, full=False)
    q = rec.q.copy()
    q[3, 2] = np.nan
    with pytest.raises(ValueError, match=r"actual_q_2 is nan at sample 3"):
        write_rtde_csv(rec.replace(q=q), tmp_path / "x.csv")
    with pytest.raises(ValueError, match="units 'mA'"):
        write_rtde_csv(rec.replace(units="mA"), tmp_path / "x.csv")


# --------------------------------------------------------------------------- generic CSV / NPZ
def test_read_csv_with_names_and_indices(tmp_path, rng):
    rec = make_recording(rng, n=25, n_joints=2, full=False)
    names = ["t", "q0", "q1", "v0", "v1", "i0", "i1", "comment"]
    data = np.hstack([rec.time[:, None], rec.q, rec.qd, rec.current])
    rows = [[repr(v) for v in row] + ["free text"] for row in data.tolist()]
    path = write_table(tmp_path / "g.csv", names, rows, delimiter=";")
    by_name = read_csv(path, {"time": "t", "q": ["q0", "q1"], "qd": ["v0", "v1"],
                              "current": ["i0", "i1"]})
    by_index = read_csv(path, {"time": 0, "q": range(1, 3), "qd": slice(3, 5),
                               "current": [5, 6]})
    assert by_name.equals(rec) and by_index.equals(rec)
    headerless = write_table(tmp_path / "h.tsv", None, [r[:-1] for r in rows], delimiter="\t")
    assert read_csv(headerless, {"time": 0, "q": range(1, 3), "qd": range(3, 5),
                                 "current": range(5, 7)}).equals(rec)


def test_read_csv_time_scale_and_units(tmp_path):
    path = write_lines(tmp_path / "ms.csv", ["0,0.1,0,2", "10,0.1,0,2", "20,0.1,0,2"])
    rec = read_csv(path, {"time": 0, "q": 1, "qd": 2, "current": 3}, time_scale=1e-3,
                   units="Nm")
    np.testing.assert_array_equal(rec.time, [0.0, 0.01, 0.02])
    assert rec.units == "Nm" and rec.n_joints == 1


@pytest.mark.parametrize("n_fields", [19, 25, 31])
def test_ur10e_preset_picks_layout_by_field_count(tmp_path, rng, n_fields):
    rec = make_recording(rng, n=30, full=False)
    path = write_lines(tmp_path / f"ur{n_fields}.csv", ur_rows(rec, n_fields))
    back = read_csv(path, "ur10e_mamedov")
    np.testing.assert_allclose(back.current, rec.current, atol=5e-7)
    assert (back.target_current is not None) == (n_fields == 31)
    if n_fields == 25:
        assert back.metadata["ignored_columns"] == list(range(19, 25))
    assert load_recording(path).equals(back)


def test_preset_unknown_field_count(tmp_path):
    path = write_lines(tmp_path / "u.csv", ["0,1,2", "1,2,3"])
    with pytest.raises(ValueError, match=r"u\.csv.*'ur10e_mamedov' has no layout for 3 fields"):
        read_csv(path, "ur10e_mamedov")
    with pytest.raises(ValueError, match="unknown column preset"):
        read_csv(path, "nope")
    with pytest.raises(ValueError, match=r"u\.csv: headerless text with 3 fields; pass column_map"):
        load_recording(path)
    assert set(COLUMN_PRESETS) == {"ur10e_mamedov", "panda_gaz"}
    with pytest.raises(ValueError, match="'panda_gaz' reads a folder of one-value-per-line"):
        read_csv(path, "panda_gaz")


def test_read_npz_default_and_key_map(tmp_path, rng):
    rec = make_recording(rng, n=20)
    arrays = {k: getattr(rec, k) for k in ("time", "q", "qd", "current", "qdd", "target_q",
                                           "target_qd", "target_qdd", "target_current",
                                           "target_torque", "labels")}
    np.savez(tmp_path / "a.npz", **arrays)
    assert read_npz(tmp_path / "a.npz").equals(rec)
    assert load_recording(tmp_path / "a.npz").equals(rec)
    np.savez(tmp_path / "b.npz", data=np.hstack([rec.time[:, None], rec.q, rec.qd, rec.current]))
    key_map = {"time": ("data", 0), "q": ("data", range(1, 7)), "qd": ("data", range(7, 13)),
               "current": ("data", range(13, 19))}
    back = read_npz(tmp_path / "b.npz", key_map)
    assert back.equals(Recording(time=rec.time, q=rec.q, qd=rec.qd, current=rec.current))
    with pytest.raises(ValueError, match=r"b\.npz: missing key 'q'"):
        read_npz(tmp_path / "b.npz", {"time": ("data", 0), "q": "q", "qd": "q", "current": "q"})
    bad = dict(arrays, qd=np.where(np.arange(20)[:, None] == 4, np.nan, rec.qd))
    np.savez(tmp_path / "c.npz", **bad)
    with pytest.raises(ValueError, match=r"c\.npz, row 4, column 'qd'\[:, 0\]: value is nan"):
        read_npz(tmp_path / "c.npz")


def test_load_recordings_folder(tmp_path, rng):
    rec = make_recording(rng, n=20)
    write_rtde_csv(rec, tmp_path / "b.csv")
    (tmp_path / "sub").mkdir()
    write_rtde_csv(rec, tmp_path / "sub" / "a.csv", delimiter=" ")
    np.savez(tmp_path / "c.npz", time=rec.time, q=rec.q, qd=rec.qd, current=rec.current)
    (tmp_path / "README.txt").write_text("not a recording")
    recs = load_recordings(tmp_path)
    assert [r.name for r in recs] == ["b.csv", "c.npz", "a.csv"]
    assert all(r.n_samples == 20 for r in recs)
    assert len(load_recordings([tmp_path / "b.csv", str(tmp_path / "sub" / "*.csv")])) == 2
    with pytest.raises(ValueError, match="no recordings found"):
        load_recordings(tmp_path / "sub" / "*.npz")


# --------------------------------------------------------------------------- dropped rows
def test_malformed_rows_dropped_with_one_warning(tmp_path, rng):
    rec = make_recording(rng, n=60, full=False)
    names, rows = rtde_text(rec)
    rows[9] = rows[9][:11]                      # truncated write -> line 11
    rows[30][4] = "0.1x\x07"                    # garbage text -> line 32
    path = write_table(tmp_path / "bad.csv", names, rows)
    with pytest.warns(RecordingWarning) as record:
        back = read_rtde_csv(path)
    assert len(record) == 1
    message = str(record[0].message)
    assert "bad.csv" in message and "line 11: 11 fields, the header has 19" in message
    assert "line 32: column 'actual_q_3'" in message
    assert back.metadata["dropped_rows"] == [11, 32]
    keep = np.setdiff1d(np.arange(60), [9, 30])
    assert back.equals(rec.slice().replace(time=rec.time[keep], q=rec.q[keep],
                                           qd=rec.qd[keep], current=rec.current[keep]))


def test_isolated_time_jumps_dropped(tmp_path, rng):
    rec = make_recording(rng, n=80, full=False)
    names, rows = rtde_text(rec)
    rows[20][0] = fmt(rec.time[5])              # jumps back -> line 22
    rows[50][0] = fmt(rec.time[-1] + 1e6)       # jumps ahead -> line 52
    rows[60][0] = rows[59][0]                   # duplicate -> line 62
    path = write_table(tmp_path / "jumps.csv", names, rows)
    with pytest.warns(RecordingWarning,
                      match=r"jumps\.csv: dropped 3 of 80 rows \(lines 22, 52, 62\)"):
        back = read_rtde_csv(path)
    assert back.metadata["dropped_rows"] == [22, 52, 62]
    assert np.all(np.diff(back.time) > 0)


def test_kinematic_glitch_dropped_unless_disabled(tmp_path, rng):
    rec = make_recording(rng, n=50, full=False)
    names, rows = rtde_text(rec)
    rows[25][3] = "253.0"                        # actual_q_2 spike -> line 27
    path = write_table(tmp_path / "spike.csv", names, rows)
    with pytest.warns(RecordingWarning, match=r"line 27: column 'actual_q_2': jumps"):
        back = read_rtde_csv(path)
    assert back.n_samples == 49
    with warnings.catch_warnings():
        warnings.simplefilter("error", RecordingWarning)
        assert read_rtde_csv(path, max_joint_speed=None).n_samples == 50


def test_logger_pause_loses_nothing(tmp_path, rng):
    rec = make_recording(rng, n=60, full=False)
    time = rec.time.copy()
    time[30:] += 120.0                           # two minutes without samples
    path = write_rtde_csv(rec.replace(time=time), tmp_path / "pause.csv")
    with pytest.warns(RecordingWarning) as record:
        back = read_rtde_csv(path)
    assert back.n_samples == 60 and back.metadata["dropped_rows"] == []
    # the pause is not an error, but it is reported (row after it, length)
    assert len(record) == 1
    assert re.search(r"pause\.csv: 1 gap in time .*: 120 s before line 32 ",
                     str(record[0].message))
    assert back.metadata["gaps"] == [[32, pytest.approx(time[30] - time[29])]]


def test_degrees_warn(tmp_path, rng):
    rec = make_recording(rng, n=30, full=False)
    path = write_rtde_csv(rec.replace(q=np.rad2deg(rec.q) + 90, qd=np.rad2deg(rec.qd)),
                          tmp_path / "deg.csv")
    with pytest.warns(RecordingWarning, match=r"deg\.csv: .*look like degrees"):
        back = read_rtde_csv(path)
    assert back.n_samples == 30  # glitch limits scale to degrees: nothing dropped


def test_row_cleaning_helpers():
    assert increasing_subsequence([3.0, 0.0, 0.1, 0.2]).tolist() == [False, True, True, True]
    t = np.arange(40) * 0.01
    q = np.zeros((40, 2))
    q[5:8] = [[4.0, 0.0], [0.0, 5.0], [9.0, 9.0]]  # a burst of garbage
    keep = glitch_mask(t, q, np.zeros((40, 2)), max_joint_speed=10.0)
    assert np.flatnonzero(~keep).tolist() == [5, 6, 7]


# --------------------------------------------------------------------------- bad input
def test_missing_columns_are_named(tmp_path, rng):
    rec = make_recording(rng, n=10, full=False)
    names, rows = rtde_text(rec)
    cut = [n.startswith("actual_current") for n in names]
    path = write_table(tmp_path / "nocur.csv", [n for n, c in zip(names, cut) if not c],
                       [[v for v, c in zip(r, cut) if not c] for r in rows])
    with pytest.raises(ValueError,
                       match=r"nocur\.csv: missing column\(s\) 'actual_current_0' \(current\)"):
        read_rtde_csv(path)
    with pytest.raises(ValueError, match=(r"nocur\.csv: missing column\(s\) 'i0' \(current\), "
                                          r"'i1' \(current\)")):
        read_csv(path, {"time": "timestamp", "q": "actual_q", "qd": "actual_qd",
                        "current": ["i0", "i1"]})
    with pytest.raises(ValueError, match=r"nocur\.csv: column map asks for column 40 \(current\)"):
        read_csv(path, {"time": 0, "q": range(1, 7), "qd": range(7, 13), "current": [40]})
    with pytest.raises(ValueError, match=r"lacks required field\(s\) \['current'\]"):
        read_csv(path, {"time": 0, "q": range(1, 7), "qd": range(7, 13)})
    with pytest.raises(ValueError, match=r"unknown field\(s\) \['torque'\]"):
        read_csv(path, {"time": 0, "q": 1, "qd": 2, "current": 3, "torque": 4})


def test_text_in_numeric_column_is_named(tmp_path, rng):
    rec = make_recording(rng, n=20, full=False)
    names, rows = rtde_text(rec)
    for row in rows:
        row[9] = "fast"                          # column actual_qd_2, every row
    path = write_table(tmp_path / "text.csv", names, rows)
    with pytest.raises(ValueError, match=(r"text\.csv: 20 of 20 rows .* malformed.*"
                                          r"first: line 2: column 'actual_qd_2': 'fast' "
                                          r"is not a number")):
        read_rtde_csv(path)


def test_nan_is_named(tmp_path, rng):
    rec = make_recording(rng, n=20, full=False)
    names, rows = rtde_text(rec)
    rows[6][14] = "nan"
    path = write_table(tmp_path / "nan.csv", names, rows)
    with pytest.raises(ValueError,
                       match=r"nan\.csv, line 8, column 'actual_current_1': value is nan"):
        read_rtde_csv(path)
    rows[6][14], rows[3][0] = "0.0", "inf"
    path = write_table(tmp_path / "inf.csv", names, rows)
    with pytest.raises(ValueError, match=r"inf\.csv, line 5, column 'timestamp': value is inf"):
        read_rtde_csv(path)
    headerless = write_lines(tmp_path / "h.csv", ur_rows(rec, 19)[:5] + ["9,nan" + ",0" * 17])
    with pytest.raises(ValueError, match=r"h\.csv, line 6, column 1 \(q\[0\]\): value is nan"):
        load_recording(headerless)


def test_fewer_joints_than_robot(tmp_path, rng):
    rec = make_recording(rng, n=20, n_joints=5, full=False)
    path = write_rtde_csv(rec, tmp_path / "five.csv")
    assert read_rtde_csv(path).n_joints == 5
    with pytest.raises(ValueError, match=r"five\.csv: missing column\(s\) 'actual_q_5' \(q\)"):
        read_rtde_csv(path, n_joints=6)
    with pytest.raises(ValueError, match=r"five\.csv: q has 5 joint column\(s\) .*expected 6"):
        read_csv(path, {"time": 0, "q": range(1, 6), "qd": range(6, 11),
                        "current": range(11, 16)}, n_joints=6)
    names, rows = rtde_text(make_recording(rng, n=20, full=False))
    drop = names.index("actual_qd_4")
    path = write_table(tmp_path / "gap.csv", names[:drop] + names[drop + 1:],
                       [r[:drop] + r[drop + 1:] for r in rows])
    with pytest.raises(ValueError, match=r"gap\.csv: missing column\(s\) 'actual_qd_4' \(qd\)"):
        read_rtde_csv(path)


def test_unsorted_timestamps_are_an_error(tmp_path, rng):
    rec = make_recording(rng, n=40, full=False)
    names, rows = rtde_text(rec)
    path = write_table(tmp_path / "rev.csv", names, rows[::-1])
    with pytest.raises(ValueError, match=(r"rev\.csv: 39 of 40 rows .*out of line.*"
                                          r"first: line \d+, column 'timestamp': t=")):
        read_rtde_csv(path)
    half = rows[20:] + rows[:20]                 # time resets halfway
    path = write_table(tmp_path / "reset.csv", names, half)
    with pytest.raises(ValueError, match=r"reset\.csv: 20 of 40 rows .*column 'timestamp'"):
        read_rtde_csv(path)


@pytest.mark.parametrize("content, message", [
    ("", r"empty\.csv: file is empty"),
    ("  \n\n", r"empty\.csv: file is empty"),
    ("# only a comment\n", r"empty\.csv: file is empty"),
    ("timestamp,actual_q_0,actual_qd_0,actual_current_0\n",
     r"empty\.csv: too short, only a header"),
    ("timestamp,actual_q_0,actual_qd_0,actual_current_0\n0.0,0.0,0.0,1.0\n",
     r"empty\.csv: too short, 1 valid sample\(s\)"),
])
def test_empty_or_short_file(tmp_path, content, message):
    path = tmp_path / "empty.csv"
    path.write_text(content)
    with pytest.raises(ValueError, match=message):
        load_recording(path, format="rtde")


def test_other_bad_sources(tmp_path):
    with pytest.raises(ValueError, match=r"nothere\.csv: no such file"):
        load_recording(tmp_path / "nothere.csv")
    binary = tmp_path / "rec.csv"
    binary.write_bytes(b"\x00\x01\x02binary")
    with pytest.raises(ValueError, match=r"rec\.csv: binary file"):
        read_csv(binary, "ur10e_mamedov")
    header = write_lines(tmp_path / "hdr.csv", ["a,b,c,d", "0,1,2,3", "1,1,2,3"])
    with pytest.raises(ValueError, match=r"hdr\.csv: non-RTDE header text"):
        load_recording(header)
    with pytest.raises(ValueError, match=r"hdr\.csv: no header line|missing column"):
        read_rtde_csv(header)
    with pytest.raises(ValueError, match="format must be"):
        load_recording(header, format="xls")
    notnpz = tmp_path / "x.npz"
    notnpz.write_text("hello")
    with pytest.raises(ValueError, match=r"x\.npz: not a readable \.npz archive"):
        load_recording(notnpz)


# --------------------------------------------------------------------------- ROS bags
def _joint_state_bag(path, ros, rng, n=30, extra_publisher=False, zero_stamps=False):
    pytest.importorskip("rosbags")
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros == 1 else Stores.ROS2_HUMBLE)
    JointState = store.types["sensor_msgs/msg/JointState"]
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    names = [f"joint_{j}" for j in range(3)]
    stamps = 100.0 + np.cumsum(rng.uniform(0.002, 0.01, n))
    q, qd, eff = (rng.uniform(-1, 1, (n, 3)) * 0.001 + k for k in (0.0, 0.2, 1.5))
    if ros == 1:
        from rosbags.rosbag1 import Writer
        writer, serialize = Writer(path), store.serialize_ros1
        header = lambda i, t: Header(seq=i, stamp=t, frame_id="")  # noqa: E731
    else:
        from rosbags.rosbag2 import Writer
        writer, serialize = Writer(path, version=9), store.serialize_cdr
        header = lambda i, t: Header(stamp=t, frame_id="")  # noqa: E731
    with writer:
        conn = writer.add_connection("/joint_states", JointState.__msgtype__, typestore=store)
        for i in range(n):
            sec = int(stamps[i])
            stamp = Time(sec=sec, nanosec=int(round((stamps[i] - sec) * 1e9)))
            if zero_stamps:
                stamp = Time(sec=0, nanosec=0)
            order = [2, 0, 1] if i % 2 else [0, 1, 2]  # publishers may reorder joints
            msg = JointState(header=header(i, stamp), name=[names[k] for k in order],
                             position=q[i, order], velocity=qd[i, order], effort=eff[i, order])
            writer.write(conn, int(stamps[i] * 1e9), serialize(msg, JointState.__msgtype__))
            if extra_publisher and i % 5 == 0:
                grip = JointState(header=header(i, stamp), name=["gripper"],
                                  position=np.zeros(1), velocity=np.zeros(1), effort=np.zeros(1))
                writer.write(conn, int(stamps[i] * 1e9) + 1,
                             serialize(grip, JointState.__msgtype__))
    stamps = np.array([int(s) + round((s - int(s)) * 1e9) * 1e-9 for s in stamps])
    return stamps, q, qd, eff


@pytest.mark.parametrize("ros", [1, 2])
def test_read_rosbag_joint_states(tmp_path, rng, ros):
    path = tmp_path / ("run.bag" if ros == 1 else "run")
    stamps, q, qd, eff = _joint_state_bag(path, ros, rng, extra_publisher=True)
    rec = load_recording(path)
    np.testing.assert_allclose(rec.time, stamps, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(rec.q, q)
    np.testing.assert_array_equal(rec.qd, qd)
    np.testing.assert_array_equal(rec.current, eff)
    assert rec.units == "A" and rec.metadata["time_source"] == "header.stamp"
    assert rec.metadata["joint_names"] == ["joint_0", "joint_1", "joint_2"]
    assert rec.metadata["other_messages"] == 6
    torque = read_rosbag(path, effort_is="torque", joint_names=["joint_2", "joint_0"])
    assert torque.units == "Nm"
    np.testing.assert_array_equal(torque.current, eff[:, [2, 0]])
    with pytest.raises(ValueError,
                       match=r"no topic '/arm/joint_states'; the bag has \['/joint_states'\]"):
        read_rosbag(path, topic="/arm/joint_states")
    with pytest.raises(ValueError, match=r"run.*: no usable JointState message; message 0: "
                       r"joint\(s\) \['elbow'\] missing"):
        read_rosbag(path, joint_names=["joint_0", "elbow"])
    with pytest.raises(ValueError, match="effort_is"):
        read_rosbag(path, effort_is="voltage")
    if ros == 2:
        db3 = next(path.glob("*.db3"))
        assert detect_format(db3) == "rosbag" and load_recording(db3).equals(rec)


def test_read_rosbag_falls_back_to_receive_time(tmp_path, rng):
    stamps, q, _, _ = _joint_state_bag(tmp_path / "z.bag", 1, rng, zero_stamps=True)
    rec = read_rosbag(tmp_path / "z.bag", n_joints=3)
    assert rec.metadata["time_source"] == "receive time"
    np.testing.assert_allclose(rec.time, stamps, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(rec.q, q)
    with pytest.raises(ValueError, match=r"z\.bag: q has 3 joint column\(s\) .*expected 6"):
        read_rosbag(tmp_path / "z.bag", n_joints=6)


def test_read_rosbag_without_rosbags(tmp_path, monkeypatch):
    real_import = builtins.__import__

    def blocked(name, *args, **kwargs):
        if name.startswith("rosbags"):
            raise ImportError("No module named 'rosbags'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", blocked)
    with pytest.raises(ImportError, match=re.escape("pip install 'sklearn-gpcd[rosbag]'")):
        read_rosbag(tmp_path / "x.bag")
