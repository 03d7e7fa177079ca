"""Open studies on the real UR10e: the measurements behind points that are not closed.

``benchmarks/real_ur10e.py`` measures the operating point; this script keeps
the studies whose findings have not become package features (the README
beside it sums up what each found). Each trains SP_C / SP_S with the
benchmark's own settings (``train_models``: causal inputs, 1,000 support
rows, Adam, seed 0) and scores them with the benchmark's functions (LORO
margin, nested false alarms, labelled pushes). The studies that became
features (regimes and rest reference, the settle-time selection, the margin
rules, the fast band, the braking regime) were retired with their code; their
figures stay on the results page with the commit that produced them.

Studies (``--study``):

- ``floor``: the nMSE an oracle reaches on the rest phases of ptp_10_points
  by predicting each sample with a *centred* moving average of the measured
  current (non-causal, the best a smooth predictor can do against the
  sensor noise).
- ``family``: collision_detection_data_2020 with SP_S trained on the
  identification runs (the benchmark) or also on ``collision_free.csv`` of
  the same task, thresholds by LORO on the task's other collision-free data
  that was not trained on.
- ``relax``: what the held current does after a stop, on every stop of
  every collision-free recording with target current that is followed by
  at least 4 s of rest: the residual ``i - i_des`` 0.15-0.35 s after the stop, in the last
  second of the rest, and the time constant of an exponential fitted in
  between; then the arm-at-rest nMSE on ptp_10_points of the simplest causal
  "model" of it, an exponential average of the measured current itself
  started at each stop, against its time constant.
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

Run: ``python studies/real_ur10e_open.py --study floor`` (seconds), ``--study
family`` (about 3 min), ``--study relax`` (seconds), ``--study presliding``
(about 8 min), ``--study correction`` (about 4 min). The data must be in
``../shared/data/real/ur10e_mamedov`` (or ``--data``); the script exits with a
message when it is not.
"""

import argparse
import json
import sys
import warnings
from pathlib import Path

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.optimize import curve_fit

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import real_ur10e as bench  # noqa: E402

from sklearn_gpcd.detection import (  # noqa: E402
    calibrate_across_recordings,
    nested_false_alarms,
    regime_excursions,
    stack_currents,
)
from sklearn.base import BaseEstimator, RegressorMixin, TransformerMixin, clone  # noqa: E402
from sklearn.gaussian_process.kernels import ConstantKernel, WhiteKernel  # noqa: E402

from sklearn_gpcd.dynamics import (  # noqa: E402
    ControllerCurrent,
    ControllerFeatures,
)
from sklearn_gpcd.gp import (  # noqa: E402
    ParametricMean,
    SemiParametricGPRegressor,
)
from sklearn_gpcd.kernels import ARDRBF  # noqa: E402
from sklearn_gpcd.layout import block_columns, column_index  # noqa: E402
from sklearn_gpcd.features import contiguous_segments  # noqa: E402
from sklearn_gpcd.metrics import alarm_onsets  # noqa: E402
from sklearn_gpcd.workflow import training_set  # noqa: E402


def rule(model, settle_time, rest_reference):
    """The benchmark's detection rule with another settle time."""
    return bench.detector(model, rest_reference, settle_time=settle_time)


def pushes_detected(det, pushes, push_blocks, labels):
    hit = total = 0
    for key, rec in pushes.items():
        events, _, _ = bench.score_events(det, push_blocks[key], rec, labels[key]["events"])
        hit += sum(e["detected"] for e in events)
        total += len(events)
    return hit, total


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
    rule = bench.detector(_Given(), reference, settle_time=settle).set_params(
        velocity_columns=velocities)
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


STUDIES = {"floor": "study_floor", "family": "study_family", "relax": "study_relax",
           "presliding": "study_presliding", "correction": "study_correction"}
#: Studies that read only the recordings (no model is trained).
DATA_ONLY = ("floor", "relax")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", required=True, choices=tuple(STUDIES))
    parser.add_argument("--data", default=None, help="folder of ur10e_mamedov")
    parser.add_argument("--n-support", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    root = bench.real_data_path(bench.DATASET, args.data)
    bench.require_data(root, "UR10e recordings (Mamedov et al.)",
                       [bench.IDENTIFICATION, bench.PTP, *bench.STILL, *bench.PUSHES])
    study = globals()[STUDIES[args.study]]
    if args.study in DATA_ONLY:
        study(root)
        return
    labels = json.loads(bench.LABELS.read_text())["files"]
    study(root, labels, args.n_support, args.seed)


if __name__ == "__main__":
    main()
