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


def test_reproduce_reports_the_causal_detection_path(tiny_run):
    out, results = tiny_run
    assert results["detector"]["path"].startswith("causal path")
    assert f"Detection path: {results['detector']['path']}." in (out / "report.md").read_text()


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


class _Alarms:
    """A detector stand-in whose ``predict`` returns fixed alarms."""

    def __init__(self, alarms):
        self.alarms = np.asarray(alarms, dtype=bool)

    def predict(self, Z):
        assert len(Z) == self.alarms.size
        return np.where(self.alarms, -1, 1)


def test_an_alarm_outlasting_its_push_is_not_a_false_alarm():
    from types import SimpleNamespace

    from sklearn_gpcd.experiments.paper import interaction_outcome

    #           moving ...............  rest ...................
    labels = [0, 1, 1, 1, 0, 0, 0, 0, 0, 2, 2, 0, 0, 0, 0, 0]
    alarms = [0, 0, 1, 1, 1, 1, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0]
    n = len(labels)
    target_qd = np.zeros((n, 2))
    target_qd[:8] = 0.5
    recording = SimpleNamespace(labels=np.array(labels), time=0.01 * np.arange(n),
                                target_qd=target_qd, qd=target_qd)
    out = interaction_outcome(_Alarms(alarms), np.zeros((n, 4)), np.zeros((n, 2)),
                              recording, sigma_v=0.01)
    assert [p["detected"] for p in out["pushes"]] == [True, True]
    assert [p["while_moving"] for p in out["pushes"]] == [True, False]
    # the alarms at 4-5 and 11 continue the pushes' own; 7 and 14 start on free samples
    assert (out["false_alarms_moving"], out["false_alarms_rest"]) == (1, 1)
    assert (out["false_alarm_samples_moving"], out["false_alarm_samples_rest"]) == (3, 2)


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
    assert results["interaction"]["false_alarms_moving"] == 0


def _full_nmse(d2_dynamic_sp_p, d2_dynamic_p_f):
    """nMSE tables of every (data set, regime) with SP_P best except where given."""
    tables = {name: {} for name in ("P_f", "SP_S", "SP_P")}
    for dataset in ("D1_test", "D2"):
        for regime in ("dynamic", "quasi_static"):
            tables["P_f"].setdefault(dataset, {})[regime] = [0.2] * 6
            tables["SP_S"].setdefault(dataset, {})[regime] = [0.3] * 6
            tables["SP_P"].setdefault(dataset, {})[regime] = [0.1] * 6
    tables["SP_P"]["D2"]["dynamic"] = d2_dynamic_sp_p
    tables["P_f"]["D2"]["dynamic"] = d2_dynamic_p_f
    return tables


def test_report_verdict_covers_every_table_with_its_losses():
    from sklearn_gpcd.experiments.report import _verdicts

    nmse = _full_nmse([0.1, 0.065, 0.07, 0.1, 0.1, 0.1], [0.2, 0.036, 0.04, 0.2, 0.2, 0.2])
    results = {"nmse": nmse,
               "interaction": {"pushes": [{"detected": True}], "all_pushes_detected": True,
                               "false_alarms_rest": 0, "false_alarms_moving": 0}}
    text = _verdicts({**results, "checks": acceptance_checks(results)})
    for dataset in ("D1_test", "D2"):
        for regime in ("dynamic", "quasi-static"):
            assert f"- {dataset}, {regime}: SP_P lowest on joint(s)" in text
    line = next(ln for ln in text.splitlines() if ln.startswith("- D2, dynamic"))
    assert "SP_P lowest on joint(s) 1, 4, 5, 6 of 6" in line
    assert "worse than P_f on joint(s) 2 (0.065 vs 0.036), 3 (0.07 vs 0.04)" in line
    assert "SP_S" not in line  # SP_P beats SP_S everywhere: no loss to report
    assert "worse than" not in text.replace(line, "")


def test_nmse_legend_does_not_cover_any_bar():
    plt = pytest.importorskip("matplotlib.pyplot")
    from sklearn_gpcd.experiments.report import _nmse_figure

    nmse = _full_nmse([0.1] * 6, [0.2] * 6)
    for regime in ("dynamic", "quasi_static"):
        for name in nmse:  # tall joint-6 bars, where the old legend sat
            for dataset in ("D1_test", "D2"):
                nmse[name][dataset][regime] = [0.01, 0.02, 0.03, 0.05, 0.5, 1.0]
        fig = _nmse_figure(plt, nmse, regime)
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        legend = fig.legends[0].get_window_extent(renderer)
        bars = [p.get_window_extent(renderer) for ax in fig.axes for p in ax.patches]
        assert len(bars) == 2 * 3 * 6
        assert not any(legend.overlaps(b) for b in bars)
        assert not any(legend.overlaps(ax.get_window_extent(renderer)) for ax in fig.axes)
        plt.close(fig)


def test_interaction_figure_names_the_pushes_and_marks_the_alarms(monkeypatch, tmp_path):
    plt = pytest.importorskip("matplotlib.pyplot")
    from types import SimpleNamespace

    from sklearn_gpcd.experiments.report import plot_interaction
    from sklearn_gpcd.io import Recording

    n = 200
    t = np.arange(n) * 0.01
    labels = np.where((t > 0.5) & (t < 0.8), 1, 0)
    alarm = (t > 0.55) & (t < 0.9)
    y = np.sin(t)[:, None] * np.ones((1, 6))
    rec = Recording(time=t, q=np.zeros((n, 6)), qd=np.zeros((n, 6)), current=y, labels=labels)
    closed = []
    monkeypatch.setattr(plt, "close", closed.append)
    path = plot_interaction(rec, y * 0.9, SimpleNamespace(thresholds_=np.full(6, 0.1)),
                            None, y, tmp_path / "interaction.png", alarm=alarm)
    assert path.stat().st_size > 1000
    top, _, bottom = closed[0].axes
    texts = [x.get_text() for x in bottom.get_legend().get_texts()]
    assert "labelled contact" in texts and "alarm" in texts
    assert "labelled contact" in [x.get_text() for x in top.get_legend().get_texts()]
    onsets = [ln.get_xdata()[0] for ln in bottom.get_lines() if ln.get_linestyle() == ":"]
    assert onsets == [pytest.approx(t[alarm][0])]
    fig = closed[0]
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    for ax in (top, bottom):  # the legends sit beside the panels, off the signals
        assert not ax.get_legend().get_window_extent(renderer).overlaps(
            ax.get_window_extent(renderer))
    closed.clear()
    plot_interaction(rec, y * 0.9, SimpleNamespace(thresholds_=np.full(6, 0.1)),
                     None, y, tmp_path / "quiet.png", alarm=np.zeros(n, dtype=bool))
    texts = [x.get_text() for x in closed[0].axes[2].get_legend().get_texts()]
    assert "alarm (none)" in texts
