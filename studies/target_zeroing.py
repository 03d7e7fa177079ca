"""Why the README recipe (SP_C) raises one false alarm on jointwise run 6 (issue 37).

The UR controller's target current of a *still* joint is often exactly zero
while the joint holds its load. SP_C's mean is ``w * i_c``: where ``i_c`` is
zeroed, its GP correction must supply the whole holding current, from states
(one joint creeping, the others still) that no training run has.

Run::

    python studies/target_zeroing.py [--model MODEL.skops] [--data DIR]

Prints, per joint, the share of held-still samples (``|qd_l| < 0.01`` for
0.2 s either side) whose target current is zero (``<= 1e-3`` of the joint's
99th percentile), over the benchmark's training runs and over its unseen
recordings, with the median ``|i|`` there. With ``--model`` (a file of
``gpcd train``, e.g. the README recipe's ``model.skops``), also the model's
mean and GP correction on joint 2 of ``ur-20_01_22-joint_6.csv`` from 4.6 to
6.3 s. Skips with a message without the data.
"""

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np
from scipy.ndimage import minimum_filter1d

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
import real_ur10e as bench
from _common import real_data_path, require_data

JOINT6 = "jointwise_motion/ur-20_01_22-joint_6.csv"


def zeroed_share(recordings, still_speed=0.01, hold=0.2):
    """Per joint: held-still samples, share with a zero target, median |i| there."""
    rows = []
    for j in range(recordings[0].n_joints):
        n, zero, held_current = 0, 0, []
        for rec in recordings:
            w = max(round(float(hold / np.median(np.diff(rec.time)))), 1)
            still = minimum_filter1d((np.abs(rec.qd[:, j]) < still_speed).astype(int),
                                     2 * w + 1) > 0
            i_c = rec.target_current[:, j]
            z = still & (np.abs(i_c) <= 1e-3 * np.percentile(np.abs(i_c), 99))
            n, zero = n + still.sum(), zero + z.sum()
            held_current += list(np.abs(rec.current[z, j]))
        rows.append((j + 1, n, zero / max(n, 1),
                     float(np.median(held_current)) if held_current else float("nan")))
    return rows


def correction_window(model_path, root, lo=4.6, hi=6.3):
    from sklearn_gpcd.io import load_recording
    from sklearn_gpcd.workflow import load_model

    trained = load_model(model_path)
    rec = load_recording(root / JOINT6)
    X = trained.features.transform(rec)
    gp = trained.regressor
    predicted = gp.predict(X)
    mean = np.column_stack([m.predict(X) for m in gp.mean_])
    t = rec.time - rec.time[0]
    print(f"\n{trained.training.get('model')} on {JOINT6}, joint 2 "
          "(t, qd_6, i, i_c, mean, GP correction, residual):")
    for k in np.flatnonzero((t >= lo) & (t < hi))[::10]:
        print(f"  {t[k]:5.2f} {rec.qd[k, 5]:6.3f} {rec.current[k, 1]:6.3f} "
              f"{rec.target_current[k, 1]:6.3f} {mean[k, 1]:6.3f} "
              f"{predicted[k, 1] - mean[k, 1]:6.3f} {rec.current[k, 1] - predicted[k, 1]:6.3f}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=None)
    parser.add_argument("--model", type=Path, default=None)
    args = parser.parse_args(argv)
    root = real_data_path(bench.DATASET, args.data)
    require_data(root, "UR10e data")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        train, unseen, _ = bench.split_recordings(root, quick=False)
        for name, recs in (("training runs", list(train)), ("unseen recordings",
                                                            list(unseen.values()))):
            print(f"{name}: joint, held-still samples, share with a zero target, "
                  "median |i| there [A]")
            for j, n, share, current in zeroed_share(recs):
                print(f"  {j}  {n:6d}  {share:5.3f}  {current:6.3f}")
        if args.model is not None:
            correction_window(args.model, root)
    return 0


if __name__ == "__main__":
    sys.exit(main())
