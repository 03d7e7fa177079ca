"""The real-UR10e benchmark script (``benchmarks/real_ur10e.py``)."""

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "real_ur10e.py"


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


def test_alarm_episodes_merge_short_gaps(bench):
    t = np.arange(100) * 0.01
    alarm = np.zeros(100, dtype=bool)
    alarm[10:20] = alarm[25:30] = alarm[70:75] = True  # gap 0.05 s, then 0.4 s
    assert bench.alarm_episodes(alarm, t, gap=0.3) == [(10, 30), (70, 75)]


def test_missing_data_exits_zero_with_message(bench, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        bench.main(["--data", str(tmp_path / "absent"), "--output", str(tmp_path / "out")])
    assert exc.value.code == 0
    assert "not found" in capsys.readouterr().out
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_quick_run_on_real_data(bench, ur10e_dir, tmp_path):
    out = tmp_path / "out"
    results = bench.main(["--quick", "--data", str(ur10e_dir), "--output", str(out)])
    saved = json.loads((out / "real_ur10e.json").read_text())
    assert saved["n_support"] == 500
    assert set(saved["nmse"]) == {"P_f", "SP_S", "SP_P"}
    # the still poses have no dynamic samples; every joint has quasi-static ones
    assert saved["counts"]["p1..p10"]["n_dynamic"] == [0] * 6
    assert min(saved["counts"]["p1..p10"]["n_quasi_static"]) > 1000
    assert all(name.endswith(".csv") and "load" not in name.replace("unload", "").lower()
               for name in saved["train_files"])
    assert bench.HELD_OUT not in saved["train_files"]
    for name in ("P_f", "SP_S", "SP_P"):
        assert len(results["detection"][name]["files"]) == 2
    assert (out / bench.TABLES).read_text().count("estimator") >= 8
