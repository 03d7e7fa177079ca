"""Could the training runs give the rest levels that one short calibration log misses? (issue 38)

Issue 38's "little data" point suggests shrinking the thresholds towards "the
level the training recordings give". On the MuJoCo little-data case
(``benchmarks/little_data_mujoco.py``), the false alarms on unseen poses are
rest excursions of 0.18-0.32 A on joints 1-3 against rest thresholds of
0.02-0.03 A from the 2-minute calibration log. This study measures the rest
(and moving, settling) levels of the training runs themselves, each held out
of a model fitted on the others: leave-one-run-out, SP_P with 300 support rows
(the model choice's fold size), every held-out run cut into 12 s pieces and
calibrated with ``calibrate_detector(select=False)`` (settle 0.5 s, rest
reference 5 s); a level is the threshold over the margin.

Run::

    python benchmarks/little_data_mujoco.py --workdir DIR --train-only
    python studies/little_data_floor.py --workdir DIR

Prints each fold's levels [A] (rows: moving, settling, rest; columns: joints).
"""

import argparse
import glob
import sys
import warnings
from pathlib import Path

import numpy as np


def fold_levels(runs, robot, split=12.0):
    """Per held-out run: (margin, coverage seconds per regime, levels [regime x joint])."""
    from sklearn_gpcd.workflow import calibrate_detector, train_model

    out = []
    for k, held in enumerate(runs):
        others = [r for i, r in enumerate(runs) if i != k]
        model = train_model(others, model="sp_p", robot=robot, n_support=300,
                            optimizer="adam", seed=0)
        summary = calibrate_detector(model, [held], split=split, select=False).calibration
        out.append((summary["margin"], {n: c["seconds"] for n, c in summary["coverage"].items()},
                    np.array(summary["thresholds_A"]) / summary["margin"]))
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workdir", type=Path, required=True,
                        help="the --workdir of benchmarks/little_data_mujoco.py")
    args = parser.parse_args(argv)
    from sklearn_gpcd.io import load_recording
    from sklearn_gpcd.robots import load_robot

    paths = sorted(glob.glob(str(args.workdir / "train" / "ident_*.csv")))
    if not paths:
        print(f"no training runs in {args.workdir / 'train'}: run benchmarks/"
              "little_data_mujoco.py --workdir DIR --train-only first")
        return 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        runs = [load_recording(p) for p in paths]
        for k, (margin, coverage, levels) in enumerate(fold_levels(runs, load_robot("ur10"))):
            print(f"held out {Path(paths[k]).name}: margin {margin:.2f}, seconds per regime "
                  f"{coverage}")
            print(np.array2string(levels, precision=3, suppress_small=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())
