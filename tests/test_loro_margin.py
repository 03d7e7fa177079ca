"""The leave-one-recording-out margin as a detector parameter (issue 14).

``AlarmRule(margin="loro")`` (a detector's rule) learns the margin that
``calibrate_across_recordings`` (``gpcd calibrate``) chooses, so that
``CollisionThresholdCV`` with recordings as groups scores it on recordings
it never saw, the same figure as the calibration's nested false alarms.
"""

import numpy as np
import pytest
from sklearn.frozen import FrozenEstimator
from sklearn.linear_model import LinearRegression
from sklearn.model_selection import LeaveOneGroupOut

from sklearn_gpcd.detection import (
    AlarmRule,
    CollisionDetector,
    CollisionThresholdCV,
    Regimes,
    calibrate_across_recordings,
    loro_margin,
    nested_alarms,
    nested_false_alarms,
    regime_excursions,
    stack_currents,
)

DT = 0.01


def _recordings(n_recordings=4, n=600, seed=0):
    """Collision-free recordings of one joint: a drive, motion and rest phases.

    The noise level differs between recordings (as between real runs), so a
    left-out recording exceeds the others' level and the margin exceeds 1.
    """
    rng = np.random.default_rng(seed)
    blocks, times = {}, {}
    for r in range(n_recordings):
        t = np.arange(n) * DT
        qd = np.where((t % 2.0) < 1.0, np.sin(np.pi * t), 0.0)[:, None]
        current = 2.0 * qd[:, 0] + (0.05 + 0.03 * r) * rng.standard_t(4, size=n)
        blocks[f"rec{r}"] = stack_currents(qd, current)
        times[f"rec{r}"] = t
    return blocks, times


def _template(regressor=None, **params):
    """The detector under test; ``params`` set its rule (``regimes__...`` its regimes)."""
    regressor = LinearRegression() if regressor is None else regressor
    rule = AlarmRule("per_joint", false_alarm_rate=0.0, filter_cutoff=5.0, min_duration=3,
                     regimes=Regimes()).set_params(**params)
    return CollisionDetector(regressor, sample_time=DT, velocity_columns=[0], rules=rule)


def _stacked(blocks):
    keys = list(blocks)
    Z = np.concatenate([blocks[k] for k in keys])
    groups = np.repeat(np.arange(len(keys)), [len(blocks[k]) for k in keys])
    return Z, groups


def test_loro_margin_is_the_calibration_margin():
    blocks, times = _recordings()
    result = calibrate_across_recordings(_template(), blocks, times)
    Z, groups = _stacked(blocks)
    det = _template(margin="loro").fit(Z, groups=groups)
    assert det.margin_.shape == det.scale_.shape
    assert det.margin_.min() > 1.0          # the noisiest recording sets it
    np.testing.assert_allclose(det.margin_, result.margin, rtol=1e-12)
    np.testing.assert_allclose(det.thresholds_, result.detector.thresholds_, rtol=1e-12)
    # the margin is the worst left-out excess of the recordings' peaks
    peaks = {k: v[2] for k, v in regime_excursions(
        _template().fit(Z, groups=groups), blocks).items()}
    np.testing.assert_allclose(det.margin_, loro_margin(peaks, list(peaks)), rtol=1e-12)


def test_the_operating_point_is_the_template_fitted_with_the_chosen_margin():
    """calibrate_across_recordings returns what fit would: same parameters,
    fitted attributes and decisions, from the one prediction it made."""
    blocks, times = _recordings(seed=3)
    result = calibrate_across_recordings(_template(), blocks, times)
    Z, groups = _stacked(blocks)
    time = np.concatenate([times[k] for k in blocks])
    fitted = _template(margin=result.margin).fit(Z, groups=groups, time=time)
    det = result.detector
    assert det is not None and sorted(det.get_params()) == sorted(fitted.get_params())
    np.testing.assert_array_equal(det.rules.margin, fitted.rules.margin)
    for name in ("scale_", "margin_", "thresholds_", "offset_", "sample_time_"):
        np.testing.assert_allclose(getattr(det, name), getattr(fitted, name), rtol=1e-12)
    np.testing.assert_allclose(det.decision_function(Z), fitted.decision_function(Z),
                               rtol=1e-12)


def test_numeric_margin_is_stored_broadcast():
    blocks, _ = _recordings(n_recordings=2)
    Z, groups = _stacked(blocks)
    det = _template(margin=1.5).fit(Z, groups=groups)
    assert det.margin_.shape == det.scale_.shape
    assert np.all(det.margin_ == 1.5)
    plain = CollisionDetector(LinearRegression(), sample_time=DT).fit(Z)
    assert np.all(plain.margin_ == 1.0)


def test_loro_margin_needs_two_recordings():
    blocks, _ = _recordings(n_recordings=2)
    Z, groups = _stacked(blocks)
    with pytest.raises(ValueError, match="groups= naming at least 2 recordings"):
        _template(margin="loro").fit(Z)
    with pytest.raises(ValueError, match="got 1"):
        _template(margin="loro").fit(Z, groups=np.zeros(len(Z)))


def test_loro_margin_needs_the_per_joint_rule():
    blocks, _ = _recordings(n_recordings=2)
    Z, groups = _stacked(blocks)
    with pytest.raises(ValueError, match="'loro' \\(with threshold='per_joint'\\)"):
        CollisionDetector(LinearRegression(), sample_time=DT, rules=AlarmRule(margin="loro")).fit(
            Z, groups=groups)
    with pytest.raises(ValueError, match="'margin' parameter of AlarmRule must be"):
        _template(margin="global").fit(Z, groups=groups)


def test_threshold_cv_scores_the_loro_margin_like_the_nested_calibration():
    """Leave-one-recording-out CV of margin="loro" == nested_false_alarms, recording by recording."""
    blocks, times = _recordings(n_recordings=5, seed=3)
    Z, groups = _stacked(blocks)
    labels = np.zeros(len(Z), dtype=int)
    search = CollisionThresholdCV(_template(), {"rules__margin": ["loro", 1.0]},
                                  cv=LeaveOneGroupOut()).fit(Z, labels, groups=groups)
    assert search.best_estimator_.margin_.min() >= 1.0
    base = _template().fit(Z, groups=groups)
    folds = nested_false_alarms(regime_excursions(base, blocks), times)
    hours = len(Z) / len(blocks) * DT / 3600.0     # the CV counts every sample's period
    for k, key in enumerate(blocks):               # LeaveOneGroupOut: fold k leaves group k out
        rate = search.cv_results_[f"split{k}_test_false_alarms_per_hour"][0]
        assert round(rate * hours) == len(folds[key]["onsets"])
    # a unit margin is at least as alarm-prone on unseen recordings as the LORO one
    mean = search.cv_results_["mean_test_false_alarms_per_hour"]
    assert mean[1] > mean[0]


def test_threshold_cv_takes_the_sampling_period_from_time_stamps():
    blocks, times = _recordings(n_recordings=3, seed=1)
    Z, groups = _stacked(blocks)
    labels = np.zeros(len(Z), dtype=int)
    labels[700:730] = 1                             # a labelled stretch in recording 1
    Z[700:730, -1] += 3.0
    time = np.concatenate([times[k] for k in blocks])
    grid = {"rules__margin": ["loro", 1.0]}
    given = CollisionThresholdCV(_template(), grid, cv=LeaveOneGroupOut(), max_delay=0.3)
    given.fit(Z, labels, groups=groups)
    auto = CollisionThresholdCV(_template().set_params(sample_time="auto"), grid,
                                cv=LeaveOneGroupOut(), max_delay=0.3)
    auto.fit(Z, labels, groups=groups, time=time)
    assert auto.best_estimator_.sample_time_ == pytest.approx(DT)
    for metric in ("recall", "false_alarms_per_hour", "delay"):
        np.testing.assert_allclose(auto.cv_results_[f"mean_test_{metric}"],
                                   given.cv_results_[f"mean_test_{metric}"], rtol=1e-9)
    recall = [given.cv_results_[f"split{k}_test_recall"][0] for k in range(3)]
    assert np.isnan(recall[0]) and recall[1] == 1.0 and np.isnan(recall[2])  # event in rec 1
    with pytest.raises(ValueError, match="sample_time='auto'"):
        CollisionThresholdCV(_template().set_params(sample_time="auto"), grid,
                             cv=LeaveOneGroupOut()).fit(Z, labels, groups=groups)
    with pytest.raises(ValueError, match="time must have shape"):
        auto.fit(Z, labels, groups=groups, time=time[:-1])


def test_margin_rules_share_the_worst_left_out_excess_as_far_as_they_say():
    """cell: each (regime, joint) alone; regime: largest over the joints;
    joint: largest over the regimes (a wrist joint's heavy tail no longer
    widens the shoulder's band); global: one for all."""
    peaks = {k: np.ones((3, 2)) for k in "abc"}
    peaks["a"][0, 1] = 4.0   # moving, joint 2: a exceeds the others' level 1 by 4
    peaks["b"][2, 0] = 1.5   # rest, joint 1: by 1.5
    keys = list(peaks)
    expected = {
        "cell": [[1.0, 4.0], [1.0, 1.0], [1.5, 1.0]],
        "regime": [[4.0, 4.0], [1.0, 1.0], [1.5, 1.5]],
        "joint": [[1.5, 4.0], [1.5, 4.0], [1.5, 4.0]],
        "global": [[4.0, 4.0], [4.0, 4.0], [4.0, 4.0]],
    }
    for rule, table in expected.items():
        np.testing.assert_array_equal(loro_margin(peaks, keys, rule), table, err_msg=rule)
    with pytest.raises(ValueError, match="rule must be one of"):
        loro_margin(peaks, keys, "joints")


def test_nested_alarms_are_the_samples_behind_the_nested_onsets():
    """Each recording's alarms come from the other recordings' margin and
    levels: a left-out recording noisier than all the others alarms, and
    its alarm episodes start at the onsets ``nested_false_alarms`` reports."""
    blocks, times = _recordings(n_recordings=5, seed=3)
    series = regime_excursions(_template().fit(np.concatenate(list(blocks.values()))), blocks)
    alarms = nested_alarms(series, "cell")
    folds = nested_false_alarms(series, times, "cell")
    assert set(alarms) == set(blocks)
    assert any(a.any() for a in alarms.values())  # the noisiest recording breaks the others' band
    for key, alarm in alarms.items():
        starts = np.flatnonzero(np.diff(alarm.astype(int), prepend=0) == 1)
        assert folds[key]["onsets"] == pytest.approx(times[key][starts].tolist())


GRID = {"regimes__settle_time": [0.1, 0.5], "regimes__rest_reference": [None, 1.0]}


def test_a_one_candidate_grid_is_the_plain_calibration():
    blocks, times = _recordings()
    plain = calibrate_across_recordings(_template(regimes__settle_time=0.5), blocks, times)
    grid = calibrate_across_recordings(_template(), blocks, times,
                                       param_grid={"regimes__settle_time": [0.5]})
    assert grid.settings == {"regimes__settle_time": 0.5} and plain.settings == {}
    np.testing.assert_array_equal(grid.detector.thresholds_, plain.detector.thresholds_)
    assert grid.folds == plain.folds


def test_each_candidate_is_calibrated_as_its_own_template():
    """The candidates share one prediction per recording; each one's margin and
    nested false alarms are those of a calibration with its settings alone."""
    blocks, times = _recordings(seed=1)
    result = calibrate_across_recordings(_template(), blocks, times, param_grid=GRID)
    assert len(result.candidates) == 4
    for row in result.candidates:
        alone = calibrate_across_recordings(_template(**row["params"]), blocks, times)
        assert row["margin"] == pytest.approx(alone.margin.max(), rel=1e-12)
        assert row["n_false_alarms"] == alone.n_false_alarms
    best = min(result.candidates, key=lambda row: (row["n_false_alarms"], row["score"]))
    assert result.settings == best["params"] and best["rank"] == 0
    ranked = sorted(result.candidates, key=lambda row: row["rank"])
    assert [row["rank"] for row in ranked] == list(range(4))
    assert ranked == sorted(ranked, key=lambda row: (row["n_false_alarms"], row["score"]))
    alone = calibrate_across_recordings(_template(**result.settings), blocks, times)
    np.testing.assert_allclose(result.detector.thresholds_, alone.detector.thresholds_,
                               rtol=1e-12)


def _frozen(blocks):
    """A regressor trained once, as the docstring asks: every calibration below
    sees the same residuals, so a choice made without a recording is exactly
    the choice of a calibration that never had it."""
    Z, _ = _stacked(blocks)
    return FrozenEstimator(LinearRegression().fit(Z[:, :1], Z[:, 1]))


def test_nested_false_alarms_use_settings_chosen_without_the_recording():
    blocks, times = _recordings(n_recordings=5, seed=2)
    regressor = _frozen(blocks)
    result = calibrate_across_recordings(_template(regressor), blocks, times, param_grid=GRID)
    assert sorted(result.fold_settings) == sorted(blocks)
    for held_out in blocks:
        others = {k: v for k, v in blocks.items() if k != held_out}
        inner = calibrate_across_recordings(_template(regressor), others, times,
                                            param_grid=GRID)
        assert result.fold_settings[held_out] == inner.settings
        # scored with that candidate's margin and levels chosen without it
        alone = calibrate_across_recordings(_template(regressor, **inner.settings), blocks,
                                            times)
        assert result.folds[held_out] == alone.folds[held_out]


def test_the_candidate_that_transfers_between_recordings_is_chosen_first():
    """The smallest thresholds on the calibration recordings are not enough: on
    these four, settle 0.5 s without a reference has the smallest score but two
    nested alarm onsets, so a candidate with none is the operating point."""
    blocks, times = _recordings(n_recordings=4, seed=2)
    result = calibrate_across_recordings(_template(_frozen(blocks)), blocks, times,
                                         param_grid=GRID)
    tightest = min(result.candidates, key=lambda row: row["score"])
    assert tightest["params"] == {"regimes__rest_reference": None, "regimes__settle_time": 0.5}
    assert tightest["n_false_alarms"] == 2
    chosen = next(row for row in result.candidates if row["params"] == result.settings)
    assert chosen["n_false_alarms"] == 0
    assert chosen["score"] == min(row["score"] for row in result.candidates
                                  if row["n_false_alarms"] == 0)


def test_param_grid_names_what_can_be_chosen():
    blocks, times = _recordings(n_recordings=3)
    with pytest.raises(ValueError, match="'cutoff' is not a setting of the last alarm rule"):
        calibrate_across_recordings(_template(), blocks, times, param_grid={"cutoff": [1.0]})
    with pytest.raises(ValueError, match="the margin is chosen across recordings"):
        calibrate_across_recordings(_template(), blocks, times, param_grid={"margin": [1.0]})
    no_regimes = _template(regimes=None)
    with pytest.raises(ValueError, match="'regimes__rest_reference' is not a setting"):
        calibrate_across_recordings(no_regimes, blocks, times,
                                    param_grid={"regimes__rest_reference": [None, 1.0]})


def _random_series(rng, keys, n=400, n_rows=3, n_joints=2):
    """:func:`regime_excursions`-like series: a few high samples on noise."""
    out = {}
    for k in keys:
        debounced = rng.gamma(2.0, size=(n, n_joints))
        debounced[rng.random(n) < 0.01] *= rng.uniform(1, 4)
        regimes = rng.integers(0, n_rows, size=n)
        peaks = np.zeros((n_rows, n_joints))
        for g in range(n_rows):
            peaks[g] = debounced[regimes == g].max(axis=0)
        out[k] = (debounced, regimes, peaks)
    return out


@pytest.mark.parametrize("rule", ["global", "cell"])
@pytest.mark.parametrize("n_fixed", [0, 1])
def test_union_onsets_of_all_subsets_equal_one_subset_at_a_time(rule, n_fixed):
    # the ranking's onsets, each series read once for every subset, against
    # nested_alarms on each subset on its own (the definition)
    from sklearn_gpcd.detection.calibration import _union_onsets
    from sklearn_gpcd.metrics import alarm_onsets

    rng = np.random.default_rng(3)
    keys = list("abcdef")
    fixed = [_random_series(rng, keys) for _ in range(n_fixed)]
    runs = [_random_series(rng, keys) for _ in range(4)]
    runs[1]["c"][0][5, 0] = np.nan  # an unknown sample alarms nowhere
    subsets = [tuple(keys)] + [tuple(k for k in keys if k != r) for r in keys]
    table = _union_onsets(fixed, runs, keys, subsets, rule)
    for subset in subsets:
        held = [nested_alarms({k: s[k] for k in subset}, rule) for s in fixed]
        expected = []
        for run in runs:
            alarms = nested_alarms({k: run[k] for k in subset}, rule)
            expected.append(sum(len(alarm_onsets(np.logical_or.reduce(
                [h[r] for h in held] + [alarms[r]]))) for r in subset))
        assert table[subset] == expected
    assert any(sum(counts) for counts in table.values())  # alarms to count
