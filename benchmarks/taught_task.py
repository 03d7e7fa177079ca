"""A taught task on the real UR10e (issue 45): collision_detection_data_2020.

Protocol (what ``gpcd train`` / ``gpcd calibrate`` / ``gpcd teach`` /
``gpcd monitor`` do, through their library functions):

1. Global model, trained once per robot on the UR10e identification runs of
   ``benchmarks/real_ur10e.py`` (unloaded, with a target current, its four
   held-out runs excluded): P_f on the state alone (the 2020 task logs no
   target current), ``gpcd train --model p_f --signals none``.
2. Calibration, once per robot, on the unseen collision-free recordings of
   ``real_ur10e.py`` (4 held-out identification runs, 6 joint-wise runs,
   ptp_10_points, p1-p10): ``gpcd calibrate`` defaults. Nothing of the
   2020 task.
3. Teaching on ``collision_free.csv`` alone (18 s): ``gpcd teach``
   defaults.
4. Monitoring every 2020 collision file through the causal streaming path
   (:meth:`StreamingMonitor.replay_recording
   <sklearn_gpcd.detection.StreamingMonitor.replay_recording>`): per
   labelled collision (``benchmarks/labels/ur10e_events.json``), detected
   or not, its delay and the number of alarm onsets inside it; alarm
   onsets on the files' event-free segments; the share of untaught motion;
   each alarm event (``sklearn_gpcd.contact.describe_alarms``) with its
   link and its force through the Jacobian (torque = residual x the
   UR10e's torque constants).

Peers, on the same data by the same rules: the same detector untaught, and
the momentum observer (``MomentumObserver(identify="all")`` identified on
the same training runs) calibrated and taught the same way. ``i - i_des``
cannot run on this task (no target current is logged).

Which data each choice was made on is in the results page
(docs/results_taught_task.rst). Run::

    python benchmarks/taught_task.py --output DIR

It skips cleanly (exit 0) without the data.
"""

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's package
sys.path.insert(0, str(Path(__file__).resolve().parent))

import real_ur10e as R  # noqa: E402
from _common import real_data_path, require_data  # noqa: E402

from sklearn_gpcd.contact import describe_alarms, protected_force  # noqa: E402
from sklearn.utils import Bunch  # noqa: E402

from sklearn_gpcd.detection import StreamingMonitor, TaughtTask, stack_currents  # noqa: E402
from sklearn_gpcd.metrics import alarm_onsets  # noqa: E402
from sklearn_gpcd.robots import load_robot  # noqa: E402
from sklearn_gpcd.workflow import (  # noqa: E402
    calibrate_detector, teach_task, train_model, training_set)

#: Seconds after a labelled collision's end still counted as its own.
TAIL = 0.5
#: Rate [Hz] at which "protected at <= X N" is evaluated along a recording.
PROTECTION_RATE = 10.0
#: The collision file whose protection is plotted.
PLOT_FILE = "collision_detection_data_2020/collision_2link.csv"


def protection(out, rec, robot):
    """``protected_force`` at the flange along ``rec`` (every 1/PROTECTION_RATE s):
    the thresholds that decided each tick, in Nm through the torque constants."""
    step = max(1, int(round(1.0 / PROTECTION_RATE / np.median(np.diff(rec.time)))))
    rows = np.arange(0, rec.n_samples, step)
    force = protected_force(robot, rec.q[rows],
                            np.asarray(out.thresholds)[rows] * robot.torque_constants)
    moving = np.asarray(out.regime)[rows] == 0
    taught = np.asarray(out.taught)[rows]
    return {"t": (rec.time[rows] - rec.time[0]).tolist(), "force_N": force.tolist(),
            "taught": taught.tolist(), "moving": moving.tolist()}


def _quiet(fn, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*args, **kwargs)


def held_alarms(alarms, events_open):
    """``alarms`` with each open event's rows carrying the joints that fired last, so
    that ``describe_alarms`` sees one run per event."""
    held = alarms.copy()
    for k in range(1, len(held)):
        if events_open[k] and not held[k].any():
            held[k] = held[k - 1]
    return held


def causal_outputs(calibrated, rec):
    """Alarms, residual, regime and taught rows of ``rec``: the streaming path
    (``gpcd monitor``'s), or for a model that it cannot run tick by tick (the
    momentum observer, a dynamic filter) the detector's batch methods, which are
    causal too (causal inputs, causal filters)."""
    det, features = calibrated.detector, calibrated.features
    try:
        monitor = StreamingMonitor(det, features=features)
    except ValueError:
        X = stack_currents(_quiet(features.transform, rec), rec.current)
        if isinstance(det, TaughtTask):
            res = det.monitoring_signal(X)
            general = det.detector.monitoring_signal(X)
            regime = np.asarray(general.regime).reshape(len(X))
            applied = np.where(res.joints, det.thresholds_,
                               np.atleast_2d(det.detector.thresholds_)[regime])
            return Bunch(alarms=res.alarms, residual=res.residual,
                         regime=np.where(res.moving, 0, 1), taught=res.taught, event=res.event,
                         event_onset=res.event_onset, thresholds=applied)
        res = det.monitoring_signal(X)
        regime = np.asarray(res.regime).reshape(len(X))
        return Bunch(alarms=res.alarms, residual=res.residual, regime=res.regime,
                     taught=np.zeros(len(X), dtype=bool), event=res.event,
                     event_onset=res.event_onset, thresholds=np.atleast_2d(det.thresholds_)[regime])
    return _quiet(monitor.replay_recording, rec)


def score_file(calibrated, rec, entry, robot):
    """Replay ``rec`` causally; per labelled collision and per alarm event."""
    tic = time.perf_counter()
    out = causal_outputs(calibrated, rec)
    seconds = time.perf_counter() - tic
    t = rec.time - rec.time[0]
    alarms = out.alarms
    # one event per contact: an event holds until the signal stays below release
    events_open = out.event | alarms.any(axis=1)
    onsets = alarm_onsets(events_open, t, new=out.event_onset)
    collisions = []
    for ev in entry["events"]:
        stop = ev.get("tail_stop_s", ev["stop_s"]) + TAIL
        window = (t >= ev["start_s"]) & (t <= stop)
        hits = np.flatnonzero(window & alarms.any(axis=1))
        collisions.append({
            "start_s": ev["start_s"], "stop_s": ev["stop_s"], "joints": ev["joints"],
            "detected": bool(hits.size),
            "delay_s": float(t[hits[0]] - ev["start_s"]) if hits.size else None,
            "onsets": int(sum(ev["start_s"] <= o <= stop for o in onsets))})
    segments = R.free_segments(rec, entry)
    free = [float(o) for a, b in segments for o in alarm_onsets(alarms[a:b].any(axis=1), t[a:b])]
    det = calibrated.detector
    if isinstance(det, TaughtTask):   # the contact is what the task reference leaves
        inputs = _quiet(calibrated.features.transform, rec)
        signal, thresholds = out.residual - det.reference(inputs), det.thresholds_
    else:
        signal = out.residual - np.nanmedian(out.residual, axis=0)
        thresholds = np.atleast_2d(det.thresholds_)[0]   # the moving row
    events = describe_alarms(held_alarms(alarms, events_open), signal, thresholds, time=t,
                             robot=robot, q=rec.q, torque=signal * robot.torque_constants)
    for e in events:
        for k in ("significance", "force_rank"):
            e.pop(k, None)
    moving = out.regime == 0
    return {"collisions": collisions, "free_onsets": free,
            "protection": protection(out, rec, robot),
            "free_minutes": sum(t[b - 1] - t[a] for a, b in segments) / 60,
            "taught_share": float(out.taught.mean()),
            "untaught_motion_share": float((moving & ~out.taught).mean()),
            "events": events, "monitor_seconds": seconds, "samples": int(rec.n_samples)}


def plot_protection(results, labels, path, key=PLOT_FILE):
    """Protected force along one collision file, untaught and taught (P_f)."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    fig, ax = plt.subplots(figsize=(9, 3))
    for shown, style in (("P_f untaught", "C7"), ("P_f taught", "C0")):
        if shown not in results:
            continue
        p = results[shown]["files"][key]["protection"]
        force = np.where(np.asarray(p["moving"]), np.asarray(p["force_N"]), np.nan)
        ax.plot(p["t"], force, lw=0.8, color=style, label=shown + " (moving)")
    for k, ev in enumerate(labels[key]["events"]):
        ax.axvspan(ev["start_s"], ev["stop_s"], color="C3", alpha=0.2,
                   label="labelled collision" if k == 0 else None)
    ax.set_yscale("log")
    ax.set_ylabel("protected at <= X [N]")
    ax.set_xlabel("t [s]")
    ax.set_title(f"{key}: smallest force at the flange always caught", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path


def summarise(files):
    cols = [c for f in files.values() for c in f["collisions"]]
    delays = [c["delay_s"] for c in cols if c["detected"]]
    return {"n_collisions": len(cols), "n_detected": sum(c["detected"] for c in cols),
            "one_event_each": sum(c["onsets"] == 1 for c in cols),
            "max_onsets_in_a_collision": max(c["onsets"] for c in cols),
            "median_delay_s": float(np.median(delays)) if delays else None,
            "max_delay_s": float(np.max(delays)) if delays else None,
            "free_onsets": sum(len(f["free_onsets"]) for f in files.values()),
            "free_minutes": sum(f["free_minutes"] for f in files.values()),
            "events_with_link_and_force": sum(
                "link" in e and np.isfinite(e.get("force_N", np.nan))
                for f in files.values() for e in f["events"]),
            # a force at the link's frame on the joint axis (link 1) cannot be seen
            "events_with_well_conditioned_force": sum(
                bool(e.get("force_well_conditioned")) for f in files.values()
                for e in f["events"]),
            "n_events": sum(len(f["events"]) for f in files.values()),
            **protection_summary(files)}


def protection_summary(files):
    """Median and 90th percentile of the protected force [N] over the moving time,
    taught and untaught (finite values; the share of moving time never protected)."""
    out = {}
    for name, pick in (("taught", True), ("untaught", False)):
        force = np.concatenate([np.asarray(f["protection"]["force_N"])[
            np.asarray(f["protection"]["moving"]) & (np.asarray(f["protection"]["taught"])
                                                     == pick)] for f in files.values()])
        finite = force[np.isfinite(force)]
        out[f"protected_N_{name}_median"] = float(np.median(finite)) if finite.size else None
        out[f"protected_N_{name}_p90"] = (float(np.percentile(finite, 90)) if finite.size
                                          else None)
        out[f"protected_{name}_samples"] = int(force.size)
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", default=None, help="the ur10e_mamedov folder")
    parser.add_argument("--output", default="taught_task", help="folder for the results")
    parser.add_argument("--n-support", type=int, default=500)
    args = parser.parse_args(argv)
    root = real_data_path("ur10e_mamedov", args.data)
    require_data(root, "the UR10e recordings of Mamedov et al.", [R.FAMILY_2020])
    out_dir = Path(args.output)
    out_dir.mkdir(parents=True, exist_ok=True)
    labels = json.loads(R.LABELS.read_text())["files"]
    robot = load_robot("ur10e")
    train, unseen, _ = R.split_recordings(root, quick=False)
    free = R.load(root / R.FAMILY_2020 / "collision_free.csv")
    recs = {k: R.load(root / k) for k in R.COLLISIONS}
    timings, results = {}, {}

    tic = time.perf_counter()
    data = _quiet(training_set, list(train), "causal", signals=())
    pf = _quiet(train_model, data, robot, "p_f", **R.train_settings(args.n_support, 0, None))
    timings["train_p_f_s"] = time.perf_counter() - tic
    tic = time.perf_counter()
    observer = R.fit_observer(train, data.features)
    timings["identify_observer_s"] = time.perf_counter() - tic
    models = {"P_f": pf, "observer": R.trained_model(observer, data.features)}
    for name, trained in models.items():
        tic = time.perf_counter()
        calibrated = _quiet(calibrate_detector, trained, list(unseen.values()),
                            keys=list(unseen))
        timings[f"calibrate_{name}_s"] = time.perf_counter() - tic
        tic = time.perf_counter()
        taught = _quiet(teach_task, calibrated, [free], keys=["collision_free.csv"])
        timings[f"teach_{name}_s"] = time.perf_counter() - tic
        for shown, det in ((f"{name} untaught", calibrated), (f"{name} taught", taught)):
            files = {k: score_file(det, rec, labels[k], robot) for k, rec in recs.items()}
            results[shown] = {"summary": summarise(files), "files": files}
            if det is taught:
                results[shown]["teach"] = taught.calibration["teach"]
            s = results[shown]["summary"]
            ticks = sum(f["samples"] for f in files.values())
            secs = sum(f["monitor_seconds"] for f in files.values())
            s["monitor_us_per_tick"] = 1e6 * secs / ticks
            print(f"{shown}: {s['n_detected']}/{s['n_collisions']} collisions, "
                  f"{s['free_onsets']} onsets on {s['free_minutes']:.1f} min event-free, "
                  f"median delay {s['median_delay_s']}, one event each "
                  f"{s['one_event_each']}/{s['n_collisions']}, "
                  f"{s['monitor_us_per_tick']:.0f} us per tick", flush=True)
    report = {"command": " ".join(["python", "benchmarks/taught_task.py", *(argv or sys.argv[1:])]),
              "timings": timings, "results": results,
              "load_average": list(map(float, Path("/proc/loadavg").read_text().split()[:3]))
              if Path("/proc/loadavg").exists() else None}
    (out_dir / "taught_task.json").write_text(json.dumps(report, indent=1, default=float))
    lines = ["model / monitor          collisions  one event  onsets (event-free)  median delay [s]"
             "  untaught motion  events w/ link+force (well-conditioned)  us/tick"]
    for shown, res in results.items():
        s = res["summary"]
        untaught = np.mean([f["untaught_motion_share"] for f in res["files"].values()])
        delay = "-" if s["median_delay_s"] is None else f"{s['median_delay_s']:.3f}"
        lines.append(f"{shown:<24} {s['n_detected']:>4}/{s['n_collisions']:<5} "
                     f"{s['one_event_each']:>4}/{s['n_collisions']:<4} "
                     f"{s['free_onsets']:>4} in {s['free_minutes']:.1f} min      {delay:>8}"
                     f"        {100 * untaught:5.1f} %        {s['events_with_link_and_force']:>3}/"
                     f"{s['n_events']:<3} ({s['events_with_well_conditioned_force']:>2})"
                     f"                    {s['monitor_us_per_tick']:6.0f}")
    lines.append("")
    lines.append("protected at <= X N at the flange, over the moving time (10 Hz): "
                 "median / 90th percentile")
    for shown, res in results.items():
        s = res["summary"]
        cells = []
        for name in ("taught", "untaught"):
            med, p90 = s[f"protected_N_{name}_median"], s[f"protected_N_{name}_p90"]
            cells.append(f"{name} " + ("-" if med is None else f"{med:6.0f} / {p90:6.0f} N"))
        lines.append(f"  {shown:<24} " + "   ".join(cells))
    lines.append("timings [s]: " + ", ".join(f"{k} {v:.1f}" for k, v in timings.items()))
    plot_protection(results, labels, out_dir / "taught_task_protection.png")
    (out_dir / "taught_task.txt").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
