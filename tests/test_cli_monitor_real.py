"""``gpcd train`` -> ``gpcd calibrate`` -> ``gpcd monitor`` on the real UR10e logs gives the
thresholds, nested false alarms and alarms of ``benchmarks/real_ur10e.py``'s functions on
the same model and data (skips without the data)."""

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from sklearn_gpcd.cli import main
from sklearn_gpcd.cli_monitor import load_detector
from sklearn_gpcd.detection import stack_currents
from sklearn_gpcd.features import CausalFeatures
from sklearn_gpcd.persistence import load

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "real_ur10e.py"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("real_ur10e_cli", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


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
                 "-o", str(det_path)]) == 0
    events_json = tmp_path / "events.json"
    assert main(["monitor", str(det_path), *(str(ur10e_dir / k) for k in bench.PUSHES),
                 "-q", "--json", str(events_json)]) == 0
    capsys.readouterr()
    detector, features, calibration = load_detector(det_path)

    # the benchmark's functions on the same model and recordings
    unseen = {k: bench.load(ur10e_dir / k) for k in cal_keys}
    reference = CausalFeatures().fit([bench.load(f) for f in train])
    assert features.signals_ == reference.signals_  # same inputs as the benchmark builds
    blocks = {k: stack_currents(reference.transform(r), r.current) for k, r in unseen.items()}
    Z = np.concatenate(list(blocks.values()))
    groups = np.repeat(np.arange(len(unseen)), [r.n_samples for r in unseen.values()])
    time = np.concatenate([r.time for r in unseen.values()])
    regressor = load(model)
    base = bench.detector(regressor, bench.REST_TAU).fit(Z, groups=groups, time=time)
    series = bench.excursions(base, blocks)
    margin = bench.loro_margin({k: v[2] for k, v in series.items()}, list(series))
    det = bench.detector(regressor, bench.REST_TAU, margin).fit(Z, groups=groups, time=time)
    folds = bench.nested_false_alarms(series, unseen)
    np.testing.assert_allclose(detector.thresholds_, det.thresholds_)
    assert calibration["margin"] == pytest.approx(np.max(margin))
    assert calibration["n_false_alarms_nested"] == sum(len(f["onsets"])
                                                       for f in folds.values())
    saved = json.loads(events_json.read_text())["events"]
    for key in bench.PUSHES:
        rec = bench.load(ur10e_dir / key)
        block = stack_currents(reference.transform(rec), rec.current)
        _, _, mon = bench.score_events(det, block, rec, [])
        t = rec.time - rec.time[0]
        expected = bench.alarm_onsets(mon.alarms.any(axis=1), t)
        got = [e["start_s"] for e in saved if e["recording"] == Path(key).name]
        assert got == pytest.approx(expected), key
        assert expected  # the pushes do raise alarms
