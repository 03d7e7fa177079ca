"""Moving thresholds at least the model's out-of-fold level on its training runs (issue 45).

One calibration log sets the moving thresholds from its own motion; another
motion meets the model's error where it was not calibrated. ``gpcd train
--model auto`` measured that error on training runs each fold left out: the
calibration raises the moving row to it, never lowers it, and leaves the
other regimes alone.
"""

import dataclasses
import warnings

import numpy as np
import pytest

from sklearn_gpcd.io import Recording
from sklearn_gpcd.workflow import calibrate_detector, calibration_report, train_model
from sklearn_gpcd.workflow.calibration import training_moving_level


def _recording(seconds, phase, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * 100)) * 0.01
    q = np.sin(0.5 * t + phase)[:, None]
    qd = 0.5 * np.cos(0.5 * t + phase)[:, None]
    return Recording(time=t, q=q, qd=qd, current=2 * q + 0.05 * rng.normal(size=q.shape),
                     target_current=2 * q)


@pytest.fixture(scope="module")
def trained():
    return train_model([_recording(30, 0.0)], model="sp_c", n_support=50)


def _with_choice(trained, level):
    choice = {"best": "sp_c", "models": ["p_f", "sp_c"],
              "thresholds": [[100.0], [float(level)]]}
    return dataclasses.replace(trained, training={**trained.training, "model_choice": choice})


def _calibrate(trained):
    logs = [_recording(40, p, seed=k) for k, p in enumerate((1.0, 2.0, 3.0))]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return calibrate_detector(trained, logs)


def _moving_row(calibrated):
    return list(calibrated.calibration["regimes"]).index("moving")


def test_without_a_model_choice_the_calibration_alone_sets_the_moving_row(trained):
    calibrated = _calibrate(trained)
    assert training_moving_level(trained.training) is None
    assert calibrated.calibration["moving_floor_A"] is None


def test_the_training_level_raises_the_moving_row_only(trained):
    plain = _calibrate(trained)
    row = _moving_row(plain)
    before = np.atleast_2d(plain.detector.thresholds_)
    level = 3.0 * before[row, 0]
    raised = _calibrate(_with_choice(trained, level))
    after = np.atleast_2d(raised.detector.thresholds_)
    assert after[row, 0] == pytest.approx(level)
    others = np.arange(len(before)) != row
    np.testing.assert_allclose(after[others], before[others])
    # every band with the main rule's filter carries it (the monitor reads the rules)
    rule = raised.detector.rules_[0]
    assert np.atleast_2d(rule.thresholds_)[row, 0] == pytest.approx(level)
    assert raised.calibration["moving_floor_A"] == [pytest.approx(level)]
    assert "left-out training runs" in calibration_report(raised.calibration)


def test_a_lower_training_level_never_tightens_the_calibration(trained):
    plain = _calibrate(trained)
    row = _moving_row(plain)
    before = np.atleast_2d(plain.detector.thresholds_)
    lowered = _calibrate(_with_choice(trained, 0.1 * before[row, 0]))
    np.testing.assert_allclose(np.atleast_2d(lowered.detector.thresholds_), before)
