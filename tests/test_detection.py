"""CollisionDetector, StreamingMonitor, CollisionThresholdCV and plot_monitoring."""

import warnings

import numpy as np
import pytest
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, DotProduct, WhiteKernel
from sklearn.gaussian_process.kernels import ConstantKernel as C
from sklearn.linear_model import LinearRegression, Ridge
from sklearn.model_selection import GridSearchCV, GroupKFold
from sklearn.neighbors import KNeighborsRegressor
from sklearn.utils.estimator_checks import parametrize_with_checks

from sklearn_gpcd.layout import column_index
from sklearn_gpcd.detection import (
    AlarmRule,
    CollisionDetector,
    CollisionThresholdCV,
    MonitorStatus,
    StreamingMonitor,
    stack_currents,
)
from sklearn_gpcd.gp import compile_predictor
from sklearn_gpcd.gp import ParametricMean, SemiParametricGPRegressor, make_sp_p
from sklearn_gpcd.kernels import ARDRBF, QuasiStaticGate
from sklearn_gpcd.metrics import (DetectionRefit, DetectionScorer, contact_events,
                                  event_recall, select_candidate)

from _synthetic import augmented_run

SIGMA_V = 1e-2


# ----------------------------------------------------------------- helpers
def bumpy_run(rng, n_samples=1500, bumps=((200, 40), (600, 40), (1000, 30), (1300, 30))):
    """One-joint run, current = f(q, qd) + noise, with known additive bumps."""
    t = np.arange(n_samples) * 0.008
    q = np.sin(0.7 * t) + 0.3 * np.sin(2.3 * t + rng.uniform(0, 1))
    qd = np.gradient(q, 0.008)
    current = 1.5 * np.sin(q) + 0.8 * qd + 0.02 * rng.normal(size=n_samples)
    labels = np.zeros(n_samples, dtype=int)
    for k, (start, length) in enumerate(bumps):
        current[start : start + length] += 0.4
        labels[start : start + length] = k + 1
    return np.column_stack([q, qd]), current, labels


def small_sp_p(n_joints, **params):
    return make_sp_p(None, n_joints, sigma_v=SIGMA_V, n_support=60, random_state=0, **params)


# ------------------------------------------------------- estimator checks
@parametrize_with_checks(
    [
        CollisionDetector(Ridge()),
        CollisionDetector(
            GaussianProcessRegressor(RBF() + WhiteKernel(), optimizer=None), normalize="std"
        ),
        CollisionDetector(Ridge(), rules=AlarmRule(contamination=0.05)),
    ]
)
def test_sklearn_compatible(estimator, check):
    check(estimator)


# ------------------------------------------------------------ the detector
def test_detects_every_bump_and_stays_quiet_elsewhere(rng):
    X_train, i_train, _ = bumpy_run(rng, bumps=())
    X_train, i_train = X_train[::3], i_train[::3]  # 500 samples keep the GP fit quick
    X_test, i_test, labels = bumpy_run(rng)
    # fixed hyperparameters (normalised units) keep the test fast and deterministic
    kernel = C(1.0) * RBF([1.0, 2.0]) + WhiteKernel(1e-3)
    rule = AlarmRule("std", k=5.0, filter_cutoff=5.0, min_duration=3)
    det = CollisionDetector(GaussianProcessRegressor(kernel, normalize_y=True, optimizer=None),
                            normalize="std", rules=rule).fit(stack_currents(X_train, i_train))
    pred = det.predict(stack_currents(X_test, i_test))
    alarms = pred == -1
    assert event_recall(labels, alarms) == 1.0
    # clean stretches: 30 samples (filter and debounce lag) away from any bump
    near = np.zeros_like(alarms)
    for start, stop in zip(*contact_events(labels)):
        near[start : stop + 30] = True
    assert not alarms[~near].any()


def test_each_threshold_rule_sets_its_level(rng):
    X, current = augmented_run(800, 2, rng)
    Z = stack_currents(X, current)
    det = CollisionDetector(Ridge(), n_joints=2, rules=AlarmRule(contamination=0.02)).fit(Z)
    assert np.mean(det.predict(Z) == -1) == pytest.approx(0.02, abs=1 / 800)
    assert np.allclose(det.thresholds_, -det.offset_ * det.scale_)
    # scale_ = RMS of the training residual per joint
    residual = current - det.regressor_.predict(X)
    assert np.allclose(det.scale_, np.sqrt(np.mean(residual**2, axis=0)))

    det = CollisionDetector(Ridge(), n_joints=2,
                            rules=AlarmRule(threshold="false_alarm_rate",
                                            false_alarm_rate=600.0)).fit(Z)
    alarms = det.predict(Z) == -1
    onsets = np.sum(alarms[1:] & ~alarms[:-1]) + alarms[0]
    hours = 800 * 0.008 / 3600
    assert onsets <= 600.0 * hours  # at most 1 onset in 6.4 s
    det.set_params(rules__false_alarm_rate=0.0).fit(Z)
    assert not (det.predict(Z) == -1).any()

    kernel = C(1.0) * RBF(np.full(12, 3.0)) + WhiteKernel(1e-2)
    gp = GaussianProcessRegressor(kernel, optimizer=None)
    det = CollisionDetector(gp, n_joints=2, normalize="std",
                            rules=AlarmRule(threshold="std", k=4.0)).fit(Z)
    assert det.offset_ == -4.0 and np.allclose(det.thresholds_, 4.0)
    det = CollisionDetector(gp, n_joints=2, rules=AlarmRule(threshold="std", k=4.0)).fit(Z)
    _, std = det.regressor_.predict(X, return_std=True)
    assert np.allclose(det.thresholds_, 4.0 * np.sqrt(np.mean(std**2, axis=0)))


def test_predict_joints_names_the_bumped_joint(rng):
    X, current = augmented_run(800, 2, rng)
    det = CollisionDetector(Ridge(), n_joints=2, rules=AlarmRule(contamination=0.001))
    det.fit(stack_currents(X, current))
    bumped = current.copy()
    bumped[300:320, 1] += 3.0
    Z = stack_currents(X, bumped)
    fired = det.predict_joints(Z)
    assert fired[300:320, 1].all() and not fired[300:320, 0].any()
    assert np.array_equal(fired.any(axis=1), det.predict(Z) == -1)
    assert np.allclose(det.decision_function(Z), det.score_samples(Z) - det.offset_)


def test_labels_leave_contacts_out_of_training(rng):
    X, current, labels = bumpy_run(rng)
    Z = stack_currents(X, current)
    with_labels = CollisionDetector(LinearRegression()).fit(Z, labels=labels)
    clean_only = CollisionDetector(LinearRegression()).fit(Z[labels == 0])
    assert np.allclose(with_labels.regressor_.coef_, clean_only.regressor_.coef_)
    with pytest.raises(ValueError, match="no collision-free row"):
        CollisionDetector(LinearRegression()).fit(Z, labels=np.ones(len(Z)))


def test_groups_restart_the_filter_and_debounce(rng):
    X, current, _ = bumpy_run(rng)
    Z = stack_currents(X, current)
    det = CollisionDetector(LinearRegression(),
                            rules=AlarmRule(filter_cutoff=3.0, filter_order=2,
                                            min_duration=4)).fit(Z)
    groups = np.repeat([0, 1, 2], [500, 400, 600])
    joint = det.score_samples(Z, groups=groups)
    parts = [det.score_samples(Z[groups == g]) for g in range(3)]
    assert np.allclose(joint, np.concatenate(parts))
    assert not np.allclose(joint, det.score_samples(Z))


def test_filter_and_debounce_change_the_signal_as_documented(rng):
    X, current, _ = bumpy_run(rng)
    Z = stack_currents(X, current)
    plain = CollisionDetector(LinearRegression()).fit(Z)
    filtered = CollisionDetector(LinearRegression(), rules=AlarmRule(filter_cutoff=2.0)).fit(Z)
    raw = plain.monitoring_signal(Z)
    smooth = filtered.monitoring_signal(Z)
    assert np.std(np.diff(smooth.signal[:, 0])) < 0.5 * np.std(np.diff(raw.signal[:, 0]))
    debounced = CollisionDetector(LinearRegression(), rules=AlarmRule(min_duration=3)).fit(Z)
    ratio = np.abs(raw.residual[:, 0]) / debounced.scale_[0]
    expected = np.minimum(np.minimum(ratio[2:], ratio[1:-1]), ratio[:-2])
    assert np.allclose(debounced.monitoring_signal(Z).ratio[2:, 0], expected)
    assert np.all(debounced.monitoring_signal(Z).ratio[:2] == 0.0)


def test_default_regressor_is_sp_p(rng):
    X, current = augmented_run(120, 1, rng)
    det = CollisionDetector(sigma_v=0.05).fit(stack_currents(X, current))
    assert isinstance(det.regressor_, SemiParametricGPRegressor)
    assert det.regressor_.sigma_v == 0.05
    gate = det.regressor_.kernel_.k1.k1.k2
    assert isinstance(gate, QuasiStaticGate) and gate.sigma_v == 0.05


@pytest.mark.parametrize(
    "params, match",
    [
        ({"rules": AlarmRule(threshold="quantile")}, "'threshold' parameter of AlarmRule"),
        ({"rules": AlarmRule(contamination=0.7)}, "'contamination' parameter of AlarmRule"),
        ({"rules": AlarmRule(min_duration=0)}, "'min_duration' parameter of AlarmRule"),
        ({"rules": AlarmRule(filter_order=3)}, "'filter_order' parameter of AlarmRule"),
        ({"rules": AlarmRule(filter_cutoff=100.0)}, "filter_cutoff must lie in"),
        ({"rules": "fast"}, "'rules' parameter of CollisionDetector"),
        ({"normalize": "std"}, "return_std"),
        ({"sigma_v": 0.1}, "no sigma_v parameter"),
        ({"sigma_v": -0.1}, "'sigma_v' parameter of CollisionDetector"),
        ({"n_joints": 2}, "at least 3 columns"),
    ],
)
def test_invalid_settings_name_the_problem(params, match, rng):
    Z = rng.normal(size=(50, 2))
    with pytest.raises(ValueError, match=match):
        CollisionDetector(Ridge(), **params).fit(Z)


# -------------------------------------------------------------- streaming
def _stream_matches_batch(det, Z, groups=None):
    monitor = StreamingMonitor(det)
    out = monitor.replay(Z, groups=groups)
    batch = det.monitoring_signal(Z, groups=groups)
    assert np.array_equal(out.prediction, det.predict(Z, groups=groups))
    # a GP mean sums weights of both signs: agreement to conditioning precision
    assert np.allclose(out.residual, batch.residual, rtol=1e-7, atol=1e-7)
    assert np.allclose(out.ratio, batch.ratio, rtol=1e-6, atol=1e-6)
    assert np.array_equal(out.alarms, batch.alarms)
    return monitor, out


@pytest.mark.parametrize("filter_order", [1, 2])
def test_streaming_equals_batch_with_sp_p(filter_order, rng):
    X, current = augmented_run(800, 2, rng)
    rule = AlarmRule(contamination=0.01, filter_cutoff=8.0, filter_order=filter_order,
                     min_duration=3)
    det = CollisionDetector(small_sp_p(2), n_joints=2, rules=rule).fit(
        stack_currents(X[::2], current[::2]))
    test_current = current + 0.01 * rng.normal(size=current.shape)
    test_current[100:140, 0] += 1.5  # contact while moving
    test_current[300:340, 1] -= 1.5  # contact at rest
    Z = stack_currents(X, test_current)
    groups = np.repeat([0, 1], 400)
    monitor, out = _stream_matches_batch(det, Z, groups)
    assert monitor.predictor_kind == "gaussian_process"
    assert (out.prediction[100:140] == -1).any() and (out.prediction[300:340] == -1).any()
    assert set(out.status) <= {"ok", "collision"}


@pytest.mark.parametrize(
    "regressor, kind",
    [
        (Ridge(), "linear"),
        (KNeighborsRegressor(5), "generic"),
        (GaussianProcessRegressor(C(1.0) * RBF([3.0] * 6) + WhiteKernel(0.01), optimizer=None),
         "gaussian_process"),
    ],
)
def test_streaming_equals_batch_for_other_regressors(regressor, kind, rng):
    X, current = augmented_run(300, 1, rng)
    det = CollisionDetector(regressor,
                            rules=AlarmRule(contamination=0.05, filter_cutoff=5.0, min_duration=2))
    det.fit(stack_currents(X, current))
    monitor, _ = _stream_matches_batch(det, stack_currents(X, current + 0.05))
    assert monitor.predictor_kind == kind


def test_streaming_with_std_normalisation(rng):
    X, current = augmented_run(200, 1, rng)
    gp = GaussianProcessRegressor(C(1.0) * RBF([3.0] * 6) + WhiteKernel(0.01), optimizer=None)
    det = CollisionDetector(gp, normalize="std", rules=AlarmRule(threshold="std", k=3.0)).fit(
        stack_currents(X, current)
    )
    _stream_matches_batch(det, stack_currents(X, current + 0.03))


def test_sensor_fault_is_reported_and_skipped(rng):
    X, current = augmented_run(400, 2, rng)
    det = CollisionDetector(Ridge(), n_joints=2,
                            rules=AlarmRule(contamination=0.02, filter_cutoff=5.0,
                                            min_duration=3)).fit(stack_currents(X, current))
    Z = stack_currents(X, current)
    bad = [50, 51, 200]
    Z_faulty = Z.copy()
    Z_faulty[50, 3] = np.nan
    Z_faulty[51, -1] = np.inf
    Z_faulty[200, 0] = np.nan
    monitor = StreamingMonitor(det)
    out = monitor.replay(Z_faulty)
    assert list(out.status[bad]) == ["sensor_fault"] * 3
    assert out.status[52] in ("ok", "collision") and out.status[201] in ("ok", "collision")
    assert np.all(out.prediction[bad] == 0) and not out.alarms[bad].any()
    # the faulty ticks are skipped: the rest equals batch predict without them
    keep = np.setdiff1d(np.arange(len(Z)), bad)
    assert np.array_equal(out.prediction[keep], det.predict(Z[keep]))
    assert monitor.n_faults == 3 and monitor.n_ticks == len(Z)
    # a missing sample, then recovery
    assert monitor.update(None) is MonitorStatus.SENSOR_FAULT
    assert np.isnan(monitor.residual).all()
    assert monitor.update(Z[10]) in (MonitorStatus.OK, MonitorStatus.COLLISION)
    assert np.isfinite(monitor.residual).all()


def test_streaming_accepts_inputs_and_currents_separately(rng):
    X, current = augmented_run(200, 2, rng)
    det = CollisionDetector(Ridge(), n_joints=2).fit(stack_currents(X, current))
    a, b = StreamingMonitor(det), StreamingMonitor(det)
    for x, i in zip(X[:20], current[:20]):
        assert a.update(x, current=i) == b.update(np.r_[x, i])
        assert np.array_equal(a.residual, b.residual)
    with pytest.raises(ValueError, match="14 values"):
        a.update(X[0])
    with pytest.raises(ValueError, match="current must have 2 values"):
        a.update(X[0], current=[1.0])


# ------------------------------------------------------- compiled predictor
def test_compiled_gp_matches_predict_with_mean_gates_and_products(rng):
    X, current = augmented_run(300, 2, rng)
    n = 2
    kernels = []
    for joint in range(n):
        gate = QuasiStaticGate(
            C(0.5) * ARDRBF(np.ones(6 * n), columns=list(range(6 * n))),
            velocity_column=column_index("qd", joint, n), sigma_v=SIGMA_V,
        )
        kinetic = C(1.0) * ARDRBF(np.ones(2), columns=[0, 1]) * RBF(np.ones(6 * n))
        kernels.append(gate + kinetic + 0.1 * DotProduct() + WhiteKernel(0.01))
    means = [
        ParametricMean(friction_columns=[column_index("qd", j, n)],
                       velocity_column=column_index("qd", j, n), sigma_v=SIGMA_V)
        for j in range(n)
    ]
    gp = SemiParametricGPRegressor(kernels, means, optimizer=None, n_support=150,
                                   random_state=0).fit(X, current)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no fallback
        predictor = compile_predictor(gp, 6 * n, n)
    assert predictor.kind == "gaussian_process"
    assert len(predictor.generic) == n  # the DotProduct summands
    got = np.array([predictor.predict_one(x, np.empty(n)) for x in X])
    assert np.allclose(got, gp.predict(X), rtol=1e-8, atol=1e-8)


@pytest.mark.parametrize("n_support, selection, random_state, layout", [
    (40, "greedy", 0, "_StackedGroup"),
    (40, "random", None, "_SharedSupportGroup"),
    (None, "random", None, "_SharedSupportGroup"),
])
def test_compiled_groups_read_each_support_once(rng, n_support, selection, random_state,
                                                layout):
    """Outputs with their own support rows share one stacked product per column
    set; outputs on one support share its matrix product. Both equal predict."""
    X, current = augmented_run(200, 3, rng)
    n = 3
    kernels = [C(1.0) * ARDRBF(np.full(3 * n, scale), columns=list(range(3 * n)))
               + QuasiStaticGate(C(0.5) * ARDRBF(np.ones(6 * n), columns=list(range(6 * n))),
                                 velocity_column=column_index("qd", j, n), sigma_v=SIGMA_V)
               + WhiteKernel(0.01) for j, scale in enumerate([1.0, 30.0, 300.0])]
    # greedy selects in each output's kernel metric (length scales differ): its
    # own rows per output; a random draw is one for all, even with random_state=None
    gp = SemiParametricGPRegressor(kernels, optimizer=None, n_support=n_support,
                                   support_selection=selection,
                                   random_state=random_state).fit(X, current)
    supports = [tuple(s) for s in gp.support_indices_]
    assert len(set(supports)) == (n if layout == "_StackedGroup" else 1)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no fallback
        predictor = compile_predictor(gp, 6 * n, n)
    assert [type(g).__name__ for g in predictor.groups] == [layout, layout]
    assert [g.W.shape[1] for g in predictor.groups] == [n, n]  # every output in each
    got = np.array([predictor.predict_one(x, np.empty(n)) for x in X])
    assert np.allclose(got, gp.predict(X), rtol=1e-8, atol=1e-8)


@pytest.mark.parametrize("length_scale, folded", [(3.0, True), (0.02, False)])
def test_support_term_is_folded_into_the_weights_only_when_safe(rng, monkeypatch,
                                                                 length_scale, folded):
    """exp(-1/2 s^T W s) goes into the weights while it cannot over- or underflow
    (long length scales); with short ones it is added each tick. Both equal
    predict, and the two forms agree where both are safe."""
    from sklearn_gpcd.gp import compiled as _compiled

    X, current = augmented_run(150, 2, rng)
    columns = [0, 1, 2, 3, 6, 7, 8, 9] if folded else list(range(12))  # a take, a slice
    kernel = C(1.0) * ARDRBF(np.full(len(columns), length_scale), columns=columns)
    gp = SemiParametricGPRegressor(kernel + WhiteKernel(0.01), optimizer=None,
                                   random_state=0).fit(X, current)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no fallback
        predictor = compile_predictor(gp, 12, 2)
    (group,) = predictor.groups
    assert (group.h is None) == folded and (group.column_slice is None) == folded
    X_test = np.vstack([X, X[:20] + 0.1 * rng.normal(size=(20, 12))])
    got = np.array([predictor.predict_one(x, np.empty(2)) for x in X_test])
    assert np.allclose(got, gp.predict(X_test), rtol=1e-8, atol=1e-8)
    if folded:
        monkeypatch.setattr(_compiled, "_FOLD_LIMIT", -1.0)  # h added each tick
        direct = compile_predictor(gp, 12, 2)
        assert direct.groups[0].h is not None
        again = np.array([direct.predict_one(x, np.empty(2)) for x in X_test])
        assert np.allclose(again, got, rtol=1e-12, atol=1e-12 * np.abs(got).max())


@pytest.mark.parametrize("selection, layout", [("random", "_SharedSupportGroup"),
                                                ("greedy", "_StackedGroup")])
def test_exponents_are_floored_before_exp(rng, selection, layout):
    """Short length scales and an input far from the support put every
    exponent below -745, where exp underflows (numpy's slow path); the
    compiled path floors them at _EXP_FLOOR, so exp stays normal (> 0), and
    the prediction still equals predict (the floor changes a summand by at
    most |a| exp(-700))."""
    from sklearn_gpcd.gp import compiled as _compiled

    X, current = augmented_run(150, 2, rng)
    kernels = [C(1.0) * ARDRBF(np.full(6, scale), columns=list(range(6)))
               + WhiteKernel(0.01) for scale in (0.05, 1.0)]
    gp = SemiParametricGPRegressor(kernels, optimizer=None, n_support=40,
                                   support_selection=selection, random_state=0).fit(X, current)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no fallback
        predictor = compile_predictor(gp, 12, 2)
    (group,) = predictor.groups
    assert type(group).__name__ == layout
    far = X[:5] + 100.0  # d^2 / l^2 of the order of 6e4 >> 2 * 745 for every support row
    got = np.array([predictor.predict_one(x, np.empty(2)) for x in far])
    # exp of the last tick (times the weights in the stacked layout): an
    # underflowed lane would be exactly 0
    values = group.G if layout == "_SharedSupportGroup" else group.v
    assert np.exp(_compiled._EXP_FLOOR) > 0.0 and np.all(values != 0.0)
    assert np.allclose(got, gp.predict(far), rtol=1e-8, atol=1e-8)


def test_compiled_predictor_falls_back_when_it_disagrees(rng, monkeypatch):
    from sklearn_gpcd.kernels import plan

    X, current = augmented_run(100, 1, rng)
    gp = GaussianProcessRegressor(RBF(np.ones(6))).fit(X, current[:, 0])
    terms = plan._SquaredExponential.terms

    def broken(self, n_features):  # a node that disagrees with its kernel object
        return [plan.Term(t.scale, t.columns, 4.0 * t.inv_sq) for t in terms(self, n_features)]

    # the check compares the compiled path with the Kernel objects (K(x, X) @ alpha)
    monkeypatch.setattr(plan._SquaredExponential, "terms", broken)
    with pytest.warns(RuntimeWarning, match="falls back"):
        predictor = compile_predictor(gp, 6, 1)
    assert predictor.kind == "generic"


# ----------------------------------------------------------- tuning by CV
def _labelled_recordings(rng, n_recordings=3):
    parts = [bumpy_run(rng) for _ in range(n_recordings)]
    X = np.vstack([p[0] for p in parts])
    current = np.concatenate([p[1] for p in parts])
    labels = np.concatenate([p[2] + 10 * k * (p[2] > 0) for k, p in enumerate(parts)])
    groups = np.repeat(np.arange(n_recordings), [len(p[2]) for p in parts])
    return stack_currents(X, current), labels, groups


class _RecordingFolds(GroupKFold):
    """GroupKFold that records the test groups of every split."""

    seen = []

    def split(self, X, y=None, groups=None):
        for train, test in super().split(X, y, groups):
            assert not set(groups[train]) & set(groups[test])
            self.seen.append(np.unique(groups[test]).tolist())
            yield train, test


def test_threshold_cv_scores_candidates_and_applies_the_rule(rng):
    Z, labels, groups = _labelled_recordings(rng)
    grid = {"rules__contamination": [0.001, 0.2], "rules__filter_cutoff": [None, 4.0],
            "rules__min_duration": [1, 3]}
    search = CollisionThresholdCV(
        CollisionDetector(LinearRegression(), rules=AlarmRule()), grid, cv=_RecordingFolds(3),
        max_delay=0.2,
    ).fit(Z, labels, groups=groups)
    assert sorted(sum(_RecordingFolds.seen, [])) == [0, 1, 2]
    res = search.cv_results_
    assert len(res["params"]) == 8 and search.n_splits_ == 3
    assert search.best_index_ == select_candidate(
        res["mean_test_recall"], res["mean_test_false_alarms_per_hour"],
        res["mean_test_delay"], max_delay=0.2,
    )
    best = search.best_index_
    assert res["mean_test_recall"][best] == 1.0
    assert res["mean_test_delay"][best] <= 0.2
    assert search.best_params_["rules__contamination"] == 0.001  # 0.2 floods with alarms
    # one candidate re-scored by hand on fold 0
    train, test = next(GroupKFold(3).split(Z, labels, groups))
    det = CollisionDetector(LinearRegression(), rules=AlarmRule()).set_params(
        **res["params"][best])
    det.fit(Z[train], labels=labels[train], groups=groups[train])
    alarms = det.predict(Z[test], groups=groups[test]) == -1
    recall = event_recall(labels[test], alarms, max_delay=0.2, sample_time=0.008,
                          groups=groups[test])
    assert res["split0_test_recall"][best] == pytest.approx(recall)
    assert np.array_equal(search.predict(Z), search.best_estimator_.predict(Z))


def test_threshold_cv_refits_the_regressor_for_sigma_v(rng):
    X, current = augmented_run(240, 1, rng)
    labels = np.zeros(240, dtype=int)
    current[50:70, 0] += 1.0
    labels[50:70] = 1
    current[170:190, 0] += 1.0
    labels[170:190] = 2
    search = CollisionThresholdCV(
        CollisionDetector(make_sp_p(None, 1, n_support=40, optimizer=None), rules=AlarmRule()),
        {"sigma_v": [0.01, 0.1], "rules__min_duration": [1, 2]}, cv=2,
    ).fit(stack_currents(X, current), labels, groups=np.repeat([0, 1], 120))
    assert search.best_estimator_.regressor_.sigma_v == search.best_params_["sigma_v"]
    assert np.all(np.isfinite(search.cv_results_["mean_test_recall"]))


def test_threshold_cv_needs_several_recordings(rng):
    Z, labels, _ = _labelled_recordings(rng, 1)
    with pytest.raises(ValueError, match="at least 2 recordings"):
        CollisionThresholdCV(CollisionDetector(Ridge()), {"sigma_v": [None]}).fit(
            Z, labels, groups=np.zeros(len(Z))
        )


def test_grid_search_with_the_detection_scorer_and_routing(rng):
    """Plain GridSearchCV + DetectionScorer under metadata routing == CollisionThresholdCV."""
    from sklearn import config_context

    Z, labels, groups = _labelled_recordings(rng)
    grid = {"rules__contamination": [0.001, 0.2], "rules__min_duration": [1, 3]}
    with config_context(enable_metadata_routing=True):
        detector = CollisionDetector(LinearRegression(), rules=AlarmRule()).set_fit_request(
            labels=True, groups=True, time=False)
        search = GridSearchCV(detector, grid, scoring=DetectionScorer(max_delay=0.2),
                              refit=DetectionRefit(max_delay=0.2), cv=GroupKFold(3))
        search.fit(Z, labels, groups=groups, labels=labels)
    thin = CollisionThresholdCV(CollisionDetector(LinearRegression(), rules=AlarmRule()), grid,
                                cv=3, max_delay=0.2).fit(Z, labels, groups=groups)
    assert search.best_params_ == thin.best_params_ == {"rules__contamination": 0.001,
                                                         "rules__min_duration": 3}
    for k in range(3):
        np.testing.assert_array_equal(-search.cv_results_[f"split{k}_test_false_alarms_per_hour"],
                                      thin.cv_results_[f"split{k}_test_false_alarms_per_hour"])


# ------------------------------------------------------- simulated robot
@pytest.fixture(scope="module")
def interaction_runs():
    from sklearn_gpcd import datasets, features

    reference, contacts = datasets.reference_interaction_test(
        n_turns=0.5, rest_duration=12.0, random_state=0
    )
    train = [datasets.simulate(reference, random_state=s, name="free") for s in (2, 3, 4)]
    test = datasets.simulate(reference, contacts=contacts, random_state=1, name="pushes")
    X_train, i_train = features.make_inputs(train)
    X_test, i_test = features.make_inputs(test)
    groups = np.repeat(np.arange(3), [r.n_samples for r in train])
    rest_start = 1.0 + (reference.duration - 1.0 - 12.0)  # lead + circle
    return (stack_currents(X_train, i_train), groups, stack_currents(X_test, i_test),
            test, rest_start)


def test_interaction_test_on_the_simulator(interaction_runs):
    """Paper Sec. V-B: four pushes on link 1, two moving and two at rest."""
    Z_train, groups, Z_test, test, rest_start = interaction_runs
    rule = AlarmRule("false_alarm_rate", false_alarm_rate=1.0, filter_cutoff=2.0,
                     min_duration=3)
    det = CollisionDetector(make_sp_p(None, 6, n_support=120, random_state=0, n_jobs=2),
                            n_joints=6, rules=rule).fit(Z_train, groups=groups)
    fired = det.predict_joints(Z_test)
    alarms = fired.any(axis=1)
    labels = test.labels
    assert event_recall(labels, alarms) == 1.0  # every push, during the push
    assert fired[labels > 0, 0].any() and not fired[labels > 0, 1:].any()
    # Collision-free rest: from the end of the circle to the last push, except
    # the 3rd push and the 1 s in which the servo pulls the arm back after it.
    # (After the last push the arm holds a new stiction equilibrium that the
    # push-free training runs never visited, and the detector keeps flagging
    # it; that stretch is the collision's aftermath, not checked here.)
    starts, stops = contact_events(labels)
    free_rest = (test.time >= rest_start) & (test.time < test.time[starts[-1]]) & (labels == 0)
    for stop in stops:
        after = test.time[stop - 1]
        free_rest &= ~((test.time >= after) & (test.time < after + 1.0))
    assert free_rest.sum() > 500
    assert not alarms[free_rest].any()
    # and the streaming monitor agrees, sample for sample
    _stream_matches_batch(det, Z_test)


# ---------------------------------------------------------------- plotting
def test_plot_monitoring_draws_fig3(rng):
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sklearn_gpcd.plotting import plot_monitoring

    X, current, labels = bumpy_run(rng)
    det = CollisionDetector(LinearRegression()).fit(stack_currents(X, current), labels=labels)
    out = det.monitoring_signal(stack_currents(X, current))
    time = np.arange(len(X)) * 0.008
    axes = plot_monitoring(time, current, out.predicted, X[:, 1], out.signal,
                           det.thresholds_, labels=labels)
    assert len(axes) == 3
    assert len(axes[0].patches) == 4  # one grey span per contact, on each panel
    band = axes[2].collections[0].get_paths()[0].vertices[:, 1]
    assert np.isclose(band.max(), det.thresholds_[0])
    with pytest.raises(ValueError, match="joint=3"):
        plot_monitoring(time, current[:, None], out.predicted, X[:, 1], out.signal, 0.1,
                        joint=3)
    plt.close("all")


def test_named_columns_reach_the_regressor(rng):
    pd = pytest.importorskip("pandas")
    X, current = augmented_run(200, 1, rng)
    names = ["q_0", "qd_0", "qdd_0", "e_q_0", "de_q_0", "i_c_0", "i_0"]
    frame = pd.DataFrame(stack_currents(X, current), columns=names)
    kernel = C(1.0) * ARDRBF([3.0, 3.0], columns=["q_0", "qd_0"]) + WhiteKernel(0.01)
    det = CollisionDetector(SemiParametricGPRegressor(kernel, optimizer=None))
    det.fit(frame)
    assert list(det.regressor_.feature_names_in_) == names[:-1]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "X does not have valid feature names"
        monitor = StreamingMonitor(det)
        out = monitor.replay(frame.to_numpy())
    assert monitor.predictor_kind == "gaussian_process"
    assert np.array_equal(out.prediction, det.predict(frame))


def test_monitor_status_keeps_its_value_in_arrays():
    statuses = [MonitorStatus.OK, MonitorStatus.COLLISION, MonitorStatus.SENSOR_FAULT]
    assert [str(s) for s in statuses] == ["ok", "collision", "sensor_fault"]
    assert np.asarray(statuses).tolist() == ["ok", "collision", "sensor_fault"]
    assert f"{MonitorStatus.COLLISION}" == "collision"
    assert MonitorStatus("collision") is MonitorStatus.COLLISION


def test_frozen_sp_p_gets_the_compiled_path(rng):
    from sklearn.frozen import FrozenEstimator

    X, current = augmented_run(600, 2, rng)
    sp_p = small_sp_p(2).fit(X[::2], current[::2])
    det = CollisionDetector(FrozenEstimator(sp_p), n_joints=2,
                            rules=AlarmRule(contamination=0.01, filter_cutoff=8.0,
                                            min_duration=3)).fit(stack_currents(X[1::2],
                                                                                current[1::2]))
    assert det.regressor_.estimator is sp_p  # frozen: not refitted
    test_current = current.copy()
    test_current[100:140, 0] += 1.5
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no fallback to the generic path
        monitor, out = _stream_matches_batch(det, stack_currents(X, test_current))
    assert monitor.predictor_kind == "gaussian_process"
    assert np.allclose(out.residual, test_current - sp_p.predict(X), rtol=1e-7, atol=1e-7)
    assert (out.prediction[100:140] == -1).any()


@pytest.mark.parametrize("coulomb_width", [None, 0.01])
def test_compiled_rigid_body_mean_shares_one_regressor_per_tick(coulomb_width, rng):
    """SP_P with RigidBodyFeatures means: one pinocchio evaluation per tick, same numbers."""
    from sklearn_gpcd.dynamics import FrictionColumns, RigidBodyFeatures
    from sklearn_gpcd.gp import make_sp_p

    n_joints = 6
    X = rng.normal(size=(120, 6 * n_joints))
    X[::3, n_joints : 2 * n_joints] *= 1e-3  # quasi-static rows: phi-bar zeroes friction
    y = np.sin(X[:, :n_joints]) + 0.1 * np.sign(X[:, n_joints : 2 * n_joints])
    features = [RigidBodyFeatures("ur10e", joint=j, sigma_v=SIGMA_V, currents=True,
                                   friction=FrictionColumns(coulomb_width=coulomb_width))
                for j in range(n_joints)]
    gp = make_sp_p(features, n_joints, sigma_v=SIGMA_V, optimizer=None).fit(X, y)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no fallback
        predictor = compile_predictor(gp, 6 * n_joints, n_joints)
    assert predictor.kind == "gaussian_process"
    assert len(predictor.states) == 1  # every joint reads the same per-tick regressor
    got = np.array([predictor.predict_one(x, np.empty(n_joints)) for x in X[:40]])
    assert np.allclose(got, gp.predict(X[:40]), rtol=1e-9, atol=1e-9)
