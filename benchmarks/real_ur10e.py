"""Real-robot detection benchmark on the UR10e recordings of Mamedov et al.

Is a learned current model a better collision monitor than the residual the
robot already gives for free, ``i - i_des``? Every number here comes from
the causal path that can run on the robot (``CausalFeatures`` inputs,
``CollisionDetector`` with its causal filter, regimes and rest reference;
``StreamingMonitor`` gives the same decisions sample for sample), on
recordings the models and the thresholds never saw. Data:
github.com/shamilmamedov/dynamic_calibration (Mamedov et al., Frontiers in
Robotics and AI 2020), no redistribution licence: read in place, never
packaged.

Protocol
--------
1. **train** each model on the unloaded Fourier-excitation runs of
   ``identification_data`` except the held-out ones (``HELD_OUT``) and the
   two early files without the target current (the peer and SP_C need it);
   loaded runs are left out (the controller was not told the payload).
   Causal inputs, ``n_support`` rows per joint, Adam, ``random_state=seed``,
   through ``sklearn_gpcd.workflow.train_model`` -- the function of ``gpcd
   train``, so ``gpcd train --inputs causal --n-support N --optimizer adam
   --seed S`` gives the same model (``train_settings``; checked by
   ``tests/test_cli_monitor_real.py``).
2. **unseen collision-free set** ``C``: the held-out identification runs,
   the six ``jointwise_motion`` runs, ``ptp_10_points`` and the still poses
   ``p1 .. p10``.
3. **one rule for every monitor**, the model's or the robot's: residual,
   2 Hz causal low-pass, 5-sample debounce, a threshold per joint and per
   regime of the arm (moving / settling / rest, ``CollisionDetector(
   regimes=True, threshold="per_joint", false_alarm_rate=0)``: each level
   is the largest debounced excursion of the calibration data), times a
   ``margin``.
4. **margins by leave-one-recording-out**: the level of a (regime, joint)
   cell calibrated on ``C`` without ``r`` is exceeded on ``r`` by a factor;
   the cell's margin is the largest such factor over ``r`` (at least 1), so
   that no left-out recording would have alarmed. The operating point is
   ``CollisionDetector(margin=M)`` calibrated on all of ``C``. Every main
   monitor is calibrated by ``sklearn_gpcd.workflow.calibrate_detector``,
   the function of ``gpcd calibrate`` (``PLAIN``, ``REST``, ``SELECTED``,
   ``banded_options``: ``--rest-reference 0 --no-select``, ``--rest-reference
   5 --no-select``, ``--select``, and the bands' options).
5. **false alarms, nested**: for each ``r`` in ``C``, margins and levels are
   chosen as in 4 on ``C`` without ``r`` only, and the alarm onsets on ``r``
   counted: the false-alarm figure never saw ``r``, not even through the
   margin.
5b. **settings chosen the same way** (the "sel" monitors, ``gpcd calibrate
   --select``): settle time x rest reference over ``SELECT_GRID``; of the
   pairs with the fewest nested alarm onsets on the calibration recordings,
   the one with the smallest time-weighted thresholds at its own LORO
   margin; for the nested false alarms of ``r`` the pair is chosen without
   ``r`` too.
6. **events**: at the operating point, every
   labelled push of ``collision_push_pose`` scored (detected, delay) with
   the labels of ``benchmarks/labels/ur10e_events.json`` (made from the data
   by ``benchmarks/label_ur10e_events.py``, method inside the file).
7. **quasi-static nMSE** (Eq. 18) on p1..p10 and on ptp_10_points (the
   paper's per-joint split, and the rest phases: the whole arm still); for the rest-referenced monitors the prediction is the
   model's plus the rest reference (causal: it uses the current measured when
   the arm came to rest).

Monitors: ``i - i_des`` (the peer: ``ControllerCurrent``), P_f, SP_S, SP_P
(the paper's, on causal inputs), SP_C (``make_sp_c``: the controller's
current as mean, GP correction), the "+R" variants with the rest
re-reference (``rest_reference=REST_TAU``) and the "sel" variants of the
peer, P_f, SP_S and SP_C with settle time and rest reference chosen across
recordings (5b). The field's standard peer, the generalized-momentum
observer (``MomentumObserver(identify="all")``, identified on the training
runs, gains of ``mikhel1984/ext_observer``), is the detector's residual model
under the same rule, plain, "+R" and "sel" (``observer_rows``; on the 2020
task too). The "bands" monitors (our extension, ``BANDED``) run the
peer, SP_C and P_f~ (P_f with a smooth Coulomb column, ``COULOMB_WIDTH``)
with two alarm rules (a fast second band beside the rule's, alarm when
either fires) and the braking regime (``brake_limit`` at the training runs'
largest causal ``|qdd|``), calibrated with the fast band chosen among
``FAST_BANDS`` across the recordings (``gpcd calibrate --band-candidate``):
each recording's nested
false alarms are counted with the band, margins and levels chosen on the
other recordings alone; P_f~ on the 2020 task too, each file with the band
chosen on its own calibration pool.

Run::

    python benchmarks/real_ur10e.py [--quick] [--output DIR] [--data DIR]

It prints progress and reStructuredText tables and writes figures,
``real_ur10e.json`` and ``real_ur10e_tables.rst.inc`` into ``--output``.
Without the data it says so and exits 0.
"""

import argparse
import datetime
import json
import platform
import sys
import time
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import real_data_path, require_data, rst_table, write_json  # noqa: E402

from sklearn.base import clone  # noqa: E402
from sklearn.frozen import FrozenEstimator  # noqa: E402

from sklearn_gpcd.detection import (
    AlarmRule,
    CollisionDetector,
    MARGIN_RULES,
    REGIME_NAMES,
    Regimes,
    calibrate_across_recordings,
    nested_alarms,
    regime_excursions,
    regime_levels,
    stack_currents,
)
from sklearn_gpcd.detection import loro_margin as _loro_margin  # noqa: E402
from sklearn_gpcd.detection import nested_false_alarms as _nested_false_alarms  # noqa: E402
from sklearn_gpcd.workflow import band_label, band_settings  # noqa: E402
from sklearn_gpcd.dynamics import ControllerCurrent  # noqa: E402
from sklearn_gpcd.experiments.paper import Progress, split_nmse  # noqa: E402
from sklearn_gpcd.features import contiguous_segments  # noqa: E402
from sklearn_gpcd.io import RecordingWarning, load_recording  # noqa: E402
from sklearn_gpcd.metrics import alarm_onsets  # noqa: E402
from sklearn_gpcd.robots import load_robot  # noqa: E402
from sklearn_gpcd.workflow import (  # noqa: E402
    TrainedModel,
    acceleration_limit,
    calibrate_detector,
    train_model,
    training_set,
)

DATASET = "ur10e_mamedov"
IDENTIFICATION = "identification_data"
#: Unloaded identification runs held out of training: unseen collision-free data.
HELD_OUT = ("ur-20_02_19_15harm50sec.csv", "ur-20_02_06-20sec_5harm.csv",
            "ur-20_02_10-30sec_12harm.csv", "ur-19_12_23_free.csv")
PTP = "validation_data/ur-20_01_17-ptp_10_points.csv"
STILL = [f"validation_data/ur-20_01_17-p{k}.csv" for k in range(1, 11)]
JOINTWISE = [f"jointwise_motion/ur-20_01_22-joint_{k}.csv" for k in range(1, 7)]
PUSHES = ["collision_push_pose/ur-20_01_22-push_pose_1.csv",
          "collision_push_pose/ur-20_01_22-push_pose_2.csv"]
FAMILY_2020 = "collision_detection_data_2020"
COLLISIONS = [f"{FAMILY_2020}/collision_{k}.csv" for k in ("2link", "3link", "wrist")]
LABELS = Path(__file__).resolve().parent / "labels" / "ur10e_events.json"
SIGMA_V = 1e-2
FILTER_CUTOFF = 2.0   # Hz
MIN_DURATION = 5      # samples (50 ms at 100 Hz)
REST_TAU = 5.0        # s, time constant of the rest reference
PEER = "i - i_des"
#: Width [rad/s] of the smooth Coulomb column of the banded P_f monitor
#: (the braking study, retired at commit d324c58: results page).
COULOMB_WIDTH = 0.01
#: Settle time and rest reference [s] of the banded monitors on ``C``: SP_C
#: sel's choice across these recordings (``SP_C_SEL`` of the studies).
BANDED_SETTINGS = {"settle_time": 3.0, "rest_reference": 2.0}
#: Candidates of the banded monitors' fast band: (cut-off [Hz], filter order,
#: debounce [samples]); the one with the fewest nested alarm onsets of the
#: union, then the smallest thresholds, is chosen without the recording scored.
FAST_BANDS = ((4.0, 2, 5), (6.0, 1, 5), (8.0, 1, 3), (10.0, 1, 3), (10.0, 2, 3),
              (10.0, 1, 2), (15.0, 1, 3), (20.0, 1, 3))
BAND_CANDIDATES = [{"filter_cutoff": c, "filter_order": o, "min_duration": d}
                   for c, o, d in FAST_BANDS]
BAND_GRID = [{k: [v] for k, v in c.items()} for c in BAND_CANDIDATES]
#: The banded monitors: model name -> shown name.
BANDED = {PEER: PEER + " bands", "P_f~": "P_f~ bands", "SP_C": "SP_C bands"}
TABLES = "real_ur10e_tables.rst.inc"


def is_unloaded(name):
    """True for identification runs without payload ("unload" is unloaded).

    >>> [is_unloaded(n) for n in ("a-unload.csv", "b-load.csv", "c50secLoad.csv", "d.csv")]
    [True, False, False, True]
    """
    return "load" not in name.lower().replace("unload", "")


def load(path):
    """One recording; the loader's warnings about dropped rows are printed."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RecordingWarning)
        rec = load_recording(path)
    for w in caught:
        print(f"    note: {w.message}", flush=True)
    return rec


def split_recordings(root, quick):
    """Training runs, unseen collision-free recordings ``{key: Recording}``, left-out names."""
    train, left_out = [], []
    for f in sorted((root / IDENTIFICATION).glob("*.csv")):
        if not is_unloaded(f.name) or f.name in HELD_OUT:
            continue
        rec = load(f)
        (train if rec.target_current is not None else left_out).append(rec)
    if quick:
        train = train[::2]
    unseen = [f"{IDENTIFICATION}/{name}" for name in HELD_OUT] + JOINTWISE + [PTP] + STILL
    return train, {key: load(root / key) for key in unseen}, [r.name for r in left_out]


#: The benchmark's models and their ``gpcd train --model`` names.
MODELS = {"P_f": "p_f", "SP_S": "sp_s", "SP_P": "sp_p", "SP_C": "sp_c"}


def train_settings(n_support, seed, n_jobs):
    """How every model is trained: ``train_model``'s keywords (``gpcd train`` options)."""
    return dict(inputs="causal", n_support=n_support, optimizer="adam", seed=seed,
                n_jobs=n_jobs)


def train_models(data, n_support, seed, n_jobs, names=tuple(MODELS), progress=None):
    """The paper's three estimators and SP_C on one rule: ``sklearn_gpcd.workflow.train_model``.

    ``data`` is the :class:`~sklearn_gpcd.workflow.TrainingSet` of the training
    runs (causal inputs), shared by the models. Returns ``({name: regressor},
    {name: fit seconds})``; the function and settings are those of ``gpcd
    train --inputs causal --n-support N --optimizer adam --seed S``.
    """
    robot = load_robot("ur10e")
    models, seconds = {}, {}
    for name in names:
        tic = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            models[name] = train_model(data, robot, MODELS[name], sigma_v=(
                SIGMA_V if name == "SP_P" else None),
                **train_settings(n_support, seed, n_jobs)).regressor
        seconds[name] = time.perf_counter() - tic
        if progress is not None:
            progress(f"trained {name} in {seconds[name]:.1f} s")
    return models, seconds


def detector(regressor, rest_reference=None, margin=1.0, **regimes):
    """The one detection rule every monitor goes through (``regimes``: other
    settings of its regimes, e.g. ``settle_time``)."""
    rule = AlarmRule("per_joint", false_alarm_rate=0.0, margin=margin,
                     filter_cutoff=FILTER_CUTOFF, min_duration=MIN_DURATION,
                     regimes=Regimes(**{"settle_time": 0.5, **regimes},
                                     rest_reference=rest_reference))
    return CollisionDetector(FrozenEstimator(regressor), n_joints=6, sample_time="auto",
                             rules=rule)


#: The fast band the banded monitors start from, until calibration chooses it
#: from ``BAND_GRID``: 10 Hz first order with a 2-sample debounce.
FAST_BAND = {"filter_cutoff": 10.0, "filter_order": 1, "min_duration": 2}


def banded_detector(regressor, limit, **settings):
    """The rule with a fast second band and the braking regime (our extension).

    Two alarm rules -- the rule's own 2 Hz band and a fast band
    (``FAST_BAND``, until calibration chooses it from ``BAND_GRID``), alarm
    when either fires -- with ``brake_limit=limit`` (a regime of its own for
    the 0.5 s after a joint's causal ``|qdd|`` exceeds the largest of the
    training runs); ``settings``: the regimes' settle time and rest reference.
    """
    det = detector(regressor, brake_limit=limit, **settings)
    fast = clone(det.rules).set_params(**FAST_BAND)
    return det.set_params(rules=[det.rules, fast])


def band_text(rule):
    """A band's filter and debounce, as the tables show them (the CLI's wording).

    >>> band_text(AlarmRule(filter_cutoff=10.0, filter_order=1, min_duration=2))
    '10 Hz, order 1, debounce 2'
    """
    return band_label(band_settings(rule))


#: The main monitors' ``calibrate_detector`` options (``gpcd calibrate``): the
#: rule at its 0.5 s settle time without rest reference (plain), with the rest
#: reference ("+R"), and with both chosen from ``SELECT_GRID`` ("sel").
PLAIN = {"rest_reference": 0, "select": False}
REST = {"rest_reference": REST_TAU, "select": False}
SELECTED = {"select": True}


def trained_model(model, features):
    """A fitted ``model`` of the causal inputs ``features``, as ``train_model`` returns it."""
    return TrainedModel(regressor=model, features=features)


def banded_options(limit):
    """The banded monitors' ``calibrate_detector`` options: ``BANDED_SETTINGS``,
    braking above ``limit`` and a fast band chosen among ``FAST_BANDS``."""
    return {**BANDED_SETTINGS, "braking": limit, "band_candidates": BAND_CANDIDATES}


def monitor_result(trained, options, blocks, unseen, pushes, push_blocks, labels):
    """One monitor: ``calibrate_detector(trained, C, **options)`` (``gpcd
    calibrate``) on the unseen recordings ``C``, pushes scored at its
    operating point. ``margin`` is the first band's (per band with several
    bands), ``onsets_by_margin_rule`` the nested onsets of the chosen settings
    by every margin rule (one band; the union's by ``MARGIN_RULE`` with
    bands), ``band_thresholds`` every band's and ``fold_settings`` the
    fast band chosen without each recording."""
    calibrated, _ = _recipe(trained, list(unseen.values()), list(unseen), options)
    det, summary = calibrated.detector, calibrated.calibration
    times = times_of(unseen)
    series = band_series(det, blocks, times)
    alarms = [nested_alarms(s, MARGIN_RULE) for s in series]
    folds = {}
    for key, onsets in summary["nested_onsets_s"].items():
        t = times[key] - times[key][0]
        alarm = np.logical_or.reduce([a[key] for a in alarms])
        folds[key] = {"onsets": onsets, "hours": float(t[-1] / 3600.0),
                      "first_second_alarm_samples": int(alarm[t < 1.0].sum())}
    result = {"margin": det.rules_[0].margin, "thresholds": np.atleast_2d(det.thresholds_)}
    if "bands" not in summary:
        result["onsets_by_margin_rule"] = {
            rule: sum(len(f["onsets"]) for f in nested_false_alarms(series[0], unseen,
                                                                     rule).values())
            for rule in MARGIN_RULES}
        result["candidates"] = [dict(c, params=regime_params(c["params"]))
                                for c in summary["candidates"]] or None
        result["fold_settings"] = {k: regime_params(p)
                                   for k, p in summary["fold_settings"].items()} or None
    else:
        result = {
            "margin": np.array([band["margin"] for band in summary["bands"]]),
            "thresholds": result["thresholds"],
            "band_thresholds": [np.atleast_2d(rule.thresholds_) for rule in det.rules_],
            "bands": [band_text(rule) for rule in det.rules_],
            "brake_limit": options.get("braking"),
            "onsets_by_margin_rule": {MARGIN_RULE: summary["n_false_alarms_nested"]},
            "candidates": [dict(c, params=band_params(c["params"]))
                           for c in summary["band_candidates"]],
            "fold_settings": {k: band_params(s) for k, s in
                              summary["fold_band_settings"].items()} or None}
    return {**result, **operating_point(det, folds, pushes, push_blocks, labels)}


def regime_params(settings):
    """Regime settings of the calibration summary with the JSON keys of this benchmark.

    >>> regime_params({"settle_time_s": 3.0, "rest_reference_s": 2.0})
    {'settle_time': 3.0, 'rest_reference': 2.0}
    """
    return {k.removesuffix("_s"): v for k, v in settings.items()}


def band_params(settings):
    """:class:`AlarmRule` parameters of a band from ``band_settings``.

    >>> band_params({"filter_cutoff_hz": 10.0, "filter_order": 1, "debounce_samples": 2})
    {'filter_cutoff': 10.0, 'filter_order': 1, 'min_duration': 2}
    """
    return {"filter_cutoff": settings["filter_cutoff_hz"],
            "filter_order": settings["filter_order"],
            "min_duration": settings["debounce_samples"]}


def band_series(det, blocks, times):
    """:func:`regime_excursions` of each band of the fitted ``det`` (the others
    through a detector of that band alone, fitted on ``blocks``)."""
    series = [regime_excursions(det, blocks)]
    if len(det.rules_) > 1:
        keys = list(blocks)
        Z = np.concatenate([blocks[k] for k in keys])
        groups = np.repeat(np.arange(len(keys)), [len(blocks[k]) for k in keys])
        time = np.concatenate([times[k] for k in keys])
        for rule in det.rules[1:]:
            alone = clone(det).set_params(rules=rule).fit(Z, groups=groups, time=time)
            series.append(regime_excursions(alone, blocks))
    return series


def operating_point(det, folds, pushes, push_blocks, labels):
    """What every monitor's result holds besides its thresholds: the nested
    false alarms of ``folds``, the pushes scored at ``det``'s operating point
    (events, onsets outside them, delays, the monitoring signals) and the
    settle time and rest reference of its first rule."""
    events, outside, monitors = {}, {}, {}
    for key, rec in pushes.items():
        events[key], outside[key], monitors[key] = score_events(
            det, push_blocks[key], rec, labels[key]["events"])
    delays = [e["delay_s"] for v in events.values() for e in v if e["detected"]]
    regimes = det.rules_[0].regimes
    return {
        "folds": folds, "onsets": sum(len(f["onsets"]) for f in folds.values()),
        "first_second_alarm_samples": sum(
            f["first_second_alarm_samples"] for f in folds.values()),
        "events": events, "outside": outside,
        "n_events": sum(len(v) for v in events.values()),
        "n_detected": sum(e["detected"] for v in events.values() for e in v),
        "median_delay_s": float(np.median(delays)) if delays else None,
        "max_delay_s": float(np.max(delays)) if delays else None,
        "settle_time_s": regimes.settle_time, "rest_reference_s": regimes.rest_reference,
        "monitors": monitors, "detector": det,
    }


def times_of(recordings):
    """Time stamps of each recording, for ``calibrate_across_recordings``."""
    return {k: r.time for k, r in recordings.items()}


def excursions(det, blocks):
    """Per recording: debounced |m| (n, 6), regimes (n,), and the peak per (regime, joint)."""
    return regime_excursions(det, blocks)


def levels(peaks, keys):
    """Per (regime, joint) level of ``threshold="per_joint"`` on the recordings ``keys``."""
    return regime_levels(peaks, keys)


MARGIN_RULE = "global"


def loro_margin(peaks, keys, rule=MARGIN_RULE):
    """The largest factor by which a left-out recording exceeds the others' level."""
    return _loro_margin(peaks, keys, rule)


def nested_false_alarms(series, recordings, rule=MARGIN_RULE):
    """Alarm onsets on each recording with margins and levels chosen without it."""
    return _nested_false_alarms(series, {k: r.time for k, r in recordings.items()}, rule)


def score_events(det, block, rec, events, tail=0.5):
    """Per labelled event: detected, delay; alarm onsets outside the events."""
    mon = det.monitoring_signal(block)
    scored, outside = score_alarms(mon.alarms, rec.time - rec.time[0], events, tail)
    return scored, outside, mon


def score_alarms(alarms, t, events, tail=0.5):
    """``score_events`` on alarms (n, n_joints) at times ``t`` [s from the start].

    ``joints_fired`` needs per-joint alarms; with one column (any joint) it is
    left out.
    """
    per_joint = alarms.ndim == 2 and alarms.shape[1] > 1
    alarm = alarms.any(axis=1) if alarms.ndim == 2 else alarms
    scored, inside = [], np.zeros(len(t), dtype=bool)
    for ev in events:
        stop = ev.get("tail_stop_s", ev["stop_s"]) + tail
        window = (t >= ev["start_s"]) & (t <= stop)
        inside |= (t >= ev["start_s"] - tail) & (t <= stop)
        hits = np.flatnonzero(window & alarm)
        scored.append({
            "start_s": ev["start_s"], "stop_s": ev["stop_s"], "joints": ev["joints"],
            "detected": bool(hits.size),
            "delay_s": float(t[hits[0]] - ev["start_s"]) if hits.size else None,
        })
        if per_joint:
            scored[-1]["joints_fired"] = [int(j) + 1 for j in np.flatnonzero(
                alarms[window].any(axis=0))]
    outside = [o for o in alarm_onsets(alarm, t) if not inside[np.searchsorted(t, o)]]
    return scored, outside


def free_segments(rec, entry, guard=0.5, min_seconds=2.0):
    """Row ranges of ``rec`` away (``guard`` s) from its labelled and ambiguous events."""
    t = rec.time - rec.time[0]
    busy = np.zeros(len(t), dtype=bool)
    for ev in entry["events"] + entry.get("ambiguous", []):
        busy |= (t >= ev["start_s"] - guard) & (t <= ev.get("tail_stop_s", ev["stop_s"]) + guard)
    return [(a, b) for a, b in contiguous_segments(~busy) if t[b - 1] - t[a] >= min_seconds]


def family_calibration(key, blocks, times, inputs, recordings, segments):
    """Calibration data for collision file ``key`` of the 2020 task.

    ``blocks`` / ``times`` (the task's collision-free recording) plus the
    event-free segments of the *other* collision files, each segment its own
    recording (``"<file>#<i>"``), so that leave-one-recording-out treats
    them as separate recordings.
    """
    blocks, times = dict(blocks), dict(times)
    for other in COLLISIONS:
        if other == key:
            continue
        for i, (a, b) in enumerate(segments[other]):
            blocks[f"{other}#{i}"] = inputs[other][a:b]
            times[f"{other}#{i}"] = recordings[other].time[a:b]
    return blocks, times


def collision_family(root, train, labels, n_support, seed, n_jobs, progress,
                     rule=MARGIN_RULE, models=None, settings=None, banded=None):
    """Detection on collision_detection_data_2020 (no target current logged).

    Models on the state only (P_f, SP_S), trained on the training runs.
    For each collision file ``f``: thresholds from the collision-free data of
    the same repetitive task that ``f`` is not part of -- ``collision_free.csv``
    and the event-free segments of the *other* collision files -- margin by
    leave-one-recording-out (``rule``, one of ``MARGIN_RULES``), scored on
    ``f``: recall and delay on its labelled collisions, alarm onsets on its
    event-free segments. ``models`` maps names to regressors already trained
    on ``train`` (else P_f and SP_S are trained). ``settings`` maps a model
    name to detector settings (those its "sel" monitor chose on the unseen
    recordings): the model is scored again with them, as ``name + " sel"``.
    ``banded`` maps shown names to ``(model, braking limit)``:
    :func:`banded_detector` at the rule's settle time and rest reference,
    every band calibrated on the same data.
    """
    free = load(root / FAMILY_2020 / "collision_free.csv")
    recs = {key: load(root / key) for key in COLLISIONS}
    data = training_set(list(train), "causal", allow_missing=True)  # i_c is not logged there
    features = data.features
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the missing i_c block, filled with zeros
        inputs = {k: stack_currents(features.transform(r), r.current) for k, r in recs.items()}
        base_blocks = {"collision_free": stack_currents(features.transform(free), free.current)}
    unseen = {"collision_free": free}
    segments = {k: free_segments(r, labels[k]) for k, r in recs.items()}

    def score(template):
        files = {}
        for key, rec in recs.items():
            blocks, times = family_calibration(key, base_blocks, times_of(unseen), inputs,
                                               recs, segments)
            banded = len(template.alarm_rules()) > 1
            calibration = calibrate_across_recordings(
                template, blocks, times, rule=rule, param_grid=BAND_GRID if banded else None)
            margin = [np.max(band.margin) for band in calibration.bands]
            thresholds = calibration.detector.rules_[0].thresholds_
            det = calibration.detector
            events, _, mon = score_events(det, inputs[key], rec, labels[key]["events"])
            t = rec.time - rec.time[0]
            alarm = mon.alarms.any(axis=1)
            onsets = [o for a, b in segments[key] for o in alarm_onsets(alarm[a:b], t[a:b])]
            files[key] = {"events": events, "free_onsets": onsets,
                          "free_minutes": sum(t[b - 1] - t[a] for a, b in segments[key]) / 60,
                          "margin": float(np.max(margin)),
                          "thresholds": np.atleast_2d(thresholds)}
        hits = sum(e["detected"] for f in files.values() for e in f["events"])
        total = sum(len(f["events"]) for f in files.values())
        onsets = sum(len(f["free_onsets"]) for f in files.values())
        regimes = template.alarm_rules()[0].regimes
        return {"files": files, "n_detected": hits, "n_events": total, "free_onsets": onsets,
                "settle_time_s": regimes.settle_time,
                "rest_reference_s": regimes.rest_reference}

    out = {}
    for name in ("P_f", "SP_S") if models is None else models:
        tic = time.perf_counter()
        model = (train_models(data, n_support, seed, n_jobs, names=(name,))[0][name]
                 if models is None else models[name])
        variants = {name: {}}
        if settings and name in settings:
            variants[name + " sel"] = settings[name]
        for shown, params in variants.items():
            res = out[shown] = score(detector(model, **params))
            progress(f"{FAMILY_2020}, {shown}: {res['n_detected']}/{res['n_events']} labelled "
                     f"collisions detected, {res['free_onsets']} alarm onset(s) on the "
                     f"event-free segments ({time.perf_counter() - tic:.0f} s)")
    for shown, (model, limit) in (banded or {}).items():
        tic = time.perf_counter()
        res = out[shown] = score(banded_detector(model, limit))
        progress(f"{FAMILY_2020}, {shown}: {res['n_detected']}/{res['n_events']} labelled "
                 f"collisions detected, {res['free_onsets']} alarm onset(s) on the "
                 f"event-free segments ({time.perf_counter() - tic:.0f} s)")
    return out


#: The ``gpcd calibrate`` recipes scored through its function, by their options.
RECIPES = {"defaults": {}}
#: The recipes of the same-task table.
SAME_TASK_RECIPES = ("defaults",)


def _recipe(trained, recordings, keys, options):
    """:func:`~sklearn_gpcd.workflow.calibrate_detector` (``gpcd calibrate``) with
    ``options``; the calibration warnings are kept with the result."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        calibrated = calibrate_detector(trained, recordings, keys=keys, **options)
    messages = sorted({str(w.message) for w in caught
                       if w.category.__name__ == "CalibrationWarning"})
    return calibrated, messages


def _recipe_result(calibrated, messages):
    summary = calibrated.calibration
    return {"nested_onsets": summary["n_false_alarms_nested"], "margin": summary["margin"],
            "settle_time_s": summary["settle_time_s"],
            "rest_reference_s": summary["rest_reference_s"],
            "thresholds": np.atleast_2d(calibrated.detector.thresholds_),
            "warnings": messages}


def same_task_recipes(data, models, unseen, pushes, labels, progress):
    """The same task through ``gpcd calibrate``'s function: P_f, SP_S and SP_C
    calibrated on the unseen recordings by ``SAME_TASK_RECIPES``, the pushes
    monitored; nested onsets, pushes detected, delays."""
    out = {}
    for name in ("P_f", "SP_S", "SP_C"):
        trained = trained_model(models[name], data.features)
        for recipe in SAME_TASK_RECIPES:
            tic = time.perf_counter()
            calibrated, messages = _recipe(trained, list(unseen.values()), list(unseen),
                                           RECIPES[recipe])
            res = out[f"{name}, {recipe}"] = {
                **_recipe_result(calibrated, messages),
                **{k: v for k, v in operating_point(calibrated.detector, {}, pushes, {
                    k: stack_currents(data.features.transform(r), r.current)
                    for k, r in pushes.items()}, labels).items()
                   if k in ("events", "outside", "n_events", "n_detected", "median_delay_s",
                            "max_delay_s")}}
            progress(f"same task, {name}, gpcd calibrate {recipe}: {res['nested_onsets']} "
                     f"nested onset(s) on the {len(unseen)} unseen recordings, "
                     f"{res['n_detected']}/{res['n_events']} pushes detected, "
                     f"{sum(len(v) for v in res['outside'].values())} onset(s) outside them "
                     f"({time.perf_counter() - tic:.0f} s)")
    return out


def cross_task(root, train, unseen, labels, n_support, seed, n_jobs, progress):
    """Detection that transfers: the 2020 task scored with nothing of it tuned.

    What a user does with ``gpcd train --signals none`` / ``gpcd calibrate`` /
    ``gpcd monitor``: state-only models (P_f, SP_S: the 2020 logs have no
    target current) trained on the training runs, thresholds chosen by
    :func:`~sklearn_gpcd.workflow.calibrate_detector` (``RECIPES``) on the
    unseen collision-free recordings plus the 2020 task's own
    ``collision_free.csv``, then every 2020 collision file monitored: recall
    and delay on its labelled collisions, alarm onsets on its event-free
    segments, and the nested false alarms of the calibration.
    """
    free = load(root / FAMILY_2020 / "collision_free.csv")
    recs = {key: load(root / key) for key in COLLISIONS}
    calibration = [*unseen.values(), free]
    keys = [*unseen, "collision_free"]
    data = training_set(list(train), "causal", signals=())
    out = {}
    for name in ("P_f", "SP_S"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            trained = train_model(data, load_robot("ur10e"), MODELS[name],
                                  **train_settings(n_support, seed, n_jobs))
        for recipe, options in RECIPES.items():
            tic = time.perf_counter()
            calibrated, messages = _recipe(trained, calibration, keys, options)
            det, features = calibrated.detector, calibrated.features
            files = {}
            for key, rec in recs.items():
                block = stack_currents(features.transform(rec), rec.current)
                t = rec.time - rec.time[0]
                alarms = det.monitoring_signal(block).alarms
                events, _ = score_alarms(alarms, t, labels[key]["events"])
                alarm = alarms.any(axis=1)
                segments = free_segments(rec, labels[key])
                files[key] = {
                    "events": events,
                    "free_onsets": [o for a, b in segments
                                    for o in alarm_onsets(alarm[a:b], t[a:b])],
                    "free_minutes": sum(t[b - 1] - t[a] for a, b in segments) / 60}
            res = out[f"{name}, {recipe}"] = {
                "files": files,
                "n_detected": sum(e["detected"] for f in files.values() for e in f["events"]),
                "n_events": sum(len(f["events"]) for f in files.values()),
                "free_onsets": sum(len(f["free_onsets"]) for f in files.values()),
                **_recipe_result(calibrated, messages),
            }
            progress(f"cross-task, {name}, gpcd calibrate {recipe}: {res['n_detected']}/"
                     f"{res['n_events']} labelled 2020 collisions detected, "
                     f"{res['free_onsets']} alarm onset(s) on their event-free segments, "
                     f"{res['nested_onsets']} nested onset(s) on the {len(keys)} calibration "
                     f"recordings, margin {res['margin']:.2f} ({time.perf_counter() - tic:.0f} s)")
    return out


#: The momentum observer's row (issue 36): ``MomentumObserver(identify="all")``
#: with the gains of ``mikhel1984/ext_observer`` (not tuned).
OBSERVER = "observer"


def fit_observer(train, features, identify="all"):
    """The momentum observer identified on the training runs (every row of each
    run, causal inputs; each run its own recording; ``identify`` as
    ``MomentumObserver``), stepping by the runs' median sampling period (a
    detector passes no time stamps)."""
    from sklearn_gpcd.dynamics import MomentumObserver

    X = [features.transform(r) for r in train]
    groups = np.concatenate([np.full(len(x), k) for k, x in enumerate(X)])
    period = float(np.median(np.concatenate([np.diff(r.time) for r in train])))
    return MomentumObserver("ur10e", identify=identify, sample_time=period).fit(
        np.vstack(X), np.vstack([r.current for r in train]), groups=groups)


def observer_rows(root, train, features, blocks, unseen, pushes, push_blocks, labels,
                  results, family, progress):
    """Add the momentum observer to ``results`` (and to ``family``, the 2020 task):
    the observer is the detector's residual model (``detector(observer)``, the
    rule of every monitor), calibrated by ``calibrate_across_recordings`` on
    the same blocks, plain, with the rest reference (``+R``) and with settle
    time and rest reference chosen across the recordings (``sel``), as the
    peer and the GP monitors are; the other rows are untouched."""
    tic = time.perf_counter()
    observer = fit_observer(train, features)
    progress(f"{OBSERVER}: identified on {len(train)} runs in {time.perf_counter() - tic:.1f} "
             f"s, sample time {observer.sample_time:g} s, residual RMS [A] "
             f"{np.round(observer.residual_std_, 3).tolist()}")
    # the rule of every monitor; "+R" and "sel" as for the peer and the GP monitors
    trained = trained_model(observer, features)
    variants = {OBSERVER: PLAIN, OBSERVER + " +R": REST, OBSERVER + " sel": SELECTED}
    for name, options in variants.items():
        tic = time.perf_counter()
        res = results[name] = monitor_result(trained, options, blocks, unseen, pushes,
                                             push_blocks, labels)
        progress(f"{name}: settle {res['settle_time_s']:g} s, rest reference "
                 f"{seconds_text(res['rest_reference_s'], unit=' s')}; {res['onsets']} alarm "
                 f"onset(s) on unseen collision-free data (nested LORO; by margin rule "
                 f"{res['onsets_by_margin_rule']}), {res['n_detected']}/{res['n_events']} "
                 "pushes detected, "
                 f"{sum(len(v) for v in res['outside'].values())} alarm onset(s) outside them "
                 f"({time.perf_counter() - tic:.0f} s)")
    if family is not None:
        chosen = {OBSERVER: {"settle_time": results[OBSERVER + " sel"]["settle_time_s"],
                             "rest_reference": results[OBSERVER + " sel"]["rest_reference_s"]}}
        family.update(collision_family(root, train, labels, None, None, None, progress,
                                       models={OBSERVER: observer}, settings=chosen))


def rest_referenced_prediction(model, block, rest_reference, settle_time=0.5):
    """Causal prediction incl. the rest reference (unfiltered monitor), for nMSE."""
    rule = AlarmRule("per_joint", false_alarm_rate=0.0,
                     regimes=Regimes(settle_time=settle_time, rest_reference=rest_reference))
    det = CollisionDetector(FrozenEstimator(model), n_joints=6, sample_time=0.01, rules=rule)
    mon = det.fit(block).monitoring_signal(block)
    return mon.predicted + (0.0 if mon.reference is None else mon.reference)


# ----------------------------------------------------------------- figures
def _pyplot():
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    return plt


def plot_push(rec, events, monitors, path, joints=(0, 1, 2)):
    """Monitoring signal and thresholds of two monitors on one push file."""
    plt = _pyplot()
    if plt is None:
        return None
    t = rec.time - rec.time[0]
    fig, axes = plt.subplots(len(joints), len(monitors), figsize=(6.5 * len(monitors), 7),
                             sharex=True, squeeze=False)
    for col, (name, (mon, det)) in enumerate(monitors.items()):
        thr = np.atleast_2d(det.thresholds_)
        for row, j in enumerate(joints):
            ax = axes[row, col]
            for k, ev in enumerate(events):
                ax.axvspan(ev["start_s"], ev["stop_s"], color="0.85",
                           label="labelled push" if k == 0 else None)
            ax.plot(t, mon.signal[:, j], lw=0.8, color="C0", label="monitoring signal m")
            band = thr[mon.regime, j]
            ax.plot(t, band, color="C3", lw=0.8, label="threshold (per regime)")
            ax.plot(t, -band, color="C3", lw=0.8)
            fired = mon.alarms[:, j]
            if fired.any():
                ax.plot(t[fired], np.zeros(fired.sum()), "|", color="k", ms=10, label="alarm")
            ax.set_ylabel(f"joint {j + 1} [A]", fontsize=8)
            if row == 0:
                ax.set_title(name, fontsize=10)
            ax.tick_params(labelsize=8)
        axes[0, col].legend(fontsize=7, loc="upper right")
    axes[-1, 0].set_xlabel("t [s]")
    fig.suptitle(f"{Path(rec.name).stem}: causal path, thresholds from unseen collision-free "
                 "recordings", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return Path(path)


def plot_thresholds(thresholds, path):
    """Thresholds per joint for moving and rest, each monitor vs the peer."""
    plt = _pyplot()
    if plt is None:
        return None
    names = list(thresholds)
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.2), sharey=True)
    for ax, regime in zip(axes, ("moving", "rest")):
        g = REGIME_NAMES.index(regime)
        x = np.arange(6)
        width = 0.8 / len(names)
        for k, name in enumerate(names):
            ax.bar(x + (k - len(names) / 2 + 0.5) * width, thresholds[name][g], width,
                   label=name)
        ax.set_xticks(x, [f"j{j + 1}" for j in x])
        ax.set_title(f"threshold at the operating point, {regime}", fontsize=10)
        ax.grid(axis="y", alpha=0.3)
    axes[0].set_ylabel("sigma_CD [A]")
    axes[1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return Path(path)


# -------------------------------------------------------------------- main
def parse_args(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=None,
                        help="UR10e data folder (default: $GPCD_REAL_DATA/ur10e_mamedov or "
                             "../shared/data/real/ur10e_mamedov next to the repository)")
    parser.add_argument("--output", default="real_ur10e_results",
                        help="folder for the figures, the JSON and the tables")
    parser.add_argument("--quick", action="store_true",
                        help="half of the training runs and n_support=300")
    parser.add_argument("--n-support", type=int, default=None,
                        help="posterior support rows per joint (default 1000, quick 300)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--n-jobs", type=int, default=2, help="joints fitted in parallel")
    return parser.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    root = real_data_path(DATASET, args.data)
    require_data(root, "UR10e recordings (Mamedov et al.)",
                 [IDENTIFICATION, PTP, *STILL, *JOINTWISE, *PUSHES])
    n_support = args.n_support or (300 if args.quick else 1000)
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    progress = Progress()
    labels = json.loads(LABELS.read_text())["files"]
    progress(f"real UR10e detection benchmark ({'quick' if args.quick else 'full'}): data "
             f"{root}, n_support {n_support}, seed {args.seed}, labels {LABELS.name}")

    train, unseen, no_ic = split_recordings(root, args.quick)
    pushes = {key: load(root / key) for key in PUSHES}
    data = training_set(list(train), "causal")
    features = data.features
    hours = sum(r.duration for r in unseen.values()) / 3600.0
    progress(f"training on {len(train)} runs ({len(data.y)} rows, causal inputs, signals "
             f"{features.signals_}); left out without target current: {no_ic}; unseen "
             f"collision-free: {len(unseen)} recordings, {hours * 60:.1f} min")

    models = {PEER: ControllerCurrent(6)}
    trained, fit_seconds = train_models(data, n_support, args.seed, args.n_jobs,
                                        progress=progress)
    models.update(trained)
    models[PEER].fit(data.X, data.y)

    blocks = {k: stack_currents(features.transform(r), r.current) for k, r in unseen.items()}
    push_blocks = {k: stack_currents(features.transform(r), r.current) for k, r in pushes.items()}
    # name -> (model, calibrate_detector options)
    monitors = {name: (model, PLAIN) for name, model in models.items()}
    monitors[PEER + " +R"] = (models[PEER], REST)
    monitors["SP_C +R"] = (models["SP_C"], REST)
    for name in (PEER, "P_f", "SP_S", "SP_C"):
        monitors[name + " sel"] = (models[name], SELECTED)

    # -- margins by leave-one-recording-out, nested false alarms, events -------
    results = {}
    for name, (model, options) in monitors.items():
        tic = time.perf_counter()
        res = results[name] = monitor_result(trained_model(model, features), options,
                                             blocks, unseen, pushes, push_blocks, labels)
        by_rule = res["onsets_by_margin_rule"]
        tau_text = seconds_text(res["rest_reference_s"], unit=" s")
        chosen = (f"settings chosen: settle {res['settle_time_s']:g} s, rest reference "
                  f"{tau_text}; " if options is SELECTED else "")
        progress(f"{name}: {chosen}{res['onsets']} alarm onset(s) on unseen collision-free "
                 f"data (nested LORO; by margin rule {by_rule}), {res['n_detected']}/"
                 f"{res['n_events']} pushes detected, "
                 f"{sum(len(v) for v in res['outside'].values())} alarm onset(s) outside them "
                 f"({time.perf_counter() - tic:.0f} s)")

    # -- a fast second band and the braking regime (our extension) ---------------
    limit = acceleration_limit(data)
    tic = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        models["P_f~"] = train_model(data, load_robot("ur10e"), "p_f",
                                     coulomb_width=COULOMB_WIDTH,
                                     **train_settings(n_support, args.seed, args.n_jobs)).regressor
    progress(f"trained P_f~ (P_f, Coulomb tanh(qd / {COULOMB_WIDTH:g})) in "
             f"{time.perf_counter() - tic:.1f} s; banded monitors: the rule's band and a fast "
             f"band chosen from {len(FAST_BANDS)} across the recordings, braking above "
             f"{limit:.2f} rad/s^2 (the largest causal |qdd| of the "
             f"training runs), settle {BANDED_SETTINGS['settle_time']:g} s, rest reference "
             f"{BANDED_SETTINGS['rest_reference']:g} s")
    for name, shown in BANDED.items():
        tic = time.perf_counter()
        res = results[shown] = monitor_result(
            trained_model(models[name], features), banded_options(limit), blocks, unseen,
            pushes, push_blocks, labels)
        chosen = Counter(band_text(AlarmRule(**s)) for s in res["fold_settings"].values())
        progress(f"{shown}: fast band {res['bands'][-1]} (chosen on all; in the nested "
                 f"folds {dict(chosen)}); {res['onsets']} alarm onset(s) of the union of the "
                 f"bands on unseen collision-free data (nested LORO), {res['n_detected']}/"
                 f"{res['n_events']} pushes detected, "
                 f"{sum(len(v) for v in res['outside'].values())} alarm onset(s) outside them "
                 f"({time.perf_counter() - tic:.0f} s)")

    # -- collision_detection_data_2020: no target current, state-only models -----
    family = None
    if all((root / key).exists() for key in COLLISIONS):
        chosen = {name: {"settle_time": results[name + " sel"]["settle_time_s"],
                         "rest_reference": results[name + " sel"]["rest_reference_s"]}
                  for name in ("P_f", "SP_S")}
        family = collision_family(root, train, labels, n_support, args.seed, args.n_jobs,
                                  progress, settings=chosen,
                                  banded={BANDED["P_f~"]: (models["P_f~"], limit)})

    # -- the momentum observer, the field's standard peer (issue 36) -------------
    observer_rows(root, train, features, blocks, unseen, pushes, push_blocks, labels, results,
                  family, progress)

    # -- gpcd calibrate's function: same task and cross-task (issue 38) ----------
    recipes = same_task_recipes(data, models, unseen, pushes, labels, progress)
    transfer = None
    if all((root / key).exists() for key in COLLISIONS):
        transfer = cross_task(root, train, unseen, labels, n_support, args.seed, args.n_jobs,
                              progress)

    # -- quasi-static nMSE ---------------------------------------------------
    nmse = {}
    tests = {"p1..p10": STILL, "ptp_10_points": [PTP]}
    for name, (model, *_) in monitors.items():
        tau, settle = results[name]["rest_reference_s"], results[name]["settle_time_s"]
        nmse[name] = {}
        for test, keys in tests.items():
            y = np.concatenate([unseen[k].current for k in keys])
            qd = np.concatenate([unseen[k].qd for k in keys])
            if tau is None:
                pred = np.concatenate([model.predict(blocks[k][:, :-6]) for k in keys])
            else:
                pred = np.concatenate([rest_referenced_prediction(model, blocks[k], tau, settle)
                                       for k in keys])
            nmse[name][test] = split_nmse(y, pred, qd, SIGMA_V)["quasi_static"]
            arm_still = np.repeat(np.all(np.abs(qd) < SIGMA_V, axis=1)[:, None], 6, axis=1)
            nmse[name][f"{test}, arm at rest"] = split_nmse(
                y, pred, qd, SIGMA_V, rows=arm_still)["quasi_static"]
    progress("quasi-static nMSE done")

    # -- report ----------------------------------------------------------------
    report = report_tables(results, nmse, unseen, family, recipes, transfer)
    print("\n" + report, flush=True)
    (out / TABLES).write_text(report)
    figures = {}
    thr = {n: r["thresholds"] for n, r in results.items()}
    if (path := plot_thresholds(thr, out / "real_ur10e_thresholds.png")):
        figures["thresholds"] = path.name
    for key, rec in pushes.items():
        shown = {n: (results[n]["monitors"][key], results[n]["detector"])
                 for n in (PEER, "SP_C +R")}
        stem = Path(key).stem
        if (path := plot_push(rec, labels[key]["events"], shown,
                              out / f"real_ur10e_{stem}.png")):
            figures[stem] = path.name
    summary = {
        "command": " ".join(["python", "benchmarks/real_ur10e.py", *(argv or sys.argv[1:])]),
        "date": datetime.date.today().isoformat(),
        "machine": f"{platform.machine()}, {platform.python_version()}",
        "mode": "quick" if args.quick else "full", "data": str(root),
        "n_support": n_support, "seed": args.seed, "sigma_v": SIGMA_V,
        "filter_cutoff_hz": FILTER_CUTOFF, "min_duration": MIN_DURATION,
        "rest_reference_s": REST_TAU, "margin_rule": MARGIN_RULE,
        "train_files": [r.name for r in train], "held_out": HELD_OUT,
        "unseen_collision_free": {k: float(r.duration) for k, r in unseen.items()},
        "unseen_minutes": hours * 60, "fit_seconds": fit_seconds,
        "labels": str(LABELS.name), "figures": figures, "nmse_quasi_static": nmse,
        "monitors": {n: {k: v for k, v in r.items() if k not in ("monitors", "detector")}
                     for n, r in results.items()},
        "collision_detection_data_2020": family,
        "same_task_recipes": recipes,
        "cross_task": transfer,
    }
    summary["elapsed_s"] = progress.elapsed
    write_json(out / "real_ur10e.json", summary)
    progress(f"wrote {out / 'real_ur10e.json'}, {out / TABLES} and {len(figures)} figure(s); "
             f"total {progress.elapsed:.0f} s")
    return summary


def same_rule_peer(monitor):
    """The peer's monitor calibrated by the same rule as ``monitor``.

    >>> [same_rule_peer(n) for n in ("SP_C", "SP_C +R", "SP_C sel", "P_f~ bands")]
    ['i - i_des', 'i - i_des +R', 'i - i_des sel', 'i - i_des bands']
    """
    for suffix in (" +R", " sel", " bands"):
        if monitor.endswith(suffix):
            return PEER + suffix
    return PEER


def settings_text(result):
    """A result's settle time and rest reference [s], as the tables show them.

    >>> settings_text({"settle_time_s": 3.0, "rest_reference_s": None})
    '3, none'
    """
    return f"{result['settle_time_s']:g}, {seconds_text(result['rest_reference_s'])}"


def seconds_text(value, unit=""):
    """A duration that may be off (None), e.g. the rest reference.

    >>> seconds_text(None), seconds_text(2.0, unit=" s")
    ('none', '2 s')
    """
    return "none" if value is None else f"{value:g}{unit}"


def report_tables(results, nmse, unseen, family=None, recipes=None, transfer=None):
    """The benchmark's tables as reStructuredText."""
    minutes = sum(r.duration for r in unseen.values()) / 60.0
    header = ["monitor", "settle, rest ref. [s]", "margin (max)", "onsets on unseen",
              "pushes detected", "median delay [s]", "max delay [s]",
              "onsets outside pushes", "alarm samples in 1st s"]
    rows = [[n, settings_text(r),
             f"{np.max(r['margin']):.2f}", r["onsets"],
             f"{r['n_detected']}/{r['n_events']}",
             "n/a" if r["median_delay_s"] is None else f"{r['median_delay_s']:.2f}",
             "n/a" if r["max_delay_s"] is None else f"{r['max_delay_s']:.2f}",
             sum(len(v) for v in r["outside"].values()), r["first_second_alarm_samples"]]
            for n, r in results.items()]
    text = [f"Alarm onsets on {len(unseen)} unseen collision-free recordings ({minutes:.1f} "
            "min), each scored with margins and levels (and, for the 'sel' monitors, "
            "settle time and rest reference) chosen without it (nested "
            "leave-one-recording-out); pushes at the operating point (margins by "
            "leave-one-recording-out on all of them)", "", rst_table(header, rows), ""]
    peer = results[PEER]["thresholds"]
    jh = [f"joint {j + 1}" for j in range(6)]
    for regime in ("moving", "rest"):
        g = REGIME_NAMES.index(regime)
        rows = [[n] + [f"{v:.2f} ({v / p:.2f}x)" for v, p in zip(r["thresholds"][g], peer[g])]
                for n, r in results.items()]
        text += [f"Thresholds at the operating point, {regime} [A] (ratio to {PEER})", "",
                 rst_table(["monitor"] + jh, rows), ""]
    rows = []
    for n, r in results.items():
        same = same_rule_peer(n)
        # moving and rest rows only: the settling stages differ with the settle time
        base = [REGIME_NAMES.index(g) for g in ("moving", "rest")]
        ratio = (np.asarray(r["thresholds"])[base]
                 / np.asarray(results[same]["thresholds"])[base])
        rows.append([n, same] + [f"{v:.2f}x" for g in range(len(base)) for v in ratio[g, :3]])
    text += ["Thresholds relative to the robot's residual calibrated with the same rule "
             "(settle time, rest reference, selection): issue 14's bar is at most 0.8x "
             "moving and 0.5x at rest on joints 1-3", "",
             rst_table(["monitor", "peer, same rule"]
                       + [f"{g} j{j + 1}" for g in ("moving", "rest") for j in range(3)], rows),
             ""]
    banded = [n for n, r in results.items() if "band_thresholds" in r]
    if banded:
        rows = []
        for n in banded:
            peer = results[same_rule_peer(n)]
            for b, (band, thr) in enumerate(zip(results[n]["bands"],
                                                results[n]["band_thresholds"])):
                # a ratio only where the peer calibrated the same band
                same = peer["bands"][b] == band
                ratio = thr / peer["band_thresholds"][b]
                rows.append([n, band] + [
                    f"{thr[g, j]:.2f}" + (f" ({ratio[g, j]:.2f}x)" if same else "")
                    for g in map(REGIME_NAMES.index, ("moving", "rest")) for j in range(3)])
        limit = results[banded[0]]["brake_limit"]
        text += ["Banded monitors (our extension: a fast second band, alarm when either band "
                 f"fires, and a braking regime above {limit:.2f} rad/s^2), each band's "
                 "thresholds [A] and their ratio to the robot's residual in the same band "
                 "(where the peer chose the same fast band); onsets above count the union "
                 "of the bands", "",
                 rst_table(["monitor", "band"] + [f"{g} j{j + 1}" for g in ("moving", "rest")
                                                  for j in range(3)], rows), ""]
    sets = list(next(iter(nmse.values())))
    rows = [[n] + list(nmse[n][test]) for test in sets for n in nmse]
    names = [f"{n}, {test}" for test in sets for n in nmse]
    rows = [[label] + row[1:] for label, row in zip(names, rows)]
    text += ["Quasi-static nMSE (Eq. 18), unseen recordings: abs(qd_l) < sigma_v per joint (the "
             "paper's split), and rows with the whole arm at rest", "",
             rst_table(["monitor, test set"] + jh, rows), ""]
    header = ["monitor", "file", "push [s]", "labelled joints", "detected", "delay [s]",
              "joints fired"]
    rows = []
    for n in (PEER, "SP_C +R"):
        for key, evs in results[n]["events"].items():
            for e in evs:
                rows.append([n, Path(key).stem, f"{e['start_s']:.2f}-{e['stop_s']:.2f}",
                             ",".join(map(str, e["joints"])), "yes" if e["detected"] else "NO",
                             "n/a" if e["delay_s"] is None else f"{e['delay_s']:.2f}",
                             ",".join(map(str, e["joints_fired"])) or "-"])
    text += ["Labelled pushes (benchmarks/labels/ur10e_events.json)", "",
             rst_table(header, rows), ""]
    if family:
        header = ["model", "settle, rest ref. [s]", "file", "collisions detected",
                  "delays [s]", "event-free [min]", "alarm onsets there", "margin"]
        rows = []
        for name, res in family.items():
            for key, f in res["files"].items():
                delays = [e["delay_s"] for e in f["events"] if e["detected"]]
                rows.append([name, settings_text(res), Path(key).stem,
                             f"{sum(e['detected'] for e in f['events'])}/{len(f['events'])}",
                             " ".join(f"{d:.2f}" for d in delays) or "-",
                             f"{f['free_minutes']:.2f}", len(f["free_onsets"]),
                             f"{f['margin']:.2f}"])
        text += [f"{FAMILY_2020} (no target current: state-only models; thresholds from "
                 "collision_free.csv and the event-free segments of the other collision "
                 "files, margin by leave-one-recording-out)", "", rst_table(header, rows), ""]
    if recipes:
        header = ["model, gpcd calibrate", "settle, rest ref. [s]", "margin",
                  "nested onsets on unseen", "pushes detected", "median delay [s]",
                  "onsets outside pushes"]
        rows = [[name, settings_text(res), f"{res['margin']:.2f}", res["nested_onsets"],
                 f"{res['n_detected']}/{res['n_events']}",
                 "n/a" if res["median_delay_s"] is None else f"{res['median_delay_s']:.2f}",
                 sum(len(v) for v in res["outside"].values())] for name, res in recipes.items()]
        text += [f"Same task through gpcd calibrate (calibrate_detector on the {len(unseen)} "
                 "unseen recordings; defaults: settle time and rest reference chosen across "
                 "them)", "", rst_table(header, rows), ""]
    if transfer:
        header = ["model, gpcd calibrate", "settle, rest ref. [s]", "margin",
                  "nested onsets (calibration)", "2020 collisions detected",
                  "median delay [s]", "onsets on 2020 event-free segments"]
        rows = []
        for name, res in transfer.items():
            delays = [e["delay_s"] for f in res["files"].values() for e in f["events"]
                      if e["detected"]]
            rows.append([name, settings_text(res), f"{res['margin']:.2f}",
                         res["nested_onsets"], f"{res['n_detected']}/{res['n_events']}",
                         f"{np.median(delays):.2f}" if delays else "n/a", res["free_onsets"]])
        text += [f"Cross-task: the {FAMILY_2020} files monitored with nothing of that task "
                 "tuned (gpcd train --signals none, gpcd calibrate on the unseen "
                 "recordings plus its collision_free.csv, gpcd monitor)", "",
                 rst_table(header, rows), ""]
    return "\n".join(text)


if __name__ == "__main__":
    main()
