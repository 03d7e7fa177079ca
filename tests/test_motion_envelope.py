"""Moving thresholds that follow the motion (Regimes(motion_envelope=...), issue 38)."""

import numpy as np
import pytest
from sklearn.linear_model import LinearRegression

from sklearn_gpcd.detection import (
    AlarmRule,
    CollisionDetector,
    Regimes,
    StreamingMonitor,
    calibrate_across_recordings,
    stack_currents,
)


def _run(seed, n=1500, dt=0.01):
    """Two joints in the paper's layout [q, qd, qdd]: joint 1 swings, joint 2 stands
    still half of the time; a still joint holds a random stiction offset, a sliding
    one only noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    qd = np.column_stack([np.sin(1.3 * t + seed), np.where(np.sin(0.4 * t + seed) > 0,
                                                           0.6 * np.cos(2.1 * t), 0.0)])
    qdd = np.gradient(qd, dt, axis=0)
    q = np.cumsum(qd, axis=0) * dt
    still = np.abs(qd) < 0.05
    offset = np.where(still, 0.4 * np.sin(0.05 * t + 3 * seed)[:, None], 0.0)
    current = 2.0 * qd + offset + 0.02 * rng.normal(size=qd.shape)
    X = np.column_stack([q[:, 0], q[:, 1], qd[:, 0], qd[:, 1], qdd[:, 0], qdd[:, 1]])
    return stack_currents(X, current), t


def _detector(envelope):
    rule = AlarmRule("per_joint", false_alarm_rate=0.0, filter_cutoff=2.0, min_duration=3,
                     regimes=Regimes(motion_envelope=envelope))
    return CollisionDetector(LinearRegression(), n_joints=2, sample_time=0.01, rules=rule)


@pytest.fixture(scope="module")
def runs():
    return {f"r{seed}": _run(seed) for seed in range(4)}


def test_a_stuck_joint_widens_its_own_band(runs):
    Z = np.concatenate([z for z, _ in runs.values()])
    det = _detector(0.05).fit(Z)
    stuck, acceleration, speed = det.rules_[0].envelope_[1]
    assert stuck > 1.0               # the offsets of a still joint are many times the noise
    plain = _detector(None).fit(Z)
    moving = 0
    # a sliding joint 2 gets a band several times tighter than the one-size band
    assert det.thresholds_[moving, 1] < 0.5 * plain.thresholds_[moving, 1]


def test_streaming_equals_batch_with_the_envelope(runs):
    Z = np.concatenate([z for z, _ in runs.values()][:3])
    det = _detector(0.05).fit(Z)
    pushed = runs["r3"][0].copy()
    pushed[700:760, -1] += 0.3 * np.hanning(60)
    out = StreamingMonitor(det).replay(pushed)
    assert np.array_equal(out.prediction, det.predict(pushed))
    assert (out.prediction[690:800] == -1).any()
    np.testing.assert_allclose(out.signal, det.monitoring_signal(pushed).signal, atol=1e-12)


def test_left_out_recordings_are_scored_with_an_envelope_fitted_without_them(runs):
    blocks = {k: z for k, (z, _) in runs.items()}
    times = {k: t for k, (_, t) in runs.items()}
    result = calibrate_across_recordings(_detector(0.05), blocks, times)
    series = result.series
    assert set(series.folds) == set(blocks)
    # the envelope without a recording differs from the one on all, at least once
    assert any(not np.array_equal(series.folds[key][key][0], series[key][0])
               for key in blocks)
    assert result.detector.rules_[0].envelope_ is not None
    assert result.false_alarms_per_hour is not None
