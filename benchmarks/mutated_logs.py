"""Mutated copies of a real push log through ``gpcd monitor`` (issue #47, point 5).

Acceptance: "of 200 mutated copies of a real push log (byte flips, scaled and
swapped columns, duplicated stamps, inf), 0 silent changes of the events:
each either unchanged, or warned or refused naming the column".

The log is ``collision_push_pose/ur-20_01_22-push_pose_1.csv`` of the UR10e
recordings (``benchmarks/real_ur10e.py``). The detector is the README's
recipe with its defaults (``benchmarks/readme_recipe.py``, run ``all``):
``gpcd train`` on the training runs, ``gpcd calibrate`` on all of the unseen
collision-free set ``C``; both are cached in ``--cache`` (default
``/tmp/gpcd_mutated_logs``) and reused when present.

Each mutated copy is drawn with a fixed seed from the families below and run
through ``gpcd monitor`` in process (the checked-out code). Outcomes:

* ``unchanged``: same alarm events as the original (onsets and ends within
  ``TOLERANCE_S``), no warning needed;
* ``warned``: a warning names a column of the mutated family, or any warning
  when the events are unchanged;
* ``refused``: exit status 2 with one line naming the column;
* ``crash``: a Python traceback;
* ``silent``: different events and no warning nor refusal naming a column --
  the defect this benchmark counts (target 0).

False warnings (``--clean``): the same checks (:func:`sklearn_gpcd.workflow.
check_signals`, all kinds collected) over every UNMUTATED real recording: the
45 UR10e CSVs against the detector (those without ``target_current``, which
the model needs, and the other arms, Panda and UR10, through the model-free
checks of :class:`~sklearn_gpcd.io.SignalCheck`). The checks' constants
were chosen on the recordings the model knows (``tuning``: the training and
calibration runs of the recipe); the others are reported apart
(``held_out``: the pushes, the loaded and early identification runs, the
2020 collision runs, Panda, UR10).

Run::

    python benchmarks/mutated_logs.py [--n 200] [--seed 0] [--output DIR]
    python benchmarks/mutated_logs.py --clean [--output DIR]

Without the data it says so and exits 0.
"""

import argparse
import contextlib
import io
import json
import shutil
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # this checkout's package
from _common import real_data_path  # noqa: E402
import readme_recipe as recipe  # noqa: E402
import real_ur10e as bench  # noqa: E402

from sklearn_gpcd.cli import main as gpcd  # noqa: E402

PUSH = "collision_push_pose/ur-20_01_22-push_pose_1.csv"


def trained(root, cache):
    """``detector.skops`` of the README recipe (run ``all``), trained once into ``cache``."""
    cache.mkdir(parents=True, exist_ok=True)
    detector = cache / "detector.skops"
    if detector.is_file():
        return detector
    commands = recipe.recipe_commands()
    train, unseen, _ = bench.split_recordings(root, quick=False)
    if not (cache / "model.skops").is_file():
        if (cache / "train").is_dir():
            shutil.rmtree(cache / "train")
        recipe.link(cache / "train", [Path(r.metadata["source"]) for r in train])
        log = []
        recipe.run(commands[0], cache, log)
        (cache / "train.txt").write_text(log[0]["stdout"])
    if not (cache / "calib").is_dir():
        recipe.link(cache / "calib", [root / k for k in unseen])
    log = []
    recipe.run(commands[1], cache, log)
    (cache / "calibrate.txt").write_text(log[0]["stdout"])
    return detector


#: Alarm events count as unchanged when onsets and ends move by less than this [s].
TOLERANCE_S = 0.05
#: Column blocks of the push log (headerless, preset ur10e_mamedov).
BLOCKS = {"time": [0], "q": list(range(1, 7)), "qd": list(range(7, 13)),
          "current": list(range(13, 19)), "target_current": list(range(19, 25))}
#: Words a message must hold to name a column of a family.
NAMES = {"time": ("time",), "q": ("q[", "q_"), "qd": ("qd[", "qd_"),
         "current": ("current[", "current_", "currents")}


def _table(text):
    return np.array([[float(v) for v in line.split(",")] for line in text.splitlines()])


def _text(table):
    return "\n".join(",".join(f"{v:.4f}" for v in row) for row in table) + "\n"


def mutations(text, n, seed):
    """``n`` mutated copies of the log ``text``: ``(family, description, columns, new_text)``.

    ``columns`` are the blocks (``"q"``, ``"current"``, ...) a message must name
    when the events change. Families, drawn in turn with ``numpy`` seed ``seed``:
    byte flips, one or all currents scaled (x1000, x57.3, x-1, x0.001), positions
    scaled (x0.001, degrees), velocities scaled (degrees, x0.001), q and qd
    swapped (all or one joint), two joints' columns swapped, duplicated time
    stamps, inf/NaN cells, time in ms.
    """
    rng = np.random.default_rng(seed)
    table = _table(text)
    out = []
    families = ["byte_flip", "current_joint", "currents", "q_scale", "qd_scale", "swap_q_qd",
                "swap_joints", "duplicate_stamps", "inf", "time_scale"]
    for k in range(n):
        family = families[k % len(families)]
        t = table.copy()
        cols = []
        if family == "byte_flip":
            data = bytearray(text.encode())
            flips = int(rng.integers(1, 6))
            for pos in rng.integers(0, len(data), flips):
                data[pos] = int(rng.integers(32, 127))
            out.append((family, f"{flips} byte(s) replaced", ["time", "q", "qd", "current"],
                        data.decode(errors="replace")))
            continue
        if family == "current_joint":
            j, factor = int(rng.integers(6)), float(rng.choice([1000, 57.3, -1, 1e-3]))
            t[:, BLOCKS["current"][j]] *= factor
            desc, cols = f"current of joint {j} x{factor:g}", ["current"]
        elif family == "currents":
            factor = float(rng.choice([1000, 57.3, -1]))
            t[:, BLOCKS["current"]] *= factor
            desc, cols = f"currents x{factor:g}", ["current"]
        elif family == "q_scale":
            factor = float(rng.choice([1e-3, 180 / np.pi]))
            joints = [int(rng.integers(6))] if rng.random() < 0.5 else list(range(6))
            t[:, [BLOCKS["q"][j] for j in joints]] *= factor
            desc, cols = f"q of joints {joints} x{factor:.4g}", ["q", "qd"]
        elif family == "qd_scale":
            factor = float(rng.choice([1e-3, 180 / np.pi]))
            t[:, BLOCKS["qd"]] *= factor
            desc, cols = f"qd x{factor:.4g}", ["q", "qd"]
        elif family == "swap_q_qd":
            joints = [int(rng.integers(6))] if rng.random() < 0.5 else list(range(6))
            a, b = [BLOCKS["q"][j] for j in joints], [BLOCKS["qd"][j] for j in joints]
            t[:, a + b] = t[:, b + a]
            desc, cols = f"q and qd of joints {joints} swapped", ["q", "qd"]
        elif family == "swap_joints":
            block = str(rng.choice(["q", "qd", "current"]))
            i, j = rng.choice(6, 2, replace=False)
            a, b = BLOCKS[block][i], BLOCKS[block][j]
            t[:, [a, b]] = t[:, [b, a]]
            desc, cols = f"{block} of joints {i} and {j} swapped", [block]
        elif family == "duplicate_stamps":
            rows = np.sort(rng.choice(np.arange(1, len(t)), int(rng.integers(1, 20)),
                                      replace=False))
            t[rows, 0] = t[rows - 1, 0]
            desc, cols = f"{len(rows)} time stamps duplicated", ["time"]
        elif family == "inf":
            cells = int(rng.integers(1, 10))
            rows, columns = rng.integers(len(t), size=cells), rng.integers(1, 19, size=cells)
            t[rows, columns] = rng.choice([np.inf, -np.inf, np.nan], size=cells)
            desc, cols = f"{cells} cell(s) inf or NaN", ["time", "q", "qd", "current"]
        else:
            t[:, 0] *= 1000.0
            desc, cols = "time x1000 (ms)", ["time"]
        out.append((family, desc, cols, _text(t)))
    return out


def monitor(detector, path):
    """``gpcd monitor`` in process: (status, events, stderr lines)."""
    out, err = io.StringIO(), io.StringIO()
    report = path.with_suffix(".json")
    report.unlink(missing_ok=True)
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), \
            warnings.catch_warnings():
        try:
            status = gpcd(["monitor", str(detector), str(path), "-q", "--json", str(report)])
        except Exception as exc:  # a traceback the user would see
            return "crash", [], [f"{type(exc).__name__}: {exc}"]
    events = []
    if status == 0 and report.is_file():
        events = [(e["start_s"], e["end_s"]) for e in json.loads(report.read_text())["events"]]
    return status, events, [line for line in err.getvalue().splitlines() if line.strip()]


def same_events(a, b):
    return len(a) == len(b) and all(abs(x[0] - y[0]) <= TOLERANCE_S
                                    and abs(x[1] - y[1]) <= TOLERANCE_S for x, y in zip(a, b))


def outcome(result, base, columns):
    """``unchanged``, ``warned``, ``refused``, ``crash`` or ``silent`` (see the docstring)."""
    status, events, lines = result
    _, base_events, base_lines = base
    new = [line for line in lines if line not in base_lines]
    named = [line for line in new if any(w in line for c in columns for w in NAMES[c])
             or "column" in line]
    if status == "crash":
        return "crash"
    if status != 0:  # one new line (the file's layout note is the original's too)
        return "refused" if len(new) == 1 and named else "unclear refusal"
    if same_events(events, base_events):
        return "warned" if new else "unchanged"
    return "warned" if named else "silent"


#: The statistics of the ``--clean`` pass and the value above which each is reported.
LIMITS = (("quiet_share", 0.5), ("span_steps", 10), ("permutation_gain", 0.5))


def _findings(rec, calibrated, name):
    """Every finding of the checks ``check_signals`` runs (none raises), their
    statistics (how near each is to its verdict) and which checks ran: with
    the model's prediction, or without (its inputs not logged, another arm)."""
    from sklearn_gpcd.io import SignalCheck
    from sklearn_gpcd.workflow import fed_signal_check, signal_check

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        how, check = "model-free", None
        if calibrated is None:
            check = SignalCheck(rec.n_joints)
        else:
            try:
                check, how = fed_signal_check(rec, calibrated, name=name), "model"
            except ValueError as exc:  # the model's inputs are not logged
                if "target_current" not in str(exc):
                    raise
                check = signal_check(calibrated)
        if how == "model-free":
            check.update(rec.time, rec.q, rec.qd, rec.current)
        return check.findings(), check.statistics(), how


def _other_arms(data_root):
    """(name, Recording) of the Panda and UR10 logs, when present."""
    from sklearn_gpcd.io import Recording, read_value_files

    out = []
    panda = data_root / "panda_gaz" / "rbt_log"
    if panda.is_dir():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out.append(("panda_gaz/rbt_log", read_value_files(panda)))
    ur10 = data_root / "ur10_polydoros" / "URpickNplace.mat"
    if ur10.is_file():
        from scipy.io import loadmat

        table = loadmat(ur10)["urPicknPlace"]
        out.append(("ur10_polydoros/URpickNplace.mat",
                    Recording(time=np.arange(len(table)) * 0.008, q=table[:, :6],
                              qd=table[:, 6:12], current=table[:, 18:24], units="Nm")))
    return out


def clean_recordings(root, detector):
    """Findings on every unmutated real recording, tagged tuning or held-out."""
    from sklearn_gpcd.io import load_recording
    from sklearn_gpcd.workflow import load_detector

    calibrated = load_detector(detector)
    train, unseen, _ = bench.split_recordings(root, quick=False)
    tuning = {Path(r.metadata["source"]).resolve() for r in train} \
        | {(root / k).resolve() for k in unseen}
    rows = []
    items = [(str(f.relative_to(root)), f) for f in sorted(root.rglob("*.csv"))]
    for key, path in items:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rec = load_recording(path)
        found, stats, how = _findings(rec, calibrated, key)
        rows.append({"recording": f"{bench.DATASET}/{key}", "set": "tuning"
                     if path.resolve() in tuning else "held_out", "checks": how,
                     "findings": [f._asdict() for f in found], "statistics": stats})
    for key, rec in _other_arms(root.parent):
        found, stats, how = _findings(rec, None, key)
        rows.append({"recording": key, "set": "held_out", "checks": how,
                     "findings": [f._asdict() for f in found], "statistics": stats})
    return rows


def _largest(rows, name):
    values = [v for r in rows for v in np.atleast_1d(r["statistics"][name])]
    values = [v for v in values if np.isfinite(v)]
    return max(values) if values else float("nan")


def _clean_summary(rows):
    lines = []
    for part in ("tuning", "held_out"):
        mine = [r for r in rows if r["set"] == part]
        kinds = {}
        for r in mine:
            for f in r["findings"]:
                key = f"{f['severity']} {f['kind']}"
                kinds[key] = kinds.get(key, 0) + 1
        flagged = sum(bool(r["findings"]) for r in mine)
        lines.append(f"{part}: {len(mine)} recordings, {flagged} with a finding"
                     + (" (" + ", ".join(f"{v} {k}" for k, v in sorted(kinds.items())) + ")"
                        if kinds else ""))
        lines.append("  largest statistics (reported above): " + "; ".join(
            f"{name} {_largest(mine, name):.3g} ({limit:g})" for name, limit in LIMITS))
    for r in rows:
        lines.append(f"  {r['set']:8s} {r['checks']:10s} {r['recording']}: "
                     + ("; ".join(f"{f['severity']} {f['kind']} {','.join(f['columns'])}"
                                  for f in r["findings"]) or "none"))
    return lines


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=None)
    parser.add_argument("--cache", type=Path, default=Path("/tmp/gpcd_mutated_logs"))
    parser.add_argument("--n", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--output", type=Path, default=None,
                        help="write mutated_logs.json and mutated_logs.txt here")
    parser.add_argument("--train-only", action="store_true")
    parser.add_argument("--clean", action="store_true",
                        help="the checks over every unmutated real recording instead")
    args = parser.parse_args(argv)
    root = args.data or real_data_path(bench.DATASET)
    if root is None or not (Path(root) / PUSH).is_file():
        print(f"UR10e push log not found under {root}; nothing to do.")
        return 0
    detector = trained(Path(root), args.cache)
    print(f"detector: {detector}")
    if args.train_only:
        return 0
    if args.clean:
        rows = clean_recordings(Path(root), detector)
        lines = _clean_summary(rows)
        print("\n".join(lines))
        if args.output is not None:
            args.output.mkdir(parents=True, exist_ok=True)
            (args.output / "signal_checks_clean.json").write_text(
                json.dumps({"detector": str(detector), "rows": rows}, indent=1))
            (args.output / "signal_checks_clean.txt").write_text("\n".join(lines) + "\n")
        return 0
    text = (Path(root) / PUSH).read_text()
    rows, counts = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        original = Path(tmp) / Path(PUSH).name
        original.write_text(text)
        base = monitor(detector, original)
        print(f"original: status {base[0]}, {len(base[1])} events {base[1]}")
        tic = time.perf_counter()
        for k, (family, desc, columns, mutated) in enumerate(mutations(text, args.n,
                                                                         args.seed)):
            path = Path(tmp) / f"m{k:03d}.csv"
            path.write_text(mutated)
            result = monitor(detector, path)
            verdict = outcome(result, base, columns)
            counts[verdict] = counts.get(verdict, 0) + 1
            rows.append({"k": k, "family": family, "mutation": desc, "outcome": verdict,
                         "status": result[0], "n_events": len(result[1]),
                         "message": next((line for line in result[2]
                                          if line not in base[2]), None)})
            print(f"{k:3d} {family:16s} {verdict:9s} {desc}", flush=True)
    summary = {"log": PUSH, "n": args.n, "seed": args.seed, "counts": counts,
               "original_events": base[1], "seconds": round(time.perf_counter() - tic, 1),
               "detector": str(detector), "rows": rows}
    print("outcomes: " + ", ".join(f"{v} {k}" for k, v in sorted(counts.items())))
    if args.output is not None:
        args.output.mkdir(parents=True, exist_ok=True)
        (args.output / "mutated_logs.json").write_text(json.dumps(summary, indent=1))
        lines = [f"{r['k']:3d} {r['family']:16s} {r['outcome']:9s} {r['mutation']}"
                 + (f"\n      {r['message']}" if r["message"] else "") for r in rows]
        (args.output / "mutated_logs.txt").write_text(
            "outcomes: " + ", ".join(f"{v} {k}" for k, v in sorted(counts.items()))
            + "\n" + "\n".join(lines) + "\n")
        print(f"wrote {args.output / 'mutated_logs.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
