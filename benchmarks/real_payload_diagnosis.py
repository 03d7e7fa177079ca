"""Real data: is the payload of the loaded UR10e runs diagnosed, and how heavy is it?

Data: ``ur10e_mamedov/identification_data`` (Mamedov et al. 2020; no
redistribution licence, read in place, never copied). Files with "load" in
the name carry a payload (``ur-20_01_13-load_2600.csv``: presumably 2.6 kg,
the data README says nothing more); ``ur-20_01_31-unload.csv`` and the
``*harm50sec.csv`` runs without "Load" are unloaded.

Two protocols, both against the built-in (unloaded) UR10e model:

A. *direct*: each loaded run against the published model and torque
   constants, no friction known (friction is reported as missing too);
B. *calibrated*: the unloaded runs are diagnosed first (friction, rotor
   inertia, ... of the real robot) and each loaded run is diagnosed
   against that refined model; the unloaded runs themselves serve as
   controls (leave-one-out calibration);
C. *every unloaded run*: each unloaded identification run (18 files, the
   two early 19-column ones included) diagnosed as in A; none should carry
   a payload. Then the spread of each estimate across these runs: per
   effect, joint and parameter, in how many runs it is named, its median,
   range and relative spread (what is stable on this robot, what is not).

Every loaded run's payload is checked against :data:`PAYLOAD_MASS` (within
10 %).

Run ``python benchmarks/real_payload_diagnosis.py [--data DIR] [--json OUT]
[--figure PNG]``.
Exits 0 with a message when the data is absent.
"""

import argparse
import json
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from sklearn_gpcd.diagnosis import DynamicsDiagnosis
from sklearn_gpcd.io import RecordingWarning, load_recording
from sklearn_gpcd.robots import load_robot

UNLOADED = ("ur-20_02_19_14harm50sec.csv", "ur-20_02_19_15harm50sec.csv",
            "ur-20_01_31-unload.csv")
LOADED = ("ur-20_02_19_14harm50secLoad.csv", "ur-20_02_19_15harm50secLoad.csv",
          "ur-20_01_31-load.csv", "ur-20_01_13-load_2600.csv")
#: Mass [kg] of the payload of the loaded runs (issue 39); checked within 10 %.
PAYLOAD_MASS = 2.805
PAYLOAD_TOLERANCE = 0.10
#: An estimate is called stable when named in every run with a relative spread
#: (std over |median|) below this.
STABLE_SPREAD = 0.2
#: Held-out pairs: same payload mounting (centre of mass found alike).
HELDOUT = {"ur-20_02_19_14harm50secLoad.csv": "ur-20_01_31-load.csv",
           "ur-20_01_31-load.csv": "ur-20_02_19_14harm50secLoad.csv"}


def data_folder(explicit):
    if explicit:
        return Path(explicit)
    root = os.environ.get("GPCD_REAL_DATA")
    root = Path(root) if root else Path(__file__).resolve().parents[1] / ".." / "shared" / \
        "data" / "real"
    return root / "ur10e_mamedov" / "identification_data"


def payload_of(diagnosis):
    for effect in diagnosis.effects_:
        if effect.name == "payload":
            p = effect.parameters
            return {"mass": p["mass"][0], "mass_std": p["mass"][1],
                    "com": [p[k][0] for k in ("com_x", "com_y", "com_z")],
                    "evidence_t": effect.evidence.t if effect.evidence else None}
    return None


def within(pay):
    """Whether a payload estimate is within PAYLOAD_TOLERANCE of PAYLOAD_MASS."""
    return pay is not None and abs(pay["mass"] / PAYLOAD_MASS - 1) <= PAYLOAD_TOLERANCE


def estimates(diagnosis):
    """``{"effect[joint j] parameter": value}`` of every named effect."""
    out = {}
    for e in diagnosis.effects_:
        where = "" if e.target is None else \
            f"[{'link' if e.name == 'link_mass' else 'joint'} {e.target + 1}]"
        for key, (value, _) in e.parameters.items():
            out[f"{e.name}{where} {key}"] = float(value)
    return out


def spread_table(per_run):
    """Rows (name, runs named, median, min, max, relative spread, verdict) over runs."""
    n = len(per_run)
    names = sorted({k for run in per_run.values() for k in run})
    rows = []
    for name in names:
        values = np.array([run[name] for run in per_run.values() if name in run])
        median = float(np.median(values))
        spread = float(values.std() / abs(median)) if values.size > 1 and median else np.nan
        stable = values.size == n and np.isfinite(spread) and spread < STABLE_SPREAD
        rows.append({"estimate": name, "runs": int(values.size), "of": n, "median": median,
                     "min": float(values.min()), "max": float(values.max()),
                     "relative_spread": spread,
                     "verdict": "stable" if stable else
                     ("named in every run, spread" if values.size == n else "not in every run")})
    return rows


def spread_figure(per_run, table, path):
    """One dot per run and estimate: its value over the median across runs, and how often named.

    Only the estimates named in at least two runs; the velocity scales and
    first moments are left out (they follow from the amplitudes).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [r for r in table if r["runs"] >= 2 and r["median"]
            and not r["estimate"].endswith(("_velocity", "first_moment_x", "first_moment_y",
                                            "first_moment_z", "torque_constant"))]
    fig, ax = plt.subplots(figsize=(8, 0.35 * len(rows) + 1.5))
    for y, row in enumerate(rows):
        values = np.array([run[row["estimate"]] for run in per_run.values()
                           if row["estimate"] in run])
        ax.plot(values / row["median"], np.full(values.size, y), "o", alpha=0.6,
                color="C0" if row["verdict"] == "stable" else "C3")
    ax.axvline(1.0, color="k", lw=0.8)
    ax.axvspan(1 - STABLE_SPREAD, 1 + STABLE_SPREAD, color="0.9", zorder=0)
    ax.set_yticks(range(len(rows)))
    ax.set_yticklabels([f"{r['estimate']} ({r['runs']}/{r['of']} runs)" for r in rows],
                       fontsize=7)
    ax.set_xlabel("estimate / its median across the runs that name it")
    ax.set_title("UR10e unloaded identification runs, each diagnosed on its own\n"
                 f"(blue: named in every run with spread < {100 * STABLE_SPREAD:.0f} %)",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def summary(diagnosis):
    return sorted({f"{e.name}" for e in diagnosis.effects_})


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=None, help="identification_data folder")
    parser.add_argument("--json", default=None, help="write all numbers here")
    parser.add_argument("--figure", default=None,
                        help="write the spread of each estimate across the unloaded runs "
                             "here (PNG, needs matplotlib)")
    args = parser.parse_args(argv)
    folder = data_folder(args.data)
    if not all((folder / name).is_file() for name in UNLOADED + LOADED):
        print(f"real data not found in {folder}: skipped")
        return 0
    warnings.simplefilter("ignore", RecordingWarning)
    start = time.perf_counter()
    recs = {name: load_recording(folder / name) for name in UNLOADED + LOADED}
    robot = load_robot("ur10e")
    results = {"direct": {}, "calibrated": {}, "controls": {}, "seconds": {}}

    print("A. direct: loaded run vs the published UR10e model (no friction known)")
    t0 = time.perf_counter()
    for name in LOADED:
        diag = DynamicsDiagnosis(robot).fit(recs[name])
        results["direct"][name] = {"payload": payload_of(diag), "effects": summary(diag)}
        pay = payload_of(diag)
        print(f"   {name:36s} payload {pay['mass']:.2f} +- {pay['mass_std']:.2f} kg "
              f"({'within' if within(pay) else 'NOT within'} 10 % of {PAYLOAD_MASS} kg)"
              if pay else f"   {name:36s} no payload found")
    results["seconds"]["direct"] = time.perf_counter() - t0

    print("B. calibrated: unloaded runs first, then each loaded run against that model")
    t0 = time.perf_counter()
    base = DynamicsDiagnosis(robot).fit([recs[n] for n in UNLOADED])
    results["calibration_effects"] = summary(base)
    results["seconds"]["calibration"] = time.perf_counter() - t0
    print(f"   calibration found: {', '.join(summary(base))} "
          f"({results['seconds']['calibration']:.1f} s)")
    t0 = time.perf_counter()
    for name in LOADED:
        diag = DynamicsDiagnosis(base_model=base.model_).fit(recs[name])
        entry = {"payload": payload_of(diag), "effects": summary(diag),
                 "nmse_before_train": diag.nmse_train_before_.tolist(),
                 "nmse_after_train": diag.nmse_train_after_.tolist()}
        if name in HELDOUT:
            scores = diag.evaluate(recs[HELDOUT[name]])
            entry["heldout"] = {"recording": HELDOUT[name], "nmse_before": scores["nmse_before"],
                                "nmse_after": scores["nmse_after"]}
        results["calibrated"][name] = entry
        pay = entry["payload"]
        line = (f"   {name:36s} payload {pay['mass']:.2f} +- {pay['mass_std']:.2f} kg "
                f"({'within' if within(pay) else 'NOT within'} 10 % of {PAYLOAD_MASS} kg), "
                f"com {np.round(pay['com'], 3).tolist()} m" if pay else
                f"   {name:36s} no payload found")
        print(line + f"; effects: {', '.join(entry['effects'])}")
        if "heldout" in entry:
            h = entry["heldout"]
            print(f"      held-out on {h['recording']}: nMSE "
                  f"{np.round(h['nmse_before'], 4).tolist()} -> "
                  f"{np.round(h['nmse_after'], 4).tolist()}")
    results["seconds"]["loaded"] = time.perf_counter() - t0

    print("   controls (unloaded run vs a model calibrated on the other unloaded runs):")
    t0 = time.perf_counter()
    for name in UNLOADED:
        others = [recs[n] for n in UNLOADED if n != name]
        calib = DynamicsDiagnosis(robot).fit(others)
        diag = DynamicsDiagnosis(base_model=calib.model_).fit(recs[name])
        results["controls"][name] = {"payload": payload_of(diag), "effects": summary(diag)}
        pay = payload_of(diag)
        rejected = [r["reason"] for r in diag.rejected_effects_ if r["effect"] == "payload"]
        print(f"   {name:36s} " + (f"payload {pay['mass']:.2f} kg (!)" if pay else
                                  "no payload") + f"; effects: {', '.join(summary(diag)) or '-'}"
              + (f"; rejected payload estimate: {rejected[0]}" if rejected else ""))
    results["seconds"]["controls"] = time.perf_counter() - t0

    print("C. every unloaded identification run, direct (as A): no payload expected")
    t0 = time.perf_counter()
    every = sorted(f.name for f in folder.glob("*.csv")
                   if "load" not in f.name.lower().replace("unload", ""))
    results["every_unloaded_direct"] = {}
    per_run = {}
    for name in every:
        diag = DynamicsDiagnosis(robot).fit(load_recording(folder / name))
        pay = payload_of(diag)
        per_run[name] = estimates(diag)
        results["every_unloaded_direct"][name] = {"payload": pay, "effects": summary(diag),
                                                  "estimates": per_run[name]}
        print(f"   {name:36s} " + (f"payload {pay['mass']:.2f} kg (!)" if pay else "no payload")
              + f"; effects: {', '.join(summary(diag)) or '-'}")
    results["seconds"]["every_unloaded"] = time.perf_counter() - t0
    table = results["spread_across_unloaded_runs"] = spread_table(per_run)
    print(f"   spread of each estimate across the {len(every)} unloaded runs (each run "
          "diagnosed on its own):")
    print(f"   {'estimate':58s} {'runs':>5s} {'median':>10s} {'min':>10s} {'max':>10s} "
          f"{'spread':>7s}  verdict")
    for row in table:
        spread = f"{100 * row['relative_spread']:.0f} %" if np.isfinite(
            row["relative_spread"]) else "-"
        print(f"   {row['estimate']:58s} {row['runs']:>2d}/{row['of']:<2d} "
              f"{row['median']:10.4g} {row['min']:10.4g} {row['max']:10.4g} {spread:>7s}  "
              f"{row['verdict']}")
    if args.figure:
        spread_figure(per_run, table, args.figure)
        print(f"   figure: {args.figure}")
    loaded_direct = sum(results["direct"][n]["payload"] is not None for n in LOADED)
    loaded_calibrated = sum(results["calibrated"][n]["payload"] is not None for n in LOADED)
    unloaded_clean = sum(results["controls"][n]["payload"] is None for n in UNLOADED)
    every_clean = sum(v["payload"] is None for v in results["every_unloaded_direct"].values())
    direct_within = sum(within(results["direct"][n]["payload"]) for n in LOADED)
    calibrated_within = sum(within(results["calibrated"][n]["payload"]) for n in LOADED)
    results["summary"] = {"loaded_with_payload_direct": loaded_direct,
                          "loaded_with_payload_calibrated": loaded_calibrated,
                          "unloaded_without_payload": unloaded_clean,
                          "n_loaded": len(LOADED), "n_unloaded": len(UNLOADED),
                          "every_unloaded_without_payload_direct": every_clean,
                          "n_every_unloaded": len(every),
                          "loaded_within_10_percent_direct": direct_within,
                          "loaded_within_10_percent_calibrated": calibrated_within}
    print(f"loaded runs diagnosed with a payload: {loaded_direct}/{len(LOADED)} (direct), "
          f"{loaded_calibrated}/{len(LOADED)} (calibrated); unloaded runs diagnosed without "
          f"a payload: {unloaded_clean}/{len(UNLOADED)} (controls), {every_clean}/{len(every)} "
          "(every unloaded identification run, direct); loaded runs with a payload within "
          f"10 % of {PAYLOAD_MASS} kg: {direct_within}/{len(LOADED)} (direct), "
          f"{calibrated_within}/{len(LOADED)} (calibrated)")
    results["seconds"]["total"] = time.perf_counter() - start
    print(f"total {results['seconds']['total']:.1f} s")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=2, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
