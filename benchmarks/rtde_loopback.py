"""``gpcd monitor --rtde`` end to end over a loopback RTDE server: latency and drops.

A simulated UR10e recording at 500 Hz (the e-Series RTDE rate; the paper's
interaction test with two current bumps added, which the controller's target
current does not explain) is served by
:class:`sklearn_gpcd.io._rtde_live.LoopbackRTDEServer` on 127.0.0.1, in a
separate process, at its own time stamps (real time). ``gpcd monitor
DETECTOR --rtde 127.0.0.1 --port P`` receives it through the CLI's RTDE
client (protocol 2) and decides every tick with ``StreamingMonitor.update_raw``.
Printed: tick latency from receiving a data package to the decision (p50,
p99, max), how far the decisions fall behind the stream's clock (packages
waiting in the socket buffer included), dropped samples (gaps in the
controller time stamps), the blind periods (no valid decision for more than
the stall bound, 20 ms at 500 Hz: a scheduling stall of either process is
one, and resets the monitor) and whether
the alarm events equal ``gpcd monitor DETECTOR FILE`` on the same recording.
The detector is made by the CLI too: ``gpcd train --model sp_c`` (or
``--model sp_p``, which adds the rigid-body mean's per-tick pinocchio call)
and ``gpcd calibrate`` on collision-free 500 Hz runs.

Run::

    python benchmarks/rtde_loopback.py [--seconds 60] [--model sp_c] [--output DIR]
"""

import argparse
import json
import multiprocessing
import sys
import tempfile
import time
from pathlib import Path

from sklearn_gpcd.cli import main as gpcd
from sklearn_gpcd.datasets import simulate_d1, simulate_interaction_test
from sklearn_gpcd.io import load_recording, write_rtde_csv

RATE = 500.0


def _serve(path, queue, max_duration):
    """Child process: serve ``path`` over RTDE on 127.0.0.1, real time."""
    from sklearn_gpcd.io._rtde_live import LoopbackRTDEServer

    server = LoopbackRTDEServer(load_recording(path), speed=1.0, max_duration=max_duration)
    with server:
        queue.put(server.port)
        server.join(timeout=max_duration + 5.0)
    queue.put({"n_sent": server.n_sent, "max_send_lag_ms": server.max_send_lag * 1e3})


def make_data(folder, seconds, seed=0):
    """Collision-free 500 Hz runs and a ``seconds`` long run with two current bumps."""
    free = [write_rtde_csv(simulate_d1("ur10e", n_targets=3, sample_rate=RATE, random_state=s),
                           folder / f"free{s}.csv", robot_comment=True) for s in range(3)]
    rec = simulate_interaction_test("ur10e", sample_rate=RATE, random_state=seed,
                                rest_duration=5.0)
    rec = rec.slice(0, int(seconds * RATE)) if rec.duration > seconds else rec
    t = rec.time - rec.time[0]
    current = rec.current.copy()
    for start, joint in ((0.3 * t[-1], 1), (0.7 * t[-1], 0)):
        current[(t >= start) & (t < start + 0.4), joint] += 1.0
    test = write_rtde_csv(rec.replace(current=current), folder / "stream.csv",
                          robot_comment=True)
    return free, test


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="stream length [s]")
    parser.add_argument("--model", default="sp_c", choices=["sp_c", "sp_p"])
    parser.add_argument("--n-support", default="300")
    parser.add_argument("--output", default=None, help="folder for the files (default: tmp)")
    args = parser.parse_args(argv)
    folder = Path(args.output or tempfile.mkdtemp(prefix="rtde-loopback-"))
    folder.mkdir(parents=True, exist_ok=True)
    tic = time.perf_counter()
    free, test = make_data(folder, args.seconds)
    rec = load_recording(test)
    print(f"data: {len(free)} collision-free runs, stream {rec.n_samples} samples "
          f"({rec.duration:.1f} s at {RATE:g} Hz) in {time.perf_counter() - tic:.0f} s",
          flush=True)
    model, det = folder / "model.skops", folder / "detector.skops"
    assert gpcd(["train", *map(str, free[:2]), "--model", args.model, "--n-support",
                 args.n_support, "-q", "-o", str(model)]) == 0
    assert gpcd(["calibrate", str(model), *map(str, free), "-q", "-o", str(det)]) == 0
    offline = folder / "offline.json"
    assert gpcd(["monitor", str(det), str(test), "-q", "--json", str(offline)]) == 0

    ctx = multiprocessing.get_context("spawn")
    queue = ctx.Queue()
    server = ctx.Process(target=_serve, args=(str(test), queue, rec.duration + 60.0))
    server.start()
    port = queue.get(timeout=60)
    live = folder / "live.json"
    status = gpcd(["monitor", str(det), "--rtde", "127.0.0.1", "--port", str(port),
                   "--json", str(live)])
    sent = queue.get(timeout=rec.duration + 70.0)
    server.join(timeout=10)
    assert status in (0, 3)  # 3: the monitor was blind at some time (a FAULT line)
    saved = json.loads(live.read_text())
    stats, faults = saved["live"], saved["faults"]
    events = {k: [(e["start_s"], e["end_s"], e["joints"])
                  for e in json.loads(p.read_text())["events"]]
              for k, p in (("offline", offline), ("live", live))}
    same = events["offline"] == events["live"]
    print(f"\nRTDE loopback, {args.model.upper()}, {rec.n_samples} samples at {RATE:g} Hz "
          f"({rec.duration:.1f} s), server in its own process (max send lag "
          f"{sent['max_send_lag_ms']:.2f} ms, {sent['n_sent']} packages sent)")
    print(f"  tick latency receive -> decision: p50 {stats['latency_ms_p50']:.3f} ms, "
          f"p99 {stats['latency_ms_p99']:.3f} ms, max {stats['latency_ms_max']:.3f} ms")
    print(f"  ticks received {stats['n_ticks']}, dropped samples {stats['dropped_samples']}")
    print(f"  decisions at most {stats['behind_stream_ms_max']:.1f} ms behind the stream's "
          "clock (time stamps; queued packages included)")
    print(f"  alarm events: live {len(events['live'])}, offline {len(events['offline'])}, "
          f"identical: {same}")
    print(f"  blind periods (no valid decision for more than the stall bound, monitor "
          f"reset): {len(faults)}" + "".join(f"; {f['kind']} at {f['start_s']:.3f} s"
                                              for f in faults[:5]))
    summary = {"model": args.model, "n_samples": rec.n_samples, "seconds": rec.duration,
               "rate_hz": RATE, **stats, **sent, "events_identical": same,
               "n_events": len(events["live"]), "n_blind": len(faults),
               "exit_status": status}
    (folder / "rtde_loopback.json").write_text(json.dumps(summary, indent=2))
    print(f"wrote {folder / 'rtde_loopback.json'}")
    return summary


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
