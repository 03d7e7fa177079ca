"""``gpcd calibrate`` and ``gpcd monitor`` (issue #15): offline, replay and RTDE loopback."""

import json
import threading

import numpy as np
import pytest
from sklearn.frozen import FrozenEstimator

from sklearn_gpcd.cli import main
from sklearn_gpcd.workflow import DETECTOR_RULE, SELECT_GRID, load_detector
from sklearn_gpcd.datasets import simulate_d1
from sklearn_gpcd.detection import (
    AlarmRule,
    CollisionDetector,
    Regimes,
    StreamingMonitor,
    calibrate_across_recordings,
    stack_currents,
)
from sklearn_gpcd.features import CausalFeatures, contiguous_segments
from sklearn_gpcd.io import load_recording, write_rtde_csv
from sklearn_gpcd.io._rtde_live import LoopbackRTDEServer
from sklearn_gpcd.workflow import load_model

RATE = 500.0  # Hz, as a UR e-Series streams


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    """Three collision-free 500 Hz UR10e runs, a run with two current bumps (the
    'collisions' the controller's target current does not see), an SP_C model
    trained and a detector calibrated by the CLI."""
    folder = tmp_path_factory.mktemp("monitor")
    free = []
    for seed in range(3):
        rec = simulate_d1("ur10e", n_targets=2, sample_rate=RATE, random_state=seed)
        free.append(write_rtde_csv(rec, folder / f"free{seed}.csv", robot_comment=True))
    rec = simulate_d1("ur10e", n_targets=2, sample_rate=RATE, random_state=7)
    t = rec.time - rec.time[0]
    current = rec.current.copy()
    current[(t >= 1.5) & (t < 1.9), 1] += 1.0
    current[(t >= 3.5) & (t < 3.8), 0] -= 1.0
    push = write_rtde_csv(rec.replace(current=current), folder / "push.csv",
                          robot_comment=True)
    model = folder / "model.skops"
    assert main(["train", *map(str, free[:2]), "--model", "sp_c", "--n-support", "100",
                 "-q", "-o", str(model)]) == 0
    detector = folder / "detector.skops"
    assert main(["calibrate", str(model), *map(str, free), "-q", "-o", str(detector)]) == 0
    return {"folder": folder, "free": free, "push": push, "model": model,
            "detector": detector}


def _json_events(path):
    return [(e["start_s"], e["end_s"], e["joints"]) for e in
            json.loads(path.read_text())["events"]]


def test_calibrate_applies_the_loro_rule_and_reports_it(work, capsys):
    out = work["folder"] / "again.skops"
    assert main(["calibrate", str(work["model"]), *map(str, work["free"]), "-q",
                 "--no-select", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "margin (leave-one-recording-out" in text and "per hour" in text
    assert "thresholds [A]" in text and "thresholds [Nm, torque constants of ur10e]" in text
    for regime in ("moving", "settling", "rest"):
        assert regime in text
    detector, features, calibration = load_detector(out)
    # the same rule by hand: the package function on the model's own causal inputs
    recs = [load_recording(p) for p in work["free"]]
    trained = load_model(work["model"])
    assert trained.training["inputs"] == "causal" and calibration["training"] == \
        trained.training
    assert features.signals_ == trained.features.signals_ == CausalFeatures().fit(
        recs[:2]).signals_  # fitted by gpcd train on its recordings
    blocks = {p.name: stack_currents(trained.features.transform(r), r.current)
              for p, r in zip(work["free"], recs)}
    template = CollisionDetector(
        FrozenEstimator(trained.regressor), n_joints=6, sample_time="auto",
        rules=AlarmRule(**DETECTOR_RULE, regimes=Regimes(rest_reference=5.0)))
    expected = calibrate_across_recordings(
        template, blocks, {p.name: r.time for p, r in zip(work["free"], recs)})
    np.testing.assert_allclose(detector.thresholds_, expected.detector.thresholds_)
    assert calibration["margin"] == pytest.approx(expected.margin.max())
    assert calibration["n_false_alarms_nested"] == expected.n_false_alarms
    assert f"{expected.margin.max():.3f}" in text
    kt = np.array(calibration["thresholds_Nm"]) / np.array(calibration["thresholds_A"])
    np.testing.assert_allclose(kt[0], [11.976, 11.976, 9.839, 10.763, 10.763, 10.763])


def test_calibrate_refuses_a_bare_regressor(work, capsys):
    """A file holding a regressor without its features is not a model file: one error line
    that names the file and the command that writes a model file."""
    from sklearn_gpcd.persistence import save

    bare = save(load_model(work["model"]).regressor, work["folder"] / "bare.joblib")
    out = work["folder"] / "bare_detector.skops"
    assert main(["calibrate", str(bare), *map(str, work["free"]), "-q", "-o", str(out),
                 "--trust-pickle"]) == 2  # our own pickle, but not a model file
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bare) in err[0] and "gpcd train" in err[0]
    assert not out.exists()


def test_calibrate_refuses_a_detector_file_as_model(work, capsys):
    assert main(["calibrate", str(work["detector"]), *map(str, work["free"]), "-q",
                 "-o", str(work["folder"] / "d2.skops")]) == 2
    assert "not a model file written by gpcd train" in capsys.readouterr().err


def test_calibrate_needs_two_recordings(work, capsys):
    assert main(["calibrate", str(work["model"]), str(work["free"][0]),
                 "-o", str(work["folder"] / "one.skops")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "at least 2" in err[0] and "--split" in err[0]


def filled(thresholds, calibration):
    """``thresholds`` of calibrate_across_recordings with ``gpcd calibrate``'s rule
    for regimes with less than 1 s of data: the largest of the regimes with data,
    and a later settling stage without data or seen in one log alone, that of
    the stage before it."""
    names, without = calibration["regimes"], calibration["regimes_without_data"]
    empty = np.array([name in without for name in names])
    one_log = set(calibration["stages_from_one_log"])
    out = np.array(thresholds, dtype=float, copy=True)
    if empty.any():
        out[empty] = out[~empty].max(axis=0)
    stages = [k for k, name in enumerate(names) if name.startswith("settling")]
    for before, k in zip(stages[:-1], stages[1:]):
        if empty[k] or names[k] in one_log:
            out[k] = out[before]
    return out


def test_calibrate_split_cuts_one_long_log_into_left_out_pieces(work, capsys):
    """--split: one recording, cut into pieces that leave-one-recording-out treats as
    recordings; the same thresholds as calibrate_across_recordings on those pieces."""
    from sklearn_gpcd.workflow import split_recordings

    rec = load_recording(work["free"][2])
    out = work["folder"] / "split.skops"
    seconds = rec.duration / 3.5  # three pieces
    assert main(["calibrate", str(work["model"]), str(work["free"][2]), "--split",
                 f"{seconds}", "--no-select", "-q", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "cut 1 recording(s) into 3 pieces" in text
    detector, features, calibration = load_detector(out)
    keys, pieces = split_recordings([work["free"][2].name], [rec], seconds)
    assert calibration["recordings"] == keys == [f"free2.csv#{i}" for i in (1, 2, 3)]
    assert sum(p.n_samples for p in pieces) == rec.n_samples
    np.testing.assert_array_equal(np.concatenate([p.time for p in pieces]), rec.time)
    trained = load_model(work["model"])
    template = CollisionDetector(
        FrozenEstimator(trained.regressor), n_joints=6, sample_time="auto",
        rules=AlarmRule(**DETECTOR_RULE, regimes=Regimes(rest_reference=5.0)))
    expected = calibrate_across_recordings(
        template, {k: stack_currents(features.transform(p), p.current)
                   for k, p in zip(keys, pieces)},
        {k: p.time for k, p in zip(keys, pieces)})
    np.testing.assert_allclose(detector.thresholds_,
                               filled(expected.detector.thresholds_, calibration))
    # one log: its later settling stages, unchecked by a left-out log, are the first's
    stages = [calibration["regimes"].index(n) for n in calibration["regimes"]
              if n.startswith("settling")]
    assert all(calibration["regimes"][k] in calibration["stages_from_one_log"]
               + calibration["regimes_without_data"] for k in stages[1:])
    assert np.all(detector.thresholds_[stages] == detector.thresholds_[stages[0]])
    # too coarse a split leaves one piece: an error that says what would work
    assert main(["calibrate", str(work["model"]), str(work["free"][2]), "--split",
                 f"{rec.duration}", "-o", str(work["folder"] / "one.skops")]) == 2
    assert "leaves 1 piece" in capsys.readouterr().err


def test_calibrate_refuses_a_recording_given_twice(work, capsys):
    free = [str(p) for p in work["free"]]
    assert main(["calibrate", str(work["model"]), *free, free[0], "-q",
                 "-o", str(work["folder"] / "twice.skops")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "given twice" in err[0]


def test_calibrate_checks_the_output_path_before_work(work, capsys):
    assert main(["calibrate", str(work["model"]), *map(str, work["free"]),
                 "-o", str(work["folder"] / "missing" / "d.skops")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_monitor_refuses_a_model_file(work, capsys):
    assert main(["monitor", str(work["model"]), str(work["push"])]) == 2
    assert "gpcd calibrate" in capsys.readouterr().err


def test_monitor_events_match_the_streaming_monitor(work, capsys):
    report, plots = work["folder"] / "events.json", work["folder"] / "plots"
    assert main(["monitor", str(work["detector"]), str(work["push"]), "-q",
                 "--json", str(report), "--plot", str(plots)]) == 0
    text = capsys.readouterr().out
    events = _json_events(report)
    assert len(events) >= 2 and "peak |m| [A]" in text and "delay [s]" in text
    assert (plots / "push.png").stat().st_size > 0
    # the same decisions from StreamingMonitor.replay_recording
    detector, features, _ = load_detector(work["detector"])
    rec = load_recording(work["push"])
    result = StreamingMonitor(detector, features=features).replay_recording(rec)
    t = rec.time - rec.time[0]
    onsets = [t[a] for a, _ in contiguous_segments(result.alarms.any(axis=1))]
    assert [e[0] for e in events] == pytest.approx(onsets)
    saved = json.loads(report.read_text())["events"]
    assert {1, 2} <= {j for e in saved for j in e["joints"]}       # both bumps, 1-based
    assert all(e["delay_s"] >= 0 and e["peak_A"] > 0.3 for e in saved)
    # the bumps (1.5-1.9 s on joint 2, 3.5-3.8 s on joint 1) are found, in order
    assert any(1.5 <= e["start_s"] < 1.9 and 2 in e["joints"] for e in saved)
    assert any(3.5 <= e["start_s"] < 3.8 and 1 in e["joints"] for e in saved)


def test_monitor_replay_gives_the_offline_events(work, capsys):
    offline, replay = work["folder"] / "off.json", work["folder"] / "replay.json"
    assert main(["monitor", str(work["detector"]), str(work["push"]), "-q",
                 "--json", str(offline)]) == 0
    assert main(["monitor", str(work["detector"]), "--replay", str(work["push"]),
                 "--speed", "0", "--json", str(replay)]) == 0
    assert "latency receive -> decision" in capsys.readouterr().out
    assert _json_events(replay) == _json_events(offline)
    assert json.loads(replay.read_text())["live"]["dropped_samples"] == 0


def test_monitor_needs_exactly_one_source(work, capsys):
    assert main(["monitor", str(work["detector"])]) == 2
    assert "exactly one" in capsys.readouterr().err


def test_monitor_rtde_loopback_gives_the_offline_events(work, capsys):
    """End to end without a robot: RTDE server on 127.0.0.1 streaming the recording at
    real time (about 5 s), the CLI's RTDE client, the same events as offline. The
    server is a thread of this process: on a loaded machine it may not send for more
    than the default stall bound (20 ms), which the monitor rightly reports as a
    fault (tests/test_monitoring.py); here the bound is 1 s."""
    offline, live = work["folder"] / "off2.json", work["folder"] / "live.json"
    assert main(["monitor", str(work["detector"]), str(work["push"]), "-q",
                 "--json", str(offline)]) == 0
    rec = load_recording(work["push"])
    with LoopbackRTDEServer(rec, speed=1.0, max_duration=60.0) as server:
        status = {}
        runner = threading.Thread(target=lambda: status.update(rc=main([
            "monitor", str(work["detector"]), "--rtde", "127.0.0.1", "--port",
            str(server.port), "--json", str(live), "--stall-timeout", "1"])))
        runner.start()
        runner.join(timeout=60.0)
    assert status.get("rc") == 0
    assert server.n_sent == rec.n_samples
    text = capsys.readouterr().out
    assert "ALARM" in text and "dropped samples 0" in text
    saved = json.loads(live.read_text())
    assert saved["live"]["n_ticks"] == rec.n_samples
    assert saved["live"]["dropped_samples"] == 0
    assert _json_events(live) == _json_events(offline)


def test_monitor_rtde_without_server_is_one_error_line(work, capsys):
    import socket

    with socket.socket() as probe:  # a free port nobody listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    assert main(["monitor", str(work["detector"]), "--rtde", "127.0.0.1",
                 "--port", str(port)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot start an RTDE stream" in err[0]


def test_monitor_hook_runs_at_each_alarm_onset(work, capsys):
    import sys
    import time

    folder = work["folder"] / "hook"
    folder.mkdir()
    script = folder / "hook.py"
    script.write_text("import os, pathlib\n"
                      f"pathlib.Path({str(folder)!r}, os.environ['GPCD_ALARM_TIME'] + '.txt')"
                      ".write_text(os.environ['GPCD_ALARM_JOINTS'])\n")
    report = folder / "events.json"
    assert main(["monitor", str(work["detector"]), "--replay", str(work["push"]), "--speed",
                 "0", "--hook", f"{sys.executable} {script}", "--json", str(report)]) == 0
    events = json.loads(report.read_text())["events"]
    for _ in range(200):  # the hook is not waited for: give the processes time to finish
        if len(list(folder.glob("*.txt"))) == len(events):
            break
        time.sleep(0.1)
    written = sorted((float(p.stem), p.read_text()) for p in folder.glob("*.txt"))
    assert [t for t, _ in written] == pytest.approx([e["start_s"] for e in events], abs=1e-6)
    assert "ALARM" in capsys.readouterr().out


def test_calibrate_select_chooses_settle_time_and_rest_reference(work, capsys):
    out = work["folder"] / "selected.skops"
    assert main(["calibrate", str(work["model"]), *map(str, work["free"]), "--select", "-q",
                 "-o", str(out)]) == 0
    text = capsys.readouterr().out
    detector, features, calibration = load_detector(out)
    recs = [load_recording(p) for p in work["free"]]
    trained = load_model(work["model"])
    blocks = {p.name: stack_currents(trained.features.transform(r), r.current)
              for p, r in zip(work["free"], recs)}
    template = CollisionDetector(
        FrozenEstimator(trained.regressor), n_joints=6, sample_time="auto",
        rules=AlarmRule(**DETECTOR_RULE, regimes=Regimes(rest_reference=5.0)))
    expected = calibrate_across_recordings(
        template, blocks, {p.name: r.time for p, r in zip(work["free"], recs)},
        param_grid=SELECT_GRID)
    regimes = detector.rules[0].regimes
    assert (regimes.settle_time, regimes.rest_reference) == (
        expected.settings["regimes__settle_time"], expected.settings["regimes__rest_reference"])
    np.testing.assert_allclose(detector.thresholds_,
                               filled(expected.detector.thresholds_, calibration))
    assert calibration["selected"] and len(calibration["candidates"]) == 12
    assert calibration["n_false_alarms_nested"] == expected.n_false_alarms
    assert "(chosen across the recordings)" in text
    lines = [line for line in text.splitlines() if line.startswith("    settle ")]
    assert len(lines) == 12
    assert lines[0].endswith("<- chosen") and sum("<- chosen" in line for line in lines) == 1


def test_calibrate_select_refuses_fixed_settings(work, capsys):
    for fixed in (["--no-regimes"], ["--rest-reference", "2"]):
        assert main(["calibrate", str(work["model"]), *map(str, work["free"]), "--select",
                     *fixed, "-q", "-o", str(work["folder"] / "x.skops")]) != 0
        assert f"drop {fixed[0]}" in capsys.readouterr().err
