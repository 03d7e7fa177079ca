"""The braking regime: hard stops get their own thresholds (issue 14).

A hard reversal rings the current for a few tenths of a second (the real
UR10e's jointwise runs: several ampere for about 0.5 s, for the controller's
own expected current too). With one threshold for all motion, that ring sets
the moving threshold and a push during ordinary motion goes unseen; with
``brake_limit`` the samples after a large acceleration are a regime of
their own.
"""


import numpy as np
import pytest
from sklearn.linear_model import LinearRegression

from sklearn_gpcd.detection import (
    AlarmRule,
    CollisionDetector,
    Regimes,
    StreamingMonitor,
    stack_currents,
)
from sklearn_gpcd.detection._regimes import BRAKING, MOVING

DT = 0.01
LIMIT = 10.0  # rad/s^2: the flips reach 100, ordinary motion about 0.1


def _reversals(n=3000, seed=0):
    """One joint, inputs [q, qd, qdd]: +-0.5 rad/s flipped every 2 s in one
    sample, each flip followed by a 0.4 s ring of the current (0.8 A)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT
    qd = 0.5 * np.where((t // 2.0) % 2 == 0, 1.0, -1.0) + 0.1 * np.sin(t)
    qdd = np.diff(qd, prepend=qd[0]) / DT  # causal (backward) difference
    q = np.cumsum(qd) * DT
    current = 2.0 * qd + 0.02 * rng.normal(size=n)
    for k in np.flatnonzero(np.abs(qdd) > LIMIT):
        tau = t[k : k + 40] - t[k]
        current[k : k + 40] += 0.8 * np.exp(-tau / 0.15) * np.sin(2 * np.pi * 5 * tau)
    return np.column_stack([q, qd, qdd]), current


def _detector(velocity_columns=None, **regimes):
    rule = AlarmRule("per_joint", false_alarm_rate=0.0, regimes=Regimes(**regimes))
    return CollisionDetector(LinearRegression(), sample_time=DT, rules=rule,
                             velocity_columns=velocity_columns)


@pytest.fixture(scope="module")
def fitted():
    X, current = _reversals()
    Z = stack_currents(X, current)
    return Z, _detector().fit(Z), _detector(brake_limit=LIMIT).fit(Z)


def test_braking_samples_are_the_hold_after_a_large_acceleration(fitted):
    Z, _, braking = fitted
    regime = braking.monitoring_signal(Z).regime
    flips = np.flatnonzero(np.abs(Z[:, 2]) > LIMIT)
    hold = round(0.5 / DT)
    expected = np.zeros(len(Z), dtype=bool)
    for k in flips:
        expected[k : k + hold + 1] = True
    assert flips.size >= 10
    np.testing.assert_array_equal(regime == BRAKING, expected)
    assert set(np.unique(regime[~expected])) == {MOVING}


def test_the_ring_no_longer_sets_the_moving_threshold(fitted):
    Z, plain, braking = fitted
    stage = ("settling after 0.25 s",)  # the default settle time's second stage
    assert plain.regime_names_ == ("moving", "settling", "rest") + stage
    assert braking.regime_names_ == ("moving", "settling", "rest", "braking") + stage
    assert braking.thresholds_.shape == (5, 1)
    moving, brake = braking.thresholds_[MOVING, 0], braking.thresholds_[BRAKING, 0]
    assert plain.thresholds_[MOVING, 0] > 0.5  # the ring
    assert moving < 0.15 < 0.5 < brake  # noise in motion, the ring while braking
    # a push in ordinary motion, between the two moving thresholds
    X, current = _reversals(seed=1)
    current[1100:1130] += 0.3  # 1 s after a flip, 1 s before the next
    fired = {name: det.predict_joints(stack_currents(X, current))[1090:1140, 0]
             for name, det in (("plain", plain), ("braking", braking))}
    assert fired["braking"][10:40].all() and not fired["braking"][:10].any()
    assert not fired["plain"].any()


def test_streaming_with_braking_equals_batch(fitted):
    _, _, braking = fitted
    X, current = _reversals(seed=2)
    current[1500:1520] += 0.3
    Z = stack_currents(X, current)
    out = StreamingMonitor(braking).replay(Z)
    batch = braking.monitoring_signal(Z)
    np.testing.assert_array_equal(out.regime, batch.regime)
    np.testing.assert_allclose(out.signal, batch.signal, rtol=1e-12, atol=1e-12)
    assert np.array_equal(out.prediction, braking.predict(Z))
    assert (out.regime == BRAKING).any() and (out.prediction == -1).any()


def test_brake_limit_is_checked():
    X, current = _reversals(n=300)
    Z = stack_currents(X, current)
    for bad in (0.0, -1.0, np.inf, "5"):
        with pytest.raises(ValueError, match="'brake_limit' parameter of Regimes must be None"):
            _detector(brake_limit=bad).fit(Z)
    with pytest.raises(ValueError, match="brake_hold"):
        _detector(brake_limit=LIMIT, brake_hold=-0.1).fit(Z)
    with pytest.raises(ValueError, match="needs the joint accelerations"):
        _detector(brake_limit=LIMIT, velocity_columns=[0]).fit(Z[:, [1, 3]])
