"""Little calibration data on the MuJoCo second engine (issue 38, "Little data").

Protocol, fixed before any result was looked at:

1. **Train** once, on the *nominal* MuJoCo plant (``_mujoco_plant.py``, no
   injected effect): ``gpcd train`` with default flags and ``--robot ur10``
   (the plant is built from the package's ``ur10`` geometry, inertias and
   torque constants, as in ``second_engine.py``) on identification-style
   logs (random flange targets at 0.8 of the velocity limits, the D1-like
   reference of ``second_engine.py``; 4 runs of 16 targets, about 3.5 min).
2. **Change the plant** (cases, drawn from ``--seed`` with the blind
   protocol's ranges, ``blind_protocol.draw_effect``): ``nominal`` (the
   control: no effect), ``stribeck`` (a Stribeck peak on 1-3 joints, 0.3-1.0
   of the joint's Coulomb level, one Stribeck velocity of 15-80 mrad/s),
   ``coulomb`` (the Coulomb level of 1-2 joints changed by 25-60 %, either
   sign) and ``viscous`` (the viscous level of 1-2 joints changed by -50 to
   +100 %; run on request, ``--cases``). The model is never refitted.
3. **Calibrate** on ONE collision-free log of a *normal task* (cycles through
   4 waypoints, random flange targets of the task's seed, at 0.4 of the
   velocity limits and 1.5 rad/s^2, a dwell of 0.5-4 s at each stop): the
   first 2 min (and, for the scaling study, the first 1 and 5 min of the same
   log) with ``gpcd calibrate`` and default flags. If the command refuses one
   log (today it needs ``--split``), the refusal is recorded and it is run
   again with ``--split S``, ``S = min(--fallback-split, duration / 3)``
   (the issue's ``--split 30`` for 2 min; at least 3 pieces, so that the
   expected false-alarm figure exists); the table says which flags ran.
4. **Score** with ``gpcd monitor``: (a) unseen collision-free logs of the
   same kind of task, other seeds (5 x 125 s, 10.4 min): alarm onsets per
   hour; (b) push logs (4 x 64 s, 4 pushes each): a push is a force on a
   link (2-6, at its centre of mass) with a sin^2 profile of 0.5-1.5 s,
   100-200 N in a random direction, redrawn while it loads no joint with 30
   Nm or more at the reference pose; one of 4 slots of 14 s, start drawn in
   the first 6 s of the slot. A push is caught by an alarm event that starts
   between its start and 1 s after its end; the delay is from its start.
   Events in push logs outside ``[start, stop + 1 s]`` of every push are
   false alarms too (reported apart). Added after the first quick run, and
   reported apart (``same/h``): (c) 2 x 150 s collision-free logs of the
   calibration log's own task (its waypoints; other dwells and noise), to
   tell thresholds too tight for the task from thresholds too tight for other
   poses of the same kind of task.
5. **The 20 s check**: ``gpcd calibrate`` on the first 20 s of the
   calibration log, default flags (then the fallback): its warnings.
6. **The peer** ``i - i_des``: the plant logs the controller's signals as a
   UR does (``target_q``, ``target_qd`` and ``target_current``, the servo's
   feed-forward over the nominal torque constants); the peer model
   (:class:`~sklearn_gpcd.dynamics.ControllerCurrent`) is saved in a model
   file and calibrated and monitored by the same commands and flags. Added
   after the first full run, to measure what a regime decided from the
   commanded motion (the issue's deliverable 3) would do: ``i-i_des cmd``,
   the peer on copies of the logs with ``q, qd := target_q, target_qd``
   (its prediction reads ``target_current`` alone, so only its regimes and
   rest reference change; ``--no-commanded-peer`` skips it).

Why pushes are missed and false alarms raised (``analysis`` in the JSON):
per push, the best joint's peak of the debounced ``|m|`` over its threshold
in the regime it was in; per false alarm, the same; per unseen log, the
largest ratio per regime; and which calibration piece set the margin (the
leave-one-piece-out factors, from the public ``regime_excursions`` and
``loro_margin`` on the same pieces); per false alarm, the regime at its
onset and what the controller commanded then (``target_qd``: moving,
stopped less than 0.5 s before, still); and the factor window: by how much
all thresholds must grow for no false alarm, and may grow before the first
push is missed.

Run ``python benchmarks/little_data_mujoco.py --output little_data.json``
(measured on 2 cores shared at a load average of about 13: training 12.7
min wall, 3 min CPU; the three cases 22 min wall, 8 min CPU, plus 2 min per
case to simulate; ``--quick`` for a smoke run: 2 training runs, 2 unseen
logs of 60 s, 2 push logs, 2 cases, 13 min wall). Flags pass
through to the commands: ``--train-args``, ``--calibrate-args``,
``--monitor-args`` (one string each, shell-split). ``--workdir`` keeps the
logs and the model; ``--reuse`` takes them from there instead of simulating
and training again (after a change of the calibration defaults, say).
Needs ``pip install mujoco`` (the ``second-engine`` extra).
"""

import argparse
import json
import shlex
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(HERE))

#: The cases, in order (their index seeds the draw).
CASES = ("nominal", "stribeck", "coulomb", "viscous")
#: The cases run by default (viscous on request: --cases, for the runtime).
DEFAULT_CASES = ("nominal", "stribeck", "coulomb")
KINDS = {"stribeck": "stribeck_friction", "coulomb": "coulomb_friction",
         "viscous": "viscous_friction"}
ROBOT = "ur10"
#: Identification-style training logs (D1-like, 16 random flange targets each).
N_TRAIN_RUNS, TRAIN_TARGETS = 4, 16
#: The normal task: waypoints, speed (fraction of the velocity limits),
#: acceleration [rad/s^2], dwell range [s].
TASK_WAYPOINTS, TASK_SPEED, TASK_ACCELERATION, TASK_DWELL = 4, 0.4, 1.5, (0.5, 4.0)
#: Calibration log lengths [s]: the main one and the scaling study.
MAIN_LENGTH, LENGTHS, SHORT_LENGTH = 120.0, (60.0, 120.0, 300.0), 20.0
#: Unseen collision-free logs: count x seconds.
N_FREE, FREE_SECONDS = 5, 125.0
#: Added after the first (quick) run: collision-free logs of the calibration log's own
#: task (its waypoints; other dwells and noise), count x seconds.
N_SAME, SAME_SECONDS = 2, 150.0
#: Push logs: count, pushes per log, slot [s], start jitter [s], first slot start [s].
N_PUSH_LOGS, PUSHES_PER_LOG, PUSH_SLOT, PUSH_JITTER, PUSH_FIRST = 4, 4, 14.0, 6.0, 4.0
PUSH_FORCE = (100.0, 200.0)      # N
PUSH_DURATION = (0.5, 1.5)       # s
PUSH_LINKS = (2, 3, 4, 5, 6)
PUSH_MIN_TORQUE = 30.0           # Nm on some joint at the reference pose
#: An alarm event starting in [start, stop + CATCH_AFTER] catches the push.
CATCH_AFTER = 1.0
FALLBACK_SPLIT = 30.0
#: The peer with regimes from the commanded motion (``commanded_copies``).
PEER_COMMANDED = "i-i_des cmd"


# -- the plant and its logs ---------------------------------------------------
def plant_setup():
    from sklearn_gpcd.datasets.plant import drive_parameters
    from sklearn_gpcd.robots import load_robot

    robot = load_robot(ROBOT)
    k, rotor = drive_parameters(robot)
    return robot, k, rotor


def draw_injection(case, seed):
    """``(Injection, truth)`` of ``case``: a function of the case and the seed alone."""
    from _mujoco_plant import DAMPING, FRICTIONLOSS, Injection
    from blind_protocol import draw_effect

    if case == "nominal":
        return Injection(), {}
    rng = np.random.default_rng([seed, CASES.index(case)])
    fields, truth = draw_effect(KINDS[case], rng, FRICTIONLOSS.copy(), DAMPING.copy())
    return Injection(**fields), {KINDS[case]: truth}


def task_reference(robot, seconds, seed, dwell_seed=None):
    """A normal task: cycles through waypoints with dwells, at least ``seconds`` long.

    ``seed`` draws the waypoints, ``dwell_seed`` (default: ``seed``) the dwells.
    """
    from sklearn_gpcd.datasets import reference_d1
    from sklearn_gpcd.datasets.trajectory import JointTrajectory, quintic_duration

    d1 = reference_d1(robot, n_targets=TASK_WAYPOINTS, random_state=seed)
    waypoints = [d1.at(p["stop"]) for p in d1.phases if p["kind"] == "move"]
    rng = np.random.default_rng(seed if dwell_seed is None else dwell_seed)
    velocity = TASK_SPEED * np.asarray(robot.velocity_limits, dtype=float)
    pieces, total, q, k = [JointTrajectory.rest(waypoints[0], 1.0)], 1.0, waypoints[0], 1
    while total < seconds + 0.5:
        target = waypoints[k % len(waypoints)]
        move = quintic_duration(q, target, velocity, TASK_ACCELERATION)
        dwell = float(rng.uniform(*TASK_DWELL))
        pieces += [JointTrajectory.point_to_point(q, target, move),
                   JointTrajectory.rest(target, dwell)]
        total += move + dwell
        q, k = target, k + 1
    return JointTrajectory.concatenate(pieces)


def draw_pushes(robot, reference, seed, n_pushes):
    """Pushes of one log (:class:`~sklearn_gpcd.datasets.Contact`, sim time)."""
    from sklearn_gpcd.datasets import Contact

    rng = np.random.default_rng([seed, 7])
    data = robot.model.createData()
    pushes = []
    for i in range(n_pushes):
        start = PUSH_FIRST + i * PUSH_SLOT + float(rng.uniform(0, PUSH_JITTER))
        duration = float(rng.uniform(*PUSH_DURATION))
        link = int(rng.choice(PUSH_LINKS))
        point = np.asarray(robot.model.inertias[link].lever, dtype=float)
        q = reference.at(start + duration / 2)
        for _ in range(100):
            direction = rng.normal(size=3)
            force = float(rng.uniform(*PUSH_FORCE)) * direction / np.linalg.norm(direction)
            push = Contact(link=link, start=start, duration=duration, force=force, point=point)
            if np.abs(push.joint_torque(robot.model, data, q)).max() >= PUSH_MIN_TORQUE:
                break
        pushes.append(push)
    return pushes


def make_logs(folder, case, seed, setup, quick, lengths, log_targets):
    """Simulate the case's logs into ``folder``; return their description."""
    from _mujoco_plant import simulate

    from sklearn_gpcd.io import write_rtde_csv

    robot, k, rotor = setup
    injection, truth = draw_injection(case, seed)
    folder.mkdir(parents=True, exist_ok=True)
    base = seed * 1000
    logs = {"truth": truth, "calibration": {}, "free": [], "pushes": []}

    def run(name, seconds, task_seed, contacts=(), waypoint_seed=None):
        ref = task_reference(robot, seconds,
                             task_seed if waypoint_seed is None else waypoint_seed, task_seed)
        rec = simulate(robot, k, rotor, injection, random_state=task_seed, name=name,
                       reference=ref, contacts=contacts, log_targets=log_targets)
        n = int(np.searchsorted(rec.time, seconds, side="right"))
        return rec.slice(0, n).replace(metadata={**rec.metadata, "robot": ROBOT})

    cal = run("cal", max(max(lengths), SHORT_LENGTH), base + 1)
    for seconds in sorted(set(lengths) | {SHORT_LENGTH}):
        n = int(np.searchsorted(cal.time, seconds, side="right"))
        path = folder / f"cal_{seconds:g}s.csv"
        write_rtde_csv(cal.slice(0, n), path, robot_comment=True)
        logs["calibration"][seconds] = str(path)
    n_free, free_s = (2, 60.0) if quick else (N_FREE, FREE_SECONDS)
    for i in range(n_free):
        rec = run(f"free{i}", free_s, base + 10 + i)
        path = folder / f"free_{i}.csv"
        write_rtde_csv(rec, path, robot_comment=True)
        logs["free"].append({"path": str(path), "seconds": float(rec.duration)})
    logs["free_same"] = []
    for i in range(1 if quick else N_SAME):
        rec = run(f"same{i}", SAME_SECONDS, base + 30 + i, waypoint_seed=base + 1)
        path = folder / f"same_{i}.csv"
        write_rtde_csv(rec, path, robot_comment=True)
        logs["free_same"].append({"path": str(path), "seconds": float(rec.duration)})
    n_push = 2 if quick else N_PUSH_LOGS
    push_s = PUSH_FIRST + PUSHES_PER_LOG * PUSH_SLOT + 4.0
    for i in range(n_push):
        task_seed = base + 50 + i
        ref = task_reference(robot, push_s, task_seed)
        contacts = draw_pushes(robot, ref, task_seed, PUSHES_PER_LOG)
        rec = simulate(robot, k, rotor, injection, random_state=task_seed, name=f"push{i}",
                       reference=ref, contacts=contacts, log_targets=log_targets)
        n = int(np.searchsorted(rec.time, push_s, side="right"))
        rec = rec.slice(0, n)
        path = folder / f"push_{i}.csv"
        write_rtde_csv(rec, path, robot_comment=True)
        logs["pushes"].append({"path": str(path), "seconds": float(rec.duration),
                               "pushes": rec.metadata["contacts"]})
    (folder / "logs.json").write_text(json.dumps(logs, indent=1, default=float))
    return logs


def make_training(folder, seed, setup, quick, log_targets):
    from _mujoco_plant import simulate

    from sklearn_gpcd.io import write_rtde_csv

    robot, k, rotor = setup
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for i in range(2 if quick else N_TRAIN_RUNS):
        rec = simulate(robot, k, rotor, None, n_targets=TRAIN_TARGETS,
                       random_state=seed * 1000 + 100 + i, name=f"ident{i}",
                       log_targets=log_targets)
        path = folder / f"ident_{i}.csv"
        write_rtde_csv(rec.replace(metadata={"robot": ROBOT}), path, robot_comment=True)
        paths.append(str(path))
    return paths


def commanded_copies(logs, folder, length):
    """The logs with ``q, qd := target_q, target_qd``: the regimes then follow the
    commanded motion. Only for the peer, whose prediction reads ``target_current``
    alone, so that nothing but its regimes (and rest reference) changes."""
    from sklearn_gpcd.io import load_recording, write_rtde_csv

    folder.mkdir(parents=True, exist_ok=True)

    def copy(path):
        out = folder / Path(path).name
        if not out.exists():
            rec = load_recording(path)
            write_rtde_csv(rec.replace(q=rec.target_q, qd=rec.target_qd), out,
                           robot_comment=True)
        return str(out)

    return {**logs, "calibration": {length: copy(logs["calibration"][length])},
            **{kind: [{**e, "path": copy(e["path"])} for e in logs.get(kind, [])]
               for kind in ("free", "free_same", "pushes")}}


# -- the commands ---------------------------------------------------------------
def gpcd(*args):
    """Run ``python -m sklearn_gpcd.cli ARGS`` from the repository: (status, out, err, s)."""
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "sklearn_gpcd.cli", *map(str, args)],
                          cwd=REPO, capture_output=True, text=True)
    return proc.returncode, proc.stdout, proc.stderr, time.perf_counter() - t0


def warnings_of(stderr):
    return [line.split("warning: ", 1)[1] for line in stderr.splitlines()
            if "warning: " in line]


def calibrate(model, log, seconds, out, extra, fallback_split, pickle):
    """``gpcd calibrate`` with ``extra``; on a refusal of one log, again with --split."""
    trust = ["--trust-pickle"] if pickle else []
    runs = []
    args = [model, log, "-o", out, "-q", *trust, *extra]
    status, stdout, stderr, secs = gpcd("calibrate", *args)
    runs.append({"flags": " ".join(extra) or "(defaults)", "status": status,
                 "warnings": warnings_of(stderr),
                 "error": stderr.strip().splitlines()[-1] if status else None,
                 "seconds": secs})
    if status and "--split" not in extra:
        split = round(min(fallback_split, seconds / 3), 3)
        flags = [*extra, "--split", f"{split:g}"]
        status, stdout, stderr, secs = gpcd("calibrate", model, log, "-o", out, "-q", *trust,
                                            *flags)
        runs.append({"flags": " ".join(flags), "status": status,
                     "warnings": warnings_of(stderr),
                     "error": stderr.strip().splitlines()[-1] if status else None,
                     "seconds": secs})
    return runs


def monitor(detector, paths, out_json, extra, pickle):
    trust = ["--trust-pickle"] if pickle else []
    status, stdout, stderr, secs = gpcd("monitor", detector, *paths, "--json", out_json, "-q",
                                        *trust, *extra)
    if status:
        raise RuntimeError(f"gpcd monitor failed: {stderr.strip()[-2000:]}")
    return json.loads(Path(out_json).read_text()), secs


def peer_model(train_paths, out):
    """A model file whose prediction is the logged target current (``i - i_des``)."""
    from sklearn_gpcd.dynamics import ControllerCurrent
    from sklearn_gpcd.features import CausalFeatures
    from sklearn_gpcd.io import load_recording
    from sklearn_gpcd.workflow import TrainedModel, save_model

    rec = load_recording(train_paths[0])
    features = CausalFeatures(signals=("target_current",)).fit(rec)
    X = features.transform(rec)
    regressor = ControllerCurrent(rec.n_joints).fit(X, rec.current)
    training = {"model": "i - i_des", "inputs": "causal", "n_support": 0,
                "optimizer": "none", "seed": 0, "signals": ["target_current"],
                "robot": None, "recordings": [Path(train_paths[0]).name]}
    save_model(TrainedModel(regressor, features, training), out)
    return out


# -- scoring ------------------------------------------------------------------------
def score(report, logs):
    """False alarms on the unseen logs, pushes caught and delays, push-log false alarms."""
    by_log = {}
    for e in report["events"]:
        by_log.setdefault(e["recording"], []).append(e)
    free_events = [e for f in logs["free"] for e in by_log.get(Path(f["path"]).name, [])]
    free_hours = sum(f["seconds"] for f in logs["free"]) / 3600
    pushes, push_fa = [], []
    for log in logs["pushes"]:
        events = by_log.get(Path(log["path"]).name, [])
        for p in log["pushes"]:
            hits = [e for e in events if p["start"] <= e["start_s"] <= p["stop"] + CATCH_AFTER]
            first = min(hits, key=lambda e: e["start_s"]) if hits else None
            ends = [e["end_s"] for e in events
                    if e["end_s"] >= p["start"] and e["start_s"] <= p["stop"] + CATCH_AFTER]
            pushes.append({"log": Path(log["path"]).name, **p, "caught": bool(hits),
                           "alarm_end_s": max(ends) if ends else None,
                           "delay_s": None if first is None else first["start_s"] - p["start"],
                           "joints": None if first is None else first["joints"]})
        for e in events:
            if not any(e["end_s"] >= p["start"] and e["start_s"] <= p["stop"] + CATCH_AFTER
                       for p in log["pushes"]):
                push_fa.append({"log": Path(log["path"]).name, **e})
    same = logs.get("free_same", [])
    same_events = [e for f in same for e in by_log.get(Path(f["path"]).name, [])]
    same_hours = sum(f["seconds"] for f in same) / 3600
    delays = [p["delay_s"] for p in pushes if p["caught"]]
    push_hours = sum(log["seconds"] for log in logs["pushes"]) / 3600
    return {"free_onsets": len(free_events), "free_minutes": free_hours * 60,
            "false_alarms_per_hour": len(free_events) / free_hours,
            "free_events": free_events, "push_log_false_alarms": push_fa,
            "same_task_onsets": len(same_events), "same_task_minutes": same_hours * 60,
            "same_task_per_hour": len(same_events) / same_hours if same else None,
            "same_task_events": same_events,
            "push_log_minutes": push_hours * 60,
            "caught": sum(p["caught"] for p in pushes), "n_pushes": len(pushes),
            "median_delay_s": float(np.median(delays)) if delays else None,
            "max_delay_s": float(np.max(delays)) if delays else None, "pushes": pushes}


# -- the same detector file in batch (library), and why ----------------------------------
class CachedPrediction:
    """The fitted model of a detector, its predictions kept by input.

    Every detector calibrated from one model file wraps the same frozen model
    and reads the same inputs of a log, so one prediction per log serves them
    all (the GP prediction is what costs). Attributes pass through.
    """

    def __init__(self, inner, store):
        self.inner, self.store = inner, store

    def predict(self, X, **kwargs):
        import hashlib

        key = (X.shape, hashlib.sha1(np.ascontiguousarray(X).tobytes()).hexdigest(),
               tuple(sorted(kwargs)))
        if key not in self.store:
            self.store[key] = self.inner.predict(X, **kwargs)
        return self.store[key]

    def __getattr__(self, name):
        return getattr(self.inner, name)


def load_cached(detector_path, pickle, store):
    from sklearn_gpcd.workflow import load_detector

    det, features, summary = load_detector(detector_path, trust_pickle=pickle)
    det.regressor_ = CachedPrediction(det.regressor_, store)
    return det, features, summary


def batch_run(det, features, logs, recs):
    """Alarm events of ``det`` on every test log (the batch path of gpcd monitor).

    Returns the events (as ``gpcd monitor --json`` lists them: contiguous runs
    of an alarm on any joint) and per log the time, debounced ``|m|`` over the
    threshold of the sample's regime, the regime and ``|m|``.
    """
    from sklearn_gpcd.detection import stack_currents

    events, series = [], {}
    for entry in logs["free"] + logs.get("free_same", []) + logs["pushes"]:
        key = Path(entry["path"]).name
        rec = recs[key]
        out = det.monitoring_signal(stack_currents(features.transform(rec), rec.current))
        band = out.bands[0]
        alarms = np.asarray(out.alarms, dtype=bool)
        series[key] = (rec.time, np.asarray(band.ratio), np.asarray(band.regime))
        any_alarm = alarms.any(axis=1)
        edges = np.flatnonzero(np.diff(np.r_[0, any_alarm.astype(int), 0]))
        for a, b in zip(edges[::2], edges[1::2]):
            events.append({"recording": key, "start_s": float(rec.time[a]),
                           "end_s": float(rec.time[b - 1]),
                           "joints": (np.flatnonzero(alarms[a:b].any(axis=0)) + 1).tolist()})
    return {"events": events}, series


def commanded(rec, t0, before=0.5):
    """What the controller commanded at ``t0``: "moving" (some ``target_qd`` nonzero),
    "stopped < 0.5 s" (it was within ``before`` s), "still", or None without the signal."""
    if rec.target_qd is None:
        return None
    cmd = np.abs(rec.target_qd).max(axis=1) > 1e-6
    k = min(int(np.searchsorted(rec.time, t0)), len(cmd) - 1)
    if cmd[k]:
        return "moving"
    recent = (rec.time >= t0 - before) & (rec.time <= t0)
    return f"stopped < {before:g} s" if cmd[recent].any() else "still"


def analyse(det, features, summary, cal_path, logs, result, series, recs):
    """Per push / false alarm / unseen log: peak debounced |m| over its threshold;
    which calibration piece set the margin."""
    from sklearn_gpcd.detection import loro_margin, regime_excursions, stack_currents
    from sklearn_gpcd.io import load_recording
    from sklearn_gpcd.workflow import split_recordings

    thresholds = np.atleast_2d(det.rules_[0].thresholds_)
    names = list(summary["regimes"])
    out = {"pushes": [], "false_alarms": [], "free_logs": [], "pieces": None}
    for log in logs["pushes"]:
        t, ratio, regime = series[Path(log["path"]).name]
        for p in log["pushes"]:
            w = (t >= p["start"]) & (t <= p["stop"] + CATCH_AFTER)
            r = ratio[w]
            i, j = np.unravel_index(np.argmax(r), r.shape)
            g = int(regime[w][i])
            out["pushes"].append({
                "log": Path(log["path"]).name, "start": p["start"], "link": p["link"],
                "best_joint": int(j) + 1, "peak_ratio": float(r[i, j]),
                "peak_A": float(r[i, j] * thresholds[g, j]), "regime": names[g],
                "threshold_A": float(thresholds[g, j]),
                "regimes_in_window": sorted({names[c] for c in regime[w]}),
                "peak_ratio_per_joint": r.max(axis=0).round(3).tolist()})
    for e in (result["push_log_false_alarms"] + result["free_events"]
              + result.get("same_task_events", [])):
        t, ratio, regime = series[e["recording"]]
        w = (t >= e["start_s"]) & (t <= e["end_s"])
        r = ratio[w]
        i, j = np.unravel_index(np.argmax(r), r.shape)
        g = int(regime[w][i])
        out["false_alarms"].append({
            "log": e["recording"], "start_s": e["start_s"], "joints": e["joints"],
            "peak_joint": int(j) + 1, "peak_ratio": float(r[i, j]), "regime": names[g],
            "threshold_A": float(thresholds[g, j]),
            "peak_A": float(r[i, j] * thresholds[g, j]),
            "onset_regime": names[int(regime[w][0])],
            "commanded": commanded(recs[e["recording"]], e["start_s"])})
    for kind in ("free", "free_same"):
        for f in logs.get(kind, []):
            t, ratio, regime = series[Path(f["path"]).name]
            worst = np.full(thresholds.shape, np.nan)
            for g in np.unique(regime):
                worst[g] = ratio[regime == g].max(axis=0)
            out["free_logs"].append({"log": Path(f["path"]).name, "kind": kind,
                                     "max_ratio_per_regime_joint": np.round(worst, 4).tolist()})
    alarm_end = {(p["log"], p["start"]): p.get("alarm_end_s") for p in result["pushes"]}
    for log in logs["pushes"]:  # outside the pushes, the second after and their alarms
        key = Path(log["path"]).name
        t, ratio, regime = series[key]
        free = np.ones(len(t), dtype=bool)
        for p in log["pushes"]:
            end = max(p["stop"] + CATCH_AFTER, alarm_end.get((key, p["start"])) or 0.0)
            free &= ~((t >= p["start"]) & (t <= end))
        worst = np.full(thresholds.shape, np.nan)
        for g in np.unique(regime[free]):
            worst[g] = ratio[free & (regime == g)].max(axis=0)
        out["free_logs"].append({"log": Path(log["path"]).name, "kind": "push_outside",
                                 "max_ratio_per_regime_joint": np.round(worst, 4).tolist()})
    # which piece set the margin: the leave-one-piece-out factors of the pieces
    split = summary.get("split_s")
    cal = load_recording(cal_path)
    keys, pieces = ((split_recordings([Path(cal_path).name], [cal], split)) if split
                    else ([Path(cal_path).name], [cal]))
    if len(pieces) >= 2:
        blocks = {k: stack_currents(features.transform(p), p.current)
                  for k, p in zip(keys, pieces)}
        peaks = {k: v[2] for k, v in regime_excursions(det, blocks).items()}
        stack = np.stack([peaks[k] for k in keys])
        factors = []
        for n, key in enumerate(keys):
            others = np.delete(stack, n, axis=0).max(axis=0)
            with np.errstate(divide="ignore", invalid="ignore"):
                f = np.where(others > 0, stack[n] / others, np.where(stack[n] > 0, np.inf, 0))
            g, j = np.unravel_index(np.argmax(f), f.shape)
            factors.append({"piece": key, "factor": float(f[g, j]), "regime": names[g],
                            "joint": int(j) + 1, "peak_A": float(stack[n, g, j]),
                            "others_max_A": float(others[g, j])})
        out["pieces"] = {"factors": factors,
                         "margin_recomputed": float(loro_margin(peaks, keys).max()),
                         "margin_reported": summary["margin"],
                         "levels_A": (thresholds / summary["margin"]).round(4).tolist()}
    return out


# -- one monitor -------------------------------------------------------------------
def run_monitor(name, model, logs, recs, folder, length, args, pickle, store, cli):
    """Calibrate ``model`` on the ``length`` log (gpcd calibrate), score the test logs
    in batch with the detector file and, with ``cli``, with gpcd monitor too."""
    cal_log = logs["calibration"][length]
    stem = "".join(c if c.isalnum() or c in "-_" else "" for c in name)
    det_path = folder / f"{stem}_{length:g}s.{'joblib' if pickle else 'skops'}"
    runs = calibrate(model, cal_log, length, det_path, args.calibrate_args,
                     args.fallback_split, pickle)
    row = {"monitor": name, "length_s": length, "calibrate_runs": runs}
    if runs[-1]["status"]:
        row["error"] = runs[-1]["error"]
        return row
    det, features, summary = load_cached(det_path, pickle, store)
    row["calibration"] = {k: summary.get(k) for k in (
        "margin", "thresholds_A", "regimes", "false_alarms_per_hour", "n_false_alarms_nested",
        "settle_time_s", "rest_reference_s", "split_s", "coverage", "hours", "signals")}
    row["model"] = (summary.get("training") or {}).get("model")
    t0 = time.perf_counter()
    report, series = batch_run(det, features, logs, recs)
    row["batch_seconds"] = time.perf_counter() - t0
    row["result"] = score(report, logs)
    row["scored_by"] = "batch (library, the detector file)"
    if cli:
        paths = [f["path"] for f in logs["free"] + logs.get("free_same", []) + logs["pushes"]]
        cli_report, secs = monitor(det_path, paths, folder / f"{stem}_{length:g}s_monitor.json",
                                   args.monitor_args, pickle)
        row["monitor_seconds"] = secs
        batch_onsets = sorted((e["recording"], round(e["start_s"], 6)) for e in report["events"])
        cli_onsets = sorted((e["recording"], round(e["start_s"], 6))
                            for e in cli_report["events"])
        row["cli_equals_batch"] = batch_onsets == cli_onsets
        row["result"] = score(cli_report, logs)
        row["scored_by"] = "gpcd monitor"
    if not args.no_analysis:
        try:
            row["analysis"] = analyse(det, features, summary, cal_log, logs, row["result"],
                                      series, recs)
        except Exception as exc:  # the analysis reads detector internals that may move
            row["analysis"] = {"error": f"{type(exc).__name__}: {exc}"}
    return row


def short_check(model, logs, folder, args):
    runs = calibrate(model, logs["calibration"][SHORT_LENGTH], SHORT_LENGTH,
                     folder / "short.skops", args.calibrate_args, args.fallback_split, False)
    return runs


# -- printing -------------------------------------------------------------------------
def fmt(v, spec=".2f"):
    return "-" if v is None else format(v, spec)


def row_regimes(row):
    return row["calibration"]["regimes"]


def print_row(row):
    flags = row["calibrate_runs"][-1]["flags"]
    refused = [r for r in row["calibrate_runs"][:-1] if r["status"]]
    head = f"  {row['monitor']:<11} cal {row['length_s']:>4g} s  gpcd calibrate {flags}"
    if "scored_by" in row:
        head += f"; scored by {row['scored_by']}"
        if "cli_equals_batch" in row:
            head += f" (== batch: {row['cli_equals_batch']})"
    if refused:
        head += f"  [defaults refused: {refused[0]['error']}]"
    print(head)
    if "error" in row:
        print(f"    FAILED: {row['error']}")
        return
    c, r = row["calibration"], row["result"]
    print(f"    model {row['model']}; margin {c['margin']:.2f}; settle "
          f"{fmt(c['settle_time_s'], 'g')} s, rest ref {fmt(c['rest_reference_s'], 'g')} s; "
          f"expected FA/h (nested) {fmt(c['false_alarms_per_hour'])}")
    print(f"    unseen collision-free: {r['free_onsets']} onset(s) in {r['free_minutes']:.1f} min"
          f" = {r['false_alarms_per_hour']:.1f} per hour; "
          + (f"same task as calibrated: {r['same_task_onsets']} in "
             f"{r['same_task_minutes']:.1f} min; " if r.get("same_task_per_hour") is not None
             else "")
          + "push logs: "
          f"{len(r['push_log_false_alarms'])} false alarm(s) in {r['push_log_minutes']:.1f} min;"
          f" pushes caught {r['caught']}/{r['n_pushes']}, median delay "
          f"{fmt(r['median_delay_s'], '.3f')} s, max {fmt(r['max_delay_s'], '.3f')} s")
    print("    thresholds [A]   " + "".join(f"{f'j{j + 1}':>8}" for j in range(6)))
    for name, t in zip(c["regimes"], c["thresholds_A"]):
        print(f"      {name:<14}" + "".join(f"{v:>8.3f}" for v in t))
    for w in row["calibrate_runs"][-1]["warnings"]:
        print(f"    warning: {w}")
    a = row.get("analysis") or {}
    if "error" in a:
        print(f"    analysis failed: {a['error']}")
        return
    if a.get("pieces"):
        p = a["pieces"]
        top = max(p["factors"], key=lambda f: f["factor"])
        print(f"    margin {p['margin_reported']:.2f} (recomputed {p['margin_recomputed']:.2f}) "
              f"set by piece {top['piece']}: {top['regime']} joint {top['joint']}, "
              f"{top['peak_A']:.3f} A vs {top['others_max_A']:.3f} A in the other pieces; "
              "factors of the pieces: " + ", ".join(f"{f['factor']:.2f} ({f['regime'][:4]} "
                                                    f"j{f['joint']})" for f in p["factors"]))
    for m in a.get("pushes", []):
        if m["peak_ratio"] <= 1.0:
            print(f"    MISSED {m['log']} push at {m['start']:.2f} s (link {m['link']}): best "
                  f"joint {m['best_joint']} peak {m['peak_A']:.3f} A = {m['peak_ratio']:.2f}x "
                  f"its {m['regime']} threshold {m['threshold_A']:.3f} A "
                  f"(regimes in window: {', '.join(m['regimes_in_window'])})")
    groups = {}
    for m in a.get("false_alarms", []):
        groups.setdefault((m["regime"], m["peak_joint"]), []).append(m)
    for (regime, joint), ms in sorted(groups.items(), key=lambda kv: -len(kv[1])):
        worst = max(ms, key=lambda m: m["peak_ratio"])
        print(f"    false alarms by {regime} joint {joint}: {len(ms)} (threshold "
              f"{worst['threshold_A']:.3f} A); worst {worst['peak_A']:.3f} A = "
              f"{worst['peak_ratio']:.2f}x ({worst['log']} at {worst['start_s']:.2f} s)")
    kinds = {}
    for m in a.get("false_alarms", []):
        if m.get("commanded") is not None:
            key = f"{m['onset_regime']} while commanded {m['commanded']}"
            kinds[key] = kinds.get(key, 0) + 1
    if kinds:
        print("    false alarms by regime at onset and the commanded motion (target_qd): "
              + ", ".join(f"{k} {n}" for k, n in sorted(kinds.items(), key=lambda kv: -kv[1])))
    window = margin_window(row)
    for kind, label in (("free", "unseen logs"), ("free_same", "same-task logs"),
                        ("push_outside", "push logs outside the pushes")):
        worst = window.get(f"worst_{kind}")
        if worst is not None:
            print(f"    {label}, largest debounced |m| / threshold per regime (j1..j6): "
                  + "; ".join(f"{name} " + " ".join(fmt(v) for v in r)
                              for name, r in zip(row_regimes(row), worst)))
    if window:
        need = max(window["need_free"], window.get("need_push_logs", 0.0))
        print(f"    thresholds x f: no alarm on the unseen logs needs f > {window['need_free']:.2f}"
              + (f", on the push logs outside the pushes f > {window['need_push_logs']:.2f}"
                 if "need_push_logs" in window else "")
              + (f" (same-task logs: f > {window['need_same']:.2f})" if "need_same" in window
                 else "")
              + f"; every push caught needs f < {window['push_min']:.2f}: "
              + ("a window exists" if need < window["push_min"]
                 else "NO factor does both"))
    if a.get("pushes"):
        ratios = sorted(m["peak_ratio"] for m in a["pushes"])
        print(f"    push peak / threshold (best joint): min {ratios[0]:.2f}, median "
              f"{np.median(ratios):.2f}")


def margin_window(row):
    """By how much the thresholds (all at once) must grow for 0 alarms on the unseen
    logs, and may grow before the first push is missed (debounced ratios)."""
    a = row.get("analysis") or {}
    if not a.get("free_logs") or not a.get("pushes"):
        return {}
    out = {"push_min": min(m["peak_ratio"] for m in a["pushes"])}
    names = {"free": "need_free", "free_same": "need_same", "push_outside": "need_push_logs"}
    for kind in ("free", "free_same", "push_outside"):
        tables = [f["max_ratio_per_regime_joint"] for f in a["free_logs"]
                  if f.get("kind", "free") == kind]
        if tables:
            with warnings.catch_warnings():  # a regime no log reached: nan
                warnings.simplefilter("ignore", RuntimeWarning)
                worst = np.nanmax(np.array(tables, dtype=float), axis=0)
            out[f"worst_{kind}"] = worst.tolist()
            out[names[kind]] = float(np.nanmax(worst))
    return out


def setter(row):
    """Which calibration piece set the margin, in words."""
    pieces = (row.get("analysis") or {}).get("pieces")
    if not pieces:
        return "-"
    top = max(pieces["factors"], key=lambda f: f["factor"])
    return (f"{top['piece'].rsplit('#', 1)[-1]} of {len(pieces['factors'])} pieces: "
            f"{top['regime']} j{top['joint']}")


def print_summary(results):
    """One line per case, monitor and calibration length."""
    print(f"{'case':<9} {'monitor':<11} {'cal':>5} {'margin':>7} {'FA/h exp':>8} {'FA/h':>6} "
          f"{'same/h':>6} {'push-log FA':>11} {'pushes':>7} {'med delay':>9} {'f for 0 FA':>10} "
          f"{'f max':>6}  margin set by")
    for case, r in results["cases"].items():
        for row in r["rows"]:
            if "error" in row:
                print(f"{case:<9} {row['monitor']:<11} {row['length_s']:>5g} failed")
                continue
            c, s, w = row["calibration"], row["result"], margin_window(row)
            print(f"{case:<9} {row['monitor']:<11} {row['length_s']:>5g} {c['margin']:>7.2f} "
                  f"{fmt(c['false_alarms_per_hour'], '.1f'):>8} "
                  f"{s['false_alarms_per_hour']:>6.1f} "
                  f"{fmt(s.get('same_task_per_hour'), '.1f'):>6} "
                  f"{len(s['push_log_false_alarms']):>11d} "
                  f"{s['caught']:>3d}/{s['n_pushes']:<3d} {fmt(s['median_delay_s'], '.3f'):>9} "
                  f"{fmt(max(w.get('need_free', 0), w.get('need_push_logs', 0)) or None):>10} "
                  f"{fmt(w.get('push_min')):>6}  {setter(row)}")


def reprint(path):
    """The tables of a results JSON written by ``--output``, without running anything."""
    results = json.loads(Path(path).read_text())
    for case, r in results["cases"].items():
        print(f"\n== case {case}: injected {json.dumps(r['truth']) or '-'} ==")
        for row in r["rows"]:
            print_row(row)
        for run in r["short_check"]:
            print(f"  gpcd calibrate on {SHORT_LENGTH:g} s, flags {run['flags']}: "
                  + (f"refused: {run['error']}" if run["status"] else
                     f"{len(run['warnings'])} warning(s)"))
            for w in run["warnings"]:
                print(f"    warning: {w}")
    print(f"\nsummary (seed {results['seed']}; {results.get('seconds', 0):.0f} s)")
    print_summary(results)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="smoke run: 2 training runs, 2 x 60 s unseen, 2 push logs, "
                        "cases nominal and stribeck, 2 min calibration only")
    parser.add_argument("--cases", default=None, help=f"comma-separated, of {', '.join(CASES)}")
    parser.add_argument("--seed", type=int, default=38)
    parser.add_argument("--lengths", default=None,
                        help="calibration lengths [s] (default 60,120,300; --quick: 120)")
    parser.add_argument("--train-args", default="", help="extra flags of gpcd train")
    parser.add_argument("--calibrate-args", default="", help="extra flags of gpcd calibrate")
    parser.add_argument("--monitor-args", default="", help="extra flags of gpcd monitor")
    parser.add_argument("--fallback-split", type=float, default=FALLBACK_SPLIT,
                        help="--split SECONDS when gpcd calibrate refuses one log "
                        "(at most duration / 3)")
    parser.add_argument("--no-peer", action="store_true", help="skip i - i_des")
    parser.add_argument("--no-targets", action="store_true",
                        help="the plant logs no controller signals (then no peer)")
    parser.add_argument("--no-analysis", action="store_true")
    parser.add_argument("--commanded-peer", action=argparse.BooleanOptionalAction,
                        default=True,
                        help="also the peer with regimes from the commanded motion, emulated "
                        "(logs with q, qd := target_q, target_qd; the peer reads only "
                        "target_current): what issue 38's 'regime from the commanded "
                        "motion' would do for it (default: on)")
    parser.add_argument("--cli-monitor", choices=("model", "all", "none"), default="model",
                        help="which 2-min rows gpcd monitor scores (default: the trained "
                        "model's; the others are scored in batch with the same detector "
                        "file, and the gpcd monitor row is checked against the batch)")
    parser.add_argument("--workdir", default=None, help="logs, model, detectors (default: tmp)")
    parser.add_argument("--reuse", action="store_true",
                        help="reuse the logs and the model of --workdir")
    parser.add_argument("--train-only", action="store_true",
                        help="simulate the training logs and train, then stop (with "
                        "--workdir, for a later --reuse)")
    parser.add_argument("--output", default=None, help="write the results as JSON here")
    parser.add_argument("--print-json", default=None, metavar="JSON",
                        help="print the tables of a results file written by --output, "
                        "and stop")
    args = parser.parse_args(argv)
    if args.print_json:
        reprint(args.print_json)
        return 0
    try:
        import mujoco  # noqa: F401
    except ImportError:
        print("mujoco is not installed (pip install mujoco): skipped")
        return 0
    args.train_args = shlex.split(args.train_args)
    args.calibrate_args = shlex.split(args.calibrate_args)
    args.monitor_args = shlex.split(args.monitor_args)
    cases = (args.cases.split(",") if args.cases else
             ["nominal", "stribeck"] if args.quick else list(DEFAULT_CASES))
    lengths = ([float(x) for x in args.lengths.split(",")] if args.lengths else
               [MAIN_LENGTH] if args.quick else list(LENGTHS))
    if MAIN_LENGTH not in lengths:
        lengths.append(MAIN_LENGTH)
    peer = not (args.no_peer or args.no_targets)
    work = Path(args.workdir or tempfile.mkdtemp(prefix="little_data_"))
    work.mkdir(parents=True, exist_ok=True)
    print(f"work folder {work}", flush=True)
    start = time.perf_counter()
    setup = plant_setup()

    model = work / "model.skops"
    train_dir = work / "train"
    if args.reuse and model.exists():
        train_paths = sorted(str(p) for p in train_dir.glob("ident_*.csv"))
        record = work / "train.json"
        train_out = {**(json.loads(record.read_text()) if record.exists() else {}),
                     "reused": True}
    else:
        t0 = time.perf_counter()
        train_paths = make_training(train_dir, args.seed, setup, args.quick,
                                    not args.no_targets)
        sim_s = time.perf_counter() - t0
        status, stdout, stderr, secs = gpcd("train", *train_paths, "--robot", ROBOT, "-o",
                                            model, "-q", *args.train_args)
        if status:
            print(stderr)
            raise SystemExit("gpcd train failed")
        train_out = {"stdout": stdout, "warnings": warnings_of(stderr), "seconds": secs,
                     "simulation_seconds": sim_s, "flags": " ".join(args.train_args)}
        (work / "train.json").write_text(json.dumps(train_out, indent=1))
        print(f"gpcd train --robot {ROBOT} {' '.join(args.train_args)} on {len(train_paths)} "
              f"identification logs ({sim_s:.0f} s simulated, {secs:.0f} s training):")
        print("\n".join("  " + line for line in stdout.strip().splitlines()[-14:]), flush=True)
    if args.train_only:
        return 0
    peer_path = None
    if peer:
        peer_path = peer_model(train_paths, work / "peer.joblib")

    results = {"protocol": {k: v for k, v in globals().items() if k.isupper()
                            and isinstance(v, (int, float, tuple, str))},
               "seed": args.seed, "quick": args.quick, "lengths": lengths,
               "train": train_out, "train_logs": [Path(p).name for p in train_paths],
               "flags": {"train": args.train_args, "calibrate": args.calibrate_args,
                         "monitor": args.monitor_args}, "cases": {}}
    for case in cases:
        t0 = time.perf_counter()
        folder = work / case
        if args.reuse and (folder / "logs.json").exists():
            logs = json.loads((folder / "logs.json").read_text())
            logs["calibration"] = {float(k): v for k, v in logs["calibration"].items()}
        else:
            logs = make_logs(folder, case, args.seed, setup, args.quick, lengths,
                             not args.no_targets)
        sim_s = time.perf_counter() - t0
        print(f"\n== case {case}: injected {json.dumps(logs['truth'], default=float) or '-'} "
              f"({sim_s:.0f} s simulating) ==", flush=True)
        from sklearn_gpcd.io import load_recording

        recs = {Path(e["path"]).name: load_recording(e["path"])
                for e in logs["free"] + logs.get("free_same", []) + logs["pushes"]}
        stores = {"model": {}, "i - i_des": {}}  # predictions, per model file
        rows = []
        for length in sorted(lengths, key=lambda x: (x != MAIN_LENGTH, x)):
            monitors = [("model", model, False)] + ([("i - i_des", peer_path, True)]
                                                    if peer and length == MAIN_LENGTH else [])
            for name, path, pickle in monitors:
                cli = length == MAIN_LENGTH and (args.cli_monitor == "all" or
                                                 args.cli_monitor == name == "model")
                row = run_monitor(name, path, logs, recs, folder, length, args, pickle,
                                  stores[name], cli)
                print_row(row)
                sys.stdout.flush()
                rows.append(row)
        if peer and args.commanded_peer:
            cmd_logs = commanded_copies(logs, folder / "commanded", MAIN_LENGTH)
            cmd_recs = {Path(e["path"]).name: load_recording(e["path"])
                        for e in cmd_logs["free"] + cmd_logs["free_same"] + cmd_logs["pushes"]}
            row = run_monitor(PEER_COMMANDED, peer_path, cmd_logs, cmd_recs, folder, MAIN_LENGTH,
                              args, True, {}, False)
            print_row(row)
            sys.stdout.flush()
            rows.append(row)
            del cmd_recs
        del recs, stores
        short = short_check(model, logs, folder, args)
        for r in short:
            print(f"  gpcd calibrate on {SHORT_LENGTH:g} s, flags {r['flags']}: "
                  + (f"refused: {r['error']}" if r["status"] else
                     f"{len(r['warnings'])} warning(s)"))
            for w in r["warnings"]:
                print(f"    warning: {w}")
        results["cases"][case] = {"truth": logs["truth"], "rows": rows, "short_check": short,
                                  "seconds": time.perf_counter() - t0}
    print(f"\nsummary (seed {args.seed}; {time.perf_counter() - start:.0f} s)")
    print_summary(results)
    results["seconds"] = time.perf_counter() - start
    if args.output:
        from _common import write_json

        write_json(args.output, results)  # numpy and NaN made plain, then compact:
        compact = json.loads(Path(args.output).read_text())
        Path(args.output).write_text(json.dumps(compact, separators=(",", ":")))
        print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
