"""Which leave-one-recording-out criterion predicts held-out detection (issue #46)?

The ``--model auto`` comparison (:func:`sklearn_gpcd.workflow.compare_models`)
fits every candidate on all training recordings but one and runs the alarm
rule of ``gpcd calibrate`` on the residual of the one left out. This study
keeps what that comparison computes per (regime, joint) -- the largest
excursion of each left-out recording -- and scores the candidates by several
criteria built from it:

* ``time``: the shipped score, thresholds (margin x level) per joint,
  geometric mean over regimes weighted by the time in each, then over joints;
* ``regime``: the same, every regime weighted equally (rest counts as much as
  motion, whatever its share of the training time);
* ``worst``: the largest regime's geometric mean over joints;
* ``level``: the levels alone (no margin): the residual scale;
* ``margin``: the leave-one-recording-out margin alone (the stability of the
  extremes);
* ``nmse``: the prediction error.

Detection counts per model come from ``benchmarks/cli_train.py`` (the
table of ``docs/_static/results/model_choice.json`` for the UR10e half 1 and
the simulated plant, and a ``--halves half2`` run for the UR10e half 2).

Run::

    python studies/model_choice_criteria.py [--plants real,sim] [--fold ROWS,SUPPORT]
        [--output FILE]
"""

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "benchmarks"))
sys.path.insert(0, str(HERE.parent))

from _common import real_data_path  # noqa: E402

import sklearn_gpcd.workflow.model_choice as mc  # noqa: E402
from sklearn_gpcd.detection import loro_margin, regime_levels  # noqa: E402


def _captured_comparison(data, robot, models, max_rows=mc.FOLD_ROWS, n_support=mc.FOLD_SUPPORT):
    """compare_models, keeping the per-recording peaks and regime counts per model."""
    captured = []
    original = mc._fold_thresholds

    def keep(peaks, counts):
        captured.append((peaks, counts))
        return original(peaks, counts)

    mc._fold_thresholds = keep
    try:
        table = mc.compare_models(data, robot, models, max_rows=max_rows, n_support=n_support,
                                  n_jobs=min(2, os.cpu_count() or 1))
    finally:
        mc._fold_thresholds = original
    return table, captured


def criteria(peaks, counts, nmse):
    """Every criterion of the module docstring for one model (smaller is better)."""
    keys = list(peaks)
    margin = loro_margin(peaks, keys)
    levels = np.maximum(regime_levels(peaks, keys), np.finfo(float).tiny)
    thresholds = margin * levels
    n = np.asarray(sum(counts.values()), float)
    seen = n > 0
    logs = np.log(thresholds[seen])
    weights = n[seen] / n[seen].sum()
    return {
        "time": float(np.exp((weights @ logs).mean())),
        "regime": float(np.exp(logs.mean())),
        "worst": float(np.exp(logs.mean(axis=1)).max()),
        "level": float(np.exp(np.log(levels[seen]).mean())),
        "margin": float(margin.max()),
        "nmse": float(np.exp(np.log(np.maximum(nmse, 1e-12)).mean())),
        "regime_shares": [round(float(v), 3) for v in n / n.sum()],
        "thresholds_by_regime": np.exp(logs.mean(axis=1)).round(4).tolist(),
    }


def plant_data(plant, root, work):
    """(training set, robot) of the benchmark's UR10e split or simulated plant."""
    import cli_train
    from sklearn_gpcd.io import read_rtde_csv
    from sklearn_gpcd.robots import load_robot
    from sklearn_gpcd.workflow import input_signals, training_set

    if plant == "real":
        import real_ur10e as bench

        train, _, _ = bench.split_recordings(root, quick=False)
        robot = load_robot("ur10e")
    else:
        files, _ = cli_train.sim_logs(work / "sim")
        train = [read_rtde_csv(f) for f in files["train"]]
        robot = load_robot(cli_train.SIM_ROBOT)
    signals, check = input_signals(list(train), "auto", "auto")
    data = training_set(list(train), "causal", signals=signals)
    models, _ = mc.candidate_models(robot, data.features.signals_, check)
    return data, robot, models


CRITERIA = ("time", "regime", "worst", "level", "margin", "nmse")


def detection_counts(path, plant, halves=None):
    """``{model: (pushes caught, false alarms)}`` of a cli_train.py report's single models."""
    rows = json.loads(Path(path).read_text())["model_choice"]
    return {r["model"]: (r["caught"], r["false_alarms"]) for r in rows
            if r["model"] != "auto" and r["plant"].startswith(plant)
            and (halves is None or set(r["seconds"]) - {"train"} == {halves})}


def agreement(rows, counts):
    """Per criterion: Spearman's rho against detection (more pushes, then fewer false
    alarms) and the model it picks with that model's counts."""
    from scipy.stats import spearmanr

    models = [m for m in rows if m in counts]
    badness = [-(100 * counts[m][0] - counts[m][1]) for m in models]
    out = {}
    for name in CRITERIA:
        values = [rows[m][name] for m in models]
        pick = models[int(np.argmin(values))]
        out[name] = (float(spearmanr(values, badness).correlation), pick, counts[pick])
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plants", default="real,sim")
    parser.add_argument("--output", type=Path, default=None)
    parser.add_argument("--fold", default=f"{mc.FOLD_ROWS},{mc.FOLD_SUPPORT}",
                        help="training rows and GP support rows per fold (default: auto's)")
    parser.add_argument("--detection", nargs="*", default=[],
                        help="NAME=PLANT:HALF:cli_train.json (HALF: half1, half2, all)")
    args = parser.parse_args(argv)
    root = real_data_path("ur10e_mamedov", None)
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for plant in args.plants.split(","):
            tic = time.perf_counter()
            data, robot, models = plant_data(plant, Path(root) if root else None, Path(tmp))
            rows_, support = (int(v) for v in args.fold.split(","))
            table, captured = _captured_comparison(data, robot, models, rows_, support)
            rows = {m: criteria(p, c, e) for m, (p, c), e in
                    zip(table.models, captured, table.errors)}
            out[plant] = dict(models=table.models, best=table.best, rows=rows,
                              held_out=table.held_out,
                              seconds=round(time.perf_counter() - tic, 1))
            print(f"{plant} ({rows_} rows, {support} support per fold): shipped choice "
                  f"{table.best}; {out[plant]['seconds']} s")
            names = CRITERIA
            print("  model " + "".join(f"{n:>9s}" for n in names) + "  thresholds by regime")
            for m, r in rows.items():
                print(f"  {m:5s} " + "".join(f"{r[n]:9.4f}" for n in names)
                      + f"  {r['thresholds_by_regime']} shares {r['regime_shares']}")
            for spec in args.detection:
                name, rest = spec.split("=", 1)
                where, half, path = rest.split(":", 2)
                if where != plant:
                    continue
                counts = detection_counts(path, "UR10e" if plant == "real" else "simulated",
                                          half)
                found = agreement(rows, counts)
                out[plant].setdefault("agreement", {})[name] = found
                print(f"  {name}: " + "; ".join(
                    f"{k} rho {r:+.2f} picks {m.upper()} {c[0]} pushes {c[1]} FA"
                    for k, (r, m, c) in found.items()))
            sys.stdout.flush()
    if args.output:
        args.output.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
