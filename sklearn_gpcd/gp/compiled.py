"""Single-sample prediction of a fitted regressor (the streaming monitor's path).

``regressor.predict(x[None])`` costs a validation pass, a kernel object call
per summand and fresh arrays every tick. :func:`compile_predictor` turns a
fitted regressor into an object whose :meth:`predict_one` writes the
prediction for one input row into a caller-owned buffer, working only in
buffers allocated once:

* linear models (``coef_`` / ``intercept_``): one matrix-vector product;
* Gaussian processes (:class:`~sklearn_gpcd.gp.SemiParametricGPRegressor`
  and :class:`sklearn.gaussian_process.GaussianProcessRegressor`): the
  kernel is flattened by its compiled nodes
  (:func:`sklearn_gpcd.kernels.plan.compile_kernel`, ``terms``) into summands
  ``c * gates * exp(-0.5 d^2)`` (sums, products with constants,
  :class:`~sklearn_gpcd.kernels.ARDRBF`, ``RBF``,
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
  Exponents are floored at -700 before ``exp`` (``_EXP_FLOOR``): below
  about -708 numpy's ``exp`` leaves its fast path, and fitted models on
  real logs get there on most ticks.
  Summands of any other kernel type are evaluated with the kernel object.
  The GP is read through its public posteriors
  (:attr:`SemiParametricGPRegressor.posteriors_
  <sklearn_gpcd.gp.SemiParametricGPRegressor.posteriors_>`), and the compiled
  path is checked against :meth:`~sklearn_gpcd.gp.GPPosterior.predict_mean`,
  which evaluates the Kernel objects.

Anything else falls back to ``regressor.predict`` on a one-row array.
"""

import warnings

import numpy as np
from sklearn.frozen import FrozenEstimator
from sklearn.gaussian_process import GaussianProcessRegressor

from .._gate import quasi_static
from ..dynamics import ControllerFeatures, RigidBodyFeatures
from ..kernels.plan import compile_kernel, flatten
from ._posterior import GPPosterior
from .mean import ParametricMean
from .regressor import SemiParametricGPRegressor

__all__ = ["compile_predictor"]


#: Largest -h of a support row (``_SharedSupportGroup``) for which exp(h) is
#: folded into the weights: exp(600) and exp(-600) are far from the limits of a
#: float64 (about exp(709) and exp(-708)).
_FOLD_LIMIT = 600.0

#: Floor of every exponent before ``exp``. Below about -708 the result of
#: ``exp`` is subnormal or zero, and numpy's vectorised ``exp`` leaves its fast
#: path for those lanes: on a 2-core AMD EPYC (AVX2) 12,000 exponents in
#: (-745, -700) took 388 us instead of 10-15 us, and a mix with half below -745
#: 66 us. Fitted models on real logs hit that every tick: the UR10e's SP_P
#: quasi-static group had 70-93 % of its exponents below -745 (rest poses far
#: from most support rows in its short length scales). A summand with weight
#: ``a`` changes by at most ``|a| exp(-700)`` (about ``1e-304 |a|``), far below
#: the rounding of the sum; with ``h`` folded into the weights the change is
#: ``|a| exp(h - 700)``, smaller still.
_EXP_FLOOR = -700.0


def _floored_exp(values, floor):
    """``exp(values)`` in place, exponents below ``_EXP_FLOOR`` first raised to
    it (``floor``: an array of ``_EXP_FLOOR`` shaped like ``values``; one read
    each tick, the write only when some exponent is below)."""
    if values.min() < _EXP_FLOOR:
        np.maximum(values, floor, out=values)
    np.exp(values, out=values)


class _Summands:
    """What the exponential groups share: the gates of the tick, the centred
    input and the scatter of the summands' values onto the outputs."""

    def _prepare(self, n_terms):
        """Per-tick lookups and buffers, once ``terms``, ``outputs`` and
        ``columns`` are final."""
        # (summand, velocity column, sigma_v) of every gate
        self.gates = [(t, column, sigma_v) for t, term in enumerate(self.terms)
                      for column, sigma_v in term.gates]
        self.gated = bool(self.gates)
        self.closed = ()
        columns = np.asarray(self.columns)
        self.column_slice = None  # a view of x when the columns are consecutive
        if columns.size and np.array_equal(columns, np.arange(columns[0], columns[-1] + 1)):
            self.column_slice = slice(int(columns[0]), int(columns[-1]) + 1)
        self.xs = np.empty(len(self.columns))
        self.f = np.empty(n_terms)  # value of each summand at x
        # the usual case, summand t on output t: f adds to the outputs as it is
        self.direct = list(self.outputs) == list(range(self.n_outputs))
        self.scatter = np.zeros((n_terms, self.n_outputs))
        self.scatter[np.arange(n_terms), np.asarray(self.outputs, dtype=np.intp)] = 1.0
        self.contribution = np.empty(self.n_outputs)

    def _centred_input(self, x):
        """False when every summand has a closed gate at ``x`` (Eq. 15); else
        the group's columns of ``x``, centred, into ``xs`` and the summands
        with a closed gate into ``closed``."""
        if self.gated:
            self.closed = {t for t, column, sigma_v in self.gates
                           if not quasi_static(x[column], sigma_v)}
            if len(self.closed) == self.f.size:
                return False
        if self.column_slice is not None:
            np.subtract(x[self.column_slice], self.center, out=self.xs)
        else:  # mode="clip": valid indices, and no buffered copy as with "raise"
            np.take(x, self.columns, out=self.xs, mode="clip")
            self.xs -= self.center
        return True

    def _add_summands(self, out):
        """``out[o_t] += f_t``, with ``f_t = 0`` for the summands whose gate is closed."""
        for t in self.closed:
            self.f[t] = 0.0
        if self.direct:
            out += self.f
        else:
            np.matmul(self.f, self.scatter, out=self.contribution)
            out += self.contribution


class _SharedSupportGroup(_Summands):
    """Exponential summands on the same support points and columns (one matrix product).

    Several summands (e.g. the outputs of a regressor conditioned on one
    support set) read the support once. With ``x`` and the rows ``s_i``
    centred, summand ``t`` (inverse squared length scales ``w_t``, weights
    ``a_ti``) is

    .. math::

        f_t(x) = \\sum_i a_{ti} \\exp(e_{ti}), \\quad
        e_{ti} = -\\tfrac12 \\sum_d w_{td} (x_d - s_{id})^2 = g_{ti} + h_{ti},

        g_{ti} = \\big[w_t \\odot x,\\ (x \\odot x)^\\top w_t\\big]
                 \\cdot \\big[s_i,\\ -\\tfrac12\\big], \\quad
        h_{ti} = -\\tfrac12 (s_i \\odot s_i)^\\top w_t \\le 0,

    so one tick is one product ``(n_terms, d + 1) @ (d + 1, n_rows)`` for
    ``g`` (the support transposed, contiguous), one ``exp`` and one
    row-wise dot product with the weights (a batched ``(1, n_rows) @
    (n_rows, 1)`` per summand: no ``n_terms x n_terms`` product for its
    diagonal). The support-only ``h`` goes into the weights,
    :math:`f_t(x) = \\sum_i \\tilde a_{ti} \\exp(g_{ti})` with
    :math:`\\tilde a_{ti} = a_{ti} e^{h_{ti}}`, when that is safe for every
    ``x``: since :math:`e_{ti} \\le 0`, :math:`g_{ti} \\le -h_{ti}`, so with
    every :math:`-h_{ti} \\le` ``_FOLD_LIMIT`` (600) ``exp(g)`` cannot
    overflow and :math:`\\tilde a` stays a normal number (relative rounding
    as for ``exp(g + h)``). Otherwise (short length scales, rows far from
    their mean) ``h`` is added to ``g`` in place each tick.
    """

    def __init__(self, support, columns, n_outputs):
        self.support = support
        self.columns = columns
        self.n_outputs = n_outputs
        self.inv_sq, self.weights, self.outputs, self.terms = [], [], [], []

    def add(self, term, weights, output):
        self.inv_sq.append(term.inv_sq)
        self.weights.append(weights * term.scale * term.gate_values(self.support))
        self.outputs.append(output)
        self.terms.append(term)

    def finalize(self):
        A = np.column_stack(self.weights)
        rows = np.flatnonzero(np.any(A != 0.0, axis=1))
        S = self.support[np.ix_(rows, self.columns)]
        self.center = S.mean(axis=0) if S.shape[0] else np.zeros(len(self.columns))
        S = S - self.center
        n_rows, d = S.shape
        self.W = np.column_stack(self.inv_sq)  # (n_columns, n_terms)
        n_terms = self.W.shape[1]
        self.WT = np.ascontiguousarray(self.W.T)
        self.ST = np.ascontiguousarray(np.vstack([S.T, np.full((1, n_rows), -0.5)]))
        h = -0.5 * ((S**2) @ self.W).T  # (n_terms, n_rows)
        self.AT = np.ascontiguousarray(A[rows].T)
        self.h = None  # folded into the weights, or added to g each tick
        if n_rows and -h.min() <= _FOLD_LIMIT:
            self.AT *= np.exp(h)
        else:
            self.h = np.ascontiguousarray(h)
        self._prepare(n_terms)
        # per-tick buffers, and the views a tick writes through
        self.XW = np.empty((n_terms, d + 1))  # [w_t * x, (x * x) @ w_t] per row
        self.wx, self.wxx = self.XW[:, :d], self.XW[:, d]
        self.G = np.empty((n_terms, n_rows))
        self.floor = np.full_like(self.G, _EXP_FLOOR)  # an array: twice as fast as a scalar
        self.G_rows, self.AT_columns = self.G[:, None, :], self.AT[:, :, None]
        self.f_batched = self.f[:, None, None]
        return self

    @property
    def n_rows(self):
        """Support rows kept (those with a non-zero weight for some kernel)."""
        return self.G.shape[1]

    def add_to(self, x, out):
        if not self._centred_input(x):
            return  # Eq. 15: every gate closed, the group contributes 0
        np.multiply(self.WT, self.xs, out=self.wx)
        np.matmul(self.wx, self.xs, out=self.wxx)
        np.matmul(self.XW, self.ST, out=self.G)  # g_ti, summands x support rows
        if self.h is not None:
            self.G += self.h  # e_ti
        _floored_exp(self.G, self.floor)
        np.matmul(self.G_rows, self.AT_columns, out=self.f_batched)  # f_t
        self._add_summands(out)


class _StackedGroup(_Summands):
    """Exponential summands on the same columns, each on its own support rows.

    Summand ``t`` (output ``o_t``, inverse squared length scales ``w_t``,
    weights ``a_t`` on its own support rows ``s_i``, e.g. the outputs of a
    multi-output regressor with ``support_selection="greedy"``) adds

    .. math::

        f_t(x) = \\sum_i a_{ti} \\exp\\big(-\\tfrac12 \\sum_d w_{td} (x_d - s_{id})^2\\big)

    to output ``o_t``. The rows of all summands are stacked, each pre-scaled
    by its summand's ``w_t``, so one tick is one vector-matrix product over
    every row of every output (the stacked rows transposed, contiguous):

    .. math::

        -\\tfrac12 d^2_t(x, s_i) = \\big[x,\\ 1\\big] \\cdot
        \\big[w_t \\odot s_i,\\ -\\tfrac12 (s_i \\odot s_i)^\\top w_t\\big]
        - \\tfrac12 (x \\odot x)^\\top w_t

    (inputs centred on the rows' mean for accuracy), the last part added to
    each summand's block of rows in place, then one ``exp``, the weights and
    one segmented sum per summand. Rows with a zero weight (gate closed at
    the support point, Eq. 15) are dropped.
    """

    def __init__(self, columns, n_outputs):
        self.columns = columns
        self.n_outputs = n_outputs
        self.supports, self.inv_sq, self.weights, self.outputs, self.terms = [], [], [], [], []

    def add(self, term, support, weights, output):
        self.supports.append(support)
        self.inv_sq.append(term.inv_sq)
        self.weights.append(weights * term.scale * term.gate_values(support))
        self.outputs.append(output)
        self.terms.append(term)

    def finalize(self):
        kept = [np.flatnonzero(a != 0.0) for a in self.weights]
        live = [t for t, rows in enumerate(kept) if rows.size]  # others always add 0
        self.terms = [self.terms[t] for t in live]
        self.outputs = [self.outputs[t] for t in live]
        d = len(self.columns)
        self.ST_hat = np.zeros((d + 1, 0))
        if live:  # else n_rows == 0 and the predictor drops the group
            centred = [self.supports[t][np.ix_(kept[t], self.columns)] for t in live]
            self.center = np.vstack(centred).mean(axis=0)
            centred = [s - self.center for s in centred]
            self.W = np.column_stack([self.inv_sq[t] for t in live])
            self.ST_hat = np.ascontiguousarray(np.vstack([
                np.hstack([c * self.inv_sq[t], -0.5 * (c**2) @ self.inv_sq[t][:, None]])
                for c, t in zip(centred, live)]).T)  # (d + 1, rows): [w_t s_i, c_i]
            self.a = np.concatenate([self.weights[t][kept[t]] for t in live])
            sizes = [kept[t].size for t in live]
            self.starts = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.intp)
        self._prepare(len(live))
        # per-tick buffers, and the views a tick writes through
        self.x1 = np.ones(d + 1)  # [x, 1], x centred
        self.xs = self.x1[:d]
        self.x2 = np.empty(d)
        self.q = np.empty(len(live))
        self.v = np.empty(self.ST_hat.shape[1])
        self.floor = np.full_like(self.v, _EXP_FLOOR)
        bounds = np.append(self.starts, self.v.size) if live else []
        self.blocks = [self.v[lo:hi] for lo, hi in zip(bounds[:-1], bounds[1:])]
        del self.supports, self.weights  # the stacked rows are all a tick needs
        return self

    @property
    def n_rows(self):
        """Rows kept over all summands (those with a non-zero weight)."""
        return self.ST_hat.shape[1]

    def add_to(self, x, out):
        if not self._centred_input(x):
            return  # Eq. 15: every gate closed, the group contributes 0
        np.matmul(self.x1, self.ST_hat, out=self.v)
        np.multiply(self.xs, self.xs, out=self.x2)
        np.matmul(self.x2, self.W, out=self.q)
        self.q *= -0.5  # -0.5 sum_d w_td x_d^2, one per summand
        for block, q in zip(self.blocks, self.q.tolist()):
            block += q  # exponent -0.5 d_t^2(x, s_i) of the summand's rows
        _floored_exp(self.v, self.floor)
        self.v *= self.a
        np.add.reduceat(self.v, self.starts, out=self.f)  # f_t(x) per summand
        self._add_summands(out)


def _groups(blocks, n_outputs):
    """Groups of one column set: a support read by several summands is read once
    (:class:`_SharedSupportGroup`, e.g. the outputs of a GP on one random
    support draw); summands alone on their support (e.g. greedy supports, chosen
    in each output's kernel metric) share one stacked product
    (:class:`_StackedGroup`)."""
    groups, stacked = [], None
    for support, members in blocks:
        columns = members[0][0].columns
        if len(members) > 1:
            group = _SharedSupportGroup(support, columns, n_outputs)
            for term, weights, output in members:
                group.add(term, weights, output)
            groups.append(group)
            continue
        if stacked is None:
            stacked = _StackedGroup(columns, n_outputs)
            groups.append(stacked)
        term, weights, output = members[0]
        stacked.add(term, support, weights, output)
    return groups


def _same(a, b):
    return a is b or (a.shape == b.shape and np.array_equal(a, b))


class _GaussianProcessPredictor:
    """Fast mean of a GP with per-output supports, weights and parametric means."""

    def __init__(self, posteriors, n_features, wrap):

        n_outputs = len(posteriors)
        self.n_outputs = n_outputs
        self.offset = np.array([post.y_mean for post in posteriors], dtype=float)
        self.generic, self.constants = [], []
        by_columns = {}  # column set -> [(support, [(term, weights, output), ...]), ...]
        for j, post in enumerate(posteriors):
            support, weights = post.X_train, post.alpha
            for term in flatten(compile_kernel(post.kernel, lower=False), n_features):
                if term.kernel is not None:
                    self.generic.append((j, term.kernel, support, weights))
                elif term.columns is None:
                    value = term.scale * float(weights @ term.gate_values(support))
                    self.constants.append((j, value, term))
                else:
                    blocks = by_columns.setdefault(tuple(term.columns.tolist()), [])
                    block = next((b for b in blocks if _same(b[0], support)), None)
                    if block is None:
                        blocks.append(block := (support, []))
                    block[1].append((term, weights, j))
        groups = (g.finalize() for blocks in by_columns.values()
                  for g in _groups(blocks, n_outputs))
        self.groups = [g for g in groups if g.n_rows]  # no row, no contribution
        self.states = {}  # rigid-body features shared by the means of one robot
        self.means = [_compile_mean(post.mean, wrap, self.states) for post in posteriors]
        self.row = np.empty((1, n_features))
        self.live_means = [(j, mean) for j, mean in enumerate(self.means) if mean is not None]

    def predict_one(self, x, out):
        np.copyto(out, self.offset)
        for group in self.groups:
            group.add_to(x, out)
        for j, value, term in self.constants:
            if term.gates_open(x):
                out[j] += value
        if self.generic:
            self.row[0] = x
            for j, kernel, support, weights in self.generic:
                out[j] += float(kernel(self.row, support)[0] @ weights)
        for state in self.states.values():  # one pinocchio call per robot and tick
            state.update(x)
        for j, mean in self.live_means:
            out[j] += mean(x, self.row)
        return out


def _rigid_body_mean(mean, states):
    """``phi-bar(x) @ coef + intercept`` with the rigid-body row of this tick (Eq. 17)."""
    features = mean.features_.sample_features()
    state = states.setdefault(features.key, _SampleState(features))
    row, columns, scale = int(features.rows[0]), features.columns, float(features.scale[0])
    # the coefficients on every column of the full row (0 on the others), and
    # the same with the friction columns zeroed (phi-bar, Eq. 17): one dot a tick
    coef = np.zeros(features.full.n_parameters)
    coef[columns] = np.asarray(mean.coef_, dtype=float) * scale
    coef_bar = coef.copy()
    coef_bar[columns[np.asarray(mean.friction_columns_, dtype=int)]] = 0.0
    intercept = float(mean.intercept_)
    velocity, sigma_v = mean.velocity_column_, mean.sigma_v

    def rigid_body(x, _row):
        static = velocity is not None and quasi_static(x[velocity], sigma_v)
        return float(state.value[row] @ (coef_bar if static else coef)) + intercept

    return rigid_body


class _SampleState:
    """The full rigid-body features at the current tick, shared by several means."""

    def __init__(self, features):
        self.features = features
        self.value = None

    def update(self, x):
        f = self.features
        self.value = f.full(x[f.q], x[f.qd], x[f.qdd], out=self.value)  # in place after the first


def _compile_mean(mean, wrap, states):
    """``x -> m(x)`` of one output: fast paths for plain ParametricMean.

    A linear mean on the inputs is one dot product; a rigid-body mean
    (:class:`~sklearn_gpcd.dynamics.RigidBodyFeatures` features, Eq. 10 and
    17) reads the regressor row of its joint from a per-tick evaluation
    (``states``) shared by every mean of the same robot; the controller
    mean of SP_C is one product. Anything else calls ``mean.predict``.
    """
    if mean is None:
        return None

    coef = getattr(mean, "coef_", None)
    plain = type(mean) is ParametricMean and np.ndim(coef) == 1
    if plain and type(mean.features_) is RigidBodyFeatures and mean.features_.joint is not None:
        return _rigid_body_mean(mean, states)
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
            if velocity is not None and quasi_static(x[velocity], sigma_v):  # phi-bar, Eq. 17
                np.take(x, friction, out=xf)
                value -= float(friction_coef @ xf)
            return value

        return linear

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


def _gp_posteriors(regressor):
    """The per-output :class:`~sklearn_gpcd.gp.GPPosterior` of a fitted GP, or None."""

    if isinstance(regressor, SemiParametricGPRegressor):
        return regressor.posteriors_
    if type(regressor) is not GaussianProcessRegressor:
        return None
    alpha = regressor.alpha_.reshape(regressor.alpha_.shape[0], -1)
    K = regressor.kernel_(regressor.X_train_)
    if not regressor.normalize_y:
        offset, scale = np.zeros(alpha.shape[1]), np.ones(alpha.shape[1])
    else:
        # predict(X) = scale * K(X, X_train) alpha_ + offset: both from
        # predictions at a few support rows (sklearn keeps them private)
        rows = slice(None, None, max(1, len(K) // 8))
        predicted = np.reshape(regressor.predict(regressor.X_train_[rows]), (-1, alpha.shape[1]))
        standard = K[rows] @ alpha
        offset, scale = np.empty(alpha.shape[1]), np.empty(alpha.shape[1])
        for j in range(alpha.shape[1]):
            design = np.column_stack([standard[:, j], np.ones(len(standard))])
            (scale[j], offset[j]), *_ = np.linalg.lstsq(design, predicted[:, j], rcond=None)
    return [
        GPPosterior(regressor.kernel_, regressor.X_train_, scale[j] * alpha[:, j], offset[j])
        for j in range(alpha.shape[1])
    ]


def _identity(X):
    return X


def _unwrap(regressor):
    """The fitted estimator inside :class:`sklearn.frozen.FrozenEstimator` wrappers.

    A frozen estimator's ``predict`` is its inner estimator's, so the
    compiled path of the inner one applies (and is checked against the
    wrapper's own ``predict``).
    """
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
        Inputs on which the compiled path is compared with the reference:
        for a GP, :meth:`~sklearn_gpcd.gp.GPPosterior.predict_mean` of each
        output (the Kernel objects, ``K(x, X_train) @ alpha``), else
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
    posteriors = _gp_posteriors(inner)
    reference = regressor.predict
    if posteriors is not None and len(posteriors) == n_outputs:
        predictor = _GaussianProcessPredictor(posteriors, n_features, wrap)
        kind = "gaussian_process"
        support = posteriors[0].X_train
        rows = support[:: max(1, len(support) // 8)]
        check_rows = rows if check_rows is None else np.vstack([check_rows, rows])

        def reference(X_mean):  # the Kernel objects, not another compiled copy
            X = np.asarray(X_mean, dtype=float)
            return np.column_stack([post.predict_mean(X, X_mean) for post in posteriors])

    elif hasattr(inner, "coef_") and hasattr(inner, "intercept_"):
        coef = np.asarray(inner.coef_)
        if coef.size == n_features * n_outputs:
            predictor, kind = _LinearPredictor(coef, inner.intercept_, n_outputs), "linear"
    if predictor is not None and check_rows is not None and len(check_rows):
        expected = reference(wrap(check_rows))
        expected = np.reshape(expected, (len(check_rows), n_outputs))
        got = np.array([predictor.predict_one(x, np.empty(n_outputs)) for x in check_rows])
        # the GP mean sums large weights of both signs: compare at the
        # precision that conditioning leaves to predict() itself
        scale = np.max(np.abs(expected)) + 1.0
        if not np.allclose(got, expected, rtol=1e-6, atol=1e-6 * scale):
            warnings.warn(
                f"the fast single-sample path for {type(regressor).__name__} disagrees "
                "with its kernel and mean objects; StreamingMonitor falls back to "
                "predict() per tick",
                RuntimeWarning,
            )
            predictor, kind = None, "generic"
    if predictor is None:
        predictor = _GenericPredictor(regressor, n_features, n_outputs, wrap)
    predictor.kind = kind
    return predictor
