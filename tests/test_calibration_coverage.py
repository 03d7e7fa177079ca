"""Calibration that says when its data cannot support its thresholds (issue 38)."""

import re
import warnings

import numpy as np
import pytest

from sklearn_gpcd.io import Recording
from sklearn_gpcd.metrics import rate_upper_bound
from sklearn_gpcd.workflow import (
    CalibrationWarning,
    calibrate_detector,
    calibration_report,
    train_model,
)


def _recording(seconds, phase, moving=True, seed=0, name=None):
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * 100)) * 0.01
    q = (np.sin(0.5 * t + phase) if moving else np.full_like(t, phase))[:, None]
    qd = (0.5 * np.cos(0.5 * t + phase) if moving else np.zeros_like(t))[:, None]
    i_c = 2 * q
    return Recording(time=t, q=q, qd=qd, current=i_c + 0.05 * rng.normal(size=q.shape),
                     target_current=i_c, name=name)


@pytest.fixture(scope="module")
def trained():
    return train_model([_recording(30, 0.0)], model="sp_c", n_support=50)


def _calibrate(trained, recordings):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        calibrated = calibrate_detector(trained, recordings)
    return calibrated, [str(w.message) for w in caught if w.category is CalibrationWarning]


def test_short_calibration_warns_with_the_false_alarm_bound(trained):
    calibrated, messages = _calibrate(trained, [_recording(7, p, seed=s)
                                                for s, p in enumerate((1.0, 2.0, 3.0))])
    short = [m for m in messages if "lasts 21 s" in m]
    assert len(short) == 1
    count = calibrated.calibration["n_false_alarms_nested"]
    bound = float(re.search(r"only by (\d+) per hour", short[0]).group(1))
    assert bound == pytest.approx(rate_upper_bound(count, 21 / 3600), abs=1.0)
    assert "gpcd calibrate" in short[0]
    report = calibration_report(calibrated.calibration)
    assert "95 % upper bound" in report and "data per regime: moving" in report


def test_a_regime_from_one_recording_is_named(trained):
    recordings = [_recording(60, 0.3, moving=False, seed=1, name="p1.csv"),
                  _recording(60, -0.2, moving=False, seed=2, name="p2.csv"),
                  _recording(60, 1.0, seed=3, name="ptp.csv")]
    calibrated, messages = _calibrate(trained, recordings)
    moving = [m for m in messages if "every moving threshold" in m]
    assert len(moving) == 1 and "ptp.csv" in moving[0]
    assert "add collision-free recordings with the motions" in moving[0]
    coverage = calibrated.calibration["coverage"]
    assert coverage["moving"]["recordings"] == 1
    assert coverage["rest"]["recordings"] == 2


def test_enough_data_from_several_recordings_does_not_warn(trained):
    recordings = []
    for s, phase in enumerate((1.0, 2.0, 3.0)):  # moves, stops 6 times, stands still
        rec = _recording(60, phase, seed=s)
        qd = rec.qd.copy()
        for k in range(6):
            qd[600 * k + 400:600 * (k + 1)] = 0.0
        # the positions follow the stops (the signal checks compare q with qd)
        dt = np.diff(rec.time)[:, None]
        q = rec.q[0] + np.vstack([np.zeros((1, qd.shape[1])),
                                  np.cumsum(0.5 * (qd[1:] + qd[:-1]) * dt, axis=0)])
        recordings.append(Recording(time=rec.time, q=q, qd=qd, current=rec.current,
                                    target_current=rec.target_current))
    calibrated, messages = _calibrate(trained, recordings)
    summary = calibrated.calibration
    # no coverage warning; the quality warning (issue 46) only for what the summary shows
    coverage = [m for m in messages if not m.startswith("the calibration falls short")]
    assert coverage == []
    short_of_good = summary["margin"] > 2.0 or summary["n_false_alarms_nested"] > 0
    assert len(messages) == int(short_of_good)


def _summary(margin, count, hours=0.5, onsets=None):
    return {"margin": margin, "n_false_alarms_nested": count, "hours": hours,
            "false_alarms_per_hour": count / hours,
            "nested_onsets_s": onsets or {"a.csv": [], "b.csv": [1.0] * count}}


@pytest.mark.parametrize("margin, count, warns", [(1.5, 0, False), (2.0, 0, False),
                                                  (3.07, 0, True), (1.2, 1, True),
                                                  (3.07, 36, True)])
def test_a_summary_short_of_good_warns_with_its_figures(margin, count, warns):
    """Good (README): margin at most 2, no expected false alarm (issue 46)."""
    from sklearn_gpcd.workflow.calibration import _warn_quality

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        _warn_quality(_summary(margin, count))
    messages = [str(w.message) for w in caught if w.category is CalibrationWarning]
    assert len(messages) == int(warns)
    if warns:
        assert f"margin {margin:.2f}" in messages[0] and "gpcd calibrate" in messages[0]
    if warns and count:
        bound = rate_upper_bound(count, 0.5)
        assert f"{count / 0.5:.0f} expected false alarms per hour" in messages[0]
        assert f"95 % upper bound {bound:.0f}" in messages[0] and "b.csv" in messages[0]
        assert "a.csv" not in messages[0]


def test_the_summary_prints_one_false_alarm_figure(trained):
    recordings = [_recording(30, p, seed=s) for s, p in enumerate((1.0, 2.0, 3.0))]
    calibrated, _ = _calibrate(trained, recordings)
    report = calibration_report(calibrated.calibration)
    assert calibrated.calibration["candidates"]  # the settings were chosen (select)
    assert len(re.findall(r"per hour", report)) == 2, report  # the figure and its bound
    assert "alone" not in report


def test_a_regime_without_data_takes_the_largest_thresholds_of_the_others(trained):
    """A few samples at rest must not set rest thresholds far below the moving ones."""
    recordings = []
    for s, phase in enumerate((1.0, 2.0, 3.0)):
        rec = _recording(30, phase, seed=s)
        qd = rec.qd.copy()
        qd[1500:1580] = 0.0  # 0.8 s still: 0.5 s settling, then 0.3 s at rest
        recordings.append(rec.replace(qd=qd))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        calibrated = calibrate_detector(trained, recordings, settle_time=0.5)
    messages = [str(w.message) for w in caught if w.category is CalibrationWarning]
    summary = calibrated.calibration
    seconds = {name: c["seconds"] for name, c in summary["coverage"].items()}
    assert seconds["moving"] > 60 and 0.0 < seconds["rest"] < 1.0
    assert "rest" in summary["regimes_without_data"]
    thresholds = dict(zip(summary["regimes"], np.array(summary["thresholds_A"])))
    with_data = [name for name in summary["regimes"]
                 if name not in summary["regimes_without_data"]]
    largest = np.max([thresholds[name] for name in with_data], axis=0)
    np.testing.assert_allclose(thresholds["rest"], largest)
    np.testing.assert_allclose(calibrated.detector.thresholds_[2], largest)
    assert any("no calibration data in the rest regime" in m for m in messages)
    report = calibration_report(summary)
    assert "largest of the regimes with data" in report


def test_units_are_checked_between_model_and_recordings():
    """A torque model calibrated on recordings read as currents is refused (issue 46)."""
    torques = [_recording(20, p, seed=s, name=f"t{s}.csv").replace(units="Nm")
               for s, p in enumerate((0.0, 1.0, 2.0))]
    trained = train_model(torques[:1], model="sp_c", n_support=30)
    assert trained.training["units"] == "Nm"
    currents = [_recording(20, p, seed=s, name=f"calib/c{s}.csv") for s, p in ((4, 1.5),
                                                                              (5, 2.5))]
    with pytest.raises(ValueError, match=r"calib/c4.csv: its currents are read as motor "
                                         r"currents \[A\], but the model was trained on "
                                         r"joint torques \[Nm\].*--column-map"):
        calibrate_detector(trained, currents)
    with pytest.raises(ValueError, match=r"mix joint torques \[Nm\] \(t0.csv\) and motor "
                                         r"currents \[A\] \(calib/c4.csv\)"):
        train_model([torques[0], currents[0]], model="sp_c", n_support=30)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        summary = calibrate_detector(trained, torques[1:]).calibration
    assert summary["units"] == "Nm" and "thresholds [Nm]:" in calibration_report(summary)


def test_wrong_joint_count_names_the_file(trained):
    rec = _recording(20, 1.0, name="calib/two.csv")
    two = rec.replace(**{k: np.hstack([getattr(rec, k)] * 2)
                         for k in ("q", "qd", "current", "target_current")})
    with pytest.raises(ValueError, match=r"calib/two.csv: 2 joints, but the model was "
                                         r"trained on recordings of 1 joints.*gpcd train"):
        calibrate_detector(trained, [two, two])
