"""Calibration that says when its data cannot support its thresholds (issue 38)."""

import re
import warnings

import numpy as np
import pytest

from sklearn_gpcd.io import Recording
from sklearn_gpcd.metrics import rate_upper_bound
from sklearn_gpcd.workflow import (
    CalibrationWarning,
    calibrate_detector,
    calibration_report,
    train_model,
)


def _recording(seconds, phase, moving=True, seed=0, name=None):
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * 100)) * 0.01
    q = (np.sin(0.5 * t + phase) if moving else np.full_like(t, phase))[:, None]
    qd = (0.5 * np.cos(0.5 * t + phase) if moving else np.zeros_like(t))[:, None]
    i_c = 2 * q
    return Recording(time=t, q=q, qd=qd, current=i_c + 0.05 * rng.normal(size=q.shape),
                     target_current=i_c, name=name)


@pytest.fixture(scope="module")
def trained():
    return train_model([_recording(30, 0.0)], model="sp_c", n_support=50)


def _calibrate(trained, recordings):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        calibrated = calibrate_detector(trained, recordings)
    return calibrated, [str(w.message) for w in caught if w.category is CalibrationWarning]


def test_short_calibration_warns_with_the_false_alarm_bound(trained):
    calibrated, messages = _calibrate(trained, [_recording(7, p, seed=s)
                                                for s, p in enumerate((1.0, 2.0, 3.0))])
    short = [m for m in messages if "lasts 21 s" in m]
    assert len(short) == 1
    count = calibrated.calibration["n_false_alarms_nested"]
    bound = float(re.search(r"only by (\d+) per hour", short[0]).group(1))
    assert bound == pytest.approx(rate_upper_bound(count, 21 / 3600), abs=1.0)
    assert "gpcd calibrate" in short[0]
    report = calibration_report(calibrated.calibration)
    assert "95 % upper bound" in report and "data per regime: moving" in report


def test_a_regime_from_one_recording_is_named(trained):
    recordings = [_recording(60, 0.3, moving=False, seed=1, name="p1.csv"),
                  _recording(60, -0.2, moving=False, seed=2, name="p2.csv"),
                  _recording(60, 1.0, seed=3, name="ptp.csv")]
    calibrated, messages = _calibrate(trained, recordings)
    moving = [m for m in messages if "every moving threshold" in m]
    assert len(moving) == 1 and "ptp.csv" in moving[0]
    assert "add collision-free recordings with the motions" in moving[0]
    coverage = calibrated.calibration["coverage"]
    assert coverage["moving"]["recordings"] == 1
    assert coverage["rest"]["recordings"] == 2


def test_enough_data_from_several_recordings_does_not_warn(trained):
    recordings = []
    for s, phase in enumerate((1.0, 2.0, 3.0)):  # moves, stops 6 times, stands still
        rec = _recording(60, phase, seed=s)
        qd = rec.qd.copy()
        for k in range(6):
            qd[600 * k + 400:600 * (k + 1)] = 0.0
        recordings.append(Recording(time=rec.time, q=rec.q, qd=qd, current=rec.current,
                                    target_current=rec.target_current))
    _, messages = _calibrate(trained, recordings)
    assert messages == []
