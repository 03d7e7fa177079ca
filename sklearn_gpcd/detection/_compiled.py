"""Single-sample prediction paths for the streaming monitor.

``regressor.predict(x[None])`` costs a validation pass, a kernel object call
per summand and fresh arrays every tick. :func:`compile_predictor` turns a
fitted regressor into an object whose :meth:`predict_one` writes the
prediction for one input row into a caller-owned buffer, working only in
buffers allocated once:

* linear models (``coef_`` / ``intercept_``): one matrix-vector product;
* Gaussian processes (:class:`~sklearn_gpcd.gp.SemiParametricGPRegressor`
  and :class:`sklearn.gaussian_process.GaussianProcessRegressor`): the
  kernel is flattened into summands ``c * gates * exp(-0.5 d^2)`` (sums,
  products with constants, :class:`~sklearn_gpcd.kernels.ARDRBF`, ``RBF``,
  :class:`~sklearn_gpcd.kernels.QuasiStaticGate`; ``WhiteKernel`` has no
  cross-covariance and drops out). For one summand and support points
  ``s_i`` with weights ``w_i`` (the GP's ``alpha``),

  .. math::

      \\sum_i w_i\\, a(s_i)\\, c\\, a(x)
          \\exp\\Big(-\\tfrac12 \\sum_d \\frac{(x_d - s_{id})^2}{l_d^2}\\Big),
      \\quad \\sum_d \\frac{(x_d - s_{id})^2}{l_d^2}
          = \\sum_d \\frac{s_{id}^2}{l_d^2}
            - 2 \\sum_d \\frac{s_{id} x_d}{l_d^2} + \\sum_d \\frac{x_d^2}{l_d^2},

  so the support-only part is precomputed and each tick costs one product
  of the (centred) support matrix with ``x / l^2`` for all summands that
  share support points and columns -- across outputs too. The gate values
  ``a(s_i)`` are folded into the weights (support points outside the gate
  are dropped) and a gated group is skipped when no gate is open at ``x``
  (Eq. 15-16: the static component vanishes while the joint moves).
  Summands of any other kernel type are evaluated with the kernel object.

Anything else falls back to ``regressor.predict`` on a one-row array.
"""

import warnings

import numpy as np
from sklearn.gaussian_process.kernels import (
    RBF,
    ConstantKernel,
    Product,
    Sum,
    WhiteKernel,
)

__all__ = ["compile_predictor"]


class _Unsupported(Exception):
    """Raised by the kernel parser for a node it cannot flatten."""


class _Summand:
    """``scale * prod(gates) * exp(-0.5 sum_d inv_sq[d] (x_d - s_d)^2)`` or a kernel."""

    def __init__(self, scale=1.0, columns=None, inv_sq=None, gates=(), kernel=None):
        self.scale = scale
        self.columns = columns  # ndarray of int, or None for no exponential factor
        self.inv_sq = inv_sq
        self.gates = tuple(gates)  # (velocity column, sigma_v)
        self.kernel = kernel  # generic kernel object (other fields unused)


def _parse_summand(kernel, n_features):
    """Summands of ``kernel``; an unsupported node becomes one generic summand."""
    try:
        return _parse(kernel, n_features)
    except _Unsupported:
        return [_Summand(kernel=kernel)]


def _parse(kernel, n_features):
    from ..kernels import ARDRBF, QuasiStaticGate  # layer 4, lazily

    if isinstance(kernel, Sum):
        return _parse_summand(kernel.k1, n_features) + _parse_summand(kernel.k2, n_features)
    if isinstance(kernel, WhiteKernel):
        return []  # k(x, s) = 0 between a new point and the support points
    if isinstance(kernel, ConstantKernel):
        return [_Summand(scale=float(kernel.constant_value))]
    if isinstance(kernel, Product):
        left, right = _parse(kernel.k1, n_features), _parse(kernel.k2, n_features)
        return [_multiply(a, b) for a in left for b in right]
    if isinstance(kernel, (RBF, ARDRBF)) and type(kernel) in (RBF, ARDRBF):
        columns = getattr(kernel, "columns", None)
        columns = np.arange(n_features) if columns is None else np.asarray(columns)
        if columns.dtype.kind not in "iu":
            raise _Unsupported
        length = np.broadcast_to(np.asarray(kernel.length_scale, float), columns.shape)
        return [_Summand(columns=columns, inv_sq=1.0 / length**2)]
    if type(kernel) is QuasiStaticGate:
        if not isinstance(kernel.velocity_column, (int, np.integer)):
            raise _Unsupported
        gate = (int(kernel.velocity_column), float(kernel.sigma_v))
        inner = _parse(kernel.kernel, n_features)
        if any(s.kernel is not None for s in inner):
            raise _Unsupported
        return [
            _Summand(s.scale, s.columns, s.inv_sq, s.gates + (gate,)) for s in inner
        ]
    raise _Unsupported


def _multiply(a, b):
    if a.kernel is not None or b.kernel is not None:
        raise _Unsupported
    if a.columns is None or b.columns is None:
        columns, inv_sq = (a.columns, a.inv_sq) if b.columns is None else (b.columns, b.inv_sq)
    else:  # exp(-0.5 A) exp(-0.5 B) = exp(-0.5 (A + B))
        columns = np.union1d(a.columns, b.columns)
        inv_sq = np.zeros(columns.shape)
        for s in (a, b):
            np.add.at(inv_sq, np.searchsorted(columns, s.columns), s.inv_sq)
    return _Summand(a.scale * b.scale, columns, inv_sq, a.gates + b.gates)


def _gate_values(X, gates):
    """prod_g 1[|X[:, col_g]| < sigma_g] per row."""
    a = np.ones(X.shape[0])
    for column, sigma_v in gates:
        a *= np.abs(X[:, column]) < sigma_v
    return a


class _ExpGroup:
    """Exponential summands sharing support points and columns, all outputs."""

    def __init__(self, support, columns, n_outputs):
        self.support = support
        self.columns = columns
        self.n_outputs = n_outputs
        self.inv_sq, self.weights, self.outputs, self.gates = [], [], [], []

    def add(self, summand, weights, output):
        self.inv_sq.append(summand.inv_sq)
        self.weights.append(weights * summand.scale * _gate_values(self.support, summand.gates))
        self.outputs.append(output)
        self.gates.append(summand.gates)

    def finalize(self):
        A = np.column_stack(self.weights)
        rows = np.flatnonzero(np.any(A != 0.0, axis=1))
        S = self.support[np.ix_(rows, self.columns)]
        self.center = S.mean(axis=0) if S.shape[0] else np.zeros(len(self.columns))
        S = S - self.center
        d = S.shape[1]
        self.W = np.column_stack(self.inv_sq)  # (n_columns, n_terms)
        n_terms = self.W.shape[1]
        # kernels x support rows: [W * x; -0.5 (x * x) @ W]^T @ [S, 1]^T
        #   = sum_d s_d x_d / l_d^2 - 0.5 sum_d x_d^2 / l_d^2
        self.ST = np.ascontiguousarray(np.vstack([S.T, np.ones((1, S.shape[0]))]))
        self.half_s2w = np.ascontiguousarray(-0.5 * ((S**2) @ self.W).T)
        self.A = np.ascontiguousarray(A[rows])
        self.scatter = np.zeros((n_terms, self.n_outputs))
        self.scatter[np.arange(n_terms), self.outputs] = 1.0
        self.gated = any(self.gates)
        self.on = np.ones(n_terms)
        # per-tick buffers
        self.xs = np.empty(d)
        self.XW = np.empty((n_terms, d + 1))
        self.WT = np.ascontiguousarray(self.W.T)
        self.G = np.empty((n_terms, S.shape[0]))
        self.GA = np.empty((n_terms, n_terms))
        self.f = self.GA.reshape(-1)[:: n_terms + 1]  # diagonal view
        self.weighted = np.empty(n_terms)
        self.contribution = np.empty(self.n_outputs)
        return self

    @property
    def n_rows(self):
        """Support rows kept (those with a non-zero weight for some kernel)."""
        return self.G.shape[1]

    def add_to(self, x, out):
        if self.gated:
            for t, gates in enumerate(self.gates):
                on = 1.0
                for column, sigma_v in gates:
                    if not abs(x[column]) < sigma_v:
                        on = 0.0
                        break
                self.on[t] = on
            if not self.on.any():
                return  # Eq. 15: every gate closed, the group contributes 0
        np.take(x, self.columns, out=self.xs)
        self.xs -= self.center
        d = self.xs.shape[0]
        np.multiply(self.WT, self.xs, out=self.XW[:, :d])
        np.matmul(self.XW[:, :d], self.xs, out=self.XW[:, d])  # sum_d x_d^2 / l_d^2
        self.XW[:, d] *= -0.5
        np.matmul(self.XW, self.ST, out=self.G)
        self.G += self.half_s2w  # exponent -0.5 d^2(x, s_i), kernels x support rows
        np.exp(self.G, out=self.G)
        np.matmul(self.G, self.A, out=self.GA)  # diagonal: sum_i A_it k_t(x, s_i)
        np.multiply(self.f, self.on, out=self.weighted)
        np.matmul(self.weighted, self.scatter, out=self.contribution)
        out += self.contribution


class _GaussianProcessPredictor:
    """Fast mean of a GP with per-output supports, weights and parametric means."""

    def __init__(self, outputs, n_features, wrap):
        # outputs: list of dicts(kernel, support, weights, offset, mean)
        n_outputs = len(outputs)
        self.n_outputs = n_outputs
        self.offset = np.array([o["offset"] for o in outputs], dtype=float)
        self.generic, self.constants = [], []
        groups, supports = {}, []
        for j, o in enumerate(outputs):
            key_support = next(
                (i for i, s in enumerate(supports) if _same(s, o["support"])), None
            )
            if key_support is None:
                supports.append(o["support"])
                key_support = len(supports) - 1
            for summand in _parse_summand(o["kernel"], n_features):
                if summand.kernel is not None:
                    self.generic.append((j, summand.kernel, o["support"], o["weights"]))
                elif summand.columns is None:
                    value = summand.scale * float(
                        o["weights"] @ _gate_values(o["support"], summand.gates)
                    )
                    self.constants.append((j, value, summand.gates))
                else:
                    key = (key_support, tuple(summand.columns.tolist()))
                    group = groups.get(key)
                    if group is None:
                        group = groups[key] = _ExpGroup(
                            supports[key_support], summand.columns, n_outputs
                        )
                    group.add(summand, o["weights"], j)
        self.groups = [g.finalize() for g in groups.values()]
        self.means = [_compile_mean(o["mean"], wrap) for o in outputs]
        self.row = np.empty((1, n_features))

    def predict_one(self, x, out):
        out[:] = self.offset
        for group in self.groups:
            group.add_to(x, out)
        for j, value, gates in self.constants:
            if all(abs(x[c]) < s for c, s in gates):
                out[j] += value
        if self.generic:
            self.row[0] = x
            for j, kernel, support, weights in self.generic:
                out[j] += float(kernel(self.row, support)[0] @ weights)
        for j, mean in enumerate(self.means):
            if mean is not None:
                out[j] += mean(x, self.row)
        return out


def _same(a, b):
    return a is b or (a.shape == b.shape and np.array_equal(a, b))


def _compile_mean(mean, wrap):
    """``x -> m(x)`` of one output; a linear fast path for plain ParametricMean."""
    if mean is None:
        return None
    from ..gp import ParametricMean  # layer 4, lazily

    coef = getattr(mean, "coef_", None)
    if type(mean) is ParametricMean and mean.features_ is None and np.ndim(coef) == 1:
        coef = np.asarray(coef, dtype=float)
        intercept = float(mean.intercept_)
        velocity = mean.velocity_column_
        friction = np.asarray(mean.friction_columns_, dtype=int)
        friction_coef = coef[friction]
        sigma_v = mean.sigma_v
        xf = np.empty(friction.shape)

        def linear(x, row):
            value = float(coef @ x) + intercept
            if velocity is not None and abs(x[velocity]) < sigma_v:  # phi-bar, Eq. 17
                np.take(x, friction, out=xf)
                value -= float(friction_coef @ xf)
            return value

        return linear

    from ..dynamics import ControllerFeatures  # layer 2, lazily

    if (type(mean) is ParametricMean and type(mean.features_) is ControllerFeatures
            and np.ndim(coef) == 1 and not len(mean.friction_columns_)):
        column, gain = mean.features_.column_, float(coef[0])
        offset = float(mean.intercept_)

        def controller(x, row):  # w * i_c + intercept (make_sp_c)
            return gain * x[column] + offset

        return controller

    def generic(x, row):
        row[0] = x
        return float(np.ravel(mean.predict(wrap(row)))[0])

    return generic


class _LinearPredictor:
    """``coef_ @ x + intercept_``."""

    def __init__(self, coef, intercept, n_outputs):
        self.coef = np.asarray(coef, dtype=float).reshape(n_outputs, -1)
        self.intercept = np.broadcast_to(np.asarray(intercept, float), (n_outputs,)).copy()

    def predict_one(self, x, out):
        np.matmul(self.coef, x, out=out)
        out += self.intercept
        return out


class _GenericPredictor:
    """``regressor.predict`` on a one-row array (allocates; any regressor)."""

    def __init__(self, regressor, n_features, n_outputs, wrap):
        self.regressor = regressor
        self.row = np.empty((1, n_features))
        self.n_outputs = n_outputs
        self.wrap = wrap

    def predict_one(self, x, out):
        self.row[0] = x
        out[:] = np.reshape(self.regressor.predict(self.wrap(self.row)), (self.n_outputs,))
        return out


def _gp_outputs(regressor):
    """Per-output kernel, support, weights, offset and mean of a fitted GP, or None."""
    from sklearn.gaussian_process import GaussianProcessRegressor

    from ..gp import SemiParametricGPRegressor  # layer 4, lazily

    if isinstance(regressor, SemiParametricGPRegressor):
        outputs = []
        for fit in regressor._outputs:
            post = fit.posterior
            outputs.append(
                dict(
                    kernel=post.kernel,
                    support=post.X,
                    weights=post.y_std * post.weights,
                    offset=post.y_mean,
                    mean=fit.mean,
                )
            )
        return outputs
    if type(regressor) is GaussianProcessRegressor:
        alpha = regressor.alpha_.reshape(regressor.alpha_.shape[0], -1)
        y_mean = np.broadcast_to(regressor._y_train_mean, (alpha.shape[1],))
        y_std = np.broadcast_to(regressor._y_train_std, (alpha.shape[1],))
        return [
            dict(
                kernel=regressor.kernel_,
                support=regressor.X_train_,
                weights=y_std[j] * alpha[:, j],
                offset=y_mean[j],
                mean=None,
            )
            for j in range(alpha.shape[1])
        ]
    return None


def _identity(X):
    return X


def _unwrap(regressor):
    """The fitted estimator inside :class:`sklearn.frozen.FrozenEstimator` wrappers.

    A frozen estimator's ``predict`` is its inner estimator's, so the
    compiled path of the inner one applies (and is checked against the
    wrapper's own ``predict``).
    """
    from sklearn.frozen import FrozenEstimator

    while isinstance(regressor, FrozenEstimator):
        regressor = regressor.estimator
    return regressor


def compile_predictor(regressor, n_features, n_outputs, check_rows=None, wrap=None):
    """A single-sample predictor for a fitted regressor.

    Parameters
    ----------
    regressor : fitted regressor
        The model of the currents; a :class:`sklearn.frozen.FrozenEstimator`
        is compiled through the fitted estimator it wraps.
    n_features : int
        Number of input columns.
    n_outputs : int
        Number of predicted currents.
    check_rows : ndarray of shape (n_rows, n_features), default=None
        Inputs on which the compiled path is compared with
        ``regressor.predict``; on a mismatch the generic path is used (with a
        warning). GP supports are always checked too.
    wrap : callable, default=None
        Turns a 2-D input array into what ``regressor.predict`` expects
        (e.g. a DataFrame with the column names seen in fit); None passes
        arrays.

    Returns
    -------
    predictor : object
        With ``predict_one(x, out)``, writing the ``(n_outputs,)`` prediction
        for the ``(n_features,)`` input ``x`` into ``out``, and ``kind``, one
        of ``"gaussian_process"``, ``"linear"``, ``"generic"``.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.linear_model import Ridge
    >>> X = np.arange(8.0).reshape(4, 2)
    >>> p = compile_predictor(Ridge().fit(X, X.sum(1)), 2, 1)
    >>> p.kind, np.allclose(p.predict_one(X[1], np.empty(1)), 5.0, atol=0.1)
    ('linear', True)
    """
    wrap = _identity if wrap is None else wrap
    predictor, kind = None, "generic"
    inner = _unwrap(regressor)
    outputs = _gp_outputs(inner)
    if outputs is not None and len(outputs) == n_outputs:
        predictor = _GaussianProcessPredictor(outputs, n_features, wrap)
        kind = "gaussian_process"
        rows = outputs[0]["support"][:: max(1, len(outputs[0]["support"]) // 8)]
        check_rows = rows if check_rows is None else np.vstack([check_rows, rows])
    elif hasattr(inner, "coef_") and hasattr(inner, "intercept_"):
        coef = np.asarray(inner.coef_)
        if coef.size == n_features * n_outputs:
            predictor, kind = _LinearPredictor(coef, inner.intercept_, n_outputs), "linear"
    if predictor is not None and check_rows is not None and len(check_rows):
        expected = regressor.predict(wrap(check_rows))
        expected = np.reshape(expected, (len(check_rows), n_outputs))
        got = np.array([predictor.predict_one(x, np.empty(n_outputs)) for x in check_rows])
        # the GP mean sums large weights of both signs: compare at the
        # precision that conditioning leaves to predict() itself
        scale = np.max(np.abs(expected)) + 1.0
        if not np.allclose(got, expected, rtol=1e-6, atol=1e-6 * scale):
            warnings.warn(
                f"the fast single-sample path for {type(regressor).__name__} disagrees "
                "with its predict(); StreamingMonitor falls back to predict() per tick",
                RuntimeWarning,
            )
            predictor, kind = None, "generic"
    if predictor is None:
        predictor = _GenericPredictor(regressor, n_features, n_outputs, wrap)
    predictor.kind = kind
    return predictor
