"""Study: can thresholds follow the motion, so that they transfer to another task? (#38)

Cross-task protocol of ``benchmarks/real_ur10e.py`` (``cross_task``): P_f
trained on the training runs (state only), thresholds on the 21 unseen
recordings plus the 2020 task's ``collision_free.csv`` (2 Hz low-pass,
5-sample debounce, regimes with a 5 s rest reference, global
leave-one-recording-out margin), scored on the 2020 collision files with the
labels of ``benchmarks/labels/ur10e_events.json``.

``python studies/transfer_scale.py --study NAME`` with NAME in

- ``peaks``: peak ``|m|`` per recording in the moving regime, and of the
  2020 collisions, and what the joints did at the calibration peaks;
- ``scale``: thresholds over a residual scale ``sigma_l(x)`` fitted by NNLS
  (local power of the residual on ``[1, |qd|, |qdd|]`` of every joint) on
  out-of-fold residuals of the training runs (3 folds by run), or on the
  calibration recordings themselves (in-sample: an upper bound);
- ``cells``: per-joint cells in the moving regime (joint sliding or stuck,
  ``|qd_l| < v0``; arm acceleration below or above ``acc``) with the margin
  shared globally, per regime or per cell.

- ``ceiling``: for each band (filter, debounce), how many 2020 collisions
  rise above the largest value the 2020 event-free segments reach on the
  same joint (an oracle threshold with 0 onsets there: what no calibration
  can beat);
- ``refclip``: the rest reference clipped to the largest ``|b|`` of the
  calibration data (gpcd calibrate's default settings, the 21 unseen
  recordings): alarm episodes per push with and without the clip.

Trained models and residuals are cached in ``--cache`` (default
``/tmp/transfer_scale.joblib``).
"""
import argparse
import json
import sys
import warnings
from pathlib import Path

import joblib
import numpy as np
from scipy.optimize import nnls
from scipy.signal import lfilter

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import real_ur10e as B  # noqa: E402
from sklearn.base import BaseEstimator, RegressorMixin  # noqa: E402
from sklearn.frozen import FrozenEstimator  # noqa: E402

from sklearn_gpcd.detection import (  # noqa: E402
    AlarmRule,
    CollisionDetector,
    Regimes,
    calibrate_across_recordings,
    stack_currents,
)
from sklearn_gpcd.layout import block_columns  # noqa: E402
from sklearn_gpcd.metrics import alarm_onsets  # noqa: E402
from sklearn_gpcd.robots import load_robot  # noqa: E402
from sklearn_gpcd.workflow import train_model, training_set  # noqa: E402

J = 6
DT = 0.01


def lowpass(x, fc=2.0):
    a = 1 - np.exp(-2 * np.pi * fc * DT)
    return lfilter([a], [1, -(1 - a)], x, axis=0)


def motion(X):
    return np.abs(X[:, block_columns("qd", J)]), np.abs(X[:, block_columns("qdd", J)])


def load_cache(path):
    if Path(path).exists():
        return joblib.load(path)
    root = B.real_data_path(B.DATASET, None)
    train, unseen, _ = B.split_recordings(root, False)
    free = B.load(root / B.FAMILY_2020 / "collision_free.csv")
    others = {k: B.load(root / k) for k in [*B.COLLISIONS, *B.PUSHES]}
    robot = load_robot("ur10e")
    data = training_set(list(train), "causal", signals=())
    settings = dict(inputs="causal", n_support=1000, optimizer="adam", seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = train_model(data, robot, "p_f", **settings).regressor
        Xs, Ss = [], []
        idx = np.arange(len(train))
        for f in range(3):
            fold = train_model(training_set([train[i] for i in idx if i % 3 != f], "causal",
                                            signals=()), robot, "p_f", **settings).regressor
            for i in idx[idx % 3 == f]:
                X = data.features.transform(train[i])
                Xs.append(X)
                Ss.append(train[i].current - fold.predict(X))
        recs = dict(unseen, collision_free=free, **others)
        blocks = {k: stack_currents(data.features.transform(r), r.current)
                  for k, r in recs.items()}
    cache = dict(model=model, Xs=Xs, Ss=Ss, blocks=blocks,
                 times={k: r.time for k, r in recs.items()},
                 calibration=[*unseen, "collision_free"])
    joblib.dump(cache, path)
    return cache


class Scaled(RegressorMixin, BaseEstimator):
    """A frozen model whose ``return_std`` is a residual scale (for normalize="std")."""

    def __init__(self, model=None, scale=None):
        self.model = model
        self.scale = scale

    def fit(self, X, y=None):
        return self

    def __sklearn_is_fitted__(self):
        return True

    def predict(self, X, return_std=False):
        mean = self.model.predict(X)
        return (mean, self.scale(X)) if return_std else mean


def nnls_scale(Xs, Ss):
    """sigma_l(x)^2 = c_l . lowpass([1, |qd|, |qdd|]) fitted to lowpass(s_l^2)."""
    F = np.vstack([lowpass(np.column_stack([np.ones(len(X)), *motion(X)])) for X in Xs])
    P = np.vstack([lowpass(S ** 2) for S in Ss])
    coef = np.array([nnls(F, P[:, j])[0] for j in range(J)]).T
    print("  coefficients (rows 1, |qd_1..6|, |qdd_1..6|; columns joints):")
    print(np.array2string(coef, precision=3, suppress_small=True))
    return lambda X: np.sqrt(np.maximum(
        np.column_stack([np.ones(len(X)), *motion(X)]) @ coef, 1e-12))


def score(det, cache, labels):
    out = []
    for family in (B.COLLISIONS, B.PUSHES):
        hits = total = outside = 0
        for key in family:
            t = cache["times"][key] - cache["times"][key][0]
            alarms = det.monitoring_signal(cache["blocks"][key]).alarms
            events, extra = B.score_alarms(alarms, t, labels[key]["events"])
            hits += sum(e["detected"] for e in events)
            total += len(events)
            outside += len(extra)
        out.append(f"{hits}/{total} (+{outside} outside)")
    return "2020 collisions {}, pushes {}".format(*out)


def calibrated(cache, regressor=None, normalize=None, *, keys=None, rules=None,
               param_grid=None):
    """``calibrate_across_recordings`` of ``rules`` (default: the present rule) over
    ``regressor`` (default: the cached P_f) on ``keys`` (default: the cross-task
    calibration recordings)."""
    if rules is None:
        rules = AlarmRule("per_joint", false_alarm_rate=0.0, filter_cutoff=2.0,
                          min_duration=5, regimes=Regimes(rest_reference=5.0))
    regressor = cache["model"] if regressor is None else regressor
    det = CollisionDetector(FrozenEstimator(regressor), n_joints=J, sample_time="auto",
                            rules=rules, normalize=normalize)
    keys = cache["calibration"] if keys is None else keys
    return calibrate_across_recordings(det, {k: cache["blocks"][k] for k in keys},
                                       {k: cache["times"][k] for k in keys},
                                       param_grid=param_grid)


def study_scale(cache, labels):
    model = cache["model"]
    keys = cache["calibration"]
    cX = [cache["blocks"][k][:, :-J] for k in keys]
    cS = [cache["blocks"][k][:, -J:] - model.predict(X) for k, X in zip(keys, cX)]
    for name, regressor, normalize in (
            ("present rule", model, None),
            ("scale, out-of-fold training residuals", Scaled(model, nnls_scale(
                cache["Xs"], cache["Ss"])), "std"),
            ("scale, calibration residuals (in-sample)", Scaled(model, nnls_scale(cX, cS)),
             "std")):
        cal = calibrated(cache, regressor, normalize)
        print(f"{name}: margin {np.max(cal.margin):.2f}, nested onsets {cal.n_false_alarms}, "
              f"{score(cal.detector, cache, labels)}", flush=True)


def monitoring(cache):
    """Debounced |m|, arm regimes, |qd|, |qdd| of every recording (present rule)."""
    det = calibrated(cache, cache["model"]).detector
    rule = det.rules_[0]
    out = {}
    for key, block in cache["blocks"].items():
        band = det.monitoring_signal(block).bands[0]
        out[key] = (rule.debounced(band.signal), band.regime, *motion(block[:, :-J]))
    return out


def event_mask(key, cache, labels, after=1.0):
    t = cache["times"][key] - cache["times"][key][0]
    mask = np.zeros(len(t), dtype=bool)
    for e in labels[key]["events"]:
        mask |= (t >= e["start_s"] - 0.5) & (t <= e.get("tail_stop_s", e["stop_s"]) + after)
    return mask


def study_peaks(cache, labels):
    series = monitoring(cache)
    for key, (deb, regime, qd, qdd) in series.items():
        moving = regime == 0
        if not moving.any() or key in B.PUSHES:
            continue
        line = f"{Path(key).name[:28]:<28} moving peak |m| {np.round(deb[moving].max(0), 2)}"
        if key in B.COLLISIONS:
            ev = event_mask(key, cache, labels)
            line += (f"\n{'':28} collisions {np.round(deb[ev].max(0), 2)}, event-free "
                     f"{np.round(deb[~ev & moving].max(0), 2)}")
        else:
            k1, k2 = (np.flatnonzero(moving)[np.argmax(deb[moving, j])] for j in (0, 1))
            line += (f"; at the joint-1 peak |qd_1| {qd[k1, 0]:.3f}, at the joint-2 peak "
                     f"|qd_2| {qd[k2, 1]:.3f} (max |qdd| {qdd[k2].max():.2f})")
        print(line)


def study_cells(cache, labels):
    series = monitoring(cache)
    keys = cache["calibration"]
    for v0, acc, share in ((0.05, np.inf, "global"), (0.05, 1.5, "global"),
                           (0.05, 1.5, "regime"), (0.05, 1.5, "cell")):
        codes = {}
        for key, (deb, regime, qd, qdd) in series.items():
            cell = np.where(qd < v0, 2, np.where(qdd.max(1, keepdims=True) < acc, 0, 1))
            codes[key] = np.where(regime[:, None] == 0, cell, regime[:, None] + 2)
        peaks = {}
        for key in keys:
            deb, code = series[key][0], codes[key]
            peaks[key] = np.array([[deb[code[:, j] == g, j].max(initial=0.0) for j in range(J)]
                                   for g in range(5)])

        def level(subset):
            L = np.max([peaks[k] for k in subset], axis=0)
            L[1] = np.maximum(L[1], L[0])  # no tighter at higher acceleration
            for j in range(J):
                present = L[:, j] > 0
                L[~present, j] = L[present, j].max() if present.any() else 1.0
            return L

        def margin(subset):
            factors = np.max([peaks[r] / level([k for k in subset if k != r])
                              for r in subset], axis=0)
            factors = np.maximum(factors, 1.0)
            return {"global": factors.max(), "regime": factors.max(1, keepdims=True),
                    "cell": factors}[share]

        def alarms(key, T):
            return series[key][0] > np.take_along_axis(T, codes[key], 0)

        nested = 0
        for r in keys:
            others = [k for k in keys if k != r]
            alarm = alarms(r, margin(others) * level(others)).any(1)
            nested += len(alarm_onsets(alarm, cache["times"][r] - cache["times"][r][0]))
        T = margin(keys) * level(keys)
        hits = total = 0
        for key in B.COLLISIONS:
            t = cache["times"][key] - cache["times"][key][0]
            events, _ = B.score_alarms(alarms(key, T), t, labels[key]["events"])
            hits += sum(e["detected"] for e in events)
            total += len(events)
        print(f"v0 {v0}, acc {acc}, margin {share}: largest margin {np.max(margin(keys)):.2f}, "
              f"nested onsets {nested}, 2020 collisions {hits}/{total}; sliding thresholds "
              f"{np.round(T[0], 2)}", flush=True)


def study_ceiling(cache, labels):
    keys = cache["calibration"]
    root = B.real_data_path(B.DATASET, None)
    recs = {key: B.load(root / key) for key in B.COLLISIONS}
    fits = dict(groups=np.repeat(np.arange(len(keys)), [len(cache["blocks"][k]) for k in keys]),
                time=np.concatenate([cache["times"][k] for k in keys]))
    Z = np.concatenate([cache["blocks"][k] for k in keys])
    for cutoff, order, debounce in ((2.0, 1, 5), (4.0, 2, 5), (10.0, 1, 2), (20.0, 1, 3)):
        rule = AlarmRule("per_joint", false_alarm_rate=0.0, filter_cutoff=cutoff,
                         filter_order=order, min_duration=debounce,
                         regimes=Regimes(rest_reference=5.0))
        det = CollisionDetector(FrozenEstimator(cache["model"]), n_joints=J,
                                sample_time="auto", rules=rule).fit(Z, **fits)
        peaks, free = [], np.zeros(J)
        for key in B.COLLISIONS:
            t = cache["times"][key] - cache["times"][key][0]
            ratio = det.monitoring_signal(cache["blocks"][key]).bands[0].ratio
            ratio = np.min([np.roll(ratio, k, axis=0) for k in range(debounce)], axis=0)
            for a, b in B.free_segments(recs[key], labels[key]):
                free = np.maximum(free, ratio[a + debounce:b].max(axis=0))
            peaks += [ratio[(t >= e["start_s"]) & (t <= e.get("tail_stop_s", e["stop_s"])
                                                   + 0.5)].max(axis=0)
                      for e in labels[key]["events"]]
        over = (np.array(peaks) / free).max(axis=1)
        print(f"{cutoff:g} Hz order {order} debounce {debounce}: "
              f"{int((over > 1).sum())}/{len(peaks)} collisions above the "
              f"event-free maximum; weakest {np.round(np.sort(over)[:4], 2)}", flush=True)


def study_refclip(cache, labels):
    from sklearn_gpcd.detection import _regimes
    from sklearn_gpcd.workflow import SELECT_GRID

    keys = cache["calibration"][:-1]
    rule = AlarmRule("per_joint", false_alarm_rate=0.0, filter_cutoff=2.0, min_duration=5,
                     regimes=Regimes(rest_reference=5.0))
    det = calibrated(cache, keys=keys, rules=rule, param_grid=SELECT_GRID).detector
    fitted = det.rules_[0]
    limit = np.zeros(J)
    for key in keys:
        r = det.residuals(cache["blocks"][key])
        _, regime, reference = fitted.signal(r.residual, motion=r.motion)
        limit = np.maximum(limit, np.abs(reference[regime == 2]).max(axis=0, initial=0.0))
    print(f"largest |b| of the calibration data {np.round(limit, 2)}")
    original = _regimes.RegimeState._reference

    def clipped(self, regime, signal):  # b clipped after each step (entry sample: m - m)
        original(self, regime, signal)
        if regime == 2 and self.beta is not None:
            np.clip(self.reference, -limit, limit, out=self.reference)
    for name, method in (("as is", original), ("clipped", clipped)):
        _regimes.RegimeState._reference = method
        for key in B.PUSHES:
            t = cache["times"][key] - cache["times"][key][0]
            alarm = det.monitoring_signal(cache["blocks"][key]).alarms.any(axis=1)
            starts = np.flatnonzero(alarm & ~np.r_[False, alarm[:-1]])
            ends = np.flatnonzero(alarm & ~np.r_[alarm[1:], False])
            episodes = [(round(float(t[a]), 2), round(float(t[b]), 2)) for a, b in zip(starts, ends)]
            print(f"{name}, {Path(key).name}: alarms {episodes}; pushes "
                  f"{[(e['start_s'], e['stop_s']) for e in labels[key]['events']]}")
    _regimes.RegimeState._reference = original


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", required=True,
                        choices=("peaks", "scale", "cells", "ceiling", "refclip"))
    parser.add_argument("--cache", default="/tmp/transfer_scale.joblib")
    args = parser.parse_args()
    root = B.real_data_path(B.DATASET, None)
    if not root.exists():
        print(f"skipped: no UR10e data in {root}")
        return
    labels = json.loads(B.LABELS.read_text())["files"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cache = load_cache(args.cache)
        {"peaks": study_peaks, "scale": study_scale, "cells": study_cells,
         "ceiling": study_ceiling, "refclip": study_refclip}[args.study](
            cache, labels)


if __name__ == "__main__":
    main()
