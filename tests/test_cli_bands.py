"""``gpcd calibrate --band`` and ``gpcd monitor`` on a multi-band detector file."""

import json

import numpy as np
import pytest
from sklearn.frozen import FrozenEstimator

from sklearn_gpcd.cli import main
from sklearn_gpcd.workflow import DETECTOR_RULE, load_detector
from sklearn_gpcd.datasets import simulate_d1
from sklearn_gpcd.detection import (
    AlarmRule,
    CollisionDetector,
    StreamingMonitor,
    Regimes,
    calibrate_across_recordings,
    stack_currents,
)
from sklearn_gpcd.dynamics import ControllerCurrent
from sklearn_gpcd.features import CausalFeatures, contiguous_segments
from sklearn_gpcd.io import load_recording, write_rtde_csv
from sklearn_gpcd.workflow import TrainedModel, load_model, save_model

from _synthetic import banded

FAST = {"filter_cutoff": 10.0, "filter_order": 1, "min_duration": 2}
MID = {"filter_cutoff": 5.0, "filter_order": 2, "min_duration": 3}
TAP_S = 1.0  # a 16 ms tap of 0.5 A on joint 2: too short for the 2 Hz main band


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    """Three collision-free 125 Hz UR10e runs, a run with a tap and a push, the
    controller's current as the model (no training: the test is about the CLI) and a
    two-band detector calibrated by the CLI."""
    folder = tmp_path_factory.mktemp("bands")
    free = [write_rtde_csv(simulate_d1("ur10e", n_targets=2, random_state=seed),
                           folder / f"free{seed}.csv", robot_comment=True)
            for seed in range(3)]
    recs = [load_recording(p) for p in free]
    features = CausalFeatures().fit(recs)
    model = ControllerCurrent(6).fit(features.transform(recs[0]), recs[0].current)
    model_file = save_model(TrainedModel(model, features, {}), folder / "model.skops")
    rec = simulate_d1("ur10e", n_targets=2, random_state=7)
    t = rec.time - rec.time[0]
    current = rec.current.copy()
    tap = np.searchsorted(t, TAP_S)
    current[tap:tap + 2, 1] += 0.5
    current[(t >= 3.5) & (t < 3.9), 0] -= 1.0
    taps = write_rtde_csv(rec.replace(current=current), folder / "tap.csv",
                          robot_comment=True)
    detector = folder / "bands.skops"
    assert main(["calibrate", str(model_file), *map(str, free), "--band", "10,1,2", "-q",
                 "-o", str(detector)]) == 0
    return {"folder": folder, "free": free, "model": model_file, "taps": taps,
            "detector": detector}


def _by_hand(work):
    """What gpcd calibrate computes on, by hand: the model's causal inputs of the
    collision-free runs, their time stamps and the CLI's detector rule."""
    recs = [load_recording(p) for p in work["free"]]
    trained = load_model(work["model"])
    blocks = {p.name: stack_currents(trained.features.transform(r), r.current)
              for p, r in zip(work["free"], recs)}
    times = {p.name: r.time for p, r in zip(work["free"], recs)}
    template = CollisionDetector(
        FrozenEstimator(trained.regressor), n_joints=6, sample_time="auto",
        rules=AlarmRule(**DETECTOR_RULE, regimes=Regimes(rest_reference=5.0)))
    return blocks, times, template


def test_calibrate_bands_equals_the_package_function(work, capsys):
    out = work["folder"] / "three.joblib"
    assert main(["calibrate", str(work["model"]), *map(str, work["free"]), "--band",
                 "10,1,2", "--band", "5, 2, 3", "-q", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    detector, features, calibration = load_detector(out, trust_pickle=True)  # our own
    assert len(detector.rules_) == 3
    # the same calibration by hand, on the model's causal inputs
    blocks, times, template = _by_hand(work)
    expected = calibrate_across_recordings(banded(template, FAST, MID), blocks, times)
    assert [rule.filter_cutoff for rule in detector.rules_] == [2.0, 10.0, 5.0]
    for fitted, band, saved in zip(detector.rules_, expected.bands, calibration["bands"]):
        np.testing.assert_allclose(fitted.thresholds_, band.rule.thresholds_)
        np.testing.assert_allclose(saved["thresholds_A"], band.rule.thresholds_)
        assert saved["margin"] == pytest.approx(band.margin.max())
        assert saved["n_false_alarms_nested"] == band.n_false_alarms
        assert f"{band.margin.max():.3f}" in text
    assert calibration["n_false_alarms_nested"] == expected.n_false_alarms
    assert calibration["nested_onsets_s"] == {k: f["onsets"] for k, f in expected.folds.items()}
    assert calibration["false_alarms_per_hour"] == pytest.approx(
        expected.false_alarms_per_hour)
    for label in ("band 1 (2 Hz, order 1, debounce 5), the main one:",
                  "band 2 (10 Hz, order 1, debounce 2):", "band 3 (5 Hz, order 2, debounce 3):",
                  "expected false alarms (any band):"):
        assert label in text
    assert text.count("thresholds [A]:") == 3 and text.count("thresholds [Nm") == 3


def test_a_multi_band_file_loads_and_says_so(work):
    detector, features, calibration = load_detector(work["detector"])  # skops: trusted
    assert len(detector.rules_) == 2
    assert [(b["filter_cutoff_hz"], b["filter_order"], b["debounce_samples"])
            for b in calibration["bands"]] == [(2.0, 1, 5), (10.0, 1, 2)]
    single = work["folder"] / "single.skops"
    assert main(["calibrate", str(work["model"]), *map(str, work["free"]), "-q",
                 "-o", str(single)]) == 0
    detector, _, calibration = load_detector(single)
    assert len(detector.rules_) == 1 and "bands" not in calibration


def test_monitor_names_the_band_that_caught_a_tap(work, capsys):
    report, plots = work["folder"] / "events.json", work["folder"] / "plots"
    assert main(["monitor", str(work["detector"]), str(work["taps"]), "-q",
                 "--json", str(report), "--plot", str(plots)]) == 0
    text = capsys.readouterr().out
    saved = json.loads(report.read_text())
    events = saved["events"]
    tap = [e for e in events if TAP_S <= e["start_s"] < TAP_S + 0.1]
    push = [e for e in events if 3.5 <= e["start_s"] < 3.9]
    # the tap: only the fast band; the push: the main band too
    assert len(tap) == 1 and tap[0]["bands"] == [2] and tap[0]["joints"] == [2]
    assert push and 1 in {b for e in push for b in e["bands"]}
    assert "band 2 (10 Hz, order 1, debounce 2) alarmed in" in text
    header = [line for line in text.splitlines() if line.startswith("recording")]
    assert header and "bands" in header[0]  # the event table's header
    assert saved["bands"] == ["2 Hz, order 1, debounce 5", "10 Hz, order 1, debounce 2"]
    assert (plots / "tap.png").stat().st_size > 0
    # the same union alarms as StreamingMonitor.replay_recording
    onsets, result, t = _replayed_onsets(work)
    assert [e["start_s"] for e in events] == pytest.approx(onsets)
    assert not result.bands[0].alarms[np.abs(t - TAP_S) < 0.1].any()


def _replayed_onsets(work):
    """Onsets [s] of the union alarms of StreamingMonitor.replay_recording on the taps."""
    detector, features, _ = load_detector(work["detector"])
    rec = load_recording(work["taps"])
    result = StreamingMonitor(detector, features=features).replay_recording(rec)
    t = rec.time - rec.time[0]
    return [t[a] for a, _ in contiguous_segments(result.alarms.any(axis=1))], result, t


def test_monitor_replay_of_a_multi_band_file(work, capsys, monkeypatch):
    import sklearn_gpcd.monitoring.session as monitoring

    class Ended:  # a hook process that ended well
        def poll(self):
            return 0

    hooks = []  # the environment of each --hook call, instead of running it
    monkeypatch.setattr(monitoring.subprocess, "Popen",
                        lambda command, env: hooks.append((command, env)) or Ended())
    replay = work["folder"] / "replay.json"
    assert main(["monitor", str(work["detector"]), "--replay", str(work["taps"]),
                 "--speed", "0", "--json", str(replay), "--hook", "alarm.sh"]) == 0
    text = capsys.readouterr().out
    assert "latency receive -> decision" in text
    assert f"ALARM tap.csv t={TAP_S + 0.008:.3f} s joints 2, band 2 (10 Hz, order 1, " \
           "debounce 2)" in text
    events = json.loads(replay.read_text())["events"]
    assert [e["start_s"] for e in events] == pytest.approx(_replayed_onsets(work)[0])
    assert [env["GPCD_ALARM_TIME"] for _, env in hooks] == [
        f"{e['start_s']:.6f}" for e in events]
    assert hooks[0][0] == ["alarm.sh"] and hooks[0][1]["GPCD_ALARM_BANDS"] == "2"


@pytest.mark.parametrize("text", ["10,1", "10,3,2", "x,1,2", "10,1,0", "-5,1,2", "10,1.5,2",
                                  "10,1,2,4", "inf,1,2"])
def test_bad_band_text_is_one_clear_error(work, capsys, text):
    assert main(["calibrate", str(work["model"]), *map(str, work["free"]), f"--band={text}",
                 "-o", str(work["folder"] / "bad.skops")]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("gpcd calibrate: error: argument --band: expected "
                          "CUTOFF,ORDER,DEBOUNCE like 10,1,2") and repr(text) in err


def test_bands_refuse_select(work, capsys):
    assert main(["calibrate", str(work["model"]), *map(str, work["free"]), "--band", "10,1,2",
                 "--select", "-o", str(work["folder"] / "select.skops")]) == 2
    assert "drop --select or the bands" in capsys.readouterr().err


# ------------------------------------------------------------------ --braking
def test_braking_takes_the_limit_given_or_the_models_own(work, capsys):
    recs = [load_recording(p) for p in work["free"]]
    trained = load_model(work["model"])
    qdd = np.abs(trained.features.transform(recs[0])[:, 12:18]).max()
    limit = round(0.5 * float(qdd), 3)  # hard enough to brake on these runs
    given = work["folder"] / "braking.skops"
    assert main(["calibrate", str(work["model"]), *map(str, work["free"]),
                 f"--braking={limit}", "--no-select", "-q", "-o", str(given)]) == 0
    assert f"braking above {limit:.3g} rad/s^2" in capsys.readouterr().out
    detector, _, calibration = load_detector(given)
    assert detector.rules[0].regimes.brake_limit == limit
    assert calibration["brake_limit"] == limit
    assert calibration["regimes"] == ["moving", "settling", "rest", "braking",
                                      "settling after 0.25 s"]
    blocks = {p.name: stack_currents(trained.features.transform(r), r.current)
              for p, r in zip(work["free"], recs)}
    times = {p.name: r.time for p, r in zip(work["free"], recs)}
    template = CollisionDetector(
        FrozenEstimator(trained.regressor), n_joints=6, sample_time="auto",
        rules=AlarmRule(**DETECTOR_RULE, regimes=Regimes(rest_reference=5.0, brake_limit=limit)))
    expected = calibrate_across_recordings(template, blocks, times)
    # a regime with less than 1 s of data takes, joint by joint, the largest
    # threshold of the regimes with data (issue 46)
    thin = [calibration["regimes"].index(name) for name in calibration["regimes_without_data"]]
    assert all(calibration["coverage"][calibration["regimes"][g]]["seconds"] < 1.0 for g in thin)
    wanted = np.array(expected.detector.thresholds_, copy=True)
    rich = [g for g in range(len(wanted)) if g not in thin]
    wanted[thin] = wanted[rich].max(axis=0)
    np.testing.assert_allclose(detector.thresholds_, wanted)
    assert any((expected.detector.monitoring_signal(b).regime == 3).any()
               for b in blocks.values())
    # without LIMIT: the one gpcd train recorded in the model file
    own = save_model(TrainedModel(trained.regressor, trained.features,
                                  {"model": "sp_c", "inputs": "causal", "n_support": 0,
                                   "optimizer": "none", "seed": 0,
                                   "acceleration_limit": 2.5}), work["folder"] / "own.skops")
    out = work["folder"] / "own_braking.skops"
    assert main(["calibrate", str(own), *map(str, work["free"]), "--braking", "-q",
                 "-o", str(out)]) == 0
    assert load_detector(out)[0].rules[0].regimes.brake_limit == 2.5


@pytest.mark.parametrize("args, message", [
    (["--braking"], "does not record the largest acceleration"),  # the fixture's model: {}
    (["--braking=-1"], "argument --braking: expected an acceleration > 0"),
    (["--braking=fast"], "argument --braking: expected an acceleration > 0"),
    (["--braking=2", "--no-regimes"], "--braking is a regime: drop --no-regimes"),
])
def test_braking_errors_say_what_to_do(work, capsys, args, message):
    assert main(["calibrate", str(work["model"]), *map(str, work["free"]), *args,
                 "-o", str(work["folder"] / "bad.skops")]) == 2
    assert message in capsys.readouterr().err


def test_settle_time_is_an_option_and_select_refuses_it(work, capsys):
    out = work["folder"] / "settle.skops"
    assert main(["calibrate", str(work["model"]), *map(str, work["free"]), "--settle-time",
                 "2", "--rest-reference", "2", "-q", "-o", str(out)]) == 0
    detector = load_detector(out)[0]
    regimes = detector.rules[0].regimes
    assert (regimes.settle_time, regimes.rest_reference) == (2.0, 2.0)
    assert main(["calibrate", str(work["model"]), *map(str, work["free"]), "--settle-time",
                 "2", "--select", "-o", str(out)]) == 2
    assert "drop --settle-time" in capsys.readouterr().err


def test_band_candidates_are_chosen_like_the_package_does(work, capsys):
    out = work["folder"] / "chosen.skops"
    assert main(["calibrate", str(work["model"]), *map(str, work["free"]),
                 "--band-candidate", "10,1,2", "--band-candidate", "5,2,3", "-q",
                 "-o", str(out)]) == 0
    text = capsys.readouterr().out
    detector, _, calibration = load_detector(out)
    blocks, times, template = _by_hand(work)
    grid = [{k: [v] for k, v in band.items()} for band in (FAST, MID)]
    expected = calibrate_across_recordings(banded(template), blocks, times, param_grid=grid)
    chosen = expected.settings
    assert detector.rules_[1].filter_cutoff == chosen["filter_cutoff"]
    for fitted, band in zip(detector.rules_, expected.bands):
        np.testing.assert_allclose(fitted.thresholds_, band.rule.thresholds_)
    assert calibration["n_false_alarms_nested"] == expected.n_false_alarms
    assert sorted(c["rank"] for c in calibration["band_candidates"]) == [0, 1]
    assert sorted(calibration["fold_band_settings"]) == sorted(blocks)
    assert "<- chosen" in text and "chosen without each recording" in text
    label = (f"{chosen['filter_cutoff']:g} Hz, order {chosen['filter_order']}, "
             f"debounce {chosen['min_duration']}")
    assert f"band 2 ({label})" in text
    assert "levels and band chosen without it" in text


def test_band_candidates_refuse_select(work, capsys):
    assert main(["calibrate", str(work["model"]), *map(str, work["free"]), "--select",
                 "--band-candidate", "10,1,2", "-q", "-o",
                 str(work["folder"] / "x.skops")]) == 2
    assert "drop --select or the bands" in capsys.readouterr().err
