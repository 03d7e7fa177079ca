"""Long recordings streamed in chunks (issue #47, item 4): the same answers as a whole
read, memory bounded by a chunk; what would not fit refused before the work.

The peak memory on 1M and 10M-row logs is measured by ``benchmarks/big_logs.py``
(no memory figure is asserted here)."""

import json

import numpy as np
import pytest

from sklearn_gpcd.cli import main
from sklearn_gpcd.datasets import simulate_d1
from sklearn_gpcd.io import (
    JOINT_SIGNALS,
    iter_recording_chunks,
    load_recording,
    write_rtde_csv,
)
from sklearn_gpcd.io import chunks as chunks_module

RATE = 500.0


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    """Three collision-free 500 Hz UR10e runs, a run with a bump on joint 2, an SP_C
    model and a detector calibrated by the CLI (the whole-read path)."""
    folder = tmp_path_factory.mktemp("streaming")
    free = [write_rtde_csv(simulate_d1("ur10e", n_targets=2, sample_rate=RATE, random_state=s),
                           folder / f"free{s}.csv") for s in range(3)]
    rec = simulate_d1("ur10e", n_targets=2, sample_rate=RATE, random_state=7)
    t = rec.time - rec.time[0]
    current = rec.current.copy()
    current[(t >= 1.5) & (t < 1.9), 1] += 1.0
    push = write_rtde_csv(rec.replace(current=current), folder / "push.csv")
    model = folder / "model.skops"
    assert main(["train", *map(str, free[:2]), "--model", "sp_c", "--n-support", "60",
                 "-q", "-o", str(model)]) == 0
    detector = folder / "detector.skops"
    assert main(["calibrate", str(model), *map(str, free), "-q", "--no-select",
                 "-o", str(detector)]) == 0
    return {"folder": folder, "free": free, "push": push, "model": model,
            "detector": detector}


def _joined(chunks):
    out = {"time": np.concatenate([c.time for c in chunks])}
    for key in JOINT_SIGNALS:
        if getattr(chunks[0], key) is not None:
            out[key] = np.concatenate([getattr(c, key) for c in chunks])
    return out


def test_chunks_are_the_whole_read_cut_in_pieces(work, tmp_path):
    """Sample for sample, a malformed line and a blank line included (dropped by both)."""
    lines = work["push"].read_text().splitlines()
    lines[1200] = "garbage,1,2"
    lines.insert(3000, "")
    path = tmp_path / "dirty.csv"
    path.write_text("\n".join(lines) + "\n")
    with pytest.warns(UserWarning):
        whole = load_recording(path)
    with pytest.warns(UserWarning, match="line 1201"):
        chunks = list(iter_recording_chunks(path, chunk_bytes=40_000))
    assert len(chunks) > 5 and [c.metadata["chunk"] for c in chunks] == list(range(len(chunks)))
    joined = _joined(chunks)
    assert np.array_equal(joined["time"], whole.time)
    for key in JOINT_SIGNALS:
        assert (getattr(whole, key) is None) == (key not in joined)
        if key in joined:
            assert np.array_equal(joined[key], getattr(whole, key)), key
    assert sorted(r for c in chunks for r in c.metadata["dropped_rows"]) == \
        whole.metadata["dropped_rows"]


def test_rows_out_of_order_across_a_chunk_boundary_are_dropped(tmp_path):
    rec = simulate_d1("ur10e", n_targets=1, sample_rate=RATE, random_state=0)
    path = write_rtde_csv(rec, tmp_path / "a.csv")
    lines = path.read_text().splitlines()
    data = "".join(line + "\n" for line in lines[1:])
    n_tail = len(lines) // 3  # a logger that wrote its last third again
    path.write_text(lines[0] + "\n" + data + "".join(line + "\n" for line in lines[-n_tail:]))
    with pytest.warns(UserWarning, match=f"{n_tail} row.* from line {len(lines) + 1} on "
                      "dropped: their time stamps do not follow"):
        chunks = list(iter_recording_chunks(path, chunk_bytes=len(data) - 1))
    assert len(chunks) == 1
    assert np.array_equal(np.concatenate([c.time for c in chunks]), rec.time)


def test_a_very_wide_header_is_refused_before_reading(tmp_path, work):
    path = tmp_path / "wide.csv"
    names = ["timestamp", "actual_q_0"] + [f"x{k}" for k in range(20_000)]
    path.write_text(",".join(names) + "\n" + ",".join(["0"] * len(names)) + "\n")
    with pytest.raises(ValueError, match=r"wide.csv: the first line has 20002 columns, more "
                       r"than the 10000 .* keep only the columns the model needs"):
        next(iter_recording_chunks(path))
    with pytest.raises(ValueError, match=r"wide.csv: the first line has 20002 columns"):
        load_recording(path)  # the whole read too
    line = tmp_path / "one_line.csv"
    line.write_bytes(b"timestamp,actual_q_0," + b"1," * 2**20)
    with pytest.raises(ValueError, match=r"one_line.csv: line 1 is longer than 1 MiB"):
        next(iter_recording_chunks(line))


def test_monitor_streams_a_big_file_with_the_same_events(work, monkeypatch, capsys):
    """Offline and paced replay: events of the streamed file equal the whole read's."""
    whole_json, chunked_json = work["folder"] / "whole.json", work["folder"] / "chunk.json"
    for replay in ([], ["--replay"]):
        source = [*replay, str(work["push"])] + (["--speed", "0"] if replay else [])
        assert main(["monitor", str(work["detector"]), *source, "-q", "--json",
                     str(whole_json)]) == 0
        monkeypatch.setattr(chunks_module, "STREAM_BYTES", 10_000)
        monkeypatch.setattr(chunks_module, "CHUNK_BYTES", 50_000)
        assert main(["monitor", str(work["detector"]), *source, "-q", "--json",
                     str(chunked_json)]) == 0
        monkeypatch.undo()
        whole, chunked = (json.loads(p.read_text()) for p in (whole_json, chunked_json))
        assert whole["events"] and chunked["events"] == whole["events"]
        assert chunked["recordings"] == whole["recordings"]
    capsys.readouterr()
    monkeypatch.setattr(chunks_module, "STREAM_BYTES", 10_000)
    assert main(["monitor", str(work["detector"]), str(work["push"]), "--plot",
                 str(work["folder"] / "figs")]) == 2
    assert "--plot keeps every sample" in capsys.readouterr().err


@pytest.mark.parametrize("bands", [False, True])
def test_streamed_calibration_equals_the_batch_one(work, tmp_path, bands, monkeypatch):
    """calibrate_across_recordings(folder=...): one recording at a time, predicted a
    block of rows at a time, the series in files, the levels from the peaks; every
    threshold, margin, candidate and nested false alarm equal to the batch
    computation's (to the last bit)."""
    monkeypatch.setattr("sklearn_gpcd.detection.calibration.PREDICT_ROWS", 700)
    from sklearn.base import clone
    from sklearn.frozen import FrozenEstimator

    from sklearn_gpcd.detection import (
        AlarmRule,
        CollisionDetector,
        Regimes,
        calibrate_across_recordings,
        stack_currents,
    )
    from sklearn_gpcd.workflow import DETECTOR_RULE, SELECT_GRID, load_model, split_recordings

    trained = load_model(work["model"])
    recs = [load_recording(p) for p in work["free"]]
    keys, pieces = split_recordings([p.name for p in work["free"]], recs, 3.0)
    blocks = {k: stack_currents(trained.features.transform(r), r.current)
              for k, r in zip(keys, pieces)}
    times = {k: r.time for k, r in zip(keys, pieces)}
    main_rule = AlarmRule(**DETECTOR_RULE, regimes=Regimes(rest_reference=5.0))
    rules = [main_rule, clone(main_rule).set_params(filter_cutoff=10.0, min_duration=2)] \
        if bands else main_rule
    grid = ({"filter_cutoff": [5.0, 10.0]} if bands else SELECT_GRID)
    template = CollisionDetector(FrozenEstimator(trained.regressor), n_joints=6,
                                 sample_time="auto", rules=rules)
    batch = calibrate_across_recordings(template, blocks, times, param_grid=grid)
    streamed = calibrate_across_recordings(template, blocks, times, param_grid=grid,
                                           folder=tmp_path / "series")
    assert len(keys) >= 5 and streamed.n_false_alarms == batch.n_false_alarms
    assert streamed.folds == batch.folds and streamed.candidates == batch.candidates
    assert streamed.fold_settings == batch.fold_settings
    assert streamed.detector.sample_time_ == batch.detector.sample_time_
    for mine, theirs in zip(streamed.detector.rules_, batch.detector.rules_):
        for name in ("thresholds_", "scale_", "margin_", "offset_", "filter_coefficients_"):
            assert np.array_equal(getattr(mine, name), getattr(theirs, name)), name
    assert np.array_equal(streamed.detector.thresholds_, batch.detector.thresholds_)
    assert sorted(p.name for p in (tmp_path / "series" / "band0").iterdir())[:2] == \
        ["0_g.npy", "0_m.npy"]


def test_calibrate_streams_a_big_file_with_the_same_detector(work, monkeypatch, capsys):
    """gpcd calibrate on files above STREAM_BYTES: read in chunks, calibrated one piece
    at a time; the same summary and thresholds as the whole read (--split, select)."""
    from sklearn_gpcd.workflow import load_detector

    outputs = {}
    for mode in ("whole", "streamed"):
        if mode == "streamed":
            monkeypatch.setattr(chunks_module, "STREAM_BYTES", 10_000)
            monkeypatch.setattr(chunks_module, "CHUNK_BYTES", 60_000)
        outputs[mode] = work["folder"] / f"{mode}.skops"
        assert main(["calibrate", str(work["model"]), *map(str, work["free"][:2]),
                     "--split", "3", "-q", "-o", str(outputs[mode])]) == 0
        monkeypatch.undo()
    whole, chunked = (load_detector(outputs[m]) for m in ("whole", "streamed"))
    assert np.array_equal(chunked.detector.thresholds_, whole.detector.thresholds_)
    # the same summary; the current's noise floor (check_signals) is, per
    # recording, the median of its chunks' median steps when streamed (bounded
    # memory), the median step when read whole
    streamed_noise = chunked.calibration["signal_ranges"].pop("current_noise")
    whole_noise = whole.calibration["signal_ranges"].pop("current_noise")
    np.testing.assert_allclose(streamed_noise, whole_noise, rtol=0.1)
    assert chunked.calibration == whole.calibration
    capsys.readouterr()
    monkeypatch.setattr(chunks_module, "STREAM_BYTES", 10_000)
    monkeypatch.setattr("sklearn_gpcd.workflow.streamed.MAX_PIECE_ROWS", 1000)
    assert main(["calibrate", str(work["model"]), *map(str, work["free"][:2]), "-q",
                 "-o", str(work["folder"] / "no.skops")]) == 2
    err = capsys.readouterr().err
    assert "free0.csv: about" in err and "cut the log into pieces with --split 2" in err
    assert not (work["folder"] / "no.skops").exists()


def test_the_big_logs_benchmark_writes_tiles_that_read_back_clean(tmp_path):
    """benchmarks/big_logs.py: its tiled log joins without a jump (no row dropped, time
    regular), its wide log is refused at once, and its measurement reads a child's peak."""
    import importlib.util
    import sys
    import warnings
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "benchmarks" / "big_logs.py"
    spec = importlib.util.spec_from_file_location("big_logs", script)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    names, rows = bench.tile()
    path = bench.write_log(tmp_path / "log.csv", len(rows) + 5000, names, rows)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing dropped, no gap: the tiles join
        chunks = list(iter_recording_chunks(path, chunk_bytes=2_000_000))
    time = np.concatenate([c.time for c in chunks])
    assert len(time) == len(rows) + 5000 and np.allclose(np.diff(time), 1 / bench.RATE)
    wide = bench.wide_log(tmp_path / "wide.csv", n_rows=2)
    with pytest.raises(ValueError, match="wide.csv: line 1 is longer than 1 MiB"):
        next(iter_recording_chunks(wide))
    rc, peak, seconds, out, err = bench.measured([sys.executable, "-c", "print('hi')"])
    assert rc == 0 and peak > 1e6 and out.strip() == "hi"
