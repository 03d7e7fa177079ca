"""The batch regime pass equals the sample-by-sample one, bit for bit.

:func:`batch_regime_pass` (array operations, what calibration and the
detector's batch path run) against :func:`regime_pass` (a
:class:`RegimeState` stepped sample by sample): the same regime codes and
the same re-referenced signal to the last bit, over still and moving
stretches, several segments, rest references with and without a rest
band, braking, and signals with NaN and signed zeros.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sklearn_gpcd.detection._regime_batch import batch_regime_pass
from sklearn_gpcd.detection._regimes import BRAKING, REST, SETTLING, regime_pass


def _bits(a):
    return np.ascontiguousarray(a, dtype=float).view(np.uint64)


def assert_same(fast, slow):
    out_f, reg_f, ref_f = fast
    out_s, reg_s, ref_s = slow
    np.testing.assert_array_equal(reg_f, reg_s)
    np.testing.assert_array_equal(_bits(out_f), _bits(out_s))
    np.testing.assert_array_equal(_bits(ref_f), _bits(ref_s))


def _stream(rng, n, n_joints, with_accel=False):
    """Velocities in still and moving stretches, a drifting signal."""
    lengths = rng.integers(1, 60, size=n)
    still = np.repeat(rng.random(len(lengths)) < 0.5, lengths)[:n]
    qd = rng.normal(scale=0.3, size=(n, n_joints))
    qd[still] = rng.uniform(-0.009, 0.009, size=(still.sum(), n_joints))
    one_moves = rng.random(n) < 0.05  # a single joint above sigma_v
    qd[one_moves, rng.integers(0, n_joints)] = 0.02
    motion = qd
    if with_accel:
        motion = np.hstack([qd, rng.normal(scale=3.0, size=(n, n_joints))])
    signal = np.cumsum(rng.normal(scale=0.05, size=(n, n_joints)), axis=0)
    return signal, motion


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("beta", [None, 0.0, 0.002, 0.3])
def test_equals_the_sample_by_sample_pass(seed, beta):
    rng = np.random.default_rng(seed)
    signal, motion = _stream(rng, 3000, 3)
    starts = np.array([0, 700, 701, 2100])
    for settle in (0, 5, 40):
        assert_same(batch_regime_pass(signal, motion, starts, 0.01, settle, beta),
                    regime_pass(signal, motion, starts, 0.01, settle, beta))


@pytest.mark.parametrize("stages", [((2, 3),), ((2, 4), (5, 5), (11, 6))])
def test_equals_with_settling_stages(stages):
    rng = np.random.default_rng(9)
    signal, motion = _stream(rng, 3000, 3)
    starts = np.array([0, 1200])
    fast = batch_regime_pass(signal, motion, starts, 0.01, 40, 0.01, stages=stages)
    assert_same(fast, regime_pass(signal, motion, starts, 0.01, 40, 0.01, stages=stages))
    codes = {code for _, code in stages}
    assert codes <= set(fast[1].tolist()) and SETTLING in fast[1]


@pytest.mark.parametrize("entry_hold", [0, 1, 7])
def test_equals_with_a_rest_band(entry_hold):
    rng = np.random.default_rng(5)
    signal, motion = _stream(rng, 4000, 4)
    band = np.array([0.05, 0.2, 1.0, 0.0])  # one joint can never take its reference
    for beta in (None, 0.0, 0.01):
        fast = batch_regime_pass(signal, motion, [0, 1500], 0.01, 10, beta, rest_band=band,
                                 entry_hold=entry_hold)
        slow = regime_pass(signal, motion, np.array([0, 1500]), 0.01, 10, beta,
                           rest_band=band, entry_hold=entry_hold)
        assert_same(fast, slow)
    assert (fast[1] == REST).any() and (fast[1] == SETTLING).any()


@pytest.mark.parametrize("hold", [0, 3])
def test_equals_with_braking(hold):
    rng = np.random.default_rng(9)
    signal, motion = _stream(rng, 3000, 2, with_accel=True)
    fast = batch_regime_pass(signal, motion, [0], 0.01, 12, 0.05, brake_limit=6.0,
                             brake_hold=hold)
    assert_same(fast, regime_pass(signal, motion, np.array([0]), 0.01, 12, 0.05,
                                  brake_limit=6.0, brake_hold=hold))
    assert (fast[1] == BRAKING).any()


def test_equals_on_nan_and_signed_zeros():
    rng = np.random.default_rng(2)
    signal, motion = _stream(rng, 1500, 2)
    signal[::7] = 0.0
    signal[3::11] = -0.0
    signal[500, 1] = np.nan
    motion[900, 0] = np.nan  # an unknown velocity is motion
    for band in (None, np.array([0.5, 0.5])):
        assert_same(batch_regime_pass(signal, motion, [0], 0.01, 3, 0.1, rest_band=band),
                    regime_pass(signal, motion, np.array([0]), 0.01, 3, 0.1, rest_band=band))


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), settle=st.integers(0, 30),
       beta=st.sampled_from([None, 0.0, 1e-3, 0.5, 1.0]),
       band=st.sampled_from([None, 0.02, 0.3]), entry_hold=st.integers(0, 5),
       n=st.integers(1, 400))
def test_equals_on_random_streams(seed, settle, beta, band, entry_hold, n):
    rng = np.random.default_rng(seed)
    signal, motion = _stream(rng, n, 2)
    starts = np.unique(np.r_[0, rng.integers(0, n, size=2)])
    rest_band = None if band is None else np.full(2, band)
    assert_same(batch_regime_pass(signal, motion, starts, 0.01, settle, beta,
                                  rest_band=rest_band, entry_hold=entry_hold),
                regime_pass(signal, motion, starts, 0.01, settle, beta, rest_band=rest_band,
                            entry_hold=entry_hold))
