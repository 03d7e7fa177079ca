"""Tests of sklearn_gpcd.kernels: gradients, contraction, sklearn protocol."""

import pickle
import tracemalloc

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from sklearn.base import clone
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, Matern, WhiteKernel
from sklearn.gaussian_process.kernels import ConstantKernel as C
from sklearn.preprocessing import PolynomialFeatures, StandardScaler

from sklearn_gpcd.gp._optimize import lbfgs_b  # the exact path's L-BFGS-B, for sklearn
from sklearn_gpcd.kernels import (
    ARDRBF,
    ParametricKernel,
    QuasiStaticGate,
    contract_gradient,
    resolve_columns,
)

SIGMA_V = 0.01
VELOCITY = 1  # column of X holding the gated joint velocity
N_FEATURES = 4


def poly_features(X):
    """A module-level feature map (picklable), 4 regressors."""
    X = np.asarray(X, dtype=float)
    return np.column_stack([np.ones(len(X)), X[:, 0], X[:, 2] ** 2, np.sin(X[:, 3])])


def friction_features(X):
    """sign(qd) and qd of the gated joint, as the friction columns of Eq. 10."""
    qd = np.asarray(X, dtype=float)[:, VELOCITY]
    return np.column_stack([np.sign(qd), qd])


def first_column(X):
    """A wrong feature map: 1-D instead of (n_samples, n_params)."""
    return np.asarray(X)[:, 0]


class RecordingRBF(RBF):
    """RBF that records the numbers of rows it is evaluated on."""

    calls = []

    def __call__(self, X, Y=None, eval_gradient=False):
        RecordingRBF.calls.append((len(X), None if Y is None else len(Y)))
        return super().__call__(X, Y, eval_gradient)

    def diag(self, X):
        RecordingRBF.calls.append((len(X), "diag"))
        return super().diag(X)


class SubclassedARDRBF(ARDRBF):
    """A subclass may change __call__, so contract_gradient must fall back."""


def make_X(rng, n=30):
    """Random inputs; velocities at least a factor 2 away from sigma_v."""
    X = rng.normal(size=(n, N_FEATURES))
    still = np.arange(n) % 3 == 0
    X[still, VELOCITY] = rng.uniform(-0.5, 0.5, still.sum()) * SIGMA_V
    moving = ~still
    X[moving, VELOCITY] = rng.choice([-1, 1], moving.sum()) * rng.uniform(
        2 * SIGMA_V, 1.0, moving.sum()
    )
    return X


def gated_ard():
    return QuasiStaticGate(
        ARDRBF([0.8, 1.3, 2.1], columns=[0, 2, 3]),
        velocity_column=VELOCITY,
        sigma_v=SIGMA_V,
    )


KERNELS = {
    "ard_isotropic": lambda: ARDRBF(1.3),
    "ard_columns": lambda: ARDRBF([0.7, 1.5, 2.5], columns=[0, 2, 3]),
    "ard_isotropic_columns": lambda: ARDRBF(0.9, columns=[3, 0]),
    "C*ard+white": lambda: C(1.7) * ARDRBF([0.5, 1.0, 1.5, 2.0]) + WhiteKernel(0.3),
    "gate": gated_ard,
    "paper_composition": lambda: (
        C(2.0) * gated_ard()
        + C(0.5) * ARDRBF([1.1, 0.6], columns=[0, 1])
        + ParametricKernel(poly_features, prior_cov=[0.5, 2.0, 1.5, 0.7])
    ),
    "parametric*rbf": lambda: ParametricKernel(poly_features, 1.5) * RBF(1.2),
    "friction": lambda: ParametricKernel(friction_features, [0.3, 2.0]) + WhiteKernel(),
    "fixed_parts": lambda: (
        C(2.0, "fixed") * ARDRBF([1.0, 2.0], [0, 3], length_scale_bounds="fixed")
        + ParametricKernel(poly_features, 1.0, "fixed")
        + C(0.7)
        * QuasiStaticGate(ARDRBF(1.0, length_scale_bounds="fixed"), VELOCITY, SIGMA_V)
        + WhiteKernel(0.2)
    ),
    "gate_of_product": lambda: QuasiStaticGate(
        C(1.5) * ARDRBF([1.0, 2.0], columns=[2, 3]) * RBF(2.0), VELOCITY, SIGMA_V
    ),
    "exponentiation": lambda: ARDRBF([1.0, 2.0, 0.5, 1.5]) ** 2 + C(0.1),
}


@pytest.fixture(params=sorted(KERNELS))
def kernel(request):
    return KERNELS[request.param]()


def finite_difference_gradient(kernel, X, step=1e-5):
    """Central differences of K with respect to theta."""
    theta = kernel.theta
    gradient = np.empty(X.shape[:1] * 2 + theta.shape)
    for k in range(theta.size):
        shift = np.zeros_like(theta)
        shift[k] = step
        K_plus = kernel.clone_with_theta(theta + shift)(X)
        K_minus = kernel.clone_with_theta(theta - shift)(X)
        gradient[:, :, k] = (K_plus - K_minus) / (2 * step)
    return gradient


# -- gradients ------------------------------------------------------------


def test_gradient_matches_finite_differences(kernel, rng):
    X = make_X(rng)
    K, K_gradient = kernel(X, eval_gradient=True)
    assert K_gradient.shape == (len(X), len(X), kernel.n_dims)
    assert_allclose(K, kernel(X), rtol=1e-12)
    reference = finite_difference_gradient(kernel, X)
    assert_allclose(K_gradient, reference, rtol=1e-5, atol=1e-9 * np.abs(K).max())
    if kernel.n_dims:  # the check is meaningful: the gradient is not all zero
        assert np.abs(K_gradient).max() > 1e-3


def test_contract_gradient_matches_einsum(kernel, rng):
    X = make_X(rng, n=40)
    W = rng.normal(size=(40, 40))  # general, not symmetric
    reference = np.einsum("ij,ijk->k", W, kernel(X, eval_gradient=True)[1])
    got = contract_gradient(kernel, X, W)
    assert got.shape == kernel.theta.shape
    atol = 1e-12 * np.abs(reference).max(initial=1.0)
    assert_allclose(got, reference, rtol=1e-10, atol=atol)


@pytest.mark.parametrize(
    "kernel",
    [
        Matern([1.0, 2.0, 3.0, 4.0], nu=2.5) * ARDRBF(1.0) + WhiteKernel(),
        SubclassedARDRBF(2.0),
    ],
    ids=["matern", "subclass"],
)
def test_contract_gradient_falls_back_for_unsupported_kernels(kernel, rng):
    X = make_X(rng)
    W = rng.normal(size=(len(X), len(X)))
    reference = np.einsum("ij,ijk->k", W, kernel(X, eval_gradient=True)[1])
    assert_allclose(contract_gradient(kernel, X, W), reference, rtol=1e-10)


def test_contract_gradient_gives_sklearn_lml_gradient(rng):
    X = make_X(rng, n=50)
    y = np.sin(X[:, 0]) + X[:, 2] + 0.1 * rng.normal(size=50)
    kernel = KERNELS["paper_composition"]() + WhiteKernel(0.1)
    gpr = GaussianProcessRegressor(kernel, optimizer=None).fit(X, y)
    _, lml_gradient = gpr.log_marginal_likelihood(kernel.theta, eval_gradient=True)
    K = kernel(X) + gpr.alpha * np.eye(len(X))
    K_inv = np.linalg.inv(K)
    alpha = K_inv @ y
    got = 0.5 * contract_gradient(kernel, X, np.outer(alpha, alpha) - K_inv)
    assert_allclose(got, lml_gradient, rtol=1e-7)


def test_gaussian_process_regressor_optimizes_our_kernels(rng):
    X = make_X(rng, n=40)
    y = np.sin(2 * X[:, 0]) + 0.5 * X[:, 3] + 0.05 * rng.normal(size=40)
    kernel = C(1.0) * ARDRBF([1.0, 1.0], columns=[0, 3]) + WhiteKernel(0.5)
    gpr = GaussianProcessRegressor(kernel, optimizer=lbfgs_b, random_state=0).fit(X, y)
    initial = gpr.log_marginal_likelihood(kernel.theta)
    assert gpr.log_marginal_likelihood_value_ > initial
    assert isinstance(gpr.kernel_.k1.k2, ARDRBF)
    assert gpr.predict(X[:3]).shape == (3,)


def test_contract_gradient_rejects_wrong_weight_shape(rng):
    with pytest.raises(ValueError, match=r"W must have shape .*\(5, 5\)"):
        contract_gradient(ARDRBF(), rng.normal(size=(5, 2)), np.eye(4))


def test_contract_gradient_memory_is_quadratic(rng):
    n, d = 1000, 18
    X = rng.normal(size=(n, d))
    W = rng.normal(size=(n, n))
    kernel = C(1.5) * ARDRBF(np.linspace(1.0, 4.0, d)) + WhiteKernel(0.1)
    tracemalloc.start()
    gradient = contract_gradient(kernel, X, W)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert gradient.shape == (d + 2,)
    # a few (n, n) float arrays; the (n, n, d) gradient alone would be d of them
    assert peak < 5 * n * n * 8


@pytest.mark.parametrize("gated", [False, True], ids=["c-ard-white", "with-gate"])
def test_fit_likelihood_gradient_memory_is_quadratic(gated, rng):
    # the path the regressor's fit runs: the compiled plan, evaluation after evaluation
    from sklearn_gpcd.gp._likelihood import _log_marginal_likelihood
    from sklearn_gpcd.kernels.plan import compile_kernel

    n, d = 1000, 18
    X, y = rng.normal(size=(n, d)), rng.normal(size=n)
    kernel = C(1.5) * ARDRBF(np.linspace(1.0, 4.0, d)) + WhiteKernel(0.1)
    if gated:
        kernel = kernel + C(0.5) * QuasiStaticGate(ARDRBF(np.ones(d)), 0, sigma_v=0.5)
    plan = compile_kernel(kernel)
    _log_marginal_likelihood(kernel.theta, kernel, X, y, 1e-10, True, plan)  # arrays kept
    tracemalloc.start()
    _, gradient = _log_marginal_likelihood(kernel.theta, kernel, X, y, 1e-10, True, plan)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert gradient.shape == kernel.theta.shape
    # a few (n, n) float arrays at most; the (n, n, n_theta) gradient would be 20 or 39
    assert peak < 4 * n * n * 8


@pytest.mark.slow
def test_contract_gradient_memory_at_n3000(rng):
    n, d = 3000, 18
    X = rng.normal(size=(n, d))
    W = rng.normal(size=(n, n))
    kernel = C(1.5) * ARDRBF(np.linspace(1.0, 4.0, d)) + WhiteKernel(0.1)
    tracemalloc.start()
    gradient = contract_gradient(kernel, X, W)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert np.all(np.isfinite(gradient))
    assert peak < 5 * n * n * 8


# -- kernel protocol --------------------------------------------------------


def test_diag_equals_diagonal_of_K(kernel, rng):
    X = make_X(rng)
    assert_allclose(kernel.diag(X), np.diag(kernel(X)), rtol=1e-12, atol=1e-15)


def test_cross_kernel_shape_and_symmetry(kernel, rng):
    X, Y = make_X(rng, n=12), make_X(rng, n=7)
    K_xy = kernel(X, Y)
    assert K_xy.shape == (12, 7)
    assert_allclose(K_xy, kernel(Y, X).T, rtol=1e-12, atol=1e-15)
    K = kernel(X)
    assert_allclose(K, K.T, rtol=1e-12, atol=1e-15)
    if not any(isinstance(k, WhiteKernel) for k in _nodes(kernel)):
        assert_allclose(kernel(X, X), K, rtol=1e-12, atol=1e-15)
    with pytest.raises(ValueError, match="Y is None"):
        kernel(X, Y, eval_gradient=True)


def _nodes(kernel):
    return [kernel] + [v for v in kernel.get_params().values() if hasattr(v, "theta")]


def test_clone_with_theta_round_trip(kernel, rng):
    X = make_X(rng)
    theta = kernel.theta
    shifted = theta + np.linspace(-0.3, 0.4, theta.size)
    other = kernel.clone_with_theta(shifted)
    assert_allclose(other.theta, shifted, rtol=1e-12)
    assert_allclose(kernel.theta, theta)  # the original is untouched
    assert_allclose(other.clone_with_theta(theta)(X), kernel(X), rtol=1e-12)
    assert not np.allclose(other(X), kernel(X))


def test_clone_and_pickle_round_trip(kernel, rng):
    X = make_X(rng)
    for copy in (clone(kernel), pickle.loads(pickle.dumps(kernel))):
        assert copy is not kernel
        assert repr(copy) == repr(kernel)
        assert_array_equal(copy.theta, kernel.theta)
        assert_allclose(copy(X), kernel(X), rtol=1e-14)


def test_hyperparameters_describe_theta(kernel):
    hyperparameters = kernel.hyperparameters
    n_free = sum(h.n_elements for h in hyperparameters if not h.fixed)
    assert n_free == kernel.theta.size > 0
    assert kernel.bounds.shape == (n_free, 2)
    params = kernel.get_params()
    assert all(h.name in params for h in hyperparameters)


def test_hyperparameter_names():
    kernel = KERNELS["paper_composition"]()
    names = [h.name for h in kernel.hyperparameters]
    assert names == [
        "k1__k1__k1__constant_value",
        "k1__k1__k2__kernel__length_scale",
        "k1__k2__k1__constant_value",
        "k1__k2__k2__length_scale",
        "k2__prior_cov",
    ]
    assert kernel.theta.size == 1 + 3 + 1 + 2 + 4


def test_get_and_set_params():
    ard = ARDRBF([1.0, 2.0], columns=[0, 3])
    assert ard.get_params() == {
        "length_scale": [1.0, 2.0],
        "columns": [0, 3],
        "length_scale_bounds": (1e-5, 1e5),
    }
    gate = QuasiStaticGate(C(2.0) * ard, VELOCITY, SIGMA_V)
    params = gate.get_params()
    assert params["kernel__k2__columns"] == [0, 3]
    assert params["sigma_v"] == SIGMA_V and params["velocity_column"] == VELOCITY
    gate.set_params(kernel__k2__length_scale=[3.0, 4.0], kernel__k1__constant_value=5.0)
    assert_allclose(gate.theta, np.log([5.0, 3.0, 4.0]))
    parametric = ParametricKernel(PolynomialFeatures(2))
    parametric.set_params(features__degree=1, prior_cov=3.0)
    assert parametric.features.degree == 1 and parametric.prior_cov == 3.0
    with pytest.raises(ValueError, match="Invalid parameter"):
        gate.set_params(velocity=3)


def test_stationarity_flags():
    assert ARDRBF().is_stationary()
    assert (C() * ARDRBF() + WhiteKernel()).is_stationary()
    assert not gated_ard().is_stationary()
    assert not ParametricKernel(poly_features).is_stationary()


def test_grid_search_can_reach_sigma_v():
    gpr = GaussianProcessRegressor(C() * gated_ard() + WhiteKernel())
    assert "kernel__k1__k2__sigma_v" in gpr.get_params()
    gpr.set_params(kernel__k1__k2__sigma_v=0.5)
    assert gpr.kernel.k1.k2.sigma_v == 0.5


# -- ARDRBF -----------------------------------------------------------------


@pytest.mark.parametrize("columns", [None, [0, 1, 2, 3]])
def test_ardrbf_on_all_columns_equals_sklearn_rbf(columns, rng):
    X, Y = make_X(rng), make_X(rng, n=5)
    length_scale = [0.5, 1.0, 2.0, 4.0]
    ours, theirs = ARDRBF(length_scale, columns=columns), RBF(length_scale)
    K, K_gradient = ours(X, eval_gradient=True)
    K_ref, K_gradient_ref = theirs(X, eval_gradient=True)
    assert_allclose(K, K_ref, rtol=1e-13)
    assert_allclose(K_gradient, K_gradient_ref, rtol=1e-12, atol=1e-15)
    assert_allclose(ours(X, Y), theirs(X, Y), rtol=1e-13)
    assert_array_equal(ours.theta, theirs.theta)
    assert_array_equal(ours.bounds, theirs.bounds)


def test_ardrbf_columns_equal_rbf_on_the_subset(rng):
    X = make_X(rng)
    ours = ARDRBF([0.5, 3.0], columns=[3, 1])
    K, K_gradient = ours(X, eval_gradient=True)
    K_ref, K_gradient_ref = RBF([0.5, 3.0])(X[:, [3, 1]], eval_gradient=True)
    assert_allclose(K, K_ref, rtol=1e-13)
    assert_allclose(K_gradient, K_gradient_ref, rtol=1e-12, atol=1e-15)


def test_ardrbf_fixed_length_scale_has_no_theta(rng):
    kernel = ARDRBF([1.0, 2.0], columns=[0, 1], length_scale_bounds="fixed")
    X = make_X(rng)
    assert kernel.theta.size == 0 and kernel.bounds.size == 0
    assert kernel(X, eval_gradient=True)[1].shape == (len(X), len(X), 0)


def test_ardrbf_resolves_names_on_dataframes(rng):
    pd = pytest.importorskip("pandas")
    X = make_X(rng)
    frame = pd.DataFrame(X, columns=["q_0", "qd_0", "qdd_0", "i_c_0"])
    by_name = ARDRBF([0.5, 2.0], columns=["i_c_0", "q_0"])
    assert_allclose(by_name(frame), ARDRBF([0.5, 2.0], columns=[3, 0])(X), rtol=1e-14)
    gate = QuasiStaticGate(by_name, velocity_column="qd_0", sigma_v=SIGMA_V)
    resolved = QuasiStaticGate(ARDRBF([0.5, 2.0], columns=[3, 0]), VELOCITY, SIGMA_V)
    assert_allclose(gate(frame), resolved(X), rtol=1e-14)
    W = rng.normal(size=(len(X), len(X)))
    assert_allclose(
        contract_gradient(gate, frame, W), contract_gradient(resolved, X, W), rtol=1e-12
    )


# -- QuasiStaticGate --------------------------------------------------------


def test_gate_zeroes_moving_samples_exactly(rng):
    X = make_X(rng)
    kernel = C(2.0) * gated_ard()
    moving = np.abs(X[:, VELOCITY]) >= SIGMA_V
    K, K_gradient = kernel(X, eval_gradient=True)
    assert moving.any() and (~moving).any()
    assert np.all(K[moving] == 0.0) and np.all(K[:, moving] == 0.0)
    assert np.all(K_gradient[moving] == 0.0) and np.all(K_gradient[:, moving] == 0.0)
    assert np.all(kernel.diag(X)[moving] == 0.0)
    assert np.all(np.diag(K)[~moving] > 0)
    assert_array_equal(kernel.k2.gate(X), (~moving).astype(float))


def test_gate_is_inner_kernel_on_still_samples(rng):
    X = make_X(rng)
    still = np.abs(X[:, VELOCITY]) < SIGMA_V
    inner = ARDRBF([0.8, 1.3, 2.1], columns=[0, 2, 3])
    K = gated_ard()(X)
    assert_allclose(K[np.ix_(still, still)], inner(X[still]), rtol=1e-14)


def test_gate_evaluates_inner_kernel_on_gated_rows_only(rng):
    X = make_X(rng)
    n_still = int(np.sum(np.abs(X[:, VELOCITY]) < SIGMA_V))
    kernel = QuasiStaticGate(RecordingRBF(1.0), VELOCITY, SIGMA_V)
    n_still_y = int(np.sum(np.abs(X[:5, VELOCITY]) < SIGMA_V))
    assert 0 < n_still_y < 5 and n_still < len(X)
    RecordingRBF.calls.clear()
    kernel(X)
    kernel(X, eval_gradient=True)
    kernel.diag(X)
    contract_gradient(kernel, X, np.ones((len(X), len(X))))  # dense fallback
    kernel(X, X[:5])
    assert RecordingRBF.calls == [
        (n_still, None),
        (n_still, None),
        (n_still, "diag"),
        (n_still, None),
        (n_still, n_still_y),
    ]


def test_gate_without_still_samples_is_zero(rng):
    X = make_X(rng)[np.arange(30) % 3 != 0]
    kernel = C() * gated_ard()
    K, K_gradient = kernel(X, eval_gradient=True)
    assert not K.any() and not K_gradient.any()
    assert not contract_gradient(kernel, X, np.ones((len(X), len(X)))).any()


def test_sigma_v_changes_K_but_not_theta(rng):
    X = make_X(rng)
    kernel = C(2.0) * gated_ard()
    theta, K = kernel.theta, kernel(X)
    kernel.set_params(k2__sigma_v=10.0)
    assert_array_equal(kernel.theta, theta)
    assert not np.allclose(kernel(X), K)
    assert np.all(kernel.k2.gate(X) == 1.0)
    assert all("sigma_v" not in h.name for h in kernel.hyperparameters)


# -- ParametricKernel -------------------------------------------------------


def test_parametric_kernel_is_phi_sigma_phi_t(rng):
    X, Y = make_X(rng), make_X(rng, n=6)
    prior_cov = np.array([0.5, 2.0, 1.5, 0.7])
    kernel = ParametricKernel(poly_features, prior_cov)
    Phi_X, Phi_Y = poly_features(X), poly_features(Y)
    assert_allclose(kernel(X), Phi_X @ np.diag(prior_cov) @ Phi_X.T, rtol=1e-12)
    assert_allclose(kernel(X, Y), Phi_X @ np.diag(prior_cov) @ Phi_Y.T, rtol=1e-12)
    scalar = ParametricKernel(poly_features, 3.0)
    assert_allclose(scalar(X), 3.0 * Phi_X @ Phi_X.T, rtol=1e-12)


def test_parametric_kernel_fits_unfitted_transformer_on_X(rng):
    X = make_X(rng)
    kernel = ParametricKernel(StandardScaler(), 2.0)
    Phi = StandardScaler().fit_transform(X)
    assert_allclose(kernel(X), 2.0 * Phi @ Phi.T, rtol=1e-12)
    assert not hasattr(kernel.features, "mean_")  # the parameter is not fitted


def test_parametric_kernel_uses_fitted_transformer_as_is(rng):
    X, other = make_X(rng), 5.0 + make_X(rng)
    scaler = StandardScaler().fit(other)
    Phi = scaler.transform(X)
    for features in (scaler, scaler.transform):
        assert_allclose(ParametricKernel(features)(X), Phi @ Phi.T, rtol=1e-12)
    # clone resets a fitted transformer but keeps a bound transform method
    cloned = clone(ParametricKernel(scaler.transform))
    assert_allclose(cloned(X), Phi @ Phi.T, rtol=1e-12)


# -- validation -------------------------------------------------------------


@pytest.mark.parametrize("sigma_v", [0.0, -0.01, np.nan, np.inf])
def test_invalid_sigma_v_is_rejected(sigma_v, rng):
    kernel = QuasiStaticGate(RBF(), VELOCITY, sigma_v=sigma_v)
    with pytest.raises(ValueError, match="sigma_v must be a finite velocity threshold"):
        kernel(make_X(rng))
    with pytest.raises(ValueError, match=r"QuasiStaticGate at 'k2'.*sigma_v"):
        resolve_columns(C() * kernel, n_features=N_FEATURES)


def test_unknown_column_name_lists_the_known_names():
    names = ["q_0", "qd_0", "qdd_0"]
    kernel = C() * ARDRBF(columns=["q_0", "tau_0"])
    match = r"unknown column name 'tau_0'; known names are \['q_0', 'qd_0', 'qdd_0'\]"
    with pytest.raises(ValueError, match=match):
        resolve_columns(kernel, feature_names=names)
    gate = QuasiStaticGate(RBF(), velocity_column="qd_9")
    with pytest.raises(ValueError, match=r"velocity_column\).*unknown column name 'qd_9'"):
        resolve_columns(gate, feature_names=names)


def test_names_without_feature_names_are_rejected(rng):
    with pytest.raises(ValueError, match="given by name but X has no feature names"):
        ARDRBF(columns=["q_0"])(make_X(rng))
    with pytest.raises(ValueError, match="given by name but X has no feature names"):
        resolve_columns(QuasiStaticGate(RBF(), "qd_0"), n_features=3)


def test_gate_column_outside_X_is_rejected(rng):
    kernel = QuasiStaticGate(RBF(), velocity_column=7)
    with pytest.raises(ValueError, match="column index 7 is outside X with 4 features"):
        kernel(make_X(rng))
    with pytest.raises(ValueError, match="column index 7 is outside X with 4 features"):
        resolve_columns(kernel + WhiteKernel(), n_features=4)
    with pytest.raises(ValueError, match="column index -1 is outside X"):
        ARDRBF(columns=[-1])(make_X(rng))


def test_length_scale_must_match_columns(rng):
    kernel = ARDRBF([1.0, 2.0], columns=[0, 1, 2])
    match = "length_scale has 2 entries but 3 columns are selected"
    with pytest.raises(ValueError, match=match):
        kernel(make_X(rng))
    with pytest.raises(ValueError, match=match):
        resolve_columns(C() * kernel, n_features=4)
    with pytest.raises(ValueError, match="length_scale has 2 entries but 4 columns"):
        ARDRBF([1.0, 2.0])(make_X(rng))


def test_other_column_problems_are_named(rng):
    with pytest.raises(ValueError, match=r"columns selects column\(s\) \[1\] twice"):
        ARDRBF(columns=[1, 1])(make_X(rng))
    with pytest.raises(ValueError, match="selects no column"):
        ARDRBF(columns=[])(make_X(rng))
    with pytest.raises(TypeError, match="must be an int index or a str name"):
        ARDRBF(columns=[1.5])(make_X(rng))
    with pytest.raises(ValueError, match="n_features=3 but 2 feature names"):
        resolve_columns(ARDRBF(), feature_names=["a", "b"], n_features=3)


def test_parametric_kernel_problems_are_named(rng):
    X = make_X(rng)
    with pytest.raises(ValueError, match=r"prior_cov has shape \(2,\) but features"):
        ParametricKernel(poly_features, [1.0, 2.0])(X)
    with pytest.raises(ValueError, match=r"shape \(30,\) for 30 samples"):
        ParametricKernel(first_column)(X)
    with pytest.raises(ValueError, match="non-finite value nan at row 0, column 0"):
        with np.errstate(invalid="ignore"):
            ParametricKernel(np.log)(-np.abs(X))
    with pytest.raises(TypeError, match="features must be a callable"):
        ParametricKernel("poly")(X)


# -- resolve_columns --------------------------------------------------------


def test_resolve_columns_rewrites_every_name_in_a_clone():
    names = ["q_0", "qd_0", "qdd_0", "i_c_0"]
    kernel = (
        C() * QuasiStaticGate(ARDRBF([1.0, 2.0], columns=["i_c_0", "q_0"]), "qd_0")
        + C() * ARDRBF(1.0, columns=["q_0", "qd_0", 2]) ** 2
        + ParametricKernel(poly_features)
    )
    resolved = resolve_columns(kernel, feature_names=names)
    assert resolved.k1.k1.k2.kernel.columns == [3, 0]
    assert resolved.k1.k1.k2.velocity_column == 1
    assert resolved.k1.k2.k2.kernel.columns == [0, 1, 2]
    assert kernel.k1.k1.k2.velocity_column == "qd_0"  # original untouched
    assert_array_equal(resolved.theta, kernel.theta)
    assert [h.name for h in resolved.hyperparameters] == [
        h.name for h in kernel.hyperparameters
    ]
    # indices pass through; without names there is nothing to range-check
    assert resolve_columns(ARDRBF(columns=[5])).columns == [5]
