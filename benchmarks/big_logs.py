"""Peak memory of ``gpcd calibrate`` and ``gpcd monitor`` on long logs (issue #47, item 4).

Writes UR RTDE CSV logs of 1M and 10M rows (500 Hz: 33 min and 5.6 h) in a
temporary folder, made of the package's simulator: one collision-free UR10e
run (``simulate_d1``) played forward then backward (velocities negated), so
that the tiles join without a jump, tiled with time stamps going on; the
columns a model reads (timestamp, actual_q, actual_qd, actual_current,
target_current) with ur_rtde's fixed 6 decimals, about 225 bytes a row. A model
is trained on a separate short run (``gpcd train --model sp_c --signals
target_current``), then, as
subprocesses, each measured by its peak resident set size (``ru_maxrss`` of
the child, ``resource.getrusage(RUSAGE_CHILDREN)`` in a fresh Python):

- ``gpcd calibrate MODEL LOG --split 500`` (the long log cut into pieces of
  250k rows left out in turn, the settle time and rest reference chosen
  among 12 candidates: the default);
- ``gpcd monitor DETECTOR LOG --json`` (offline, sample by sample; the
  detector calibrated on a 200k-row log of the same tiles);
- the refusals, before any work: a 720 MB log with a 100,000-column header
  (the issue's 725 MB file passed 4 GB), and
  ``gpcd calibrate`` of two 10M-row logs without ``--split``.

The runs go in parallel (each child's peak measured on its own), so the wall
times are those of a shared machine.

Printed: one row per run (rows, file size, peak RSS, wall time, exit
status, the first line of a refusal); ``--json`` writes the same. The
acceptance of the issue: peak RSS under 1 GB for both on the 10M-row log.
The files are deleted at the end (``--keep`` keeps them); ``--only
calibrate`` (or ``monitor``, ``refusals``) runs those only, and ``--reuse``
keeps a log of ``--dir`` that an earlier ``--keep`` run left (same rows).

Run::

    python benchmarks/big_logs.py [--rows 1000000 10000000] [--json out.json]
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from sklearn_gpcd.datasets import simulate_d1
from sklearn_gpcd.io import Recording, write_rtde_csv
from sklearn_gpcd.io.rtde import rtde_columns

RATE = 500.0
#: Pieces of the long logs for ``--split`` [s]: 250k rows at 500 Hz.
SPLIT_S = 500.0
#: Peak memory asked by the issue [bytes].
BUDGET = 1e9

_MEASURE = """
import resource, subprocess, sys, time
start = time.perf_counter()
run = subprocess.run(sys.argv[1:], capture_output=True, text=True)
peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024
print(repr((run.returncode, peak, time.perf_counter() - start, run.stdout[-3000:],
            run.stderr[-3000:])))
"""


def measured(argv):
    """Exit status, peak RSS [bytes], wall time [s], stdout and stderr tails of ``argv``."""
    out = subprocess.run([sys.executable, "-c", _MEASURE, *map(str, argv)],
                         capture_output=True, text=True, check=True)
    return eval(out.stdout)  # our own repr of a tuple


def tile(seed=0):
    """Names and rows (without time) of the tile: a run forward then backward."""
    rec = simulate_d1("ur10e", n_targets=6, sample_rate=RATE, random_state=seed)
    rec = Recording(time=rec.time, q=rec.q, qd=rec.qd, current=rec.current,
                    target_current=rec.target_current)  # what the model reads
    names, blocks = rtde_columns(rec)
    values = np.hstack(blocks[1:])
    back = values[::-1].copy()
    for k, name in enumerate(names[1:]):
        if "qd" in name:  # velocities change sign backwards in time
            back[:, k] = -back[:, k]
    rows = np.vstack([values, back])
    return names, [",".join(f"{v:.6f}" for v in row) for row in rows.tolist()]


def write_log(path, n_rows, names, rows):
    """``n_rows`` rows of the tile ``rows`` at :data:`RATE`, time going on."""
    with open(path, "w") as handle:
        handle.write(",".join(names) + "\n")
        for start in range(0, n_rows, len(rows)):
            count = min(len(rows), n_rows - start)
            handle.write("".join(f"{(start + k) / RATE!r},{rows[k]}\n" for k in range(count)))
    return path


def wide_log(path, n_columns=100_000, n_rows=1800):
    """A log with a header of ``n_columns`` columns (timestamp, actual_q_0, ...)."""
    names = ["timestamp", "actual_q_0"] + [f"extra_{k}" for k in range(n_columns - 2)]
    row = ",".join(["0.0"] * n_columns)
    with open(path, "w") as handle:
        handle.write(",".join(names) + "\n")
        for _ in range(n_rows):
            handle.write(row + "\n")
    return path


def gpcd(*args):
    return [sys.executable, "-m", "sklearn_gpcd.cli", *map(str, args)]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, nargs="+", default=[1_000_000, 10_000_000])
    parser.add_argument("--json", default=None)
    parser.add_argument("--keep", action="store_true")
    parser.add_argument("--dir", default=None, help="work folder (default: a temporary one)")
    parser.add_argument("--only", nargs="+", choices=("calibrate", "monitor", "refusals"),
                        default=("calibrate", "monitor", "refusals"))
    parser.add_argument("--reuse", action="store_true",
                        help="keep the logs an earlier --keep run left in --dir")
    args = parser.parse_args(argv)
    root = Path(args.dir or tempfile.mkdtemp(prefix="gpcd-big-"))
    root.mkdir(parents=True, exist_ok=True)
    free = shutil.disk_usage(root).free
    need = 250 * max(args.rows) * 1.1
    if free < need:
        print(f"{root}: {free / 1e9:.1f} GB free, the logs need about {need / 1e9:.1f} GB")
        return 1
    results = []
    try:
        train = write_rtde_csv(simulate_d1("ur10e", n_targets=20, sample_rate=RATE,
                                       random_state=1), root / "train.csv")
        model = root / "model.skops"
        status = subprocess.run(gpcd("train", train, "--model", "sp_c", "--n-support", "200",
                                     "--signals", "target_current", "-q", "-o", model), capture_output=True, text=True)
        if status.returncode:
            print(status.stdout, status.stderr)
            return 1
        names, rows = tile()
        small = write_log(root / "calib_small.csv", 200_000, names, rows)
        detector = root / "detector.skops"
        status = subprocess.run(gpcd("calibrate", model, small, "--split", 100, "--no-select",
                                     "-q", "-o", detector), capture_output=True, text=True)
        if status.returncode:
            print(status.stdout, status.stderr)
            return 1
        runs = []
        for n_rows in args.rows:
            log = root / f"log_{n_rows}.csv"
            if not (args.reuse and log.exists()):
                write_log(log, n_rows, names, rows)
            if "calibrate" in args.only:
                runs.append((f"calibrate --split {SPLIT_S:g}", n_rows, log,
                             gpcd("calibrate", model, log, "--split", SPLIT_S, "-q", "-o",
                                  root / f"d{n_rows}.skops")))
            if "monitor" in args.only:
                runs.append(("monitor", n_rows, log, gpcd("monitor", detector, log, "-q",
                                                          "--json", root / f"m{n_rows}.json")))
        if "refusals" in args.only:
            big = root / f"log_{max(args.rows)}.csv"
            if not big.with_name("copy.csv").exists():
                os.link(big, big.with_name("copy.csv"))
            wide = wide_log(root / "wide.csv")
            runs += [("calibrate, two logs, no --split", max(args.rows), big,
                      gpcd("calibrate", model, big, big.with_name("copy.csv"), "-q", "-o",
                           root / "d.skops")),
                     ("calibrate, 100k-column header", 1800, wide,
                      gpcd("calibrate", model, wide, small, "-q", "-o", root / "d.skops"))]
        with ThreadPoolExecutor(len(runs)) as pool:  # each child measured on its own
            done = pool.map(lambda run: _row(run[0], run[1], run[2].stat().st_size,
                                             measured(run[3])), runs)
            for row in done:
                results.append(row)
                print(_line(row), flush=True)
    finally:
        if not args.keep:
            shutil.rmtree(root, ignore_errors=True)
    print()
    print(f"{'run':<32}{'rows':>11}{'file MB':>9}{'peak RSS MB':>13}{'s':>8}{'rc':>4}  "
          "first line of stderr (refusals)")
    for r in results:
        print(_line(r))
    if args.json:
        Path(args.json).write_text(json.dumps({"budget_bytes": BUDGET, "rate_hz": RATE,
                                               "split_s": SPLIT_S, "runs": results},
                                              indent=2) + "\n")
    return 0


def _row(what, n_rows, size, measurement):
    rc, peak, seconds, out, err = measurement
    said = [line for line in err.splitlines() if line.strip()]
    return {"run": what, "rows": n_rows, "file_bytes": size, "peak_rss_bytes": peak,
            "seconds": round(seconds, 1), "exit_status": rc,
            "message": said[-1][:300] if rc and said else "",
            "stdout_tail": out.splitlines()[-3:]}


def _line(r):
    return (f"{r['run']:<32}{r['rows']:>11,}{r['file_bytes'] / 1e6:>9.0f}"
            f"{r['peak_rss_bytes'] / 1e6:>13.0f}{r['seconds']:>8.1f}{r['exit_status']:>4}  "
            f"{r['message'][:120]}")


if __name__ == "__main__":
    sys.exit(main())
