"""``gpcd train`` with its defaults: wall time and peak memory on large logs (issue #15).

Two logs, each trained by the real command in a child process
(``python -m sklearn_gpcd.cli train ... -o model.skops``, default model
``auto`` -- the comparison of the candidates by the thresholds their
left-out residuals need, then the chosen one --, default ``--n-support auto``),
whose peak resident memory is read with
psutil (the sum over the child and its worker processes, polled every 0.1 s;
without psutil ``resource.getrusage``'s largest single process):

1. **real UR10e**: the 15 unloaded identification runs of Mamedov et al. that
   ``benchmarks/real_ur10e.py`` trains on (unloaded, with target current, the
   held-out run left out), 41,707 rows at ~100 Hz. Target (issue #46): the
   defaults (``--model auto``: the comparison on a subsample, then the
   chosen model) in <= 90 s wall and <= 2 GB on a 2-core machine. The named
   peer, run in the same process tree right after, is ``gpcd train --model
   p_f`` (the cheapest fit, no comparison): the ratio of the two wall times
   is the figure that survives other jobs on the machine. Skipped (with a
   message) when the data are absent.
2. **synthetic 1 hour at 500 Hz**: 1,800,000 rows x 6 joints of the simulator
   (:func:`sklearn_gpcd.datasets.simulate_d1`, UR10e, ``sample_rate=500``),
   simulated in chunks of ``--chunk-targets`` D1 targets (each chunk its own
   seed and its own rest-to-rest trajectory) written as RTDE CSV files, the
   last one cut so the total is exactly 1,800,000 rows. The files are cached
   in ``--cache`` (generation is timed separately and is not part of the
   training time). Target: < 10 min, < 4 GB.

3. **model choice against detection** (issue #46): does the model ``--model
   auto`` chooses detect at least as well as every single model? Each of
   ``gpcd train --model auto / p_f / sp_s / sp_p / sp_c / gp`` (defaults
   otherwise) goes through the README's recipe without ``--plot``:
   ``gpcd calibrate`` on collision-free logs the model never saw, ``gpcd
   monitor`` on pushes and on other unseen collision-free logs. Two plants:

   * the **UR10e split** of ``benchmarks/real_ur10e.py`` (its 12 training
     runs; calibrate on one half of its unseen collision-free set, monitor the
     two push files -- 10 labelled pushes -- and the other half, then the
     halves swapped, as ``benchmarks/readme_recipe.py``);
   * a **simulated UR10 whose target current is the feed-forward only**
     (``simulate(..., target_current="feedforward")``, as a UR logs it): four
     D1 training runs, four collision-free repetitions of a task to calibrate
     on, two unseen repetitions to count false alarms and two with four pushes
     each (two in motion, two at rest, 60-120 Nm on joint 1).

   Per model: pushes caught, alarm onsets on the collision-free logs and
   outside the pushes (false alarms); for ``auto`` the comparison it printed.
   ``--output`` writes ``model_choice.json`` and ``model_choice.txt``.
4. **fold-size sensitivity** of the auto criterion (``--fold-sizes``): the
   comparison of :func:`~sklearn_gpcd.workflow.compare_models` on the UR10e
   split's training runs with (training rows, support rows) per fold of
   (2,500, 100), (5,000, 200) (the default) and (10,000, 400): the choice and
   the threshold scores.

Run::

    python benchmarks/cli_train.py [--cache DIR] [--skip-real] [--skip-synthetic]
        [--choice real,sim] [--fold-sizes] [--output DIR]

Timings depend on the load of the machine: say so when other jobs ran.

It prints both logs' wall time, CPU time and peak memory against the
targets; the issue notes hold the measured figures with the machine's load.
"""

import argparse
import contextlib
import io
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # this checkout's package
from _common import real_data_path  # noqa: E402

HELD_OUT = "ur-20_02_19_15harm50sec.csv"
SYNTHETIC_ROWS = 1_800_000
CHILD = (
    "import resource, sys\n"
    "from sklearn_gpcd.cli import main\n"
    "status = main(sys.argv[1:])\n"
    "peak = max(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,\n"
    "           resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)\n"
    "print(f'PEAK_RSS_KB {peak}', file=sys.stderr)\n"
    "sys.exit(status)\n"
)


def is_unloaded(name):
    """True for runs without payload ("unload" is unloaded), as benchmarks/real_ur10e.py."""
    return "load" not in name.lower().replace("unload", "")


def has_target_current(path):
    """The 31-field layout (the two early 19-field files lack i_c)."""
    with open(path) as handle:
        return len(handle.readline().split(",")) == 31


def _tree_rss(proc):
    """Resident memory of ``proc`` and all its descendants (psutil), in bytes."""
    total = 0
    for p in [proc] + proc.children(recursive=True):
        try:
            total += p.memory_info().rss
        except Exception:  # the process ended meanwhile
            pass
    return total


def run_train(files, output, extra=()):
    """``gpcd train FILES -o OUTPUT`` in a child process.

    Returns (wall seconds, CPU seconds of the child and its children, peak GB,
    stdout). The peak is the largest *sum* of resident memory over the child
    and its worker processes (psutil, polled every 0.1 s) when psutil is
    installed, else ``getrusage``'s largest single process.
    """
    argv = [sys.executable, "-c", CHILD, "train", *map(str, files), "-o", str(output), *extra]
    try:
        import psutil
    except ImportError:
        psutil = None
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    tic = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    peak_tree = 0
    if psutil is not None:
        watched = psutil.Process(proc.pid)
        while proc.poll() is None:
            peak_tree = max(peak_tree, _tree_rss(watched))
            time.sleep(0.1)
    out, err = proc.communicate()
    seconds = time.perf_counter() - tic
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    peak_kb = [int(line.split()[1]) for line in err.splitlines()
               if line.startswith("PEAK_RSS_KB")]
    if proc.returncode != 0:
        sys.stderr.write(err)
        raise SystemExit(f"gpcd train failed with status {proc.returncode}")
    peak = max(peak_tree / 1024**3, peak_kb[0] / 1024**2 if peak_kb else 0.0)
    return seconds, cpu, peak, out


def synthetic_files(cache, chunk_targets):
    """RTDE CSV chunks of a 1-hour 500 Hz D1 log (cached); returns (paths, seconds)."""
    from sklearn_gpcd.datasets import simulate_d1
    from sklearn_gpcd.io import write_rtde_csv

    cache.mkdir(parents=True, exist_ok=True)
    paths, total, tic, seed = [], 0, time.perf_counter(), 0
    while total < SYNTHETIC_ROWS:
        path = cache / f"d1_500hz_{chunk_targets}targets_seed{seed}.csv"
        done = cache / (path.name + ".rows")
        if done.exists():
            rows = int(done.read_text())
        else:
            rec = simulate_d1("ur10e", n_targets=chunk_targets, sample_rate=500.0,
                          random_state=seed)
            rows = min(rec.n_samples, SYNTHETIC_ROWS - total)
            rec = rec.slice(0, rows)
            write_rtde_csv(rec, path)
            done.write_text(str(rows))
            print(f"  simulated chunk {seed}: {rows} rows ({rows / 500:.0f} s), "
                  f"{time.perf_counter() - tic:.0f} s so far", flush=True)
        rows = min(rows, SYNTHETIC_ROWS - total)
        paths.append(path)
        total += rows
        seed += 1
    assert total == SYNTHETIC_ROWS, total
    return paths, time.perf_counter() - tic


#: ``gpcd train --model`` values of the model-choice table, ``auto`` first.
CHOICE_MODELS = ("auto", "p_f", "sp_s", "sp_p", "sp_c", "gp")
#: Simulated plant: robot, and the four pushes of a push log
#: (phase, start as a fraction of the motion or seconds into the rest, torque [Nm]).
SIM_ROBOT = "ur10"
SIM_PUSHES = (("moving", 0.3, 120.0), ("moving", 0.7, -120.0), ("rest", 2.0, 60.0),
              ("rest", 4.0, -60.0))
#: (training rows, support rows) per fold of the fold-size sensitivity.
FOLD_SIZES = ((2_500, 100), (5_000, 200), (10_000, 400))


def gpcd_in_process(argv):
    """``gpcd ARGV`` in this process; returns stdout (raises on a failure)."""
    from sklearn_gpcd.cli import main as gpcd

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = gpcd([str(a) for a in argv])
    if status != 0:
        sys.stderr.write(err.getvalue()[-3000:])
        raise SystemExit(f"gpcd {argv[0]} failed (status {status})")
    return out.getvalue()


def recipe(model, train, calib, work, extra=()):
    """Train (``--model MODEL``), calibrate, monitor: the events and what auto printed."""
    work.mkdir(parents=True, exist_ok=True)
    m, d, e = work / "model.skops", work / "detector.skops", work / "events.json"
    tic = time.perf_counter()
    text = gpcd_in_process(["train", *train, "--model", model, "-q", "-o", m, *extra])
    seconds = {"train": time.perf_counter() - tic}
    choice = [line for line in text.splitlines() if line.startswith(("model choice", "  "))]
    from sklearn_gpcd.workflow import load_model

    chosen = load_model(m).training["model"]
    folds = []
    for name, (cal, mon) in calib.items():
        tic = time.perf_counter()
        gpcd_in_process(["calibrate", m, *cal, "-q", "-o", d])
        gpcd_in_process(["monitor", d, *mon, "-q", "--json", e])
        seconds[name] = time.perf_counter() - tic
        folds.append((name, json.loads(e.read_text())))
    return chosen, choice, folds, seconds


def choice_real(root, work, models=CHOICE_MODELS, halves=("half1", "half2")):
    """The table's UR10e rows: each model through the recipe on the benchmark's split."""
    import readme_recipe
    import real_ur10e as bench

    labels = json.loads(bench.LABELS.read_text())
    train, unseen, _ = bench.split_recordings(root, quick=False)
    train = [Path(r.metadata["source"]) for r in train]
    first, second = readme_recipe.halves(list(unseen))
    calib = {"half1": ([root / k for k in first],
                       [root / k for k in bench.PUSHES + second]),
             "half2": ([root / k for k in second],
                       [root / k for k in bench.PUSHES + first])}
    held = {"half1": second, "half2": first}
    calib = {name: calib[name] for name in halves}
    rows = []
    for model in models:
        chosen, choice, folds, seconds = recipe(model, train, calib, work / model)
        caught = n_pushes = outside = 0
        for name, report in folds:
            res = readme_recipe.score(report["events"], labels, bench.PUSHES, held[name])
            caught += sum(p["caught"] for p in res["pushes"])
            n_pushes += len(res["pushes"])
            outside += (sum(len(v) for v in res["false_alarms_unseen"].values())
                        + len(res["false_alarms_push_files"]))
        rows.append(dict(plant="UR10e split", model=model, chosen=chosen, caught=caught,
                         pushes=n_pushes, false_alarms=outside,
                         seconds={k: round(v, 1) for k, v in seconds.items()},
                         choice=choice))
        print(table_row(rows[-1]), flush=True)
    return rows


def sim_task(seed, n_targets=4):
    """A D1 motion to ``n_targets`` targets, then 6 s at rest; and the motion's length."""
    from sklearn_gpcd.datasets import JointTrajectory, reference_d1

    moves = reference_d1(SIM_ROBOT, n_targets=n_targets, random_state=seed)
    rest = JointTrajectory.rest(moves.at(moves.duration), 6.0)
    return JointTrajectory.concatenate([moves, rest]), moves.duration


def sim_logs(folder, seed=0):
    """RTDE CSV files of the simulated plant, and the push windows ``{file: [(lo, hi)]}``."""
    from sklearn_gpcd.datasets import Contact, simulate
    from sklearn_gpcd.io import write_rtde_csv

    def log(name, reference, k, contacts=()):
        rec = simulate(reference, SIM_ROBOT, contacts=contacts, random_state=seed + k,
                       target_current="feedforward", name=name)
        return write_rtde_csv(rec, folder / f"{name}.csv")

    folder.mkdir(parents=True, exist_ok=True)
    files = {"train": [log(f"train{k}", sim_task(seed + k)[0], k) for k in range(4)]}
    reference, moving = sim_task(seed + 50)
    files["calibrate"] = [log(f"free{k}", reference, 100 + k) for k in range(4)]
    files["unseen"] = [log(f"unseen{k}", reference, 200 + k) for k in range(2)]
    contacts = [Contact(link=1, start=f * moving if phase == "moving" else moving + f,
                        duration=0.8, force=[0.0, torque / 0.2, 0.0], point=[0.2, 0.0, 0.0],
                        frame="local") for phase, f, torque in SIM_PUSHES]
    files["push"] = [log(f"pushes{k}", reference, 300 + k, contacts) for k in range(2)]
    windows = [(c.start, c.start + c.duration + 0.5) for c in contacts]
    return files, windows


def choice_sim(work, models=CHOICE_MODELS):
    """The table's simulated rows: feed-forward target current, pushes on joint 1."""
    files, windows = sim_logs(work / "logs")
    monitor = files["push"] + files["unseen"]
    push_names = {Path(f).name for f in files["push"]}
    rows = []
    for model in models:
        chosen, choice, folds, seconds = recipe(
            model, files["train"], {"all": (files["calibrate"], monitor)},
            work / model, ["--robot", SIM_ROBOT])
        report = folds[0][1]
        caught = outside = 0
        for name in push_names:
            starts = [e["start_s"] for e in report["events"] if e["recording"] == name]
            caught += sum(any(lo <= s <= hi for s in starts) for lo, hi in windows)
            outside += sum(not any(lo <= s <= hi for lo, hi in windows) for s in starts)
        outside += sum(e["recording"] not in push_names for e in report["events"])
        rows.append(dict(plant="simulated UR10, feed-forward target", model=model,
                         chosen=chosen, caught=caught, pushes=len(windows) * len(push_names),
                         false_alarms=outside,
                         seconds={k: round(v, 1) for k, v in seconds.items()},
                         choice=choice))
        print(table_row(rows[-1]), flush=True)
    return rows


def table_row(row):
    """One line of the model-choice table."""
    model = f"auto ({row['chosen'].upper()})" if row["model"] == "auto" else row["model"].upper()
    return (f"{row['plant']:38s} {model:11s} {row['caught']:3d}/{row['pushes']:<3d} "
            f"{row['false_alarms']:6d}   {sum(row['seconds'].values()):7.0f}")


def choice_table(rows):
    """The model-choice table as text, with auto's comparisons and the verdict per plant."""
    out = [f"{'plant':38s} {'model':11s} {'pushes':7s} {'false alarms':12s} {'time [s]':>8s}"]
    out += [table_row(r) for r in rows]
    for plant in dict.fromkeys(r["plant"] for r in rows):
        mine = [r for r in rows if r["plant"] == plant]
        auto = next((r for r in mine if r["model"] == "auto"), None)
        if auto is None:
            continue
        better = [r["model"].upper() for r in mine if r["model"] != "auto" and (
            r["caught"] > auto["caught"] or (r["caught"] == auto["caught"]
                                            and r["false_alarms"] < auto["false_alarms"]))]
        verdict = ("auto detects at least as well as every single model" if not better
                   else f"auto detects worse than {', '.join(better)}")
        out += ["", f"{plant}: {verdict} (more pushes caught first, then fewer false "
                "alarms)", *auto["choice"]]
    return out


def fold_sizes(root):
    """The auto comparison on the UR10e split's training runs at several fold sizes."""
    import real_ur10e as bench
    from sklearn_gpcd.robots import load_robot
    from sklearn_gpcd.workflow import (candidate_models, compare_models, input_signals,
                                       training_set)

    train, _, _ = bench.split_recordings(root, quick=False)
    signals, check = input_signals(train, "auto", "auto")
    data = training_set(list(train), "causal", signals=signals)
    robot = load_robot("ur10e")
    models, _ = candidate_models(robot, data.features.signals_, check)
    out = []
    for rows, support in FOLD_SIZES:
        tic = time.perf_counter()
        comparison = compare_models(data, robot, models, n_support=support, max_rows=rows,
                                    n_jobs=min(6, os.cpu_count() or 1))
        scores = " ".join(f"{m.upper()} {t:.3f}" for m, t in
                          zip(comparison.models, comparison.threshold_score))
        out.append(f"{rows:6d} rows, {support:3d} support: chosen {comparison.best.upper():5s}"
                   f" thresholds (geo. mean, A): {scores}; "
                   f"{time.perf_counter() - tic:.0f} s")
        print(out[-1], flush=True)
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=None, help="UR10e data folder")
    parser.add_argument("--cache", default=os.path.join(tempfile.gettempdir(),
                                                        "gpcd-cli-train-cache"),
                        help="folder for the synthetic 1-hour log (reused across runs)")
    parser.add_argument("--chunk-targets", type=int, default=100,
                        help="D1 targets per simulated chunk (about 300 s each)")
    parser.add_argument("--skip-real", action="store_true")
    parser.add_argument("--skip-synthetic", action="store_true")
    choice_options = {  # the model-choice table and the fold sizes
        "--choice": dict(default="", help="comma-separated plants of the model-choice "
                         "table: real, sim"),
        "--models": dict(default=",".join(CHOICE_MODELS), help="comma-separated gpcd "
                         "train --model values of the table"),
        "--halves": dict(default="half1,half2", help="UR10e split: calibrate on half1 "
                         "and/or half2 of its unseen set"),
        "--fold-sizes": dict(action="store_true", help="the auto comparison at several "
                             "fold sizes (UR10e split)"),
        "--output": dict(type=Path, default=None, help="folder for cli_train.json and "
                         "model_choice.txt"),
    }
    for flag, options in choice_options.items():
        parser.add_argument(flag, **options)
    args = parser.parse_args(argv)
    print(f"cores: {os.cpu_count()}, load average at start: "
          f"{', '.join(f'{v:.1f}' for v in os.getloadavg())}", flush=True)
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        if not args.skip_real:
            root = real_data_path("ur10e_mamedov", args.data) / "identification_data"
            if not root.is_dir():
                print(f"real UR10e data not found ({root}): real part skipped")
            else:
                files = [f for f in sorted(root.glob("*.csv")) if is_unloaded(f.name)
                         and has_target_current(f) and f.name != HELD_OUT]
                print(f"real UR10e: gpcd train (defaults) on {len(files)} unloaded runs ...",
                      flush=True)
                load_before = os.getloadavg()[0]
                seconds, cpu, peak, out = run_train(files, Path(tmp) / "real.skops")
                print(out, end="")
                results.append(("real UR10e, 15 unloaded runs", seconds, cpu, peak, 90, 2.0))
                print(f"  (load average {load_before:.1f} before, "
                      f"{os.getloadavg()[0]:.1f} after)")
                peer = run_train(files, Path(tmp) / "peer.skops", ["--model", "p_f"])
                results.append(("  peer: same runs, --model p_f", *peer[:3], None, None))
                print(f"  peer gpcd train --model p_f: {peer[0]:.1f} s wall, {peer[1]:.1f} s "
                      f"CPU, {peer[2]:.2f} GB; defaults / peer wall time "
                      f"{seconds / peer[0]:.2f}x (load average {os.getloadavg()[0]:.1f})")
        if not args.skip_synthetic:
            print(f"synthetic 1 h at 500 Hz: generating (cache {args.cache}) ...", flush=True)
            files, gen = synthetic_files(Path(args.cache), args.chunk_targets)
            print(f"  {len(files)} files, {SYNTHETIC_ROWS} rows, ready in {gen:.0f} s "
                  "(generation, not timed below)")
            print("synthetic: gpcd train (defaults) ...", flush=True)
            seconds, cpu, peak, out = run_train(files, Path(tmp) / "synthetic.skops",
                                                ["--robot", "ur10e"])
            print(out, end="")
            results.append(("synthetic 1 h, 500 Hz, 1.8 M rows", seconds, cpu, peak, 600, 4.0))
    print()
    print(f"{'log':36s} {'wall [s]':>9s} {'CPU [s]':>8s} {'peak [GB]':>10s}  target")
    for name, seconds, cpu, peak, max_s, max_gb in results:
        if max_s is None:  # a peer: no target
            print(f"{name:36s} {seconds:9.1f} {cpu:8.1f} {peak:10.2f}")
            continue
        ok = "ok" if seconds <= max_s and peak <= max_gb else "MISSED"
        print(f"{name:36s} {seconds:9.1f} {cpu:8.1f} {peak:10.2f}  "
              f"<= {max_s} s, <= {max_gb} GB: {ok}")
    print("CPU = user + system time of gpcd train and its worker processes (all cores); "
          "wall time grows when other jobs share the cores (see the load averages).")
    print(f"load average at end: {', '.join(f'{v:.1f}' for v in os.getloadavg())}")
    report = {"cores": os.cpu_count(), "timing": [
        dict(log=name, wall_s=round(s, 1), cpu_s=round(c, 1), peak_GB=round(g, 2))
        for name, s, c, g, _, _ in results]}
    plants = [p for p in args.choice.split(",") if p]
    if plants or args.fold_sizes:
        root = real_data_path("ur10e_mamedov", args.data)
        have_real = root is not None and Path(root).is_dir()
        rows, models = [], args.models.split(",")
        with tempfile.TemporaryDirectory() as tmp:
            for plant in plants:
                print(f"model choice against detection: {plant} ...", flush=True)
                if plant == "real" and not have_real:
                    print(f"  real UR10e data not found ({root}): skipped")
                elif plant == "real":
                    rows += choice_real(Path(root), Path(tmp) / "real", models,
                                        args.halves.split(","))
                else:
                    rows += choice_sim(Path(tmp) / "sim", models)
                report["model_choice"] = rows
                write_report(args.output, report)
        if rows:
            report["model_choice_table"] = choice_table(rows)
            print("\n".join(report["model_choice_table"]))
        if args.fold_sizes and have_real:
            print("fold-size sensitivity of the auto criterion (UR10e split):", flush=True)
            report["fold_sizes"] = fold_sizes(Path(root))
        report["load_average_end"] = [round(v, 1) for v in os.getloadavg()]
    write_report(args.output, report)


def write_report(folder, report):
    """``cli_train.json`` and (with the table) ``model_choice.txt`` into ``folder``."""
    if folder is None:
        return
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "cli_train.json").write_text(json.dumps(report, indent=1))
    if "model_choice_table" in report:
        (folder / "model_choice.txt").write_text(
            "\n".join(report["model_choice_table"] + report.get("fold_sizes", [])) + "\n")


if __name__ == "__main__":
    main()
