"""Soak test (issue #35): the live monitor over an accelerated shift with random faults.

The loopback RTDE server (127.0.0.1, its own thread, bounded by
``max_duration``) streams a collision-free run over and over, time stamps
going on, at 10x real time, with pushes at 0.5, 2.2, 4.0 and 6.0 s of each
repeat and, in every other repeat, one fault drawn with a seed (link reset,
stall, samples lost, clock jumping an hour, unknown packages, frozen stamps,
NaN currents, malformed packages, a broken package size) into
:meth:`MonitorSession.run_rtde`. Every injected fault must be reported as a
blind period, every push clear of blind periods (and of the warm-up after
them) must be detected, and memory must stay flat: allocated blocks grow
only with the events and fault records the report keeps.

The default version streams 8 repeats (62 s of robot time, about 6 s);
``-m slow`` runs 200 (26 simulated minutes, about 3 minutes).
"""

import sys

import numpy as np
import pytest
from _live import PUSH_S, RATE, free_runs, linear_bundle, with_pushes

from sklearn_gpcd.io._rtde_live import LoopbackRTDEServer, RTDEClient
from sklearn_gpcd.monitoring import MonitorSession

PUSHES = (0.5, 2.2, 4.0, 6.0)
SPEED = 10.0
STALL = 0.08  # [s]: a loaded test machine may not schedule the client for 20 ms
#: fault kind -> (value, samples it spans after its sample)
SOAK_FAULTS = {"drop": (0, 0), "stall": (0.2, 0), "gap": (500, 500),
               "clock_back": (-3600.0, 0), "clock_forward": (3600.0, 0),
               "unknown": (100, 100), "freeze": (50, 50), "nan": (50, 50),
               "malformed": (60, 60), "bad_size": (0, 0)}
LOST = 1500  # samples a reset link may lose before the fault's sample (in flight)


@pytest.fixture(scope="module")
def parts():
    runs = free_runs()
    detector, features = linear_bundle(runs)
    return detector, features, with_pushes(runs[0], PUSHES)


def injected_faults(n, repeats, seed):
    """``[(sample, kind, value, span)]``: one fault in every other repeat."""
    rng = np.random.default_rng(seed)
    out = []
    for r in range(1, repeats, 2):
        kind = str(rng.choice(sorted(SOAK_FAULTS)))
        value, span = SOAK_FAULTS[kind]
        out.append((r * n + int(rng.integers(300, n - 300 - span)), kind, value, span))
    return out


def server_faults(faults):
    names = {"clock_back": "clock_jump", "clock_forward": "clock_jump"}
    return [(k, names.get(kind, kind), value) for k, kind, value, _ in faults]


def run_soak(parts, repeats, seed):
    detector, features, stream = parts
    n, t0 = stream.n_samples, stream.time[0]

    def row(stamp):
        """Sample index of the whole stream from a time stamp (clock jumps: +-1 h)."""
        u = stamp - t0
        return round((u - 3600.0 * round(u / 3600.0)) * RATE)

    pushes = np.array([r * n + int(p * RATE) for r in range(repeats) for p in PUSHES])
    hit = np.zeros(pushes.size, dtype=bool)
    session = MonitorSession(detector, features, stall_timeout=STALL)
    tick = session.tick

    def watched(t, fields, received=None):
        status = tick(t, fields, received)
        if status == "collision" and np.isfinite(t):
            k = row(t)
            inside = (pushes <= k) & (k < pushes + int(PUSH_S * RATE))
            hit[inside] = True
        return status

    session.tick = watched
    faults = injected_faults(n, repeats, seed)
    blocks = {}
    with LoopbackRTDEServer(stream, speed=SPEED, faults=server_faults(faults), repeat=repeats,
                            max_duration=repeats * stream.duration / SPEED + 60) as server:
        client = RTDEClient("127.0.0.1", server.port, RATE, timeout=2.0).connect()
        original = client.receive
        mark = 2 * n  # allocated blocks after two repeats, and at the end

        def receive(deadline=None):
            if "start" not in blocks and server.n_sent > mark:
                blocks["start"] = (sys.getallocatedblocks(), len(session.events),
                                   len(session.faults))
            return original(deadline)

        client.receive = receive
        session.run_rtde(client, "soak", reconnect_timeout=5.0)
    blocks["end"] = (sys.getallocatedblocks(), len(session.events), len(session.faults))
    return session, faults, pushes, hit, row, blocks


@pytest.mark.parametrize("repeats", [8, pytest.param(200, marks=pytest.mark.slow)])
def test_soak_every_fault_reported_every_clear_push_detected_memory_flat(parts, repeats,
                                                                        capsys):
    session, faults, pushes, hit, row, blocks = run_soak(parts, repeats, seed=repeats)
    capsys.readouterr()
    assert session.end_reason == "the controller paused the stream"
    records = session.faults
    blind = [(row(f["last_stamp"]) if f["last_stamp"] is not None else -1,
              row(f["recovered_stamp"]) if f["recovered_stamp"] is not None else 1 << 40)
             for f in records]
    # every injected fault: a blind period starting near it
    for k, kind, _, span in faults:
        assert any(k - LOST <= start <= k + span for start, _ in blind), (k, kind, records)
    # every push clear of faults and warm-ups is detected
    warm = int(session.warmup_s * RATE) + 20
    clear = np.ones(pushes.size, dtype=bool)
    for start, end in blind:
        clear &= (pushes + int(PUSH_S * RATE) <= start) | (pushes >= end + warm)
    for k, _, _, span in faults:
        clear &= (pushes + int(PUSH_S * RATE) < k - LOST) | (pushes > k + span + warm)
    assert clear.sum() >= pushes.size // 2
    assert hit[clear].all(), pushes[clear & ~hit]
    # memory: the report's events and fault records, nothing per tick
    (start, events0, faults0), (end, events1, faults1) = blocks["start"], blocks["end"]
    assert end - start < 1000 + 40 * ((events1 - events0) + (faults1 - faults0))
