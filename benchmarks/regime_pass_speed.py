"""CPU time of the regime pass over arrays against the sample-by-sample one.

What ``gpcd calibrate`` runs for each of its 12 candidate settings (settle
time 0.5, 1, 2, 3 s x rest reference none, 2, 5 s; ``SELECT_GRID``) and
each recording: :func:`~sklearn_gpcd.detection._regime_batch.batch_regime_pass`
against its peer, :func:`~sklearn_gpcd.detection._regimes.regime_pass` (a
``RegimeState`` stepped sample by sample), in the same run, on the tile of
``benchmarks/big_logs.py`` (one collision-free UR10e run of the simulator
played forward then backward, 500 Hz) repeated to ``--rows`` rows: the
velocities set the regimes, the measured minus the target current stands
for the residual the rest reference tracks.

Printed per candidate: the share of rest samples, CPU microseconds a sample
of each path (``time.process_time``), their ratio, and whether the regime
codes and the signal are equal to the last bit (they must be). ``--json``
writes the same.

Run::

    python benchmarks/regime_pass_speed.py [--rows 200000] [--json out.json]
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # this checkout's package
from sklearn_gpcd._gate import DEFAULT_SIGMA_V  # noqa: E402
from sklearn_gpcd.datasets import simulate_d1  # noqa: E402
from sklearn_gpcd.detection._regime_batch import batch_regime_pass  # noqa: E402
from sklearn_gpcd.detection._regimes import REST, regime_pass  # noqa: E402
from sklearn_gpcd.workflow.calibration import SELECT_GRID  # noqa: E402

RATE = 500.0


def tile_signals(n_rows, seed=0):
    """Velocities and residual stand-in of the big_logs tile, ``n_rows`` rows."""
    rec = simulate_d1("ur10e", n_targets=6, sample_rate=RATE, random_state=seed)
    qd, residual = rec.qd, rec.current - rec.target_current
    qd = np.vstack([qd, -qd[::-1]])  # played backward: velocities change sign
    residual = np.vstack([residual, residual[::-1]])
    reps = -(-n_rows // len(qd))
    return np.tile(qd, (reps, 1))[:n_rows], np.tile(residual, (reps, 1))[:n_rows]


def _cpu(function, *args, **kwargs):
    start = time.process_time()
    out = function(*args, **kwargs)
    return out, time.process_time() - start


def _same(a, b):
    return all(np.array_equal(np.asarray(x).view(np.uint64) if x.dtype == float else x,
                              np.asarray(y).view(np.uint64) if y.dtype == float else y)
               for x, y in zip(a, b))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=200_000)
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    qd, signal = tile_signals(args.rows)
    starts = np.array([0])
    dt = 1.0 / RATE
    rows = []
    print(f"{'settle s':>9}{'tau s':>7}{'rest %':>8}{'per-sample us':>15}{'batch us':>10}"
          f"{'ratio':>8}  equal")
    for settle_time in SELECT_GRID["regimes__settle_time"]:
        for tau in SELECT_GRID["regimes__rest_reference"]:
            settings = dict(sigma_v=DEFAULT_SIGMA_V, settle=int(round(settle_time / dt)),
                            beta=None if tau is None else float(-np.expm1(-dt / tau)))
            slow, t_slow = _cpu(regime_pass, signal, qd, starts, **settings)
            fast, t_fast = _cpu(batch_regime_pass, signal, qd, starts, **settings)
            row = {"settle_time_s": settle_time, "rest_reference_s": tau,
                   "rest_share": float(np.mean(fast[1] == REST)),
                   "per_sample_us": 1e6 * t_slow / args.rows,
                   "batch_us": 1e6 * t_fast / args.rows,
                   "ratio": t_slow / max(t_fast, 1e-9), "equal": _same(slow, fast)}
            rows.append(row)
            print(f"{settle_time:>9g}{'none' if tau is None else f'{tau:g}':>7}"
                  f"{100 * row['rest_share']:>8.1f}{row['per_sample_us']:>15.2f}"
                  f"{row['batch_us']:>10.3f}{row['ratio']:>8.1f}  {row['equal']}", flush=True)
    total = sum(r["per_sample_us"] for r in rows) / sum(r["batch_us"] for r in rows)
    print(f"all 12 candidates: {total:.1f} times less CPU, "
          f"{sum(r['equal'] for r in rows)}/12 equal to the last bit ({args.rows:,} rows)")
    if args.json:
        Path(args.json).write_text(json.dumps({"rows": args.rows, "rate_hz": RATE,
                                               "candidates": rows, "ratio_all": total},
                                              indent=2) + "\n")
    return 0 if all(r["equal"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
