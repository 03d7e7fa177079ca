"""Numerical robustness of the GP regressor and the collision detector.

Degenerate but legal inputs (duplicated rows, constant targets, extreme
length scales and target scales, one sample, more features than samples,
gates all open or all closed) must give finite predictions and standard
deviations, and a warning where the model had to be regularised.
"""

import warnings

import numpy as np
import pytest
from sklearn.exceptions import ConvergenceWarning
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, WhiteKernel
from sklearn.gaussian_process.kernels import ConstantKernel as C
from sklearn.linear_model import Ridge

from sklearn_gpcd.layout import block_columns
from sklearn_gpcd.detection import AlarmRule, CollisionDetector, StreamingMonitor, stack_currents
from sklearn_gpcd.gp import ParametricMean, SemiParametricGPRegressor, make_sp_p, make_sp_s
from sklearn_gpcd.kernels import ARDRBF, QuasiStaticGate

N_JOINTS = 2


# ----------------------------------------------------------------- helpers
def smooth_problem(n=20, seed=0):
    rng = np.random.RandomState(seed)
    X = rng.uniform(-2, 2, size=(n, 2))
    return X, np.sin(X[:, 0]) + X[:, 1] + 0.05 * rng.randn(n)


def with_duplicates(X, y, gap, seed=0):
    """Every row twice, ``gap`` apart, with slightly different targets."""
    rng = np.random.RandomState(seed)
    return np.vstack([X, X + gap]), np.concatenate([y, y + 0.01 * rng.randn(len(y))])


def fit_quietly(estimator, *data):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return estimator.fit(*data)


def assert_finite_prediction(gp, X):
    """Mean, std and covariance at ``X`` are finite (std >= 0); returns mean, std."""
    mean, std = gp.predict(X, return_std=True)
    _, cov = gp.predict(X, return_cov=True)
    assert np.all(np.isfinite(mean)), "NaN or inf in the predicted mean"
    assert np.all(np.isfinite(std)) and np.all(std >= 0), "bad predicted std"
    assert np.all(np.isfinite(cov)), "NaN or inf in the predicted covariance"
    return mean, std


def augmented_inputs(n, rng, qd=None):
    """x^a (Eq. 13) for N_JOINTS joints; ``qd`` overrides the velocity block."""
    X = rng.uniform(-1, 1, size=(n, 6 * N_JOINTS))
    if qd is not None:
        X[:, block_columns("qd", N_JOINTS)] = qd
    Y = np.column_stack([np.sin(X[:, j]) + 0.3 * X[:, 5 * N_JOINTS + j] for j in range(N_JOINTS)])
    return X, Y + 0.01 * rng.normal(size=Y.shape)


# ------------------------------------------------- duplicated input rows
@pytest.mark.parametrize("gap", [0.0, 1e-12], ids=["exact", "near"])
@pytest.mark.parametrize("optimizer", [None, "fmin_l_bfgs_b"])
def test_duplicated_inputs_without_noise_add_jitter_with_a_warning(gap, optimizer):
    X, y = with_duplicates(*smooth_problem(), gap)
    gp = SemiParametricGPRegressor(C(1.0) * RBF([1.0, 1.0]), alpha=0.0, optimizer=optimizer)
    with pytest.warns(RuntimeWarning, match="not positive definite; added jitter"):
        gp.fit(X, y)
    mean, _ = assert_finite_prediction(gp, X)
    # each duplicated pair is predicted between (near) its two targets
    pair_mean, half_gap = (y[:20] + y[20:]) / 2, np.abs(y[:20] - y[20:]) / 2
    assert np.all(np.abs(mean[:20] - pair_mean) <= half_gap + 1e-3)


@pytest.mark.parametrize("gap", [0.0, 1e-12], ids=["exact", "near"])
@pytest.mark.parametrize("alpha", [1e-15, 1e-10])
def test_duplicated_inputs_with_tiny_alpha_predict_finite_values(gap, alpha):
    X, y = with_duplicates(*smooth_problem(), gap)
    gp = fit_quietly(SemiParametricGPRegressor(C(1.0) * RBF([1.0, 1.0]), alpha=alpha,
                                               optimizer=None), X, y)
    mean, _ = assert_finite_prediction(gp, X)
    pair_mean, half_gap = (y[:20] + y[20:]) / 2, np.abs(y[:20] - y[20:]) / 2
    # alpha=1e-15 conditions K to ~1e15: round-off of a few 1e-3 is expected
    tolerance = 1e-3 if alpha >= 1e-10 else 0.05
    assert np.all(np.abs(mean[:20] - pair_mean) <= half_gap + tolerance)


@pytest.mark.filterwarnings("ignore:Predicted variances smaller than 0")
def test_near_duplicates_with_a_short_length_scale_match_sklearn():
    X, y = with_duplicates(*smooth_problem(), gap=1e-12)
    kernel = C(1.0) * RBF([1e-5, 1e-5], "fixed")  # default alpha=1e-10
    ours = SemiParametricGPRegressor(kernel, optimizer=None).fit(X, y)
    reference = GaussianProcessRegressor(kernel, optimizer=None).fit(X, y)
    mean, _ = assert_finite_prediction(ours, X)
    assert_allclose(mean, reference.predict(X), atol=1e-4)


def test_singular_kernel_matrix_still_reports_a_finite_log_marginal_likelihood():
    X, y = with_duplicates(*smooth_problem(), gap=0.0)
    gp = SemiParametricGPRegressor(C(1.0) * RBF([1.0, 1.0]), alpha=0.0)
    with pytest.warns(ConvergenceWarning, match="singular at every theta"):
        gp.fit(X, y)
    assert np.isfinite(gp.log_marginal_likelihood_value_)


# ------------------------------------------------------- constant targets
@pytest.mark.parametrize("normalize_y", [False, True])
@pytest.mark.parametrize("value", [0.0, 3.0])
@pytest.mark.parametrize(
    "kernel", [None, C(1.0) * ARDRBF([1.0, 1.0]) + WhiteKernel(1.0)], ids=["default", "ard"]
)
def test_constant_targets_predict_the_constant(kernel, value, normalize_y):
    X, _ = smooth_problem()
    y = np.full(len(X), value)
    gp = fit_quietly(SemiParametricGPRegressor(kernel, normalize_y=normalize_y,
                                               random_state=0), X, y)
    inside = np.clip(X + 0.1, -2, 2)
    for rows in (X, inside):
        mean, std = assert_finite_prediction(gp, rows)
        if normalize_y:  # standardised targets are all 0: exactly the mean back
            assert_array_equal(mean, value)
        else:
            assert_allclose(mean, value, atol=1e-4 * max(value, 1.0))
        assert np.all(std < 0.05)  # the optimiser learns there is no noise


@pytest.mark.parametrize("normalize_y", [False, True])
def test_constant_targets_with_a_parametric_mean(normalize_y):
    X, _ = smooth_problem()
    gp = SemiParametricGPRegressor(mean=ParametricMean(fit_intercept=True),
                                   normalize_y=normalize_y, random_state=0)
    fit_quietly(gp, X, np.full(len(X), -2.5))
    mean, _ = assert_finite_prediction(gp, X)
    assert_allclose(mean, -2.5, atol=1e-6)
    assert_allclose(gp.mean_.coef_[:2], 0.0, atol=1e-9)


# --------------------------------------------------- extreme length scales
@pytest.mark.parametrize("length_scale", [1e-5, 1e5])
@pytest.mark.parametrize("noise", [None, 1e-2], ids=["noise-free", "white"])
@pytest.mark.parametrize("rbf", [RBF, ARDRBF])
def test_fixed_extreme_length_scales_predict_finite_values(rbf, noise, length_scale):
    X, y = smooth_problem()
    kernel = C(1.0) * rbf([length_scale, length_scale], length_scale_bounds="fixed")
    if noise is not None:
        kernel = kernel + WhiteKernel(noise)
    gp = fit_quietly(SemiParametricGPRegressor(kernel, random_state=0), X, y)
    far = X + 0.5
    assert_finite_prediction(gp, far)
    mean, std = assert_finite_prediction(gp, X)
    if length_scale == 1e-5:  # every point is alone: prior mean and std away from data
        amplitude = gp.kernel_.k1.k1.constant_value if noise else gp.kernel_.k1.constant_value
        far_mean, far_std = gp.predict(far, return_std=True)
        assert_allclose(far_mean, 0.0, atol=1e-12)
        noise_var = gp.kernel_.k2.noise_level if noise else 0.0
        assert_allclose(far_std, np.sqrt(amplitude + noise_var), rtol=1e-6)


def test_length_scales_optimised_to_their_bounds():
    rng = np.random.RandomState(1)
    X, _ = smooth_problem(40)
    bounds = (1e-5, 1e5)
    # an irrelevant second input drives its length scale to the upper bound
    y = np.sin(X[:, 0])
    gp = fit_quietly(SemiParametricGPRegressor(
        C(1.0) * ARDRBF([1.0, 1.0], length_scale_bounds=bounds) + WhiteKernel(1e-2),
        random_state=0), X, y)
    assert gp.kernel_.k1.k2.length_scale[1] == pytest.approx(1e5, rel=1e-6)
    X_test = rng.uniform(-2, 2, size=(50, 2))
    mean, _ = assert_finite_prediction(gp, X_test)
    assert_allclose(mean, np.sin(X_test[:, 0]), atol=0.05)
    # white-noise targets without a noise kernel drive one to the lower bound
    gp = fit_quietly(SemiParametricGPRegressor(
        C(1.0) * ARDRBF([1.0, 1.0], length_scale_bounds=bounds), random_state=0),
        X, rng.randn(len(X)))
    assert gp.kernel_.k2.length_scale.min() == pytest.approx(1e-5, rel=1e-6)
    assert_finite_prediction(gp, X_test)


def test_optimizer_started_at_the_bounds_predicts_finite_values():
    X, y = smooth_problem()
    kernel = C(1e5, (1e-5, 1e5)) * RBF([1e-5, 1e5], (1e-5, 1e5)) + WhiteKernel(1e-5, (1e-5, 1e5))
    gp = fit_quietly(SemiParametricGPRegressor(kernel, n_restarts_optimizer=2,
                                               random_state=0), X, y)
    assert_finite_prediction(gp, X + 0.3)


# ------------------------------------------------------------ target scale
@pytest.mark.parametrize("scale", [1e6, 1e-6])
@pytest.mark.parametrize("mean", [None, ParametricMean()], ids=["no-mean", "mean"])
@pytest.mark.parametrize(
    "kernel", [None, C(1.0) * ARDRBF([1.0, 1.0]) + WhiteKernel(1.0)], ids=["default", "ard"]
)
def test_normalized_fit_is_equivariant_to_the_target_scale(kernel, mean, scale):
    X, y = smooth_problem(30)
    X_test = np.random.RandomState(1).uniform(-2, 2, size=(10, 2))
    params = dict(kernel=kernel, mean=mean, normalize_y=True, random_state=0)
    base = fit_quietly(SemiParametricGPRegressor(**params), X, y)
    scaled = fit_quietly(SemiParametricGPRegressor(**params), X, scale * y)
    mean0, std0 = base.predict(X_test, return_std=True)
    mean1, std1 = assert_finite_prediction(scaled, X_test)
    assert_allclose(mean1 / scale, mean0, rtol=1e-7, atol=1e-7 * np.abs(mean0).max())
    assert_allclose(std1 / scale, std0, rtol=1e-6)


@pytest.mark.parametrize("scale", [1e6, 1e-6])
def test_unnormalized_extreme_target_scales_predict_finite_values(scale):
    X, y = smooth_problem()
    gp = fit_quietly(SemiParametricGPRegressor(random_state=0), X, scale * y)
    assert_finite_prediction(gp, X + 0.1)


# ------------------------------------------------ tiny and wide problems
@pytest.mark.parametrize("normalize_y", [False, True])
@pytest.mark.parametrize("mean", [None, ParametricMean()], ids=["no-mean", "mean"])
def test_single_training_sample(mean, normalize_y):
    X, y = smooth_problem()
    gp = fit_quietly(SemiParametricGPRegressor(mean=mean, normalize_y=normalize_y,
                                               random_state=0), X[:1], y[:1])
    pred, _ = assert_finite_prediction(gp, X)
    if normalize_y and mean is None:  # one target: its value everywhere
        assert_array_equal(pred, y[0])
    elif mean is not None:  # the mean fits one row exactly
        assert pred[0] == pytest.approx(y[0], abs=1e-3)
    else:  # zero prior mean: shrunk towards 0 as far as the fitted noise says
        assert 0 < pred[0] / y[0] <= 1 + 1e-9


def test_single_sample_sp_p_with_more_support_than_rows():
    rng = np.random.default_rng(0)
    X, Y = augmented_inputs(1, rng)
    gp = fit_quietly(make_sp_p(None, N_JOINTS, n_support=50, random_state=0), X, Y)
    assert_array_equal(gp.support_indices_[0], [0])
    X_test, _ = augmented_inputs(5, rng)
    mean, _ = assert_finite_prediction(gp, X_test)
    assert mean.shape == (5, N_JOINTS)


@pytest.mark.parametrize("with_mean", [False, True])
def test_more_features_than_samples(with_mean):
    rng = np.random.RandomState(0)
    X = rng.randn(5, 30)
    y = X[:, 0] - 0.5 * X[:, 1]
    kernel = C(1.0) * ARDRBF(np.ones(30)) + WhiteKernel(1.0)
    mean = ParametricMean(alpha=1e-6) if with_mean else None
    gp = fit_quietly(SemiParametricGPRegressor(kernel, mean=mean, normalize_y=True,
                                               random_state=0), X, y)
    assert_finite_prediction(gp, rng.randn(8, 30))
    sp_s = fit_quietly(make_sp_s(None, 5, random_state=0), X, np.column_stack([y] * 5))
    assert_finite_prediction(sp_s, rng.randn(8, 30))


# ------------------------------------------------- quasi-static gate (SP_P)
@pytest.mark.parametrize("training", ["all-static", "none-static"])
def test_sp_p_with_every_gate_open_or_closed(training):
    rng = np.random.default_rng(0)
    qd = 0.0 if training == "all-static" else rng.choice([-1, 1], (60, N_JOINTS)) * 0.5
    X, Y = augmented_inputs(60, rng, qd=qd)
    gp = fit_quietly(make_sp_p(None, N_JOINTS, random_state=0), X, Y)
    for query_qd in (0.0, 0.5):  # gates open, gates closed
        X_test, _ = augmented_inputs(20, rng, qd=query_qd)
        assert_finite_prediction(gp, X_test)
    mean, _ = assert_finite_prediction(gp, X)
    assert np.mean((mean - Y) ** 2) < 0.1 * np.var(Y)
    if training == "none-static":  # no gated pair: the static part has no gradient
        initial = make_sp_p(None, N_JOINTS).kernel[0].k1.k1.k2.kernel.length_scale
        fitted = gp.kernel_[0].k1.k1.k2.kernel.length_scale
        assert_array_equal(fitted, initial)


def test_gated_kernel_with_extreme_length_scales():
    rng = np.random.default_rng(1)
    X, Y = augmented_inputs(40, rng, qd=np.where(rng.random((40, N_JOINTS)) < 0.5, 0.0, 0.3))
    for length_scale in (1e-5, 1e5):
        kernel = C(1.0) * QuasiStaticGate(
            ARDRBF(length_scale, length_scale_bounds="fixed"), velocity_column=N_JOINTS,
            sigma_v=1e-2,
        ) + WhiteKernel(1e-2)
        gp = fit_quietly(SemiParametricGPRegressor(kernel, random_state=0), X, Y[:, 0])
        assert_finite_prediction(gp, X)


# -------------------------------------------------- never NaN (property)
@settings(max_examples=40, deadline=None)
@given(
    n_samples=st.integers(1, 12),
    n_features=st.integers(1, 3),
    duplicates=st.integers(0, 4),
    log_scale=st.floats(-6, 6),
    alpha=st.sampled_from([0.0, 1e-15, 1e-10]),
    normalize_y=st.booleans(),
    optimize=st.booleans(),
    seed=st.integers(0, 2**16),
)
def test_predictions_are_never_nan(n_samples, n_features, duplicates, log_scale, alpha,
                                   normalize_y, optimize, seed):
    rng = np.random.RandomState(seed)
    X = rng.uniform(-3, 3, size=(n_samples, n_features))
    rows = rng.randint(0, n_samples, duplicates)
    X = np.vstack([X, X[rows] + rng.choice([0.0, 1e-12], size=(duplicates, 1))])
    y = 10.0**log_scale * (np.sin(X.sum(axis=1)) + 0.1 * rng.randn(len(X)))
    gp = SemiParametricGPRegressor(
        C(1.0) * RBF(np.ones(n_features)) + WhiteKernel(1e-3), alpha=alpha,
        normalize_y=normalize_y, optimizer="fmin_l_bfgs_b" if optimize else None,
        random_state=0,
    )
    fit_quietly(gp, X, y)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # negative variances clipped: fine here
        assert_finite_prediction(gp, rng.uniform(-4, 4, size=(5, n_features)))


# ---------------------------------------------------------- the detector
@pytest.mark.parametrize("threshold", ["contamination", "false_alarm_rate", "std"])
def test_detector_on_constant_currents(threshold):
    rng = np.random.default_rng(0)
    X, _ = augmented_inputs(80, rng)
    current = np.full((80, N_JOINTS), 1.5)
    regressor = make_sp_p(None, N_JOINTS, n_support=40, random_state=0)
    det = CollisionDetector(regressor, n_joints=N_JOINTS, rules=AlarmRule(threshold=threshold))
    fit_quietly(det, stack_currents(X, current))
    assert np.all(np.isfinite(det.scale_)) and np.all(det.scale_ > 0)
    assert np.isfinite(det.offset_)
    Z = stack_currents(X, current)
    assert np.all(np.isfinite(det.decision_function(Z)))
    assert np.all(det.predict(Z) == 1)  # the training currents are no collision
    hit = current.copy()
    hit[10:20, 0] += 1.0
    assert np.all(det.predict(stack_currents(X, hit))[10:20] == -1)


@pytest.mark.parametrize("n_rows", [1, 2, 3])
@pytest.mark.parametrize("threshold", ["contamination", "false_alarm_rate", "std"])
def test_detector_on_a_tiny_training_set(n_rows, threshold):
    rng = np.random.default_rng(0)
    X, Y = augmented_inputs(60, rng)
    det = CollisionDetector(make_sp_p(None, N_JOINTS, random_state=0), n_joints=N_JOINTS,
                            rules=AlarmRule(threshold=threshold, filter_cutoff=5.0,
                                            min_duration=2))
    fit_quietly(det, stack_currents(X[:n_rows], Y[:n_rows]))
    assert np.all(np.isfinite(det.scale_)) and np.isfinite(det.offset_)
    Z = stack_currents(X[n_rows:], Y[n_rows:])  # rows the fit has not seen
    assert np.all(np.isfinite(det.decision_function(Z)))
    batch = det.predict(Z)
    assert_array_equal(StreamingMonitor(det).replay(Z).prediction, batch)


def test_no_training_sample_sits_exactly_on_the_false_alarm_level():
    rng = np.random.default_rng(0)
    X, Y = augmented_inputs(10, rng)
    det = CollisionDetector(make_sp_p(None, N_JOINTS, random_state=0), n_joints=N_JOINTS,
                            rules=AlarmRule(threshold="false_alarm_rate", filter_cutoff=5.0,
                                            min_duration=2))
    Z = stack_currents(X, Y)
    fit_quietly(det, Z)
    assert not np.any(-det.score_samples(Z) == -det.offset_)


def test_detector_with_a_linear_model_on_constant_currents():
    X = np.linspace(-1, 1, 50)[:, None]
    det = CollisionDetector(Ridge(),
                            rules=AlarmRule(contamination=0.01)).fit(stack_currents(X,
                                                                                    np.ones(50)))
    assert np.isfinite(det.scale_[0]) and det.scale_[0] > 0
    assert np.all(det.predict(stack_currents(X, np.ones(50))) == 1)
    assert det.predict(stack_currents(X[:1], [1.5]))[0] == -1
