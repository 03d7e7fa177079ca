"""Event-level detection metrics, nMSE (paper Eq. 18) and scorers."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.base import BaseEstimator, OutlierMixin

from sklearn_gpcd.metrics import (
    alarm_onsets,
    contact_events,
    DetectionRefit,
    DetectionScorer,
    detection_delay,
    event_recall,
    false_alarms_per_hour,
    fold_means,
    mean_detection_delay,
    nmse,
)

#            0  1  2  3  4  5  6  7  8  9 10 11 12 13 14 15
LABELS = [0, 0, 1, 1, 1, 0, 0, 0, 2, 2, 0, 0, 3, 3, 0, 0]
ALARMS = [1, 0, 0, 0, 1, 1, 0, 0, 0, 0, 1, 0, 0, 1, 1, 0]
# events: [2, 5) detected at 4 (delay 2), [8, 10) missed (alarm at 10 is
# 2 samples after onset), [12, 14) detected at 13 (delay 1).
# alarm onsets: 0 (free -> false), 4 (event 1), 10 (free -> false unless
# max_delay >= 2 attributes it to event 2), 13 (event 3).


def test_contact_events_splits_on_label_change_and_groups():
    starts, stops = contact_events([0, 1, 1, 2, 2, 0, 3, 3, 3], groups=[0] * 7 + [1] * 2)
    assert starts.tolist() == [1, 3, 6, 7]
    assert stops.tolist() == [3, 5, 7, 9]


def test_detection_delay_in_samples_and_seconds():
    assert np.array_equal(detection_delay(LABELS, ALARMS), [2.0, np.nan, 1.0], equal_nan=True)
    delays = detection_delay(LABELS, ALARMS, sample_time=0.5)
    assert np.allclose(delays, [1.0, np.nan, 0.5], equal_nan=True)


def test_detection_delay_with_irregular_time_stamps():
    time = np.cumsum(np.r_[0.0, np.full(15, 0.1)])
    time[4:] += 0.25  # a gap before sample 4
    delays = detection_delay(LABELS, ALARMS, time=time)
    assert np.allclose(delays, [0.45, np.nan, 0.1], equal_nan=True)


def test_max_delay_extends_and_limits_the_window():
    # window of event 2 = [8, 8 + 2]: the alarm at 10 now detects it
    assert np.allclose(
        detection_delay(LABELS, ALARMS, max_delay=2), [2.0, 2.0, 1.0], equal_nan=True
    )
    # a 1-sample window misses event 1 (alarm 2 samples after onset)
    assert np.allclose(
        detection_delay(LABELS, ALARMS, max_delay=1), [np.nan, np.nan, 1.0], equal_nan=True
    )
    # seconds: 2 samples of 8 ms = 16 ms is still accepted (rounding slack)
    delays = detection_delay(LABELS, ALARMS, max_delay=0.016, sample_time=0.008)
    assert np.allclose(delays, [0.016, 0.016, 0.008])


def test_event_recall_hand_computed():
    assert event_recall(LABELS, ALARMS) == pytest.approx(2 / 3)
    assert event_recall(LABELS, ALARMS, max_delay=2) == 1.0
    assert event_recall(LABELS, np.zeros(16, bool)) == 0.0
    assert np.isnan(event_recall(np.zeros(5), np.ones(5, bool)))


def test_window_never_reaches_the_next_event():
    labels = [1, 0, 2, 2]
    alarms = [0, 0, 1, 0]
    # with a long max_delay, event 1's window stops at event 2's onset
    assert np.allclose(detection_delay(labels, alarms, max_delay=10), [np.nan, 0.0],
                       equal_nan=True)


def test_false_alarms_per_hour_hand_computed():
    # 9 free samples of 360 s = 0.9 h; onsets at 0 and 10 are false
    rate = false_alarms_per_hour(LABELS, ALARMS, sample_time=360.0)
    assert rate == pytest.approx(2 / 0.9)
    # max_delay = 2 samples (720 s) attributes the onset at 10 to event 2
    rate = false_alarms_per_hour(LABELS, ALARMS, sample_time=360.0, max_delay=720.0)
    assert rate == pytest.approx(1 / 0.9)


def test_false_alarms_count_onsets_not_samples():
    labels = np.zeros(10, dtype=int)
    alarms = np.array([0, 1, 1, 1, 0, 0, 1, 1, 0, 0], dtype=bool)
    assert false_alarms_per_hour(labels, alarms, sample_time=360.0) == pytest.approx(2.0)


def test_false_alarms_restart_at_recording_boundaries():
    labels = np.zeros(6, dtype=int)
    alarms = np.array([0, 1, 1, 1, 1, 0], dtype=bool)
    one = false_alarms_per_hour(labels, alarms, sample_time=600.0)
    two = false_alarms_per_hour(labels, alarms, sample_time=600.0, groups=[0, 0, 0, 1, 1, 1])
    assert one == pytest.approx(1.0)
    assert two == pytest.approx(2.0)


def test_false_alarms_inside_a_contact_never_count():
    labels = [0, 1, 1, 1, 1, 0]
    alarms = [0, 0, 0, 0, 1, 0]  # late in the contact, outside a 1-sample window
    assert false_alarms_per_hour(labels, alarms, sample_time=1.0, max_delay=1.0) == 0.0


def test_false_alarms_with_time_stamps():
    time = np.array([0.0, 1800.0, 3600.0, 5400.0])
    labels = [0, 0, 0, 0]
    alarms = [1, 0, 1, 0]  # 2 onsets; 4 samples x 1800 s (last one: median) = 2 h
    assert false_alarms_per_hour(labels, alarms, time=time) == pytest.approx(1.0)


def test_false_alarms_need_a_time_base():
    with pytest.raises(ValueError, match="sample_time"):
        false_alarms_per_hour([0, 0], [0, 1])


def test_alarm_onsets_are_what_false_alarms_per_hour_counts_without_contacts():
    onsets = alarm_onsets(ALARMS)
    assert onsets == [0, 4, 10, 13]
    free = np.zeros(len(ALARMS))
    assert false_alarms_per_hour(free, ALARMS, sample_time=3600.0 / len(ALARMS)) == 4.0
    t = 0.01 * np.arange(len(ALARMS))
    assert alarm_onsets(ALARMS, time=t) == pytest.approx(t[onsets].tolist())


def test_alarm_onsets_merge_overlapping_joints():
    per_joint = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0], [0, 1]], dtype=bool)
    assert alarm_onsets(per_joint) == [1, 5]  # joint 2 continues joint 1's episode
    assert alarm_onsets(per_joint[:, 1]) == [2, 5]


def test_alarm_onsets_reject_bad_input():
    with pytest.raises(ValueError, match="boolean"):
        alarm_onsets([0, 1, 2])
    with pytest.raises(ValueError, match="1-D .* or 2-D"):
        alarm_onsets(np.zeros((2, 2, 2)))
    with pytest.raises(ValueError, match=r"time must have shape \(3,\)"):
        alarm_onsets([0, 1, 0], time=[0.0, 1.0])


def test_mean_detection_delay_charges_missed_events():
    # delays 2 and 1 samples, event 2 missed: charged its length (2 samples)
    assert mean_detection_delay(LABELS, ALARMS) == pytest.approx((2 + 2 + 1) / 3)
    # with max_delay the miss costs max_delay
    assert mean_detection_delay(LABELS, ALARMS, max_delay=1) == pytest.approx((1 + 1 + 1) / 3)
    seconds = mean_detection_delay(LABELS, ALARMS, sample_time=0.5)
    assert seconds == pytest.approx((1.0 + 1.0 + 0.5) / 3)


def test_predict_output_is_rejected_with_a_hint():
    with pytest.raises(ValueError, match="predict\\(X\\) == -1"):
        event_recall([0, 1], [1, -1])
    with pytest.raises(ValueError, match="shape"):
        event_recall([0, 1, 0], [True, False])


def test_nmse_equals_the_formula(rng):
    y = rng.normal(size=(200, 3))
    y_hat = y + rng.normal(scale=0.3, size=y.shape)
    expected = np.mean((y - y_hat) ** 2, axis=0) / np.var(y, axis=0)
    assert np.allclose(nmse(y, y_hat), expected)
    assert nmse(y, y_hat, multioutput="uniform_average") == pytest.approx(expected.mean())
    assert nmse(y[:, 0], y_hat[:, 0]) == pytest.approx(expected[0])
    assert np.allclose(nmse(y, np.broadcast_to(y.mean(axis=0), y.shape)), 1.0)


def test_nmse_masks_per_joint(rng):
    y = rng.normal(size=(100, 2))
    y_hat = y + rng.normal(scale=0.5, size=y.shape)
    mask = rng.random((100, 2)) < 0.4
    got = nmse(y, y_hat, mask=mask)
    for j in range(2):
        m = mask[:, j]
        assert got[j] == pytest.approx(np.mean((y[m, j] - y_hat[m, j]) ** 2) / np.var(y[m, j]))
    rows = mask[:, 0]
    assert np.allclose(nmse(y, y_hat, mask=rows), nmse(y[rows], y_hat[rows]))


def test_nmse_constant_target_and_bad_shapes():
    assert np.isnan(nmse([1.0, 1.0], [1.0, 2.0]))
    with pytest.raises(ValueError, match="same shape"):
        nmse([1.0, 2.0], [1.0])
    with pytest.raises(ValueError, match="mask"):
        nmse([1.0, 2.0], [1.0, 2.0], mask=[True])


class _FixedAlarms(OutlierMixin, BaseEstimator):
    """Predicts -1 on the rows whose first column is 1."""

    def fit(self, X, y=None):
        return self

    def predict(self, X):
        return np.where(np.asarray(X)[:, 0] == 1, -1, 1)


def test_scorer_follows_sklearn_sign_conventions():
    X = np.array(ALARMS, dtype=float)[:, None]
    est = _FixedAlarms()
    scores = DetectionScorer(sample_time=360.0)(est, X, LABELS)
    assert scores["recall"] == pytest.approx(2 / 3)
    assert scores["false_alarms_per_hour"] == pytest.approx(-2 / 0.9)
    assert scores["delay"] == pytest.approx(-360.0 * (2 + 2 + 1) / 3)
    # time stamps replace the sampling period; groups split the events
    timed = DetectionScorer()(est, X, LABELS, time=360.0 * np.arange(len(LABELS)))
    assert timed == pytest.approx(scores)
    request = DetectionScorer().get_metadata_routing()
    assert set(request.score.requests) == {"groups", "time"}


def test_refit_rule_ignores_folds_without_events():
    results = {"split0_test_recall": np.array([1.0, 0.5]),
               "split1_test_recall": np.array([np.nan, np.nan]),
               "split0_test_false_alarms_per_hour": np.array([-3.0, -1.0]),
               "split1_test_false_alarms_per_hour": np.array([-1.0, -1.0]),
               "split0_test_delay": np.array([-0.1, -0.1]),
               "split1_test_delay": np.array([np.nan, np.nan])}
    np.testing.assert_allclose(fold_means(results, "false_alarms_per_hour")[0], [-2.0, -1.0])
    assert DetectionRefit()(results) == 0          # recall 1.0 beats 0.5 despite NaN fold


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.integers(0, 2), min_size=1, max_size=40),
    st.lists(st.booleans(), min_size=40, max_size=40),
    st.integers(0, 5),
)
def test_metric_invariants(labels, alarms, max_delay):
    labels = np.array(labels)
    alarms = np.array(alarms[: len(labels)])
    delays = detection_delay(labels, alarms, max_delay=max_delay)
    starts, _ = contact_events(labels)
    assert delays.shape == starts.shape
    found = ~np.isnan(delays)
    assert np.all(delays[found] <= max_delay)
    assert np.all(alarms[(starts + np.nan_to_num(delays).astype(int))[found]])
    if len(starts):
        assert event_recall(labels, alarms, max_delay=max_delay) == pytest.approx(found.mean())
    # alarms only inside contacts are never false alarms
    inside = alarms & (labels != 0)
    if (labels == 0).any():
        assert false_alarms_per_hour(labels, inside, sample_time=1.0) == 0.0


def test_time_stamps_may_restart_per_recording():
    time = np.r_[np.arange(5) * 0.1, np.arange(5) * 0.1]
    labels = [0, 1, 1, 0, 0, 0, 2, 2, 0, 0]
    alarms = [0, 0, 0, 1, 0, 0, 0, 0, 1, 0]
    groups = np.repeat([0, 1], 5)
    delays = detection_delay(labels, alarms, max_delay=0.25, time=time, groups=groups)
    assert np.allclose(delays, [0.2, 0.2])
    # the window of event 1 never reaches into recording 1
    alarms = [0, 0, 0, 0, 0, 1, 0, 0, 0, 0]
    delays = detection_delay(labels, alarms, max_delay=10.0, time=time, groups=groups)
    assert np.isnan(delays).all()
