"""``benchmarks/isolation_ur10e.py``: the momentum observer through the detector's
rule, and a clean exit without the data."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from sklearn_gpcd.detection import stack_currents
from sklearn_gpcd.dynamics import MomentumObserver

from _pushes import inputs, training_run

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "isolation_ur10e.py"


@pytest.fixture(scope="module")
def bench():
    sys.path.insert(0, str(SCRIPT.parent))
    spec = importlib.util.spec_from_file_location("isolation_ur10e", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_missing_data_exits_zero_with_message(bench, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        bench.main(["--data", str(tmp_path / "absent"), "--output", str(tmp_path / "out")])
    assert exc.value.code == 0
    assert "not found" in capsys.readouterr().out
    assert not (tmp_path / "out").exists()


def test_the_observer_is_the_benchmark_rule_s_residual_model(bench):
    """The benchmark's rule (``real_ur10e.detector``) takes the observer itself:
    the detector's residual is the observer's."""
    rec = training_run(seed=1, n_targets=3)
    obs = MomentumObserver("ur10", identify="friction", sample_time=0.008).fit(
        inputs(rec), rec.current)
    block = stack_currents(inputs(rec), rec.current)
    det = bench.detector(obs).fit(block, time=rec.time)
    np.testing.assert_allclose(det.monitoring_signal(block).residual,
                               obs.residual(inputs(rec), rec.current), rtol=0, atol=1e-12)
