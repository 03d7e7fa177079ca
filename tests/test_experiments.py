"""Tests of the paper's experiments pipeline (``gpcd reproduce``)."""

import json

import numpy as np
import pytest

from sklearn_gpcd.cli import main
from sklearn_gpcd.experiments import PaperConfig, reproduce, split_nmse
from sklearn_gpcd.experiments.paper import acceptance_checks

TINY = PaperConfig(d1_targets=3, d2_targets=1, n_support=150, batch_size=100, rest_duration=8.0)


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce")
    results = reproduce(out, config=TINY, random_state=0, verbose=False)
    return out, results


def test_reproduce_writes_report_json_and_figures(tiny_run):
    out, results = tiny_run
    report = (out / "report.md").read_text()
    on_disk = json.loads((out / "results.json").read_text())
    assert on_disk["nmse"].keys() == {"P_f", "SP_S", "SP_P"}
    for figure in ("nmse_dynamic", "nmse_quasi_static", "cyclic", "interaction"):
        name = on_disk["figures"][figure]
        assert (out / name).stat().st_size > 10_000
        assert f"]({name})" in report
    assert "## Verdict" in report


def test_results_json_holds_every_number_of_the_report(tiny_run):
    out, _ = tiny_run
    results = json.loads((out / "results.json").read_text())
    report = (out / "report.md").read_text()
    for name in ("P_f", "SP_S", "SP_P"):
        for value in results["nmse"][name]["D2"]["quasi_static"]:
            if value is not None:
                assert f"{value:.3g}" in report
    assert len(results["interaction"]["pushes"]) == 4
    assert results["n_samples"]["d1"] > 0


def test_report_states_failures_plainly():
    results = {
        "nmse": {name: {"D2": {"quasi_static": [1.0, 1.0, 1.0]}}
                 for name in ("P_f", "SP_S", "SP_P")},
        "interaction": {"pushes": [{"detected": False}], "all_pushes_detected": False,
                        "false_alarms_rest": 2, "false_alarms_moving": 0},
    }
    checks = acceptance_checks(results)
    assert not checks["sp_p_quasi_static_best_majority"]
    assert not checks["all_pushes_detected"]
    assert not checks["no_false_alarm_at_rest"]
    from sklearn_gpcd.experiments.report import _verdicts

    text = _verdicts({**results, "checks": checks})
    assert text.count("Not delivered") == 3


def test_split_nmse_separates_regimes():
    rng = np.random.default_rng(0)
    y = rng.normal(size=(200, 2))
    qd = np.zeros((200, 2))
    qd[100:] = 1.0
    y_pred = y.copy()
    y_pred[:100] += 0.5 * rng.normal(size=(100, 2))  # errors only at rest
    out = split_nmse(y, y_pred, qd, sigma_v=1e-2)
    assert out["dynamic"] == [0.0, 0.0]
    assert all(v > 0.1 for v in out["quasi_static"])
    assert out["n_quasi_static"] == [100, 100]


@pytest.mark.slow
def test_gpcd_reproduce_quick_end_to_end(tmp_path):
    """The README's main job, as a user runs it (minutes)."""
    assert main(["reproduce", "--quick", "-o", str(tmp_path), "--quiet"]) == 0
    results = json.loads((tmp_path / "results.json").read_text())
    assert (tmp_path / "report.md").exists()
    assert set(results["figures"]) == {"nmse_dynamic", "nmse_quasi_static", "cyclic",
                                       "interaction"}
    # the paper's claims, on the quick sizes
    assert results["checks"]["sp_p_quasi_static_best_majority"]
    assert results["checks"]["all_pushes_detected"]
    assert results["checks"]["no_false_alarm_at_rest"]
