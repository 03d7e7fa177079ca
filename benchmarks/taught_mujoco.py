"""A taught task with little data on the MuJoCo second engine (issue 45).

Protocol, fixed with its seed (``SEED``) before this file was first run:

1. **Train** once, on the *nominal* MuJoCo plant of
   ``little_data_mujoco.py`` (``_mujoco_plant.py``, no injected effect):
   ``gpcd train --robot ur10`` with default flags on its identification-style
   logs (4 runs of 16 random flange targets).
2. **Calibrate** on ONE collision-free log of a cyclic task (4 waypoints at
   0.4 of the velocity limits, dwells of 0.5-4 s; ``little_data_mujoco``'s
   normal task): its first 2 min, ``gpcd calibrate`` defaults with
   ``--split 30`` (one log: the command's own advice).
3. **Teach** on the same 2-min log: ``gpcd teach`` defaults.
4. **Score** through the causal streaming path (``gpcd monitor``'s): (a) the
   same task, 2 x 150 s unseen logs (its waypoints, other dwells and noise):
   alarm onsets per hour; (b) other poses: 5 x 125 s collision-free logs of
   other waypoints: onsets per hour and the share of motion declared
   untaught; (c) 4 push logs of other waypoints, 4 pushes each (100-200 N on
   links 2-6, 0.5-1.5 s; ``little_data_mujoco.draw_pushes``): a push is
   caught by an alarm event that starts between its start and 1 s after its
   end, and its delay is from its start; events elsewhere in the push logs
   are false alarms (reported apart).
5. **Teach one cycle of each other pose** (9 logs: the waypoints of each
   free and push log, other dwells and noise, one cycle each) beside the
   2-min log, and score (b) and (c) again.

Peers on the same logs by the same rules (calibrated, taught and scored
alike): ``i - i_des`` (the plant logs the servo's target current) and the
momentum observer (identified on the training logs). Every monitor row
prints its untaught twin (the calibrated detector alone).

Run ``python benchmarks/taught_mujoco.py --output DIR`` (``--workdir`` keeps
the logs and the model; ``--reuse`` takes them from there). Needs ``pip
install mujoco`` (the ``second-engine`` extra); skips cleanly without it.
"""

import argparse
import json
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO))  # this checkout's package
sys.path.insert(0, str(HERE))

#: Fixed before the first run (issue 45, session 24); ``little_data_mujoco``
#: used 38. The development seed: the per-joint stiction gate and the tail
#: level of ``TaughtTask`` were chosen after its first run (3 onsets on the
#: same task, all where a joint was at |qd| < sigma_v or breaking away).
SEED = 4524
#: The scoring seed. 4525 scored session 24's design once (24/h on the same
#: task, 351/h on other poses: docs/results_taught_task.rst's history). 4526
#: was fixed (session 25) after the rest band and the untaught events' fix,
#: and after seed 4524 was rerun on them, before any run of its own. 4527 was
#: fixed (session 26) after the settling stages, and after seed 4524 was rerun
#: on them (0 onsets on the same task and other poses, 16/16), before any run
#: of its own; 4526 scored session 25's design once. 4527 scored the stages
#: once (0/h, 16/16, 4 events outside the pushes in the push logs, all in the
#: first settling stage); 4528 was fixed after the fading stages that
#: followed, before any run of its own. 4528 scored them once (other poses
#: 115/h: later stages set by one log); 4529 was fixed after the rule that
#: followed (a stage seen in one log alone takes the stage before), before
#: any run of its own. 4529 scored it once (other poses 57.6/h, all while
#: moving); 4530 was fixed (session 27) after the new-contact event onset and
#: the moving thresholds floored at the model's level on its left-out training
#: runs, before any run of its own. 4530 scored them once (other poses 40.3/h,
#: all in settling and at rest); 4531 was fixed (session 28) after every
#: regime's floor from the left-out training runs, and after seeds 4524,
#: 4528, 4529 and 4530 were rerun on it, before any run of its own.
SCORE_SEED = 4531
#: Calibration and teaching: the first ``TASK_SECONDS`` of the task log, cut in
#: pieces of ``SPLIT`` seconds for the calibration.
TASK_SECONDS, SPLIT = 120.0, 30.0
N_SAME, SAME_SECONDS = 2, 150.0
N_FREE, FREE_SECONDS = 5, 125.0
N_PUSH_LOGS = 4
#: One cycle of a pose: the 4 moves and dwells after the first rest.
CYCLE_MOVES = 4
CATCH_AFTER = 1.0


def _quiet(fn, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*args, **kwargs)


# -- logs -----------------------------------------------------------------------
def cycle_seconds(robot, seed, dwell_seed):
    """Length [s] of one cycle of the task of waypoint seed ``seed``: the first
    rest and ``CYCLE_MOVES`` moves with their dwells."""
    import little_data_mujoco as L

    ref = L.task_reference(robot, 120.0, seed, dwell_seed)  # the same first pieces
    return float(ref.phases[2 * CYCLE_MOVES]["stop"])


def simulate_log(setup, path, seconds, waypoint_seed, dwell_seed, pushes=0):
    """One nominal-plant log of the task of ``waypoint_seed`` into ``path``."""
    import little_data_mujoco as L
    from _mujoco_plant import Injection, simulate

    from sklearn_gpcd.io import write_rtde_csv

    robot, k, rotor = setup
    ref = L.task_reference(robot, seconds, waypoint_seed, dwell_seed)
    contacts = L.draw_pushes(robot, ref, dwell_seed, pushes) if pushes else ()
    rec = simulate(robot, k, rotor, Injection(), random_state=dwell_seed, name=path.stem,
                   reference=ref, contacts=contacts, log_targets=True)
    n = int(np.searchsorted(rec.time, seconds, side="right"))
    rec = rec.slice(0, n).replace(metadata={**rec.metadata, "robot": L.ROBOT})
    write_rtde_csv(rec, path, robot_comment=True)
    return {"path": str(path), "seconds": float(rec.duration),
            "waypoint_seed": waypoint_seed, "dwell_seed": dwell_seed,
            "pushes": rec.metadata.get("contacts", []) if pushes else []}


def make_logs(folder, setup, seed):
    """Every log of the protocol (``logs.json`` describes them)."""
    import little_data_mujoco as L

    folder.mkdir(parents=True, exist_ok=True)
    base = seed * 1000
    task = base + 1
    push_s = L.PUSH_FIRST + L.PUSHES_PER_LOG * L.PUSH_SLOT + 4.0
    logs = {"task": simulate_log(setup, folder / "task.csv", TASK_SECONDS, task, task),
            "same": [simulate_log(setup, folder / f"same_{i}.csv", SAME_SECONDS, task,
                                  base + 30 + i) for i in range(N_SAME)],
            "free": [simulate_log(setup, folder / f"free_{i}.csv", FREE_SECONDS,
                                  base + 10 + i, base + 10 + i) for i in range(N_FREE)],
            "push": [simulate_log(setup, folder / f"push_{i}.csv", push_s, base + 50 + i,
                                  base + 50 + i, pushes=L.PUSHES_PER_LOG)
                     for i in range(N_PUSH_LOGS)]}
    logs["cycles"] = []
    for entry in logs["free"] + logs["push"]:
        waypoints, dwell = entry["waypoint_seed"], entry["dwell_seed"] + 500
        seconds = cycle_seconds(setup[0], waypoints, dwell)
        name = f"cycle_{Path(entry['path']).stem}.csv"
        logs["cycles"].append(simulate_log(setup, folder / name, seconds, waypoints, dwell))
    (folder / "logs.json").write_text(json.dumps(logs, indent=1, default=float))
    return logs


def train(work, setup, seed):
    """``gpcd train --robot ur10`` defaults on the identification logs (subprocess)."""
    import little_data_mujoco as L

    paths = L.make_training(work / "train", seed, setup, False, True)
    tic = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "sklearn_gpcd.cli", "train", *paths,
                           "--robot", L.ROBOT, "-o", str(work / "model.skops"), "-q"],
                          cwd=REPO, capture_output=True, text=True)
    if proc.returncode:
        print(proc.stderr)
        raise SystemExit("gpcd train failed")
    out = {"seconds": time.perf_counter() - tic, "stdout": proc.stdout,
           "paths": [str(p) for p in paths]}
    (work / "train.json").write_text(json.dumps(out, indent=1))
    return out


# -- monitors and scores ----------------------------------------------------------
def monitors(work, logs, recs):
    """``{name: (trained model, calibrated, taught, taught with one cycle of each pose)}``
    for the model of ``gpcd train``, ``i - i_des`` and the momentum observer."""
    import little_data_mujoco as L
    from real_ur10e import trained_model

    from sklearn_gpcd.dynamics import MomentumObserver
    from sklearn_gpcd.workflow import calibrate_detector, load_model, teach_task

    train_recs = [load(p) for p in json.loads((work / "train.json").read_text())["paths"]]
    model = load_model(work / "model.skops")
    peer = load_model(L.peer_model([str(p) for p in sorted((work / "train").glob("*.csv"))],
                                   work / "peer.joblib"), trust_pickle=True)
    X = [model.features.transform(r) for r in train_recs]
    groups = np.concatenate([np.full(len(x), k) for k, x in enumerate(X)])
    period = float(np.median(np.concatenate([np.diff(r.time) for r in train_recs])))
    observer = MomentumObserver(L.ROBOT, identify="all", sample_time=period).fit(
        np.vstack(X), np.vstack([r.current for r in train_recs]), groups=groups)
    task = recs["task.csv"]
    cycles = [recs[Path(e["path"]).name] for e in logs["cycles"]]
    out, timings = {}, {}
    for name, trained in (("model", model), ("i - i_des", peer),
                          ("observer", trained_model(observer, model.features))):
        tic = time.perf_counter()
        calibrated = _quiet(calibrate_detector, trained, [task], keys=["task.csv"], split=SPLIT)
        timings[f"calibrate {name}"] = time.perf_counter() - tic
        tic = time.perf_counter()
        taught = _quiet(teach_task, calibrated, [task], keys=["task.csv"])
        timings[f"teach {name}"] = time.perf_counter() - tic
        every = _quiet(teach_task, calibrated, [task, *cycles],
                       keys=["task.csv", *(Path(e["path"]).name for e in logs["cycles"])])
        out[name] = (calibrated, taught, every)
    return out, timings


def load(path):
    from sklearn_gpcd.io import load_recording

    return load_recording(path)


def replay(calibrated, rec):
    """Causal outputs (``taught_task.causal_outputs``: ``gpcd monitor``'s path)."""
    from taught_task import causal_outputs

    return _quiet(causal_outputs, calibrated, rec)


def onsets_of(out, t):
    """Event onsets [s]: an event holds while the signal has not been released, and a
    new contact on joints that had let go starts another (``event_onset``)."""
    from sklearn_gpcd.metrics import alarm_onsets

    return np.asarray(alarm_onsets(out.event | out.alarms.any(axis=1), t, new=out.event_onset),
                      dtype=float)


def score_set(calibrated, recs, entries):
    """Onsets per hour, untaught share of motion, pushes caught, per set of logs."""
    onsets, seconds, moving, untaught, pushes, push_fa = 0, 0.0, 0, 0, [], 0
    for entry in entries:
        rec = recs[Path(entry["path"]).name]
        out = replay(calibrated, rec)
        t = rec.time - rec.time[0]
        ons = onsets_of(out, t)
        move = np.asarray(out.regime) == 0
        moving += int(move.sum())
        untaught += int((move & ~np.asarray(out.taught, dtype=bool)).sum())
        seconds += float(t[-1])
        if not entry.get("pushes"):
            onsets += len(ons)
            continue
        windows = [(p["start"], p["stop"] + CATCH_AFTER) for p in entry["pushes"]]
        for (lo, hi), p in zip(windows, entry["pushes"]):
            inside = ons[(ons >= lo) & (ons <= hi)]
            pushes.append({"log": Path(entry["path"]).name, "start": p["start"],
                           "link": p.get("link"), "caught": bool(inside.size),
                           "events": int(inside.size),
                           "delay_s": float(inside[0] - lo) if inside.size else None})
        push_fa += int(sum(not any(lo <= o <= hi for lo, hi in windows) for o in ons))
    hours = seconds / 3600
    res = {"minutes": 60 * hours, "untaught_motion_share": untaught / max(moving, 1)}
    if pushes:
        delays = [p["delay_s"] for p in pushes if p["caught"]]
        res.update(caught=sum(p["caught"] for p in pushes), n_pushes=len(pushes),
                   one_event=sum(p["events"] == 1 for p in pushes),
                   median_delay_s=float(np.median(delays)) if delays else None,
                   false_alarms=push_fa, false_alarms_per_hour=push_fa / hours, pushes=pushes)
    else:
        res.update(onsets=onsets, per_hour=onsets / hours)
    return res


def row_text(name, r):
    def rate(x):
        return f"{x['onsets']:>3} ({x['per_hour']:6.1f}/h, untaught {100 * x['untaught_motion_share']:4.1f} %)"

    p = r["push"]
    delay = "-" if p["median_delay_s"] is None else f"{p['median_delay_s']:.3f}"
    return (f"{name:<28} {rate(r['same'])}  {rate(r['free'])}  {p['caught']:>2}/{p['n_pushes']}"
            f" one event {p['one_event']:>2}, delay {delay} s, {p['false_alarms']} FA"
            f" ({p['false_alarms_per_hour']:.1f}/h), untaught {100 * p['untaught_motion_share']:4.1f} %")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workdir", default=None, help="logs and model (default: tmp)")
    parser.add_argument("--reuse", action="store_true", help="reuse --workdir's logs, model")
    parser.add_argument("--prepare-only", action="store_true",
                        help="simulate and train, then stop")
    parser.add_argument("--output", default=None, help="folder for the results")
    parser.add_argument("--seed", type=int, default=SCORE_SEED,
                        help=f"{SCORE_SEED} scores; {SEED} is the development seed")
    args = parser.parse_args(argv)
    try:
        import mujoco  # noqa: F401
    except ImportError:
        print("mujoco is not installed (pip install mujoco): skipped")
        return 0
    import tempfile

    import little_data_mujoco as L

    work = Path(args.workdir or tempfile.mkdtemp(prefix="taught_mujoco_"))
    work.mkdir(parents=True, exist_ok=True)
    setup = L.plant_setup()
    if args.reuse and (work / "logs.json").exists():
        logs = json.loads((work / "logs.json").read_text())
    else:
        logs = make_logs(work, setup, args.seed)
    print(f"logs in {work}", flush=True)
    if not (args.reuse and (work / "model.skops").exists()):
        out = train(work, setup, args.seed)
        print(f"trained in {out['seconds']:.0f} s", flush=True)
    if args.prepare_only:
        return 0
    recs = {Path(e["path"]).name: load(e["path"])
            for e in [logs["task"], *logs["same"], *logs["free"], *logs["push"], *logs["cycles"]]}
    built, timings = monitors(work, logs, recs)
    results = {}
    header = (f"{'monitor':<28} {'same task: onsets':<36}  {'other poses: onsets':<36}  pushes")
    lines = [header]
    print(header, flush=True)
    for name, (calibrated, taught, every) in built.items():
        for shown, det, sets in ((f"{name} untaught", calibrated, ("same", "free", "push")),
                                 (f"{name} taught", taught, ("same", "free", "push")),
                                 (f"{name} + 1 cycle per pose", every, ("same", "free", "push"))):
            tic = time.perf_counter()
            r = {k: score_set(det, recs, logs[k]) for k in sets}
            r["monitor_seconds"] = time.perf_counter() - tic
            if det is not calibrated:
                r["teach"] = det.calibration["teach"]
            results[shown] = r
            lines.append(row_text(shown, r))
            print(lines[-1], flush=True)
    lines.append("timings [s]: " + ", ".join(f"{k} {v:.1f}" for k, v in timings.items()))
    report = {"command": " ".join(["python", "benchmarks/taught_mujoco.py", *(argv or sys.argv[1:])]),
              "seed": args.seed, "timings": timings, "results": results,
              "logs": {k: v for k, v in logs.items()},
              "load_average": list(map(float, Path("/proc/loadavg").read_text().split()[:3]))}
    if args.output:
        out = Path(args.output)
        out.mkdir(parents=True, exist_ok=True)
        (out / "taught_mujoco.json").write_text(json.dumps(report, indent=1, default=float))
        (out / "taught_mujoco.txt").write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
