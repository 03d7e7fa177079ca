"""Every ``gpcd`` error and warning of the docs' list names its fix (issue #37).

The list is the table of ``docs/user_guide/cli_messages.rst``; this module
reads it. For each row a trigger below makes the message happen through the
command (:func:`sklearn_gpcd.cli.main`, on recordings the package simulates),
and the test checks the printed line: its kind (``gpcd CMD: error:``,
``gpcd CMD: warning:`` or a line of the normal output), the row's message
words, every ``literal`` of the row's fix (the option or the command), and
the bad file's name where the fix says "the file it names". A row without a
trigger or a trigger without a row fails: the table and the commands cannot
drift apart.
"""

import contextlib
import importlib.util
import io
import json
import re
import socket
import sys
from pathlib import Path

import numpy as np
import pytest

from sklearn_gpcd.cli import main
from sklearn_gpcd.datasets import simulate_d1
from sklearn_gpcd.io import write_rtde_csv
from sklearn_gpcd.io.recording import JOINT_SIGNALS

PAGE = Path(__file__).resolve().parents[1] / "docs" / "user_guide" / "cli_messages.rst"
NAMES_FILE = "the file it names"
KINDS = ("error", "warning", "printed")


def _literals(text):
    return re.findall(r"``(.+?)``", text)


def read_table(text):
    """``{key: {"kind", "command", "message", "fix"}}`` from the page's list-table."""
    rows = []
    for line in text.split(".. list-table::", 1)[1].splitlines()[1:]:
        if line.startswith("   * - "):
            rows.append([line[7:]])
        elif line.startswith("     - "):
            rows[-1].append(line[7:])
        elif line.startswith("       ") and rows:
            rows[-1][-1] += " " + line.strip()
        elif line.strip() and not line.startswith("   "):
            break
    header, *rows = rows
    assert [c.strip() for c in header] == ["Key", "Kind", "Command", "Message", "Fix"]
    table = {}
    for key, kind, command, message, fix in rows:
        (key,), (message,) = _literals(key), _literals(message)
        assert key not in table, f"row {key} twice"
        table[key] = {"kind": kind.strip(), "command": command, "message": message,
                      "fix": fix}
    return table


ROWS = read_table(PAGE.read_text())


# ------------------------------------------------------------------ data
def _rows(rec, idx):
    """``rec`` restricted to the samples ``idx``."""
    fields = {k: getattr(rec, k)[idx] for k in ("time", "labels", *JOINT_SIGNALS)
              if getattr(rec, k) is not None}
    return rec.replace(**fields)


def _rtde(rec, path):
    return str(write_rtde_csv(rec, path, robot_comment=True))


def _run(argv):
    """``gpcd ARGV`` in process: (status, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main([str(a) for a in argv])
    return status, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def sims(tmp_path_factory):
    """Three small simulated UR10e runs (RTDE CSV naming their robot), variants of
    the first one, a GP model trained on it and a detector calibrated on all three."""
    folder = tmp_path_factory.mktemp("messages")
    recs = [simulate_d1("ur10e", n_targets=3, random_state=seed) for seed in range(3)]
    rec = recs[0]
    s = {"folder": folder, "rec": rec,
         **{f"d{k}": _rtde(r, folder / f"d{k}.csv") for k, r in enumerate(recs)}}
    s["anon"] = str(write_rtde_csv(rec.replace(metadata={}), folder / "anon.csv"))
    columns = [rec.time[:, None], rec.q, rec.qd, rec.current, rec.target_current]
    s["mamedov"] = folder / "mamedov.csv"  # 25 fields: the ur10e_mamedov layout
    np.savetxt(s["mamedov"], np.hstack(columns), delimiter=",", fmt="%.9g")
    s["custom"] = folder / "custom.csv"  # 26 fields: no preset
    np.savetxt(s["custom"], np.hstack(columns + [np.ones((rec.n_samples, 1))]),
               delimiter=",", fmt="%.9g")
    s["model"], s["det"] = folder / "model.skops", folder / "det.skops"
    status, _, _ = _run(["train", s["d0"], "--model", "gp", "--n-support", "30", "-q",
                         "-o", s["model"]])
    assert status == 0
    status, out, err = _run(["calibrate", s["model"], s["d0"], s["d1"], s["d2"], "-q",
                             "-o", s["det"]])
    assert status == 0
    s["calibrate_output"] = (status, out, err)
    return s


def _text(path, lines):
    Path(path).write_text("\n".join(lines) + "\n")
    return str(path)


def _edit_lines(s, tmp, name, change):
    """The first run's RTDE file with ``change(data_lines)`` applied."""
    lines = Path(s["d0"]).read_text().splitlines()
    head = [i for i, line in enumerate(lines) if line.startswith(("#", "timestamp"))]
    body = lines[max(head) + 1:]
    change(body)
    return _text(tmp / name, lines[:max(head) + 1] + body)


def _fast_fail():
    """Options that make ``gpcd train`` stop right after reading (to see its warnings)."""
    return ["--model", "sp_c", "--signals", "none"]


FIVE_MAP = json.dumps({"time": 0, "q": [1, 2, 3, 4, 5], "qd": [6, 7, 8, 9, 10],
                       "current": [11, 12, 13, 14, 15]})
FULL_MAP = {"time": 0, "q": [1, 2, 3, 4, 5, 6], "qd": [7, 8, 9, 10, 11, 12],
            "current": [13, 14, 15, 16, 17, 18]}


def _free_port():
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _no_skops(mp):
    find_spec = importlib.util.find_spec
    mp.setattr(importlib.util, "find_spec",
               lambda name, *a, **k: None if name == "skops" else find_spec(name, *a, **k))


def _stop_before_fit(mp):
    import sklearn_gpcd.workflow as workflow

    def stop(*args, **kwargs):
        raise ValueError("stopped before the fit by the test")

    mp.setattr(workflow, "train_model", stop)
    mp.setattr(workflow, "compare_models", stop)


def _model_variant(s, tmp, name, features=True, training=None):
    from sklearn_gpcd.workflow import TrainedModel, load_model, save_model

    trained = load_model(s["model"])
    path = tmp / name
    save_model(TrainedModel(trained.regressor, trained.features if features else None,
                            training if training is not None else trained.training), path)
    return str(path)


def _damaged(s, tmp):
    """The detector file with its zip directory overwritten."""
    data = bytearray(Path(s["det"]).read_bytes())
    data[-256:] = bytes(256)
    path = tmp / "damaged.skops"
    path.write_bytes(bytes(data))
    return str(path)


def _nan_threshold(s, tmp):
    """The detector file with its thresholds edited to NaN."""
    import zipfile

    with zipfile.ZipFile(s["det"]) as archive:
        entries = {n: archive.read(n) for n in archive.namelist()}
    stack, files = [json.loads(entries["schema.json"])], []
    while stack:
        node = stack.pop()
        if isinstance(node, dict):
            inner = node.get("content")
            if isinstance(inner, dict) and "thresholds_" in inner.get("content", {}):
                files.append(inner["content"]["thresholds_"]["file"])
            stack.extend(node.values())
        elif isinstance(node, list):
            stack.extend(node)
    for name in files:
        out = io.BytesIO()
        np.save(out, np.load(io.BytesIO(entries[name])) * np.nan)
        entries[name] = out.getvalue()
    path = tmp / "nan.skops"
    with zipfile.ZipFile(path, "w") as archive:
        for name, data in entries.items():
            archive.writestr(name, data)
    return str(path)


def _envelope_file(s, tmp):
    """The detector file as written before the motion envelope was removed
    (issue 45): its rule holds the envelope's coefficients."""
    from sklearn_gpcd.persistence import load, save

    bundle = load(s["det"])
    rule = bundle["detector"].rules_[0]
    rule.envelope_ = np.full((len(np.atleast_2d(rule.thresholds_)[0]), 3), 0.5)
    return str(save(bundle, tmp / "envelope.skops"))


def _no_limit(s):
    from sklearn_gpcd.workflow import load_model

    training = dict(load_model(s["model"]).training)
    training.pop("acceleration_limit")
    return training


def _hide_matplotlib(mp):
    for name in [m for m in sys.modules if m == "matplotlib" or m.startswith("matplotlib.")]:
        mp.setitem(sys.modules, name, None)
    mp.setitem(sys.modules, "matplotlib", None)


def _first_joints(rec, n):
    """``rec`` with its first ``n`` joints only."""
    return rec.replace(**{k: getattr(rec, k)[:, :n] for k in JOINT_SIGNALS
                          if getattr(rec, k) is not None})


def _bump(rec):
    """A hard push on joint 2 early in the run (the hook has the rest to end)."""
    current = rec.current.copy()
    current[rec.n_samples // 4:rec.n_samples // 4 + 100, 1] += 20.0  # within the drive
    return rec.replace(current=current)


# Each trigger: (s, tmp_path, monkeypatch) -> dict(argv=[...], file=bad file name or None)
# or dict(output=(status, stdout, stderr)) for a command the fixture already ran.
T = {
    "robot-unknown": lambda s, t, mp: dict(
        argv=["train", s["d0"], "--robot", "nosuch", "-o", t / "m.skops"]),
    "urdf-missing": lambda s, t, mp: dict(
        argv=["train", s["d0"], "--robot", t / "arm.urdf", "-o", t / "m.skops"]),
    "column-map-unknown": lambda s, t, mp: dict(
        argv=["train", s["d0"], "--column-map", "nosuch", "-o", t / "m.skops"]),
    "column-map-json": lambda s, t, mp: dict(
        argv=["train", s["d0"], "--column-map", "{bad", "-o", t / "m.skops"]),
    "output-folder": lambda s, t, mp: dict(
        argv=["train", s["d0"], "-o", t / "nofolder" / "m.skops"]),
    "output-format": lambda s, t, mp: dict(argv=["train", s["d0"], "-o", t / "m.txt"]),
    "skops-missing": lambda s, t, mp: _no_skops(mp) or dict(
        argv=["train", s["d0"], "-o", t / "m.skops"]),
    "plot-is-file": lambda s, t, mp: dict(
        argv=["monitor", s["det"], s["d0"], "--plot", s["d0"]]),
    "band-format": lambda s, t, mp: dict(
        argv=["calibrate", s["model"], s["d0"], s["d1"], "--band", "1,2", "-o",
              t / "x.skops"]),
    "number-range": lambda s, t, mp: dict(
        argv=["train", s["d0"], "--n-support", "0", "-o", t / "m.skops"]),
    "signals-list": lambda s, t, mp: dict(
        argv=["train", s["d0"], "--signals", "foo", "-o", t / "m.skops"]),
    "file-missing": lambda s, t, mp: dict(
        argv=["monitor", t / "nosuch.skops", s["d0"]], file="nosuch.skops"),
    "no-recordings": lambda s, t, mp: dict(
        argv=["train", t / "nofolder" / "*.csv", "-o", t / "m.skops"], file="nofolder"),
    "recording-missing": lambda s, t, mp: dict(
        argv=["train", t / "missing.csv", "-o", t / "m.skops"], file="missing.csv"),
    "empty-file": lambda s, t, mp: dict(
        argv=["train", _text(t / "empty.csv", []), "-o", t / "m.skops"], file="empty.csv"),
    "binary-file": lambda s, t, mp: (t / "bin.csv").write_bytes(b"\x00\x01\x02" * 50) and dict(
        argv=["train", t / "bin.csv", "-o", t / "m.skops"], file="bin.csv"),
    "layout-unknown": lambda s, t, mp: dict(argv=["train", s["custom"], "-o", t / "m.skops"]),
    "layout-guessed": lambda s, t, mp: dict(  # two files: said once
        argv=["train", s["mamedov"], _text(t / "again.csv", Path(s["mamedov"]).read_text(
        ).splitlines()), *_fast_fail(), "-o", t / "m.skops"]),
    "column-out-of-range": lambda s, t, mp: dict(
        argv=["train", s["mamedov"], "--column-map",
              json.dumps({**FULL_MAP, "current": list(range(40, 46))}), "-o", t / "m.skops"]),
    "map-lacks-field": lambda s, t, mp: dict(
        argv=["train", s["mamedov"], "--column-map",
              json.dumps({"time": 0, "q": FULL_MAP["q"]}), "-o", t / "m.skops"]),
    "map-unknown-field": lambda s, t, mp: dict(
        argv=["train", s["mamedov"], "--column-map", json.dumps({**FULL_MAP, "torque": 3}),
              "-o", t / "m.skops"]),
    "header-missing-column": lambda s, t, mp: dict(
        argv=["train", s["d0"], "--column-map", json.dumps(
            {"time": "timestamp", "q": "nosuch_q", "qd": "actual_qd",
             "current": "actual_current"}), "-o", t / "m.skops"]),
    "preset-needs-folder": lambda s, t, mp: dict(
        argv=["train", s["d0"], "--column-map", "panda_gaz", "-o", t / "m.skops"],
        file="d0.csv"),
    "nan-value": lambda s, t, mp: dict(
        argv=["train", _edit_lines(s, t, "nan.csv", lambda b: b.__setitem__(
            20, re.sub(r",[^,]+", ",nan", b[20], count=1))), "-o", t / "m.skops"],
        file="nan.csv"),
    "malformed-rows": lambda s, t, mp: dict(
        argv=["train", _edit_lines(s, t, "malformed.csv", lambda b: [
            b.__setitem__(i, ",".join(b[i].split(",")[:3])) for i in range(5, len(b), 5)]),
              "-o", t / "m.skops"]),
    "out-of-line-rows": lambda s, t, mp: dict(argv=["train", _rtde(s["rec"].replace(
        q=s["rec"].q + np.where(np.arange(s["rec"].n_samples) % 5 == 0, 3.0, 0.0)[:, None]),
        t / "jumps.csv"), "-o", t / "m.skops"]),
    "dropped-rows": lambda s, t, mp: dict(
        argv=["train", _edit_lines(s, t, "dropped.csv", lambda b: b.__setitem__(
            30, ",".join(b[30].split(",")[:3]))), *_fast_fail(), "-o", t / "m.skops"],
        file="dropped.csv"),
    "time-gap": lambda s, t, mp: dict(
        argv=["train", _rtde(_rows(s["rec"], np.r_[0:300, 500:s["rec"].n_samples]),
                             t / "gap.csv"), *_fast_fail(), "-o", t / "m.skops"],
        file="gap.csv"),
    "degrees": lambda s, t, mp: dict(
        argv=["train", _rtde(s["rec"].replace(q=np.rad2deg(s["rec"].q)), t / "deg.csv"),
              "-o", t / "m.skops"]),
    "milliseconds": lambda s, t, mp: dict(
        argv=["train", _rtde(s["rec"].replace(time=s["rec"].time * 1000), t / "ms.csv"),
              "-o", t / "m.skops"]),
    "too-short": lambda s, t, mp: dict(
        argv=["train", _rtde(_rows(s["rec"], np.arange(50)), t / "short.csv"),
              "-o", t / "m.skops"]),
    "time-scale-rtde": lambda s, t, mp: dict(
        argv=["train", s["d0"], "--time-scale", "0.001", "-o", t / "m.skops"]),
    "joints-mismatch": lambda s, t, mp: dict(
        argv=["train", _rtde(_first_joints(s["rec"], 5), t / "five_named.csv"), "-o",
              t / "m.skops"], file="five_named.csv"),
    "joints-fewer": lambda s, t, mp: dict(
        argv=["train", _five_joints(s, t), "--column-map", FIVE_MAP, "--robot", "ur10e",
              "-o", t / "m.skops"], file="five.csv"),
    "joints-columns": lambda s, t, mp: dict(
        argv=["train", s["d0"], "--robot", "ur10e", "--joints", "5", "-o", t / "m.skops"]),
    "joints-too-many": lambda s, t, mp: dict(
        argv=["train", s["d0"], "--robot", "ur10e", "--joints", "9", "-o", t / "m.skops"]),
    "joints-unknown": lambda s, t, mp: dict(
        argv=["train", s["d0"], "--robot", "ur10e", "--joints", "nosuch", "-o",
              t / "m.skops"]),
    "robot-mismatch": lambda s, t, mp: dict(
        argv=["train", s["d0"], "--robot", "ur5", *_fast_fail(), "-o", t / "m.skops"]),
    "robot-required": lambda s, t, mp: dict(argv=["diagnose", s["anon"]]),
    "model-needs-robot": lambda s, t, mp: dict(
        argv=["train", s["anon"], "--model", "p_f", "-o", t / "m.skops"]),
    "sp-c-signals": lambda s, t, mp: dict(
        argv=["train", s["d0"], *_fast_fail(), "-o", t / "m.skops"]),
    "sp-c-no-target": lambda s, t, mp: dict(
        argv=["train", s["d0"], _rtde(s["rec"].replace(target_current=None),
                                      t / "notarget.csv"),
              "--model", "sp_c", "-o", t / "m.skops"], file="notarget.csv"),
    "sp-c-feedback": lambda s, t, mp: _stop_before_fit(mp) or dict(
        argv=["train", s["d0"], "--model", "sp_c", "-q", "-o", t / "m.skops"]),
    "calibrate-one-recording": lambda s, t, mp: dict(
        argv=["calibrate", s["model"], s["d0"], "-o", t / "x.skops"]),
    "calibrate-twice": lambda s, t, mp: dict(
        argv=["calibrate", s["model"], s["d0"], s["d0"], "-o", t / "x.skops"], file="d0.csv"),
    "select-fixed": lambda s, t, mp: dict(
        argv=["calibrate", s["model"], s["d0"], s["d1"], "--select", "--settle-time", "1",
              "-o", t / "x.skops"]),
    "select-bands": lambda s, t, mp: dict(
        argv=["calibrate", s["model"], s["d0"], s["d1"], "--select", "--band", "10,1,2",
              "-o", t / "x.skops"]),
    "braking-no-regimes": lambda s, t, mp: dict(
        argv=["calibrate", s["model"], s["d0"], s["d1"], "--braking", "--no-regimes",
              "-o", t / "x.skops"]),
    "split-too-long": lambda s, t, mp: dict(
        argv=["calibrate", s["model"], s["d0"], "--split", "100", "-o", t / "x.skops"]),
    "not-a-model": lambda s, t, mp: dict(
        argv=["calibrate", s["det"], s["d0"], s["d1"], "-o", t / "x.skops"]),
    "not-a-detector": lambda s, t, mp: dict(argv=["monitor", s["model"], s["d0"]]),
    "file-damaged": lambda s, t, mp: dict(argv=["monitor", _damaged(s, t), s["d0"]],
                                          file="damaged.skops"),
    "file-value-invalid": lambda s, t, mp: dict(argv=["monitor", _nan_threshold(s, t),
                                                      s["d0"]], file="nan.skops"),
    "file-option-removed": lambda s, t, mp: dict(argv=["monitor", _envelope_file(s, t),
                                                       s["d0"]], file="envelope.skops"),
    "pickle-untrusted": lambda s, t, mp: dict(
        argv=["calibrate", _model_variant(s, t, "model.joblib"), s["d0"], s["d1"],
              "-o", t / "x.skops"]),
    "model-without-features": lambda s, t, mp: dict(
        argv=["calibrate", _model_variant(s, t, "old.skops", features=False), s["d0"],
              s["d1"], "-o", t / "x.skops"]),
    "braking-without-limit": lambda s, t, mp: dict(
        argv=["calibrate", _model_variant(s, t, "old.skops", training=_no_limit(s)),
              s["d0"], s["d1"], "--braking", "-o", t / "x.skops"]),
    "signals-missing": lambda s, t, mp: dict(
        argv=["calibrate", s["model"], _rtde(s["rec"].replace(
            target_q=None, target_qd=None, target_current=None), t / "nosignals.csv"),
              s["d1"], "-o", t / "x.skops"]),
    "calibrate-joints": lambda s, t, mp: dict(
        argv=["calibrate", s["model"], _five_joints(s, t), _five_joints(s, t, "five_b.csv"),
              "--column-map", FIVE_MAP, "-o", t / "x.skops"], file="five.csv"),
    "units-mismatch": lambda s, t, mp: dict(
        argv=["calibrate", _model_variant(s, t, "torque.skops", training=_in_nm(s)),
              s["d0"], s["d1"], "-o", t / "x.skops"], file="d0.csv"),
    "monitor-units": lambda s, t, mp: dict(
        argv=["monitor", _detector_in_nm(s, t), s["d1"]], file="d1.csv"),
    "training-short": lambda s, t, mp: _stop_before_fit(mp) or dict(
        argv=["train", s["d0"], s["d1"], "--model", "gp", "-q", "-o", t / "m.skops"]),
    "calibration-short": lambda s, t, mp: dict(output=s["calibrate_output"]),
    "regime-coverage": lambda s, t, mp: dict(output=s["calibrate_output"]),
    "calibration-short-of-good": lambda s, t, mp: dict(output=s["calibrate_output"]),
    "monitor-source": lambda s, t, mp: dict(argv=["monitor", s["det"]]),
    "plot-rtde": lambda s, t, mp: dict(
        argv=["monitor", s["det"], "--rtde", "127.0.0.1", "--plot", t / "figures"]),
    "monitor-joints": lambda s, t, mp: dict(
        argv=["monitor", s["det"], _five_joints(s, t), "--column-map", FIVE_MAP],
        file="five.csv"),
    "rtde-connect": lambda s, t, mp: dict(
        argv=["monitor", s["det"], "--rtde", "127.0.0.1", "--port", _free_port()]),
    "sample-rate": lambda s, t, mp: dict(
        argv=["monitor", s["det"], _rtde(_rows(s["rec"], np.arange(0, s["rec"].n_samples, 2)),
                                         t / "half_rate.csv"), "-q"]),
    "hook-failed": lambda s, t, mp: dict(
        argv=["monitor", s["det"], _rtde(_bump(s["rec"]), t / "bump.csv"), "--hook", "false",
              "--json", t / "events.json", "-q"]),
    "hook-not-started": lambda s, t, mp: dict(
        argv=["monitor", s["det"], _rtde(_bump(s["rec"]), t / "bump.csv"), "--hook",
              t / "no_such_command", "-q"]),
    "matplotlib-missing": lambda s, t, mp: _hide_matplotlib(mp) or dict(
        argv=["monitor", s["det"], s["d1"], "--plot", t / "figures", "-q"]),
}


def _in_nm(s):
    """The training record of the fixture's model, as if trained on joint torques."""
    from sklearn_gpcd.workflow import load_model

    return dict(load_model(s["model"]).training, units="Nm")


def _detector_in_nm(s, t):
    """The fixture's detector, as if calibrated on joint torques."""
    from sklearn_gpcd.workflow import CalibratedDetector, load_detector, save_detector

    detector, features, calibration = load_detector(s["det"])
    path = t / "torque_detector.skops"
    save_detector(CalibratedDetector(detector, features, dict(calibration, units="Nm")), path)
    return str(path)


def _five_joints(s, t, name="five.csv"):
    rec = s["rec"]
    path = t / name
    np.savetxt(path, np.hstack([rec.time[:, None], rec.q[:, :5], rec.qd[:, :5],
                                rec.current[:, :5]]), delimiter=",", fmt="%.9g")
    return str(path)


def test_every_row_has_a_trigger_and_every_trigger_a_row():
    assert sorted(ROWS) == sorted(T)
    assert {row["kind"] for row in ROWS.values()} <= set(KINDS)


@pytest.mark.parametrize("key", sorted(ROWS))
def test_message_names_its_fix(key, sims, tmp_path, monkeypatch):
    row = ROWS[key]
    how = T[key](sims, tmp_path, monkeypatch)
    if "output" in how:
        status, out, err = how["output"]
        command = "calibrate"
    else:
        status, out, err = _run(how["argv"])
        command = str(how["argv"][0])
    lines = (out if row["kind"] == "printed" else err).splitlines()
    found = [line for line in lines if row["message"] in line]
    assert found, (f"{key}: no line with {row['message']!r}:\n"
                   + "\n".join(out.splitlines()[-5:] + err.splitlines()[-10:]))
    line = found[0]
    if row["kind"] != "printed":
        assert line.startswith(f"gpcd {command}: {row['kind']}: "), line
    if row["kind"] == "error":
        assert status == 2
    for fix in _literals(row["fix"]):
        assert fix in line, f"{key}: the fix {fix!r} is not in: {line}"
    if NAMES_FILE in row["fix"]:
        assert how.get("file") and how["file"] in line, f"{key}: no file name in: {line}"
    assert len(found) == 1, f"{key}: said {len(found)} times"


def test_calibrate_prints_one_false_alarm_figure(sims):
    """``gpcd calibrate`` (``--select`` by default) prints one expected false-alarm
    figure, the nested one, with its bound (issue 46: not a second figure "at the
    chosen settings alone")."""
    _, out, _ = sims["calibrate_output"]
    assert len([line for line in out.splitlines() if line.endswith("<- chosen")]) == 1
    figures = [line for line in out.splitlines() if "per hour" in line]
    assert len(figures) == 2, figures
    assert figures[0].lstrip().startswith("expected false alarms: ")
    assert figures[1].lstrip().startswith("95 % upper bound: ")


def test_train_and_calibrate_print_the_size_of_the_file_they_wrote(sims):
    """The docs say the commands print the file size (issue 46)."""
    import os

    _, out, _ = sims["calibrate_output"]
    size = os.path.getsize(sims["det"])
    line = next(line for line in out.splitlines() if "wrote" in line)
    number, unit = re.search(r"wrote .*det\.skops, ([\d.]+) (GB|MB|kB|bytes)", line).groups()
    scale = {"GB": 1e9, "MB": 1e6, "kB": 1e3, "bytes": 1}[unit]
    assert float(number) * scale == pytest.approx(size, rel=0.01)
    _, train_out, _ = _run(["train", sims["d0"], "--model", "gp", "--n-support", "30", "-q",
                            "-o", sims["folder"] / "sized.skops"])
    assert re.search(r"wrote .*sized\.skops, [\d.]+ (GB|MB|kB|bytes)", train_out)
