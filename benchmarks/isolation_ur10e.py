"""The momentum observer beside ``i - i_des``, and isolation on the real UR10e.

Data: the UR10e recordings of Mamedov et al. (github.com/shamilmamedov/
dynamic_calibration; no redistribution licence: read in place, never
packaged), split exactly as ``benchmarks/real_ur10e.py`` splits them (its
``split_recordings``: training runs, the unseen collision-free set ``C``),
labels from ``benchmarks/labels/ur10e_events.json``.

1. **The observer** (:class:`sklearn_gpcd.dynamics.MomentumObserver`, gains
   :data:`~sklearn_gpcd.dynamics.UR_OBSERVER_GAINS`, not tuned) is fitted on
   the training runs (causal inputs of ``CausalFeatures``, as every model of
   the real benchmark): ``identify="all"`` (base inertial parameters, rotor
   inertias and friction, like P_f) and ``identify="friction"`` (friction and
   rotor inertia on the nominal UR10e model) are both reported, nothing is
   chosen between them.
2. **Same rule as every monitor**: the observer's residual current is run
   through the benchmark's own detector (``real_ur10e.detector``: 2 Hz
   causal low-pass, 5-sample debounce, a threshold per joint and regime,
   ``threshold="per_joint", false_alarm_rate=0``) and calibrated by the
   package's ``calibrate_across_recordings`` (leave-one-recording-out margin,
   nested false alarms) on ``C``, beside the peer ``i - i_des``. The
   observer is the detector's residual model itself (the detector passes it
   the measured currents, ``sklearn_gpcd.detection.reads_currents``; it
   steps by the training runs' median period, ``real_ur10e.fit_observer``).
   The GP monitors P_f, SP_C and SP_C +R (rest reference ``REST_TAU``),
   trained by ``real_ur10e.train_models`` as the real benchmark trains them
   (``--n-support``, ``--seed``; ``--no-gp`` leaves them out), go through
   the same rule. Printed: thresholds per joint and regime in A and Nm
   (times the torque constants), every monitor's thresholds over the
   observer's, nested false alarms, the labelled pushes of
   ``collision_push_pose`` detected and their delays.
3. **Isolation on the 2020 collision files** (named by the link hit:
   ``2link``, ``3link``, ``wrist``; no target current is logged, so the
   observer is the only monitor of the two that runs there): thresholds
   from the collision-free data of the same task that the file is not part
   of (``real_ur10e.family_calibration``: ``collision_free.csv`` and the
   event-free segments of the other two files), each detected labelled
   collision isolated by :func:`sklearn_gpcd.contact.isolate_contact` on the
   monitoring signal over the event window (onset to ``tail_stop`` + 0.5 s,
   the window the benchmark scores detection in) against the thresholds of
   each sample's regime. Printed: the share attributed to the right link
   group (acceptance: 90 %), the confusion, and a force estimate per event
   at the link's frame (:func:`sklearn_gpcd.contact.estimate_force`, no
   ground truth: shown, not scored).

Run::

    python benchmarks/isolation_ur10e.py [--quick] [--no-gp] [--data DIR] [--output DIR]

Without the data it says so and exits 0.
"""

import argparse
import json
import sys
import time
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import real_data_path, require_data, rst_table, write_json  # noqa: E402
from real_ur10e import (  # noqa: E402
    COLLISIONS,
    DATASET,
    FAMILY_2020,
    LABELS,
    MARGIN_RULE,
    PEER,
    PUSHES,
    REST_TAU,
    detector,
    family_calibration,
    fit_observer,
    free_segments,
    load,
    operating_point,
    score_alarms,
    split_recordings,
    times_of,
    train_models,
)

from sklearn_gpcd.contact import estimate_force, isolate_contact  # noqa: E402
from sklearn_gpcd.detection import calibrate_across_recordings, stack_currents  # noqa: E402
from sklearn_gpcd.dynamics import ControllerCurrent  # noqa: E402
from sklearn_gpcd.experiments.paper import Progress  # noqa: E402
from sklearn_gpcd.robots import load_robot  # noqa: E402
from sklearn_gpcd.workflow import training_set  # noqa: E402

#: The observer variants reported (``identify`` of MomentumObserver).
OBSERVERS = {"observer (all)": "all", "observer (friction)": "friction"}
#: Link group of each 2020 collision file, from its name.
TRUE_GROUP = {f"{FAMILY_2020}/collision_2link.csv": "link 2",
              f"{FAMILY_2020}/collision_3link.csv": "link 3",
              f"{FAMILY_2020}/collision_wrist.csv": "wrist"}
TAIL = 0.5  # s after tail_stop_s, the scoring window of real_ur10e.score_alarms
#: GP monitors trained as the real benchmark trains them (``train_models``).
GP_MODELS = ("P_f", "SP_C")
#: The observer whose thresholds the GP monitors are compared with.
REFERENCE = "observer (all)"


def fit_observers(train, features, progress):
    """Both observer variants, identified on the training runs
    (``real_ur10e.fit_observer``)."""
    out = {}
    for name, identify in OBSERVERS.items():
        tic = time.perf_counter()
        out[name] = fit_observer(train, features, identify)
        progress(f"{name}: fitted in {time.perf_counter() - tic:.1f} s; residual RMS on the "
                 f"training runs [A] {np.round(out[name].residual_std_, 3).tolist()}")
    return out


def threshold_rows(name, det, k_tau):
    """Table rows: per regime, the thresholds in A and Nm of each joint."""
    rows = []
    for regime, values in zip(det.regime_names_, np.atleast_2d(det.thresholds_)):
        rows.append([name, regime, "A", *[float(v) for v in values]])
        rows.append([name, regime, "Nm", *[float(v) for v in values * k_tau]])
    return rows


def unseen_comparison(observers, features, unseen, pushes, labels, models, progress):
    """Peer, GP models and observers through the benchmark's rule on ``C``; pushes
    scored. ``models`` maps names to ``(regressor, rest reference)``; the
    observers are residual models like the others."""
    blocks = {k: stack_currents(features.transform(r), r.current) for k, r in unseen.items()}
    push_blocks = {k: stack_currents(features.transform(r), r.current)
                   for k, r in pushes.items()}
    monitors = dict(models)
    monitors.update({name: (obs, None) for name, obs in observers.items()})
    results = {}
    for name, (model, tau) in monitors.items():
        tic = time.perf_counter()
        calibration = calibrate_across_recordings(detector(model, tau), blocks,
                                                  times_of(unseen), rule=MARGIN_RULE)
        res = operating_point(calibration.detector, calibration.folds, pushes,
                              push_blocks, labels)
        res["margin"] = float(np.max(calibration.margin))
        res["hours"] = calibration.hours
        results[name] = res
        delays = res["median_delay_s"]
        progress(f"{name}: {res['onsets']} alarm onset(s) on the unseen collision-free "
                 f"recordings (nested LORO, {calibration.hours * 60:.1f} min), "
                 f"{res['n_detected']}/{res['n_events']} pushes detected, median delay "
                 f"{'n/a' if delays is None else f'{delays * 1000:.0f} ms'}, margin "
                 f"{res['margin']:.2f} ({time.perf_counter() - tic:.0f} s)")
    return results


def isolation_2020(root, train, observer, labels, progress):
    """The observer on the 2020 task: detection and isolation of the labelled collisions."""
    robot = load_robot("ur10e")
    k_tau = np.asarray(robot.torque_constants)
    data = training_set(list(train), "causal", allow_missing=True)  # i_c is not logged there
    features = data.features
    free = load(root / FAMILY_2020 / "collision_free.csv")
    recs = {key: load(root / key) for key in COLLISIONS}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the missing i_c block, filled with zeros
        inputs = {k: stack_currents(features.transform(r), r.current) for k, r in recs.items()}
        base = {"collision_free": stack_currents(features.transform(free), free.current)}
    segments = {k: free_segments(r, labels[k]) for k, r in recs.items()}
    std_torque = observer.residual_std_ * k_tau
    files = {}
    for key, rec in recs.items():
        blocks, times = family_calibration(key, base, times_of({"collision_free": free}),
                                           inputs, recs, segments)
        calibration = calibrate_across_recordings(detector(observer), blocks, times,
                                                  rule=MARGIN_RULE)
        det = calibration.detector
        mon = det.monitoring_signal(inputs[key])
        t = rec.time - rec.time[0]
        scored, _ = score_alarms(mon.alarms, t, labels[key]["events"], TAIL)
        thresholds = np.atleast_2d(det.thresholds_)[mon.regime]
        events = []
        for event, score in zip(labels[key]["events"], scored):
            window = np.flatnonzero((t >= event["start_s"])
                                    & (t <= event.get("tail_stop_s", event["stop_s"]) + TAIL))
            out = isolate_contact(mon.signal[window], thresholds[window])
            # force at the sample where the whitened residual torque peaks
            torque = -mon.residual[window] * k_tau
            peak = window[np.argmax(np.linalg.norm(torque / std_torque, axis=1))]
            force = estimate_force(robot, rec.q[peak], -mon.residual[peak] * k_tau,
                                   link=out.link, torque_std=std_torque)
            events.append({"start_s": event["start_s"], "detected": score["detected"],
                           "delay_s": score["delay_s"], "link": out.link, "group": out.group,
                           "confidence": out.confidence,
                           "significance": out.significance.round(2).tolist(),
                           "labelled_joints": event["joints"],
                           "force_N": force.magnitude, "force_std_N": force.magnitude_std,
                           "force_rank": force.rank, "force_condition": force.condition})
        detected = [e for e in events if e["detected"]]
        right = sum(e["group"] == TRUE_GROUP[key] for e in detected)
        files[key] = {"events": events, "n_events": len(events), "n_detected": len(detected),
                      "n_right_group": right, "true_group": TRUE_GROUP[key],
                      "groups": dict(Counter(e["group"] for e in detected)),
                      "thresholds": np.atleast_2d(det.thresholds_),
                      "regimes": list(det.regime_names_)}
        progress(f"{Path(key).name}: {len(detected)}/{len(events)} labelled collisions "
                 f"detected; isolated to {TRUE_GROUP[key]}: {right}/{len(detected)}; groups "
                 f"{files[key]['groups']}")
    return files


def report(results, files, k_tau):
    text = ["Observer beside i - i_des on the unseen collision-free recordings (same rule, "
            "nested LORO)", ""]
    rows = [[name, r["onsets"], f"{r['n_detected']}/{r['n_events']}",
             "n/a" if r["median_delay_s"] is None else round(r["median_delay_s"] * 1000),
             round(r["margin"], 2)] for name, r in results.items()]
    text.append(rst_table(["monitor", "nested false alarms", "pushes detected",
                           "median delay [ms]", "margin"], rows))
    text += ["", "Thresholds per joint and regime (A, and Nm = A x torque constant)", ""]
    rows = []
    for name, r in results.items():
        rows += threshold_rows(name, r["detector"], k_tau)
    text.append(rst_table(["monitor", "regime", "unit", *[f"joint {j}" for j in range(1, 7)]],
                          rows))
    if REFERENCE in results:
        text += ["", f"Thresholds over those of {REFERENCE}, per joint and regime "
                 "(below 1: more sensitive than the observer)", ""]
        ref = np.atleast_2d(results[REFERENCE]["detector"].thresholds_)
        rows = []
        for name, r in results.items():
            if name == REFERENCE:
                continue
            det = r["detector"]
            for regime, values in zip(det.regime_names_, np.atleast_2d(det.thresholds_) / ref):
                rows.append([name, regime, *[round(float(v), 2) for v in values]])
        text.append(rst_table(["monitor", "regime", *[f"joint {j}" for j in range(1, 7)]],
                              rows))
    if files:
        text += ["", "Isolation on the 2020 collision files (observer (all))", ""]
        rows = [[Path(k).name, f["true_group"], f"{f['n_detected']}/{f['n_events']}",
                 f"{f['n_right_group']}/{f['n_detected']}", json.dumps(f["groups"])]
                for k, f in files.items()]
        right = sum(f["n_right_group"] for f in files.values())
        detected = sum(f["n_detected"] for f in files.values())
        rows.append(["all", "", f"{detected}/{sum(f['n_events'] for f in files.values())}",
                     f"{right}/{detected} = {100 * right / max(detected, 1):.0f} %", ""])
        text.append(rst_table(["file", "link hit", "detected", "right group",
                               "groups attributed"], rows))
        text += ["", "Per event (detected): isolated link, confidence, force at the link "
                 "frame", ""]
        rows = []
        for key, f in files.items():
            for e in f["events"]:
                if e["detected"]:
                    rows.append([Path(key).stem.replace("collision_", ""), e["start_s"],
                                 e["link"], round(e["confidence"], 2),
                                 " ".join(f"{s:g}" for s in e["significance"]),
                                 f"{e['force_N']:.0f} +- {e['force_std_N']:.0f}",
                                 e["force_rank"]])
        text.append(rst_table(["file", "onset [s]", "link", "confidence",
                               "peak |m| / threshold, joints 1-6", "force [N]", "rank"], rows))
    return "\n".join(text)


def parse_args(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=None,
                        help="UR10e data folder (default: $GPCD_REAL_DATA/ur10e_mamedov)")
    parser.add_argument("--output", default=None, help="folder for isolation_ur10e.json")
    parser.add_argument("--quick", action="store_true", help="half of the training runs")
    parser.add_argument("--no-gp", action="store_true",
                        help="leave out the GP monitors (P_f, SP_C, SP_C +R)")
    parser.add_argument("--n-support", type=int, default=1000,
                        help="posterior support rows per joint of the GP models")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--n-jobs", type=int, default=2, help="joints fitted in parallel")
    return parser.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    root = real_data_path(DATASET, args.data)
    require_data(root, "UR10e recordings (Mamedov et al.)", PUSHES)
    progress = Progress()
    labels = json.loads(LABELS.read_text())["files"]
    train, unseen, _ = split_recordings(root, args.quick)
    pushes = {key: load(root / key) for key in PUSHES}
    data = training_set(list(train), "causal")
    features = data.features
    progress(f"training runs {len(train)}, unseen collision-free {len(unseen)}")
    observers = fit_observers(train, features, progress)
    models = {PEER: (ControllerCurrent(6).fit(data.X, data.y), None)}
    if not args.no_gp:
        trained, _ = train_models(data, args.n_support, args.seed, args.n_jobs,
                                        names=GP_MODELS, progress=progress)
        models.update({name: (trained[name], None) for name in GP_MODELS})
        models["SP_C +R"] = (trained["SP_C"], REST_TAU)
    results = unseen_comparison(observers, features, unseen, pushes, labels, models, progress)
    files = None
    if all((root / key).exists() for key in COLLISIONS):
        files = isolation_2020(root, train, observers["observer (all)"], labels, progress)
    k_tau = np.asarray(load_robot("ur10e").torque_constants)
    text = report(results, files, k_tau)
    print("\n" + text, flush=True)
    if args.output:
        out = Path(args.output)
        out.mkdir(parents=True, exist_ok=True)
        for r in results.values():
            r.pop("monitors", None)
            r["thresholds"] = np.atleast_2d(r.pop("detector").thresholds_)
        write_json(out / "isolation_ur10e.json", {"unseen": results, "collisions_2020": files})
        (out / "isolation_ur10e_tables.rst.inc").write_text(text + "\n")


if __name__ == "__main__":
    main()
