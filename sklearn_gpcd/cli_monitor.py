"""``gpcd calibrate`` and ``gpcd monitor``: thresholds across recordings, then detection.

``gpcd calibrate MODEL COLLISION_FREE... -o DETECTOR``
    Wraps a model saved by ``gpcd train`` in a
    :class:`~sklearn_gpcd.detection.CollisionDetector` (causal inputs,
    2 Hz causal low-pass, 5-sample debounce, one threshold per joint and per
    regime of the arm) whose thresholds are chosen across recordings by
    :func:`~sklearn_gpcd.detection.calibrate_across_recordings` (the
    leave-one-recording-out margin of ``benchmarks/real_ur10e.py``), and
    saves it with the model's :class:`~sklearn_gpcd.features.CausalFeatures`
    (fitted by ``gpcd train`` on the training recordings, so the detector
    feeds the model the inputs it was trained on). Each ``--band
    CUTOFF,ORDER,DEBOUNCE`` adds a band: the file then holds a
    :class:`~sklearn_gpcd.detection.MultiBandDetector` calibrated by
    :func:`~sklearn_gpcd.detection.calibrate_bands_across_recordings`;
    ``--band-candidate`` (repeatable) adds one more band whose settings that
    function chooses among the candidates across the recordings
    (``band_grid``).
``gpcd monitor DETECTOR RECORDINGS... | --replay FILE | --rtde HOST``
    Feeds raw samples through :meth:`StreamingMonitor.update_raw
    <sklearn_gpcd.detection.StreamingMonitor.update_raw>` (the causal path
    that runs on the robot) and reports the alarm events. Recordings are
    processed as fast as possible, ``--replay`` paces one recording to its
    time stamps (``--speed``), ``--rtde`` receives a live UR controller's
    stream (RTDE protocol 2, :mod:`sklearn_gpcd.io._rtde_live`). All three
    go through the same per-sample loop
    (:class:`~sklearn_gpcd.monitoring.MonitorSession`, fail-safe on live
    streams: FAULT lines, reset, reconnection, exit status 3), a
    :class:`~sklearn_gpcd.detection.MultiBandMonitor` for a multi-band file
    (an event: samples where any band alarms; the report names the bands).
"""

import argparse
import json
import math
import sys
import time
import warnings
from collections import Counter
from pathlib import Path

__all__ = ["DETECTOR_KIND", "DETECTOR_RULE", "SELECT_GRID", "add_commands", "load_detector"]

#: What a detector file holds (a dict saved with :func:`sklearn_gpcd.save`).
DETECTOR_KIND = "gpcd-detector"
#: The detection rule ``gpcd calibrate`` applies (that of benchmarks/real_ur10e.py).
DETECTOR_RULE = dict(threshold="per_joint", false_alarm_rate=0.0, filter_cutoff=2.0,
                     min_duration=5, sample_time="auto", sigma_v=None, settle_time=0.5)
#: The settings ``gpcd calibrate --select`` chooses among (benchmarks/real_ur10e.py's
#: "selected" monitors): settle time [s] x rest reference time constant [s].
SELECT_GRID = {"settle_time": [0.5, 1.0, 2.0, 3.0], "rest_reference": [None, 2.0, 5.0]}


# ---------------------------------------------------------------- arguments
def _non_negative_float(value):
    import argparse

    try:
        number = float(value)
    except ValueError:
        number = float("nan")
    if not (number >= 0 and math.isfinite(number)):
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {value!r}")
    return number


def _band_arg(value):
    """``CUTOFF,ORDER,DEBOUNCE`` as CollisionDetector overrides (``--band``)."""
    usage = ("expected CUTOFF,ORDER,DEBOUNCE like 10,1,2 (low-pass cut-off > 0 Hz, filter "
             f"order 1 or 2, debounce >= 1 samples), got {value!r}")
    parts = value.split(",")
    try:
        cutoff, order, debounce = float(parts[0]), int(parts[1]), int(parts[2])
    except (ValueError, IndexError):
        raise argparse.ArgumentTypeError(usage) from None
    if len(parts) != 3 or not (0 < cutoff < math.inf and order in (1, 2) and debounce >= 1):
        raise argparse.ArgumentTypeError(usage)
    return {"filter_cutoff": cutoff, "filter_order": order, "min_duration": debounce}


def _braking_arg(value):
    """``--braking [LIMIT]``: "model", or a finite acceleration > 0 [rad/s^2]."""
    if value == "model":
        return value
    try:
        limit = float(value)
    except ValueError:
        limit = float("nan")
    if not (0.0 < limit < float("inf")):
        raise argparse.ArgumentTypeError(
            f"expected an acceleration > 0 in rad/s^2 (or nothing: the model's own "
            f"limit), got {value!r}")
    return limit


def _brake_limit(args, training):
    """``CollisionDetector(brake_limit=...)`` from ``--braking`` and the model file."""
    if args.braking is None:
        return None
    if args.no_regimes:
        raise ValueError("--braking is a regime: drop --no-regimes")
    if args.braking != "model":
        return args.braking
    if (limit := training.get("acceleration_limit")) is None:
        raise ValueError(f"{args.model} does not record the largest acceleration it was "
                         "trained on (written by an earlier gpcd train): give --braking "
                         "LIMIT in rad/s^2, or train the model again")
    return float(limit)


def _existing_file(value):
    import argparse

    if not Path(value).is_file():
        raise argparse.ArgumentTypeError(f"{value}: no such file")
    return value


def add_commands(sub):
    """Register ``calibrate`` and ``monitor`` on the ``gpcd`` subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        What ``parser.add_subparsers()`` returned (see
        :func:`sklearn_gpcd.cli.build_parser`).

    Returns
    -------
    None

    Examples
    --------
    >>> import argparse
    >>> parser = argparse.ArgumentParser(prog="gpcd")
    >>> add_commands(parser.add_subparsers(dest="command"))
    >>> sorted(parser._subparsers._group_actions[0].choices)
    ['calibrate', 'monitor']
    """
    from . import cli

    cal = sub.add_parser(
        "calibrate",
        help="choose detection thresholds on collision-free recordings",
        description="Wrap a model saved by 'gpcd train' in a collision detector on causal "
        "inputs (2 Hz causal low-pass, 5-sample debounce, a threshold per joint and per "
        "regime of the arm: moving, settling, rest). Each level is the largest excursion of "
        "the calibration recordings, times a margin chosen by leave-one-recording-out: the "
        "largest factor by which a left-out recording exceeds the levels of the others. The "
        "expected false alarms per hour come from the nested version (margin and levels "
        "chosen without the recording they are counted on).",
    )
    cal.add_argument("model", type=_existing_file, help="model file written by gpcd train")
    cal.add_argument("recordings", nargs="+",
                     help="collision-free recordings (files, folders or glob patterns; at "
                     "least 2, 3 for the false-alarm figure)")
    cli._add_recording_options(cal, "built-in name or URDF path, for thresholds in Nm "
                               "(default: the robot named in the recordings' metadata)")
    cal.add_argument("--rest-reference", type=_non_negative_float, default=None,
                     help="time constant [s] of the rest re-reference (0: none; default 5)")
    cal.add_argument("--settle-time", type=_non_negative_float, default=None,
                     metavar="SECONDS",
                     help="seconds the arm must be still after a motion before it is at "
                     "rest (default 0.5)")
    cal.add_argument("--select", action="store_true",
                     help="choose the settle time (0.5, 1, 2, 3 s) and the rest reference "
                     "(none, 2, 5 s) across the recordings too: of the pairs with the fewest "
                     "nested alarm onsets on the recordings, the one with the smallest "
                     "time-weighted thresholds at its own leave-one-recording-out margin; "
                     "the expected false alarms then count each recording at the pair "
                     "chosen without it")
    cal.add_argument("--no-regimes", action="store_true",
                     help="one threshold per joint for every regime (no rest reference)")
    cal.add_argument("--band", type=_band_arg, action="append", default=None,
                     metavar="CUTOFF,ORDER,DEBOUNCE",
                     help="add a band: the same detector with its own causal low-pass "
                     "(cut-off [Hz], order 1 or 2) and debounce [samples], calibrated by the "
                     "same rule on the same model; a sample is a collision when any band "
                     "alarms (repeatable; e.g. --band 10,1,2 for short taps the 2 Hz main "
                     "band smooths away). The false-alarm figure counts the union")
    cal.add_argument("--band-candidate", type=_band_arg, action="append", default=None,
                     metavar="CUTOFF,ORDER,DEBOUNCE", dest="band_candidates",
                     help="a candidate for one more band whose settings are chosen across "
                     "the recordings (repeatable: give two or more): of the candidates, the "
                     "one with the fewest nested alarm onsets of the union of all bands, "
                     "then the smallest time-weighted thresholds; the expected false alarms "
                     "then count each recording with the band chosen without it")
    cal.add_argument("--braking", nargs="?", const="model", default=None, metavar="LIMIT",
                     type=_braking_arg,
                     help="a fourth regime with its own thresholds, braking: the 0.5 s after "
                     "a sample where some joint's |qdd| exceeds LIMIT [rad/s^2] (hard stops "
                     "ring the current); without LIMIT, the largest |qdd| the model was "
                     "trained on (recorded by gpcd train)")
    cal.add_argument("--split", type=cli._positive_float, default=None, metavar="SECONDS",
                     help="cut every recording into pieces of at least SECONDS, each left "
                     "out in turn like a recording of its own (for one long collision-free "
                     "log; pieces of one log are less independent than separate runs, so "
                     "the margin and the false-alarm figure are less safe)")
    cal.add_argument("-o", "--output", type=cli._model_file_arg, required=True,
                     help="detector file to write (.skops, or .joblib / .pkl)")
    cal.add_argument("--trust-pickle", action="store_true",
                     help="load a .joblib / .pkl model file (a pickle runs any code it "
                     "carries: only for a file from a source you trust)")
    cal.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    cal.set_defaults(func=_cmd_calibrate)

    mon = sub.add_parser(
        "monitor",
        help="detect collisions in recordings, a real-time replay or a live UR (RTDE)",
        description="Run a detector from 'gpcd calibrate' sample by sample through the "
        "causal streaming path and report alarm events: start, end, joints (1-based), peak "
        "|m| and the delay from the first threshold crossing to the alarm; with several "
        "bands (gpcd calibrate --band), an alarm of any band, and which bands alarmed.",
    )
    mon.add_argument("detector", type=_existing_file,
                     help="detector file written by gpcd calibrate")
    mon.add_argument("recordings", nargs="*", help="recordings to monitor (offline)")
    mon.add_argument("--column-map", type=cli._column_map_arg, default=None,
                     help="column layout of the recordings (as for gpcd train)")
    mon.add_argument("--replay", default=None, metavar="FILE",
                     help="replay one recording paced to its time stamps")
    mon.add_argument("--speed", type=_non_negative_float, default=1.0,
                     help="replay speed factor (1: real time, 0: as fast as possible)")
    mon.add_argument("--rtde", default=None, metavar="HOST",
                     help="monitor a live UR controller over RTDE")
    mon.add_argument("--port", type=cli._positive_int, default=30004, help="RTDE port")
    mon.add_argument("--frequency", type=cli._positive_float, default=None,
                     help="RTDE output frequency [Hz] (default: the detector's calibration "
                     "rate, 1 / sample time, so that its filters fit; at most 500 on "
                     "e-Series, 125 on CB3)")
    mon.add_argument("--duration", type=cli._positive_float, default=None,
                     help="stop a live or replayed stream after this many seconds of "
                     "stream time")
    mon.add_argument("--hook", default=None, metavar="CMD",
                     help="command run (not waited for) at each alarm onset (it gets "
                     "GPCD_ALARM_TIME and GPCD_ALARM_JOINTS in its environment) and at each "
                     "fault of a live stream (GPCD_FAULT, GPCD_FAULT_TIME); one that fails "
                     "is reported and monitoring goes on")
    mon.add_argument("--json", type=cli._output_file_arg, default=None,
                     help="write the events (and live statistics) as JSON here")
    mon.add_argument("--plot", type=cli._output_dir_arg, default=None, metavar="DIR",
                     help="write one figure per recording here (offline and replay)")
    mon.add_argument("--trust-pickle", action="store_true",
                     help="load a .joblib / .pkl detector file (a pickle runs any code it "
                     "carries: only for a file from a source you trust)")
    mon.add_argument("--stall-timeout", type=cli._positive_float, default=None,
                     metavar="SECONDS",
                     help="live streams: blind (a FAULT line, the hook with GPCD_FAULT, "
                     "monitor reset) after this long without a valid decision (default: "
                     "3 control periods or 20 ms, whichever is larger)")
    mon.add_argument("--reconnect-timeout", type=_non_negative_float, default=30.0,
                     metavar="SECONDS",
                     help="--rtde: after a lost link, reconnect with backoff for this long, "
                     "then end (exit status 3)")
    mon.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    mon.set_defaults(func=_cmd_monitor)
    cli._RECORDING_POSITIONALS.update(calibrate="recordings", monitor="recordings")


# ---------------------------------------------------------------- calibrate
def _recording_keys(recordings):
    """Unique names of the recordings (their file names, numbered on a clash)."""
    keys = []
    for i, rec in enumerate(recordings):
        name = Path(str(rec.name or f"#{i}")).name
        keys.append(name if name not in keys else f"{name} ({i + 1})")
    return keys


def _optional_robot(args, recordings):
    """The robot for Nm figures: --robot, else the recordings' metadata, else None."""
    from .cli import _robot_for

    try:
        return _robot_for(args, recordings)
    except ValueError:
        if args.robot is not None:
            raise
        return None


def _check_model_inputs(model, features, path):
    n_in = getattr(model, "n_features_in_", None)
    n_rows = (6 if features.augmented else 3) * features.n_joints_
    if n_in is not None and n_in != n_rows:
        raise ValueError(f"{path}: the model takes {n_in} input columns but the recordings "
                         f"give {n_rows} ({features.n_joints_} joints)")


def _cmd_calibrate(args):
    """``gpcd calibrate``: LORO thresholds on collision-free recordings, saved detector."""
    from sklearn.frozen import FrozenEstimator

    from .cli import _Progress, _read_recordings
    from .detection import (
        CollisionDetector,
        MultiBandDetector,
        calibrate_across_recordings,
        calibrate_bands_across_recordings,
        stack_currents,
    )
    from .features import CausalFeatures
    from .io.load import recording_paths
    from .persistence import save
    from .workflow import load_model

    start = time.perf_counter()
    paths = [Path(p).resolve() for p in recording_paths(args.recordings)]
    if (twice := sorted({str(p) for p in paths if paths.count(p) > 1})):
        raise ValueError(f"{twice[0]} is given twice; a left-out recording must not stay in "
                         "the others (check overlapping patterns)")
    if len(paths) < 2 and args.split is None:  # before any work
        raise ValueError("thresholds are chosen across recordings (leave-one-recording-out): "
                         f"give at least 2 collision-free recordings, got {len(paths)} "
                         "(or cut a long one into pieces with --split SECONDS)")
    if args.select and (args.no_regimes or args.rest_reference is not None
                        or args.settle_time is not None):
        raise ValueError("--select chooses the settle time and the rest reference of the "
                         "regimes: drop " + ("--no-regimes" if args.no_regimes
                                             else "--rest-reference" if args.settle_time
                                             is None else "--settle-time"))
    if args.select and (args.band or args.band_candidates):
        raise ValueError("--select chooses the settings of one band; with --band or "
                         "--band-candidate there are several: drop --select or the bands")
    trained = load_model(args.model, trust_pickle=args.trust_pickle)
    model, features = trained.regressor, trained.features
    recordings = _read_recordings(args.recordings, args, "calibration recordings")
    robot = _optional_robot(args, recordings)
    if features is None:  # a bare regressor, from a gpcd train that did not save features
        warnings.warn(f"{args.model} holds no input features (an older gpcd train file): "
                      "causal features fitted on the calibration recordings are used; "
                      "retrain with gpcd train to calibrate on the model's own inputs",
                      UserWarning, stacklevel=2)
        features = CausalFeatures().fit(recordings)
    _check_model_inputs(model, features, args.model)
    keys = _recording_keys(recordings)
    n_files = len(recordings)
    if args.split is not None:
        keys, recordings = split_recordings(keys, recordings, args.split)
    bar = _Progress("causal inputs", len(recordings), enabled=not args.quiet)
    blocks, times = {}, {}
    for key, rec in zip(keys, recordings):
        blocks[key] = stack_currents(features.transform(rec), rec.current)
        times[key] = rec.time
        bar.update()
    regimes = not args.no_regimes
    tau = 5.0 if args.rest_reference is None else args.rest_reference
    tau = tau if (regimes and tau > 0) else None
    template = CollisionDetector(FrozenEstimator(model), n_joints=features.n_joints_,
                                 regimes=regimes, rest_reference=tau,
                                 brake_limit=_brake_limit(args, trained.training),
                                 **DETECTOR_RULE)
    if args.settle_time is not None:
        template.set_params(settle_time=args.settle_time)
    candidates = args.band_candidates
    if args.band or candidates:
        grid = [{k: [v] for k, v in c.items()} for c in candidates] if candidates else None
        # the chosen band is the last; its overrides stand in until the grid's replace them
        overrides = [{}, *(args.band or [])] + ([candidates[0]] if candidates else [])
        result = calibrate_bands_across_recordings(
            MultiBandDetector(template, bands=overrides), blocks, times, band_grid=grid)
        bands = result.bands
    else:
        result = calibrate_across_recordings(template, blocks, times,
                                             param_grid=SELECT_GRID if args.select else None)
        bands = [result]
    kt = None if robot is None else getattr(robot, "torque_constants", None)
    entries = [_band_entry(band, kt) for band in bands]
    det = bands[0].detector  # the main band
    summary = {
        "recordings": keys, "split_s": args.split, "n_files": n_files,
        "hours": result.hours, "margin": entries[0]["margin"],
        "margin_rule": "global", "regimes": list(bands[0].regime_names),
        "settle_time_s": det.settle_time, "rest_reference_s": det.rest_reference,
        "brake_limit": det.brake_limit, "selected": bool(args.select),
        "candidates": [dict(c, params=_json_params(c["params"])) for c in result.candidates]
        if args.select else [],
        "thresholds_A": entries[0]["thresholds_A"],
        "n_false_alarms_nested": result.n_false_alarms,
        "false_alarms_per_hour": result.false_alarms_per_hour,
        "nested_onsets_s": {k: f["onsets"] for k, f in result.folds.items()},
        "training": trained.training,
        "signals": list(features.signals_), "sample_time_s": float(det.sample_time_),
        "robot": None if robot is None else robot.name,
    }
    if kt is not None:
        summary["thresholds_Nm"] = entries[0]["thresholds_Nm"]
    if args.band or candidates:
        summary["bands"] = entries
    if candidates:
        summary["band_candidates"] = [
            dict(c, params=_band_settings(CollisionDetector(**c["params"])))
            for c in result.band_candidates]
        summary["fold_band_settings"] = {
            k: _band_settings(CollisionDetector(**p)) for k, p in
            result.fold_band_settings.items()}
    save({"kind": DETECTOR_KIND, "detector": result.detector, "features": features,
          "calibration": summary}, args.output)
    _print_calibration(summary, len(recordings))
    print(f"  {time.perf_counter() - start:.1f} s; wrote {args.output}")
    return 0


def _band_settings(detector):
    """What sets a band apart: its low-pass filter and debounce."""
    return {"filter_cutoff_hz": detector.filter_cutoff, "filter_order": detector.filter_order,
            "debounce_samples": detector.min_duration}


def _band_label(settings):
    """``"10 Hz, order 1, debounce 2"`` from :func:`_band_settings`."""
    cutoff = settings["filter_cutoff_hz"]
    low_pass = "no low-pass" if cutoff is None else (f"{cutoff:g} Hz, order "
                                                     f"{settings['filter_order']}")
    return f"{low_pass}, debounce {settings['debounce_samples']}"


def _band_entry(result, torque_constants):
    """One band's calibration (a calibrate_across_recordings result) for the summary."""
    import numpy as np

    thresholds = np.atleast_2d(result.detector.thresholds_)
    entry = {**_band_settings(result.detector), "margin": float(result.margin.max()),
             "thresholds_A": thresholds.tolist(),
             "n_false_alarms_nested": result.n_false_alarms,
             "false_alarms_per_hour": result.false_alarms_per_hour}
    if torque_constants is not None:
        entry["thresholds_Nm"] = (thresholds * np.asarray(torque_constants)).tolist()
    return entry


def split_recordings(keys, recordings, seconds):
    """Each recording cut into pieces of at least ``seconds``, keyed ``"name#i"``.

    A recording shorter than ``2 * seconds`` stays whole. The pieces of a
    recording have about equal numbers of samples (``floor(duration / seconds)``
    of them); filters and debounce restart at each piece, as at the start of
    a recording.

    Parameters
    ----------
    keys : list of str
        Names of the recordings.
    recordings : list of Recording
    seconds : float
        Shortest piece [s].

    Returns
    -------
    keys, pieces : list of str, list of Recording

    Raises
    ------
    ValueError
        When the pieces are fewer than 2.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> rec = Recording(time=np.arange(1000) * 0.01, q=np.zeros((1000, 1)),
    ...                 qd=np.zeros((1000, 1)), current=np.zeros((1000, 1)))
    >>> keys, pieces = split_recordings(["free.csv"], [rec], 3.0)
    >>> keys, [p.n_samples for p in pieces]
    (['free.csv#1', 'free.csv#2', 'free.csv#3'], [333, 334, 333])
    """
    import numpy as np

    out_keys, pieces = [], []
    for key, rec in zip(keys, recordings):
        n_pieces = int(rec.duration // seconds) if rec.duration >= 2 * seconds else 1
        if n_pieces == 1:
            out_keys.append(key)
            pieces.append(rec)
            continue
        bounds = np.linspace(0, rec.n_samples, n_pieces + 1).round().astype(int)
        for i, (start, stop) in enumerate(zip(bounds[:-1], bounds[1:]), start=1):
            out_keys.append(f"{key}#{i}")
            pieces.append(rec.slice(start, stop))
    if len(pieces) < 2:
        longest = max(rec.duration for rec in recordings)
        raise ValueError(f"--split {seconds:g} leaves {len(pieces)} piece: the longest "
                         f"recording lasts {longest:.1f} s; use a split of at most "
                         f"{longest / 2:.1f} s")
    return out_keys, pieces


def _json_params(params):
    """Candidate settings with JSON keys: ``settle_time`` -> ``settle_time_s``."""
    return {f"{k}_s" if k in ("settle_time", "rest_reference") else k: v
            for k, v in params.items()}


def _seconds(value):
    return "none" if value is None else f"{value:g} s"


def _print_calibration(summary, n_recordings):
    if summary.get("split_s") is not None:
        print(f"cut {summary['n_files']} recording(s) into {n_recordings} pieces of at least "
              f"{summary['split_s']:g} s (--split), each left out in turn like a recording; "
              "pieces of one log are less independent than separate runs")
    print(f"calibrated on {n_recordings} collision-free recording(s), "
          f"{summary['hours'] * 60:.1f} min, sample time {summary['sample_time_s']:g} s, "
          f"controller signals used: {', '.join(summary['signals']) or 'none'}; settle "
          f"time {_seconds(summary['settle_time_s'])}, rest reference "
          f"{_seconds(summary['rest_reference_s'])}"
          + (" (chosen across the recordings)" if summary.get("selected") else "")
          + ("" if summary.get("brake_limit") is None else
             f"; braking above {summary['brake_limit']:.3g} rad/s^2"))
    if summary.get("candidates"):
        print("  candidates, best first (alarms: nested onsets at that fixed candidate, "
              "fewest first; score: time-weighted mean log threshold, smaller is tighter):")
        for c in sorted(summary["candidates"], key=lambda c: c["rank"]):
            settle, tau = c["params"]["settle_time_s"], c["params"]["rest_reference_s"]
            print(f"    settle {_seconds(settle):>6}, rest reference {_seconds(tau):>5}: "
                  f"alarms {c['n_false_alarms']}, score {c['score']:+.3f}, "
                  f"margin {c['margin']:.3f}" + ("  <- chosen" if c["rank"] == 0 else ""))
    if (info := summary.get("training")):
        print(f"  model: {info['model'].upper()} trained on {info['inputs']} inputs, "
              f"{info['n_support']} support rows per joint, optimizer {info['optimizer']}, "
              f"seed {info['seed']}")
    if "bands" not in summary:
        _print_margin(summary, "  ")
        _print_false_alarms(summary)
        _print_thresholds(summary, summary, "  ")
        return
    for b, band in enumerate(summary["bands"], start=1):
        print(f"  band {b} ({_band_label(band)})" + (", the main one:" if b == 1 else ":"))
        _print_margin(band, "    ")
        if band["false_alarms_per_hour"] is not None:
            print(f"    nested false alarms of this band alone: "
                  f"{band['n_false_alarms_nested']} alarm onset(s) = "
                  f"{band['false_alarms_per_hour']:.2f} per hour")
        _print_thresholds(band, summary, "    ")
    if (table := summary.get("band_candidates")):
        print(f"  band {len(summary['bands'])} chosen across the recordings, candidates best "
              "first (alarms: nested onsets of the union; score: time-weighted mean log "
              "threshold of the band, smaller is tighter):")
        for c in sorted(table, key=lambda c: c["rank"]):
            print(f"    {_band_label(c['params']):<28} alarms {c['n_false_alarms']}, score "
                  f"{c['score']:+.3f}" + ("  <- chosen" if c["rank"] == 0 else ""))
        folds = Counter(map(_band_label, summary["fold_band_settings"].values()))
        if folds:
            print("    chosen without each recording (for the expected false alarms): "
                  + ", ".join(f"{label} {n}x" for label, n in folds.most_common()))
    _print_false_alarms(summary, " (any band)")


def _print_margin(entry, pad):
    print(f"{pad}margin (leave-one-recording-out, one for all joints and regimes): "
          f"{entry['margin']:.3f}")


def _print_false_alarms(summary, which=""):
    if summary["false_alarms_per_hour"] is None:
        print(f"  expected false alarms{which} per hour: n/a (the nested figure needs >= 3 "
              "recordings)")
        return
    print(f"  expected false alarms{which}: {summary['n_false_alarms_nested']} alarm "
          f"onset(s) on left-out recordings in {summary['hours'] * 60:.1f} min = "
          f"{summary['false_alarms_per_hour']:.2f} per hour (nested leave-one-recording-"
          "out: each recording scored with margin"
          + (", levels and settings" if summary.get("selected")
             else ", levels and band" if summary.get("band_candidates") else " and levels")
          + " chosen without it)")


def _print_thresholds(entry, summary, pad):
    """The thresholds table(s) of ``entry`` (A, and Nm when known), one row per regime."""
    n = len(entry["thresholds_A"][0])
    units = [("A", entry["thresholds_A"])]
    if "thresholds_Nm" in entry:
        units.append((f"Nm, torque constants of {summary['robot']}", entry["thresholds_Nm"]))
    for unit, table in units:
        print(f"{pad}thresholds [{unit}]:")
        print(f"{pad}  " + f"{'regime':<10}" + "".join(f"{f'joint {j + 1}':>10}"
                                                        for j in range(n)))
        for name, row in zip(summary["regimes"], table):
            print(f"{pad}  " + f"{name:<10}" + "".join(f"{v:>10.3f}" for v in row))


# ---------------------------------------------------------------- monitor
def load_detector(path, trust_pickle=False):
    """Load a detector file written by ``gpcd calibrate``.

    Parameters
    ----------
    path : str or path-like
        ``.skops`` (or ``.joblib`` / ``.pkl``) file.
    trust_pickle : bool, default=False
        Load a ``.joblib`` / ``.pkl`` file (see :func:`sklearn_gpcd.load`).

    Returns
    -------
    detector : CollisionDetector or MultiBandDetector
        Fitted, thresholds chosen across recordings; a
        :class:`~sklearn_gpcd.detection.MultiBandDetector` when the file was
        calibrated with ``--band`` (then ``calibration["bands"]`` holds each
        band's settings, margin and thresholds).
    features : CausalFeatures
        Fitted on the calibration recordings (for
        :meth:`StreamingMonitor.update_raw
        <sklearn_gpcd.detection.StreamingMonitor.update_raw>`).
    calibration : dict
        What ``gpcd calibrate`` printed (margin, thresholds, false alarms).

    Raises
    ------
    ValueError
        If the file is not a detector file (e.g. a model from ``gpcd train``).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from sklearn_gpcd.persistence import save
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "not_a_detector.joblib"
    >>> _ = save({"kind": "something else"}, path)
    >>> load_detector(path, trust_pickle=True)
    Traceback (most recent call last):
    ...
    ValueError: ...not_a_detector.joblib: not a detector file written by gpcd calibrate...
    """
    from .persistence import load

    bundle = load(path, trust_pickle=trust_pickle)
    if not (isinstance(bundle, dict) and bundle.get("kind") == DETECTOR_KIND):
        raise ValueError(f"{path}: not a detector file written by gpcd calibrate (a model "
                         "from gpcd train goes through gpcd calibrate first)")
    return bundle["detector"], bundle["features"], bundle.get("calibration", {})


def _cmd_monitor(args):
    """``gpcd monitor``: alarm events through the causal streaming path.

    The loop is :class:`sklearn_gpcd.monitoring.MonitorSession`; the JSON
    report is written on every exit path once monitoring started (Ctrl-C and
    errors included), and the exit status is 3 when a live stream was blind
    at some time or ended abnormally.
    """
    from .cli import _one_line, _read_recordings
    from .monitoring import MonitorSession

    sources = sum([bool(args.recordings), args.replay is not None, args.rtde is not None])
    if sources != 1:
        raise ValueError("give recordings, --replay FILE or --rtde HOST (exactly one)")
    if args.plot is not None and args.rtde is not None:
        raise ValueError("--plot is for recordings and --replay, not --rtde")
    start = time.perf_counter()
    detector, features, calibration = load_detector(args.detector,
                                                    trust_pickle=args.trust_pickle)
    if args.plot is not None:
        Path(args.plot).mkdir(parents=True, exist_ok=True)
    live = args.rtde is not None or args.replay is not None
    session = MonitorSession(detector, features, hook=args.hook,
                             keep_series=args.plot is not None, echo=live,
                             stall_timeout=args.stall_timeout)
    session.band_labels = [_band_label(_band_settings(b.detector)) for b in session.bands]
    plots = []
    try:
        if args.rtde is not None:
            _monitor_rtde(args, session)
        else:
            paths = [args.replay] if args.replay is not None else args.recordings
            args.robot = None
            recordings = _read_recordings(paths, args, "recordings",
                                          progress=not (args.quiet or live))
            keys = _recording_keys(recordings)
            for key, rec in zip(keys, recordings):
                if rec.n_joints != session.monitor.n_joints:
                    raise ValueError(f"{rec.name}: {rec.n_joints} joints but the detector "
                                     f"has {session.monitor.n_joints}")
                session.run_recording(rec, key, duration=args.duration,
                                      speed=args.speed if args.replay is not None else None)
                if args.plot is not None:
                    plots.append(_plot(session, Path(args.plot), key))
    except BaseException as exc:  # the report on every exit path, then as before
        if session.recordings:
            session.finish()  # the open event, the summary so far
            session.end("interrupted" if isinstance(exc, KeyboardInterrupt)
                        else f"error: {_one_line(exc)}", abnormal=True)
            _write_report(args, session, calibration, plots)
        raise
    _print_events(session)
    stats = session.live_statistics() if live else None
    if stats is not None:
        print(f"  {stats['n_ticks']} ticks; latency receive -> decision p50 "
              f"{stats['latency_ms_p50']:.3f} ms, p99 {stats['latency_ms_p99']:.3f} ms, max "
              f"{stats['latency_ms_max']:.3f} ms; dropped samples {stats['dropped_samples']}; "
              f"decisions at most {stats['behind_stream_ms_max']:.1f} ms behind the stream's "
              "clock")
    if session.exit_status:
        blind = sum(f["blind_s"] or 0.0 for f in session.faults)
        print(f"  {session.n_blind} fault(s): blind {blind:.3f} s in total"
              + (f"; the stream ended abnormally: {session.end_reason}"
                 if session.abnormal_end else "") + f" (exit status {session.exit_status})")
    if args.json is not None:
        _write_report(args, session, calibration, plots)
        print(f"wrote {args.json}")
    for path in plots:
        if path is not None:
            print(f"wrote {path}")
    print(f"done in {time.perf_counter() - start:.1f} s")
    return session.exit_status


def _monitor_rtde(args, session):
    """``gpcd monitor --rtde``: connect, then :meth:`MonitorSession.run_rtde`."""
    from .io import RTDEClient

    if session.monitor.n_joints != 6:
        raise ValueError(f"RTDE streams 6 joints; the detector has "
                         f"{session.monitor.n_joints}")
    frequency = args.frequency or round(1.0 / session.sample_time, 6)
    client = RTDEClient(args.rtde, args.port, frequency)
    try:
        client.connect()
    except (OSError, ConnectionError) as exc:
        raise OSError(f"cannot start an RTDE stream from {args.rtde}:{args.port}: "
                      f"{exc}") from None
    print(f"monitoring {args.rtde}:{args.port} at {frequency:g} Hz (Ctrl-C stops)",
          flush=True)
    session.run_rtde(client, f"rtde://{args.rtde}:{args.port}", duration=args.duration,
                     reconnect_timeout=args.reconnect_timeout)


def _write_report(args, session, calibration, plots):
    """The JSON report of ``gpcd monitor`` (``--json``), if asked for."""
    if args.json is None:
        return
    report = {"detector": str(args.detector), "calibration": calibration,
              **session.report(), "figures": [str(p) for p in plots if p is not None]}
    if session.multiband:
        report["bands"] = session.band_labels
    Path(args.json).write_text(json.dumps(report, indent=2))


def _print_events(session):
    n_samples = sum(r["n_samples"] for r in session.recordings)
    n_faults = sum(r["n_sensor_faults"] for r in session.recordings)
    print(f"{len(session.events)} alarm event(s) in {len(session.recordings)} recording(s), "
          f"{n_samples} samples ({n_faults} sensor faults)")
    if session.multiband:
        for b, label in enumerate(session.band_labels, start=1):
            n_events = sum(b in e["bands"] for e in session.events)
            print(f"  band {b} ({label}) alarmed in {n_events} event(s)")
    if not session.events:
        return
    width = max(9, *(len(e["recording"]) for e in session.events))
    columns = [("recording", f"<{width}", lambda e: e["recording"]),
               ("start [s]", ">9", lambda e: f"{e['start_s']:.3f}"),
               ("end [s]", ">9", lambda e: f"{e['end_s']:.3f}"),
               ("joints", "<12", lambda e: ",".join(map(str, e["joints"]))),
               ("peak |m| [A]", ">12", lambda e: f"{e['peak_A']:.3f}"),
               ("delay [s]", ">9", lambda e: f"{e['delay_s']:.3f}")]
    if session.multiband:
        columns.insert(4, ("bands", "<6", lambda e: ",".join(map(str, e["bands"]))))
    print("  ".join(f"{name:{spec}}" for name, spec, _ in columns))
    for e in session.events:
        print("  ".join(f"{value(e):{spec}}" for _, spec, value in columns))


#: Line colours of the bands in a multi-band figure (C3, red, shades the events).
_BAND_COLORS = ("C0", "C2", "C4", "C1", "C5", "C6", "C8", "C9")


def _plot(session, folder, key):
    """One figure per recording, one axis per joint, alarm events shaded, alarms marked.

    One band: the monitoring signal and its per-regime thresholds [A]. Several
    bands: each band's ``|m|`` over its threshold (per regime), so that every
    band crosses at 1.
    """
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("gpcd monitor: warning: matplotlib is not installed; no figure",
              file=sys.stderr)
        return None
    import numpy as np

    s = session.series
    t = np.asarray(s["t"])
    signal, regime = np.asarray(s["signal"]), np.asarray(s["regime"], dtype=int)
    alarms = np.asarray(s["alarms"], dtype=bool)
    n = signal.shape[2] if signal.ndim == 3 else 0
    fig, axes = plt.subplots(max(n, 1), 1, figsize=(9, 1.6 * max(n, 1) + 0.8), sharex=True,
                             squeeze=False)
    events = [e for e in session.events if e["recording"] == key]
    draw = _draw_ratios if session.multiband else _draw_signal
    for j in range(n):
        ax = axes[j, 0]
        for k, e in enumerate(events):
            ax.axvspan(e["start_s"], e["end_s"], color="C3", alpha=0.15,
                       label="alarm event" if k == 0 else None)
        ax.set_ylabel(draw(ax, session, t, signal[:, :, j], regime, j), fontsize=8)
        if alarms[:, j].any():
            ax.plot(t[alarms[:, j]], np.zeros(alarms[:, j].sum()), "|", color="k", ms=8,
                    label="alarm")
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=6, loc="upper right")
    axes[-1, 0].set_xlabel("t [s]")
    fig.suptitle(f"{key}: " + ("each band's |m| over its threshold (per regime), alarms"
                               if session.multiband else
                               "causal monitoring signal, per-regime thresholds, alarms"),
                 fontsize=9)
    fig.tight_layout()
    path = folder / f"{Path(key).stem}.png"
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path


def _draw_signal(ax, session, t, signal, regime, j):
    """One band: joint ``j``'s signal and its thresholds ``+-`` (per regime); the y label."""
    ax.plot(t, signal[:, 0], lw=0.7, color="C0", label="monitoring signal m")
    band = session.thresholds[0][regime[:, 0], j]
    ax.plot(t, band, lw=0.7, color="C1",
            label="threshold (" + "/".join(session.regime_names) + ")")
    ax.plot(t, -band, lw=0.7, color="C1")
    return f"joint {j + 1} [A]"


def _draw_ratios(ax, session, t, signal, regime, j):
    """Several bands: joint ``j``'s ``|m| / threshold`` per band, and 1; the y label."""
    for b, label in enumerate(session.band_labels):
        ratio = abs(signal[:, b]) / session.thresholds[b][regime[:, b], j]
        ax.plot(t, ratio, lw=0.7, color=_BAND_COLORS[b % len(_BAND_COLORS)],
                label=f"band {b + 1} ({label})")
    ax.axhline(1.0, lw=0.7, ls="--", color="k", label="threshold")
    return f"joint {j + 1}\n|m| / threshold"
