"""The momentum observer as a CollisionDetector's residual model: same rules, same
calibration as any monitor (issue 36)."""

import numpy as np
import pytest
from sklearn.frozen import FrozenEstimator
from sklearn.linear_model import Ridge

from sklearn_gpcd.detection import (
    AlarmRule,
    CollisionDetector,
    Regimes,
    StreamingMonitor,
    calibrate_across_recordings,
    reads_currents,
    stack_currents,
)
from sklearn_gpcd.dynamics import MomentumObserver

from _pushes import inputs, push_runs, training_run

DT = 0.008  # the simulator's sample time


@pytest.fixture(scope="module")
def observer():
    train = training_run(seed=0, n_targets=6)
    return MomentumObserver("ur10", identify="friction", sample_time=DT).fit(
        inputs(train), train.current)


@pytest.fixture(scope="module")
def runs():
    return push_runs(seed=5, n_per_link=1)


def test_reads_currents():
    assert reads_currents(MomentumObserver())
    assert reads_currents(FrozenEstimator(MomentumObserver()))
    assert not reads_currents(Ridge())
    assert not reads_currents(FrozenEstimator(Ridge()))


def test_detector_residual_is_the_observer_residual_per_recording(observer, runs):
    """Stacked recordings (``groups``) restart the observer at each one, in
    fit_residuals and in monitoring_signal alike."""
    pushes, twin, _ = runs
    a, b = stack_currents(inputs(twin), twin.current), stack_currents(inputs(pushes),
                                                                       pushes.current)
    Z = np.vstack([a, b])
    groups = np.repeat([0, 1], [len(a), len(b)])
    det = CollisionDetector(FrozenEstimator(observer), n_joints=6, sample_time=DT)
    fitted = det.fit_residuals(Z, groups=groups)
    expected = np.vstack([observer.residual(inputs(twin), twin.current),
                          observer.residual(inputs(pushes), pushes.current)])
    np.testing.assert_allclose(fitted.residual, expected, rtol=0, atol=1e-12)
    det.calibrate(fitted)
    np.testing.assert_allclose(det.monitoring_signal(Z, groups=groups).residual, expected,
                               rtol=0, atol=1e-12)
    # without groups the observer runs through the junction: the second part differs
    joined = det.monitoring_signal(Z).residual
    assert not np.allclose(joined[len(a):len(a) + 5], expected[len(a):len(a) + 5])


def test_rows_left_out_by_labels_restart_the_observer(observer, runs):
    pushes = runs[0]
    Z = stack_currents(inputs(pushes), pushes.current)
    det = CollisionDetector(FrozenEstimator(observer), n_joints=6, sample_time=DT)
    fitted = det.fit_residuals(Z, labels=pushes.labels)
    free = np.flatnonzero(pushes.labels == 0)
    first_gap = free[np.flatnonzero(np.diff(free) > 1)[0] + 1]   # first row after a push
    after = free >= first_gap
    segment_end = free[after][np.argmax(np.diff(free[after]) > 1)] + 1
    rows = slice(first_gap, segment_end)
    alone = observer.residual(inputs(pushes)[rows], pushes.current[rows])
    np.testing.assert_allclose(fitted.residual[after][:len(alone)], alone, rtol=0, atol=1e-12)


def test_observer_calibrated_across_recordings_detects_the_pushes(observer):
    """The package's calibration rule on collision-free runs; every push on links
    1-3 is alarmed, no collision-free run alarms at the operating point."""
    free = {f"free{k}": training_run(seed=10 + k, n_targets=3) for k in range(3)}
    blocks = {k: stack_currents(inputs(r), r.current) for k, r in free.items()}
    times = {k: r.time for k, r in free.items()}
    rule = AlarmRule("per_joint", false_alarm_rate=0.0, filter_cutoff=10.0, min_duration=3,
                     regimes=Regimes())
    template = CollisionDetector(FrozenEstimator(observer), n_joints=6, sample_time=DT,
                                 rules=rule)
    result = calibrate_across_recordings(template, blocks, times)
    det = result.detector
    for block in blocks.values():
        assert (det.predict(block) == 1).all()
    pushes, _, contacts = push_runs(seed=7, n_per_link=1)
    alarms = det.predict(stack_currents(inputs(pushes), pushes.current)) == -1
    for k, contact in enumerate(contacts, start=1):
        if contact.link <= 3:
            assert alarms[pushes.labels == k].any(), f"push on link {contact.link} missed"


def test_streaming_monitor_refuses_an_observer(observer, runs):
    twin = runs[1]
    Z = stack_currents(inputs(twin), twin.current)
    det = CollisionDetector(FrozenEstimator(observer), n_joints=6, sample_time=DT).fit(Z)
    with pytest.raises(ValueError, match="MomentumObserver.*dynamic filter"):
        StreamingMonitor(det)
