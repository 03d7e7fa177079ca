"""Signals a detector cannot trust (issue #47, point 5): scaled, sign-flipped or swapped
columns are refused or warned about naming the column, never accepted in silence.

Simulator data (``simulate_d1``, UR10e at 500 Hz); the real push log is
``benchmarks/mutated_logs.py``.
"""

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sklearn_gpcd.cli import main
from sklearn_gpcd.datasets import simulate_d1
from sklearn_gpcd.io import Recording, SignalCheck, load_recording, signal_ranges, write_rtde_csv
from sklearn_gpcd.workflow import check_signals, load_detector

RATE = 500.0


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    """An SP_C model and a detector calibrated by the CLI on simulated runs; a run to
    monitor: the last calibration run with one current bump (within what the model
    knows, so that its clean copy gives no warning)."""
    folder = tmp_path_factory.mktemp("plausibility")
    free = [write_rtde_csv(simulate_d1("ur10e", n_targets=2, sample_rate=RATE, random_state=s),
                           folder / f"free{s}.csv", robot_comment=True) for s in range(3)]
    rec = load_recording(free[2])
    t = rec.time - rec.time[0]
    current = rec.current.copy()
    current[(t >= 1.5) & (t < 1.9), 1] += 1.0
    push = rec.replace(current=current)
    model, detector = folder / "model.skops", folder / "detector.skops"
    assert main(["train", *map(str, free[:2]), "--model", "sp_c", "--n-support", "60",
                 "-q", "-o", str(model)]) == 0
    assert main(["calibrate", str(model), *map(str, free), "-q", "-o", str(detector)]) == 0
    return {"folder": folder, "push": push, "detector": detector}


def _events(path):
    return [(e["start_s"], e["end_s"]) for e in json.loads(path.read_text())["events"]]


def _monitor(work, rec, name, capsys):
    path = write_rtde_csv(rec, work["folder"] / f"{name}.csv", robot_comment=True)
    report = work["folder"] / f"{name}.json"
    status = main(["monitor", str(work["detector"]), str(path), "-q", "--json", str(report)])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    return status, (_events(report) if status == 0 else None), err


def _scaled(rec, field, factor, joints=None):
    values = getattr(rec, field).copy()
    values[:, slice(None) if joints is None else joints] *= factor
    return rec.replace(**{field: values})


#: Mutation families: (name, function of a recording, a word the message must hold).
FAMILIES = [
    ("current_joint_x1000", lambda r: _scaled(r, "current", 1000.0, [2]), "current[2]"),
    ("current_joint_x0.001", lambda r: _scaled(r, "current", 1e-3, [1]), "current[1]"),
    ("currents_swapped", lambda r: r.replace(current=r.current[:, [0, 2, 1, 3, 4, 5]]),
     "current["),
    ("qd_x0.001", lambda r: _scaled(r, "qd", 1e-3), "qd"),
    ("currents_x57", lambda r: _scaled(r, "current", 57.3), "current["),
    ("currents_sign", lambda r: _scaled(r, "current", -1.0), "current["),
    ("q_x0.001", lambda r: _scaled(r, "q", 1e-3), "q["),
    ("q_degrees", lambda r: _scaled(r, "q", 180 / np.pi), "q"),
    ("qd_degrees", lambda r: _scaled(r, "qd", 180 / np.pi), "qd"),
    ("q_qd_swapped", lambda r: r.replace(q=r.qd, qd=r.q), "qd"),
    ("time_ms", lambda r: r.replace(time=r.time * 1000), "time"),
]


def test_the_unmutated_run_monitors_without_a_word(work, capsys):
    status, events, err = _monitor(work, work["push"], "clean", capsys)
    assert status == 0 and events, err
    assert not any("warning" in line for line in err), err


@pytest.mark.parametrize("name, mutate, word", FAMILIES, ids=[f[0] for f in FAMILIES])
def test_a_scaled_or_swapped_column_is_named_never_silent(work, capsys, name, mutate, word):
    """Each family: refused (rc 2, one line naming the column and --units-confirmed), or
    warned naming it with the same events; never other events in silence."""
    _, clean, _ = _monitor(work, work["push"], "base", capsys)
    status, events, err = _monitor(work, mutate(work["push"]), name, capsys)
    if status == 2:
        assert len(err) == 1 and word in err[0], err
    else:
        assert status == 0, err
        assert events == clean or any(word in line and "warning" in line for line in err), \
            (events, clean, err)


def test_units_confirmed_lets_a_refused_recording_through(work, capsys):
    status, events, err = _monitor(work, _scaled(work["push"], "current", -1.0), "flip", capsys)
    assert status == 2
    path = work["folder"] / "flip.csv"
    assert main(["monitor", str(work["detector"]), str(path), "-q",
                 "--units-confirmed"]) == 0


def test_the_detector_file_keeps_the_ranges_of_training_and_calibration(work):
    _, _, calibration = load_detector(work["detector"])
    ranges = calibration["signal_ranges"]
    assert ranges["units"] == "A"
    assert np.all(np.array(ranges["q"][0]) <= np.array(calibration["training"]
                                                        ["signal_ranges"]["q"][0]))
    free = load_recording(work["folder"] / "free2.csv")  # calibration only
    assert np.all(np.array(ranges["current"][1]) >= free.current.max(0) - 1e-9)


def test_at_rest_a_swapped_or_scaled_velocity_is_caught():
    """The arm standing still: q constant, qd zero. Swapped, qd integrates to metres of
    travel q never shows; the correlation test this replaces said nothing at rest."""
    t = np.arange(2000) * 0.002
    q = np.tile([0.3, -1.9, -1.7, -1.5, 1.0, 0.4], (len(t), 1))
    qd = np.zeros_like(q)
    assert SignalCheck(6).update(t, q, qd, np.zeros_like(q)).findings() == []
    found = SignalCheck(6).update(t, qd, q, np.zeros_like(q)).findings()
    assert [f.columns for f in found] == [[f"q[{j}]", f"qd[{j}]"] for j in range(6)]
    assert all("swapped" in f.sentence and f.severity == "error" for f in found)


def test_chunks_give_the_findings_of_the_whole(work):
    """The state carried across chunks: the same findings in chunks as at once."""
    rec = _scaled(work["push"], "qd", 180 / np.pi)
    whole = SignalCheck(6).update(rec.time, rec.q, rec.qd, rec.current).findings()
    chunked = SignalCheck(6)
    for start in range(0, rec.n_samples, 777):
        rows = slice(start, start + 777)
        chunked.update(rec.time[rows], rec.q[rows], rec.qd[rows], rec.current[rows])
    assert [f.columns for f in chunked.findings()] == [f.columns for f in whole] != []


def test_a_current_beyond_the_training_range_scaled_is_an_error_at_rest():
    ranges = signal_ranges([Recording(time=[0.0, 1.0], q=[[0.0], [1.0]], qd=[[0.0], [0.0]],
                                      current=[[-2.0], [5.0]])])
    t = np.arange(100) * 0.01
    still = np.zeros((100, 1))
    check = SignalCheck(1, ranges=ranges).update(t, still, still, np.full((100, 1), 4.0e3),
                                                  np.full((100, 1), 4.0))
    assert [(f.kind, f.severity) for f in check.findings()] == [("current", "error"),
                                                                ("range", "warning")]
    flipped = SignalCheck(1, ranges=ranges).update(t, still, still, np.full((100, 1), -4.0),
                                                    np.full((100, 1), 4.0))
    assert "opposite sign" in flipped.findings()[0].sentence


#: Scales per column of the issue's families (currents x1000, x57.3, x-1, x0.001; q
#: x0.001, degrees; qd in degrees, x0.001).
SCALES = {"current": [1000.0, 57.3, -1.0, 1e-3], "q": [1e-3, 180 / np.pi],
          "qd": [180 / np.pi, 1e-3], "swap": [1.0]}


@settings(max_examples=12, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(["current", "q", "qd", "swap"]), pick=st.integers(0, 3),
       joint=st.integers(-1, 5))
def test_property_mutated_recordings_never_pass_in_silence(work, field, pick, joint):
    """Over scaled or swapped columns of the simulated run: check_signals (what gpcd
    monitor runs first) never raises anything but a ValueError naming the column, and
    an accepted recording whose column the model depends on is at least warned about
    or keeps its events... here: refused or unchanged prediction of the alarms."""
    factor = SCALES[field][pick % len(SCALES[field])]
    calibrated = load_detector(work["detector"])
    rec = work["push"]
    joints = None if joint < 0 else [joint]
    if field == "swap":
        q, qd = rec.q.copy(), rec.qd.copy()
        cols = slice(None) if joints is None else joints
        q[:, cols], qd[:, cols] = rec.qd[:, cols], rec.q[:, cols]
        mutated, word = rec.replace(q=q, qd=qd), "q"
    else:
        mutated, word = _scaled(rec, field, factor, joints), field
    try:
        findings = check_signals(mutated, calibrated, name="m.csv")
    except ValueError as exc:
        assert str(exc).startswith("m.csv: ") and word in str(exc)
        return
    # accepted: the detector's alarms on it equal those on the clean run
    from sklearn_gpcd.detection import stack_currents

    detector, features, _ = calibrated
    a = detector.predict(stack_currents(features.transform(rec), rec.current))
    b = detector.predict(stack_currents(features.transform(mutated), mutated.current))
    assert np.array_equal(a, b) or any(word in " ".join(f.columns) for f in findings)


def test_a_live_stream_names_a_swapped_column_per_window(work, capsys, monkeypatch):
    """Live (received times given): no check before the work, a SIGNALS line per
    implausible column at the end of a window, all in the report."""
    from sklearn_gpcd.monitoring import MonitorSession, recording_samples, signals
    from sklearn_gpcd.workflow import signal_check

    monkeypatch.setattr(signals, "WINDOW_SECONDS", 2.0)
    calibrated = load_detector(work["detector"])
    detector, features, _ = calibrated
    rec = work["push"]
    for mutated, expect in ((rec, []), (rec.replace(q=rec.qd, qd=rec.q), ["q[0]", "qd[0]"])):
        session = MonitorSession(detector, features, echo=True,
                                 signal_check=signal_check(calibrated))
        session.start("live")
        for t, fields in recording_samples(mutated):
            session.tick(t, fields, received=t)
        found = session.report()["signal_findings"]
        lines = [line for line in capsys.readouterr().out.splitlines()
                 if line.startswith("SIGNALS")]
        if not expect:
            assert found == [] and lines == []
        else:
            assert found and found[0]["columns"] == expect and found[0]["severity"] == "error"
            assert len(lines) == len({(f["kind"], tuple(f["columns"])) for f in found})


def test_a_file_that_would_not_fit_is_refused_before_reading(tmp_path, monkeypatch):
    """Issue #47 point 4: the estimate (about 10x the file size) against the memory
    available, before a byte is parsed: one line naming the file and what to do."""
    from sklearn_gpcd.io import _text

    rec = simulate_d1("ur10e", n_targets=1, random_state=0)
    path = write_rtde_csv(rec, tmp_path / "long.csv")
    size = path.stat().st_size
    monkeypatch.setattr(_text, "available_memory", lambda: 5 * size)
    with pytest.raises(ValueError, match="long.csv: .* of memory to read, more than"):
        load_recording(path)
    monkeypatch.setattr(_text, "available_memory", lambda: 20 * size)
    assert load_recording(path).n_samples == rec.n_samples


def test_the_detector_file_keeps_the_current_noise_of_its_recordings(work):
    """The smallest median sample-to-sample current step of the recordings the model
    knows: the sensor noise a real current does not fall below."""
    from sklearn_gpcd.io import load_recording

    noise = np.array(load_detector(work["detector"])[2]["signal_ranges"]["current_noise"])
    free = [load_recording(work["folder"] / f"free{s}.csv") for s in range(3)]
    steps = [np.median(np.abs(np.diff(r.current, axis=0)), axis=0) for r in free]
    np.testing.assert_allclose(noise, np.min(steps, axis=0))
    assert (noise > 0).all()


def test_simulated_runs_the_model_never_saw_give_no_finding(work):
    """False warnings: runs of other seeds (the same simulator) pass every check."""
    calibrated = load_detector(work["detector"])
    for seed in (7, 8, 9):
        rec = simulate_d1("ur10e", n_targets=2, sample_rate=RATE, random_state=seed)
        found = check_signals(rec, calibrated, accept=("range",), name=f"seed{seed}")
        assert [f for f in found if f.kind != "range"] == [], found


def _at_rest(n=3000, seed=0):
    """An arm standing still at 100 Hz, gravity loads on the currents with sensor noise
    (0.03 A), pushed twice by hand: the positions move by 20 encoder steps (1e-4 rad)
    and back, the velocity follows; everything written with 4 decimals like a UR log."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.01
    bump = np.exp(-0.5 * ((t[:, None] - np.array([8.0, 20.0])) / 0.3) ** 2).sum(1)
    q = np.array([0.3, -1.9, -1.7, -1.5, 1.0, 0.4]) + 2e-3 * bump[:, None] * [1, 1, 1, 0, 0, 0]
    qd = np.gradient(q, t, axis=0)
    gravity = np.array([0.1, 6.5, 3.9, 0.3, -0.05, 0.0])
    current = gravity + 0.03 * rng.standard_normal((n, 6)) + 2.0 * bump[:, None] * [1, 1, 0,
                                                                                    0, 0, 0]
    ranges = {"q": [[-3.0] * 6, [3.0] * 6], "qd": [[-2.0] * 6, [2.0] * 6],
              "current": [[-7.0, -16.0, -8.0, -1.2, -0.9, -0.8], [6.0, 20.0, 9.0, 1.1, 0.9,
                                                                  0.8]],
              "current_noise": [0.03] * 6, "units": "A"}
    rounded = [np.round(v, 4) for v in (q, qd, current)]
    return t, rounded, np.tile(gravity, (n, 1)), ranges


def _rest_findings(t, q, qd, current, predicted, ranges):
    thresholds = [2.5, 3.0, 1.9, 0.41, 0.55, 0.39]
    check = SignalCheck(6, ranges=ranges, thresholds=thresholds)
    return [(f.kind, f.columns) for f in check.update(t, q, qd, current, predicted).findings()]


def test_at_rest_a_scaled_down_or_swapped_column_is_named():
    """Issue #47 point 5, at rest: velocity x0.001 (zero at 4 decimals while q moves 20
    steps), one current x0.001 (below the sensor noise the model knows), two currents
    swapped (each fits the other joint's gravity load): each named; the clean log
    passes."""
    t, (q, qd, current), predicted, ranges = _at_rest()
    assert _rest_findings(t, q, qd, current, predicted, ranges) == []
    slow = _rest_findings(t, q, np.round(qd * 1e-3, 4), current, predicted, ranges)
    assert [c for kind, c in slow] == [["q[0]", "qd[0]"], ["q[1]", "qd[1]"], ["q[2]", "qd[2]"]]
    quiet = current.copy()
    quiet[:, 4] = np.round(quiet[:, 4] * 1e-3, 4)
    assert ("current", ["current[4]"]) in _rest_findings(t, q, qd, quiet, predicted, ranges)
    swapped = current[:, [0, 1, 3, 2, 4, 5]]
    assert ("current", ["current[2]", "current[3]"]) in _rest_findings(t, q, qd, swapped,
                                                                         predicted, ranges)
