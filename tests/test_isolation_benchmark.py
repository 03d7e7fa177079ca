"""``benchmarks/isolation_ur10e.py``: the glue that puts the momentum observer
through the detector's rule, and a clean exit without the data."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from sklearn_gpcd.detection import CollisionDetector
from sklearn_gpcd.dynamics import ControllerCurrent, MomentumObserver
from sklearn_gpcd.io import Recording

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


def test_the_detector_residual_of_an_observer_block_is_the_observer_residual(bench):
    rec = training_run(seed=1, n_targets=3)
    augmented = np.hstack([inputs(rec), np.zeros((rec.n_samples, 18))])  # [.., e_q, de_q, i_c]
    obs = MomentumObserver("ur10", identify="friction").fit(augmented, rec.current,
                                                            time=rec.time)
    block = bench.observer_block(obs, augmented, rec)
    det = CollisionDetector(ControllerCurrent(6), n_joints=6, sample_time=0.008).fit(block)
    np.testing.assert_allclose(det.monitoring_signal(block).residual,
                               obs.residual(augmented, rec.current, time=rec.time),
                               rtol=1e-12, atol=1e-12)
    assert isinstance(rec, Recording)
