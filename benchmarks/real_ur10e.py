"""Real-robot benchmark: P_f, SP_S and SP_P on the UR10e recordings of Mamedov et al.

The paper's study (Sec. V, simulated in :mod:`sklearn_gpcd.experiments.paper`)
repeated on a real UR10e (data: github.com/shamilmamedov/dynamic_calibration,
Mamedov et al., Frontiers in Robotics and AI 2020; no redistribution licence,
so the data are read in place and never packaged):

1. **train** the three estimators on the *unloaded* Fourier-excitation runs of
   ``identification_data`` (file names without "load"; ``...-unload.csv`` is
   unloaded), except one run held out for calibration and the two early
   19-column files, which lack the target current ``i_c`` that SP_P needs;
2. **nMSE** (Eq. 18) per joint, split into dynamic (``|qd_l| >= sigma_v``)
   and quasi-static samples, on ``validation_data/ur-20_01_17-ptp_10_points``
   (point-to-point motion with stops), the still poses ``p1 .. p10`` and the
   held-out identification run;
3. **thresholds** of the collision detector (low-pass 2 Hz, 50 ms debounce,
   0.1 % of calibration samples flagged) from collision-free data the models
   did not see: the held-out run and the still poses;
4. **monitoring** on the two ``collision_push_pose`` files (a human pushes the
   robot while it holds a pose). The files carry no labels; the push
   intervals below are the data README's estimates by inspection, used for
   shading and for scoring, and are NOT ground truth.

The data logs ``target_current`` (``i_c``) but not ``target_q`` /
``target_qd``, so ``e_q`` and ``de_q`` of the augmented inputs (Eq. 13) are
zero: SP_P's quasi-static kernel only gains ``i_c`` over SP_S.

Run::

    python benchmarks/real_ur10e.py [--quick] [--output DIR] [--data DIR]

It prints progress, the nMSE tables and the detection outcome (as
reStructuredText tables), and writes PNG figures, ``real_ur10e.json`` (all
numbers) and ``real_ur10e_tables.rst.inc`` into ``--output``. Without the data it
prints why and exits 0.
"""

import argparse
import datetime
import platform
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import real_data_path, require_data, rst_table, write_json  # noqa: E402

from sklearn_gpcd._layout import block_columns, column_names  # noqa: E402
from sklearn_gpcd.detection import stack_currents  # noqa: E402
from sklearn_gpcd.experiments.paper import (  # noqa: E402
    ESTIMATORS,
    PaperConfig,
    Progress,
    build_estimators,
    interaction_outcome,
    make_detector,
    split_nmse,
)
from sklearn_gpcd.features import contiguous_segments, make_inputs  # noqa: E402
from sklearn_gpcd.features.inputs import MissingSignalWarning  # noqa: E402
from sklearn_gpcd.io import RecordingWarning, load_recording  # noqa: E402
from sklearn_gpcd.robots import load_robot  # noqa: E402

DATASET = "ur10e_mamedov"
IDENTIFICATION = "identification_data"
#: Unloaded identification run held out to calibrate the detector thresholds.
HELD_OUT = "ur-20_02_19_15harm50sec.csv"
PTP = "validation_data/ur-20_01_17-ptp_10_points.csv"
STILL = [f"validation_data/ur-20_01_17-p{k}.csv" for k in range(1, 11)]
#: Push intervals [s after the first sample]: the data README's ESTIMATES
#: (by inspection of |i - i_des|), not ground truth.
PUSHES = {
    "collision_push_pose/ur-20_01_22-push_pose_1.csv": [(4.7, 5.7), (8.7, 9.3), (12.0, 13.1)],
    "collision_push_pose/ur-20_01_22-push_pose_2.csv": [(2.7, 3.6), (5.2, 5.8), (11.6, 12.3)],
}
SAMPLE_TIME = 0.01  # the logs run at ~100 Hz (median dt 10 ms, jittered)
MIN_DURATION = 5  # debounce: 5 samples = 50 ms
TEST_SETS = ("ptp_10_points", "p1..p10", "held-out identification")
#: The printed tables, for ``.. include::`` in the docs (``*.rst.inc`` is not a page).
TABLES = "real_ur10e_tables.rst.inc"
COLORS = {"P_f": "#7f7f7f", "SP_S": "#1f77b4", "SP_P": "#d62728"}


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


def inputs(recordings):
    """``make_inputs`` (augmented), with its missing-signal warning shown once."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", MissingSignalWarning)
        X, y = make_inputs(recordings, augmented=True)
    messages = {str(w.message) for w in caught if issubclass(w.category, MissingSignalWarning)}
    if messages and not inputs.warned:
        print(f"    note: {sorted(messages)[0]}", flush=True)
        inputs.warned = True
    return X, y


inputs.warned = False


def training_files(root, quick):
    """Unloaded identification runs usable for training, and the held-out run."""
    files = sorted((root / IDENTIFICATION).glob("*.csv"))
    unloaded = [f for f in files if is_unloaded(f.name)]
    skipped_load = [f.name for f in files if not is_unloaded(f.name)]
    train, no_ic = [], []
    for f in unloaded:
        if f.name == HELD_OUT:
            continue
        rec = load(f)
        (train if rec.target_current is not None else no_ic).append(rec)
    if quick:
        train = train[::3]
    return train, load(root / IDENTIFICATION / HELD_OUT), skipped_load, [r.name for r in no_ic]


def push_labels(rec, intervals):
    """Labels 0 / k (k-th estimated push interval) for ``rec``."""
    t = rec.time - rec.time[0]
    labels = np.zeros(rec.n_samples, dtype=int)
    for k, (start, stop) in enumerate(intervals, start=1):
        labels[(t >= start) & (t <= stop)] = k
    return labels


def rest_poses(X, sigma_v, n_joints=6):
    """Joint positions of the rows where every joint is quasi-static."""
    still = np.all(np.abs(X[:, block_columns("qd", n_joints)]) < sigma_v, axis=1)
    return X[still][:, block_columns("q", n_joints)]


def rest_coverage(X_train, test_inputs, sigma_v):
    """How far the quasi-static test poses are from the quasi-static training poses.

    Returns the spread of the training rest poses (max over joints of
    ``|q - median(q)|``) and, per test set, the median over its rest rows of
    the distance (max over joints, rad) to the nearest training rest row.
    """
    from scipy.spatial import cKDTree

    train = rest_poses(X_train, sigma_v)
    tree = cKDTree(train)
    out = {"train_rest_rows": int(len(train)),
           "train_rest_center": np.median(train, axis=0),
           "train_rest_spread": float(np.abs(train - np.median(train, axis=0)).max())}
    for name, X in test_inputs.items():
        q = rest_poses(X, sigma_v)
        out[name] = float(np.median(tree.query(q, p=np.inf)[0])) if len(q) else None
    return out


def static_length_scales(model, n_shortest=3):
    """Shortest length scales of SP_P's gated static ARD kernel, per joint."""
    names = column_names(6, augmented=True)
    out = []
    for kernel in model.kernel_:
        scales = [v for k, v in kernel.get_params().items() if k.endswith("kernel__length_scale")]
        if not scales:
            return None
        ls = np.asarray(scales[0], dtype=float)
        order = np.argsort(ls)[:n_shortest]
        out.append([(names[i], float(ls[i])) for i in order])
    return out


def alarm_episodes(alarm, t, gap=0.3):
    """Contiguous alarm segments, merged when less than ``gap`` seconds apart."""
    episodes = []
    for a, b in contiguous_segments(alarm):
        if episodes and t[a] - t[episodes[-1][1] - 1] < gap:
            episodes[-1] = (episodes[-1][0], b)
        else:
            episodes.append((a, b))
    return episodes


def push_outcome(detector, rec, intervals, sigma_v, tolerance=0.5):
    """Detection on one push file: per estimated push, and alarms outside them.

    ``interaction_outcome`` (the simulator study's scoring) decides per push
    whether an alarm falls inside the estimated interval and how long after
    its estimated start. Because the intervals are estimates, alarm
    *episodes* (alarms less than 0.3 s apart merged) are then attributed to
    a push when they overlap its interval widened by ``tolerance`` seconds;
    the others are listed as "outside", with the joints that fired and
    whether the arm moved (``|qd| > 1e-3`` rad/s within 0.5 s): the commanded
    pose is fixed, so motion means that something pushed the arm.
    """
    rec = rec.replace(labels=push_labels(rec, intervals))
    X, y = inputs(rec)
    outcome = interaction_outcome(detector, X, y, rec, sigma_v)
    mon = detector.monitoring_signal(stack_currents(X, y))
    t = rec.time - rec.time[0]
    for push in outcome["pushes"]:
        idx = np.flatnonzero(rec.labels == push["event"])
        push["joints_fired"] = [int(j) + 1 for j in np.flatnonzero(mon.alarms[idx].any(axis=0))]
    inside, outside = 0, []
    for a, b in alarm_episodes(outcome["alarm"], t):
        if any(t[a] <= stop + tolerance and t[b - 1] >= start - tolerance
               for start, stop in intervals):
            inside += 1
            continue
        near = (t >= t[a] - 0.5) & (t <= t[b - 1] + 0.5)
        outside.append({
            "start_s": float(t[a]), "stop_s": float(t[b - 1]),
            "joints_fired": [int(j) + 1 for j in np.flatnonzero(mon.alarms[a:b].any(axis=0))],
            "arm_moved": bool(np.abs(rec.qd[near]).max() > 1e-3),
        })
    outcome["episodes_at_pushes"] = inside
    outcome["outside"] = outside
    outcome["alarm_fraction"] = float(outcome["alarm"].mean())
    for key in ("false_alarms_moving", "false_alarms_rest"):
        outcome.pop(key)  # counted per interval boundary; superseded by "outside"
    return rec, X, y, mon, outcome


# ----------------------------------------------------------------- figures
def _pyplot():
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    return plt


def plot_nmse(nmse, path):
    """nMSE per joint: ptp dynamic, ptp quasi-static, still poses quasi-static."""
    plt = _pyplot()
    if plt is None:
        return None
    panels = [("ptp_10_points", "dynamic"), ("ptp_10_points", "quasi_static"),
              ("p1..p10", "quasi_static")]
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.0), sharey=True)
    for ax, (test, regime) in zip(axes, panels):
        x = np.arange(6)
        for k, name in enumerate(ESTIMATORS):
            v = np.asarray(nmse[name][test][regime], dtype=float)
            ax.bar(x + (k - 1) * 0.27, np.nan_to_num(v, nan=0.0), 0.27, label=name,
                   color=COLORS[name])
        ax.set_xticks(x, [f"j{j + 1}" for j in x])
        ax.set_yscale("log")
        ax.set_title(f"{test}, {regime.replace('_', '-')}", fontsize=10)
        ax.grid(axis="y", alpha=0.3)
    axes[0].set_ylabel("nMSE (Eq. 18)")
    axes[-1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return Path(path)


def plot_push(rec, mon, detector, outcome, title, path, joints=(0, 1, 2)):
    """``plot_monitoring`` (paper Fig. 3 layout) for three joints, SP_P."""
    from sklearn_gpcd.plotting import plot_monitoring

    plt = _pyplot()
    if plt is None:
        return None
    t = rec.time - rec.time[0]
    fig, axes = plt.subplots(3, len(joints), figsize=(4.2 * len(joints), 5.6), sharex=True)
    for col, j in enumerate(joints):
        ax = axes[:, col]
        plot_monitoring(t, rec.current, mon.predicted, rec.qd, mon.signal,
                        detector.thresholds_, labels=rec.labels, joint=j, ax=ax)
        alarm = mon.alarms[:, j]
        ax[2].plot(t[alarm], np.zeros(alarm.sum()), "|", color="k", ms=8,
                   label="alarm" if alarm.any() else None)
        ax[0].set_title(f"joint {j + 1}", fontsize=10)
        for a in ax[[0, 2]]:
            a.legend(fontsize=7, loc="upper right")
        for a in ax:
            a.tick_params(labelsize=8)
            a.yaxis.label.set_size(8)
    fig.suptitle(title + " -- grey: estimated push intervals (not ground truth)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return Path(path)


# ------------------------------------------------------------------ tables
def nmse_tables(nmse, counts):
    """One RST table per (test set, regime): estimators x joints."""
    out = {}
    header = ["estimator"] + [f"joint {j + 1}" for j in range(6)]
    for test in TEST_SETS:
        for regime in ("dynamic", "quasi_static"):
            rows = [[name] + list(nmse[name][test][regime]) for name in ESTIMATORS]
            rows.append(["samples"] + list(counts[test][f"n_{regime}"]))
            out[f"{test}, {regime.replace('_', '-')}"] = rst_table(header, rows)
    return out


def detection_table(detection):
    header = ["estimator", "file", "push", "interval [s]", "detected", "delay [s]",
              "joints fired"]
    rows = []
    for name in ESTIMATORS:
        for fname, outcome in detection[name]["files"].items():
            for p in outcome["pushes"]:
                rows.append([name, fname, p["event"], f"{p['start_s']:.1f}-{p['stop_s']:.1f}",
                             "yes" if p["detected"] else "NO",
                             "n/a" if p["delay_s"] is None else f"{p['delay_s']:.2f}",
                             ",".join(map(str, p["joints_fired"])) or "-"])
    return rst_table(header, rows)


def outside_table(detection):
    header = ["estimator", "file", "episodes at pushes", "outside", "arm moved",
              "outside onsets [s] (joints)"]
    rows = []
    for name in ESTIMATORS:
        for fname, outcome in detection[name]["files"].items():
            out = outcome["outside"]
            onsets = ", ".join(f"{o['start_s']:.1f} ({','.join(map(str, o['joints_fired']))})"
                               for o in out) or "-"
            rows.append([name, fname, outcome["episodes_at_pushes"], len(out),
                         sum(o["arm_moved"] for o in out), onsets])
    return rst_table(header, rows)


def threshold_table(detection):
    header = ["estimator"] + [f"joint {j + 1}" for j in range(6)]
    return rst_table(header, [[n] + list(detection[n]["thresholds"]) for n in ESTIMATORS])


# -------------------------------------------------------------------- main
def parse_args(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=None,
                        help="UR10e data folder (default: $GPCD_REAL_DATA/ur10e_mamedov or "
                             "../shared/data/real/ur10e_mamedov next to the repository)")
    parser.add_argument("--output", default="real_ur10e_results",
                        help="folder for the figures, the JSON and the tables")
    parser.add_argument("--quick", action="store_true",
                        help="a third of the training files and n_support=500")
    parser.add_argument("--n-support", type=int, default=None,
                        help="posterior support rows per joint (default 5000 as the paper, quick 500)")
    parser.add_argument("--sigma-v", type=float, default=1e-2,
                        help="quasi-static velocity threshold [rad/s] (paper: 1e-2)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--n-jobs", type=int, default=2, help="joints fitted in parallel")
    return parser.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    root = real_data_path(DATASET, args.data)
    require_data(root, "UR10e recordings (Mamedov et al.)",
                 [IDENTIFICATION, PTP, *STILL, *PUSHES])
    n_support = args.n_support or (500 if args.quick else 5000)
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    progress = Progress()
    progress(f"real UR10e benchmark ({'quick' if args.quick else 'full'}): data {root}, "
             f"n_support {n_support}, sigma_v {args.sigma_v}, seed {args.seed}")

    # -- data ------------------------------------------------------------
    train, held_out, skipped_load, no_ic = training_files(root, args.quick)
    progress(f"training on {len(train)} unloaded identification runs; held out {HELD_OUT}; "
             f"left out with payload: {', '.join(skipped_load)}; left out without target "
             f"current: {', '.join(no_ic) or '-'}")
    X, y = inputs(train)
    tests = {"ptp_10_points": [load(root / PTP)], "p1..p10": [load(root / f) for f in STILL],
             "held-out identification": [held_out]}
    test_data = {name: inputs(recs) for name, recs in tests.items()}
    n_samples = {"train": len(y), **{k: len(v[1]) for k, v in test_data.items()}}
    progress("samples: " + ", ".join(f"{k} {v}" for k, v in n_samples.items()))

    # -- training ----------------------------------------------------------
    robot = load_robot("ur10e")
    config = PaperConfig(n_support=n_support, batch_size=min(512, n_support), sigma_v=args.sigma_v)
    models = build_estimators(robot, config, args.seed, args.n_jobs)
    fit_seconds, optimizer = {}, {}
    for name, model in models.items():
        tic = time.perf_counter()
        progress(f"training {name} ({len(y)} rows, n_support {n_support}) ...")
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            model.fit(X, y)
        for message in sorted({f"{w.category.__name__}: {w.message}" for w in caught}):
            print(f"    note ({name}): {message}", flush=True)
        fit_seconds[name] = time.perf_counter() - tic
        optimizer[name] = str(model.optimizer_)
        progress(f"trained {name} in {fit_seconds[name]:.1f} s (optimizer {model.optimizer_}, "
                 f"iterations {np.atleast_1d(model.n_iter_).tolist()})")

    static = static_length_scales(models["SP_P"])
    if static:
        progress("SP_P static (gated) kernel, shortest ARD length scales per joint: " + "; ".join(
            f"j{j + 1} " + ", ".join(f"{c}={v:.2g}" for c, v in row)
            for j, row in enumerate(static)))
    push_inputs = {Path(rel).stem: inputs(load(root / rel))[0] for rel in PUSHES}
    coverage = rest_coverage(X, {**{k: v[0] for k, v in test_data.items()}, **push_inputs},
                             args.sigma_v)
    progress(f"quasi-static coverage: {coverage['train_rest_rows']} training rows with all "
             f"joints at rest, all within {coverage['train_rest_spread']:.3f} rad of q = "
             f"{np.round(coverage['train_rest_center'], 2).tolist()}; median distance of the "
             "test rest rows to the nearest training rest row: " + ", ".join(
                 f"{k} {coverage[k]:.3f} rad" for k in [*test_data, *push_inputs]
                 if coverage[k] is not None))

    # -- nMSE ----------------------------------------------------------------
    nmse, counts = {name: {} for name in ESTIMATORS}, {}
    for test, (Xt, yt) in test_data.items():
        qd = Xt[:, block_columns("qd", 6)]
        for name, model in models.items():
            res = split_nmse(yt, model.predict(Xt), qd, args.sigma_v)
            nmse[name][test] = {k: res[k] for k in ("dynamic", "quasi_static")}
            counts[test] = {k: res[k] for k in ("n_dynamic", "n_quasi_static")}
        progress(f"nMSE on {test} done")

    # -- detection -----------------------------------------------------------
    calib_recs = [held_out] + tests["p1..p10"]
    Xc, yc = inputs(calib_recs)
    groups = np.repeat(np.arange(len(calib_recs)), [r.n_samples for r in calib_recs])
    detection, monitors = {}, {}
    for name, model in models.items():
        detector = make_detector(model, 6).set_params(
            sample_time=SAMPLE_TIME, min_duration=MIN_DURATION)
        detector.fit(stack_currents(Xc, yc), groups=groups)
        files = {}
        for rel, intervals in PUSHES.items():
            rec, Xp, yp, mon, outcome = push_outcome(
                detector, load(root / rel), intervals, args.sigma_v)
            files[Path(rel).stem] = {k: v for k, v in outcome.items() if k != "alarm"}
            monitors[(name, Path(rel).stem)] = (rec, mon, detector, outcome)
        detection[name] = {"thresholds": detector.thresholds_, "files": files}
        n_hit = sum(p["detected"] for f in files.values() for p in f["pushes"])
        n_out = sum(len(f["outside"]) for f in files.values())
        progress(f"detector {name}: {n_hit}/6 estimated pushes detected, {n_out} alarm "
                 "episode(s) outside the estimated intervals")

    # -- figures -------------------------------------------------------------
    figures = {}
    path = plot_nmse(nmse, out / "real_ur10e_nmse.png")
    if path:
        figures["nmse"] = path.name
    for rel in PUSHES:
        stem = Path(rel).stem
        rec, mon, detector, outcome = monitors[("SP_P", stem)]
        path = plot_push(rec, mon, detector, outcome, f"{stem}, SP_P",
                         out / f"real_ur10e_{stem}.png")
        if path:
            figures[stem] = path.name

    # -- report --------------------------------------------------------------
    tables = nmse_tables(nmse, counts)
    text = []
    for title, table in tables.items():
        text += [f"nMSE (Eq. 18), {title}", "", table, ""]
    text += ["Detector thresholds sigma_CD [A] (filtered residual; calibrated on "
             f"{HELD_OUT} + p1..p10)", "", threshold_table(detection), ""]
    text += ["Detection on the push files (intervals are estimates, not ground truth)", "",
             detection_table(detection), ""]
    text += ["Alarm episodes (alarms < 0.3 s apart merged) at the estimated pushes (+/- 0.5 s) "
             "and outside them; 'arm moved': abs(qd) > 1e-3 rad/s within 0.5 s of the episode", "",
             outside_table(detection), ""]
    report = "\n".join(text)
    print("\n" + report, flush=True)
    (out / TABLES).write_text(report)

    results = {
        "command": " ".join(["python", "benchmarks/real_ur10e.py", *(argv or sys.argv[1:])]),
        "date": datetime.date.today().isoformat(),
        "machine": f"{platform.machine()}, {platform.python_version()}",
        "mode": "quick" if args.quick else "full",
        "data": str(root),
        "n_support": n_support, "sigma_v": args.sigma_v, "seed": args.seed,
        "train_files": [r.name for r in train], "held_out": HELD_OUT,
        "left_out_payload": skipped_load, "left_out_no_target_current": no_ic,
        "n_samples": n_samples, "fit_seconds": fit_seconds, "optimizer": optimizer,
        "kernels": {name: [str(k) for k in m.kernel_] for name, m in models.items()},
        "sp_p_static_shortest_length_scales": static, "rest_coverage": coverage,
        "nmse": nmse, "counts": counts, "detection": detection, "figures": figures,
        "push_intervals_estimated": {Path(k).stem: v for k, v in PUSHES.items()},
    }
    results["elapsed_s"] = progress.elapsed
    write_json(out / "real_ur10e.json", results)
    progress(f"wrote {out / 'real_ur10e.json'}, {out / TABLES} and "
             f"{len(figures)} figure(s); total {progress.elapsed:.0f} s")
    return results


if __name__ == "__main__":
    main()
