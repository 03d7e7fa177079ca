"""StreamingMonitor under sensor faults (issue #9: streaming fault behaviour).

Every fault kind -- NaN or inf in a position, velocity or current, a missing
sample, a time stamp that does not advance, a non-finite prediction -- must
give ``MonitorStatus.SENSOR_FAULT``: no exception, no alarm, and the state
left exactly as it was. The reference for "exactly" is a twin monitor that
never saw the faulty ticks: after every later tick both must hold identical
arrays. A wrong-length or non-numeric sample is a wiring error (ValueError)
and must not touch the state either.
"""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, WhiteKernel
from sklearn.gaussian_process.kernels import ConstantKernel as C
from sklearn.linear_model import Ridge

from sklearn_gpcd.layout import column_index
from sklearn_gpcd.detection import (
    AlarmRule,
    CollisionDetector,
    MonitorStatus,
    StreamingMonitor,
    stack_currents,
)
from sklearn_gpcd.gp import make_sp_p

from _synthetic import augmented_run

N_JOINTS = 2
STATE = ("predicted", "residual", "signal", "ratio", "alarms")


# ----------------------------------------------------------------- helpers
@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(0)
    X, current = augmented_run(800, N_JOINTS, rng)
    Z_train = stack_currents(X[::2], current[::2])
    test_current = current + 0.01 * rng.normal(size=current.shape)
    test_current[300:360, 0] += 2.0  # a contact on joint 0
    return Z_train, stack_currents(X, test_current)


@pytest.fixture(scope="module")
def ridge_detector(data):
    """Linear regressor, 2nd-order low-pass filter and a 3-sample debounce."""
    return CollisionDetector(Ridge(), n_joints=N_JOINTS,
                             rules=AlarmRule(contamination=0.01, filter_cutoff=5.0, filter_order=2,
                                             min_duration=3)).fit(data[0])


@pytest.fixture(scope="module")
def gp_detector(data):
    """SP_P on the compiled GP path, filtered and debounced."""
    sp_p = make_sp_p(None, N_JOINTS, n_support=60, random_state=0)
    return CollisionDetector(sp_p, n_joints=N_JOINTS,
                             rules=AlarmRule(contamination=0.01, filter_cutoff=8.0,
                                             min_duration=3)).fit(data[0])


def assert_same_state(a, b):
    assert a.status is b.status
    for name in STATE:
        assert np.array_equal(getattr(a, name), getattr(b, name), equal_nan=True), name


def feed_both(a, b, rows):
    for row in rows:
        assert a.update(row) is b.update(row)
        assert_same_state(a, b)


def faulty(row, column, value):
    row = row.copy()
    row[column] = value
    return row


Q0 = column_index("q", 0, N_JOINTS)
QD1 = column_index("qd", 1, N_JOINTS)
I_C0 = column_index("i_c", 0, N_JOINTS)
CURRENT1 = 6 * N_JOINTS + 1

FAULTS = {
    "nan position": (lambda row: faulty(row, Q0, np.nan), "non-finite value in q_0"),
    "inf velocity": (lambda row: faulty(row, QD1, np.inf), "non-finite value in qd_1"),
    "-inf controller current": (lambda row: faulty(row, I_C0, -np.inf),
                                "non-finite value in i_c_0"),
    "nan measured current": (lambda row: faulty(row, CURRENT1, np.nan),
                             "non-finite value in current[1]"),
    "everything nan": (lambda row: np.full_like(row, np.nan),
                       "non-finite value in q_0, q_1, qd_0, qd_1 and 10 more"),
    "missing sample": (lambda row: None, "missing sample (x is None)"),
    "None inside the sample": (lambda row: [None if i == QD1 else v for i, v in enumerate(row)],
                               "non-finite value in qd_1"),
}


# ------------------------------------------------------- each fault kind
@pytest.mark.parametrize("detector_name", ["ridge_detector", "gp_detector"])
@pytest.mark.parametrize("kind", list(FAULTS))
def test_fault_is_reported_skipped_and_recovered(kind, detector_name, data, request):
    detector = request.getfixturevalue(detector_name)
    Z = data[1]
    make_fault, reason = FAULTS[kind]
    monitor, twin = StreamingMonitor(detector), StreamingMonitor(detector)
    feed_both(monitor, twin, Z[:60])
    status = monitor.update(make_fault(Z[60]))  # no exception
    assert status is MonitorStatus.SENSOR_FAULT and status == "sensor_fault"
    assert monitor.fault_reason == reason
    assert not monitor.alarms.any() and np.isnan(monitor.score)
    assert np.isnan(monitor.residual).all() and np.isnan(monitor.ratio).all()
    assert (monitor.n_ticks, monitor.n_faults, monitor.n_consecutive_faults) == (61, 1, 1)
    # recovery: the next valid ticks are processed as if the fault never came
    feed_both(monitor, twin, Z[61:120])
    assert monitor.fault_reason is None and monitor.n_consecutive_faults == 0
    assert np.isfinite(monitor.residual).all()


def test_inputs_and_currents_given_separately(ridge_detector, data):
    Z = data[1]
    monitor, twin = StreamingMonitor(ridge_detector), StreamingMonitor(ridge_detector)
    n_inputs = monitor.n_inputs
    feed_both(monitor, twin, Z[:20])
    assert monitor.update(Z[20, :n_inputs], current=[np.nan, 1.0]) == "sensor_fault"
    assert monitor.fault_reason == "non-finite value in current[0]"
    assert monitor.update(None, current=Z[20, n_inputs:]) == "sensor_fault"
    for row in Z[20:40]:
        assert monitor.update(row[:n_inputs], current=row[n_inputs:]) is twin.update(row)
        assert_same_state(monitor, twin)


def test_named_columns_are_named_in_the_fault_reason(rng):
    pd = pytest.importorskip("pandas")
    X, current = augmented_run(200, N_JOINTS, rng)
    names = [f"c{i}" for i in range(6 * N_JOINTS)] + ["i_left", "i_right"]
    frame = pd.DataFrame(stack_currents(X, current), columns=names)
    monitor = StreamingMonitor(CollisionDetector(Ridge(), n_joints=N_JOINTS).fit(frame))
    row = frame.to_numpy()[0].copy()
    row[[3, -1]] = np.nan
    assert monitor.update(row) == "sensor_fault"
    assert monitor.fault_reason == "non-finite value in c3, i_right"


# ------------------------------------------------ wiring errors: ValueError
@pytest.mark.parametrize(
    "args, match",
    [
        ((np.zeros(6 * N_JOINTS + N_JOINTS - 1),), r"x must have 14 values .* got shape \(13,\)"),
        ((np.zeros(6 * N_JOINTS + N_JOINTS + 1),), r"x must have 14 values"),
        ((np.zeros((1, 6 * N_JOINTS + N_JOINTS)),), r"got shape \(1, 14\)"),
        ((np.zeros(6 * N_JOINTS), [1.0]), "current must have 2 values"),
        ((np.zeros(6 * N_JOINTS + 1), [1.0, 2.0]), "x must have 12 input values"),
        ((["a"] * 14,), "x must hold numbers"),
        ((np.zeros(6 * N_JOINTS), ["x", "y"]), "current must hold numbers"),
    ],
)
def test_wrong_length_is_a_value_error_that_leaves_the_state(args, match, ridge_detector, data):
    """A wrong length is a programming (wiring) error, not a sensor fault."""
    Z = data[1]
    monitor, twin = StreamingMonitor(ridge_detector), StreamingMonitor(ridge_detector)
    feed_both(monitor, twin, Z[:30])
    with pytest.raises(ValueError, match=match):
        monitor.update(*args)
    assert (monitor.n_ticks, monitor.n_faults) == (30, 0)
    assert_same_state(monitor, twin)
    feed_both(monitor, twin, Z[30:60])


def test_bad_time_is_a_value_error(ridge_detector, data):
    monitor = StreamingMonitor(ridge_detector)
    with pytest.raises(ValueError, match="time must be a number"):
        monitor.update(data[1][0], time="noon")
    assert monitor.n_ticks == 0


# ----------------------------------------------------------- time stamps
def test_repeated_or_earlier_time_stamp_is_a_fault(ridge_detector, data):
    Z = data[1]
    time = 0.008 * np.arange(len(Z))
    monitor, twin = StreamingMonitor(ridge_detector), StreamingMonitor(ridge_detector)
    for t in range(40):
        assert monitor.update(Z[t], time=time[t]) is twin.update(Z[t])
    assert monitor.last_time == time[39]
    # the packet of tick 39 arrives again, then a stale one, then a NaN stamp
    assert monitor.update(Z[39], time=time[39]) == "sensor_fault"
    assert "is not after the last valid sample's" in monitor.fault_reason
    assert monitor.update(Z[20], time=time[20]) == "sensor_fault"
    assert monitor.update(Z[40], time=np.nan) == "sensor_fault"
    assert monitor.fault_reason == "non-finite time nan"
    assert monitor.n_consecutive_faults == 3 and monitor.last_time == time[39]
    assert_same_state(monitor, monitor)  # arrays are NaN / False, not stale
    # a gap (ticks 40-44 lost) is not a fault; the stream goes on
    for t in range(45, 80):
        assert monitor.update(Z[t], time=time[t]) is twin.update(Z[t])
        assert_same_state(monitor, twin)
    assert monitor.n_faults == 3
    # reset (a new recording) forgets the last stamp: time may restart
    monitor.reset()
    assert monitor.last_time is None
    assert monitor.update(Z[0], time=0.0) != "sensor_fault"


def test_replay_with_time_stamps(ridge_detector, data):
    Z = data[1][:200]
    time = 0.008 * np.arange(len(Z))
    time[[50, 120]] = time[[49, 100]]  # a duplicate and a late packet
    out = StreamingMonitor(ridge_detector).replay(Z, time=time)
    assert np.flatnonzero(out.status == "sensor_fault").tolist() == [50, 120]
    keep = np.setdiff1d(np.arange(len(Z)), [50, 120])
    assert np.array_equal(out.prediction[keep], ridge_detector.predict(Z[keep]))
    with pytest.raises(ValueError, match=r"time must have shape \(200,\)"):
        StreamingMonitor(ridge_detector).replay(Z, time=time[:10])


# -------------------------------------------------- bursts and collisions
def test_burst_of_100_faults_then_recovery(gp_detector, data):
    Z = data[1]
    monitor, twin = StreamingMonitor(gp_detector), StreamingMonitor(gp_detector)
    feed_both(monitor, twin, Z[:100])
    kinds = list(FAULTS.values())
    for k in range(100):
        make_fault, _ = kinds[k % len(kinds)]
        assert monitor.update(make_fault(Z[100 + k])) is MonitorStatus.SENSOR_FAULT
        assert not monitor.alarms.any()
    assert monitor.n_consecutive_faults == 100 and monitor.n_faults == 100
    # the held filter and debounce state resume where they were
    feed_both(monitor, twin, Z[200:260])
    assert monitor.n_consecutive_faults == 0 and monitor.n_ticks == 260


def test_fault_during_a_collision(ridge_detector, data):
    """Contact on joint 0 over rows 300-359 (+2 A)."""
    Z = data[1]
    clean = StreamingMonitor(ridge_detector).replay(Z)
    first = 300 + int(np.flatnonzero(clean.status[300:] == "collision")[0])
    assert first < 310 and (clean.status[first:355] == "collision").all()
    assert (clean.status[250:300] == "ok").all() and (clean.status[420:460] == "ok").all()
    # faults in the middle of the contact: no alarm while faulty, and the
    # alarm is back on the first valid tick (no new min_duration wait)
    Z_faulty = Z.copy()
    Z_faulty[320:330, CURRENT1] = np.nan
    out = StreamingMonitor(ridge_detector).replay(Z_faulty)
    assert (out.status[320:330] == "sensor_fault").all() and not out.alarms[320:330].any()
    assert (out.status[first:320] == "collision").all()
    assert out.status[330] == "collision" and out.alarms[330, 0]
    # faults that outlast the contact: the valid samples decide as batch does
    Z_faulty = Z.copy()
    Z_faulty[340:400] = np.nan
    out = StreamingMonitor(ridge_detector).replay(Z_faulty)
    keep = np.r_[0:340, 400:len(Z)]
    assert np.array_equal(out.prediction[keep], ridge_detector.predict(Z[keep]))
    assert out.status[339] == "collision" and (out.status[340:400] == "sensor_fault").all()
    # the held filter state still carries the contact, so the alarm lasts a
    # few valid ticks after the outage and then ends, as in batch
    assert out.status[400] == "collision" and (out.status[430:460] == "ok").all()
    # after a long outage the caller may reset(): the stale contact is forgotten
    monitor = StreamingMonitor(ridge_detector)
    monitor.replay(Z_faulty[:400])
    monitor.reset()
    assert [monitor.update(row) for row in Z[400:460]] == ["ok"] * 60


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(faults=st.lists(st.tuples(st.integers(0, 399), st.sampled_from(list(FAULTS))),
                       max_size=60))
def test_valid_ticks_equal_batch_on_the_valid_rows(faults, ridge_detector, data):
    """Property: whatever the faults, the valid ticks equal batch predict on them."""
    Z = data[1][150:550]
    monitor = StreamingMonitor(ridge_detector)
    bad = {row: kind for row, kind in faults}
    statuses = []
    for t, row in enumerate(Z):
        sample = FAULTS[bad[t]][0](row) if t in bad else row
        statuses.append(monitor.update(sample).value)
    statuses = np.array(statuses)
    faulty_rows = np.array(sorted(bad), dtype=int)
    keep = np.setdiff1d(np.arange(len(Z)), faulty_rows)
    assert (statuses[faulty_rows] == "sensor_fault").all()
    prediction = np.where(statuses == "collision", -1, 1)
    assert np.array_equal(prediction[keep], ridge_detector.predict(Z[keep]))
    assert monitor.n_faults == len(bad)


# ------------------------------------------- faults past the input check
class _Overflowing(RegressorMixin, BaseEstimator):
    """Ridge-like regressor whose prediction overflows when x[0] > 100."""

    def fit(self, X, y):
        self.ridge_ = Ridge().fit(X, y)
        self.n_features_in_ = X.shape[1]
        return self

    def predict(self, X):
        y = self.ridge_.predict(X)
        return np.where(np.asarray(X)[:, :1] > 100, np.inf, y)


def test_non_finite_prediction_is_a_fault_and_does_not_poison_the_filter(data):
    Z_train, Z = data
    det = CollisionDetector(_Overflowing(), n_joints=N_JOINTS,
                            rules=AlarmRule(contamination=0.01, filter_cutoff=5.0, filter_order=2,
                                            min_duration=3)).fit(Z_train)
    monitor, twin = StreamingMonitor(det), StreamingMonitor(det)
    assert monitor.predictor_kind == "generic"
    feed_both(monitor, twin, Z[:50])
    assert monitor.update(faulty(Z[50], Q0, 1e3)) == "sensor_fault"  # finite input
    assert monitor.fault_reason == "non-finite predicted current of joint(s) [0, 1]"
    feed_both(monitor, twin, Z[50:150])  # the filter state was restored
    assert np.isfinite(monitor.signal).all()


def test_fault_on_the_first_tick_leaves_the_filter_fresh(data):
    """The filter starts in steady state on the first VALID sample, as batch."""
    Z_train, Z = data
    det = CollisionDetector(_Overflowing(), n_joints=N_JOINTS,
                            rules=AlarmRule(filter_cutoff=5.0, min_duration=1)).fit(Z_train)
    monitor, twin = StreamingMonitor(det), StreamingMonitor(det)
    assert monitor.update(faulty(Z[0], Q0, 1e3)) == "sensor_fault"
    feed_both(monitor, twin, Z[1:40])


def test_filter_overflow_is_a_fault_that_leaves_the_filter_state(data, ridge_detector):
    """A finite residual whose filter step overflows (here the first tick's
    steady state) is rejected before the state moves: the next valid ticks are
    processed as if it never came, instead of an infinite state faulting them all."""
    Z = data[1]
    monitor, twin = StreamingMonitor(ridge_detector), StreamingMonitor(ridge_detector)
    with np.errstate(over="ignore"):
        status = monitor.update(faulty(Z[0], CURRENT1 - 1, 1.7e308))
    assert status == "sensor_fault"
    assert monitor.fault_reason == "non-finite monitoring signal of joint(s) [0]"
    feed_both(monitor, twin, Z[1:60])


def test_std_normalisation_recovers_after_a_fault(rng):
    X, current = augmented_run(200, N_JOINTS, rng)
    gp = GaussianProcessRegressor(C(1.0) * RBF([3.0] * 12) + WhiteKernel(0.01), optimizer=None)
    det = CollisionDetector(gp, n_joints=N_JOINTS, normalize="std",
                            rules=AlarmRule(threshold="std", k=3.0,
                                            filter_cutoff=5.0)).fit(stack_currents(X, current))
    Z = stack_currents(X, current + 0.03)
    monitor, twin = StreamingMonitor(det), StreamingMonitor(det)
    feed_both(monitor, twin, Z[:30])
    assert monitor.update(faulty(Z[30], QD1, np.nan)) == "sensor_fault"
    feed_both(monitor, twin, Z[30:60])
