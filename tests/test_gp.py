"""Tests of ``sklearn_gpcd.gp``: the semi-parametric GP regressor, its
parametric mean and the paper's estimator factories."""

import pickle
import warnings

import numpy as np
import pandas as pd
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from sklearn import config_context
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.compose import ColumnTransformer
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, WhiteKernel
from sklearn.gaussian_process.kernels import ConstantKernel as C
from sklearn.linear_model import LinearRegression
from sklearn.model_selection import GridSearchCV, KFold
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import StandardScaler

from sklearn_gpcd.gp._optimize import lbfgs_b  # the exact path's L-BFGS-B, for sklearn
from sklearn_gpcd.layout import column_index, column_names
from sklearn_gpcd.gp import (
    ParametricMean,
    SemiParametricGPRegressor,
    make_p_f,
    make_sp_p,
    make_sp_s,
)
from sklearn_gpcd.gp._posterior import _chunk_rows
from sklearn_gpcd.kernels import ARDRBF, QuasiStaticGate

# ---------------------------------------------------------------- fixtures


def smooth_problem(n=60, seed=0):
    """Two smooth targets, both depending on both inputs (so that every
    hyperparameter is identifiable and optima are compared, not plateaus)."""
    rng = np.random.RandomState(seed)
    X = rng.uniform(-3, 3, size=(n, 2))
    Y = np.column_stack(
        [
            np.sin(X[:, 0]) + 0.3 * np.cos(X[:, 1]) + 0.1 * rng.randn(n),
            X[:, 1] ** 2 / 3 + np.cos(X[:, 0]) + 0.2 * rng.randn(n) + 1.0,
        ]
    )
    return X, Y


def gated_problem(n, seed):
    """Target with a history-like term present only where |v| < 0.05."""
    rng = np.random.RandomState(seed)
    v = rng.choice([-1, 1], n) * 10 ** rng.uniform(-3, 0, n)
    X = pd.DataFrame(
        {
            "x0": rng.uniform(-2, 2, n),
            "x1": rng.uniform(-2, 2, n),
            "v": v,
            "h": rng.uniform(-1, 1, n),
        }
    )
    at_rest = np.abs(v) < 0.05
    y = np.sin(X.x0) + 0.5 * X.x1 + at_rest * 1.5 * np.sin(3 * X.h) + 0.05 * rng.randn(n)
    return X, y.to_numpy()


def gated_kernel(sigma_v=0.01):
    return (
        C(1.0) * ARDRBF([1.0, 1.0], columns=["x0", "x1"])
        + C(1.0)
        * QuasiStaticGate(ARDRBF(1.0, columns=["h"]), velocity_column="v", sigma_v=sigma_v)
        + WhiteKernel(0.1)
    )


class ToyRegressor(TransformerMixin, BaseEstimator):
    """Linear-in-parameters model of one joint of a toy robot with friction.

    ``phi_l = [qdd_l, sin(q_l), cos(q_0 + q_1), qd_0 qd_1, sign(qd_l), qd_l]``;
    the last two columns are Coulomb and viscous friction (Eq. 10).
    """

    def __init__(self, joint=0, n_joints=2):
        self.joint = joint
        self.n_joints = n_joints

    def fit(self, X, y=None):
        self.friction_columns_ = [4, 5]
        return self

    def transform(self, X):
        n, j = self.n_joints, self.joint
        q, qd, qdd = (X[:, b * n : (b + 1) * n] for b in range(3))
        return np.column_stack(
            [
                qdd[:, j],
                np.sin(q[:, j]),
                np.cos(q.sum(axis=1)),
                qd.prod(axis=1),
                np.sign(qd[:, j]),
                qd[:, j],
            ]
        )


def robot_data(n, n_joints, seed, rest_fraction=0.0, static_gain=0.0, sigma_v=None):
    """Augmented inputs (Eq. 13) and currents of the toy robot.

    Without ``sigma_v`` the currents follow Eq. 10 exactly. With it, a
    fraction of the samples is at rest (|qd| < sigma_v / 2); where |qd| <
    sigma_v the friction columns are inactive (phi-bar) and the current
    carries a history-like term ``static_gain * tanh(2 i_c)`` that the state
    x = [q, qd, qdd] cannot explain but the controller current i_c can.
    """
    rng = np.random.RandomState(seed)
    X = rng.uniform(-1.5, 1.5, size=(n, 6 * n_joints))
    qd = block(X, "qd", n_joints)
    rest = rng.uniform(size=n) < rest_fraction
    if rest.any():
        qd[rest] = rng.uniform(-sigma_v / 2, sigma_v / 2, size=(rest.sum(), n_joints))
    X[:, n_joints : 2 * n_joints] = qd
    w = np.array([[1.0, 2.0, -0.5, 0.3, 0.8, 0.4], [0.5, -1.0, 0.7, -0.2, 0.5, 0.2]])[:n_joints]
    Y = np.empty((n, n_joints))
    for j in range(n_joints):
        phi = ToyRegressor(j, n_joints).fit(X).transform(X)
        at_rest = np.abs(qd[:, j]) < (sigma_v or 0.0)
        phi[at_rest, 4:] = 0.0
        i_c = X[:, column_index("i_c", j, n_joints)]
        Y[:, j] = phi @ w[j] + at_rest * static_gain * np.tanh(2 * i_c) + 0.01 * rng.randn(n)
    return X, Y, w


def block(X, name, n_joints):
    start = column_index(name, 0, n_joints)
    return X[:, start : start + n_joints].copy()


# ------------------------------------------------- equality with sklearn GPR


@pytest.mark.parametrize(
    "kernel",
    [C(1.0) * RBF([1.0, 1.0]) + WhiteKernel(1.0), RBF(1.0) + WhiteKernel(0.5)],
    ids=["C*RBF+White", "RBF+White"],
)
@pytest.mark.parametrize("normalize_y", [False, True])
def test_matches_sklearn_gpr_per_output(kernel, normalize_y):
    X, Y = smooth_problem()
    X_test = np.random.RandomState(1).uniform(-3, 3, size=(20, 2))
    params = dict(n_restarts_optimizer=2, normalize_y=normalize_y, random_state=1)
    ours = SemiParametricGPRegressor(kernel, **params).fit(X, Y)
    mean, std = ours.predict(X_test, return_std=True)
    assert ours.n_outputs_ == 2 and mean.shape == std.shape == (20, 2)
    for j in range(2):
        ref = GaussianProcessRegressor(kernel, optimizer=lbfgs_b, **params).fit(X, Y[:, j])
        ref_mean, ref_std = ref.predict(X_test, return_std=True)
        assert_allclose(mean[:, j], ref_mean, rtol=1e-6)
        assert_allclose(std[:, j], ref_std, rtol=1e-6)
        assert_allclose(np.exp(ours.kernel_[j].theta), np.exp(ref.kernel_.theta), rtol=1e-6)
        assert_allclose(
            ours.log_marginal_likelihood_value_[j], ref.log_marginal_likelihood_value_, rtol=1e-6
        )


def test_single_output_shapes_and_cov_match_sklearn():
    X, Y = smooth_problem()
    kernel = C(1.0) * RBF(1.0) + WhiteKernel(1.0)
    ours = SemiParametricGPRegressor(kernel, random_state=0).fit(X, Y[:, 0])
    ref = GaussianProcessRegressor(kernel, optimizer=lbfgs_b, random_state=0).fit(X, Y[:, 0])
    mean, cov = ours.predict(X[:7], return_cov=True)
    ref_mean, ref_cov = ref.predict(X[:7], return_cov=True)
    assert mean.shape == (7,) and cov.shape == (7, 7)
    assert_allclose(mean, ref_mean, rtol=1e-6)
    assert_allclose(cov, ref_cov, rtol=1e-6, atol=1e-12)
    assert isinstance(ours.kernel_, type(kernel))
    assert np.ndim(ours.log_marginal_likelihood_value_) == 0
    # a 2-D y with one column is squeezed like sklearn's GPR
    two_d = SemiParametricGPRegressor(kernel, random_state=0).fit(X, Y[:, :1])
    assert two_d.predict(X[:7]).shape == (7,)
    # multi-output covariance stacks on the last axis
    multi = SemiParametricGPRegressor(kernel, random_state=0).fit(X, Y)
    assert multi.predict(X[:7], return_cov=True)[1].shape == (7, 7, 2)


def test_parametric_mean_plus_gp_on_residual():
    """y = m(x) + f(x): the GP part equals sklearn's GPR on y - m(x)."""
    X, Y = smooth_problem()
    y = Y[:, 1] + 2.0 * X[:, 0]
    kernel = C(1.0) * RBF(1.0) + WhiteKernel(1.0)
    ours = SemiParametricGPRegressor(
        kernel, mean=ParametricMean(fit_intercept=True), normalize_y=True, random_state=0
    ).fit(X, y)
    linear = LinearRegression().fit(X, y)
    assert_allclose(ours.mean_.coef_, linear.coef_, rtol=1e-8)
    ref = GaussianProcessRegressor(kernel, normalize_y=True, optimizer=lbfgs_b, random_state=0)
    ref.fit(X, y - linear.predict(X))
    X_test = X[:10] + 0.1
    mean, std = ours.predict(X_test, return_std=True)
    ref_mean, ref_std = ref.predict(X_test, return_std=True)
    assert_allclose(mean, ref_mean + linear.predict(X_test), rtol=1e-6)
    assert_allclose(std, ref_std, rtol=1e-6)


def test_log_marginal_likelihood_and_gradient():
    X, y = gated_problem(80, 0)
    gp = SemiParametricGPRegressor(gated_kernel(0.05), normalize_y=True, random_state=0).fit(X, y)
    theta = gp.kernel_.theta
    assert gp.log_marginal_likelihood() == gp.log_marginal_likelihood_value_
    assert_allclose(gp.log_marginal_likelihood(theta), gp.log_marginal_likelihood_value_)
    theta0 = theta + 0.3
    lml, grad = gp.log_marginal_likelihood(theta0, eval_gradient=True)
    eps = 1e-6
    lml_at = gp.log_marginal_likelihood
    numeric = [
        (lml_at(theta0 + eps * e) - lml_at(theta0 - eps * e)) / (2 * eps)
        for e in np.eye(len(theta0))
    ]
    assert_allclose(grad, numeric, rtol=1e-4, atol=1e-4)
    with pytest.raises(ValueError, match="theta has shape"):
        gp.log_marginal_likelihood(theta[:2])


def test_optimizer_none_and_callable():
    X, Y = smooth_problem()
    kernel = C(2.0) * RBF(0.7) + WhiteKernel(0.3)
    fixed = SemiParametricGPRegressor(kernel, optimizer=None).fit(X, Y[:, 0])
    assert_allclose(fixed.kernel_.theta, kernel.theta)
    calls = []

    def first_step(obj_func, initial_theta, bounds):
        calls.append(initial_theta)
        value, grad = obj_func(initial_theta)
        theta = np.clip(initial_theta - 0.01 * grad, bounds[:, 0], bounds[:, 1])
        return theta, obj_func(theta, eval_gradient=False)

    custom = SemiParametricGPRegressor(kernel, optimizer=first_step).fit(X, Y[:, 0])
    assert len(calls) == 1
    assert not np.allclose(custom.kernel_.theta, kernel.theta)
    assert custom.log_marginal_likelihood_value_ > fixed.log_marginal_likelihood_value_
    with pytest.raises(ValueError, match="'optimizer' parameter of .* Got 'adam_typo'"):
        SemiParametricGPRegressor(kernel, optimizer="adam_typo").fit(X, Y[:, 0])


# ------------------------------------------------------------ sigma_v tuning


def test_grid_search_over_sigma_v_picks_the_true_threshold():
    X, y = gated_problem(180, 0)
    scale = ColumnTransformer(
        [("scale", StandardScaler(), ["x0", "x1"])],
        remainder="passthrough",
        verbose_feature_names_out=False,
    ).set_output(transform="pandas")
    gp = SemiParametricGPRegressor(
        gated_kernel(), mean=ParametricMean(), normalize_y=True, random_state=0
    )
    pipe = Pipeline([("scale", scale), ("gp", gp)])
    cv = KFold(3, shuffle=True, random_state=0)
    grid = [0.005, 0.05, 0.5]
    for key in ["gp__sigma_v", "gp__kernel__k1__k2__k2__sigma_v"]:
        search = GridSearchCV(pipe, {key: grid}, cv=cv).fit(X, y)
        assert search.best_params_ == {key: 0.05}
        scores = search.cv_results_["mean_test_score"]
        assert scores[1] > max(scores[0], scores[2]) + 0.05
    # the user's kernel is never modified
    assert gp.kernel.k1.k2.k2.sigma_v == 0.01


def test_sigma_v_overrides_every_sub_object_on_clones():
    X, y = gated_problem(60, 0)
    mean = ParametricMean(lambda X: X[:, [2]], friction_columns=[0], velocity_column="v")
    kernel = gated_kernel(0.01)
    gp = SemiParametricGPRegressor(kernel, mean=mean, sigma_v=0.3, optimizer=None).fit(X, y)
    assert gp.kernel_.k1.k2.k2.sigma_v == 0.3
    assert gp.mean_.sigma_v == 0.3
    assert kernel.k1.k2.k2.sigma_v == 0.01 and mean.sigma_v is None
    assert gp.kernel_.k1.k2.k2.velocity_column == 2  # name resolved to an index
    # phi-bar: the friction column is zeroed where |v| < 0.3
    Phi = gp.mean_.design_matrix(X)
    assert_array_equal(Phi[:, 0] == 0, np.abs(X.v) < 0.3)


def test_sigma_v_without_target_is_an_error():
    X, Y = smooth_problem()
    with pytest.raises(ValueError, match="no kernel or mean has a `sigma_v`"):
        SemiParametricGPRegressor(sigma_v=0.1).fit(X, Y)


# ----------------------------------------------------- persistence, parallel


def test_pickle_round_trip_and_n_jobs_invariance():
    X, Y = smooth_problem(50)
    kernels = [C(1.0) * RBF(1.0) + WhiteKernel(1.0), RBF([1.0, 1.0]) + WhiteKernel(1.0)]
    params = dict(
        kernel=kernels, mean=ParametricMean(), n_restarts_optimizer=1, n_support=40,
        random_state=np.random.RandomState(3),
    )
    one = SemiParametricGPRegressor(n_jobs=1, **params).fit(X, Y)
    params["random_state"] = np.random.RandomState(3)
    two = SemiParametricGPRegressor(n_jobs=2, **params).fit(X, Y)
    mean, std = one.predict(X, return_std=True)
    mean2, std2 = two.predict(X, return_std=True)
    assert_allclose(mean, mean2, rtol=1e-12)
    assert_allclose(std, std2, rtol=1e-12)
    for a, b in zip(one.support_indices_, two.support_indices_):
        assert_array_equal(a, b)
    loaded = pickle.loads(pickle.dumps(one))
    assert_array_equal(loaded.predict(X), mean)
    # each output keeps its own kernel and hyperparameters
    assert one.kernel_[0].theta.shape == (3,) and one.kernel_[1].theta.shape == (3,)
    assert one.kernel_[0].k1.k2.length_scale != one.kernel_[1].k1.length_scale[0]


def test_predict_in_chunks_gives_the_same_result():
    X, Y = smooth_problem(50)
    gp = SemiParametricGPRegressor(random_state=0).fit(X, Y)
    mean, std = gp.predict(X, return_std=True)
    with config_context(working_memory=1e-3):  # 1 row per chunk
        assert _chunk_rows(row_bytes=16 * len(X)) == 1
        mean_c, std_c = gp.predict(X, return_std=True)
    assert_allclose(mean_c, mean, rtol=1e-10, atol=1e-12)
    assert_allclose(std_c, std, rtol=1e-10, atol=1e-12)


# ---------------------------------------------------------------- n_support


def test_n_support_conditions_on_the_support_rows_only():
    X, Y = smooth_problem(100)
    kernel = C(1.0) * RBF(1.0) + WhiteKernel(1.0)
    gp = SemiParametricGPRegressor(kernel, n_support=30, random_state=0).fit(X, Y[:, 0])
    support = gp.support_indices_
    assert support.shape == (30,) and len(np.unique(support)) == 30
    ref = GaussianProcessRegressor(kernel, optimizer=lbfgs_b, random_state=0)
    ref.fit(X[support], Y[support, 0])
    assert_allclose(gp.predict(X), ref.predict(X), rtol=1e-6)
    assert_allclose(np.exp(gp.kernel_.theta), np.exp(ref.kernel_.theta), rtol=1e-6)
    # changing targets outside the support changes nothing
    y_other = Y[:, 0].copy()
    y_other[np.setdiff1d(np.arange(100), support)] += 10.0
    gp_other = SemiParametricGPRegressor(kernel, n_support=30, random_state=0).fit(X, y_other)
    assert_allclose(gp_other.predict(X), gp.predict(X), rtol=1e-10)


@pytest.mark.parametrize("random_state", [None, np.random.RandomState(3), 5])
def test_random_support_is_one_draw_for_all_outputs(random_state):
    """A uniform support draw does not depend on the output: every output of a
    fit is conditioned on the same rows, whatever ``random_state``."""
    X, Y = smooth_problem(100)
    Y = np.column_stack([Y, Y[:, 0] - Y[:, 1]])
    kernels = [C(1.0) * RBF(1.0) + WhiteKernel(1.0), RBF([1.0, 1.0]) + WhiteKernel(1.0),
               C(2.0) * RBF(0.5) + WhiteKernel(0.1)]
    gp = SemiParametricGPRegressor(kernels, n_support=30, optimizer=None,
                                   random_state=random_state).fit(X, Y)
    first = gp.support_indices_[0]
    assert len(np.unique(first)) == 30
    for support in gp.support_indices_[1:]:
        assert_array_equal(support, first)
    if isinstance(random_state, int):  # still one fit per column with that seed
        for j, kernel in enumerate(kernels):
            one = SemiParametricGPRegressor(kernel, n_support=30, optimizer=None,
                                            random_state=random_state).fit(X, Y[:, j])
            assert_array_equal(one.support_indices_, first)
            assert_allclose(one.predict(X), gp.predict(X)[:, j], rtol=1e-12)


def test_greedy_support_is_deterministic_and_spreads_out():
    rng = np.random.RandomState(0)
    X = np.vstack([0.01 * rng.randn(95, 2), [[5, 5], [-5, 5], [5, -5], [-5, -5], [8, 0]]])
    y = np.sin(X[:, 0])
    params = dict(kernel=RBF(1.0) + WhiteKernel(0.1), n_support=6, optimizer=None)
    first = SemiParametricGPRegressor(support_selection="greedy", random_state=4, **params)
    second = SemiParametricGPRegressor(support_selection="greedy", random_state=4, **params)
    s1 = first.fit(X, y).support_indices_
    assert_array_equal(s1, second.fit(X, y).support_indices_)
    assert set(range(95, 100)) <= set(s1)  # every far point is chosen
    random = SemiParametricGPRegressor(support_selection="random", random_state=4, **params)
    assert len(set(random.fit(X, y).support_indices_) & set(range(95, 100))) < 5


# ---------------------------------------------------------- bad input errors


@pytest.mark.parametrize("where", ["X", "y"])
@pytest.mark.parametrize("value", [np.nan, np.inf])
def test_non_finite_input_is_rejected(where, value):
    X, Y = smooth_problem(20)
    (X if where == "X" else Y)[3, 0] = value
    with pytest.raises(ValueError, match="NaN|infinity"):
        SemiParametricGPRegressor().fit(X, Y)


def test_wrong_number_of_columns_at_predict():
    X, Y = smooth_problem(20)
    gp = SemiParametricGPRegressor(optimizer=None).fit(X, Y)
    with pytest.raises(ValueError, match="X has 3 features.*expecting 2"):
        gp.predict(np.zeros((2, 3)))


def test_unknown_column_name_in_kernel():
    X, y = gated_problem(20, 0)
    kernel = RBF(1.0) + ARDRBF(1.0, columns=["x0", "tau"])
    with pytest.raises(ValueError, match="unknown column name 'tau'"):
        SemiParametricGPRegressor(kernel).fit(X, y)


@pytest.mark.parametrize(
    "gp",
    [
        SemiParametricGPRegressor(gated_kernel(), sigma_v=0.0),
        SemiParametricGPRegressor(gated_kernel(-1.0)),
        SemiParametricGPRegressor(mean=ParametricMean(sigma_v=0.0, friction_columns=[0])),
    ],
    ids=["regressor", "kernel", "mean"],
)
def test_non_positive_sigma_v(gp):
    X, y = gated_problem(20, 0)
    with pytest.raises(ValueError, match="sigma_v(' parameter of .*)? must be"):
        gp.fit(X, y)


def test_gate_column_outside_X():
    X, Y = smooth_problem(20)
    kernel = QuasiStaticGate(RBF(1.0), velocity_column=5) + WhiteKernel()
    with pytest.raises(ValueError, match="column index 5 is outside X with 2 features"):
        SemiParametricGPRegressor(kernel).fit(X, Y)


def test_list_lengths_must_match_outputs():
    X, Y = smooth_problem(20)
    with pytest.raises(ValueError, match="kernel is a list of 3 items but y has 2 output"):
        SemiParametricGPRegressor([RBF()] * 3).fit(X, Y)
    with pytest.raises(ValueError, match="mean is a list of 1 items but y has 2 output"):
        SemiParametricGPRegressor(mean=[ParametricMean()]).fit(X, Y)


@pytest.mark.parametrize(
    "params, match",
    [
        (dict(n_support=0), "'n_support' parameter of SemiParametricGPRegressor must be"),
        (dict(support_selection="best"), "'support_selection' parameter of"),
        (dict(n_restarts_optimizer=-1), "'n_restarts_optimizer' parameter of"),
        (dict(alpha=np.ones(3)), r"alpha must be a float or an array of shape \(20,\)"),
        (dict(kernel=RBF(1.0, length_scale_bounds=(1e-5, np.inf)), n_restarts_optimizer=1),
         "requires finite bounds"),
    ],
)
def test_bad_parameters(params, match):
    X, Y = smooth_problem(20)
    with pytest.raises(ValueError, match=match):
        SemiParametricGPRegressor(**params).fit(X, Y)


def test_std_and_cov_together_is_an_error():
    X, Y = smooth_problem(20)
    gp = SemiParametricGPRegressor(optimizer=None).fit(X, Y)
    with pytest.raises(ValueError, match="At most one of return_std or return_cov"):
        gp.predict(X, return_std=True, return_cov=True)


def test_cholesky_failure_adds_jitter_and_predicts_finite_values():
    X = np.linspace(0, 1, 8)[:, None]
    y = np.arange(8.0)
    gp = SemiParametricGPRegressor(C(1.0), alpha=0.0, optimizer=None)
    with pytest.warns(RuntimeWarning, match="not positive definite; added jitter"):
        gp.fit(X, y)
    mean, std = gp.predict(X, return_std=True)
    assert np.all(np.isfinite(mean)) and np.all(np.isfinite(std))


# ---------------------------------------------------------- ParametricMean


def test_parametric_mean_ridge_and_phi_bar_by_name():
    X, y = gated_problem(50, 0)
    features = lambda X: np.column_stack([X[:, 0], np.sign(X[:, 2]), X[:, 2]])  # noqa: E731
    mean = ParametricMean(features, friction_columns=[1, 2], velocity_column="v", sigma_v=0.05)
    Phi = mean.fit(X, y).design_matrix(X)
    at_rest = np.abs(X.v.to_numpy()) < 0.05
    assert np.all(Phi[at_rest, 1:] == 0) and np.all(Phi[~at_rest, 1] != 0)
    assert_allclose(mean.coef_, np.linalg.lstsq(Phi, y, rcond=None)[0])
    ridge = ParametricMean(features, alpha=1e3).fit(X, y)
    assert np.linalg.norm(ridge.coef_) < 0.5 * np.linalg.norm(
        ParametricMean(features).fit(X, y).coef_
    )


@pytest.mark.parametrize(
    "mean, match",
    [
        (ParametricMean(lambda X: X[:, 0]), r"shape \(n_samples, n_params\)"),
        (ParametricMean(lambda X: np.where(X > 0, np.nan, X)), "features returned NaN or inf"),
        (ParametricMean(friction_columns=[7]), r"friction_columns \[7\] are outside"),
        (ParametricMean(friction_columns=[0], sigma_v=0.1), "velocity_column is required"),
        (ParametricMean(friction_columns=[0], sigma_v=0.1, velocity_column="w"),
         "velocity_column='w' is not a column"),
        (ParametricMean(alpha=-1.0), "'alpha' parameter of ParametricMean must be"),
    ],
)
def test_parametric_mean_errors(mean, match):
    X, y = gated_problem(20, 0)
    with pytest.raises(ValueError, match=match):
        mean.fit(X, y)


def test_parametric_mean_rejects_non_callable_features():
    with pytest.raises(TypeError, match="'features' parameter of ParametricMean must be"):
        ParametricMean(features=3).fit(np.ones((3, 1)), np.ones(3))


# --------------------------------------------------------------- factories


def test_p_f_recovers_the_coefficients():
    n_joints = 2
    X, Y, w = robot_data(300, n_joints, seed=0)
    features = [ToyRegressor(j, n_joints) for j in range(n_joints)]
    p_f = make_p_f(features, n_joints).fit(X, Y)
    for j in range(n_joints):
        assert_allclose(p_f.mean_[j].coef_, w[j], atol=0.01)
        assert_array_equal(p_f.mean_[j].friction_columns_, [4, 5])
    # only a WhiteKernel: the GP adds nothing to the mean, its noise is the
    # residual variance
    mean, std = p_f.predict(X, return_std=True)
    assert_allclose(mean[:, 0], p_f.mean_[0].predict(X), rtol=1e-12)
    assert_allclose(std, 0.01, rtol=0.2)


def test_sp_p_beats_sp_s_in_quasi_static_samples():
    data = dict(rest_fraction=0.5, static_gain=1.0, sigma_v=1e-2)
    X, Y, _ = robot_data(200, 1, seed=0, **data)
    X_test, Y_test, _ = robot_data(200, 1, seed=1, **data)
    features = [ToyRegressor(0, 1)]
    rest = np.abs(X_test[:, column_index("qd", 0, 1)]) < 1e-2
    errors = {}
    for name, factory in [("sp_s", make_sp_s), ("sp_p", make_sp_p)]:
        gp = factory(features, 1, random_state=0).fit(X, Y[:, 0])
        residual = gp.predict(X_test) - Y_test[:, 0]
        errors[name] = np.mean(residual[rest] ** 2) / np.var(Y_test[rest, 0])
    assert errors["sp_p"] < 0.3 * errors["sp_s"], errors
    assert errors["sp_p"] < 0.1, errors


def test_factories_share_the_augmented_layout_and_accept_no_features():
    n_joints = 2
    X, Y, _ = robot_data(40, n_joints, seed=0)
    X = pd.DataFrame(X, columns=column_names(n_joints))
    for factory in (make_p_f, make_sp_s, make_sp_p):
        gp = factory(None, n_joints, optimizer=None).fit(X, Y)
        assert gp.mean_ == [None, None]
        assert gp.predict(X).shape == (40, n_joints)
    sp_p = make_sp_p(None, n_joints, optimizer=None).fit(X, Y)
    gates = [k.k1.k1.k2 for k in sp_p.kernel_]
    assert [g.velocity_column for g in gates] == [2, 3]  # qd_0, qd_1
    with pytest.raises(ValueError, match="features has 1 entries but n_joints=2"):
        make_sp_p([ToyRegressor()], n_joints)


def test_sp_p_needs_the_augmented_columns():
    X, Y, _ = robot_data(20, 1, seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        make_sp_s(None, 1, optimizer=None).fit(X[:, :3], Y)  # state columns suffice
    with pytest.raises(ValueError, match="outside X with 3 features"):
        make_sp_p(None, 1, optimizer=None).fit(X[:, :3], Y)
