"""StreamingMonitor.replay / replay_recording with several bands: a loop of updates,
and the batch detector."""

import numpy as np
import pytest

from sklearn_gpcd.detection import (
    AlarmRule,
    CollisionDetector,
    Regimes,
    StreamingMonitor,
    stack_currents,
)
from sklearn_gpcd.features import CausalFeatures
from sklearn_gpcd.gp import make_sp_p

from _synthetic import augmented_run, banded, controller_detector, simulated_interaction

BAND_FIELDS = ("signal", "ratio", "alarms", "regime")


def _assert_batch(out, det, Z, groups=None):
    """The replay's rows equal the detector's monitoring_signal on the same rows."""
    batch = det.monitoring_signal(Z, groups)
    np.testing.assert_array_equal(out.alarms, batch.alarms)
    np.testing.assert_array_equal(out.alarms, det.predict_joints(Z, groups))
    np.testing.assert_array_equal(out.prediction, det.predict(Z, groups))
    np.testing.assert_allclose(out.score, det.score_samples(Z, groups), rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(out.predicted, batch.predicted, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(out.residual, batch.residual, rtol=1e-9, atol=1e-12)
    assert len(out.bands) == len(batch.bands)
    for streamed, band in zip(out.bands, batch.bands):
        assert streamed.level == band.level
        np.testing.assert_allclose(streamed.signal, band.signal, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(streamed.ratio, band.ratio, rtol=1e-9, atol=1e-12)
        np.testing.assert_array_equal(streamed.alarms, band.alarms)
        np.testing.assert_array_equal(streamed.regime, band.regime)


def _loop(monitor, ticks):
    """Statuses, union alarms and per-band fields of a loop of update calls."""
    rows = []
    for tick in ticks:
        status = tick(monitor)
        rows.append((status.value, monitor.alarms.copy(),
                     [[np.copy(getattr(m, f)) for f in BAND_FIELDS] for m in monitor.bands]))
    return rows


def _assert_loop(out, rows):
    assert out.status.tolist() == [status for status, _, _ in rows]
    np.testing.assert_array_equal(out.alarms, [alarms for _, alarms, _ in rows])
    for b, band in enumerate(out.bands):
        for f, field in enumerate(BAND_FIELDS):
            np.testing.assert_array_equal(band[field], [per_band[b][f] for _, _, per_band in rows])


def test_replay_equals_a_loop_of_updates_and_the_batch_detector(rng):
    X, current = augmented_run(800, 2, rng)
    model = make_sp_p(None, 2, sigma_v=1e-2, n_support=60, random_state=0, optimizer=None)
    rule = AlarmRule("per_joint", margin=1.5, filter_cutoff=2.0, min_duration=5,
                     regimes=Regimes())
    template = CollisionDetector(model, n_joints=2, sample_time=0.008, rules=rule)
    det = banded(template).fit(stack_currents(X[::2], current[::2]))
    test = current + 0.01 * rng.normal(size=current.shape)
    test[100:110, 0] += 1.0  # a 80 ms tap
    test[300:380, 1] -= 1.0  # a push
    Z = stack_currents(X, test)
    groups = np.repeat([0, 1], 400)
    time = np.arange(800) * 0.008
    time[650] = time[649]  # a repeated stamp: a sensor fault
    faulty = Z.copy()
    faulty[[50, 600], 3] = np.nan  # missing values: sensor faults

    out = StreamingMonitor(det).replay(faulty, groups=groups, time=time)
    bad = [50, 600, 650]
    assert np.flatnonzero(out.prediction == 0).tolist() == bad
    assert not out.alarms[bad].any() and np.isnan(out.score[bad]).all()
    assert np.isnan(out.bands[1].signal[bad]).all()

    def update(t):
        def tick(monitor):
            if t and groups[t] != groups[t - 1]:
                monitor.reset()
            return monitor.update(faulty[t], time=time[t])
        return tick

    _assert_loop(out, _loop(StreamingMonitor(det), [update(t) for t in range(800)]))
    kept = np.setdiff1d(np.arange(800), bad)
    _assert_batch(_rows(out, kept), det, Z[kept], groups[kept])
    assert out.bands[1].alarms[100:110].any() and out.alarms[300:390].any()
    with pytest.raises(ValueError, match=r"time must have shape \(800,\)"):
        StreamingMonitor(det).replay(Z, time=time[:5])


def _rows(out, rows):
    """The replay Bunch restricted to ``rows``."""
    from sklearn.utils import Bunch

    picked = Bunch(**{k: v[rows] for k, v in out.items() if k != "bands"})
    picked.bands = [Bunch(**{k: v if k == "level" else v[rows] for k, v in band.items()})
                    for band in out.bands]
    return picked


def test_replay_recording_equals_update_raw_and_the_batch_detector():
    rec, free = simulated_interaction()
    features = CausalFeatures().fit(free)
    Z = stack_currents(features.transform(free), free.current)
    det = banded(controller_detector()).fit(Z, time=free.time)
    out = StreamingMonitor(det, features=features).replay_recording(rec)
    signals = {s: getattr(rec, s) for s in features.signals_}

    def raw(k):
        return lambda monitor: monitor.update_raw(rec.time[k], rec.q[k], rec.qd[k],
                                                  rec.current[k],
                                                  **{s: v[k] for s, v in signals.items()})

    _assert_loop(out, _loop(StreamingMonitor(det, features=features),
                            [raw(k) for k in range(rec.n_samples)]))
    _assert_batch(out, det, stack_currents(features.transform(rec), rec.current))
    assert out.alarms.any() and len(np.unique(out.bands[0].regime)) > 1
    with pytest.raises(ValueError, match="replay_recording needs"):
        StreamingMonitor(det).replay_recording(rec)
