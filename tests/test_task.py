"""A taught task (issue 45): a reference of the residual in the task's states,
one conformal level over cycles, untaught motion left to the detector.

Data: the package's own simulator (UR10), a global model that is a plain
ridge on ``[q, qd, qdd]`` (so it leaves a large, state-dependent residual
for the task reference to learn).
"""

import pickle

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.exceptions import NotFittedError
from sklearn.linear_model import Ridge

from sklearn_gpcd.datasets import Contact, JointTrajectory, simulate
from sklearn_gpcd.layout import block_columns
from sklearn_gpcd.detection import (AlarmRule, CollisionDetector, Regimes, TaughtTask,
                                    stack_currents,
                                    task_period)

Q0 = np.array([0.0, -1.57, 1.57, -1.57, -1.57, 0.0])
Q1 = Q0 + [0.6, 0.3, -0.4, 0.5, 0.4, 0.8]
DT = 0.008
#: Peak force [N] of the test push on link 3.
FORCE = 40.0


def _cycles(n, a=Q0, b=Q1, move=2.0):
    cycle = [JointTrajectory.point_to_point(a, b, move), JointTrajectory.rest(b, 0.3),
             JointTrajectory.point_to_point(b, a, move), JointTrajectory.rest(a, 0.3)]
    return JointTrajectory.concatenate(cycle * n)


#: Rows of the first cycle: a simulation's first motion starts from the
#: servo's initial state, unlike every later cycle (the teach summary flags it)
FIRST = 575


def _block(rec, skip=FIRST):
    qdd = np.gradient(rec.qd, rec.time, axis=0)
    return stack_currents(np.hstack([rec.q, rec.qd, qdd]), rec.current)[skip:]


@pytest.fixture(scope="module")
def taught():
    """A detector calibrated on other motions (margin 3, quiet on the task but
    blind to a 40 N push), and the task taught from 3 cycles."""
    moves = [Q0, Q1, Q0 + [0.2, 0.4, -0.2, 0.3, 0.6, 0.2], Q0 + [0.5, 0.1, -0.5, 0.6, 0.2, 1.0],
             Q0]
    general = JointTrajectory.concatenate([JointTrajectory.point_to_point(a, b, 3.5)
                                           for a, b in zip(moves[:-1], moves[1:])] * 2)
    rule = AlarmRule("per_joint", false_alarm_rate=0.0, margin=3.0, filter_cutoff=2.0,
                     min_duration=5, regimes=Regimes())
    det = CollisionDetector(Ridge(alpha=1e-3), rules=rule,
                            n_joints=6, sample_time=DT)
    det.fit(_block(simulate(general, "ur10", random_state=1), skip=0))
    # the first cycle of a simulation starts from the servo's initial state:
    # teach on the three after it (the teach summary flags such a cycle)
    task = TaughtTask(det).fit(_block(simulate(_cycles(4), "ur10", random_state=2)))
    return det, task


def test_task_period_finds_the_cycle():
    rec = simulate(_cycles(3), "ur10", random_state=0)
    period, corr = task_period(rec.q, DT)
    assert period == pytest.approx(4.6, abs=0.05)
    assert corr > 0.9


def test_teach_learns_the_cycles_and_tightens_the_thresholds(taught):
    det, task = taught
    assert task.n_cycles_ == 3
    assert task.period_ == pytest.approx(4.6, abs=0.05)
    assert task.level_ >= 1.0
    # the reference removes most of the ridge's residual on held-out cycles
    assert np.all(task.explained_ > 0.5), task.explained_
    # far tighter than the detector's moving thresholds on joints 2-6 (joint 1's
    # breakaway from rest, history-dependent, sets its own)
    moving = np.atleast_2d(det.thresholds_)[0]
    assert np.all(task.thresholds_[1:5] < 0.6 * moving[1:5]), (task.thresholds_, moving)
    assert np.all(task.thresholds_ < 1.1 * moving)
    summary = task.summary()
    assert summary["n_cycles"] == 3
    assert summary["false_alarm_bound_per_cycle"] == pytest.approx(0.25)


def test_a_push_is_caught_and_the_rest_of_the_task_is_quiet(taught):
    det, task = taught
    push = Contact(link=3, start=10.1, duration=0.8, force=[0.0, 0.0, -FORCE])
    rec = simulate(_cycles(4), "ur10", contacts=[push], random_state=3)
    res = task.monitoring_signal(_block(rec))
    t = rec.time[FIRST:]
    inside = (t >= push.start) & (t <= push.stop + 0.3)
    assert res.alarms[inside].any()
    assert not res.alarms[~inside].any()
    # one event for the push: open at its first alarm, held until the signal stays low
    from sklearn_gpcd.features import contiguous_segments
    events = contiguous_segments(res.event)
    assert len(events) == 1 and inside[events[0][0]]
    # taught where the arm moves (rest, settling and breakaway stay with the detector)
    assert not (res.taught & ~res.moving).any()
    assert res.taught.mean() > 0.5
    # the general detector alone misses it
    assert not res.general_alarms[inside].any()


def test_untaught_motion_falls_back_to_the_detector(taught):
    det, task = taught
    other = _cycles(1, a=Q0, b=Q0 + [-0.7, 0.0, 0.0, 0.0, 0.0, 0.0])
    X = _block(simulate(other, "ur10", random_state=4), skip=0)
    res = task.monitoring_signal(X)
    assert res.novelty.max() > 1.0
    untaught = ~res.taught
    assert untaught.mean() > 0.3
    np.testing.assert_array_equal(res.alarms[untaught], res.general_alarms[untaught])


def test_an_untaught_contact_is_the_detectors_event(taught):
    """Where nothing is taught the events are the detector's own: an event holds
    on its ratio until released, not only while it alarms."""
    det, task = taught
    a, b = Q0 + [0.2, 0.4, -0.2, 0.3, 0.6, 0.2], Q0 + [0.5, 0.1, -0.5, 0.6, 0.2, 1.0]
    push = Contact(link=3, start=4.0, duration=1.0, force=[0.0, 0.0, -150.0])
    X = _block(simulate(_cycles(2, a=a, b=b, move=3.5), "ur10", contacts=[push],
                        random_state=6), skip=0)
    res = task.monitoring_signal(X)
    general = det.monitoring_signal(X)
    assert not res.joints.any() and general.event.any()
    assert general.event.sum() > general.alarms.any(axis=1).sum()  # held past the alarm
    np.testing.assert_array_equal(res.event, general.event)
    _assert_stream_equals_batch(task, X)


def test_streaming_equals_batch(taught):
    det, task = taught
    push = Contact(link=3, start=5.4, duration=0.5, force=[0.0, 0.0, -60.0])
    X = _block(simulate(_cycles(2), "ur10", contacts=[push], random_state=5))
    _assert_stream_equals_batch(task, X)


def _assert_stream_equals_batch(task, X):
    """TaskStream, tick by tick, against the batch decisions of ``X``."""
    batch = task.monitoring_signal(X)
    stream = task.stream()
    n = task.n_joints_
    for i in range(len(X)):
        alarm, is_taught = stream.step(X[i, :-n], X[i, -n:], batch.general_alarms[i],
                                       batch.general_ratio[i], moving=batch.moving[i])
        assert is_taught == batch.taught[i]
        np.testing.assert_allclose(stream.signal, batch.signal[i], rtol=1e-9, atol=1e-12)
        np.testing.assert_array_equal(alarm, batch.alarms[i])
        assert stream.event == batch.event[i]
        assert stream.event_onset == batch.event_onset[i]


def test_a_cycle_unlike_the_others_is_named(taught):
    det, task = taught
    assert task.deviant_cycles() == []
    # someone leant on link 3 during the second taught cycle
    touch = Contact(link=3, start=10.1, duration=1.0, force=[0.0, 0.0, -150.0])
    X = _block(simulate(_cycles(4), "ur10", contacts=[touch], random_state=2))
    touched = TaughtTask(det).fit(X)
    assert [c["index"] for c in touched.deviant_cycles(factor=1.5)] == [1]
    assert task.deviant_cycles(factor=1.5) == []
    assert touched.level_ > 1.5 * task.level_


def test_one_cycle_is_refused_with_what_to_record(taught):
    det, _ = taught
    X = _block(simulate(_cycles(2), "ur10", random_state=6))
    with pytest.raises(ValueError, match="at least two cycles"):
        TaughtTask(det).fit(X)


# sklearn's parametrize_with_checks is not run on TaughtTask: it wraps a
# *fitted* detector and reads the paper's layout (q, qd, qdd blocks) of its
# inputs, while the generic checks fit it on 1-10 random columns. The
# contract those checks cover is tested here.
def test_sklearn_contract(taught):
    det, task = taught
    with pytest.raises(NotFittedError):
        TaughtTask(det).reference(np.zeros((1, 18)))
    with pytest.raises(ValueError, match="cutoff"):
        TaughtTask(det, cutoff=-1.0).fit(np.zeros((10, 24)))
    fresh = clone(task)
    assert fresh.get_params()["cutoff"] == task.cutoff
    assert not hasattr(fresh, "coef_")
    again = pickle.loads(pickle.dumps(task))
    X = _block(simulate(_cycles(2), "ur10", random_state=7))
    np.testing.assert_array_equal(again.monitoring_signal(X).alarms,
                                  task.monitoring_signal(X).alarms)


def test_streaming_monitor_runs_a_taught_task(taught):
    """StreamingMonitor(task): the detector's bands and the task in one tick."""
    from sklearn_gpcd.detection import StreamingMonitor

    det, task = taught
    push = Contact(link=3, start=5.4, duration=0.5, force=[0.0, 0.0, -FORCE])
    X = _block(simulate(_cycles(2), "ur10", contacts=[push], random_state=8))
    batch = task.monitoring_signal(X)
    monitor = StreamingMonitor(task)
    n = det.n_joints
    alarms, taught_rows = [], []
    for row in X:
        monitor.update(row[:-n], current=row[-n:])
        alarms.append(monitor.alarms.copy())
        taught_rows.append(monitor.taught)
    np.testing.assert_array_equal(np.array(taught_rows), batch.taught)
    np.testing.assert_array_equal(np.array(alarms), batch.alarms)
    assert batch.alarms.any()


# -- keep learning (partial_fit): a slow drift is tracked, a slow push is not ------------
def _monitor_and_learn(task, blocks, learn):
    """Monitor each block (one cycle or more) in turn, learning after each as a cell
    would between cycles; the alarms of every row as they were monitored."""
    task = pickle.loads(pickle.dumps(task))
    alarms, task.verdicts = [], []
    for X in blocks:
        alarms.append(task.monitoring_signal(X).alarms.any(axis=1))
        if learn:
            task.partial_fit(X)
            task.verdicts += task.last_learning_["verdicts"]
    return task, np.concatenate(alarms)


def _cycle_blocks(task, X):
    period = int(round(task.period_ / task.sample_time_))
    return [X[k:k + period] for k in range(0, len(X) - period + 1, period)]


@pytest.fixture(scope="module")
def warm_up(taught):
    """24 cycles (eight simulated ones, three times) while friction falls: every
    joint's current in the direction of motion drops steadily, by 0.45 of its
    taught threshold in all (warm-up)."""
    _, task = taught
    cycles = _cycle_blocks(task, _block(simulate(_cycles(9), "ur10", random_state=9))) * 3
    n = task.n_joints_
    rows = np.cumsum([0] + [len(c) for c in cycles])
    share = np.linspace(0.0, 1.0, rows[-1])
    out = []
    for c, lo in zip(cycles, rows[:-1]):
        c = c.copy()
        qd = c[:, block_columns("qd", n)]
        c[:, -n:] -= (share[lo:lo + len(c), None] * 0.45 * task.thresholds_
                      * np.tanh(qd / 0.05))
        out.append(c)
    return out


def test_keep_learning_tracks_a_warm_up(taught, warm_up):
    from sklearn_gpcd.detection.task import LEARN_LIMIT

    _, task = taught
    _, fixed_alarms = _monitor_and_learn(task, warm_up, learn=False)
    learned, alarms = _monitor_and_learn(task, warm_up, learn=True)
    assert fixed_alarms.any()             # the taught thresholds alone raise alarms
    assert not alarms.any()               # learning cycle by cycle follows the drift
    # the friction column of every joint carries the drift, within its bound
    share = learned.drift_ / task.thresholds_
    assert np.all(share[1] < -0.25), share
    assert np.all(np.abs(learned.drift_).sum(axis=0) <= LEARN_LIMIT * task.thresholds_ + 1e-12)
    np.testing.assert_array_equal(learned.thresholds_, task.thresholds_)
    assert learned.summary()["learned_cycles"] == learned.learned_cycles_ > 12


def test_streaming_equals_batch_after_learning(taught, warm_up):
    det, task = taught
    learned, _ = _monitor_and_learn(task, warm_up, learn=True)
    assert np.abs(learned.drift_).max() > 0
    _assert_stream_equals_batch(learned, warm_up[-1])


def test_a_slow_push_ramp_is_detected_not_learned(taught):
    """5 N/s on average up to 60 N on link 3 (a lean that grows), monitored and
    learned two cycles at a time: caught as early as without learning, and the
    cycles it touched teach nothing."""
    _, task = taught
    lean = Contact(link=3, start=10.0, duration=30.0, rise_time=12.0,
                   force=[0.0, 0.0, -60.0])
    rec = simulate(_cycles(9), "ur10", contacts=[lean], random_state=10)
    X, t = _block(rec), rec.time[FIRST:]
    blocks = _cycle_blocks(task, X)
    t = t[:sum(len(b) for b in blocks)]
    _, fixed_alarms = _monitor_and_learn(task, blocks, learn=False)
    learned, alarms = _monitor_and_learn(task, blocks, learn=True)
    assert not alarms[t < lean.start].any()
    first = t[np.argmax(alarms)]
    assert alarms.any() and first == t[np.argmax(fixed_alarms)]
    assert 60.0 * lean.profile([first])[0] < 60.0       # before the lean is full
    # no cycle the lean touched taught anything: none accepted, and one that
    # passed (its start, a few N) waited and was dropped by the alarm after it
    ends = np.cumsum([len(b) for b in blocks]) - 1
    touched = [bool(t[end] >= lean.start and t[end - len(b) + 1] <= lean.stop)
               for b, end in zip(blocks, ends)]
    verdicts = learned.verdicts
    assert any(touched)
    for k, (verdict, hit) in enumerate(zip(verdicts, touched)):
        assert not (hit and verdict == "accepted"), verdicts
        if hit and verdict == "pending":
            assert verdicts[k + 1] == "alarm", verdicts
    assert learned.learned_cycles_ <= touched.index(True), verdicts
    # and it is still caught by the learned task on the whole log
    assert learned.monitoring_signal(X).alarms[rec.time[FIRST:] >= lean.start].any()


def test_applied_thresholds_follow_the_taught_joints(taught):
    """What decided each tick: the task's threshold where its joint is taught
    (batch ``joints``), the detector's in its regime elsewhere."""
    from sklearn_gpcd.detection import StreamingMonitor

    det, task = taught
    X = _block(simulate(_cycles(2), "ur10", random_state=8))
    batch = task.monitoring_signal(X)
    monitor = StreamingMonitor(task)
    n = det.n_joints
    general = np.atleast_2d(det.thresholds_)
    for i, row in enumerate(X):
        monitor.update(row[:-n], current=row[-n:])
        expected = np.where(batch.joints[i], task.thresholds_, general[monitor.regime])
        np.testing.assert_array_equal(monitor.applied_thresholds, expected)
    assert batch.joints.any() and not batch.joints.all()
    assert not (batch.joints & ~batch.taught[:, None]).any()
