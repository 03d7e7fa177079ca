"""``gpcd train`` -> ``gpcd calibrate`` -> ``gpcd monitor`` on the real UR10e logs
reproduces the detection figures of ``benchmarks/real_ur10e.py`` (skips without the data).

``test_cli_reproduces_the_benchmark_figures`` runs the benchmark itself (``--quick
--n-support 100``) and the three commands with the benchmark's settings on the
benchmark's recordings, and compares margin, thresholds, nested false alarms and
per-push detections and delays exactly (SP_C +R and SP_P);
``test_cli_reproduces_the_published_full_run`` does the same against the full run
published in ``docs/_static/results/real_ur10e.json`` (SP_C +R).
``test_cli_workflow_matches_the_benchmark_rule_on_real_logs`` is the quicker check on
part of the logs: ``gpcd calibrate`` and the benchmark's ``calibrate_detector`` options.
"""

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from sklearn_gpcd.cli import main
from sklearn_gpcd.workflow import load_detector
from sklearn_gpcd.detection import stack_currents
from sklearn_gpcd.workflow import load_model

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "real_ur10e.py"
PUBLISHED = Path(__file__).resolve().parents[1] / "docs" / "_static" / "results" / \
    "real_ur10e.json"
N_SUPPORT, SEED, N_JOBS = 100, 0, 2


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("real_ur10e_cli", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _cli_alarms(events, name, rec):
    """Alarm samples (any joint) of ``rec`` from ``gpcd monitor``'s events: each event
    runs from its first to its last alarm sample."""
    t = rec.time - rec.time[0]
    alarm = np.zeros(len(t), dtype=bool)
    for e in events:
        if e["recording"] == name:
            alarm |= (t >= e["start_s"]) & (t <= e["end_s"])
    return alarm, t


def _assert_cli_reproduces(bench, root, tmp_path, published, monitor, model, calibrate=()):
    """``gpcd train`` (the benchmark's settings, from ``published``) -> ``gpcd calibrate``
    (its unseen collision-free recordings, in its order) -> ``gpcd monitor`` (its push
    recordings) give ``published["monitors"][monitor]``: equal, not close."""
    settings = bench.train_settings(published["n_support"], published["seed"], N_JOBS)
    options = ["--inputs", settings["inputs"], "--n-support", str(settings["n_support"]),
               "--optimizer", settings["optimizer"], "--seed", str(settings["seed"]),
               "--n-jobs", str(settings["n_jobs"])]
    train = [str(root / bench.IDENTIFICATION / name) for name in published["train_files"]]
    unseen = [str(root / key) for key in published["unseen_collision_free"]]
    expected = published["monitors"][monitor]
    model_file, det_file = tmp_path / f"{model}.skops", tmp_path / f"{model}_det.skops"
    events_file = tmp_path / f"{model}_events.json"
    assert main(["train", *train, "--model", model, *options, "-q",
                 "-o", str(model_file)]) == 0
    fixed = [] if "--select" in calibrate else ["--no-select"]  # the benchmark's rule
    assert main(["calibrate", str(model_file), *unseen, *calibrate, *fixed, "-q",
                 "-o", str(det_file)]) == 0
    assert main(["monitor", str(det_file), *(str(root / k) for k in bench.PUSHES), "-q",
                 "--json", str(events_file)]) == 0
    trained = load_model(model_file)
    assert trained.training["recordings"] == published["train_files"]
    assert (trained.training["inputs"], trained.training["optimizer"]) == ("causal", "adam")
    detector, _, calibration = load_detector(det_file)
    # margin, thresholds per regime and joint
    assert calibration["margin"] == np.max(expected["margin"]), monitor
    assert np.array_equal(calibration["thresholds_A"], expected["thresholds"]), monitor
    assert np.array_equal(np.atleast_2d(detector.thresholds_), expected["thresholds"])
    # nested false alarms: the count, and each onset on each left-out recording
    assert calibration["n_false_alarms_nested"] == expected["onsets"], monitor
    assert calibration["nested_onsets_s"] == {
        Path(k).name: f["onsets"] for k, f in expected["folds"].items()}, monitor
    assert calibration["hours"] * 60 == pytest.approx(published["unseen_minutes"], rel=1e-12)
    # every labelled push: detected or not, delay; alarm onsets outside the pushes
    labels = json.loads(bench.LABELS.read_text())["files"]
    saved = json.loads(events_file.read_text())["events"]
    detected = 0
    for key in bench.PUSHES:
        rec = bench.load(root / key)
        alarm, t = _cli_alarms(saved, Path(key).name, rec)
        scored, outside = bench.score_alarms(alarm, t, labels[key]["events"])
        assert [(e["detected"], e["delay_s"]) for e in scored] == \
            [(e["detected"], e["delay_s"]) for e in expected["events"][key]], (monitor, key)
        assert outside == expected["outside"][key], (monitor, key)
        detected += sum(e["detected"] for e in scored)
    assert detected == expected["n_detected"]


@pytest.mark.slow
def test_cli_reproduces_the_benchmark_figures(bench, ur10e_dir, tmp_path, capsys):
    """The benchmark run here (--quick --n-support 100) and the CLI with its settings."""
    bench.main(["--quick", "--n-support", str(N_SUPPORT), "--seed", str(SEED),
                "--n-jobs", str(N_JOBS), "--data", str(ur10e_dir),
                "--output", str(tmp_path / "bench")])
    published = json.loads((tmp_path / "bench" / "real_ur10e.json").read_text())
    train, unseen, _ = bench.split_recordings(ur10e_dir, quick=True)
    assert [r.name for r in train] == published["train_files"]
    assert list(unseen) == list(published["unseen_collision_free"])
    # the operating point (SP_C +R) and the paper's SP_P (no rest reference)
    _assert_cli_reproduces(bench, ur10e_dir, tmp_path, published, "SP_C +R", "sp_c")
    _assert_cli_reproduces(bench, ur10e_dir, tmp_path, published, "SP_P", "sp_p",
                           ["--rest-reference", "0"])
    capsys.readouterr()


@pytest.mark.slow
def test_cli_reproduces_the_published_full_run(bench, ur10e_dir, tmp_path, capsys):
    """The figures published in docs/_static/results (the full run: 12 training runs,
    1,000 support rows) at the operating point, SP_C +R."""
    published = json.loads(PUBLISHED.read_text())
    assert published["mode"] == "full"
    _assert_cli_reproduces(bench, ur10e_dir, tmp_path, published, "SP_C +R", "sp_c")
    capsys.readouterr()


def test_cli_workflow_matches_the_benchmark_rule_on_real_logs(bench, ur10e_dir, tmp_path,
                                                               capsys):
    ident = ur10e_dir / bench.IDENTIFICATION
    train = [f for f in sorted(ident.glob("*.csv"))
             if bench.is_unloaded(f.name) and f.name not in bench.HELD_OUT
             and bench.load(f).target_current is not None][:2]
    cal_keys = [f"{bench.IDENTIFICATION}/{n}" for n in bench.HELD_OUT[:2]] + \
        bench.STILL[:3] + [bench.PTP]
    model, det_path = tmp_path / "model.skops", tmp_path / "detector.skops"
    assert main(["train", *map(str, train), "--model", "sp_c", "--n-support", "200", "-q",
                 "-o", str(model)]) == 0
    assert main(["calibrate", str(model), *(str(ur10e_dir / k) for k in cal_keys), "-q",
                 "--no-select", "-o", str(det_path)]) == 0
    events_json = tmp_path / "events.json"
    assert main(["monitor", str(det_path), *(str(ur10e_dir / k) for k in bench.PUSHES),
                 "-q", "--json", str(events_json)]) == 0
    capsys.readouterr()
    detector, features, calibration = load_detector(det_path)

    # the benchmark's path (calibrate_detector, "+R") on the same model and recordings
    unseen = {k: bench.load(ur10e_dir / k) for k in cal_keys}
    pushes = {k: bench.load(ur10e_dir / k) for k in bench.PUSHES}
    trained = load_model(model)
    assert features.signals_ == trained.features.signals_  # the model's own inputs
    blocks, push_blocks = ({k: stack_currents(features.transform(r), r.current)
                            for k, r in recs.items()} for recs in (unseen, pushes))
    labels = json.loads(bench.LABELS.read_text())["files"]
    res = bench.monitor_result(trained, bench.REST, blocks, unseen, pushes, push_blocks,
                               labels)
    np.testing.assert_allclose(detector.thresholds_, res["thresholds"])
    assert calibration["margin"] == pytest.approx(np.max(res["margin"]))
    assert calibration["n_false_alarms_nested"] == res["onsets"]
    saved = json.loads(events_json.read_text())["events"]
    for key, rec in pushes.items():
        t = rec.time - rec.time[0]
        expected = bench.alarm_onsets(res["monitors"][key].alarms.any(axis=1), t)
        got = [e["start_s"] for e in saved if e["recording"] == Path(key).name]
        assert got == pytest.approx(expected), key
        assert expected  # the pushes do raise alarms
