"""Fail closed (issue #47): a detector or model file never switches protection off in silence.

Every file here is crafted in the test from a small detector of the package's
own simulator (two 500 Hz UR10e runs, a linear regressor on the causal inputs,
:mod:`_live`): values edited to NaN, inf or negatives, an unstable filter,
wrong shapes, a schema that is not skops', a missing array, an array header
claiming 134 GiB, overwritten bytes, a zip bomb, a truncated or huge pinocchio
model text, trusted classes built by a call with the file's arguments. Each
must end in ONE :class:`~sklearn_gpcd.persistence.MalformedFileError` naming
the field (or the member) and the command that rebuilds the file, and
``gpcd monitor`` in exit status 2 with one ``error:`` line, nothing monitored.
"""

import io
import json
import zipfile

import numpy as np
import pytest
from _live import free_runs, linear_bundle, with_pushes
from test_model_files import _Call, craft_skops

from sklearn.linear_model import LinearRegression

from sklearn_gpcd.cli import main
from sklearn_gpcd.detection import AlarmRule, CollisionDetector, Regimes, stack_currents
from sklearn_gpcd.io import write_rtde_csv
from sklearn_gpcd.persistence import MalformedFileError, UntrustedTypesError, load, save
from sklearn_gpcd.workflow import (
    DETECTOR_KIND,
    MODEL_KIND,
    CalibratedDetector,
    load_detector,
    load_model,
    save_detector,
)

skops_io = pytest.importorskip("skops.io")


def make_good(folder):
    """A valid detector file, a model file and a recording to monitor, in ``folder``."""
    runs = free_runs(n=2, n_targets=1)
    detector, features = linear_bundle(runs)
    path = save_detector(CalibratedDetector(detector, features, {"margin": 1.5}),
                         folder / "detector.skops")
    regressor = LinearRegression().fit(np.eye(3), np.eye(3)[:, :2])
    model = save({"kind": MODEL_KIND, "regressor": regressor, "features": None,
                  "training": {}}, folder / "model.skops")
    recording = write_rtde_csv(runs[0], folder / "run.csv", robot_comment=True)
    pushed = write_rtde_csv(with_pushes(runs[0], [0.5, 1.5]), folder / "push.csv",
                            robot_comment=True)
    return {"folder": folder, "detector": path, "model": model, "recording": recording,
            "objects": (detector, features), "run": runs[0], "pushed": pushed}


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    """A valid detector file, a model file and a recording to monitor."""
    return make_good(tmp_path_factory.mktemp("fail_closed"))


# ------------------------------------------------------------------ crafting files
def entries_of(path):
    with zipfile.ZipFile(path) as archive:
        return {n: archive.read(n) for n in archive.namelist()}


def write_entries(path, entries, compression=zipfile.ZIP_STORED):
    with zipfile.ZipFile(path, "w", compression) as archive:
        for name, data in entries.items():
            archive.writestr(name, data)
    return path


def array_nodes(schema, attribute):
    """The schema nodes of every object attribute ``attribute``."""
    found, stack = [], [schema]
    while stack:
        node = stack.pop()
        if isinstance(node, dict):
            content = node.get("content")
            if (node.get("__loader__") == "ObjectNode" and isinstance(content, dict)
                    and attribute in content.get("content", {})):
                found.append(content["content"][attribute])
            stack.extend(node.values())
        elif isinstance(node, list):
            stack.extend(node)
    assert found, attribute
    return found


def edit_arrays(source, target, attribute, change):
    """Copy of ``source`` with every array ``attribute`` (or its items) replaced by
    ``change(array)``."""
    entries = entries_of(source)
    schema = json.loads(entries["schema.json"])
    for node in array_nodes(schema, attribute):
        for leaf in node.get("content", [node]) if "file" not in node else [node]:
            if "file" not in leaf:
                continue
            array = np.load(io.BytesIO(entries[leaf["file"]]))
            out = io.BytesIO()
            np.save(out, change(array))
            entries[leaf["file"]] = out.getvalue()
    return write_entries(target, entries)


def assert_refused(path, good, capsys, *words, loader=load_detector):
    """One MalformedFileError naming ``words``; ``gpcd monitor`` exits 2 with one line."""
    with pytest.raises(MalformedFileError) as caught:
        loader(path)
    message = str(caught.value)
    assert "\n" not in message and str(path) in message
    for word in words:
        assert word in message, message
    assert "rebuild it with gpcd" in message
    if loader is load_detector:
        assert main(["monitor", str(path), str(good["recording"])]) == 2
        captured = capsys.readouterr()
        err = captured.err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("gpcd monitor: error: "), err
        assert words[0] in err[0]
        assert "alarm event" not in captured.out  # nothing was monitored
    return message


def test_the_good_files_load(good):
    detector, features, calibration = load_detector(good["detector"])
    assert calibration == {"margin": 1.5} and features.n_joints_ == detector.n_joints == 6
    assert load_model(good["model"]).regressor.n_features_in_ == 3


# ------------------------------------------------------------------ values
@pytest.mark.parametrize("attribute", ["thresholds_", "scale_", "margin_"])
@pytest.mark.parametrize("value, words", [(np.nan, "nan"), (np.inf, "inf"),
                                          (-np.inf, "-inf"), (-1.0, "must be positive"),
                                          (0.0, "must be positive")])
def test_a_threshold_scale_or_margin_that_is_not_finite_and_positive_is_refused(
        good, tmp_path, capsys, attribute, value, words):
    path = edit_arrays(good["detector"], tmp_path / "edited.skops", attribute,
                       lambda a: np.full_like(a, value))
    assert_refused(path, good, capsys, attribute, words)


def test_one_nan_threshold_of_one_joint_is_refused(good, tmp_path, capsys):
    def one(a):
        a = a.copy()
        a.reshape(-1)[2] = np.nan
        return a

    path = edit_arrays(good["detector"], tmp_path / "one.skops", "thresholds_", one)
    assert_refused(path, good, capsys, "thresholds_", "nan")


def filter_file(good, target, a):
    """A copy of the good detector whose filters' denominators are ``a``."""
    entries = entries_of(good["detector"])
    schema = json.loads(entries["schema.json"])
    for node in array_nodes(schema, "filter_coefficients_"):
        out = io.BytesIO()
        np.save(out, np.array(a))
        entries[node["content"][1]["file"]] = out.getvalue()
    return write_entries(target, entries)


@pytest.mark.parametrize("a, words", [([np.nan, np.nan], "finite coefficients"),
                                      ([1.0, -1.5], "unstable filter"),
                                      ([1.0, -1.0], "unstable filter"),
                                      ([0.0, 0.5], "a[0] != 0")])
def test_an_unusable_filter_is_refused(good, tmp_path, capsys, a, words):
    path = filter_file(good, tmp_path / "filter.skops", a)
    assert_refused(path, good, capsys, "filter_coefficients_", words)


def test_thresholds_for_another_joint_count_are_refused(good, tmp_path, capsys):
    path = edit_arrays(good["detector"], tmp_path / "shape.skops", "thresholds_",
                       lambda a: a[..., :3])
    assert_refused(path, good, capsys, "thresholds_", "has shape (3,)")


def envelope_file(good, target, envelope, motion_envelope):
    """A detector file as written before the motion envelope was removed (issue 45):
    a rule with regimes whose ``envelope_`` and ``regimes.motion_envelope`` are
    the given values (what that version's ``gpcd calibrate --motion-envelope``
    stored; None without the option)."""
    features = good["objects"][1]
    run = good["run"]
    rule = AlarmRule("per_joint", false_alarm_rate=0.0, margin=1.5, filter_cutoff=10.0,
                     min_duration=5, regimes=Regimes())
    detector = CollisionDetector(LinearRegression(), n_joints=6, sample_time=run.time[1]
                                 - run.time[0], rules=rule)
    detector.fit(stack_currents(features.transform(run), run.current))
    fitted = detector.rules_[0]
    fitted.envelope_ = envelope
    vars(fitted.regimes)["motion_envelope"] = motion_envelope
    return save_detector(CalibratedDetector(detector, features, {}), target)


@pytest.mark.parametrize("envelope, motion_envelope, field", [
    (np.full((6, 3), 0.5), 0.05, "envelope_"),
    (None, 0.05, "regimes.motion_envelope")])
def test_a_file_calibrated_with_the_removed_motion_envelope_is_refused(
        good, tmp_path, capsys, envelope, motion_envelope, field):
    path = envelope_file(good, tmp_path / "envelope.skops", envelope, motion_envelope)
    message = assert_refused(path, good, capsys, f"detector.rules_[0].{field}",
                             "--motion-envelope", "was removed")
    assert f"gpcd calibrate MODEL RECORDINGS -o {path}" in message


def test_a_file_written_before_the_removal_without_the_envelope_loads(good, tmp_path):
    path = envelope_file(good, tmp_path / "plain.skops", None, None)
    detector = load_detector(path).detector
    assert detector.rules_[0].regime_names_[:3] == ("moving", "settling", "rest")
    assert main(["monitor", str(path), str(good["recording"])]) == 0  # no alarm on it


def test_a_model_with_a_nan_coefficient_is_refused(good, tmp_path, capsys):
    path = edit_arrays(good["model"], tmp_path / "model.skops", "coef_",
                       lambda a: a * np.nan)
    assert_refused(path, good, capsys, "coef_", "nan", loader=load_model)


def parameter_file(good, target):
    """A copy of the good detector with ``min_duration = -3`` in its schema."""
    entries = entries_of(good["detector"])
    schema = json.loads(entries["schema.json"])
    for node in array_nodes(schema, "min_duration"):
        node["content"] = "-3"
    entries["schema.json"] = json.dumps(schema).encode()
    return write_entries(target, entries)


def test_a_parameter_out_of_its_range_is_refused(good, tmp_path, capsys):
    assert_refused(parameter_file(good, tmp_path / "param.skops"), good, capsys,
                   "min_duration")


# ------------------------------------------------------------------ the archive
def test_overwritten_bytes_name_the_file_and_the_command(good, tmp_path, capsys):
    data = bytearray(good["detector"].read_bytes())
    data[-512:] = b"\0" * 512  # the zip directory
    path = tmp_path / "overwritten.skops"
    path.write_bytes(bytes(data))
    message = assert_refused(path, good, capsys, "damaged or overwritten")
    assert "gpcd calibrate" in message


#: The malformed archives: case -> words of the refusal.
ARCHIVE_CASES = {"no schema": "no schema.json", "schema a list": "a JSON list",
                 "schema not JSON": "cannot be rebuilt",
                 "schema without protocol": "cannot be rebuilt", "missing array": "is missing",
                 "header 134 GiB": "its header claims", "truncated array": "its header claims",
                 "array of objects": "holds Python objects"}


def malformed_archive(good, target, case):
    """A copy of the good detector broken as ``case`` (:data:`ARCHIVE_CASES`)."""
    entries = entries_of(good["detector"])
    arrays = sorted(n for n in entries if n.endswith(".npy"))
    if case == "no schema":
        del entries["schema.json"]
    elif case == "schema a list":
        entries["schema.json"] = b"[1, 2, 3]"
    elif case == "schema not JSON":
        entries["schema.json"] = entries["schema.json"][:1000]
    elif case == "schema without protocol":
        schema = json.loads(entries["schema.json"])
        del schema["protocol"]
        entries["schema.json"] = json.dumps(schema).encode()
    elif case == "missing array":
        del entries[arrays[0]]
    elif case == "header 134 GiB":
        header = np.lib.format.header_data_from_array_1_0(np.zeros(1))
        header["shape"] = (18_000_000_000,)  # 134 GiB of float64
        out = io.BytesIO()
        np.lib.format.write_array_header_1_0(out, header)
        entries[arrays[0]] = out.getvalue() + bytes(64)
    elif case == "truncated array":
        entries[arrays[0]] = entries[arrays[0]][:-8]
    elif case == "array of objects":
        out = io.BytesIO()
        np.save(out, np.array([None, 1], dtype=object), allow_pickle=True)
        entries[arrays[0]] = out.getvalue()
    return write_entries(target, entries)


@pytest.mark.parametrize("case", list(ARCHIVE_CASES))
def test_a_malformed_archive_is_one_line(good, tmp_path, capsys, case):
    path = malformed_archive(good, tmp_path / "malformed.skops", case)
    assert_refused(path, good, capsys, ARCHIVE_CASES[case])


def zip_bomb(good, path):
    """4 GiB of zeros packed into 4 MiB, next to the good detector's schema."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("schema.json", entries_of(good["detector"])["schema.json"])
        with archive.open("zeros.npy", "w", force_zip64=True) as member:
            block = bytes(1 << 24)
            for _ in range(256):
                member.write(block)
    return path


def test_a_zip_bomb_is_refused_from_its_directory(good, tmp_path, capsys):
    """Refused before a byte is unpacked."""
    path = zip_bomb(good, tmp_path / "bomb.skops")
    assert path.stat().st_size < 5 << 20
    assert_refused(path, good, capsys, "unpacks to 4", "zip bomb")


def test_an_oversized_file_is_refused_before_it_is_read(good, tmp_path, capsys, monkeypatch):
    import sklearn_gpcd.persistence as persistence

    monkeypatch.setattr(persistence, "MAX_FILE_BYTES", 1000)
    assert_refused(good["detector"], good, capsys, "a model or detector file may have")


# ------------------------------------------------------------------ trusted classes
def craft_call(path, good, target, args):
    """A detector file whose calibration is the call ``target(*args)`` (skops' reduce
    node: the class called with arguments from the file)."""
    return craft_skops(path, {"kind": DETECTOR_KIND, "detector": good["objects"][0],
                              "features": good["objects"][1], "calibration": _Call(*args)},
                       target)


@pytest.mark.parametrize("target, args", [
    ("sklearn_gpcd.diagnosis.nominal.NominalModel", ["/any/path.urdf"]),
    ("sklearn_gpcd.diagnosis.report.DiagnosisReport", []),
    ("sklearn_gpcd.robots.robot.Robot", ["ur10"]),
])
def test_a_trusted_class_is_never_called_with_the_files_arguments(
        good, tmp_path, capsys, monkeypatch, target, args):
    import importlib

    module, name = target.rsplit(".", 1)
    cls = getattr(importlib.import_module(module), name)
    calls = []
    monkeypatch.setattr(cls, "__init__", lambda self, *a, **k: calls.append(a))
    path = craft_call(tmp_path / "call.skops", good, target, args)
    assert_refused(path, good, capsys, name, "only its saved state")
    assert calls == []


def pinocchio_files(folder):
    """Model files whose pinocchio model text is cut in half or huge:
    ``[(label, path, words)]``, after checking the uncut one loads."""
    from sklearn_gpcd.robots import load_robot
    from sklearn_gpcd.robots.robot import MAX_MODEL_TEXT

    robot = load_robot("ur10")
    path = save({"kind": MODEL_KIND, "regressor": LinearRegression().fit(np.eye(2), [0, 1]),
                 "features": None, "training": {}, "robot": robot}, folder / "robot.skops")
    assert load_model(path).regressor.n_features_in_ == 2
    entries = entries_of(path)
    text = json.loads(entries["schema.json"])
    model_node = array_nodes(text, "model")[0]
    original = json.loads(model_node["content"])
    out = []
    for label, changed, words in [
            ("truncated", original[: len(original) // 2], "does not load"),
            ("huge", original + " 0" * (MAX_MODEL_TEXT // 2), "more than the")]:
        model_node["content"] = json.dumps(changed)
        entries["schema.json"] = json.dumps(text).encode()
        out.append((label, write_entries(folder / f"{label}.skops", entries,
                                         zipfile.ZIP_DEFLATED), words))
    return out


def test_a_truncated_or_huge_pinocchio_model_text_is_one_line(good, tmp_path, capsys):
    for _, crafted, words in pinocchio_files(tmp_path):
        message = assert_refused(crafted, good, capsys, "pinocchio model text", words,
                                 loader=load_model)
        assert "gpcd train" in message


def test_untrusted_types_are_still_refused_first(good, tmp_path):
    path = craft_call(tmp_path / "cli.skops", good, "sklearn_gpcd.cli.main", [["robots"]])
    with pytest.raises(UntrustedTypesError):
        load(path)


# ------------------------------------------------------------------ atomic writes
def test_a_failed_save_leaves_the_old_detector_intact(good, tmp_path, monkeypatch):
    """The disk fills up after part of the file is written (``fsync`` fails)."""
    import os

    path = tmp_path / "detector.skops"
    path.write_bytes(good["detector"].read_bytes())
    before = path.read_bytes()

    def full(descriptor):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    detector, features = good["objects"]
    with pytest.raises(OSError) as caught:
        save_detector(CalibratedDetector(detector, features, {"new": True}), path)
    message = str(caught.value)
    assert "\n" not in message and str(path) in message
    assert "No space left on device" in message and "previous file is intact" in message
    monkeypatch.undo()
    assert path.read_bytes() == before
    assert load_detector(path).calibration == {"margin": 1.5}
    assert [p.name for p in tmp_path.iterdir()] == ["detector.skops"]  # no temporary left


SIZE_LIMITED = """
import resource, sys
resource.setrlimit(resource.RLIMIT_FSIZE, ({limit}, {limit}))
from sklearn_gpcd.cli import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.parametrize("what", ["detector", "report", "figure"])
def test_a_file_size_limit_leaves_the_old_file_intact(good, tmp_path, what):
    """RLIMIT_FSIZE in a child process: the detector file (20 kB limit, the file
    has about 40 kB), the monitor's JSON report (300 bytes) or its figure
    (20 kB) cannot be written; the old file of that name stays as it was."""
    import subprocess
    import sys

    detector = tmp_path / "detector.skops"
    detector.write_bytes(good["detector"].read_bytes())
    report, figure = tmp_path / "report.json", tmp_path / "run.png"
    report.write_text(json.dumps({"old": "x" * 30000}))
    figure.write_bytes(b"old figure" * 3000)
    monitor = ["monitor", str(detector), str(good["recording"]), "--duration", "1"]
    if what == "detector":
        assert detector.stat().st_size > 20000
        code = ("import resource, sys\n"
                "from sklearn_gpcd.workflow import load_detector, save_detector\n"
                f"bundle = load_detector({str(detector)!r})\n"
                "resource.setrlimit(resource.RLIMIT_FSIZE, (20000, 20000))\n"
                "try:\n"
                f"    save_detector(bundle, {str(detector)!r})\n"
                "except OSError as exc:\n"
                "    sys.exit(str(exc))\n")
        args, target = [sys.executable, "-c", code], detector
    elif what == "report":
        args = [sys.executable, "-c", SIZE_LIMITED.format(limit=300), *monitor,
                "--json", str(report)]
        target = report
    else:
        args = [sys.executable, "-c", SIZE_LIMITED.format(limit=20000), *monitor,
                "--plot", str(tmp_path)]
        target = figure
    before = target.read_bytes()
    done = subprocess.run(args, capture_output=True, text=True, timeout=300,
                          cwd=str(tmp_path), env=_env())
    assert done.returncode != 0
    err = [line for line in done.stderr.splitlines() if "not written" in line]
    assert len(err) == 1 and "previous file is intact" in err[0], done.stderr[-2000:]
    assert str(target) in err[0]
    assert target.read_bytes() == before
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".part")]


def _env():
    import os
    from pathlib import Path

    env = dict(os.environ)
    env["PYTHONPATH"] = str(Path(__file__).resolve().parents[1])
    return env


# ------------------------------------------------------------------ every stop is reported
def test_a_dead_link_reports_its_blind_time(good, capsys):
    """The controller dies at 1.2 s: blind until the session gives up (0.5 s of
    reconnecting, more with the stall bound), and the report says how long."""
    from sklearn_gpcd.io._rtde_live import LoopbackRTDEServer, RTDEClient
    from sklearn_gpcd.monitoring import MonitorSession

    detector, features = good["objects"]
    session = MonitorSession(detector, features, stall_timeout=0.08)
    with LoopbackRTDEServer(good["run"], speed=2.0, faults=[(600, "kill", 0)],
                            max_duration=30.0) as server:
        client = RTDEClient("127.0.0.1", server.port, 500.0, timeout=2.0).connect()
        session.run_rtde(client, "loop", reconnect_timeout=0.5)
    record = session.faults[-1]
    assert record["kind"] == "link" and record["recovered_s"] is None
    assert record["blind_s"] >= 0.5
    total = sum(f["blind_s"] for f in session.faults)
    assert f"blind {total:.3f} s in total" in session.summary_text(live=True)
    assert "blind 0.000 s" not in session.summary_text(live=True)


def _stop(args, signum, tmp_path, ready, server=None):
    """Run ``gpcd monitor ARGS --json REPORT`` in a child, send ``signum`` once a
    line of its output starts with ``ready``; (exit status, stderr, report)."""
    import signal
    import subprocess
    import sys

    report = tmp_path / "stopped.json"
    process = subprocess.Popen([sys.executable, "-m", "sklearn_gpcd.cli", "monitor", *args,
                                "--json", str(report)], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, env=_env())
    try:
        for line in process.stdout:
            if line.startswith(ready):
                break
        process.send_signal(signum)
        _, err = process.communicate(timeout=120)
    finally:
        process.kill()
    assert report.exists(), (process.returncode, err[-2000:])
    return process.returncode, err, json.loads(report.read_text())


@pytest.mark.parametrize("name", ["SIGTERM", "SIGHUP"])
@pytest.mark.parametrize("source", ["replay", "live", "offline"])
def test_a_stop_signal_writes_the_report(good, tmp_path, name, source):
    import shutil
    import signal

    from sklearn_gpcd.io._rtde_live import LoopbackRTDEServer

    signum = getattr(signal, name)
    detector = str(good["detector"])
    if source == "replay":
        status, err, report = _stop([detector, "--replay", str(good["pushed"])], signum,
                                    tmp_path, "ALARM")
    elif source == "offline":
        copies = [shutil.copy(good["pushed"], tmp_path / f"run{k}.csv") for k in range(100)]
        status, err, report = _stop([detector, *map(str, copies), "--hook",
                                     "echo started"], signum, tmp_path, "started")
    else:
        with LoopbackRTDEServer(good["run"], speed=1.0, max_duration=60.0) as server:
            status, err, report = _stop([detector, "--rtde", "127.0.0.1", "--port",
                                         str(server.port)], signum, tmp_path, "monitoring")
    assert status == 128 + signum
    assert err.strip().splitlines()[-1].startswith(f"gpcd monitor: stopped by {name}")
    assert "Traceback" not in err
    assert report["end"] == {"reason": f"stopped by {name}", "abnormal": True,
                             "exit_status": 3}
    if source != "live":  # a live stop may come before the first sample
        assert report["recordings"][0]["n_samples"] > 0


#: ``gpcd calibrate`` in a child, with files above 10 kB streamed through a work folder.
_STREAMED_CALIBRATE = """
import sys
from sklearn_gpcd.cli import main
from sklearn_gpcd.io import chunks
chunks.STREAM_BYTES, chunks.CHUNK_BYTES = 10_000, 20_000
sys.exit(main(sys.argv[1:]))
"""


def stop_calibration(good, folder, signum):
    """Send ``signum`` to a streamed ``gpcd calibrate`` (a child) once its work folder
    has content; (exit status, stderr, what is left in its TMPDIR, whether the old
    output file is byte for byte, temporaries left next to it)."""
    import subprocess
    import sys
    import time

    detector, features = good["objects"]
    model = save({"kind": MODEL_KIND, "regressor": detector.regressor_,
                  "features": features, "training": {}}, folder / "model.skops")
    logs = [write_rtde_csv(run, folder / f"free{s}.csv")
            for s, run in enumerate(free_runs(n=3, n_targets=2))]
    output = folder / "old.skops"
    output.write_bytes(good["detector"].read_bytes())
    before = output.read_bytes()
    work = folder / "tmp"
    work.mkdir()
    process = subprocess.Popen(
        [sys.executable, "-c", _STREAMED_CALIBRATE, "calibrate", str(model), *map(str, logs),
         "-q", "-o", str(output)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**_env(), "TMPDIR": str(work)})
    try:
        deadline = time.monotonic() + 120
        while not any(p.name.startswith("gpcd-calibrate-") and any(p.iterdir())
                      for p in work.iterdir()):
            assert process.poll() is None and time.monotonic() < deadline, \
                process.communicate()
            time.sleep(0.01)
        process.send_signal(signum)
        _, err = process.communicate(timeout=120)
    finally:
        process.kill()
    parts = [p.name for p in folder.iterdir() if p.name.endswith(".part")]
    return (process.returncode, err, sorted(p.name for p in work.iterdir()),
            output.read_bytes() == before, parts)


@pytest.mark.parametrize("name", ["SIGTERM", "SIGHUP"])
def test_a_stopped_calibration_leaves_no_work_folder(good, tmp_path, name):
    """gpcd calibrate of long logs spools them into a temporary work folder; a stop
    signal while it works removes it, leaves the old detector file as it was and
    ends in one line and 128 + the signal number (as gpcd monitor does)."""
    import signal

    signum = getattr(signal, name)
    status, err, left, intact, parts = stop_calibration(good, tmp_path, signum)
    assert status == 128 + signum, err[-2000:]
    assert err.strip().splitlines() == [f"gpcd calibrate: stopped by {name}"]
    assert left == [] and intact and parts == []

# ------------------------------------------------------------------ fuzzing
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

#: Values an edited array may get (the ones that switch a detector off among them).
ODD_VALUES = [np.nan, np.inf, -np.inf, -1.0, 0.0, -0.0, 1e-300, 1e300, 5e-324]

MUTATION = st.one_of(
    st.tuples(st.just("flip"), st.lists(st.tuples(st.floats(0, 1, exclude_max=True),
                                                    st.integers(1, 255)), min_size=1,
                                         max_size=8)),
    st.tuples(st.just("drop"), st.floats(0, 1, exclude_max=True)),
    st.tuples(st.just("array"), st.floats(0, 1, exclude_max=True),
              st.sampled_from(["fill", "one", "truncate", "empty", "int8", "transpose",
                               "scale"]),
              st.sampled_from(ODD_VALUES)),
    st.tuples(st.just("cut"), st.floats(0, 1, exclude_max=True)),
)


def mutate(source, target, mutation):
    """A copy of ``source`` with ``mutation`` applied (see :data:`MUTATION`)."""
    data = source.read_bytes()
    if mutation[0] == "flip":
        data = bytearray(data)
        for where, xor in mutation[1]:
            data[int(where * len(data))] ^= xor
        target.write_bytes(bytes(data))
        return target
    if mutation[0] == "cut":
        target.write_bytes(data[:int(mutation[1] * len(data))])
        return target
    entries = entries_of(source)
    names = sorted(entries)
    if mutation[0] == "drop":
        del entries[names[int(mutation[1] * len(names))]]
        return write_entries(target, entries)
    _, where, how, value = mutation
    arrays = [n for n in names if n.endswith(".npy")]
    name = arrays[int(where * len(arrays))]
    array = np.load(io.BytesIO(entries[name]))
    if array.dtype.kind == "f":
        with np.errstate(all="ignore"):
            array = _changed(array, how, value)
    else:
        array = array.reshape(-1)[:-1]
    out = io.BytesIO()
    np.save(out, array)
    entries[name] = out.getvalue()
    return write_entries(target, entries)


def _changed(array, how, value):
    """``array`` filled with, or one item set to, or scaled by ``value``; or reshaped."""
    return {"fill": lambda a: np.full_like(a, value),
            "one": lambda a: np.where(np.arange(a.size).reshape(a.shape) == 0, value, a),
            "truncate": lambda a: a.reshape(-1)[:-1],
            "empty": lambda a: a.reshape(-1)[:0],
            "int8": lambda a: a.astype(np.int8),
            "transpose": lambda a: a.T.copy() if a.ndim == 2 else a[None],
            "scale": lambda a: a * value}[how](array)


def assert_valid_detector(bundle):
    """What a loaded detector must be, checked here without the package's checks."""
    detector, features = bundle.detector, bundle.features
    assert features.n_joints_ == detector.n_joints == 6
    for part in [detector, *detector.rules_]:
        for name in ("thresholds_", "scale_", "margin_"):
            values = np.asarray(getattr(part, name), dtype=float)
            assert values.shape[-1] == 6 and np.isfinite(values).all() and (values > 0).all()
        b, a = part.filter_coefficients_
        assert np.ndim(b) == np.ndim(a) == 1 and len(b) == len(a)
        assert np.isfinite(b).all() and np.isfinite(a).all() and a[0] != 0
        assert np.abs(np.roots(a)).max(initial=0.0) < 1
        assert np.isfinite(part.sample_time_) and part.sample_time_ > 0


def check_mutant(good, mutation, kind="detector"):
    """Load a mutant of the good ``kind`` file: a valid object or ONE clean error line."""
    loader, command = ((load_detector, "gpcd calibrate") if kind == "detector"
                       else (load_model, "gpcd train"))
    path = mutate(good[kind], good["folder"] / f"mutant_{kind}.skops", mutation)
    try:
        loaded = loader(path)
    except MalformedFileError as exc:
        assert "\n" not in str(exc) and str(path) in str(exc) and command in str(exc)
        return "refused"
    except ValueError as exc:  # the kind of file, or a type the allow-list refuses
        assert type(exc) in (ValueError, UntrustedTypesError), repr(exc)
        assert "\n" not in str(exc) and str(path) in str(exc)
        return "refused"
    if kind == "detector":
        assert_valid_detector(loaded)
    else:
        assert np.isfinite(loaded.regressor.coef_).all()
        assert np.isfinite(loaded.regressor.predict(np.eye(3))).all()
    return "loaded"


FUZZ = dict(deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                  HealthCheck.too_slow])


@pytest.mark.parametrize("kind", ["detector", "model"])
@settings(max_examples=25, **FUZZ)
@given(mutation=MUTATION)
def test_a_mutated_file_loads_valid_or_is_refused_in_one_line(good, kind, mutation):
    """Small budget in the default run (25 files of each kind); see the slow variant."""
    check_mutant(good, mutation, kind)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["detector", "model"])
@settings(max_examples=1000, **FUZZ)
@given(mutation=MUTATION)
def test_a_thousand_mutated_files(good, kind, mutation):
    check_mutant(good, mutation, kind)
