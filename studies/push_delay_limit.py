"""Why the push files' median delay stays above 0.2 s (issue 45): the trade-off.

Study, not a feature. The issue's bar for the UR10e push files is a median
delay <= 0.2 s; ``benchmarks/push_events.py`` measures 0.228 s with P_f at
``gpcd calibrate``'s defaults (2 Hz band), and the banded monitors of
``benchmarks/real_ur10e.py`` (a fast second band chosen across the
recordings) 0.27 s. This study measures where the delay comes from, on the
same model, calibration and labels as ``push_events.py``:

1. **Filter lag**: per push, the delay of the detector's alarm and the
   delay of the *unfiltered* residual (minus the same rest reference)
   crossing the same thresholds with the same debounce: what a band with
   no lag would reach at these thresholds, and the number of alarm onsets
   that unfiltered signal raises on the unseen collision-free set ``C``
   (the recordings the thresholds were calibrated on).
2. **Threshold height**: the detector's thresholds scaled by ``s`` (alarm
   where the debounced ratio exceeds ``s``): the median delay on the
   pushes and the alarm onsets on ``C`` (in-sample: at ``s = 1`` zero by
   construction; any onset at ``s < 1`` is a false alarm on data the
   calibration has seen, so on unseen data there are at least as many).

Run::

    python studies/push_delay_limit.py

Prints the two tables. Reads the UR10e recordings in place
(``../shared/data/real/ur10e_mamedov``); exits 0 without them.
"""

import json
import sys
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "benchmarks"))
from _common import real_data_path, require_data  # noqa: E402
import real_ur10e as ur  # noqa: E402

from sklearn_gpcd.detection import stack_currents  # noqa: E402
from sklearn_gpcd.metrics import alarm_onsets  # noqa: E402
from sklearn_gpcd.workflow import training_set  # noqa: E402

SCALES = (1.0, 0.9, 0.8, 0.7, 0.6, 0.5)


def debounced(over, n):
    """Rows where ``over`` (bool, per joint) held for ``n`` samples on some joint."""
    run = np.zeros(over.shape, dtype=int)
    for k in range(len(over)):
        run[k] = np.where(over[k], (run[k - 1] if k else 0) + 1, 0)
    return (run >= n).any(axis=1)


def unfiltered_alarms(det, mon):
    """The residual minus the rest reference over the thresholds of each sample's
    regime, debounced as the rule does: a band without lag at these thresholds."""
    thresholds = np.atleast_2d(det.thresholds_)[mon.regime]
    raw = np.abs(mon.residual - mon.reference) > thresholds
    return debounced(raw, det.rules_[0].min_duration)


def first_after(rows, t, lo, hi):
    hits = np.flatnonzero(rows & (t >= lo) & (t <= hi))
    return float(t[hits[0]] - lo) if hits.size else None


def main():
    root = real_data_path(ur.DATASET, None)
    require_data(root, "UR10e recordings (Mamedov et al.)",
                 [ur.IDENTIFICATION, ur.PTP, *ur.STILL, *ur.JOINTWISE, *ur.PUSHES])
    labels = json.loads(ur.LABELS.read_text())["files"]
    train, unseen, _ = ur.split_recordings(root, False)
    pushes = {key: ur.load(root / key) for key in ur.PUSHES}
    data = training_set(list(train), "causal")
    features = data.features
    models, _ = ur.train_models(data, 1000, 0, 1, names=("P_f",), progress=ur.Progress())
    calibrated, _ = ur._recipe(ur.trained_model(models["P_f"], features),
                               list(unseen.values()), list(unseen), {})
    det = calibrated.detector
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        free = {k: det.monitoring_signal(stack_currents(features.transform(r), r.current))
                for k, r in unseen.items()}
        pushed = {k: det.monitoring_signal(stack_currents(features.transform(r), r.current))
                  for k, r in pushes.items()}
    hours = sum(r.duration for r in unseen.values()) / 3600
    windows = []
    for k, rec in pushes.items():
        t = rec.time - rec.time[0]
        for ev in labels[k]["events"]:
            windows.append((k, t, ev["start_s"], ev.get("tail_stop_s", ev["stop_s"]) + 0.5))

    print("1. filter lag: delay [s] per push, the detector's alarm and the unfiltered "
          "residual at the same thresholds")
    band, flat = [], []
    for k, t, lo, hi in windows:
        mon = pushed[k]
        a = first_after(mon.alarms.any(axis=1), t, lo, hi)
        b = first_after(unfiltered_alarms(det, mon), t, lo, hi)
        band.append(a)
        flat.append(b)
        print(f"  {Path(k).stem}  {lo:7.3f}  band {a:.3f}  unfiltered {b:.3f}")
    free_onsets = sum(len(alarm_onsets(unfiltered_alarms(det, m))) for m in free.values())
    print(f"  median: band {np.median(band):.3f} s, unfiltered {np.median(flat):.3f} s; "
          f"unfiltered onsets on C: {free_onsets} ({free_onsets / hours:.0f}/h; the band: "
          f"{sum(len(alarm_onsets(m.alarms)) for m in free.values())})")

    print("\n2. threshold height: thresholds x s (2 Hz band), pushes and in-sample onsets on C")
    print(f"  {'s':>4}  {'detected':>8}  {'median delay [s]':>16}  {'onsets on C':>11}  per hour")
    for s in SCALES:
        delays = []
        for k, t, lo, hi in windows:
            d = first_after(pushed[k].ratio.max(axis=1) > s, t, lo, hi)
            if d is not None:
                delays.append(d)
        onsets = sum(len(alarm_onsets(m.ratio.max(axis=1) > s)) for m in free.values())
        print(f"  {s:4.1f}  {len(delays):>5}/{len(windows)}  {np.median(delays):16.3f}  "
              f"{onsets:11d}  {onsets / hours:8.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
