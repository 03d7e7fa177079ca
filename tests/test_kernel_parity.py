"""Parity of the compiled kernel algebra (sklearn_gpcd.kernels.plan) with the Kernel objects.

Every fast path evaluates a kernel through its compiled nodes: the Gram matrix
and likelihood gradient of the fit, ``predict`` on batches and on one row,
and the one-sample path of the streaming monitor. On random kernel trees
(the generator of tests/test_properties.py, grown with products, gates of
trees, noise, fixed hyperparameters and opaque kernels) they must all equal
what the Kernel objects compute, and scikit-learn's GaussianProcessRegressor.
"""

import inspect
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from numpy.testing import assert_allclose
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process import kernels as sk_kernels
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel
from test_properties import SETTINGS, ard_kernels, kernel_trees

import sklearn_gpcd.kernels as gpcd_kernels
from sklearn_gpcd.gp import compile_predictor
from sklearn_gpcd.gp import SemiParametricGPRegressor
from sklearn_gpcd.gp._likelihood import _log_marginal_likelihood
from sklearn_gpcd.kernels import ARDRBF, QuasiStaticGate, contract_gradient
from sklearn_gpcd.kernels import plan as kernel_plan
from sklearn_gpcd.kernels.plan import OpaqueKernelWarning, compile_kernel, gram_matrix

#: the scikit-learn kernels the package composes with; each needs a node or
#: an explicit opaque registration
SKLEARN_KERNELS_USED = [
    sk_kernels.Sum,
    sk_kernels.Product,
    sk_kernels.ConstantKernel,
    sk_kernels.WhiteKernel,
    sk_kernels.RBF,
    sk_kernels.Exponentiation,
]


@st.composite
def leaves(draw, n_features):
    kind = draw(st.sampled_from(["tree", "constant", "rbf", "fixed_ard", "power"]))
    if kind == "tree":  # sums of scaled ARDRBF, gates and ParametricKernel
        return draw(kernel_trees(n_features))
    if kind == "constant":
        bounds = draw(st.sampled_from([(1e-5, 1e5), "fixed"]))
        return ConstantKernel(draw(st.floats(0.1, 5.0)), constant_value_bounds=bounds)
    if kind == "rbf":
        if draw(st.booleans()):
            return RBF(draw(st.floats(0.3, 4.0)))
        return RBF(draw(st.lists(st.floats(0.3, 4.0), min_size=n_features,
                                 max_size=n_features)))
    if kind == "fixed_ard":
        ard = draw(ard_kernels(n_features))
        return ard.set_params(length_scale_bounds="fixed")
    return draw(ard_kernels(n_features)) ** 2  # Exponentiation: opaque by design


@st.composite
def trees(draw, n_features, depth=2):
    """Random trees: sums, products, gates of subtrees over the leaves above."""
    if depth == 0 or draw(st.integers(0, 2)) == 0:
        return draw(leaves(n_features))
    kind = draw(st.sampled_from(["sum", "product", "gate"]))
    left = draw(trees(n_features, depth - 1))
    if kind == "gate":
        return QuasiStaticGate(left, velocity_column=draw(st.integers(0, n_features - 1)),
                               sigma_v=draw(st.floats(0.05, 2.0)))
    right = draw(trees(n_features, depth - 1))
    return left + right if kind == "sum" else left * right


@st.composite
def cases(draw):
    n_features = draw(st.integers(1, 4))
    kernel = draw(trees(n_features)) + WhiteKernel(draw(st.floats(0.05, 1.0)))
    n = draw(st.integers(1, 7))
    elements = st.floats(-2, 2)
    # some velocities (any column may be a gate's) exactly at rest
    X = draw(hnp.arrays(np.float64, (n, n_features), elements=elements))
    X[:: 2, 0] *= 0.01
    Q = draw(hnp.arrays(np.float64, (draw(st.integers(1, 4)), n_features), elements=elements))
    y = draw(hnp.arrays(np.float64, n, elements=st.floats(-3, 3)))
    W = draw(hnp.arrays(np.float64, (n, n), elements=st.floats(-1, 1)))
    return kernel, X, Q, y, W


def _close(got, expected, rtol=1e-8):
    scale = max(float(np.max(np.abs(expected), initial=0.0)), 1.0)
    assert_allclose(got, expected, rtol=rtol, atol=1e-9 * scale)


@settings(max_examples=200, **SETTINGS)
@given(case=cases())
def test_compiled_kernel_equals_the_kernel_objects(case):
    """Gram, gradient contraction, LML gradient, batch and one-row predict."""
    kernel, X, Q, y, W = case
    with warnings.catch_warnings():
        warnings.simplefilter("error", OpaqueKernelWarning)  # all registered
        plan = compile_kernel(kernel)
        K_reference, K_gradient = kernel(X, eval_gradient=True)

        # Gram matrix, full and (while optimising) lower triangle
        _close(gram_matrix(plan, X), K_reference, rtol=1e-10)
        _close(np.tril(gram_matrix(plan, X, keep=True)), np.tril(K_reference), rtol=1e-10)
        # gradient contraction (full W) and the log-marginal-likelihood gradient
        _close(contract_gradient(kernel, X, W), np.einsum("ij,ijk->k", W, K_gradient))
        theta = kernel.theta
        lml, gradient = _log_marginal_likelihood(theta, kernel, X, y, 1e-10, eval_gradient=True)
        gpr = GaussianProcessRegressor(kernel, optimizer=None).fit(X, y)
        lml_reference, gradient_reference = gpr.log_marginal_likelihood(theta, True)
        _close(lml, lml_reference)
        _close(gradient, gradient_reference, rtol=1e-6)

        # batch and one-row predict of the fitted regressor
        gp = SemiParametricGPRegressor(kernel, optimizer=None).fit(X, y)
        posterior = gp.posteriors_[0]
        by_kernel = kernel(Q, X) @ posterior.alpha + posterior.y_mean
        _close(posterior.predict_mean(Q), by_kernel)
        _close(gp.predict(Q), by_kernel, rtol=1e-7)
        _close(gpr.predict(Q), by_kernel, rtol=1e-7)
        _close(np.concatenate([gp.predict(Q[i : i + 1]) for i in range(len(Q))]), by_kernel,
               rtol=1e-7)
        # the one-sample path of the streaming monitor (terms of the nodes)
        predictor = compile_predictor(gp, X.shape[1], 1, check_rows=Q)
        assert predictor.kind == "gaussian_process"
        one_row = np.concatenate([predictor.predict_one(q, np.empty(1)) for q in Q])
        _close(one_row, by_kernel, rtol=1e-7)


def _kernel_classes(module):
    return {obj for _, obj in inspect.getmembers(module, inspect.isclass)
            if issubclass(obj, sk_kernels.Kernel) and obj.__module__.startswith(module.__name__)}


@pytest.mark.parametrize(
    "kind",
    sorted(_kernel_classes(gpcd_kernels) | set(SKLEARN_KERNELS_USED), key=lambda k: k.__name__),
    ids=lambda k: k.__name__,
)
def test_every_kernel_class_is_registered(kind):
    """Each kernel has a node or is explicitly opaque, with the parameters it has today."""
    entry = kernel_plan.registered_node(kind)
    assert entry is not None, f"{kind.__name__}: register a node or register_node(kind, None)"
    node_class, params = entry
    assert params == set(inspect.signature(kind.__init__).parameters) - {"self"}


class _SubclassedRBF(RBF):
    """A subclass may override __call__: it must not use RBF's node."""

    def __call__(self, X, Y=None, eval_gradient=False):
        return super().__call__(X, Y, eval_gradient)


class _ARDRBFWithOffset(ARDRBF):
    """A changed ARDRBF (one more parameter) must not silently use the old node."""

    def __init__(self, length_scale=1.0, columns=None, length_scale_bounds=(1e-5, 1e5),
                 offset=0.0):
        super().__init__(length_scale, columns, length_scale_bounds)
        self.offset = offset


def test_unknown_kernels_are_opaque_and_warn_once(monkeypatch):
    monkeypatch.setattr(kernel_plan, "_WARNED", set())
    X = np.random.default_rng(0).normal(size=(6, 2))
    kernel = ConstantKernel(2.0) * _SubclassedRBF(1.5) + _SubclassedRBF(0.5)
    with pytest.warns(OpaqueKernelWarning, match="_SubclassedRBF") as record:
        plan = compile_kernel(kernel)
        compile_kernel(kernel)
    assert len(record) == 1
    assert isinstance(plan.k1.k2, kernel_plan._Opaque)
    _close(gram_matrix(plan, X), kernel(X), rtol=1e-12)
    # a registered type with parameters its node does not know is opaque too
    monkeypatch.setitem(kernel_plan._REGISTRY, _ARDRBFWithOffset,
                        kernel_plan.registered_node(ARDRBF))
    with pytest.warns(OpaqueKernelWarning, match="_ARDRBFWithOffset"):
        node = compile_kernel(_ARDRBFWithOffset(1.0, columns=[0]))
    assert isinstance(node, kernel_plan._Opaque)


def test_kernel_given_by_column_names_is_opaque_not_wrong():
    pd = pytest.importorskip("pandas")
    X = pd.DataFrame(np.random.default_rng(1).normal(size=(5, 2)), columns=["q_0", "qd_0"])
    kernel = QuasiStaticGate(ARDRBF(1.0, columns=["q_0"]), "qd_0", sigma_v=0.5)
    plan = compile_kernel(kernel)
    assert isinstance(plan, kernel_plan._Opaque)


def test_constant_times_a_product_fits():
    """Found by the parity test: C * (C * ARDRBF) crashed the gradient contraction."""
    X = np.random.default_rng(0).normal(size=(30, 2))
    kernel = ConstantKernel(1.0) * (ConstantKernel(2.0) * ARDRBF(1.0, columns=[0])) + WhiteKernel()
    W = np.random.default_rng(1).normal(size=(30, 30))
    _close(contract_gradient(kernel, X, W),
           np.einsum("ij,ijk->k", W, kernel(X, eval_gradient=True)[1]))
    gp = SemiParametricGPRegressor(kernel, random_state=0).fit(X, X[:, 0])
    assert np.isfinite(gp.log_marginal_likelihood_value_)


def test_product_of_gates():
    """Found by the parity test: the product of two gated blocks crashed the Gram matrix."""
    X = np.random.default_rng(0).normal(size=(20, 2))
    X[::2, 0] *= 1e-3
    gate = QuasiStaticGate(ConstantKernel(2.0) * ARDRBF(1.0, columns=[1]), 0, sigma_v=0.1)
    kernel = gate * QuasiStaticGate(ARDRBF(0.5, columns=[1]), 0, sigma_v=0.1) + WhiteKernel()
    _close(gram_matrix(compile_kernel(kernel), X), kernel(X), rtol=1e-12)
    gp = SemiParametricGPRegressor(kernel, optimizer=None).fit(X, X[:, 1])
    _close(gp.predict(X), gp.posteriors_[0].predict_mean(X), rtol=1e-8)
