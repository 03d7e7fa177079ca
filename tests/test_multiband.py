"""Several bands on one model (MultiBandDetector) and their streaming twin."""

import pickle
import warnings

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.frozen import FrozenEstimator
from sklearn.linear_model import LinearRegression, Ridge
from sklearn.model_selection import ParameterGrid
from sklearn.utils.estimator_checks import parametrize_with_checks

from sklearn_gpcd.detection import (
    CollisionDetector,
    MonitorStatus,
    MultiBandDetector,
    MultiBandMonitor,
    stack_currents,
)
from sklearn_gpcd.features import CausalFeatures
from sklearn_gpcd.gp import make_sp_p

from _synthetic import augmented_run, controller_detector, simulated_interaction

SIGMA_V = 1e-2
FAST = {"filter_cutoff": 10.0, "filter_order": 1, "min_duration": 2}


def _order_dependent(estimator):
    """A band with a low-pass filter or a debounce is a filter over time: its
    output depends on the order of the samples, by design (as for a
    CollisionDetector with filter_cutoff or min_duration > 1)."""
    filtered = any(band.get("filter_cutoff") or band.get("min_duration", 1) > 1
                   for band in estimator.bands)
    reason = "a filter over time depends on the order and the neighbours of a sample"
    checks = ("check_methods_sample_order_invariance", "check_methods_subset_invariance")
    return {check: reason for check in checks} if filtered else {}


@parametrize_with_checks([
    MultiBandDetector(CollisionDetector(Ridge()), bands=[{}, {"contamination": 0.05}]),
    MultiBandDetector(CollisionDetector(Ridge())),  # the default fast band
    MultiBandDetector(CollisionDetector(Ridge(), contamination=0.05),
                      bands=[{}, {"filter_cutoff": 20.0, "sample_time": 0.01}]),
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
                                 filter_cutoff=2.0, min_duration=5)
    det = MultiBandDetector(template, bands=[{}, FAST, {"filter_cutoff": 5.0}]).fit(X)
    assert CountingRidge.fits == 1  # the model is fitted once
    assert [d.filter_cutoff for d in det.detectors_] == [2.0, 10.0, 5.0]
    assert all(isinstance(d.regressor_, FrozenEstimator) for d in det.detectors_[1:])
    assert all(d.regressor_.estimator is det.regressor_ for d in det.detectors_[1:])
    # each band is the detector fitted alone on the frozen model
    alone = template.set_params(regressor=FrozenEstimator(det.regressor_), **FAST).fit(X)
    np.testing.assert_array_equal(alone.thresholds_, det.detectors_[1].thresholds_)
    test = noisy.copy()
    test[1000:1010, 0] += 0.6  # a 0.1 s tap
    test[2000:2100, 1] -= 0.4  # a 1 s push
    Z = stack_currents(x, test)
    out = det.monitoring_signal(Z)
    for band, member in zip(out.bands, det.detectors_):
        np.testing.assert_array_equal(band.alarms, member.predict_joints(Z))
        np.testing.assert_allclose(band.ratio, member.monitoring_signal(Z).ratio)
    union = np.logical_or.reduce([m.predict_joints(Z) for m in det.detectors_])
    np.testing.assert_array_equal(out.alarms, union)
    np.testing.assert_array_equal(det.predict_joints(Z), union)
    np.testing.assert_array_equal(det.predict(Z) == -1, union.any(axis=1))
    np.testing.assert_array_equal(det.decision_function(Z) < 0, union.any(axis=1))
    decisions = np.min([m.decision_function(Z) for m in det.detectors_], axis=0)
    np.testing.assert_allclose(det.score_samples(Z), decisions)
    assert union[1000:1030, 0].any() and union[2000:2120, 1].any()


@pytest.mark.parametrize("bands, match", [
    ([], "non-empty list"),
    ({"filter_cutoff": 10.0}, "non-empty list"),
    ([{}, {"regressor": Ridge()}], "'regressor' is not a parameter a band may set"),
    ([{"n_joints": 2}], "'n_joints'"),
    ([{"filter_cutof": 10.0}], "'filter_cutof'"),
])
def test_bad_bands_are_named(bands, match, rng):
    X = stack_currents(rng.normal(size=(50, 1)), rng.normal(size=50))
    with pytest.raises(ValueError, match=match):
        MultiBandDetector(CollisionDetector(Ridge()), bands=bands).fit(X)


def test_a_frozen_model_keeps_its_sigma_v_and_the_regimes_use_the_detectors(rng):
    X, current = augmented_run(400, 2, rng)
    Z = stack_currents(X, current)
    template = CollisionDetector(make_sp_p(None, 2, sigma_v=SIGMA_V, n_support=40,
                                           optimizer=None),
                                 n_joints=2, sigma_v=0.02, regimes=True,
                                 threshold="per_joint", margin=1.5, sample_time=0.008)
    det = MultiBandDetector(template).fit(Z)
    assert det.regressor_.sigma_v == 0.02  # set on the fitted model by the first band
    assert det.detectors_[1]._regime_settings()["sigma_v"] == 0.02


@pytest.fixture(scope="module")
def simulated():
    return simulated_interaction()


def _gp_detector(n_joints, Z, **params):
    template = CollisionDetector(
        make_sp_p(None, n_joints, sigma_v=SIGMA_V, n_support=60, random_state=0,
                  optimizer=None),
        n_joints=n_joints, contamination=0.01, filter_cutoff=2.0, min_duration=5, **params)
    return MultiBandDetector(template).fit(Z)


def test_streaming_equals_batch_with_faults_restarts_and_one_prediction(rng):
    X, current = augmented_run(800, 2, rng)
    det = _gp_detector(2, stack_currents(X[::2], current[::2]), sample_time=0.008)
    test = current + 0.01 * rng.normal(size=current.shape)
    test[100:110, 0] += 1.0
    test[300:380, 1] -= 1.0
    Z = stack_currents(X, test)
    monitor = MultiBandMonitor(det)
    assert monitor.monitors[0].predictor_kind == "gaussian_process"
    calls = []
    inner = monitor.monitors[0]._predictor.predictor
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
    # one prediction per valid tick, by the first band; the others copy it
    assert len(calls) == len(Z) - len(bad)
    assert all(type(m._predictor).__name__ == "_CopiedPrediction" for m in monitor.monitors[1:])
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
    det = MultiBandDetector(controller_detector()).fit(Z, time=free.time)
    monitor = MultiBandMonitor(det, features=features)
    half = rec.n_samples // 2
    signals = {"target_q": rec.target_q, "target_qd": rec.target_qd,
               "target_current": rec.target_current}

    def raw(m, k):
        return m.update_raw(rec.time[k], rec.q[k], rec.qd[k], rec.current[k],
                            **{s: v[k] for s, v in signals.items() if v is not None})

    streamed = [raw(monitor, k) == MonitorStatus.COLLISION for k in range(half)]
    resumed = pickle.loads(pickle.dumps(monitor))
    assert isinstance(resumed.monitors[1]._predictor, type(monitor.monitors[1]._predictor))
    streamed += [raw(resumed, k) == MonitorStatus.COLLISION for k in range(half, rec.n_samples)]
    batch = det.predict(stack_currents(features.transform(rec), rec.current)) == -1
    np.testing.assert_array_equal(streamed, batch)
    assert batch.any()


def test_calibrate_bands_counts_the_nested_alarms_of_the_union():
    from sklearn.linear_model import LinearRegression

    from sklearn_gpcd.detection import (
        calibrate_across_recordings,
        calibrate_bands_across_recordings,
        nested_alarms,
    )
    from sklearn_gpcd.metrics import alarm_onsets

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
    template = CollisionDetector(model, threshold="per_joint", false_alarm_rate=0.0,
                                 sample_time=0.01, filter_cutoff=2.0, min_duration=5)
    result = calibrate_bands_across_recordings(MultiBandDetector(template), blocks, times)
    alone = [calibrate_across_recordings(template, blocks, times),
             calibrate_across_recordings(clone(template).set_params(**FAST), blocks, times)]
    for band, single, fitted in zip(result.bands, alone, result.detector.detectors_):
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
    # the fitted detector is a MultiBandDetector like any other
    Z = blocks["c"]
    np.testing.assert_array_equal(
        result.detector.predict_joints(Z),
        np.logical_or.reduce([d.predict_joints(Z) for d in result.detector.detectors_]))


def _tapped_recordings(n_recordings=6, seed=0):
    """Collision-free 1-joint recordings, some with a short tap or a slow swell."""
    from sklearn.linear_model import LinearRegression

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
    template = CollisionDetector(model, threshold="per_joint", false_alarm_rate=0.0,
                                 sample_time=0.01, filter_cutoff=2.0, min_duration=5)
    return template, blocks, times


BAND_GRID = {"filter_cutoff": [5.0, 10.0, 20.0], "min_duration": [2, 4]}


def test_band_grid_of_one_candidate_is_the_fixed_band():
    from sklearn_gpcd.detection import calibrate_bands_across_recordings

    template, blocks, times = _tapped_recordings()
    fixed = calibrate_bands_across_recordings(MultiBandDetector(template), blocks, times)
    grid = calibrate_bands_across_recordings(MultiBandDetector(template), blocks, times,
                                             band_grid={k: [v] for k, v in FAST.items()})
    assert grid.band_settings == FAST and fixed.band_settings == {}
    assert all(s == FAST for s in grid.fold_band_settings.values())
    assert grid.folds == fixed.folds and grid.n_false_alarms == fixed.n_false_alarms
    for a, b in zip(grid.detector.detectors_, fixed.detector.detectors_):
        np.testing.assert_array_equal(a.thresholds_, b.thresholds_)
    assert [c["rank"] for c in grid.band_candidates] == [0]


def test_band_grid_scores_each_recording_with_the_band_chosen_without_it():
    """The nested figure, rebuilt from public calls: for each recording, every
    candidate calibrated on the other recordings alone, the best one (fewest
    nested onsets of the union there, then the smallest score of the band)
    refitted there and run on the left-out recording."""
    from sklearn_gpcd.detection import calibrate_bands_across_recordings
    from sklearn_gpcd.metrics import alarm_onsets

    template, blocks, times = _tapped_recordings()
    result = calibrate_bands_across_recordings(MultiBandDetector(template), blocks, times,
                                               band_grid=BAND_GRID)
    candidates = list(ParameterGrid(BAND_GRID))
    assert len(result.band_candidates) == len(candidates)
    for r in blocks:
        others = {k: v for k, v in blocks.items() if k != r}
        runs = [calibrate_bands_across_recordings(
            MultiBandDetector(template, bands=({}, {**FAST, **c})), others, times)
            for c in candidates]
        ranks = [(run.n_false_alarms, run.bands[-1].candidates[0]["score"]) for run in runs]
        c = min(range(len(runs)), key=ranks.__getitem__)
        assert result.fold_band_settings[r] == candidates[c]
        alarm = runs[c].detector.predict(blocks[r]) == -1
        assert result.folds[r]["onsets"] == alarm_onsets(alarm, times[r] - times[r][0]), r
    # the data make the choice depend on the recording left out
    assert len({str(s) for s in result.fold_band_settings.values()}) > 1
    # the operating point: the candidate ranked first on all recordings, refitted on all
    ranked = {str(c["params"]): c["rank"] for c in result.band_candidates}
    assert ranked[str(result.band_settings)] == 0
    best = calibrate_bands_across_recordings(
        MultiBandDetector(template, bands=({}, {**FAST, **result.band_settings})), blocks, times)
    for a, b in zip(result.detector.detectors_, best.detector.detectors_):
        np.testing.assert_array_equal(a.thresholds_, b.thresholds_)


class RowCountingRegression(LinearRegression):
    """LinearRegression that counts the rows it predicts (module level so it pickles)."""

    rows = 0

    def predict(self, X):
        type(self).rows += len(X)
        return super().predict(X)


THREE_BANDS = ({}, FAST, {"filter_cutoff": 5.0, "filter_order": 2})


def test_the_bands_share_one_prediction_and_calibrate_as_alone():
    from sklearn_gpcd.detection import (
        calibrate_across_recordings,
        calibrate_bands_across_recordings,
    )

    template, blocks, times = _tapped_recordings()
    n_rows = sum(len(block) for block in blocks.values())
    model = RowCountingRegression().fit(blocks["r0"][:, :1], blocks["r0"][:, 1])
    template.set_params(regressor=FrozenEstimator(model))
    for band_grid in (None, BAND_GRID):
        RowCountingRegression.rows = 0
        result = calibrate_bands_across_recordings(
            MultiBandDetector(template, bands=THREE_BANDS), blocks, times, band_grid=band_grid)
        assert RowCountingRegression.rows == n_rows, band_grid  # once, for every band
    RowCountingRegression.rows = 0
    result = calibrate_bands_across_recordings(
        MultiBandDetector(template, bands=THREE_BANDS), blocks, times)
    for band, settings in zip(result.bands, THREE_BANDS):
        alone = calibrate_across_recordings(clone(template).set_params(**settings),
                                            blocks, times)
        np.testing.assert_array_equal(band.detector.thresholds_, alone.detector.thresholds_)
        np.testing.assert_array_equal(band.margin, alone.margin)
        np.testing.assert_array_equal(band.levels, alone.levels)
        assert band.folds == alone.folds and band.settings == alone.settings == {}
        assert band.candidates == alone.candidates
        assert band.detector.get_params() == alone.detector.get_params()
    assert RowCountingRegression.rows == 4 * n_rows  # the bands once, each alone once


def test_a_band_that_differs_before_the_regressor_predicts_on_its_own(rng):
    x, _, noisy = _taps(rng)
    X = stack_currents(x, noisy)
    template = CollisionDetector(RowCountingRegression(), n_joints=2, sample_time=0.01,
                                 filter_cutoff=2.0, min_duration=5, contamination=0.01)
    after = THREE_BANDS + ({"contamination": 0.05},)  # the level acts after the model
    RowCountingRegression.rows = 0
    shared = MultiBandDetector(template, bands=after).fit(X)
    assert RowCountingRegression.rows == len(X)
    before = ({}, {"sample_time": 0.02})  # the sampling period is set with the fit
    RowCountingRegression.rows = 0
    with pytest.warns(UserWarning, match="sample_time=0.02"):
        other = MultiBandDetector(template, bands=before).fit(X, time=np.arange(len(X)) * 0.01)
    assert RowCountingRegression.rows == 2 * len(X)
    assert other.detectors_[1].sample_time_ == 0.02
    first_alone = clone(template).fit(X)  # the same model: the bands left it as it was
    np.testing.assert_array_equal(shared.detectors_[0].thresholds_, first_alone.thresholds_)
    for det, bands in ((shared, after), (other, before)):
        for band, settings in zip(det.detectors_[1:], bands[1:]):
            frozen = FrozenEstimator(det.regressor_)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # sample_time against time: checked above
                alone = clone(template).set_params(regressor=frozen, **settings).fit(
                    X, time=np.arange(len(X)) * 0.01)
            np.testing.assert_array_equal(band.thresholds_, alone.thresholds_)
            assert band.offset_ == alone.offset_
            assert band.get_params()["regressor"] is band.regressor_


def test_band_grid_takes_only_settings_chosen_after_the_model():
    from sklearn_gpcd.detection import calibrate_bands_across_recordings

    template, blocks, times = _tapped_recordings(n_recordings=3)
    with pytest.raises(ValueError, match="'threshold' cannot be chosen across recordings"):
        calibrate_bands_across_recordings(MultiBandDetector(template), blocks, times,
                                          band_grid={"threshold": ["global"]})
