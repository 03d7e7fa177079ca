"""The real-UR10e detection benchmark (``benchmarks/real_ur10e.py``) and the causal
path on a real recording (both skip without the data)."""

import importlib.util
import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from sklearn_gpcd.detection import AlarmRule, CollisionDetector, Regimes, stack_currents
from sklearn_gpcd.dynamics import ControllerCurrent
from sklearn_gpcd.features import CausalFeatures
from sklearn_gpcd.io import load_recording

from _synthetic import assert_raw_stream_equals_batch

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "real_ur10e.py"
LABELS = Path(__file__).resolve().parents[1] / "benchmarks" / "labels" / "ur10e_events.json"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("real_ur10e", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_unloaded_selection_keeps_unload_and_drops_load(bench):
    names = ["ur-20_01_31-unload.csv", "ur-20_01_31-load.csv", "ur-20_01_13-load_2600.csv",
             "ur-20_02_19_15harm50secLoad.csv", "ur-20_02_05-20sec_12harm.csv"]
    assert [bench.is_unloaded(n) for n in names] == [True, False, False, False, True]


def test_loro_margin_is_the_worst_left_out_excess(bench):
    peaks = {"a": np.ones((3, 6)), "b": np.full((3, 6), 2.0), "c": np.ones((3, 6))}
    peaks["c"][2, 1] = 3.0
    cell = bench.loro_margin(peaks, list(peaks), "cell")
    # b exceeds max(a, c) = 1 by 2 everywhere but at (rest, joint 2), where c is 3
    assert cell[0, 0] == 2.0 and cell[2, 1] == pytest.approx(1.5)
    assert np.all(bench.loro_margin(peaks, list(peaks), "global") == 2.0)
    rule = bench.loro_margin(peaks, list(peaks), "regime")
    assert rule.shape == (3, 6) and np.all(rule == 2.0)


def test_levels_fill_an_absent_regime_with_the_largest(bench):
    peaks = {"a": np.array([[1.0, 2.0], [0.0, 0.0], [0.5, 0.2]])}
    np.testing.assert_array_equal(bench.levels(peaks, ["a"])[1], [1.0, 2.0])


def test_each_monitor_is_compared_with_the_peer_of_its_own_rule(bench):
    pairs = {name: bench.same_rule_peer(name) for name in
             ("P_f", "SP_C", "SP_C +R", "SP_C sel", bench.PEER, bench.PEER + " sel")}
    assert pairs == {"P_f": bench.PEER, "SP_C": bench.PEER, "SP_C +R": bench.PEER + " +R",
                     "SP_C sel": bench.PEER + " sel", bench.PEER: bench.PEER,
                     bench.PEER + " sel": bench.PEER + " sel"}


def test_labels_are_stored_with_their_method():
    data = json.loads(LABELS.read_text())
    assert "method" in data and len(data["method"]) > 200
    pushes = [f for f in data["files"] if "push_pose" in f]
    assert len(pushes) == 2
    for name in pushes:
        events = data["files"][name]["events"]
        assert len(events) >= 3
        assert all(e["start_s"] < e["stop_s"] for e in events)
    assert data["files"]["collision_detection_data_2020/collision_free.csv"]["events"] == []


def test_missing_data_exits_zero_with_message(bench, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        bench.main(["--data", str(tmp_path / "absent"), "--output", str(tmp_path / "out")])
    assert exc.value.code == 0
    assert "not found" in capsys.readouterr().out
    assert not (tmp_path / "out").exists()


def _load(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_recording(path)


def _peer_on_ptp(ur10e_dir, **regimes):
    """Causal features and the robot's residual as a detector (the benchmark's rule
    with ``regimes``), both fitted on ptp_10_points."""
    free = _load(ur10e_dir / "validation_data" / "ur-20_01_17-ptp_10_points.csv")
    features = CausalFeatures().fit(free)
    rule = AlarmRule("per_joint", false_alarm_rate=0.0, margin=1.5, filter_cutoff=2.0,
                     min_duration=5, regimes=Regimes(**regimes))
    det = CollisionDetector(ControllerCurrent(6), n_joints=6, sample_time="auto", rules=rule)
    det.fit(stack_currents(features.transform(free), free.current), time=free.time)
    return features, det


@pytest.mark.realdata
def test_batch_equals_streaming_on_a_real_push_recording(ur10e_dir):
    """Raw UR10e samples through StreamingMonitor == the batch detector, sample for sample."""
    features, det = _peer_on_ptp(ur10e_dir, rest_reference=5.0)
    push = _load(ur10e_dir / "collision_push_pose" / "ur-20_01_22-push_pose_1.csv")
    out = assert_raw_stream_equals_batch(det, features, push)
    assert (out.prediction == -1).any() and (out.prediction == 1).any()


@pytest.mark.realdata
def test_batch_equals_streaming_with_the_braking_regime_on_a_real_hard_stop(ur10e_dir):
    """jointwise_2's hard stops (causal |qdd| up to 8 rad/s^2) in the braking regime,
    raw samples through StreamingMonitor == the batch detector."""
    features, det = _peer_on_ptp(ur10e_dir, rest_reference=2.0, settle_time=3.0,
                                 brake_limit=5.05)
    stops = _load(ur10e_dir / "jointwise_motion" / "ur-20_01_22-joint_2.csv")
    out = assert_raw_stream_equals_batch(det, features, stops)
    assert (out.regime == 3).sum() > 40


@pytest.mark.slow
def test_quick_run_on_real_data(bench, ur10e_dir, tmp_path):
    out = tmp_path / "out"
    bench.main(["--quick", "--n-support", "100", "--data", str(ur10e_dir),
                "--output", str(out)])
    saved = json.loads((out / "real_ur10e.json").read_text())
    assert saved["n_support"] == 100
    assert set(saved["monitors"]) == {"i - i_des", "P_f", "SP_S", "SP_P", "SP_C",
                                      "i - i_des +R", "SP_C +R", "i - i_des sel",
                                      "P_f sel", "SP_S sel", "SP_C sel", *bench.BANDED.values(),
                                      "observer", "observer +R", "observer sel"}
    chosen = saved["monitors"]["SP_C sel"]
    assert len(chosen["candidates"]) == 12 and len(chosen["fold_settings"]) == len(
        saved["unseen_collision_free"])
    assert saved["unseen_minutes"] > 10
    assert not set(saved["train_files"]) & set(bench.HELD_OUT)
    for result in saved["monitors"].values():
        assert result["n_events"] == 10
        assert len(result["folds"]) == len(saved["unseen_collision_free"])
    assert (out / bench.TABLES).read_text().count("SP_C +R") >= 5
    family = saved["collision_detection_data_2020"]
    assert set(family) == {"P_f", "SP_S", "P_f sel", "SP_S sel", bench.BANDED["P_f~"],
                           "observer", "observer sel"}
    assert all(res["n_events"] == 25 for res in family.values())
