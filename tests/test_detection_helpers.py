"""The private helpers of ``sklearn_gpcd.detection``, one small case each.

These were the examples of their docstrings (issue 34 made the private
docstrings short); each pins an edge case or a number by hand.
"""

import numpy as np
from scipy.signal import lfilter

from sklearn_gpcd.detection import AlarmRule, Regimes
from sklearn_gpcd.detection._regimes import (
    AlarmState,
    RegimeState,
    held_regime_pass,
    regime_pass,
)
from sklearn_gpcd.detection._signal import (
    filter_segments,
    lowpass_coefficients,
    recording_index,
    segment_starts,
    window_segments,
)
from sklearn_gpcd.detection._thresholds import (
    contamination_level,
    false_alarm_level,
    fill_absent_regimes,
    peak_levels,
    recording_peaks,
    rms_scale,
    shared_margin,
)
from sklearn_gpcd.detection.streaming import _filter_transition


# ------------------------------------------------------------------ _signal
def test_lowpass_filters_have_unit_dc_gain_and_start_in_steady_state():
    for order in (1, 2):
        b, a = lowpass_coefficients(10.0, 0.008, order)
        assert round(float(b.sum() / a.sum()), 12) == 1.0
    b, a = lowpass_coefficients(1.0, 0.01)
    assert np.allclose(filter_segments(np.ones((3, 1)), b, a, np.array([0])), 1.0)


def test_recordings_and_segments():
    assert recording_index(["b", "b", "a", "a"], labels=[0, 1, 0, 0]).tolist() == [1, 0, 0]
    assert recording_index(None) is None
    assert segment_starts(6, groups=[0, 0, 1, 1, 1, 2]).tolist() == [0, 2, 5]
    # a gap of dropped rows starts a segment; indices count the kept rows
    assert segment_starts(5, keep=np.array([1, 1, 0, 1, 1], bool)).tolist() == [0, 2]


def test_window_pads_with_zeros_or_the_first_row():
    r = np.array([[2.0], [3.0], [1.0], [5.0], [6.0]])
    debounced = window_segments(r, 2, np.array([0]), np.min, pad=0.0)
    assert debounced[:, 0].tolist() == [0.0, 2.0, 1.0, 1.0, 5.0]
    held = window_segments(np.array([[1.0], [3.0], [1.0], [1.0], [1.0]]), 2, np.array([0]),
                           np.max)
    assert held[:, 0].tolist() == [1.0, 3.0, 3.0, 1.0, 1.0]
    assert window_segments(r, 2, np.array([0, 3]), np.max)[:, 0].tolist() == [
        2.0, 3.0, 3.0, 5.0, 6.0]
    assert window_segments(r, 1, np.array([0]), np.min) is r


# -------------------------------------------------------------- _thresholds
def test_scales_and_levels():
    assert rms_scale(np.array([[3.0, 0.0], [-3.0, 0.0]])).tolist() == [3.0, 1.0]
    assert contamination_level(np.arange(10.0), 0.1) == 8.1


def test_false_alarm_level_counts_onsets_and_lifts_the_level():
    peak = np.array([0.0, 2.0, 0.0, 1.0, 0.0])  # two bumps
    hours = 5 * 1.0 / 3600
    assert false_alarm_level(peak, np.array([0]), 1.0, rate=1.5 / hours) == 1.000000001
    assert false_alarm_level(peak, np.array([0]), 1.0, rate=0.0) == 2.000000002


def test_regime_tables():
    filled = fill_absent_regimes(np.array([[1.0, 4.0], [9.0, 9.0], [2.0, 3.0]]),
                                 np.array([True, False, True]))
    assert filled.tolist() == [[1.0, 4.0], [2.0, 4.0], [2.0, 3.0]]
    d = np.array([[1.0], [3.0], [2.0]])
    peaks = recording_peaks(d, np.array([0, 0, 1]), np.array([0, 1, 1]), 2)
    assert peaks[:, :, 0].tolist() == [[1.0, 0.0], [3.0, 2.0]]
    assert peak_levels(np.array([[[1.0, 2.0], [0.0, 0.0], [0.5, 0.2]]]))[1].tolist() == [
        1.0, 2.0]
    factors = [np.array([[0.5, 2.0]]), np.array([[1.5, 0.5]])]
    assert shared_margin(factors, "joint").tolist() == [[1.5, 2.0]]


# ----------------------------------------------------------------- _regimes
def test_regime_state_references_the_signal_at_rest_entry():
    state = RegimeState(sigma_v=0.01, settle=2, beta=0.0, n_joints=1)
    out = []
    for qd, m in [(0.5, 1.0), (0.0, 2.0), (0.0, 2.0), (0.0, 2.5), (0.0, 3.0)]:
        signal = np.array([m])
        out.append((state.step(np.array([qd]), signal), float(signal[0])))
    # moving, settling x2, rest with the reference 2.5 from entry
    assert out == [(0, 1.0), (1, 2.0), (1, 2.0), (2, 0.0), (2, 0.5)]


def test_regime_pass_rest_and_braking():
    m = np.array([[1.0], [1.0], [1.2]])
    out, reg, _ = regime_pass(m, np.zeros((3, 1)), np.array([0]), 0.01, 5, 0.0)
    assert out[:, 0].round(6).tolist() == [0.0, 0.0, 0.2] and reg.tolist() == [2, 2, 2]
    # a hard stop (|qdd| > 5) and the 2 samples after it are braking
    motion = np.array([[0.5, 1.0], [0.5, 9.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    regimes = regime_pass(np.zeros((5, 1)), motion, np.array([0]), 0.01, 5, None,
                          brake_limit=5.0, brake_hold=2)[1]
    assert regimes.tolist() == [0, 3, 3, 3, 1]


def test_a_hold_keeps_its_regime():
    # (a dipping alarm kept as one: EventHold, which replaced AlarmState's release)
    # a push on a still arm (0.5 rad/s while pushed) stays one alarm at rest
    m = np.array([[0.0], [2.0], [2.0], [0.5], [0.0]])
    qd = np.array([[0.0], [0.0], [0.5], [0.5], [0.0]])
    settings = {"sigma_v": 0.01, "settle": 5, "beta": None, "alarm_hold": 100}
    scales = np.array([[10.0], [10.0], [1.0]])  # moving, settling, rest
    _, regime, _, _, alarms = held_regime_pass(m, qd, settings, scales, 1.0, 1)
    assert regime.tolist() == [2, 2, 2, 2, 1]
    assert alarms[:, 0].tolist() == [False, True, True, False, False]


def test_regime_settings_are_in_samples():
    rule = AlarmRule(regimes=Regimes(rest_reference=2.0)).prepare(0.01)
    settings = rule.regime_settings()
    assert settings["settle"] == 50 and settings["sigma_v"] == 1e-2
    assert settings["beta"] == -np.expm1(-0.01 / 2.0)


# ---------------------------------------------------------------- streaming
def test_filter_transition_is_one_lfilter_step():
    b, a = np.array([0.2, 0.1]), np.array([1.0, -0.5])
    T, _ = _filter_transition((b, a))
    u, state, y = [1.0, 3.0, -2.0], np.zeros(2), []
    for value in u:
        state[0] = value
        state = T @ state
        y.append(state[0])
    assert np.allclose(y, lfilter(b, a, u))

