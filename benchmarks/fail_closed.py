"""Fail closed (issue #47): the issue's probes re-run, one table of outcomes.

Every probe of the issue but the 10M-row memory probe (big logs have their
own benchmark), on a small detector of the package's simulator (two 500 Hz
UR10e runs, a linear regressor on the causal inputs: the files, signals and
stops are under test, not the model; ``tests/_live.py``). The files are
crafted by the same functions as ``tests/test_fail_closed.py`` and
``tests/test_model_files.py`` (imported from there, not copied); what this
adds is the count, in one run, of what a user would see:

1. **Malformed and crafted files** through ``gpcd monitor FILE RUN`` (model
   files through ``gpcd calibrate``), in process: edited values (NaN, inf,
   negative, zero thresholds, scales, margins), unstable filters, wrong
   shapes, a schema that is not skops', missing or huge arrays, overwritten
   bytes, a zip bomb, trusted classes called with the file's arguments,
   calls of code (``os.system``, ``eval``, the CLI), a pickle with a
   payload, a truncated or huge pinocchio model text. Counted: exit status
   2 with exactly one ``error:`` line, tracebacks (an exception escaping
   ``main``), anything monitored.
2. **Failed writes**: the old file must stay byte for byte. A file-size
   limit (``RLIMIT_FSIZE`` in a child process) on the detector, the JSON
   report and the figure; the disk full (``ENOSPC``) on a tmpfs of a few
   kB when one can be mounted (root), else said so.
3. **Every stop is reported**: ``SIGTERM`` and ``SIGHUP`` to ``gpcd
   monitor`` offline, ``--replay`` and live (``--rtde`` on the loopback
   server of :mod:`sklearn_gpcd.io._rtde_live`, as
   ``benchmarks/rtde_loopback.py``): exit status, the last line, the JSON
   report's ``end``; to a streamed ``gpcd calibrate`` once its temporary
   work folder has content: exit status, one line, the folder gone, the old
   detector file byte for byte; and a killed link: the blind time the
   summary and the report give against the time the link was down.
4. **Mutated real logs**: the summary of ``benchmarks/mutated_logs.py``
   (``--mutated`` names its JSON; default the committed result).

Run::

    python benchmarks/fail_closed.py [--output DIR] [--mutated PATH]
"""

import argparse
import contextlib
import hashlib
import io
import json
import os
import pickle
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # this checkout's package
sys.path.insert(0, str(ROOT / "tests"))  # the crafting functions of the tests
import test_fail_closed as tfc  # noqa: E402
from test_model_files import _Payload  # noqa: E402

from sklearn_gpcd.cli import main as gpcd  # noqa: E402
from sklearn_gpcd.workflow import DETECTOR_KIND  # noqa: E402

RESULTS = ROOT / "docs" / "_static" / "results"


#: Code a crafted file asks the loader to call (skops' reduce node).
CALLS = [("os.system", ["touch /tmp/gpcd_pwned"]), ("builtins.eval", ["1 + 1"]),
         ("builtins.exec", ["x = 1"]), ("subprocess.call", [["true"]]),
         ("sklearn_gpcd.cli.main", [["robots"]]),
         ("sklearn_gpcd.diagnosis.nominal.NominalModel", ["/any/path.urdf"]),
         ("sklearn_gpcd.diagnosis.report.DiagnosisReport", []),
         ("sklearn_gpcd.robots.robot.Robot", ["ur10"])]


def crafted_files(good):
    """``(name, kind, path)`` of every malformed or crafted file."""
    folder = good["folder"] / "crafted"
    folder.mkdir(exist_ok=True)
    det = good["detector"]
    cases = []
    for attribute in ("thresholds_", "scale_", "margin_"):
        for value in (np.nan, np.inf, -np.inf, -1.0, 0.0):
            name = f"{attribute} = {value}"
            path = tfc.edit_arrays(det, folder / f"{attribute}{value}.skops", attribute,
                                   lambda a, v=value: np.full_like(a, v))
            cases.append((name, "detector", path))

    def one_nan(a):
        a = a.copy()
        a.reshape(-1)[2] = np.nan
        return a

    cases.append(("one threshold NaN", "detector",
                  tfc.edit_arrays(det, folder / "one.skops", "thresholds_", one_nan)))
    for a, label in (([np.nan, np.nan], "NaN"), ([1.0, -1.5], "unstable"),
                     ([1.0, -1.0], "marginally stable"), ([0.0, 0.5], "a[0] = 0")):
        cases.append((f"filter coefficients {label}", "detector",
                      tfc.filter_file(good, folder / f"filter_{label}.skops", a)))
    cases.append(("thresholds for 3 joints", "detector",
                  tfc.edit_arrays(det, folder / "shape.skops", "thresholds_",
                                  lambda a: a[..., :3])))
    cases.append(("min_duration = -3", "detector",
                  tfc.parameter_file(good, folder / "param.skops")))
    data = bytearray(det.read_bytes())
    data[-512:] = b"\0" * 512
    (folder / "overwritten.skops").write_bytes(bytes(data))
    cases.append(("zip directory overwritten", "detector", folder / "overwritten.skops"))
    for case in tfc.ARCHIVE_CASES:
        cases.append((case, "detector", tfc.malformed_archive(
            good, folder / f"{case.replace(' ', '_')}.skops", case)))
    cases.append(("zip bomb 4 GiB", "detector", tfc.zip_bomb(good, folder / "bomb.skops")))
    for target, args in CALLS:
        cases.append((f"calls {target}", "detector",
                      tfc.craft_call(folder / f"call_{target}.skops", good, target, args)))
    pickled = folder / "payload.pkl"
    pickled.write_bytes(pickle.dumps({"kind": DETECTOR_KIND,
                                      "detector": _Payload(folder / "ran")}))
    cases.append(("pickle with a payload", "detector", pickled))
    cases.append(("model coef_ NaN", "model",
                  tfc.edit_arrays(good["model"], folder / "model_nan.skops", "coef_",
                                  lambda a: a * np.nan)))
    cases.extend((f"pinocchio model text {label}", "model", path)
                 for label, path, _ in tfc.pinocchio_files(folder))
    return cases


def run_file(good, kind, path):
    """The CLI on one file, in process: (status, stderr lines, traceback, monitored)."""
    if kind == "detector":
        args = ["monitor", str(path), str(good["recording"])]
    else:
        args = ["calibrate", str(path), str(good["recording"]), str(good["pushed"]), "-q", "-o",
                str(good["folder"] / "never.skops")]
    out, err = io.StringIO(), io.StringIO()
    traceback = None
    tic = time.perf_counter()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            status = gpcd(args)
        except BaseException as exc:  # a traceback the user would see
            status, traceback = "crash", f"{type(exc).__name__}: {exc}"[:300]
    lines = [line for line in err.getvalue().splitlines() if line.strip()]
    return {"status": status, "stderr_lines": len(lines), "first_line": (lines or [""])[0][:300],
            "traceback": traceback, "monitored": "alarm event" in out.getvalue(),
            "seconds": round(time.perf_counter() - tic, 2)}


def files_probe(good):
    rows = []
    for name, kind, path in crafted_files(good):
        row = {"file": name, "kind": kind, **run_file(good, kind, path)}
        row["code_ran"] = (good["folder"] / "crafted" / "ran").exists() \
            or Path("/tmp/gpcd_pwned").exists()
        row["ok"] = (row["status"] == 2 and row["stderr_lines"] == 1 and not row["code_ran"]
                     and row["traceback"] is None and not row["monitored"]
                     and row["first_line"].startswith("gpcd "))
        rows.append(row)
        print(f"  {'ok ' if row['ok'] else 'BAD'} {name:40s} rc {row['status']} "
              f"{row['stderr_lines']} line(s) {row['first_line'][:110]}", flush=True)
    return rows


# ------------------------------------------------------------------ 2. writes
def _digest(path):
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _child(args, cwd, limit=None):
    """``python -c`` or the CLI in a child, with a file-size limit."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    prefix = ("import resource, sys\n"
              f"resource.setrlimit(resource.RLIMIT_FSIZE, ({limit}, {limit}))\n"
              if limit else "import sys\n")
    return subprocess.run([sys.executable, "-c", prefix + args[0], *args[1:]],
                          capture_output=True, text=True, timeout=600, cwd=str(cwd), env=env)


SAVE = ("from sklearn_gpcd.workflow import load_detector, save_detector\n"
        "bundle = load_detector(sys.argv[1])\n"
        "{limit}"
        "try:\n"
        "    save_detector(bundle, sys.argv[1])\n"
        "except OSError as exc:\n"
        "    sys.exit(str(exc))\n")
CLI = "from sklearn_gpcd.cli import main\nsys.exit(main(sys.argv[1:]))\n"


def _write_row(what, how, target, before, done):
    line = next((x for x in done.stderr.splitlines() if "not written" in x
                 or "No space" in x or "intact" in x), (done.stderr.strip().splitlines()
                                                         or [""])[-1])
    intact = Path(target).is_file() and _digest(target) == before
    leftovers = [p.name for p in Path(target).parent.iterdir() if p.name.endswith(".part")]
    row = {"file": what, "how": how, "status": done.returncode, "old_file_intact": intact,
           "temporary_left": leftovers, "line": line[:300],
           "traceback": "Traceback" in done.stderr}
    row["ok"] = (done.returncode != 0 and intact and not leftovers and not row["traceback"]
                 and "intact" in line)
    print(f"  {'ok ' if row['ok'] else 'BAD'} {what:9s} {how:16s} rc {done.returncode} "
          f"intact {intact}: {line[:100]}", flush=True)
    return row


def writes_probe(good, tmp):
    rows = []
    folder = tmp / "writes"
    folder.mkdir()
    detector = folder / "detector.skops"
    report, figure = folder / "report.json", folder / "run.png"
    monitor = ["monitor", str(detector), str(good["recording"]), "--duration", "1"]
    # file-size limit: the detector file (20 kB of about 40), the report, the figure
    shutil.copy(good["detector"], detector)
    before = _digest(detector)
    code = SAVE.format(limit="import resource\nresource.setrlimit(resource.RLIMIT_FSIZE, "
                             "(20000, 20000))\n")
    rows.append(_write_row("detector", "RLIMIT_FSIZE 20 kB", detector, before,
                           _child([code, str(detector)], folder)))
    report.write_text(json.dumps({"old": "x" * 30000}))
    before = _digest(report)
    rows.append(_write_row("report", "RLIMIT_FSIZE 300 B", report, before,
                           _child([CLI, *monitor, "--json", str(report)], folder, 300)))
    figure.write_bytes(b"old figure" * 3000)
    before = _digest(figure)
    rows.append(_write_row("figure", "RLIMIT_FSIZE 20 kB", figure, before,
                           _child([CLI, *monitor, "--plot", str(folder)], folder, 20000)))
    rows.extend(_disk_full(good, tmp))
    return rows


def _disk_full(good, tmp):
    """ENOSPC on a tmpfs just larger than the old file (root only)."""
    mount = tmp / "tiny"
    mount.mkdir()
    size = good["detector"].stat().st_size + 16 * 1024
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(mount)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        why = (done.stderr.strip() or "mount failed")[:200]
        print(f"  --  disk full: no tmpfs ({why})")
        return [{"file": "detector/report", "how": "tmpfs full", "skipped": why}]
    rows = []
    try:
        detector = mount / "detector.skops"
        shutil.copy(good["detector"], detector)
        before = _digest(detector)
        rows.append(_write_row("detector", f"tmpfs of {size // 1024} kB", detector, before,
                               _child([SAVE.format(limit=""), str(detector)], tmp)))
        for p in mount.iterdir():
            p.unlink()  # the detector case: only the old file and the failed temporary
        report = mount / "report.json"
        report.write_text(json.dumps({"old": "x" * 30000}))
        before = _digest(report)
        _fill(mount / "filler")  # the disk is full
        rows.append(_write_row("report", f"tmpfs of {size // 1024} kB", report, before,
                               _child([CLI, "monitor", str(good["detector"]),
                                       str(good["recording"]), "--duration", "1", "--json",
                                       str(report)], tmp)))
    finally:
        subprocess.run(["umount", str(mount)], capture_output=True)
    return rows


def _fill(path):
    """Write ``path`` until the file system is full."""
    handle = open(path, "wb", buffering=0)
    try:
        while True:
            handle.write(bytes(1024))
    except OSError:
        pass
    finally:
        with contextlib.suppress(OSError):
            handle.close()


# ------------------------------------------------------------------ 3. stops
def stops_probe(good, tmp):
    from sklearn_gpcd.io._rtde_live import LoopbackRTDEServer

    rows = []
    detector = str(good["detector"])
    for name in ("SIGTERM", "SIGHUP"):
        signum = getattr(signal, name)
        for source in ("offline", "replay", "live"):
            folder = tmp / f"{name}_{source}"
            folder.mkdir()
            tic = time.perf_counter()
            try:
                if source == "replay":
                    status, err, report = tfc._stop([detector, "--replay", str(good["pushed"])],
                                                     signum, folder, "ALARM")
                elif source == "offline":
                    copies = [shutil.copy(good["pushed"], folder / f"run{k}.csv")
                              for k in range(100)]
                    status, err, report = tfc._stop([detector, *map(str, copies), "--hook",
                                                     "echo started"], signum, folder,
                                                    "started")
                else:
                    with LoopbackRTDEServer(good["run"], speed=1.0,
                                            max_duration=60.0) as server:
                        status, err, report = tfc._stop([detector, "--rtde", "127.0.0.1",
                                                         "--port", str(server.port)], signum,
                                                        folder, "monitoring")
            except AssertionError as exc:  # no report written
                status, err, report = None, str(exc), None
            last = (err.strip().splitlines() or [""])[-1]
            row = {"signal": name, "source": source, "status": status, "last_line": last[:200],
                   "end": None if report is None else report.get("end"),
                   "traceback": "Traceback" in err,
                   "seconds": round(time.perf_counter() - tic, 1)}
            row["ok"] = (status == 128 + signum and report is not None
                         and report["end"].get("reason") == f"stopped by {name}"
                         and not row["traceback"])
            rows.append(row)
            print(f"  {'ok ' if row['ok'] else 'BAD'} {name} {source:8s} rc {status} "
                  f"end {row['end']}", flush=True)
        folder = tmp / f"{name}_calibrate"
        folder.mkdir()
        tic = time.perf_counter()
        status, err, left, intact, parts = tfc.stop_calibration(good, folder, signum)
        lines = err.strip().splitlines()
        row = {"signal": name, "source": "calibrate", "status": status,
               "last_line": (lines or [""])[-1][:200], "work_left": left,
               "old_file_intact": intact, "temporaries_left": parts,
               "traceback": "Traceback" in err, "seconds": round(time.perf_counter() - tic, 1)}
        row["ok"] = (status == 128 + signum and lines == [f"gpcd calibrate: stopped by {name}"]
                     and not left and intact and not parts)
        rows.append(row)
        print(f"  {'ok ' if row['ok'] else 'BAD'} {name} calibrate rc {status} work left "
              f"{left} old file intact {intact}", flush=True)
    return rows


def blind_probe(good):
    """The controller killed at 1.2 s of stream: blind time reported against measured."""
    from sklearn_gpcd.io._rtde_live import LoopbackRTDEServer, RTDEClient
    from sklearn_gpcd.monitoring import MonitorSession

    detector, features = good["objects"]
    session = MonitorSession(detector, features, stall_timeout=0.08)
    with LoopbackRTDEServer(good["run"], speed=2.0, faults=[(600, "kill", 0)],
                            max_duration=30.0) as server:
        client = RTDEClient("127.0.0.1", server.port, 500.0, timeout=2.0).connect()
        tic = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            session.run_rtde(client, "loop", reconnect_timeout=0.5)
        wall = time.perf_counter() - tic
    record = session.faults[-1]
    total = sum(f["blind_s"] or 0.0 for f in session.faults)
    summary = next((line for line in session.summary_text(live=True).splitlines()
                    if "blind" in line), "")
    row = {"fault": "controller killed after 600 packages (1.2 s of stream at 2x)",
           "run_wall_s": round(wall, 3), "faults": len(session.faults),
           "last_fault_kind": record["kind"], "recovered_s": record["recovered_s"],
           "blind_s_last": record["blind_s"], "blind_s_total": round(total, 3),
           "summary_line": summary.strip()[:200]}
    row["ok"] = (record["blind_s"] is not None and record["blind_s"] >= 0.5
                 and f"blind {total:.3f} s in total" in summary)
    print(f"  {'ok ' if row['ok'] else 'BAD'} killed link: blind {row['blind_s_total']} s "
          f"reported, run {row['run_wall_s']} s; {row['summary_line']}", flush=True)
    return [row]


# ------------------------------------------------------------------ 4. logs
def mutated_summary(path):
    if path is None or not Path(path).is_file():
        return {"skipped": f"no result file {path}"}
    data = json.loads(Path(path).read_text())
    return {"source": str(path), "log": data["log"], "n": data["n"], "seed": data["seed"],
            "counts": data["counts"], "silent": [r["mutation"] for r in data["rows"]
                                                 if r["outcome"] == "silent"]}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=None,
                        help="write fail_closed.json and fail_closed.txt here")
    parser.add_argument("--mutated", type=Path, default=RESULTS / "mutated_logs.json")
    parser.add_argument("--skip", nargs="*", default=[],
                        choices=["files", "writes", "stops", "blind"])
    args = parser.parse_args(argv)
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        good = tfc.make_good(tmp)
        for part, probe in (("files", lambda: files_probe(good)),
                            ("writes", lambda: writes_probe(good, tmp)),
                            ("stops", lambda: stops_probe(good, tmp)),
                            ("blind", lambda: blind_probe(good))):
            if part in args.skip:
                continue
            print(f"{part}:", flush=True)
            out[part] = probe()
    out["mutated_logs"] = mutated_summary(args.mutated)
    lines = []
    for part in ("files", "writes", "stops", "blind"):
        rows = [r for r in out.get(part, []) if "skipped" not in r]
        if part in out:
            tracebacks = sum(bool(r.get("traceback")) for r in rows)
            lines.append(f"{part}: {sum(r['ok'] for r in rows)} of {len(rows)} as required, "
                         f"{tracebacks} tracebacks")
    m = out["mutated_logs"]
    if "counts" in m:
        lines.append(f"mutated logs ({m['n']} of {m['log']}): "
                     + ", ".join(f"{v} {k}" for k, v in sorted(m["counts"].items())))
    print("\n".join(lines))
    if args.output is not None:
        args.output.mkdir(parents=True, exist_ok=True)
        (args.output / "fail_closed.json").write_text(json.dumps(out, indent=1, default=str))
        (args.output / "fail_closed.txt").write_text("\n".join(lines) + "\n")
        print(f"wrote {args.output / 'fail_closed.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
