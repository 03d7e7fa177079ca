"""Does ``gpcd train --model auto`` pick the model that detects best? (issue #46, point 7)

A simulated UR10 whose controller logs its *feed-forward* as the target
current (``target_current="feedforward"``, as a UR does): four training runs
(D1 motions, 4 targets and 6 s of rest each), four collision-free repetitions
of a task for the calibration, and the task with four pushes (two while the
arm moves, two at rest, 60-120 Nm on joint 1). Every model of ``gpcd train
--model`` and ``auto`` goes through the README's recipe (train, calibrate,
monitor, defaults but ``--n-support``), and the table gives, per model, the
pushes caught, the alarm onsets outside the pushes, the calibration's
margin, and for ``auto`` the comparison it printed (thresholds on the
left-out training runs, margin, nMSE): which criterion ranks the models as
their held-out detection does.

Run::

    python studies/model_choice_detection.py [--n-support 300] [--seed 0]
"""

import argparse
import contextlib
import io
import json
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from sklearn_gpcd.cli import main as gpcd  # noqa: E402
from sklearn_gpcd.datasets import Contact, JointTrajectory, reference_d1, simulate  # noqa: E402
from sklearn_gpcd.io import write_rtde_csv  # noqa: E402
from sklearn_gpcd.workflow import load_model  # noqa: E402

ROBOT = "ur10"
PUSHES = (("moving", 0.3, 120.0), ("moving", 0.7, -120.0), ("rest", 2.0, 60.0),
          ("rest", 4.0, -60.0))
MODELS = ("auto", "p_f", "sp_s", "sp_p", "sp_c", "gp")


def task(seed, n_targets=4):
    moves = reference_d1(ROBOT, n_targets=n_targets, random_state=seed)
    rest = JointTrajectory.rest(moves.at(moves.duration), 6.0)
    return JointTrajectory.concatenate([moves, rest]), moves.duration


def push(start, torque, lever=0.2, duration=0.8):
    return Contact(link=1, start=start, duration=duration, force=[0.0, torque / lever, 0.0],
                   point=[lever, 0.0, 0.0], frame="local")


def logs(folder, seed):
    paths = {"train": [], "calibrate": []}
    for k in range(4):
        rec = simulate(task(seed + k)[0], ROBOT, random_state=seed + k,
                       target_current="feedforward")
        paths["train"].append(write_rtde_csv(rec, folder / f"train{k}.csv"))
    reference, moving = task(seed + 50)
    for k in range(4):
        rec = simulate(reference, ROBOT, random_state=seed + 100 + k,
                       target_current="feedforward")
        paths["calibrate"].append(write_rtde_csv(rec, folder / f"free{k}.csv"))
    contacts = [push(f * moving if phase == "moving" else moving + f, torque)
                for phase, f, torque in PUSHES]
    rec = simulate(reference, ROBOT, contacts=contacts, random_state=seed + 7,
                   target_current="feedforward")
    paths["push"], paths["contacts"] = write_rtde_csv(rec, folder / "pushes.csv"), contacts
    return paths


def run(argv):
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        status = gpcd(argv)
    if status != 0:
        raise SystemExit(f"gpcd {argv[0]} failed")
    return out.getvalue()


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-support", default="300")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        paths = logs(tmp, args.seed)
        for model in MODELS:
            tic = time.perf_counter()
            m, d, e = tmp / f"{model}.skops", tmp / f"{model}_d.skops", tmp / f"{model}.json"
            text = run(["train", *map(str, paths["train"]), "--robot", ROBOT, "--model", model,
                        "--n-support", args.n_support, "-q", "-o", str(m)])
            if model == "auto":
                print("\n".join(line for line in text.splitlines()
                                if line.startswith(("model choice", "  "))))
            run(["calibrate", str(m), *map(str, paths["calibrate"]), "-q", "-o", str(d)])
            run(["monitor", str(d), str(paths["push"]), "-q", "--json", str(e)])
            report = json.loads(e.read_text())
            starts = [ev["start_s"] for ev in report["events"]]
            windows = [(c.start, c.start + c.duration + 0.5) for c in paths["contacts"]]
            caught = sum(any(lo <= s <= hi for s in starts) for lo, hi in windows)
            outside = sum(not any(lo <= s <= hi for lo, hi in windows) for s in starts)
            margin = report.get("calibration", {}).get("margin")
            chosen = load_model(m).training["model"]
            rows.append((model, chosen, caught, outside, margin, time.perf_counter() - tic))
            print(f"{model:5s} ({chosen}): pushes {caught}/4, onsets outside {outside}, "
                  f"margin {margin}, {rows[-1][-1]:.0f} s", flush=True)
    return rows


if __name__ == "__main__":
    main()
