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
   (:func:`sklearn_gpcd.datasets.make_d1`, UR10e, ``sample_rate=500``),
   simulated in chunks of ``--chunk-targets`` D1 targets (each chunk its own
   seed and its own rest-to-rest trajectory) written as RTDE CSV files, the
   last one cut so the total is exactly 1,800,000 rows. The files are cached
   in ``--cache`` (generation is timed separately and is not part of the
   training time). Target: < 10 min, < 4 GB.

Run::

    python benchmarks/cli_train.py [--cache DIR] [--skip-real] [--skip-synthetic]

Timings depend on the load of the machine: say so when other jobs ran.

It prints both logs' wall time, CPU time and peak memory against the
targets; the issue notes hold the measured figures with the machine's load.
"""

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
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
    from sklearn_gpcd.datasets import make_d1
    from sklearn_gpcd.io import write_rtde_csv

    cache.mkdir(parents=True, exist_ok=True)
    paths, total, tic, seed = [], 0, time.perf_counter(), 0
    while total < SYNTHETIC_ROWS:
        path = cache / f"d1_500hz_{chunk_targets}targets_seed{seed}.csv"
        done = cache / (path.name + ".rows")
        if done.exists():
            rows = int(done.read_text())
        else:
            rec = make_d1("ur10e", n_targets=chunk_targets, sample_rate=500.0,
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


if __name__ == "__main__":
    main()
