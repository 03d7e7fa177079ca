"""Several alarm rules (bands) on one model: CollisionDetector(rules=[...]), its
calibration across recordings and its streaming twin."""

import pickle

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.frozen import FrozenEstimator
from sklearn.linear_model import LinearRegression, Ridge
from sklearn.model_selection import ParameterGrid
from sklearn.utils.estimator_checks import parametrize_with_checks

from sklearn_gpcd.detection import (
    AlarmRule,
    CollisionDetector,
    MonitorStatus,
    Regimes,
    StreamingMonitor,
    calibrate_across_recordings,
    nested_alarms,
    stack_currents,
)
from sklearn_gpcd.features import CausalFeatures
from sklearn_gpcd.gp import make_sp_p
from sklearn_gpcd.metrics import alarm_onsets

from _synthetic import FAST, augmented_run, banded, controller_detector, simulated_interaction

SIGMA_V = 1e-2


def _order_dependent(estimator):
    """A band with a low-pass filter or a debounce is a filter over time: its
    output depends on the order of the samples, by design."""
    filtered = any(rule.filter_cutoff or rule.min_duration > 1 for rule in estimator.rules)
    reason = "a filter over time depends on the order and the neighbours of a sample"
    checks = ("check_methods_sample_order_invariance", "check_methods_subset_invariance")
    return {check: reason for check in checks} if filtered else {}


@parametrize_with_checks([
    CollisionDetector(Ridge(), rules=[AlarmRule(), AlarmRule(contamination=0.05)]),
    CollisionDetector(Ridge(), rules=[AlarmRule(), AlarmRule(**FAST)]),
    CollisionDetector(Ridge(), rules=[AlarmRule(contamination=0.05),
                                      AlarmRule(contamination=0.05, filter_cutoff=20.0)]),
], expected_failed_checks=_order_dependent)
def test_sklearn_compatible(estimator, check):
    check(estimator)


class CountingRidge(Ridge):
    """Ridge that counts its fits (module level so it pickles)."""

    fits = 0

    def fit(self, X, y, sample_weight=None):
        type(self).fits += 1
        return super().fit(X, y, sample_weight)


def _taps(rng, n=3000, period=0.01):
    """One joint whose current follows x, with 0.1 s taps and a 1 s push."""
    x = np.cumsum(rng.normal(size=(n, 2)), axis=0) * 0.01
    current = np.column_stack([2.0 * x[:, 0], x[:, 1] - x[:, 0]])
    noisy = current + 0.05 * rng.normal(size=current.shape)
    return x, current, noisy


def test_bands_are_detectors_on_one_fitted_model(rng):
    x, _, noisy = _taps(rng)
    X = stack_currents(x, noisy)
    CountingRidge.fits = 0
    template = CollisionDetector(CountingRidge(), n_joints=2, sample_time=0.01,
                                 rules=AlarmRule(filter_cutoff=2.0, min_duration=5))
    det = banded(template, FAST, {"filter_cutoff": 5.0}).fit(X)
    assert CountingRidge.fits == 1  # the model is fitted once
    assert [rule.filter_cutoff for rule in det.rules_] == [2.0, 10.0, 5.0]
    # each band is the detector fitted alone on the (frozen) model
    members = [clone(template).set_params(regressor=FrozenEstimator(det.regressor_),
                                          rules=rule).fit(X) for rule in det.rules]
    np.testing.assert_array_equal(members[1].thresholds_, det.rules_[1].thresholds_)
    test = noisy.copy()
    test[1000:1010, 0] += 0.6  # a 0.1 s tap
    test[2000:2100, 1] -= 0.4  # a 1 s push
    Z = stack_currents(x, test)
    out = det.monitoring_signal(Z)
    for band, member in zip(out.bands, members):
        np.testing.assert_array_equal(band.alarms, member.predict_joints(Z))
        np.testing.assert_allclose(band.ratio, member.monitoring_signal(Z).ratio)
    union = np.logical_or.reduce([m.predict_joints(Z) for m in members])
    np.testing.assert_array_equal(out.alarms, union)
    np.testing.assert_array_equal(det.predict_joints(Z), union)
    np.testing.assert_array_equal(det.predict(Z) == -1, union.any(axis=1))
    np.testing.assert_array_equal(det.decision_function(Z) < 0, union.any(axis=1))
    decisions = np.min([m.decision_function(Z) for m in members], axis=0)
    np.testing.assert_allclose(det.score_samples(Z), decisions)
    assert union[1000:1030, 0].any() and union[2000:2120, 1].any()


@pytest.mark.parametrize("rules, match", [
    ([], "non-empty list"),
    ([AlarmRule(), {"filter_cutoff": 10.0}], "non-empty list of AlarmRule"),
    ([AlarmRule(), AlarmRule(filter_order=3)], "'filter_order' parameter of AlarmRule"),
])
def test_bad_rules_are_named(rules, match, rng):
    X = stack_currents(rng.normal(size=(50, 1)), rng.normal(size=50))
    with pytest.raises(ValueError, match=match):
        CollisionDetector(Ridge(), rules=rules).fit(X)


def test_every_band_reads_the_detectors_sigma_v(rng):
    X, current = augmented_run(400, 2, rng)
    Z = stack_currents(X, current)
    model = make_sp_p(None, 2, sigma_v=SIGMA_V, n_support=40, optimizer=None)
    rule = AlarmRule("per_joint", margin=1.5, regimes=Regimes())
    det = banded(CollisionDetector(model, n_joints=2, sigma_v=0.02, sample_time=0.008,
                                   rules=rule)).fit(Z)
    assert det.regressor_.sigma_v == 0.02  # set on the model
    assert [r.regime_settings()["sigma_v"] for r in det.rules_] == [0.02, 0.02]


@pytest.fixture(scope="module")
def simulated():
    return simulated_interaction()


def _gp_detector(n_joints, Z, **params):
    model = make_sp_p(None, n_joints, sigma_v=SIGMA_V, n_support=60, random_state=0,
                      optimizer=None)
    rule = AlarmRule(contamination=0.01, filter_cutoff=2.0, min_duration=5)
    return banded(CollisionDetector(model, n_joints=n_joints, rules=rule, **params)).fit(Z)


def test_streaming_equals_batch_with_faults_restarts_and_one_prediction(rng):
    X, current = augmented_run(800, 2, rng)
    det = _gp_detector(2, stack_currents(X[::2], current[::2]), sample_time=0.008)
    test = current + 0.01 * rng.normal(size=current.shape)
    test[100:110, 0] += 1.0
    test[300:380, 1] -= 1.0
    Z = stack_currents(X, test)
    monitor = StreamingMonitor(det)
    assert monitor.predictor_kind == "gaussian_process" and len(monitor.bands) == 2
    calls = []
    inner = monitor._predictor
    original = inner.predict_one
    inner.predict_one = lambda x, out: calls.append(1) or original(x, out)
    bad = {50, 51, 600}  # sensor faults: dropped by every band, as if never there
    streamed, kept = [], []
    for k, row in enumerate(Z):
        if k == 400:
            monitor.reset()  # a new recording
        if k in bad:
            faulty = row.copy()
            faulty[3] = np.nan
            assert monitor.update(faulty) == MonitorStatus.SENSOR_FAULT
            assert not monitor.alarms.any() and np.isnan(monitor.score)
            continue
        streamed.append(monitor.update(row) == MonitorStatus.COLLISION)
        kept.append(k)
    # one prediction per valid tick, for every band
    assert len(calls) == len(Z) - len(bad)
    groups = np.repeat([0, 1], 400)[kept]
    batch = det.predict(Z[kept], groups=groups) == -1
    np.testing.assert_array_equal(streamed, batch)
    assert batch[100:112].any() and batch[300:380].any()
    # the score too, on the last tick
    np.testing.assert_allclose(monitor.score,
                               det.score_samples(Z[kept], groups=groups)[-1], rtol=1e-6)


def test_raw_stream_equals_batch_and_pickles_mid_stream(simulated):
    rec, free = simulated
    features = CausalFeatures().fit(free)
    Z = stack_currents(features.transform(free), free.current)
    det = banded(controller_detector()).fit(Z, time=free.time)
    monitor = StreamingMonitor(det, features=features)
    half = rec.n_samples // 2
    signals = {"target_q": rec.target_q, "target_qd": rec.target_qd,
               "target_current": rec.target_current}

    def raw(m, k):
        return m.update_raw(rec.time[k], rec.q[k], rec.qd[k], rec.current[k],
                            **{s: v[k] for s, v in signals.items() if v is not None})

    streamed = [raw(monitor, k) == MonitorStatus.COLLISION for k in range(half)]
    resumed = pickle.loads(pickle.dumps(monitor))
    assert resumed.predictor_kind == monitor.predictor_kind and len(resumed.bands) == 2
    streamed += [raw(resumed, k) == MonitorStatus.COLLISION for k in range(half, rec.n_samples)]
    batch = det.predict(stack_currents(features.transform(rec), rec.current)) == -1
    np.testing.assert_array_equal(streamed, batch)
    assert batch.any()


def test_calibration_counts_the_nested_alarms_of_the_union():
    blocks, times = {}, {}
    rng = np.random.default_rng(0)
    for name in "abcde":
        x = np.cumsum(rng.normal(size=(800, 1)), axis=0) * 0.01
        current = 2.0 * x[:, 0] + 0.05 * rng.normal(size=800)
        if name == "c":
            current[400:403] += 1.0  # a 30 ms tap
        if name == "d":  # a slow collision-free swell: it widens the 2 Hz band's margin
            current[200:500] += 0.1 * np.sin(np.linspace(0, np.pi, 300))
        blocks[name] = stack_currents(x, current)
        times[name] = np.arange(800) * 0.01
    model = FrozenEstimator(LinearRegression().fit(blocks["a"][:, :1], blocks["a"][:, 1]))
    rule = AlarmRule("per_joint", false_alarm_rate=0.0, filter_cutoff=2.0, min_duration=5)
    template = CollisionDetector(model, sample_time=0.01, rules=rule)
    result = calibrate_across_recordings(banded(template), blocks, times)
    alone = [calibrate_across_recordings(template, blocks, times),
             calibrate_across_recordings(template.set_params(rules=clone(rule).set_params(**FAST)),
                                         blocks, times)]
    for band, single, fitted in zip(result.bands, alone, result.detector.rules_):
        np.testing.assert_array_equal(fitted.thresholds_, single.detector.thresholds_)
        assert band.n_false_alarms == single.n_false_alarms
    for key in blocks:
        union = nested_alarms(alone[0].series)[key] | nested_alarms(alone[1].series)[key]
        assert result.folds[key]["onsets"] == alarm_onsets(union, times[key])
    n_alone = [single.n_false_alarms for single in alone]
    assert result.n_false_alarms == sum(len(f["onsets"]) for f in result.folds.values())
    assert result.n_false_alarms >= max(n_alone)
    # the tap: too short for the 2 Hz band, a nested alarm of the fast band and the union
    assert n_alone == [0, 1] and result.folds["c"]["onsets"] == [4.01]
    assert result.false_alarms_per_hour == pytest.approx(result.n_false_alarms / result.hours)
    # the fitted detector alarms where any of its bands does
    Z = blocks["c"]
    out = result.detector.monitoring_signal(Z)
    assert len(out.bands) == 2
    np.testing.assert_array_equal(result.detector.predict_joints(Z),
                                  np.logical_or.reduce([band.alarms for band in out.bands]))


def _tapped_recordings(n_recordings=6, seed=0):
    """Collision-free 1-joint recordings, some with a short tap or a slow swell."""
    rng = np.random.default_rng(seed)
    blocks, times = {}, {}
    for r in range(n_recordings):
        x = np.cumsum(rng.normal(size=(800, 1)), axis=0) * 0.01
        current = 2.0 * x[:, 0] + 0.05 * rng.normal(size=800)
        if r in (1, 3):
            current[400:400 + 2 * r] += 0.6  # taps of 20 and 60 ms
        if r == 4:
            current[200:500] += 0.1 * np.sin(np.linspace(0, np.pi, 300))
        blocks[f"r{r}"] = stack_currents(x, current)
        times[f"r{r}"] = np.arange(800) * 0.01
    model = FrozenEstimator(LinearRegression().fit(blocks["r0"][:, :1], blocks["r0"][:, 1]))
    rule = AlarmRule("per_joint", false_alarm_rate=0.0, filter_cutoff=2.0, min_duration=5)
    return CollisionDetector(model, sample_time=0.01, rules=rule), blocks, times


BAND_GRID = {"filter_cutoff": [5.0, 10.0, 20.0], "min_duration": [2, 4]}


def test_a_grid_of_one_candidate_is_the_fixed_band():
    template, blocks, times = _tapped_recordings()
    fixed = calibrate_across_recordings(banded(template), blocks, times)
    grid = calibrate_across_recordings(banded(template), blocks, times,
                                       param_grid={k: [v] for k, v in FAST.items()})
    assert grid.settings == FAST and fixed.settings == {}
    assert grid.fold_settings == {}  # one candidate: nothing chosen per fold
    assert grid.folds == fixed.folds and grid.n_false_alarms == fixed.n_false_alarms
    for a, b in zip(grid.detector.rules_, fixed.detector.rules_):
        np.testing.assert_array_equal(a.thresholds_, b.thresholds_)
    assert [c["rank"] for c in grid.candidates] == [0]


def test_the_grid_scores_each_recording_with_the_band_chosen_without_it():
    """The nested figure, rebuilt from public calls: for each recording, every
    candidate calibrated on the other recordings alone, the best one (fewest
    nested onsets of the union there, then the smallest score of the band)
    refitted there and run on the left-out recording."""
    template, blocks, times = _tapped_recordings()
    result = calibrate_across_recordings(banded(template), blocks, times,
                                         param_grid=BAND_GRID)
    candidates = list(ParameterGrid(BAND_GRID))
    assert len(result.candidates) == len(candidates)
    for r in blocks:
        others = {k: v for k, v in blocks.items() if k != r}
        runs = [calibrate_across_recordings(banded(template, {**FAST, **c}), others, times)
                for c in candidates]
        ranks = [(run.n_false_alarms, run.candidates[0]["score"]) for run in runs]
        c = min(range(len(runs)), key=ranks.__getitem__)
        assert result.fold_settings[r] == candidates[c]
        alarm = runs[c].detector.predict(blocks[r]) == -1
        assert result.folds[r]["onsets"] == alarm_onsets(alarm, times[r] - times[r][0]), r
    # the data make the choice depend on the recording left out
    assert len({str(s) for s in result.fold_settings.values()}) > 1
    # the operating point: the candidate ranked first on all recordings, refitted on all
    ranked = {str(c["params"]): c["rank"] for c in result.candidates}
    assert ranked[str(result.settings)] == 0
    best = calibrate_across_recordings(banded(template, {**FAST, **result.settings}), blocks,
                                       times)
    for a, b in zip(result.detector.rules_, best.detector.rules_):
        np.testing.assert_array_equal(a.thresholds_, b.thresholds_)


class RowCountingRegression(LinearRegression):
    """LinearRegression that counts the rows it predicts (module level so it pickles)."""

    rows = 0

    def predict(self, X):
        type(self).rows += len(X)
        return super().predict(X)


THREE_BANDS = (FAST, {"filter_cutoff": 5.0, "filter_order": 2})


def test_the_bands_share_one_prediction_and_calibrate_as_alone():
    template, blocks, times = _tapped_recordings()
    n_rows = sum(len(block) for block in blocks.values())
    model = RowCountingRegression().fit(blocks["r0"][:, :1], blocks["r0"][:, 1])
    template.set_params(regressor=FrozenEstimator(model))
    for grid in (None, BAND_GRID):
        RowCountingRegression.rows = 0
        calibrate_across_recordings(banded(template, *THREE_BANDS), blocks, times,
                                    param_grid=grid)
        assert RowCountingRegression.rows == n_rows, grid  # once, for every band
    RowCountingRegression.rows = 0
    three = banded(template, *THREE_BANDS)
    result = calibrate_across_recordings(three, blocks, times)
    for band, rule in zip(result.bands, three.rules):
        alone = calibrate_across_recordings(clone(template).set_params(rules=rule),
                                            blocks, times)
        np.testing.assert_array_equal(band.rule.thresholds_, alone.detector.thresholds_)
        np.testing.assert_array_equal(band.margin, alone.margin)
        np.testing.assert_array_equal(band.levels, alone.levels)
        assert band.folds == alone.folds and alone.settings == {}
        assert band.n_false_alarms == alone.n_false_alarms
        assert band.rule.get_params() == alone.detector.rules.get_params()
    assert RowCountingRegression.rows == 4 * n_rows  # the bands once, each alone once


def test_bands_are_fitted_with_one_prediction(rng):
    x, _, noisy = _taps(rng)
    X = stack_currents(x, noisy)
    rule = AlarmRule(contamination=0.01, filter_cutoff=2.0, min_duration=5)
    template = CollisionDetector(RowCountingRegression(), n_joints=2, sample_time=0.01,
                                 rules=rule)
    RowCountingRegression.rows = 0
    shared = banded(template, *THREE_BANDS, {"contamination": 0.05}).fit(X)
    assert RowCountingRegression.rows == len(X)
    first_alone = clone(template).fit(X)  # the same model: the bands left it as it was
    np.testing.assert_array_equal(shared.rules_[0].thresholds_, first_alone.thresholds_)
    for band, rule in zip(shared.rules_[1:], shared.rules[1:]):
        alone = clone(template).set_params(regressor=FrozenEstimator(shared.regressor_),
                                           rules=rule).fit(X)
        np.testing.assert_array_equal(band.thresholds_, alone.thresholds_)
        assert band.offset_ == alone.offset_


def test_the_grid_takes_only_settings_of_the_last_rule():
    template, blocks, times = _tapped_recordings(n_recordings=3)
    with pytest.raises(ValueError, match="'cutoff' is not a setting of the last alarm rule"):
        calibrate_across_recordings(banded(template), blocks, times,
                                    param_grid={"cutoff": [5.0]})
