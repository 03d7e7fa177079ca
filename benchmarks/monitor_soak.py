"""Memory of the live monitor over a simulated shift: after 1 hour and after 8 hours.

:class:`sklearn_gpcd.monitoring.MonitorSession` is fed a simulated 500 Hz UR10e
stream as fast as it can take it, each sample with its arrival time
(``received``): the live path, with its statistics, fault handling and
events, without the socket (``tests/test_monitoring.py`` and the soak test
drive the same session through the loopback RTDE server). The stream is a
collision-free run (it calibrated the detector) repeated with its time
stamps going on, a push (2 A on joint 2 for 0.3 s) every 10 s of stream
and, every 10 minutes, one fault drawn with a seed: all-NaN currents or
frozen time stamps for 50 samples, the controller clock jumping an hour
back or forth, 1 s of samples lost, or one infinite time stamp.

The detector is a linear model on the causal inputs with per-joint
thresholds (1.5x the largest excursion of the calibration runs): the
session's memory does not depend on the regressor, and it keeps a shift to
minutes. The issue's peer is the monitor before it: per-tick latency and
stamp lists, 96 bytes per tick (173 MB per hour at 500 Hz).

Printed: resident set size (RSS, after a full garbage collection) after 1
simulated hour and after 8, their ratio (acceptance: within 10 %), ticks per
second, faults injected and reported, pushes detected.

Run::

    python benchmarks/monitor_soak.py [--hours 8] [--checkpoint 1] [--seed 0]
"""

import argparse
import contextlib
import gc
import json
import os
import sys
import time
from pathlib import Path

import numpy as np
from sklearn.linear_model import LinearRegression

from sklearn_gpcd.datasets import simulate_d1
from sklearn_gpcd.detection import AlarmRule, CollisionDetector, stack_currents
from sklearn_gpcd.features import CausalFeatures
from sklearn_gpcd.monitoring import MonitorSession

RATE = 500.0
PUSH_EVERY, PUSH_S, PUSH_A = 10.0, 0.3, 2.0  # s, s, A
FAULT_EVERY = 600.0  # s of stream
FAULTS = ("nan", "freeze", "clock_back", "clock_forward", "lost", "inf")
BLINDING = {"nan", "freeze", "clock_back", "clock_forward", "lost"}


def rss_bytes():
    """Resident set size of this process [bytes] (Linux /proc; else the peak)."""
    try:
        pages = int(Path("/proc/self/statm").read_text().split()[1])
        return pages * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        import resource

        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def setup():
    """The detector, its features and the run streamed over and over."""
    runs = [simulate_d1("ur10e", n_targets=2, sample_rate=RATE, random_state=s) for s in range(3)]
    features = CausalFeatures().fit(runs)
    X = np.vstack([stack_currents(features.transform(r), r.current) for r in runs])
    rule = AlarmRule("per_joint", false_alarm_rate=0.0, margin=1.5, filter_cutoff=10.0,
                     min_duration=5)
    detector = CollisionDetector(LinearRegression(), n_joints=6, sample_time=1 / RATE,
                                 rules=rule).fit(X)
    return detector, features, runs[0]


def schedule(n_ticks, rng):
    """``{tick: fault}``: one fault drawn per FAULT_EVERY seconds, mid-interval."""
    every = int(FAULT_EVERY * RATE)
    return {k + int(rng.integers(every // 4, 3 * every // 4)): str(rng.choice(FAULTS))
            for k in range(0, n_ticks, every)}


def soak(session, run, n_ticks, checkpoints, rng, out):
    """Feed ``n_ticks`` samples; RSS at each checkpoint tick; counters in ``out``."""
    n, dt = run.n_samples, 1.0 / RATE
    names = ("q", "qd", "current", "target_current", "target_q", "target_qd")
    columns = {f: getattr(run, f) for f in names if getattr(run, f) is not None}
    push_len, push_every = int(PUSH_S * RATE), int(PUSH_EVERY * RATE)
    faults = schedule(n_ticks, rng)
    offset, pending, last_t = 0.0, None, None
    push_hit = np.zeros(n_ticks // push_every + 1, dtype=bool)
    push_ok = np.ones_like(push_hit)  # no fault near the push, the whole push streamed
    push_ok[-1] = (push_ok.size - 1) * push_every + push_len <= n_ticks
    session.start("soak")
    k = 0
    while k < n_ticks:
        if k in checkpoints:
            gc.collect()
            out["rss"][checkpoints[k]] = rss_bytes()
        kind = faults.get(k)
        if kind is not None:
            out["injected"][kind] = out["injected"].get(kind, 0) + 1
            start = k // push_every * push_every
            push_ok[start // push_every] &= k < start - 100 or k > start + push_len
            push_ok[start // push_every + 1] &= k + 600 < start + push_every
            if kind == "clock_back":
                offset -= 3600.0
            elif kind == "clock_forward":
                offset += 3600.0
            elif kind == "lost":
                k += int(RATE)
            else:
                pending = [kind, 1 if kind == "inf" else 50]
        row = k % n
        t = k * dt + offset
        fields = {f: v[row] for f, v in columns.items()}
        if k % push_every < push_len:
            current = fields["current"].copy()
            current[1] += PUSH_A
            fields["current"] = current
        if pending is not None:
            if pending[0] == "nan":
                fields["current"] = fields["current"] * np.nan
            elif pending[0] == "freeze":
                t = last_t
            else:
                t = np.inf
            pending[1] -= 1
            pending = pending if pending[1] > 0 else None
        status = session.tick(t, fields, received=time.perf_counter())
        if status == "collision" and k % push_every < push_len:
            push_hit[k // push_every] = True
        if np.isfinite(t):
            last_t = t
        k += 1
    out["pushes"] = int(push_ok.sum()), int((push_hit & push_ok).sum())
    session.finish()


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=8.0, help="simulated shift [h]")
    parser.add_argument("--checkpoint", type=float, default=1.0,
                        help="first memory reading [h of stream]")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--output", default=None, help="write the figures as JSON here")
    args = parser.parse_args(argv)
    detector, features, run = setup()
    session = MonitorSession(detector, features)
    n_ticks = int(args.hours * 3600 * RATE)
    first = int(args.checkpoint * 3600 * RATE)
    out = {"rss": {}, "injected": {}}
    rng = np.random.default_rng(args.seed)
    tic = time.perf_counter()
    with open(os.devnull, "w") as sink, contextlib.redirect_stdout(sink):  # FAULT lines
        soak(session, run, n_ticks + 1, {first: "first", n_ticks: "last"}, rng, out)
    seconds = time.perf_counter() - tic
    rss_1, rss_8 = out["rss"]["first"], out["rss"]["last"]
    blinding = sum(v for k, v in out["injected"].items() if k in BLINDING)
    eligible, detected = out["pushes"]
    stats = session.live_statistics()
    print(f"MonitorSession soak: {args.hours:g} h of simulated {RATE:g} Hz stream "
          f"({n_ticks} ticks) in {seconds:.0f} s ({n_ticks / seconds:.0f} ticks/s), seed "
          f"{args.seed}, linear detector")
    print(f"  RSS after {args.checkpoint:g} h: {rss_1 / 2**20:.1f} MiB; after {args.hours:g} h: "
          f"{rss_8 / 2**20:.1f} MiB; ratio {rss_8 / rss_1:.4f} (acceptance: within 10 %)")
    print(f"  faults injected {sum(out['injected'].values())} "
          f"({', '.join(f'{k} {v}' for k, v in sorted(out['injected'].items()))}); of those "
          f"that blind the monitor ({blinding}), blind periods reported {session.n_blind}")
    print(f"  pushes clear of faults {eligible}, detected {detected}; sensor faults counted "
          f"{session.recordings[-1]['n_sensor_faults']}; latency p50 "
          f"{stats['latency_ms_p50']:.3f} ms, p99 {stats['latency_ms_p99']:.3f} ms")
    summary = {"hours": args.hours, "checkpoint_h": args.checkpoint, "seed": args.seed,
               "n_ticks": n_ticks, "seconds": seconds, "rss_checkpoint": rss_1,
               "rss_end": rss_8, "ratio": rss_8 / rss_1, "injected": out["injected"],
               "n_blind": session.n_blind, "pushes_clear": eligible,
               "pushes_detected": detected, "live": stats}
    if args.output:
        Path(args.output).write_text(json.dumps(summary, indent=2))
        print(f"wrote {args.output}")
    return summary


if __name__ == "__main__":
    result = main()
    sys.exit(0 if abs(result["ratio"] - 1) <= 0.1 else 1)
