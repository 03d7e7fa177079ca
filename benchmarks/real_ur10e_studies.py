"""What we tried on the real UR10e to close issue 14's open points, and what it gave.

``benchmarks/real_ur10e.py`` measures the operating point; this script keeps
the studies behind the choices, so the figures in the issue notes can be
re-run. Each study trains SP_C / SP_S with the benchmark's own settings
(``train_models``: causal inputs, 1,000 support rows, Adam, seed 0) and
scores them with the benchmark's functions (LORO margin, nested false alarms,
labelled pushes).

Studies (``--study``):

- ``rest``: the arm-level regimes and rest reference, swept over
  ``settle_time`` and ``rest_reference`` for SP_C and the peer ``i - i_des``:
  global LORO margin, nested alarm onsets on the 21 unseen collision-free
  recordings, pushes detected, thresholds of joints 1-3 relative to the
  peer's at ``settle_time=0.5``, and the arm-at-rest quasi-static nMSE on
  p1..p10 and ptp_10_points.
- ``floor``: the nMSE an oracle reaches on the rest phases of ptp_10_points
  by predicting each sample with a *centred* moving average of the measured
  current (non-causal, the best a smooth predictor can do against the
  sensor noise).
- ``family``: collision_detection_data_2020 with SP_S trained on the
  identification runs (the benchmark) or also on ``collision_free.csv`` of
  the same task, thresholds by LORO on the task's other collision-free data
  that was not trained on.
- ``select``: the ``rest`` grid chosen honestly: for every unseen recording,
  the cell (``settle_time``, ``rest_reference``) is chosen on the other 20
  only, and that recording is scored with the cell's levels and margin from
  the same 20 (selection nested inside leave-one-recording-out). Criterion:
  the time-weighted mean log ratio of the thresholds of joints 1-3 to the
  peer's at ``settle_time=0.5`` without reference, both calibrated on the
  same recordings (smaller thresholds = a more sensitive monitor; every cell
  has 0 onsets on its own calibration recordings by construction of the
  margin). The pushes are scored at the cell chosen on all 21.
- ``relax``: what the held current does after a stop, on every stop of
  every collision-free recording with target current that is followed by
  at least 4 s of rest: the residual ``i - i_des`` 0.15-0.35 s after the stop, in the last
  second of the rest, and the time constant of an exponential fitted in
  between; then the arm-at-rest nMSE on ptp_10_points of the simplest causal
  "model" of it, an exponential average of the measured current itself
  started at each stop, against its time constant.
- ``margin``: how far the leave-one-recording-out margin is shared
  (``MARGIN_RULES``: per cell, per regime, per joint, global), for the
  peer, P_f, SP_S and SP_C (with and without the rest reference): nested
  alarm onsets on the 21 unseen recordings, pushes detected and the margin
  of each joint; then collision_detection_data_2020 (P_f, SP_S) under each
  rule: collisions detected and onsets on the event-free segments.
- ``presliding``: is the moving band of joint 2 set by friction at velocity
  reversals? The controller's model turns its Coulomb friction over smoothly
  in the velocity, centred on the reversal; the measured current turns over
  after it, along the displacement since the reversal (pre-sliding, Dahl's
  model). SP_C is refitted with the causal
  Dahl state ``z`` of each joint (:func:`dahl_state`, characteristic
  displacement ``x0``, velocities below a dead band do not move it) either
  in the mean (``[i_c, z, tanh(qd / 0.005)]`` per joint, least squares) or
  as six more GP input columns; thresholds against the peer's, global LORO
  margin, nested onsets and pushes, as in ``rest``.

- ``impact``: do the short contacts that collision_detection_data_2020's
  models miss (taps of 0.1-0.2 s on link 2, which the 2 Hz filter of the
  benchmark's rule halves) show in a faster band? The rule is run a second
  time with another low-pass and debounce (``IMPACT_BANDS``: cut-off [Hz],
  filter order, debounce [samples]), calibrated the same way, and a sample
  alarms when either band does. First on the 2020 task (P_f, SP_S: the
  benchmark's protocol for it), every band of the sweep; then the band
  ``IMPACT_CHECK`` on the 21 unseen collision-free recordings and the pushes
  (nested onsets of the union, pushes detected, the fast band's margin and
  thresholds) for the peer, P_f, SP_S and SP_C at settle 0.5 s without rest
  reference and at settle 3 s / rest reference 2 s. The model predictions
  are computed once per recording (:class:`_Given`).
- ``correction``: does SP_C's GP correction transfer, joint by joint? Over
  the 12 training runs, each left out of an SP_C fit in turn, the debounced
  moving-regime peak of each joint's monitoring signal (settle 3 s / rest
  reference 2 s, SP_C sel's choice) with the correction and with the
  controller's mean ``w i_c + b`` alone; the correction is kept on the joints
  where it lowers the peak on average. Then, on the 21 unseen recordings at
  the same settings: the peer, SP_C, SP_C with the corrections so chosen,
  and SP_C without joint 2's correction (chosen by looking at those
  recordings, for comparison only): margin, nested onsets, pushes,
  thresholds against the peer's.
- ``braking``: what the second band of ``impact`` trips on. Two causes
  found by reading its false alarms: (1) at rest the logged velocity
  jitters by about 1e-4 rad/s, and P_f's Coulomb column
  :math:`\mathrm{sign}(\dot q)` flips the predicted current by the whole
  Coulomb level (about 1.2 A on joint 2; jointwise_6 at 79.5 s); (2) hard
  stops of the jointwise runs (causal ``|qdd|`` up to 9.6 rad/s^2, against at
  most 5.05 in the training runs and 2.4 in the 2020 collision files) ring
  the current by several ampere for about half a second, for the peer too
  (jointwise_2 at 61.7 s). Tried: P_f with a smooth Coulomb column
  (``tanh(qd / width)``, ``RigidBodyRegressor(coulomb_width=...)``,
  ``COULOMB_WIDTHS``) and a fourth regime,
  ``braking`` (:func:`braking`: causal ``|qdd|`` on some joint above the
  largest of the training runs, held ``BRAKE_HOLD`` s), with its own
  per-joint levels, calibrated like the others. For the peer, P_f and P_f
  with each width, every band of ``IMPACT_BANDS``: the 2020 task (family
  calibration, braking regime on) and ``C`` at settle 3 s / rest reference
  2 s with the braking regime off and on (nested onsets, pushes, moving
  thresholds of joints 1-3 against the peer's at the same settings). Then
  the second band chosen honestly, braking regime on
  (:func:`_nested_band`): on ``C`` each recording is scored with the
  band chosen on the other 20 (fewest nested onsets of the two bands'
  union there, then the smallest time-weighted mean log threshold, the
  ranking of ``calibrate_across_recordings``); each 2020 file with the band
  chosen on its own calibration pool.

Run: ``python benchmarks/real_ur10e_studies.py --study rest`` (about 4 min on
2 cores), ``--study floor`` (seconds), ``--study family`` (about 3 min),
``--study select`` (about 2 min), ``--study relax`` (seconds), ``--study
margin`` (about 7 min), ``--study presliding`` (about 8 min), ``--study impact``
(about 1.5 min), ``--study correction`` (about 4 min), ``--study braking``
(about 1.5 min). The
data must be in ``../shared/data/real/ur10e_mamedov`` (or ``--data``); the
script exits with a message when it is not.
"""

import argparse
import json
import sys
import warnings
from collections import Counter
from pathlib import Path

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.optimize import curve_fit

sys.path.insert(0, str(Path(__file__).resolve().parent))

import real_ur10e as bench  # noqa: E402

from sklearn_gpcd.detection import (  # noqa: E402
    MARGIN_RULES,
    calibrate_across_recordings,
    loro_margin,
    nested_alarms,
    nested_false_alarms,
    regime_excursions,
    regime_levels,
    stack_currents,
)
from sklearn.base import BaseEstimator, RegressorMixin, TransformerMixin, clone  # noqa: E402
from sklearn.gaussian_process.kernels import ConstantKernel, WhiteKernel  # noqa: E402

from sklearn_gpcd.dynamics import (  # noqa: E402
    ControllerCurrent,
    ControllerFeatures,
    RigidBodyRegressor,
)
from sklearn_gpcd.gp import (  # noqa: E402
    ParametricMean,
    SemiParametricGPRegressor,
    make_p_f,
    resolve_n_support,
)
from sklearn_gpcd.kernels import ARDRBF  # noqa: E402
from sklearn_gpcd.layout import block_columns, column_index  # noqa: E402
from sklearn_gpcd.experiments.paper import split_nmse  # noqa: E402
from sklearn_gpcd.features import contiguous_segments  # noqa: E402
from sklearn_gpcd.metrics import alarm_onsets  # noqa: E402
from sklearn_gpcd.workflow import training_set  # noqa: E402

SETTLE_TIMES = (0.5, 1.0, 2.0, 3.0)
REST_REFERENCES = (None, 2.0, 5.0)


def rule(model, settle_time, rest_reference):
    """The benchmark's detection rule with another settle time."""
    return bench.detector(model, rest_reference).set_params(settle_time=settle_time)


def pushes_detected(det, pushes, push_blocks, labels):
    hit = total = 0
    for key, rec in pushes.items():
        events, _, _ = bench.score_events(det, push_blocks[key], rec, labels[key]["events"])
        hit += sum(e["detected"] for e in events)
        total += len(events)
    return hit, total


def rest_nmse(model, unseen, blocks, settle_time, rest_reference):
    """Arm-at-rest quasi-static nMSE (Eq. 18) of the monitor's prediction."""
    out = {}
    for test, keys in {"p1..p10": bench.STILL, "ptp": [bench.PTP]}.items():
        y, pred, qd = [], [], []
        for key in keys:
            y.append(unseen[key].current)
            pred.append(bench.rest_referenced_prediction(model, blocks[key], rest_reference,
                                                         settle_time))
            qd.append(unseen[key].qd)
        y, pred, qd = map(np.concatenate, (y, pred, qd))
        still = np.repeat(np.all(np.abs(qd) < bench.SIGMA_V, axis=1)[:, None], 6, axis=1)
        out[test] = split_nmse(y, pred, qd, bench.SIGMA_V, rows=still)["quasi_static"]
    return out


def study_rest(root, labels, n_support, seed):
    train, unseen, _ = bench.split_recordings(root, quick=False)
    pushes = {key: bench.load(root / key) for key in bench.PUSHES}
    data = training_set(list(train), "causal")
    models, _ = bench.train_models(data, n_support, seed, None, names=("SP_C",))
    models[bench.PEER] = ControllerCurrent(6).fit(data.X, data.y)
    blocks = {k: stack_currents(data.features.transform(r), r.current)
              for k, r in unseen.items()}
    push_blocks = {k: stack_currents(data.features.transform(r), r.current)
                   for k, r in pushes.items()}
    peer = calibrate_across_recordings(rule(models[bench.PEER], 0.5, None), blocks,
                                       bench.times_of(unseen)).detector.thresholds_
    print("monitor  settle  tau  | margin onsets pushes | moving/peer j1-3 | rest/peer j1-3 | "
          "nMSE rest p1..p10 j1..6 | nMSE rest ptp j1..6", flush=True)
    for name in (bench.PEER, "SP_C"):
        for settle_time in SETTLE_TIMES:
            for tau in REST_REFERENCES:
                cal = calibrate_across_recordings(rule(models[name], settle_time, tau), blocks,
                                                  bench.times_of(unseen))
                hit, total = pushes_detected(cal.detector, pushes, push_blocks, labels)
                ratio = cal.detector.thresholds_ / peer
                nmse = rest_nmse(models[name], unseen, blocks, settle_time, tau)
                print(f"{name:9s} {settle_time:4.1f} {str(tau):4s} | {cal.margin.max():5.2f} "
                      f"{cal.n_false_alarms:3d} {hit:3d}/{total} | "
                      f"{np.round(ratio[0, :3], 2)} | {np.round(ratio[2, :3], 2)} | "
                      f"{np.round(nmse['p1..p10'], 2)} | {np.round(nmse['ptp'], 2)}",
                      flush=True)


def study_floor(root):
    rec = bench.load(root / bench.PTP)
    still = np.all(np.abs(rec.qd) < bench.SIGMA_V, axis=1)
    for window in (11, 51, 101):
        floor = []
        for joint in range(6):
            errors, values = [], []
            for a, b in contiguous_segments(still):
                segment = rec.current[a:b, joint]
                smooth = uniform_filter1d(segment, size=min(window, b - a), mode="nearest")
                errors.append(segment - smooth)
                values.append(segment)
            floor.append(np.mean(np.concatenate(errors) ** 2) / np.concatenate(values).var())
        print(f"ptp_10_points arm at rest, centred moving average of {window} samples: "
              f"nMSE {np.round(floor, 3)}")


def study_family(root, labels, n_support, seed):
    train, _, _ = bench.split_recordings(root, quick=False)
    free = bench.load(root / bench.FAMILY_2020 / "collision_free.csv")
    recs = {key: bench.load(root / key) for key in bench.COLLISIONS}
    segments = {k: bench.free_segments(r, labels[k]) for k, r in recs.items()}
    for variant, runs in (("identification runs", train), ("+ collision_free.csv", train + [free])):
        data = training_set(list(runs), "causal", allow_missing=True)
        model = bench.train_models(data, n_support, seed, None, names=("SP_S",))[0]["SP_S"]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the missing i_c block, filled with zeros
            inputs = {k: stack_currents(data.features.transform(r), r.current)
                      for k, r in recs.items()}
            free_block = stack_currents(data.features.transform(free), free.current)
        hits = total = onsets = 0
        for key, rec in recs.items():
            blocks, pieces = {}, {}
            if variant == "identification runs":        # not trained on: calibrate on it
                blocks["collision_free"], pieces["collision_free"] = free_block, free
            for other in bench.COLLISIONS:
                if other != key:
                    for i, (a, b) in enumerate(segments[other]):
                        blocks[f"{other}#{i}"] = inputs[other][a:b]
                        pieces[f"{other}#{i}"] = recs[other].slice(a, b)
            cal = calibrate_across_recordings(bench.detector(model), blocks,
                                              bench.times_of(pieces))
            events, _, mon = bench.score_events(cal.detector, inputs[key], rec,
                                                labels[key]["events"])
            t = rec.time - rec.time[0]
            alarm = mon.alarms.any(axis=1)
            free_onsets = [o for a, b in segments[key]
                           for o in alarm_onsets(alarm[a:b], t[a:b])]
            hit = sum(e["detected"] for e in events)
            hits, total, onsets = hits + hit, total + len(events), onsets + len(free_onsets)
            missed = [e["start_s"] for e in events if not e["detected"]]
            print(f"SP_S trained on {variant}: {Path(key).name} {hit}/{len(events)}, "
                  f"{len(free_onsets)} onsets on its event-free segments, margin "
                  f"{cal.margin.max():.2f}, missed at {missed} s", flush=True)
        print(f"SP_S trained on {variant}: {hits}/{total} collisions, {onsets} onsets", flush=True)


class _Memo:
    """A fitted model whose predictions are kept per input array.

    The ``select`` study runs the detection rule 13 times over the same
    recordings; the model's predictions do not depend on the rule.
    ``clone`` returns the object itself, like :class:`FrozenEstimator`.
    """

    def __init__(self, model):
        self.model, self.memo = model, {}

    def __sklearn_clone__(self):
        return self

    def __sklearn_is_fitted__(self):
        return True

    def fit(self, *args, **kwargs):
        return self

    def predict(self, X, **kwargs):
        key = (id(X), X.shape, kwargs.get("return_std", False))
        if key not in self.memo:
            self.memo[key] = (X, self.model.predict(X, **kwargs))  # X kept: id stays unique
        return self.memo[key][1]

    def __getattr__(self, name):
        return getattr(self.__dict__["model"], name)


def _operating_point(peaks, keys):
    """Thresholds of the benchmark's rule on the recordings ``keys``: levels x LORO margin."""
    return regime_levels(peaks, keys) * loro_margin(peaks, keys, bench.MARGIN_RULE)


def study_select(root, labels, n_support, seed):
    train, unseen, _ = bench.split_recordings(root, quick=False)
    pushes = {key: bench.load(root / key) for key in bench.PUSHES}
    data = training_set(list(train), "causal")
    models, _ = bench.train_models(data, n_support, seed, None, names=("SP_C",))
    models = {bench.PEER: ControllerCurrent(6).fit(data.X, data.y), **models}
    blocks = {k: stack_currents(data.features.transform(r), r.current)
              for k, r in unseen.items()}
    push_blocks = {k: stack_currents(data.features.transform(r), r.current)
                   for k, r in pushes.items()}
    times, keys = bench.times_of(unseen), list(blocks)
    Z = np.concatenate([blocks[k] for k in keys])
    groups = np.repeat(np.arange(len(keys)), [len(blocks[k]) for k in keys])
    time = np.concatenate([times[k] for k in keys])
    cells = [(s, t) for s in SETTLE_TIMES for t in REST_REFERENCES]
    memos = {name: _Memo(model) for name, model in models.items()}

    def excursions(model, cell):
        det = rule(model, *cell).set_params(margin=1.0).fit(Z, groups=groups, time=time)
        series = regime_excursions(det, blocks)
        return series, {k: v[2] for k, v in series.items()}

    _, peer_peaks = excursions(memos[bench.PEER], (0.5, None))
    for name, memo in memos.items():
        runs = {}
        for cell in cells:
            series, peaks = excursions(memo, cell)
            runs[cell] = (series, peaks, nested_false_alarms(series, times, bench.MARGIN_RULE))

        def criterion(cell, ks):
            series, peaks, _ = runs[cell]
            counts = sum(np.bincount(series[k][1], minlength=3) for k in ks)
            ratio = _operating_point(peaks, ks) / _operating_point(peer_peaks, ks)
            return float(counts / counts.sum() @ np.log(ratio[:, :3]).mean(axis=1))

        chosen, onsets = {}, {}
        for held_out in keys:
            others = [k for k in keys if k != held_out]
            chosen[held_out] = min(cells, key=lambda cell: criterion(cell, others))
            onsets[held_out] = runs[chosen[held_out]][2][held_out]["onsets"]
        final = min(cells, key=lambda cell: criterion(cell, keys))
        cal = calibrate_across_recordings(rule(memo, *final), blocks, times)
        hit, total = pushes_detected(cal.detector, pushes, push_blocks, labels)
        ratio = cal.detector.thresholds_ / _operating_point(peer_peaks, keys)
        print(f"{name}: cells chosen in the 21 outer folds {dict(Counter(chosen.values()))}; "
              f"nested onsets {sum(map(len, onsets.values()))} "
              f"({ {k: v for k, v in onsets.items() if v} }); chosen on all 21: {final}, "
              f"margin {cal.margin.max():.2f}, pushes {hit}/{total}; thresholds / peer's at "
              f"(0.5, None), joints 1-3: moving {np.round(ratio[0, :3], 2)}, settling "
              f"{np.round(ratio[1, :3], 2)}, rest {np.round(ratio[2, :3], 2)}", flush=True)
        for held_out in keys:
            if chosen[held_out] != final:
                print(f"    {held_out}: chosen {chosen[held_out]} without it", flush=True)
        for cell in cells:
            print(f"    {cell}: criterion on all 21 {criterion(cell, keys):+.3f}, nested "
                  f"onsets {sum(len(f['onsets']) for f in runs[cell][2].values())}", flush=True)


def study_margin(root, labels, n_support, seed):
    train, unseen, _ = bench.split_recordings(root, quick=False)
    pushes = {key: bench.load(root / key) for key in bench.PUSHES}
    data = training_set(list(train), "causal")
    models, _ = bench.train_models(data, n_support, seed, None, names=("P_f", "SP_S", "SP_C"))
    models = {bench.PEER: ControllerCurrent(6).fit(data.X, data.y), **models}
    blocks = {k: stack_currents(data.features.transform(r), r.current)
              for k, r in unseen.items()}
    push_blocks = {k: stack_currents(data.features.transform(r), r.current)
                   for k, r in pushes.items()}
    times = bench.times_of(unseen)
    print("unseen collision-free recordings (21, 11.9 min): nested alarm onsets, pushes "
          "detected, margin per joint", flush=True)
    for name, model in models.items():
        for tau in (None, bench.REST_TAU) if name in (bench.PEER, "SP_C") else (None,):
            for rule in MARGIN_RULES:
                cal = calibrate_across_recordings(bench.detector(model, tau), blocks, times,
                                                  rule=rule)
                onsets = sum(len(f["onsets"]) for f in
                             nested_false_alarms(cal.series, times, rule).values())
                hit, total = pushes_detected(cal.detector, pushes, push_blocks, labels)
                print(f"{name + (' +R' if tau else ''):12s} {rule:7s} onsets {onsets:3d}, "
                      f"pushes {hit}/{total}, margin {np.round(cal.margin.max(axis=0), 2)}",
                      flush=True)
    family_models = {name: models[name] for name in ("P_f", "SP_S")}  # same runs, same fit
    for rule in MARGIN_RULES:
        family = bench.collision_family(root, train, labels, n_support, seed, None,
                                        lambda message: None, rule=rule,
                                        models=family_models)
        for name, res in family.items():
            missed = [(Path(key).stem, e["start_s"]) for key, f in res["files"].items()
                      for e in f["events"] if not e["detected"]]
            print(f"{bench.FAMILY_2020} {name:4s} {rule:7s} {res['n_detected']}/"
                  f"{res['n_events']} collisions, {res['free_onsets']} onsets on the "
                  f"event-free segments; missed {missed}", flush=True)


def _relaxation(t, y):
    """Residual shortly after a stop, at the end of the rest, and a fitted time constant."""
    start, end = y[(t > 0.15) & (t < 0.35)].mean(), y[t > t[-1] - 1.0].mean()
    late = t > 0.15
    try:
        (_, _, tau), _ = curve_fit(lambda x, a, b, tau: a + b * np.exp(-x / tau), t[late],
                                   y[late], p0=(end, start - end, 1.5), maxfev=5000)
    except RuntimeError:
        tau = np.nan
    return start, end, tau


def study_relax(root):
    files = (sorted((root / bench.IDENTIFICATION).glob("*.csv"))
             + sorted((root / "jointwise_motion").glob("*.csv"))
             + [root / bench.PTP])
    print("stops followed by >= 4 s of rest; residual i - i_des of joints 1, 2, 3, 5: "
          "0.15-0.35 s after the stop -> last second (fitted time constant, s)")
    for path in files:
        rec = bench.load(path)
        if rec.target_current is None:
            continue
        t = rec.time - rec.time[0]
        residual = rec.current - rec.target_current
        still = np.all(np.abs(rec.qd) < bench.SIGMA_V, axis=1)
        for a, b in contiguous_segments(still):
            if a == 0 or t[b - 1] - t[a] < 4.0:
                continue
            cells = []
            for joint in (0, 1, 2, 4):
                start, end, tau = _relaxation(t[a:b] - t[a], residual[a:b, joint])
                decay = f"{tau:.1f}" if 0 < tau < 100 else "none"
                cells.append(f"j{joint + 1} {start:+.2f} -> {end:+.2f} ({decay})")
            print(f"  {path.name[:30]:30s} stop at {t[a]:5.1f} s, rest {t[b - 1] - t[a]:4.1f} s: "
                  + ", ".join(cells), flush=True)
    rec = bench.load(root / bench.PTP)
    still = np.all(np.abs(rec.qd) < bench.SIGMA_V, axis=1)
    segments = contiguous_segments(still)
    rows = np.concatenate([np.arange(a, b) for a, b in segments])
    for tau in (0.05, 0.1, 0.2, 0.3, 0.5, 1.0, 2.0, 5.0):
        beta = -np.expm1(-0.01 / tau)
        predicted = np.empty_like(rec.current)
        for a, b in segments:
            reference = rec.current[a].copy()
            for k in range(a, b):
                predicted[k] = reference
                reference += beta * (rec.current[k] - reference)
        error = rec.current[rows] - predicted[rows]
        nmse = np.mean(error**2, axis=0) / rec.current[rows].var(axis=0)
        print(f"ptp_10_points arm at rest, exponential average of the measured current "
              f"(time constant {tau} s) from each stop: nMSE {np.round(nmse, 2)}", flush=True)


def dahl_state(time, qd, x0, dead_band=0.0):
    """Causal Dahl friction state per joint, in [-1, 1].

    .. math::

        z_k = s_k + (z_{k-1} - s_k)\\, e^{-|\\Delta q_k| / x_0}, \\quad
        \\Delta q_k = \\dot q_k\\, \\Delta t_k, \\quad s_k = \\operatorname{sign}(\\Delta q_k)

    (Dahl's model with the displacement as its clock: after a reversal the
    friction turns over within a few ``x0``). Velocities below ``dead_band``
    leave ``z`` as it is: a held joint's encoder noise does not move it.

    >>> t = np.arange(6) * 0.01
    >>> qd = np.array([[-0.01], [-0.01], [0.001], [0.01], [0.01], [0.01]])
    >>> dahl_state(t, qd, x0=3e-4, dead_band=0.002).ravel().round(2).tolist()
    [-1.0, -1.0, -1.0, -0.43, -0.03, 0.26]
    """
    dt = np.diff(time, prepend=time[0])
    dq = np.where(np.abs(qd) > dead_band, qd, 0.0) * dt[:, None]
    z = np.empty_like(qd)
    state = np.sign(qd[0])
    for k, step in enumerate(dq):
        s = np.sign(step)
        state = np.where(s != 0, s + (state - s) * np.exp(-np.abs(step) / x0), state)
        z[k] = state
    return z


class PreslidingFeatures(TransformerMixin, BaseEstimator):
    """``[i_c, z, tanh(qd / width)]`` of one joint; ``z`` in the columns after the layout."""

    def __init__(self, joint=0, n_joints=6, width=0.005):
        self.joint, self.n_joints, self.width = joint, n_joints, width

    def fit(self, X, y=None):
        self.n_features_in_ = X.shape[1]
        return self

    def transform(self, X):
        j, n = self.joint, self.n_joints
        return np.column_stack([X[:, column_index("i_c", j, n)], X[:, 6 * n + j],
                                np.tanh(X[:, column_index("qd", j, n)] / self.width)])


def study_presliding(root, labels, n_support, seed):
    train, unseen, _ = bench.split_recordings(root, quick=False)
    pushes = {key: bench.load(root / key) for key in bench.PUSHES}
    data = training_set(list(train), "causal")
    features, y = data.features, np.vstack([r.current for r in train])  # every row: no thinning
    times = bench.times_of(unseen)
    state = [int(c) for name in ("q", "qd", "qdd") for c in block_columns(name, 6)]
    velocities = [int(c) for c in block_columns("qd", 6)]

    causal = {}  # the layout's inputs of each recording, computed once for every variant

    def inputs(rec, x0, dead_band):
        X = causal.get(id(rec))
        if X is None:
            X = causal[id(rec)] = features.transform(rec)
        return X if x0 is None else np.hstack([X, dahl_state(rec.time, rec.qd, x0, dead_band)])

    def fit(X, variant):
        if variant == "mean":
            means, columns = [ParametricMean(PreslidingFeatures(j)) for j in range(6)], state
        else:
            means = [ParametricMean(ControllerFeatures(j, 6)) for j in range(6)]
            columns = state + list(range(36, X.shape[1]))
        model = SemiParametricGPRegressor(
            kernel=[ConstantKernel(1.0) * ARDRBF(np.ones(len(columns)), columns=columns)
                    + WhiteKernel(1.0) for _ in range(6)],
            mean=means, normalize_y=True, n_support=n_support, optimizer="adam",
            batch_size=min(512, n_support), random_state=seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return model.fit(X, y)

    blocks = {k: stack_currents(inputs(r, None, 0), r.current) for k, r in unseen.items()}
    peer = calibrate_across_recordings(
        bench.detector(ControllerCurrent(6).fit(data.X, data.y)), blocks,
        times).detector.thresholds_
    print("SP_C variant | margin, nested onsets, pushes | thresholds / peer's (joints 1-3) "
          "moving, rest | moving level of joints 1-3 and the recording that sets it", flush=True)
    for x0, dead_band in ((None, 0.0), (3e-4, 0.0), (3e-4, 2e-3), (1e-3, 2e-3)):
        X = np.vstack([inputs(r, x0, dead_band) for r in train])
        blocks = {k: stack_currents(inputs(r, x0, dead_band), r.current)
                  for k, r in unseen.items()}
        push_blocks = {k: stack_currents(inputs(r, x0, dead_band), r.current)
                       for k, r in pushes.items()}
        for variant in ("gp",) if x0 is None else ("mean", "gp"):
            model = fit(X, variant)
            if variant == "mean":
                coef = np.array([post.mean.coef_ for post in model.posteriors_])
                print(f"x0 {x0}, dead band {dead_band}: mean coefficients of [i_c, z, tanh] "
                      f"per joint {np.round(coef, 2).tolist()}", flush=True)
            for tau in (None, bench.REST_TAU):
                det = bench.detector(model, tau).set_params(velocity_columns=velocities)
                cal = calibrate_across_recordings(det, blocks, times)
                onsets = {Path(k).stem: v["onsets"] for k, v in
                          nested_false_alarms(cal.series, times, bench.MARGIN_RULE).items()
                          if v["onsets"]}
                hit, total = pushes_detected(cal.detector, pushes, push_blocks, labels)
                ratio = cal.detector.thresholds_ / peer
                level = cal.detector.thresholds_[0, :3] / cal.margin.max()
                where = [Path(max(cal.series, key=lambda k: cal.series[k][2][0, j])).stem
                         for j in range(3)]
                name = "SP_C" if x0 is None else f"x0 {x0} dead {dead_band} {variant}"
                print(f"{name + (' +R' if tau else ''):30s} | {cal.margin.max():.2f}, "
                      f"{sum(map(len, onsets.values()))} {onsets}, {hit}/{total} | "
                      f"{np.round(ratio[0, :3], 2)} {np.round(ratio[2, :3], 2)} | "
                      f"{np.round(level, 2)} {where}", flush=True)


#: Second bands of the ``impact`` study: (cut-off [Hz], filter order, debounce [samples]).
IMPACT_BANDS = bench.FAST_BANDS  # the candidates of the benchmark's fast band
#: The band checked on the unseen collision-free recordings and the pushes.
IMPACT_CHECK = (10.0, 2, 3)
N_JOINTS = 6


class _Given(RegressorMixin, BaseEstimator):
    """A "regressor" whose prediction is already in the last ``N_JOINTS`` input columns.

    The ``impact`` study calibrates many detection rules on the same recordings;
    each recording's model prediction is computed once and appended to its inputs.
    """

    def __sklearn_is_fitted__(self):
        return True

    def fit(self, X, y=None):
        return self

    def predict(self, X, return_std=False):
        return X[:, -N_JOINTS:]


def _given_block(X, prediction, current):
    """``[X, prediction, current]``: a detector block for :class:`_Given`."""
    return stack_currents(np.hstack([X, prediction]), current)


def _with_prediction(model, X, current):
    """:func:`_given_block` with ``model``'s prediction."""
    return _given_block(X, model.predict(X), current)


def _banded(rule, band):
    """``rule`` with the low-pass and debounce of ``band`` (cut-off, order, debounce)."""
    cutoff, order, debounce = band
    return clone(rule).set_params(filter_cutoff=cutoff, filter_order=order,
                                  min_duration=debounce)


#: The band of the benchmark's rule: (cut-off [Hz], filter order, debounce [samples]).
MAIN_BAND = (bench.FILTER_CUTOFF, 1, bench.MIN_DURATION)


def study_impact(root, labels, n_support, seed):
    train, unseen, _ = bench.split_recordings(root, quick=False)
    data = training_set(list(train), "causal", allow_missing=True)
    models, _ = bench.train_models(data, n_support, seed, None, names=("P_f", "SP_S", "SP_C"))
    models[bench.PEER] = ControllerCurrent(N_JOINTS).fit(data.X, data.y)
    velocities = [int(c) for c in block_columns("qd", N_JOINTS)]
    base = bench.detector(_Given()).set_params(velocity_columns=velocities)
    _impact_on_2020(root, labels, models, data.features, base)
    _impact_on_unseen(root, labels, unseen, models, data.features, base)


def _impact_on_2020(root, labels, models, features, base):
    """collision_detection_data_2020, the benchmark's protocol, union of two bands."""
    bands = [MAIN_BAND]
    free = bench.load(root / bench.FAMILY_2020 / "collision_free.csv")
    recs = {key: bench.load(root / key) for key in bench.COLLISIONS}
    segments = {k: bench.free_segments(r, labels[k]) for k, r in recs.items()}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # no target current there: zeros, unused by P_f, SP_S
        X = {k: features.transform(r) for k, r in recs.items()}
        X_free = features.transform(free)
    for name in ("P_f", "SP_S"):
        inputs = {k: _with_prediction(models[name], X[k], r.current) for k, r in recs.items()}
        free_block = _with_prediction(models[name], X_free, free.current)
        for band in [None, *IMPACT_BANDS]:
            hits = total = n_onsets = 0
            missed = []
            for key, rec in recs.items():
                blocks, times = bench.family_calibration(
                    key, {"collision_free": free_block}, {"collision_free": free.time},
                    inputs, recs, segments)
                alarm = np.zeros(rec.n_samples, dtype=bool)
                for b in bands + ([band] if band else []):
                    cal = calibrate_across_recordings(_banded(base, b), blocks, times)
                    alarm |= cal.detector.monitoring_signal(inputs[key]).alarms.any(axis=1)
                t = rec.time - rec.time[0]
                events, _ = bench.score_alarms(alarm, t, labels[key]["events"])
                hits += sum(e["detected"] for e in events)
                total += len(events)
                missed += [f"{Path(key).stem[10:]} {e['start_s']:.2f}"
                           for e in events if not e["detected"]]
                n_onsets += sum(len(alarm_onsets(alarm[a:b], t[a:b]))
                                for a, b in segments[key])
            print(f"2020, {name}, 2 Hz band{' + ' + str(band) if band else ' only'}: "
                  f"{hits}/{total} collisions, {n_onsets} onsets on the event-free "
                  f"segments; missed {missed}", flush=True)


def _impact_on_unseen(root, labels, unseen, models, features, base):
    """The band ``IMPACT_CHECK`` on the unseen collision-free recordings and the pushes."""
    bands = [MAIN_BAND]
    pushes = {key: bench.load(root / key) for key in bench.PUSHES}
    X_unseen = {k: features.transform(r) for k, r in unseen.items()}
    X_push = {k: features.transform(r) for k, r in pushes.items()}
    times = bench.times_of(unseen)
    for name in (bench.PEER, "P_f", "SP_S", "SP_C"):
        blocks = {k: _with_prediction(models[name], X_unseen[k], r.current)
                  for k, r in unseen.items()}
        push_blocks = {k: _with_prediction(models[name], X_push[k], r.current)
                       for k, r in pushes.items()}
        for settle, reference in ((0.5, None), (3.0, 2.0)):
            rule = clone(base).set_params(settle_time=settle, rest_reference=reference)
            for extra in (None, IMPACT_CHECK):
                alarms = {k: np.zeros(len(t), dtype=bool) for k, t in times.items()}
                push_alarms = {k: np.zeros(r.n_samples, dtype=bool) for k, r in pushes.items()}
                for b in bands + ([extra] if extra else []):
                    cal = calibrate_across_recordings(_banded(rule, b), blocks, times)
                    for k, a in nested_alarms(cal.series, bench.MARGIN_RULE).items():
                        alarms[k] |= a
                    for k in pushes:
                        push_alarms[k] |= cal.detector.monitoring_signal(
                            push_blocks[k]).alarms.any(axis=1)
                onsets = {Path(k).stem: alarm_onsets(a, times[k] - times[k][0])
                          for k, a in alarms.items()}
                onsets = {k: [round(o, 2) for o in v] for k, v in onsets.items() if v}
                hit = total = 0
                for k, rec in pushes.items():
                    events, _ = bench.score_alarms(push_alarms[k], rec.time - rec.time[0],
                                                   labels[k]["events"])
                    hit, total = hit + sum(e["detected"] for e in events), total + len(events)
                last = (f"; fast band margin {cal.margin.max():.2f}, moving thresholds "
                        f"j1-3 {np.round(cal.detector.thresholds_[0, :3], 2)} A"
                        if extra else "")
                print(f"unseen, {name}, settle {settle} s, rest ref. {reference}, 2 Hz band"
                      f"{' + ' + str(extra) if extra else ' only'}: "
                      f"{sum(map(len, onsets.values()))} nested onsets {onsets}, "
                      f"pushes {hit}/{total}{last}", flush=True)


#: Settle time and rest reference [s] that SP_C sel chooses on the 21 unseen recordings.
SP_C_SEL = (3.0, 2.0)


def _correction_split(model, X):
    """SP_C's prediction as the controller's mean ``w i_c + b`` and the GP correction."""
    mean = np.column_stack([post.y_mean + np.ravel(post.mean.predict(X))
                            for post in model.posteriors_])
    return mean, model.predict(X) - mean


def _moving_peaks(rule, X, pred, recording):
    """Debounced peak of ``|m|`` per joint in the moving regime, under ``rule``."""
    block = _given_block(X, pred, recording.current)
    # fitted for its filter, debounce and regimes; its thresholds are unused
    det = clone(rule).fit(block, time=recording.time)
    return regime_excursions(det, {"r": block})["r"][2][0]


def study_correction(root, labels, n_support, seed):
    """Per joint, keep SP_C's GP correction only where it lowers the moving peaks
    on training runs left out of the fit; then the operating point on ``C``."""
    train, unseen, _ = bench.split_recordings(root, quick=False)
    velocities = [int(c) for c in block_columns("qd", N_JOINTS)]
    settle, reference = SP_C_SEL
    rule = bench.detector(_Given()).set_params(
        velocity_columns=velocities, settle_time=settle, rest_reference=reference)
    ratios = []
    for k, held in enumerate(train):
        data = training_set([r for i, r in enumerate(train) if i != k], "causal")
        model = bench.train_models(data, n_support, seed, None, names=("SP_C",))[0]["SP_C"]
        X = data.features.transform(held)
        mean, correction = _correction_split(model, X)
        with_gp = _moving_peaks(rule, X, mean + correction, held)
        without = _moving_peaks(rule, X, mean, held)
        ratios.append(with_gp / without)
        print(f"left out {held.name}: moving peaks [A] with the correction "
              f"{np.round(with_gp, 3)}, without {np.round(without, 3)}", flush=True)
    ratios = np.array(ratios)
    keep = ratios.mean(axis=0) <= 1.0
    print(f"over {len(train)} left-out training runs, per joint: correction lowers the peak "
          f"in {(ratios < 1).sum(axis=0)} runs, mean ratio with / without "
          f"{np.round(ratios.mean(axis=0), 3)}; kept on joints "
          f"{[int(j) + 1 for j in np.flatnonzero(keep)]}", flush=True)

    data = training_set(list(train), "causal")
    model = bench.train_models(data, n_support, seed, None, names=("SP_C",))[0]["SP_C"]
    peer = ControllerCurrent(N_JOINTS).fit(data.X, data.y)
    pushes = {key: bench.load(root / key) for key in bench.PUSHES}
    recordings = {**unseen, **pushes}
    X = {k: data.features.transform(r) for k, r in recordings.items()}
    split = {k: _correction_split(model, x) for k, x in X.items()}
    hindsight = np.ones(N_JOINTS, dtype=bool)
    hindsight[1] = False
    variants = {
        bench.PEER: {k: peer.predict(x) for k, x in X.items()},
        "SP_C": {k: m + c for k, (m, c) in split.items()},
        "SP_C, corrections chosen on training runs": {
            k: m + c * keep for k, (m, c) in split.items()},
        "SP_C without joint 2's correction (chosen on C: hindsight)": {
            k: m + c * hindsight for k, (m, c) in split.items()},
    }
    times = bench.times_of(unseen)
    peer_thresholds = None
    for name, preds in variants.items():
        blocks = {k: _given_block(X[k], preds[k], recordings[k].current) for k in recordings}
        cal = calibrate_across_recordings(rule, {k: blocks[k] for k in unseen}, times)
        thresholds = cal.detector.thresholds_
        if peer_thresholds is None:
            peer_thresholds = thresholds
        hit, total = pushes_detected(cal.detector, pushes, blocks, labels)
        ratio = thresholds / peer_thresholds
        print(f"{name}, settle {settle:g} s, rest ref. {reference:g} s: margin "
              f"{cal.margin.max():.3f}, {cal.n_false_alarms} nested onsets, pushes "
              f"{hit}/{total}; thresholds j1-3 moving {np.round(thresholds[0, :3], 3)} A "
              f"({np.round(ratio[0, :3], 2)}x the peer at the same settings), rest "
              f"{np.round(thresholds[-1, :3], 3)} A ({np.round(ratio[-1, :3], 2)}x)", flush=True)


#: Regime code of the ``braking`` study, after the detector's moving / settling / rest.
BRAKING = 3
#: Seconds the braking regime lasts after the last sample above the limit:
#: the current rings for about that long after a hard stop (jointwise_2, 61.6 s).
BRAKE_HOLD = 0.5
#: Widths [rad/s] of the smooth Coulomb term tried in the ``braking`` study.
COULOMB_WIDTHS = (0.01, 0.03)
QDD = block_columns("qdd", N_JOINTS)


def braking(X, time, limit, hold=BRAKE_HOLD):
    """Causal braking flag: from a sample whose causal ``|qdd|`` exceeds
    ``limit`` on some joint until ``hold`` seconds after the last such sample."""
    out = np.zeros(len(time), dtype=bool)
    for k in np.flatnonzero((np.abs(X[:, QDD]) > limit).any(axis=1)):
        out[k:np.searchsorted(time, time[k] + hold, side="right")] = True
    return out


def _with_braking(excursions, X, times, limit):
    """:func:`regime_excursions` output with the samples of :func:`braking` in
    regime ``BRAKING`` (their own per-joint levels); ``limit=inf`` leaves them
    as they are."""
    out = {}
    for k, (debounced, regime, _) in excursions.items():
        regime = np.where(braking(X[k], times[k], limit), BRAKING, regime)
        peaks = np.zeros((BRAKING + 1, N_JOINTS))
        for g in np.unique(regime):
            peaks[g] = debounced[regime == g].max(axis=0)
        out[k] = (debounced, regime, peaks)
    return out


def _band_series(rule, band, calibration, scored, X, times, limits):
    """Per braking limit, the series of one band (detector settings from
    :func:`calibrate_across_recordings` on ``calibration``) on the calibration
    recordings and on the recordings to score."""
    det = calibrate_across_recordings(_banded(rule, band), calibration, times).detector
    excursions = regime_excursions(det, {**calibration, **scored})
    return {limit: _with_braking(excursions, X, times, limit) for limit in limits}


def _thresholds(series, keys):
    """Margin (global LORO rule) times the per-(regime, joint) levels over ``keys``."""
    peaks = {k: series[k][2] for k in keys}
    return loro_margin(peaks, keys, bench.MARGIN_RULE) * regime_levels(peaks, keys)


def _alarms(series, thresholds):
    """Any-joint alarms of each recording of ``series`` at ``thresholds``."""
    return {k: (d > thresholds[g]).any(axis=1) for k, (d, g, _) in series.items()}


def _nested_union(bands, keys):
    """Nested alarms (:func:`nested_alarms` on ``keys``) of the union of the
    bands' series."""
    union = {k: False for k in keys}
    for series in bands:
        for k, a in nested_alarms({k: series[k] for k in keys}, bench.MARGIN_RULE).items():
            union[k] = union[k] | a
    return union


def _union_alarm(bands, key, keys):
    """Alarms of recording ``key`` under the union of the bands, each band's
    thresholds calibrated on ``keys``."""
    alarm = False
    for series in bands:
        alarm = alarm | _alarms({key: series[key]}, _thresholds(series, keys))[key]
    return alarm


def study_braking(root, labels, n_support, seed):
    """Smooth Coulomb friction and a braking regime: the second band's false
    alarms on ``C`` and collision_detection_data_2020 (see the module docstring)."""
    train, unseen, _ = bench.split_recordings(root, quick=False)
    data = training_set(list(train), "causal", allow_missing=True)
    limit = max(np.abs(data.features.transform(r)[:, QDD]).max() for r in train)
    print(f"braking limit: the largest causal |qdd| of the {len(train)} training runs, "
          f"{limit:.2f} rad/s^2; hold {BRAKE_HOLD} s", flush=True)
    models = {bench.PEER: ControllerCurrent(N_JOINTS).fit(data.X, data.y)}
    models.update(bench.train_models(data, n_support, seed, None, names=("P_f",))[0])
    # P_f's settings in train_model, with the smooth Coulomb term
    gp = dict(n_support=resolve_n_support(n_support, len(data.y)), optimizer="adam",
              random_state=seed, n_jobs=None)
    gp["batch_size"] = min(512, gp["n_support"])
    for width in COULOMB_WIDTHS:
        phi = [RigidBodyRegressor("ur10e", joint=joint, coulomb_width=width)
               for joint in range(N_JOINTS)]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            models[f"P_f, tanh(qd / {width:g})"] = make_p_f(phi, N_JOINTS, **gp).fit(
                data.X, data.y)
    velocities = [int(c) for c in block_columns("qd", N_JOINTS)]
    base = bench.detector(_Given()).set_params(velocity_columns=velocities)
    free = bench.load(root / bench.FAMILY_2020 / "collision_free.csv")
    recs = {key: bench.load(root / key) for key in bench.COLLISIONS}
    pushes = {key: bench.load(root / key) for key in bench.PUSHES}
    segments = {k: bench.free_segments(r, labels[k]) for k, r in recs.items()}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # 2020: no target current, unused by P_f
        X_2020 = {k: data.features.transform(r) for k, r in {**recs, "free": free}.items()}
    X_c = {k: data.features.transform(r) for k, r in {**unseen, **pushes}.items()}
    times = bench.times_of(unseen)
    for key, rec in recs.items():
        t = rec.time - rec.time[0]
        peak = [np.abs(X_2020[key][(t >= e["start_s"] - 0.3) & (t <= e["stop_s"])][:, QDD]).max()
                for e in labels[key]["events"]]
        print(f"{Path(key).stem}: largest |qdd| around a labelled collision {max(peak):.2f}, "
              f"in the whole file {np.abs(X_2020[key][:, QDD]).max():.2f} rad/s^2; braking "
              f"samples {braking(X_2020[key], rec.time, limit).sum()}", flush=True)
    for k, x in X_c.items():
        n = braking(x, (unseen | pushes)[k].time, limit).sum()
        if n:
            print(f"{Path(k).stem}: {n} braking samples, largest |qdd| "
                  f"{np.abs(x[:, QDD]).max():.2f} rad/s^2", flush=True)
    settle, reference = SP_C_SEL
    rule = clone(base).set_params(settle_time=settle, rest_reference=reference)
    peer_thresholds, computed = {}, {}
    for name, model in models.items():
        on_unseen = _unseen_series(model, rule, unseen, pushes, X_c, times, (np.inf, limit))
        family = (None if name == bench.PEER else
                  _family_series(model, base, recs, free, X_2020, segments, limit))
        for band in [None, *IMPACT_BANDS]:
            bands = [MAIN_BAND] + ([band] if band else [])
            text = f"2 Hz band{' + ' + str(band) if band else ' only'}"
            if family is not None:
                print(f"2020, {name}, {text}: " + _family_result(
                    family, bands, recs, labels, segments), flush=True)
            for brake in (np.inf, limit):
                line, moving = _unseen_result([on_unseen[b][brake] for b in bands], unseen,
                                              pushes, times, labels)
                cell = (band, brake)
                peer_thresholds.setdefault(cell, moving)
                print(f"unseen, {name}, {text}, braking regime "
                      f"{'off' if brake == np.inf else 'on'}: {line}; last band's moving j1-3 "
                      f"{np.round(moving, 2)} A ({np.round(moving / peer_thresholds[cell], 2)}x "
                      "the peer)", flush=True)
        if family is not None:
            computed[name] = ({b: v[limit] for b, v in on_unseen.items()}, family)
    for name, (on_unseen, family) in computed.items():
        _nested_band(name, on_unseen, family, unseen, pushes, times, recs, labels, segments)


def _unseen_series(model, rule, unseen, pushes, X, times, limits):
    """Per band (the main band and ``IMPACT_BANDS``) and braking limit: the series
    on ``C`` (the calibration recordings) and on the pushes."""
    blocks = {k: _with_prediction(model, X[k], r.current)
              for k, r in {**unseen, **pushes}.items()}
    calibration = {k: blocks[k] for k in unseen}
    scored = {k: blocks[k] for k in pushes}
    all_times = {**times, **bench.times_of(pushes)}
    return {b: _band_series(rule, b, calibration, scored, X, all_times, limits)
            for b in (MAIN_BAND, *IMPACT_BANDS)}


def _unseen_result(bands, unseen, pushes, times, labels):
    """``C`` under the union of the bands' series: nested onsets, pushes (thresholds
    from all of ``C``), and the moving thresholds of joints 1-3 of the last band."""
    keys = list(unseen)
    alarms = _nested_union(bands, keys)
    onsets = {Path(k).stem: [round(o, 2) for o in alarm_onsets(a, times[k] - times[k][0])]
              for k, a in alarms.items()}
    onsets = {k: v for k, v in onsets.items() if v}
    hit, total = _pushes(bands, keys, pushes, labels)
    return (f"{sum(map(len, onsets.values()))} nested onsets {onsets}, pushes {hit}/{total}",
            _thresholds(bands[-1], keys)[0, :3])


def _pushes(bands, keys, pushes, labels):
    """Pushes detected and labelled, under the union of the bands calibrated on ``keys``."""
    hit = total = 0
    for k, rec in pushes.items():
        events, _ = bench.score_alarms(_union_alarm(bands, k, keys), rec.time - rec.time[0],
                                       labels[k]["events"])
        hit, total = hit + sum(e["detected"] for e in events), total + len(events)
    return hit, total


def _family_series(model, base, recs, free, X, segments, limit):
    """Per 2020 file: its calibration pool's keys and, per band, the series
    (braking regime on) on the pool and on the file."""
    inputs = {k: _with_prediction(model, X[k], r.current) for k, r in recs.items()}
    free_block = {"collision_free": _with_prediction(model, X["free"], free.current)}
    out = {}
    for key, rec in recs.items():
        pool, tms = bench.family_calibration(key, free_block, {"collision_free": free.time},
                                             inputs, recs, segments)
        rows = {**_pool_rows(pool, X, segments), key: X[key]}
        tms = {**tms, key: rec.time}
        out[key] = (list(pool), {
            b: _band_series(base, b, pool, {key: inputs[key]}, rows, tms, [limit])[limit]
            for b in (MAIN_BAND, *IMPACT_BANDS)})
    return out


def _family_result(family, bands, recs, labels, segments, choose=None):
    """The 2020 task under the union of the main band and the ``bands[1:]``
    (or, with ``choose``, the second band it picks from each file's pool)."""
    hits = total = n_onsets = 0
    missed, picks = [], []
    for key, rec in recs.items():
        pool_keys, series = family[key]
        if choose is not None:
            second = IMPACT_BANDS[choose(series[MAIN_BAND],
                                         [series[b] for b in IMPACT_BANDS], pool_keys)]
            picks.append(second)
            bands = [MAIN_BAND, second]
        chosen = [series[b] for b in bands]
        score = _score_2020(_union_alarm(chosen, key, pool_keys), rec,
                            labels[key]["events"], segments[key])
        hits, total, n_onsets = hits + score[0], total + score[1], n_onsets + score[3]
        missed += [f"{Path(key).stem[10:]} {start:.2f}" for start in score[2]]
    text = (f"{hits}/{total} collisions, {n_onsets} onsets on the event-free segments; "
            f"missed {missed}")
    return text + (f"; bands chosen {picks}" if choose is not None else "")


def _pool_rows(pool, X, segments):
    """Input rows of each recording of a 2020 calibration pool
    (``bench.family_calibration``): ``collision_free`` and the event-free
    segments ``"<file>#<i>"``."""
    rows = {"collision_free": X["free"]}
    for key in pool:
        if "#" in key:
            name, i = key.rsplit("#", 1)
            a, b = segments[name][int(i)]
            rows[key] = X[name][a:b]
    return rows


def _score_2020(alarm, rec, events, segments):
    """Collisions detected, labelled, the start times missed, and the onsets on
    the event-free ``segments`` of one 2020 file."""
    t = rec.time - rec.time[0]
    scored, _ = bench.score_alarms(alarm, t, events)
    missed = [e["start_s"] for e in scored if not e["detected"]]
    onsets = sum(len(alarm_onsets(alarm[a:b], t[a:b])) for a, b in segments)
    return sum(e["detected"] for e in scored), len(scored), missed, onsets


def _band_score(series, keys):
    """The time-weighted mean log threshold of one band on ``keys`` (as
    :func:`calibrate_across_recordings` ranks candidates)."""
    thresholds = _thresholds(series, keys)
    counts = sum(np.bincount(series[k][1], minlength=thresholds.shape[0]) for k in keys)
    return float(counts / counts.sum() @ np.log(thresholds).mean(axis=1))


def _choose_band(main, bands, keys):
    """Index of the second band with the fewest nested onsets of the union on
    ``keys`` (each recording scored with thresholds from the others), then the
    smallest score."""
    ranks = [(sum(len(alarm_onsets(a)) for a in _nested_union([main, b], keys).values()),
              _band_score(b, keys)) for b in bands]
    return min(range(len(bands)), key=ranks.__getitem__)


def _nested_band(name, on_unseen, family, unseen, pushes, times, recs, labels, segments):
    """The second band chosen without the recording it is scored on (braking
    regime on): on ``C`` each recording with the band chosen on the other 20,
    each 2020 file with the band chosen on its calibration pool."""
    main, bands = on_unseen[MAIN_BAND], [on_unseen[b] for b in IMPACT_BANDS]
    keys = list(unseen)
    onsets, chosen = {}, Counter()
    for r in keys:
        others = [k for k in keys if k != r]
        c = _choose_band(main, bands, others)
        chosen[IMPACT_BANDS[c]] += 1
        found = alarm_onsets(_union_alarm([main, bands[c]], r, others), times[r] - times[r][0])
        if found:
            onsets[Path(r).stem] = [round(o, 2) for o in found]
    c = _choose_band(main, bands, keys)
    hit, total = _pushes([main, bands[c]], keys, pushes, labels)
    print(f"unseen, {name}, second band chosen without the scored recording (braking on): "
          f"{sum(map(len, onsets.values()))} nested onsets {onsets}, bands chosen "
          f"{dict(chosen)}; pushes {hit}/{total} with {IMPACT_BANDS[c]} (chosen on all 21)",
          flush=True)
    print(f"2020, {name}, second band chosen on each file's calibration pool: "
          + _family_result(family, None, recs, labels, segments, choose=_choose_band),
          flush=True)

def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", required=True, choices=(
        "rest", "floor", "family", "select", "relax", "margin", "presliding", "impact",
        "correction", "braking"))
    parser.add_argument("--data", default=None, help="folder of ur10e_mamedov")
    parser.add_argument("--n-support", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    root = bench.real_data_path(bench.DATASET, args.data)
    bench.require_data(root, "UR10e recordings (Mamedov et al.)",
                       [bench.IDENTIFICATION, bench.PTP, *bench.STILL, *bench.PUSHES])
    labels = json.loads(bench.LABELS.read_text())["files"]
    if args.study == "rest":
        study_rest(root, labels, args.n_support, args.seed)
    elif args.study == "floor":
        study_floor(root)
    elif args.study == "select":
        study_select(root, labels, args.n_support, args.seed)
    elif args.study == "relax":
        study_relax(root)
    elif args.study == "margin":
        study_margin(root, labels, args.n_support, args.seed)
    elif args.study == "presliding":
        study_presliding(root, labels, args.n_support, args.seed)
    elif args.study == "impact":
        study_impact(root, labels, args.n_support, args.seed)
    elif args.study == "correction":
        study_correction(root, labels, args.n_support, args.seed)
    elif args.study == "braking":
        study_braking(root, labels, args.n_support, args.seed)
    else:
        study_family(root, labels, args.n_support, args.seed)


if __name__ == "__main__":
    main()
