"""Settling thresholds by time since stop: what the UR10e push files ask of them.

Issue 45 (push files): on main, one push of ``push_pose_2`` (8.0 s) is
missed under the single settling threshold (settle time 3 s chosen by
``gpcd calibrate``). Measured here, before any change of the detector:

- per calibration recording of ``benchmarks/push_events.py``'s unseen
  collision-free set C, the debounced ``|m|`` of P_f in settling samples,
  binned by time since stop (0-0.25-0.5-1-2-settle s), per joint;
- the staged thresholds those bins would give (largest peak per bin made
  non-increasing in time, times their own leave-one-recording-out factor)
  beside the single settling threshold of the calibrated detector;
- the nested check: each recording of C scored in its settling samples
  against stages calibrated without it (ratios above 1 are false alarms);
- the pushes that fall in settling: time since stop, peak debounced ``|m|``
  over the push per joint, and whether the single and the staged
  thresholds catch them.

Run::

    python studies/settling_stages.py   # about 2 min; needs the UR10e data
"""

import json
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import real_ur10e as ur  # noqa: E402
from _common import real_data_path  # noqa: E402

from sklearn_gpcd.workflow import training_set  # noqa: E402
from sklearn_gpcd.detection import stack_currents  # noqa: E402
from sklearn_gpcd.detection._regimes import SETTLING  # noqa: E402
from sklearn_gpcd.detection._thresholds import loro_factors  # noqa: E402

EDGES_S = (0.25, 0.5, 1.0, 2.0)


def since_stop(qd, sigma_v):
    """Samples every joint has been still (RegimeState's counter), per sample."""
    still = (np.abs(qd) < sigma_v).all(axis=1)
    out = np.zeros(len(still), dtype=int)
    run = 0
    for k, s in enumerate(still.tolist()):
        run = run + 1 if s else 0
        out[k] = run
    return out


def stage(count, dt):
    return np.searchsorted(np.asarray(EDGES_S), count * dt, side="right")


def series(det, rec, features):
    block = stack_currents(features.transform(rec), rec.current)
    band = det.monitoring_signal(block).bands[0]
    rule = det.rules_[0]
    debounced = rule.debounced(band.signal)
    count = since_stop(rec.qd, rule.regime_settings()["sigma_v"])
    return debounced, band.regime, stage(count, rule.sample_time_), count


def stage_peaks(items, n_stages):
    out = np.zeros((len(items), n_stages, items[0][0].shape[1]))
    for r, (deb, regime, st, _) in enumerate(items):
        for s in range(n_stages):
            rows = (regime == SETTLING) & (st == s)
            if rows.any():
                out[r, s] = deb[rows].max(axis=0)
    return out


def staged(peaks):
    """Non-increasing levels per stage times their LORO factor."""
    levels = peaks.max(axis=0)
    present = peaks.any(axis=(0, 2))
    for s in range(1, len(levels)):  # no data, no tighter band
        if not present[s]:
            levels[s] = levels[s - 1]
    levels = np.maximum.accumulate(levels[::-1], axis=0)[::-1]
    factor = float(loro_factors(peaks, "global").max()) if len(peaks) > 1 else 1.0
    return factor * levels, factor


def main():
    root = real_data_path(ur.DATASET, None)
    train, unseen, _ = ur.split_recordings(root, False)
    pushes = {key: ur.load(root / key) for key in ur.PUSHES}
    labels = json.loads(ur.LABELS.read_text())["files"]
    data = training_set(list(train), "causal")
    models, _ = ur.train_models(data, 1000, 0, 1, names=("P_f",), progress=ur.Progress())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        calibrated, _ = ur._recipe(ur.trained_model(models["P_f"], data.features),
                                   list(unseen.values()), list(unseen), {})
    det = calibrated.detector
    rule = det.rules_[0]
    single = np.atleast_2d(rule.thresholds_)[SETTLING]
    settle = rule.regimes.settle_time
    n_stages = 1 + sum(e < settle for e in EDGES_S)
    print(f"settle time {settle} s, margin {float(np.max(rule.margin_)):.3f}, "
          f"single settling threshold [A] {np.round(single, 3).tolist()}")
    items = [series(det, rec, data.features) for rec in unseen.values()]
    peaks = stage_peaks(items, n_stages)
    thresholds, factor = staged(peaks)
    thresholds = np.minimum(thresholds, single)
    bounds = (0.0,) + EDGES_S[:n_stages - 1] + (settle,)
    print(f"stages [s] {bounds}; recordings with settling samples per stage "
          f"{peaks.any(axis=2).sum(axis=0).tolist()} of {len(items)}; LORO factor {factor:.3f}")
    for s in range(n_stages):
        print(f"  stage {bounds[s]:.2f}-{bounds[s + 1]:.2f} s: staged threshold [A] "
              f"{np.round(thresholds[s], 3).tolist()}")
    worst = []
    for r in range(len(items)):
        others = np.delete(peaks, r, axis=0)
        held, _ = staged(others)
        held = np.minimum(held, single)
        deb, regime, st, _ = items[r]
        rows = regime == SETTLING
        if rows.any():
            worst.append(float((deb[rows] / held[np.minimum(st[rows], n_stages - 1)]).max()))
    print(f"nested: largest settling ratio per left-out recording: max {max(worst):.3f}, "
          f"{sum(w > 1 for w in worst)} of {len(worst)} above 1")
    for key, rec in pushes.items():
        deb, regime, st, count = series(det, rec, data.features)
        t = rec.time - rec.time[0]
        for push in labels[key]["events"] if "events" in labels[key] else labels[key]:
            start, stop = push["start_s"], push.get("tail_stop_s", push.get("stop_s"))
            rows = (t >= start) & (t <= stop + 0.5)
            settling = rows & (regime == SETTLING)
            if not settling.any():
                continue
            k = np.flatnonzero(settling)
            ratio_single = (deb[k] / single).max()
            ratio_staged = (deb[k] / thresholds[np.minimum(st[k], n_stages - 1)]).max()
            print(f"{Path(key).stem} push {start:.3f} s: settling samples {len(k)}, since stop "
                  f"{count[k[0]] * rule.sample_time_:.2f}-{count[k[-1]] * rule.sample_time_:.2f}"
                  f" s, peak ratio single {ratio_single:.2f}, staged {ratio_staged:.2f}")


if __name__ == "__main__":
    main()
