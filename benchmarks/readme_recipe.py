"""The README's recipe, verbatim, on the real UR10e recordings (issue #37).

Acceptance: "a user who reads only the README trains, calibrates and
monitors the UR10e push files and gets 10/10 pushes with no false alarm on
unseen logs". This script reads the three commands of the README's
"**The recipe.**" block (``README.md``, section "Your own robot") and runs
them as written -- same subcommands, same flags, nothing added -- through
:func:`sklearn_gpcd.cli.main` (the ``gpcd`` command, in process, so that the
checked-out code runs). Only the file names of the recipe are filled in:

* ``train/*.csv``: the training runs of ``benchmarks/real_ur10e.py``
  (``split_recordings``: the unloaded identification runs that log the
  target current, less the held-out ones), linked into a ``train/`` folder;
* ``calib/*.csv``: one half of that benchmark's unseen collision-free set
  ``C`` (held-out identification runs, jointwise runs, ptp_10_points, the
  still poses p1..p10), linked into ``calib/``;
* ``today.csv``: the two push files and the *other* half of ``C``, which
  neither the model nor the thresholds saw.

Two runs with the halves swapped (``half1``, ``half2``), so that every
recording of ``C`` is monitored once unseen, and a third (``all``) that
calibrates on all of ``C`` and monitors the pushes, whose only figure for
``C`` is the calibration's nested one. Scoring, with the labels of
``benchmarks/labels/ur10e_events.json`` (times from each file's first
sample): a push is caught when an alarm event overlaps ``[start_s,
tail_stop_s + 0.5 s]`` (the window of ``real_ur10e.score_alarms``); alarm
onsets on the unseen collision-free logs are false alarms; on the push
files, onsets outside every push window are false alarms and onsets beyond
the first inside one push window are counted apart ("onsets inside a
push"). The calibration's own figure, nested onsets by
leave-one-recording-out on the calibration logs, is printed beside.

Run::

    python benchmarks/readme_recipe.py [--data DIR] [--output DIR] [--runs half1,half2,all]

Without the data it says so and exits 0. Writes ``readme_recipe.json`` into
``--output`` (default: a temporary folder, removed).
"""

import argparse
import contextlib
import glob
import io
import json
import re
import shlex
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # this checkout's package
from _common import real_data_path  # noqa: E402
import real_ur10e as bench  # noqa: E402

from sklearn_gpcd.cli import main as gpcd  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
TAIL = 0.5  # s after a push's tail_stop_s still counted as the push (real_ur10e)


def recipe_commands(readme=README):
    """The ``gpcd`` command lines of the README's recipe block, comments removed.

    Returns
    -------
    commands : list of list of str
        ``[["train", "train/*.csv", "-o", "model.skops"], ...]``, without ``gpcd``.
    """
    text = readme.read_text()
    start = text.index("**The recipe.**")
    block = re.search(r"```bash\n(.*?)```", text[start:], re.S).group(1)
    commands = []
    for line in block.splitlines():
        words = shlex.split(line, comments=True)
        if words and words[0] == "gpcd":
            commands.append(words[1:])
    verbs = [c[0] for c in commands]
    if verbs != ["train", "calibrate", "monitor"]:
        raise ValueError(f"the README's recipe has the commands {verbs}, expected train, "
                         "calibrate, monitor")
    return commands


def halves(unseen_keys):
    """Two halves of ``C``, each with every kind of recording (every other one)."""
    kinds = {}
    for key in unseen_keys:
        kinds.setdefault(key.split("/")[0] + ("/p" if "-p" in key else ""), []).append(key)
    first, second = [], []
    for keys in kinds.values():
        first += keys[0::2]
        second += keys[1::2]
    return first, second


def link(folder, paths):
    folder.mkdir(parents=True, exist_ok=True)
    for path in paths:
        (folder / Path(path).name).symlink_to(path)


def run(words, cwd, log):
    """One ``gpcd`` command in ``cwd``, its globs expanded as a shell would; output kept."""
    argv = []
    for w in words:
        matches = sorted(glob.glob(w, root_dir=cwd)) if any(c in w for c in "*?[") else []
        argv += matches or [w]
    out, err = io.StringIO(), io.StringIO()
    tic = time.perf_counter()
    with contextlib.chdir(cwd), contextlib.redirect_stdout(out), \
            contextlib.redirect_stderr(err):
        status = gpcd(argv)
    seconds = time.perf_counter() - tic
    log.append({"argv": ["gpcd"] + words, "status": status, "seconds": round(seconds, 1),
                "stdout": out.getvalue(),
                "stderr": [l for l in err.getvalue().splitlines() if "\r" not in l
                           and "%|" not in l]})
    print(f"  $ gpcd {' '.join(words)}  -> status {status}, {seconds:.0f} s", flush=True)
    if status != 0:
        print(err.getvalue()[-2000:])
        raise SystemExit(f"gpcd {words[0]} failed (status {status})")
    return out.getvalue()


def score(events, labels, pushes, unseen):
    """Pushes caught, onsets inside pushes beyond the first, false alarms."""
    by_file = {}
    for e in events:
        by_file.setdefault(e["recording"], []).append(e)
    result = {"pushes": [], "false_alarms_push_files": [], "false_alarms_unseen": {},
              "extra_onsets_inside_pushes": 0}
    for key in pushes:
        name = Path(key).name
        evs = by_file.get(name, [])
        windows = [(ev["start_s"], ev.get("tail_stop_s", ev["stop_s"]) + TAIL)
                   for ev in labels["files"][key]["events"]]
        for lo, hi in windows:
            hits = [e for e in evs if e["start_s"] <= hi and e["end_s"] >= lo]
            onsets_inside = [e for e in evs if lo <= e["start_s"] <= hi]
            result["pushes"].append({
                "file": name, "start_s": lo, "stop_s": hi, "caught": bool(hits),
                "delay_s": (max(hits[0]["start_s"] - lo, 0.0) if hits else None)})
            result["extra_onsets_inside_pushes"] += max(len(onsets_inside) - 1, 0)
        result["false_alarms_push_files"] += [
            {"file": name, "start_s": e["start_s"]} for e in evs
            if not any(lo - TAIL <= e["start_s"] <= hi for lo, hi in windows)]
    for key in unseen:
        name = Path(key).name
        result["false_alarms_unseen"][name] = [e["start_s"] for e in by_file.get(name, [])]
    return result


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=None,
                        help="the ur10e_mamedov folder (default: the shared real data)")
    parser.add_argument("--output", type=Path, default=None)
    parser.add_argument("--runs", default="half1,half2,all",
                        help="comma-separated: half1 / half2 (calibrate on one half of C, "
                        "monitor the other half and the pushes), all (calibrate on all of "
                        "C, monitor the pushes; C's false alarms: the calibration's nested "
                        "figure only)")
    args = parser.parse_args(argv)
    root = args.data or real_data_path(bench.DATASET)
    if root is None or not Path(root).is_dir():
        print(f"UR10e data not found ({root}); nothing to do.")
        return 0
    root = Path(root)
    commands = recipe_commands()
    print("README recipe:\n" + "\n".join("  gpcd " + " ".join(c) for c in commands))
    labels = json.loads(bench.LABELS.read_text())
    train, unseen, _ = bench.split_recordings(root, quick=False)
    train_paths = [Path(r.metadata["source"]) for r in train]
    first, second = halves(list(unseen))
    report = {"commands": [["gpcd"] + c for c in commands],
              "train_files": [p.name for p in train_paths], "folds": []}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        link(work / "train", train_paths)
        log = []
        print(f"train: {len(train_paths)} runs")
        run(commands[0], work, log)
        runs = {"half1": (first, second), "half2": (second, first), "all": (first + second, [])}
        for fold, run_name in enumerate(args.runs.split(",")):
            calib, held = runs[run_name]
            fdir = work / run_name
            link(fdir / "calib", [root / k for k in calib])
            (fdir / "model.skops").symlink_to(work / "model.skops")
            today = [str(root / k) for k in bench.PUSHES + held]
            monitor = []
            for w in commands[2]:
                monitor += today if w == "today.csv" else [w]
            print(f"{run_name}: calibrate on {len(calib)}, monitor 2 push files and "
                  f"{len(held)} unseen collision-free logs")
            calib_out = run(commands[1], fdir, log)
            sizes = {name: round((fdir / name).stat().st_size / 1e6, 1)
                     for name in ("model.skops", "detector.skops") if (fdir / name).exists()}
            print(f"  file sizes [MB]: {sizes} (issue #46: detector <= 40 MB)")
            run(monitor, fdir, log)
            events = json.loads((fdir / "events.json").read_text())
            res = score(events["events"], labels, bench.PUSHES, held)
            nested = events.get("calibration", {}).get("n_false_alarms_nested")
            res.update(run=run_name, file_sizes_MB=sizes,
                       calibration_files=[Path(k).name for k in calib],
                       calibration_nested_onsets=nested, calibration_report=calib_out)
            report["folds"].append(res)
            n_fa = sum(len(v) for v in res["false_alarms_unseen"].values())
            print(f"  pushes caught {sum(p['caught'] for p in res['pushes'])}/"
                  f"{len(res['pushes'])}; false alarms: {n_fa} onset(s) on {len(held)} unseen "
                  f"collision-free logs, {len(res['false_alarms_push_files'])} on the push "
                  f"files outside the pushes; extra onsets inside pushes "
                  f"{res['extra_onsets_inside_pushes']}; calibration's nested onsets {nested}")
        report["model_output"] = log[0]["stdout"]
        report["log"] = [{k: v for k, v in entry.items() if k != "stdout"} for entry in log]
        if args.output is not None:
            args.output.mkdir(parents=True, exist_ok=True)
            (args.output / "readme_recipe.json").write_text(json.dumps(report, indent=1))
            print(f"wrote {args.output / 'readme_recipe.json'}")
    print(report["model_output"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
