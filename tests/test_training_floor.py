"""Thresholds at least the model's out-of-fold levels on its training runs (issue 45).

One calibration log sets the thresholds from its own motions, stops and
rests; another program meets the model's error where it was not calibrated.
``gpcd train --model auto`` measured that error, regime by regime, on
training runs each fold left out: the calibration raises each regime's row
to it, never lowers it. Moving takes the time-weighted level the model was
chosen on; a settling stage or rest takes its own row when two left-out runs
held it.
"""

import dataclasses
import warnings

import numpy as np
import pytest

from sklearn_gpcd.detection import AlarmRule, Regimes, nested_alarms
from sklearn_gpcd.io import Recording
from sklearn_gpcd.workflow import (
    calibrate_detector, calibration_report, compare_models, train_model, training_set)
from sklearn_gpcd.workflow.calibration import training_levels


def _recording(seconds, phase, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * 100)) * 0.01
    q = np.sin(0.5 * t + phase)[:, None]
    qd = 0.5 * np.cos(0.5 * t + phase)[:, None]
    return Recording(time=t, q=q, qd=qd, current=2 * q + 0.05 * rng.normal(size=q.shape),
                     target_current=2 * q)


@pytest.fixture(scope="module")
def trained():
    return train_model([_recording(30, 0.0)], model="sp_c", n_support=50)


@pytest.fixture(scope="module")
def plain(trained):
    return _calibrate(trained)


#: The training rule's regimes (settle time 0.5 s) and their windows after the stop.
WINDOWS = {"moving": None, "settling": [0.0, 0.25], "rest": [0.5, None],
           "settling after 0.25 s": [0.25, 0.5]}


def _with_choice(trained, level, regimes=None, logs=2):
    choice = {"best": "sp_c", "models": ["p_f", "sp_c"],
              "thresholds": [[100.0], [float(level)]]}
    if regimes is not None:  # {name: level}
        choice.update(regimes=list(regimes), regime_seconds=[5.0] * len(regimes),
                      regime_windows=[WINDOWS[name] for name in regimes],
                      regime_logs=[logs] * len(regimes),
                      regime_thresholds=[[[100.0]] * len(regimes),
                                         [[float(v)] for v in regimes.values()]])
    return dataclasses.replace(trained, training={**trained.training, "model_choice": choice})


def _calibrate(trained):
    logs = [_recording(40, p, seed=k) for k, p in enumerate((1.0, 2.0, 3.0))]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return calibrate_detector(trained, logs)


def _row(calibrated, name):
    return list(calibrated.calibration["regimes"]).index(name)


def _thresholds(calibrated):
    return np.atleast_2d(calibrated.detector.thresholds_)


def test_without_a_model_choice_the_calibration_alone_sets_the_thresholds(trained, plain):
    assert training_levels(trained.training) == {}
    assert plain.calibration["training_floor_A"] == {}


def test_a_file_without_regime_levels_raises_the_moving_row_only(trained, plain):
    row = _row(plain, "moving")
    before = _thresholds(plain)
    level = 3.0 * before[row, 0]
    raised = _calibrate(_with_choice(trained, level))
    after = _thresholds(raised)
    assert after[row, 0] == pytest.approx(level)
    others = np.arange(len(before)) != row
    np.testing.assert_allclose(after[others], before[others])
    # every band with the main rule's filter carries it (the monitor reads the rules)
    rule = raised.detector.rules_[0]
    assert np.atleast_2d(rule.thresholds_)[row, 0] == pytest.approx(level)
    assert raised.calibration["training_floor_A"] == {"moving": [pytest.approx(level)]}
    report = calibration_report(raised.calibration)
    assert "left-out training runs" in report
    # the report names the command that records the other regimes' levels
    assert "run gpcd train --model auto again" in report


def test_each_regime_takes_the_training_rows_of_its_window(trained, plain):
    before = _thresholds(plain)
    top = before.max()
    levels = {"moving": 100.0, "settling": 2.0 * top, "settling after 0.25 s": 3.0 * top,
              "rest": 4.0 * top}
    raised = _calibrate(_with_choice(trained, 0.0, levels))
    after = _thresholds(raised)
    windows = raised.detector.rules_[0].since_stop()
    for name, window in zip(raised.calibration["regimes"], windows):
        if window is None:  # moving takes the time-weighted level (0 here: no floor)
            assert after[_row(raised, name), 0] == pytest.approx(before[_row(plain, name), 0])
            continue
        # the largest training row whose window overlaps this regime's
        expected = max(v for k, v in levels.items() if k != "moving" and
                       WINDOWS[k][0] < window[1] and window[0] < (WINDOWS[k][1] or np.inf))
        assert after[_row(raised, name), 0] == pytest.approx(expected), name
    assert "moving" not in raised.calibration["training_floor_A"]
    report = calibration_report(raised.calibration)
    assert "rest " in report and "settling " in report
    assert "gpcd train --model auto again" not in report
    # the nested false alarms are counted at the floored thresholds
    assert "each threshold at least its training floor" in report
    assert "at least its training floor" not in calibration_report(plain.calibration)


def test_a_longer_settle_time_takes_the_training_rest_after_its_stop(trained):
    levels = {"moving": 1.0, "settling": 2.0, "settling after 0.25 s": 3.0, "rest": 4.0}
    choice = _with_choice(trained, 1.0, levels).training
    rule = AlarmRule(regimes=Regimes(settle_time=2.0)).prepare(0.01)
    got = {k: float(v[0]) for k, v in training_levels(choice, rule).items()}
    # 0.5-1 s and 1-2 s after the stop are rest for the training rule (settle 0.5 s)
    assert got == {"moving": 1.0, "settling": 2.0, "settling after 0.25 s": 3.0,
                   "settling after 0.5 s": 4.0, "settling after 1 s": 4.0, "rest": 4.0}


def test_a_regime_one_left_out_run_held_sets_no_floor(trained, plain):
    before = _thresholds(plain)
    levels = {"rest": 4.0 * before[_row(plain, "rest"), 0]}
    assert "rest" not in training_levels(_with_choice(trained, 1.0, levels, logs=1).training)
    once = _calibrate(_with_choice(trained, 0.0, levels, logs=1))
    np.testing.assert_allclose(_thresholds(once), before)


def test_a_lower_training_level_never_tightens_the_calibration(trained, plain):
    before = _thresholds(plain)
    low = {name: 0.1 * before[k, 0] for k, name in enumerate(plain.calibration["regimes"])}
    lowered = _calibrate(_with_choice(trained, 0.1 * before.min(), low))
    np.testing.assert_allclose(_thresholds(lowered), before)


def test_the_model_choice_records_the_rows_its_thresholds_are_the_mean_of():
    runs = [_recording(30, p, seed=k) for k, p in enumerate((0.0, 1.5, 3.0))]
    for run in runs:  # a stop and a rest in each run
        run.qd[1000:1800] = 0.0
    table = compare_models(training_set(runs), models=["sp_c"], n_support=40)
    rows = table.regime_thresholds[0]
    assert rows.shape == (len(table.regimes), 1) and "rest" in table.regimes
    seconds = np.asarray(table.regime_seconds)
    mean = np.exp((seconds / seconds.sum()) @ np.log(rows))
    np.testing.assert_allclose(mean, table.thresholds[0])
    assert table.regime_logs[table.regimes.index("rest")] == 3
    text = "\n".join(table.text())
    assert "SP_C's thresholds per regime on the left-out recordings" in text
    assert f"    rest                   {rows[table.regimes.index('rest')][0]:.3f}" in text
    summary = table.summary()
    assert summary["regimes"] == table.regimes and len(summary["regime_thresholds"]) == 1
    assert summary["regime_windows"][table.regimes.index("rest")] == [0.5, None]


def test_the_nested_false_alarms_count_at_the_floored_thresholds(trained):
    # a calibration with nested alarms: one log rings where the others do not
    logs = [_recording(40, p, seed=k) for k, p in enumerate((1.0, 2.0, 3.0))]
    logs[2].current[2000:2100] += 0.4
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plain = calibrate_detector(trained, logs)
        assert plain.calibration["n_false_alarms_nested"] > 0
        top = 10.0 * _thresholds(plain).max()
        levels = {"settling": top, "settling after 0.25 s": top, "rest": top}
        floored = calibrate_detector(_with_choice(trained, top, {"moving": 0.0, **levels}),
                                     logs)
    # thresholds above every excursion: no recording alarms with the others' levels
    assert floored.calibration["n_false_alarms_nested"] == 0
    # the floors do not choose the settings: those are the calibration's own
    assert floored.calibration["settle_time_s"] == plain.calibration["settle_time_s"]


def test_nested_alarms_never_go_below_the_floor():
    flat = (np.ones((5, 1)), np.zeros(5, dtype=int), np.ones((1, 1)))
    bump = (np.array([[1.0], [3.0], [1.0], [1.0], [1.0]]), np.zeros(5, dtype=int),
            np.array([[3.0]]))
    series = {"a": flat, "b": flat, "c": bump}
    assert nested_alarms(series)["c"].any()
    assert not nested_alarms(series, floor=np.array([[3.0]]))["c"].any()
    assert nested_alarms(series, floor=np.array([[2.9]]))["c"].any()
