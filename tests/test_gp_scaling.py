"""Tests of the scalable paths of ``SemiParametricGPRegressor`` (issue 6):
minibatch Adam on the marginal likelihood, the ``optimizer="auto"`` rule,
the compiled kernel (gradient without the n x n x d array, gated block
skipped at prediction) and the lean single-sample predict."""

import numpy as np
import pandas as pd
import pytest
from numpy.testing import assert_allclose
from sklearn import config_context
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, Matern, WhiteKernel
from sklearn.gaussian_process.kernels import ConstantKernel as C

from sklearn_gpcd.gp import SemiParametricGPRegressor
from sklearn_gpcd.kernels.plan import _Gate, _Product, compile_kernel, gram_matrix
from sklearn_gpcd.gp._likelihood import _log_marginal_likelihood, single_threaded_blas
from sklearn_gpcd.gp._optimize import (
    AdamSettings,
    _fit_hyperparameters,
    _fit_hyperparameters_adam,
    data_driven_init,
    resolve_optimizer,
)
from sklearn_gpcd.kernels import ARDRBF, QuasiStaticGate


def smooth(n, seed=0, noise=0.05):
    """y = sin(2 x0) + 0.5 x1^2 - 0.3 x2 + noise, x uniform in [-2, 2]^3."""
    rng = np.random.RandomState(seed)
    X = rng.uniform(-2, 2, size=(n, 3))
    y = np.sin(2 * X[:, 0]) + 0.5 * X[:, 1] ** 2 - 0.3 * X[:, 2] + noise * rng.randn(n)
    return X, y


def ard_kernel():
    return C(1.0) * RBF([1.0, 1.0, 1.0]) + WhiteKernel(1.0)


def gated(n, seed=0):
    """Gated problem: a term in h only where |v| < 0.05 (half of the rows)."""
    rng = np.random.RandomState(seed)
    v = np.where(rng.uniform(size=n) < 0.5, rng.uniform(-0.04, 0.04, n), rng.uniform(0.1, 1, n))
    X = np.column_stack([rng.uniform(-2, 2, n), v, rng.uniform(-1, 1, n)])
    y = np.sin(X[:, 0]) + (np.abs(v) < 0.05) * np.sin(3 * X[:, 2]) + 0.05 * rng.randn(n)
    kernel = (
        C(1.0) * ARDRBF([1.0, 1.0], columns=[0, 1])
        + C(1.0) * QuasiStaticGate(ARDRBF([1.0, 1.0], columns=[0, 2]), 1, sigma_v=0.05)
        + WhiteKernel(0.1)
    )
    return X, y, kernel


def find(plan, kind):
    """The first node of a compiled tree of the given class."""
    if isinstance(plan, kind):
        return plan
    for child in (getattr(plan, "k1", None), getattr(plan, "k2", None),
                  getattr(plan, "inner", None)):
        node = None if child is None else find(child, kind)
        if node is not None:
            return node
    return None


# ------------------------------------------------------------ Adam path


def test_adam_increases_the_lml_and_lands_near_the_exact_optimum():
    X, y = smooth(600)
    y = (y - y.mean()) / y.std()
    kernel = ard_kernel()
    settings = AdamSettings(batch_size=128, max_iter=300, learning_rate=0.05, tol=1e-3,
                            n_iter_no_change=5, verbose=0)
    with single_threaded_blas():  # as in fit
        start = _log_marginal_likelihood(kernel.theta, kernel, X, y, 1e-10)
        exact, lml_exact, _ = _fit_hyperparameters(
            kernel, X, y, 1e-10, "fmin_l_bfgs_b", 0, np.random.RandomState(0)
        )
        adam, info = _fit_hyperparameters_adam(
            kernel, X, y, 1e-10, settings, 0, np.random.RandomState(0)
        )
        lml_adam = _log_marginal_likelihood(adam.theta, kernel, X, y, 1e-10)
    # the negative LML fell a lot (from the initial kernel) ...
    assert lml_adam > start + 0.8 * (lml_exact - start)
    # ... and minibatch Adam alone lands within 0.15 nats per sample of the optimum
    assert lml_exact - lml_adam < 0.15 * len(y)
    steps = [h[0] for h in info["history"]]
    assert steps == sorted(steps) and info["n_iter"] == steps[-1]
    assert info["validation_lml"] >= max(h[2] for h in info["history"]) - 1e-12


def test_minibatch_trained_nmse_within_10_percent_of_exact():
    X, y = smooth(800, seed=1)
    X_test, y_test = smooth(500, seed=2)
    scores = {}
    for optimizer in ("fmin_l_bfgs_b", "adam"):
        gp = SemiParametricGPRegressor(
            ard_kernel(), optimizer=optimizer, batch_size=128, normalize_y=True, random_state=0
        ).fit(X, y)
        scores[optimizer] = np.mean((gp.predict(X_test) - y_test) ** 2) / np.var(y_test)
    assert scores["adam"] <= 1.10 * scores["fmin_l_bfgs_b"], scores


def test_early_stopping_triggers_and_keeps_the_best_theta():
    X, y = smooth(800)
    gp = SemiParametricGPRegressor(
        ard_kernel(), optimizer="adam", batch_size=128, max_iter=1000, tol=10.0,
        n_iter_no_change=2, random_state=0,
    ).fit(X, y)
    # no check can improve by 10 nats per sample: stop after 2 checks (20 steps)
    assert gp.n_iter_ == 20
    patient = SemiParametricGPRegressor(
        ard_kernel(), optimizer="adam", batch_size=128, max_iter=60, tol=0.0,
        n_iter_no_change=100, random_state=0,
    ).fit(X, y)
    assert patient.n_iter_ == 60  # never stale: runs to max_iter


def test_verbose_prints_adam_progress(capsys):
    X, y = smooth(400)
    SemiParametricGPRegressor(
        ard_kernel(), optimizer="adam", batch_size=64, max_iter=30, verbose=1, random_state=0
    ).fit(X, y)
    out = capsys.readouterr().out
    lines = [line for line in out.splitlines() if line.startswith("[Adam]")]
    assert len(lines) == 3  # steps 10, 20, 30
    assert "held-out LML/n" in lines[0] and "step    30" in lines[-1]


def test_adam_with_restarts_and_per_sample_alpha():
    X, y = smooth(300)
    gp = SemiParametricGPRegressor(
        ard_kernel(), optimizer="adam", batch_size=64, max_iter=40, n_restarts_optimizer=1,
        alpha=np.full(300, 1e-8), random_state=0,
    ).fit(X, y)
    assert np.isfinite(gp.log_marginal_likelihood_value_)
    assert gp.log_marginal_likelihood_value_ == pytest.approx(
        gp.log_marginal_likelihood(gp.kernel_.theta), rel=1e-8
    )


def test_data_driven_init_only_replaces_default_length_scales():
    rng = np.random.RandomState(0)
    X = rng.normal(scale=[0.1, 10.0, 1.0], size=(400, 3))
    kernel = C() * ARDRBF([1.0, 1.0, 3.0]) + RBF(1.0, length_scale_bounds="fixed")
    init = data_driven_init(kernel, X, rng)
    ls = init.k1.k2.length_scale
    assert ls[2] == 3.0 and 0.05 < ls[0] < 0.5 and 5 < ls[1] < 50
    assert init.k2.length_scale == 1.0  # fixed: untouched
    assert kernel.k1.k2.length_scale == [1.0, 1.0, 3.0]  # input not modified


# ------------------------------------------------------------ auto rule


@pytest.mark.parametrize(
    "n, n_theta, expected",
    [(3000, 20, "fmin_l_bfgs_b"), (3001, 3, "adam"), (1000, 61, "adam"), (60, 5, "fmin_l_bfgs_b")],
)
def test_auto_rule(n, n_theta, expected):
    assert resolve_optimizer("auto", n, n_theta) == expected
    assert resolve_optimizer("fmin_l_bfgs_b", n, n_theta) == "fmin_l_bfgs_b"
    assert resolve_optimizer(None, n, n_theta) is None


def test_auto_picks_each_path_in_fit():
    X, y = smooth(300)
    small = SemiParametricGPRegressor(ard_kernel(), random_state=0).fit(X, y)
    assert small.optimizer_ == "fmin_l_bfgs_b"
    exact = SemiParametricGPRegressor(ard_kernel(), optimizer="fmin_l_bfgs_b", random_state=0)
    assert_allclose(small.kernel_.theta, exact.fit(X, y).kernel_.theta)
    # 2,000 rows x 32 hyperparameters > 60,000: the stochastic path
    rng = np.random.RandomState(0)
    X_wide = rng.uniform(size=(2000, 30))
    y_wide = X_wide[:, 0] + 0.1 * rng.randn(2000)
    kernel = C() * RBF(np.ones(30)) + WhiteKernel()
    big = SemiParametricGPRegressor(kernel, batch_size=64, max_iter=20, random_state=0)
    assert big.fit(X_wide, y_wide).optimizer_ == "adam"
    assert big.n_iter_ <= 20


def test_bad_adam_parameters():
    X, y = smooth(30)
    for params, match in [
        (dict(batch_size=0), "'batch_size' parameter of SemiParametricGPRegressor must be"),
        (dict(max_iter=1.5), "'max_iter' parameter of SemiParametricGPRegressor must be"),
        (dict(learning_rate=0.0), "'learning_rate' parameter of"),
        (dict(tol=-1.0), "'tol' parameter of SemiParametricGPRegressor must be"),
        (dict(n_iter_no_change=0), "'n_iter_no_change' parameter of"),
    ]:
        with pytest.raises(ValueError, match=match):
            SemiParametricGPRegressor(**params).fit(X, y)


# ------------------------------------------------------- compiled kernel


@pytest.mark.parametrize(
    "kernel",
    [
        C(2.0) * ARDRBF([0.5, 1.0], columns=[0, 2]) * RBF(1.5) + WhiteKernel(0.3),
        C(1.0) * QuasiStaticGate(C(0.5) * ARDRBF([1.0, 2.0], columns=[0, 2]), 1, sigma_v=0.05)
        + C(1.0, "fixed") * ARDRBF([1.0, 1.0], columns=[0, 1]) + WhiteKernel(0.1),
        C(1.0) * Matern(1.0, nu=2.5) + RBF([1.0, 2.0, 3.0], length_scale_bounds="fixed")
        + WhiteKernel(0.2),
    ],
    ids=["products", "gated", "opaque-and-fixed"],
)
def test_compiled_lml_and_gradient_equal_sklearn(kernel):
    X, y, _ = gated(120)
    y = y - y.mean()
    ref = GaussianProcessRegressor(kernel, optimizer=None).fit(X, y)
    theta = kernel.theta + 0.2
    lml, grad = _log_marginal_likelihood(theta, kernel, X, y, 1e-10, eval_gradient=True)
    ref_lml, ref_grad = ref.log_marginal_likelihood(theta, eval_gradient=True)
    assert_allclose(lml, ref_lml, rtol=1e-10)
    assert_allclose(grad, ref_grad, rtol=1e-7, atol=1e-9)
    plan = compile_kernel(kernel.clone_with_theta(theta))
    assert_allclose(gram_matrix(plan, X), kernel.clone_with_theta(theta)(X), rtol=1e-12)


@pytest.mark.parametrize(
    "kernel, lower",
    [
        (C(2.0) * RBF([0.5, 1.0, 2.0]) + WhiteKernel(0.3), True),
        (RBF(1.5) + C(0.5) * ARDRBF([1.0, 2.0], columns=[0, 2]) + C(0.2) + WhiteKernel(0.1), True),
        (C(2.0) * RBF([0.5, 1.0, 2.0], length_scale_bounds="fixed") + WhiteKernel(0.3), True),
        (C(2.0) * ARDRBF([0.5, 1.0], columns=[0, 2]) * RBF(1.5) + WhiteKernel(0.3), False),
        (C(1.0) * QuasiStaticGate(C(0.5) * ARDRBF([1.0, 2.0], columns=[0, 2]), 1, sigma_v=0.05)
         + WhiteKernel(0.1), False),
    ],
    ids=["c-rbf-white", "sum-of-scaled", "fixed-rbf", "rbf-product", "gated"],
)
def test_lower_triangle_plans_give_the_full_plans_lml_and_gradient(kernel, lower):
    # sums of c * RBF, constants and noise are optimised on lower triangles only;
    # anything else on full matrices; both give sklearn's numbers, evaluation after
    # evaluation (the plan reuses its arrays)
    X, y, _ = gated(300)
    y = y - y.mean()
    plan = compile_kernel(kernel)
    assert plan.lower is lower
    assert find(plan, _Gate) is None or not find(find(plan, _Gate).inner, _Product).lower
    ref = GaussianProcessRegressor(kernel, optimizer=None).fit(X, y)
    for step in (0.2, -0.3, 0.2):
        theta = kernel.theta + step
        lml, grad = _log_marginal_likelihood(theta, kernel, X, y, 1e-10, True, plan)
        ref_lml, ref_grad = ref.log_marginal_likelihood(theta, eval_gradient=True)
        assert_allclose(lml, ref_lml, rtol=1e-10)
        assert_allclose(grad, ref_grad, rtol=1e-7, atol=1e-9)
    if lower:  # the plan wrote the lower triangle; the full Gram matrix is intact
        K = gram_matrix(plan, X, keep=True)
        full = kernel.clone_with_theta(theta)(X)
        assert_allclose(np.tril(K), np.tril(full), rtol=1e-12)
        assert_allclose(gram_matrix(plan, X), full, rtol=1e-12)


@pytest.mark.parametrize("n", [1, 2, 31, 32, 33, 500])
def test_squared_exponential_gram_in_row_blocks(n, monkeypatch):
    from scipy.spatial.distance import cdist

    from sklearn_gpcd.kernels import plan as _kernel_plan

    monkeypatch.setattr(_kernel_plan, "_BLOCK_BYTES", 8 * 32 * max(n, 1))  # 32-row blocks
    Z = np.random.RandomState(n).normal(size=(n, 4))
    Z -= Z.mean(axis=0)
    expected = np.exp(-0.5 * cdist(Z, Z, "sqeuclidean"))
    K = _kernel_plan._se_gram(Z, np.empty((n, n)))
    assert np.array_equal(K, K.T) and np.all(np.diag(K) == 1.0)
    assert_allclose(K, expected, rtol=1e-12)
    scaled, lower = np.zeros((n, n)), np.zeros((n, n))
    _kernel_plan._se_gram(Z, lower, scaled=(3.0, scaled), lower=True)
    assert_allclose(np.tril(lower), np.tril(expected), rtol=1e-12)
    assert_allclose(np.tril(scaled), 3.0 * np.tril(lower), rtol=1e-15)
    far = 1e4 * Z  # expansion round-off too large: exact differences
    assert_allclose(_kernel_plan._se_gram(far, np.empty((n, n))),
                    np.exp(-0.5 * cdist(far, far, "sqeuclidean")), rtol=1e-12)


def test_gated_block_is_skipped_for_moving_samples():
    X, y, kernel = gated(200)
    gp = SemiParametricGPRegressor(kernel, optimizer=None).fit(X, y)
    plan = gp._outputs[0].posterior.plan
    gate = find(plan, _Gate)
    calls = []
    inner_cross_dot = gate.inner.cross_dot

    def spy(Q):
        calls.append(len(Q))
        return inner_cross_dot(Q)

    gate.inner.cross_dot = spy
    moving = X[np.abs(X[:, 1]) >= 0.05]
    gp.predict(moving)
    gp.predict(moving[:1])
    assert calls == []  # the gate is 0 everywhere: the static block is never evaluated
    mixed = X[:50]
    n_gated = int(np.sum(np.abs(mixed[:, 1]) < 0.05))
    pred = gp.predict(mixed)
    assert calls == [n_gated] and 0 < n_gated < 50
    gate.inner.cross_dot = inner_cross_dot
    # and skipping changes nothing: equal to the dense k(X*, X) w of sklearn
    ref = GaussianProcessRegressor(kernel, optimizer=None).fit(X, y)
    assert_allclose(pred, ref.predict(mixed), rtol=1e-9, atol=1e-12)


def test_chunked_predict_equals_unchunked_with_a_gate():
    X, y, kernel = gated(150)
    gp = SemiParametricGPRegressor(kernel, normalize_y=True, random_state=0).fit(X, y)
    mean, std = gp.predict(X, return_std=True)
    with config_context(working_memory=1e-3):  # one row per chunk
        mean_c, std_c = gp.predict(X, return_std=True)
        mean_only = gp.predict(X)
    assert_allclose(mean_c, mean, rtol=1e-9, atol=1e-12)
    assert_allclose(std_c, std, rtol=1e-9, atol=1e-12)
    assert_allclose(mean_only, mean, rtol=1e-9, atol=1e-12)


# ------------------------------------------------------ single-sample path


def test_single_row_predict_equals_batch_and_still_validates():
    X, y, kernel = gated(100)
    gp = SemiParametricGPRegressor(kernel, optimizer=None).fit(X, y)
    batch = gp.predict(X[:20])
    rows = np.array([gp.predict(X[i : i + 1])[0] for i in range(20)])
    assert_allclose(rows, batch, rtol=1e-9, atol=1e-12)
    assert_allclose(gp.predict(X[:3].tolist()), batch[:3], rtol=1e-12)  # slow path
    bad = X[:1].copy()
    bad[0, 2] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        gp.predict(bad)
    with pytest.raises(ValueError, match="X has 2 features"):
        gp.predict(X[:1, :2])
    frame = pd.DataFrame(X, columns=["x", "v", "h"])
    named = SemiParametricGPRegressor(kernel, optimizer=None).fit(frame, y)
    with pytest.warns(UserWarning, match="does not have valid feature names"):
        named.predict(X[:1])  # a fitted-with-names model still warns on arrays


# -- memory: gated blocks, the lazily rebuilt factor, the mirrored inverse ----
@pytest.mark.parametrize("kind", range(6))
def test_gram_with_gated_blocks_equals_the_kernel(kind):
    """Gated Gram blocks are added in place (no second (n, n) array) exactly."""
    rng = np.random.RandomState(kind)
    X = rng.normal(size=(120, 4))
    X[::3, 1] = 1e-3  # a third of the rows quasi-static
    g1 = QuasiStaticGate(ARDRBF([1.0, 2.0], columns=[0, 2]), velocity_column=1, sigma_v=0.01)
    g2 = QuasiStaticGate(ARDRBF([1.5], columns=[3]), velocity_column=1, sigma_v=0.01)
    kernel = [
        C(2.0) * g1,
        ARDRBF([1.0] * 4) + C(2.0) * g1 + WhiteKernel(0.1),
        g1 + g2,
        WhiteKernel(0.1) + g1,
        g1 * C(3.0) + C(1.0),
        g1 * RBF(1.0),
    ][kind]
    plan = compile_kernel(kernel)
    in_place = gram_matrix(plan, X)  # gated blocks added in place
    assert np.array_equal(in_place, gram_matrix(plan, X, keep=True))  # dense blocks
    assert_allclose(in_place, kernel(X), rtol=1e-12, atol=1e-14)


@pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")
def test_large_factor_is_rebuilt_on_demand_with_identical_results(monkeypatch):
    from sklearn_gpcd.gp import _posterior

    X, y = smooth(150)
    kept = SemiParametricGPRegressor(ard_kernel(), random_state=0).fit(X, y)
    monkeypatch.setattr(_posterior, "FACTOR_KEEP_BYTES", 0)
    lean = SemiParametricGPRegressor(ard_kernel(), random_state=0).fit(X, y)
    assert kept._outputs[0].posterior._L is not None
    assert lean._outputs[0].posterior._L is None  # not held after the fit
    assert lean.log_marginal_likelihood_value_ == kept.log_marginal_likelihood_value_
    assert np.array_equal(lean.predict(X), kept.predict(X))
    mean, std = lean.predict(X, return_std=True)
    assert lean._outputs[0].posterior._L is not None  # rebuilt once, then cached
    assert np.array_equal(std, kept.predict(X, return_std=True)[1])


@pytest.mark.parametrize("n", [1, 2, 255, 256, 257, 700])
def test_weight_matrix_is_the_symmetric_inverse_minus_a_a_t(n):
    from scipy.linalg.lapack import dpotrf

    from sklearn_gpcd.kernels.plan import mirror_upper
    from sklearn_gpcd.gp._likelihood import _negated_weight_matrix

    A = np.random.RandomState(n).normal(size=(n, n))
    K = A @ A.T + n * np.eye(n)
    U, info = dpotrf(K, lower=0, clean=1)
    a = np.random.RandomState(0).normal(size=n)
    V = _negated_weight_matrix(U.copy(order="F"), a)  # K^{-1} - a a^T
    assert info == 0 and np.array_equal(V, V.T) and V.flags.c_contiguous
    assert_allclose(V, np.linalg.inv(K) - np.outer(a, a), rtol=1e-9, atol=1e-12)
    lower = _negated_weight_matrix(U, a, mirror=False)  # zeros above the diagonal
    assert lower.flags.c_contiguous and np.array_equal(lower, np.tril(V))
    upper = np.triu(A)
    assert np.array_equal(mirror_upper(upper.copy(), tile=64), upper + np.triu(upper, 1).T)


def test_single_output_keeps_blas_threads_multi_output_pins_them(monkeypatch):
    from sklearn_gpcd.gp import regressor

    seen = []
    real = regressor.single_threaded_blas

    def spy():
        seen.append(True)
        return real()

    monkeypatch.setattr(regressor, "single_threaded_blas", spy)
    X, y = smooth(60)
    SemiParametricGPRegressor(ard_kernel(), random_state=0).fit(X, y)
    # one output: only the posterior's factorisation is pinned (so that it is
    # the factor rebuilt later for std); the optimisation keeps BLAS's threads
    assert len(seen) == 1
    seen.clear()
    SemiParametricGPRegressor(ard_kernel(), random_state=0).fit(X, np.c_[y, y])
    assert len(seen) == 4  # per output: the whole fit, and the posterior inside it
