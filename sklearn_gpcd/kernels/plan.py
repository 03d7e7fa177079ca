r"""The compiled kernel algebra: one registry from kernel type to node.

:func:`compile_kernel` turns a kernel tree into a tree of *nodes*, one per
kernel, looked up in one registry (:func:`register_node`). Every fast path
of the package evaluates a kernel through its node:

* the fit (:mod:`sklearn_gpcd.gp`): the Gram matrix (:func:`gram_matrix`)
  and the log-marginal-likelihood gradient contracted per node
  (:meth:`_Node.contract`, also behind :func:`~sklearn_gpcd.kernels.contract_gradient`);
* the data-driven initial hyperparameters of the optimizer
  (:meth:`_Node.init_hyperparameters`);
* ``predict``: cross-covariances and :math:`k_*^T w` (:meth:`_Node.prepare`,
  :meth:`_Node.cross`, :meth:`_Node.cross_dot`, with a one-row path);
* the streaming monitor (:mod:`sklearn_gpcd.detection`): the kernel
  flattened into terms ``c * gates * exp(-0.5 d^2)`` (:meth:`_Node.terms`,
  :class:`Term`) that it batches across outputs.

**Registry and dispatch.** The registry maps an *exact* kernel type to its
node class and to the kernel parameters the node understands. A subclass of
a registered kernel is not matched (it may override ``__call__``): it is
evaluated as an opaque node, through the Kernel object itself, unless it is
registered too (:func:`register_node` is the explicit opt-in). A registered
kernel whose parameters differ from those declared (e.g. a parameter added
to :class:`~sklearn_gpcd.kernels.ARDRBF` but not to its node) is opaque too.
An opaque node without an explicit registration emits one
:class:`OpaqueKernelWarning` per kernel type. Nodes read the structure of
their kernel (columns, gate column and threshold) from the Kernel object at
compile time; hyperparameter values come from ``theta``
(:meth:`_Node.set_theta`, laid out like ``kernel.theta``), so optimizers do
not rebuild kernel objects at every step. The gate of Eq. 15 is
:func:`sklearn_gpcd._gate.quasi_static`, the function
:meth:`QuasiStaticGate.gate <sklearn_gpcd.kernels.QuasiStaticGate.gate>` uses.

The nodes compute exactly what the kernels compute (the parity property
test checks it on random trees), but

* **without copies of constants**: a ``ConstantKernel`` stays a scalar and a
  ``WhiteKernel`` a diagonal, so ``C * ARDRBF + White`` costs one ``n x n``
  array, not four;
* **keeping the parts the gradient needs** (``gram(X, keep=True)``): the
  log-marginal-likelihood gradient (R&W Eq. 5.9)

  .. math::

      \partial_{\theta_k} \log p = \tfrac12 \sum_{ij} W_{ij}
      \frac{\partial K_{ij}}{\partial \theta_k}, \qquad W = a a^T - K_y^{-1},

  is contracted per node with the node values already computed for
  :math:`K`, never forming the ``(n, n, n_theta)`` array. For a
  squared-exponential block (Eq. 11) with scaled inputs
  :math:`z_{id} = x_{id} / l_d` and :math:`M = W \circ K`, all length scales
  come from one matrix product, as

  .. math::

      \sum_{ij} M_{ij} (z_{id} - z_{jd})^2
      = \sum_i z_{id}^2 \big(\textstyle\sum_j M_{ij} + M_{ji}\big)
        - 2\, z_{\cdot d}^T M z_{\cdot d};

* **touching each ``(n, n)`` array as few times as possible**: a
  squared-exponential Gram matrix is built row block by row block, each
  block in cache while it is multiplied, shifted, exponentiated and scaled
  (:func:`_se_gram`), and the gradient contraction above runs on the same
  blocks without forming :math:`M`; for the common sums of
  :math:`c\,K_{SE}`, constants and noise, only the lower triangles are
  computed while optimising (LAPACK reads and returns those), and arrays are
  reused from one likelihood evaluation to the next;
* **evaluating only what a prediction needs**: the posterior mean
  :math:`k_*^T w` is a sum over blocks, each with its support points scaled
  once; a :class:`~sklearn_gpcd.kernels.QuasiStaticGate` block (Eq. 16) is
  evaluated only for the queries whose gate :math:`a_\ell(x_*)` is 1,
  against the gated support points only.

Examples
--------
>>> import numpy as np
>>> from sklearn.gaussian_process.kernels import ConstantKernel, WhiteKernel
>>> from sklearn_gpcd.kernels import ARDRBF, QuasiStaticGate
>>> from sklearn_gpcd.kernels.plan import compile_kernel, gram_matrix
>>> kernel = ConstantKernel(2.0) * QuasiStaticGate(ARDRBF(1.0, columns=[0]), 1) + WhiteKernel()
>>> X = np.array([[0.0, 0.0], [1.0, 0.005], [2.0, 0.5]])
>>> plan = compile_kernel(kernel)
>>> bool(np.allclose(gram_matrix(plan, X), kernel(X)))
True
>>> [(t.scale, t.gates) for t in plan.terms(n_features=2)]
[(2.0, ((1, 0.01),))]
"""

import inspect
import math
import warnings

import numpy as np
from scipy.spatial.distance import cdist, pdist, squareform
from sklearn.gaussian_process.kernels import (
    RBF,
    ConstantKernel,
    Exponentiation,
    Product,
    Sum,
    WhiteKernel,
)

from .._gate import quasi_static
from .ard import ARDRBF
from .columns import is_anisotropic
from .gate import QuasiStaticGate
from .parametric import ParametricKernel

__all__ = [
    "compile_kernel",
    "gram_matrix",
    "register_node",
    "registered_node",
    "OpaqueKernelWarning",
    "Term",
]

#: Largest half squared norm of scaled, centred coordinates for which cross
#: kernels use the expansion |z - s|^2 = |z|^2 + |s|^2 - 2 z.s (one matrix
#: product): its round-off, ~4 eps |z|^2, stays below 1e-9 in the exponent.
_EXPANSION_MAX = 1e6
#: Largest half squared norm of a scaled query for the one-row prediction
#: path, which exponentiates up to it before scaling (exp(700) < 1.8e308).
_ROW_MAX_HALF_NORM = 700.0


class OpaqueKernelWarning(UserWarning):
    """A kernel has no compiled node and is evaluated through its own object.

    Emitted once per kernel type. The results are the same, but the fit
    forms the kernel's full ``(n, n, n_theta)`` gradient and predictions
    call the kernel object. Register a node with :func:`register_node`, or
    register the type as opaque (``register_node(kind, None)``) to silence it.

    Examples
    --------
    >>> import warnings
    >>> import numpy as np
    >>> from sklearn.gaussian_process.kernels import RBF
    >>> from sklearn_gpcd.kernels import OpaqueKernelWarning
    >>> from sklearn_gpcd.kernels.plan import compile_kernel
    >>> class MyRBF(RBF):                      # a subclass is not matched
    ...     pass
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     _ = compile_kernel(MyRBF(1.0))
    >>> any(issubclass(w.category, OpaqueKernelWarning) for w in caught)
    True
    """


#: exact kernel type -> (node class, names of the kernel parameters it reads)
_REGISTRY = {}
#: kernel types already warned about (OpaqueKernelWarning once per type)
_WARNED = set()


def register_node(kernel_type, node_class, params=None):
    """Register the compiled node of a kernel type (exact type; no subclasses).

    Parameters
    ----------
    kernel_type : type
        A :class:`sklearn.gaussian_process.kernels.Kernel` class.
    node_class : type or None
        The node class, constructed as ``node_class(kernel)``; None marks
        the type as known to be opaque (evaluated through the Kernel object,
        no :class:`OpaqueKernelWarning`).
    params : iterable of str, default=None
        The kernel parameters (``get_params(deep=False)``) the node reads. A
        kernel with other parameters falls back to the opaque node, so a
        parameter added to the kernel class cannot silently be ignored.
        None: those of the class today.

    Examples
    --------
    How :class:`~sklearn_gpcd.kernels.ARDRBF` is registered (a kernel
    without a node would be ``register_node(MyKernel, None)``):

    >>> from sklearn_gpcd.kernels import ARDRBF
    >>> node, params = registered_node(ARDRBF)
    >>> node.__name__, sorted(params)
    ('_SquaredExponential', ['columns', 'length_scale', 'length_scale_bounds'])
    """
    if params is None:  # the constructor's parameters, as get_params reads them
        signature = inspect.signature(kernel_type.__init__).parameters.values()
        params = [p.name for p in signature if p.name != "self" and p.kind != p.VAR_KEYWORD]
    _REGISTRY[kernel_type] = (node_class, frozenset(params))


def registered_node(kernel_type):
    """``(node class or None, params)`` registered for ``kernel_type``, else None.

    Examples
    --------
    >>> from sklearn.gaussian_process.kernels import Matern
    >>> registered_node(Matern) is None  # evaluated through Matern itself, with a warning
    True
    """
    return _REGISTRY.get(kernel_type)


def compile_kernel(kernel, lower=True):
    """Compiled mirror of ``kernel`` (with its current hyperparameters).

    Parameters
    ----------
    kernel : Kernel
        A kernel whose columns are integer indices (see
        :func:`~sklearn_gpcd.kernels.resolve_columns`); a node given by
        name is opaque.
    lower : bool, default=True
        Let trees that allow it work on lower triangles while optimising
        (see :func:`gram_matrix`); False when the gradient weights ``W``
        passed to ``contract`` are full matrices.

    Returns
    -------
    plan : _Node
        Root of the compiled tree; ``plan.n_dims == kernel.n_dims``.
        ``plan.lower`` tells whether, while optimising, it works on lower
        triangles only.
    """
    plan = _compile(kernel)
    if lower and _lower_ready(plan):
        _set_lower(plan)
    return plan


class _NotCompilable(Exception):
    """Raised by a node constructor for a kernel it cannot mirror (e.g. str columns)."""


def _compile(kernel):
    entry = _REGISTRY.get(type(kernel))
    node_class, params = entry if entry is not None else (None, frozenset())
    if node_class is not None and set(kernel.get_params(deep=False)) == params:
        try:
            return node_class(kernel)
        except _NotCompilable:
            return _Opaque(kernel)
    if entry is None or node_class is not None:
        _warn_opaque(kernel)
    return _Opaque(kernel)


def _warn_opaque(kernel):
    kind = type(kernel)
    if kind in _WARNED:
        return
    _WARNED.add(kind)
    warnings.warn(
        f"{kind.__name__} has no compiled node (sklearn_gpcd.kernels.plan); it is "
        "evaluated through the kernel object, with its full gradient array while "
        "fitting. Register a node, or register_node(kind, None) to silence this.",
        OpaqueKernelWarning,
        stacklevel=3,
    )


def _lower_ready(node):
    r"""Whether every node can optimise on lower triangles: sums of constants,
    white noise, squared exponentials and products :math:`c\,K_{SE}`.

    Only the lower triangle of :math:`K` is needed: LAPACK factorises it
    and its inverse comes back in it, so a tree of such nodes computes half
    of each Gram matrix and contracts the gradient on half of
    :math:`W` (see :meth:`_SquaredExponential.contract`); the triangle is
    never mirrored.
    """
    if isinstance(node, (_Constant, _White, _SquaredExponential)):
        return True
    if isinstance(node, _Sum):
        return _lower_ready(node.k1) and _lower_ready(node.k2)
    return isinstance(node, _Product) and node._scaled_exponential() is not None


def _set_lower(node):
    node.lower = True
    for child in (getattr(node, "k1", None), getattr(node, "k2", None)):
        if child is not None:
            _set_lower(child)


# -- values: a float (same value everywhere), a _Diagonal, or an ndarray ----


class _Diagonal:
    """A diagonal matrix, e.g. the Gram matrix of a ``WhiteKernel``."""

    def __init__(self, values):
        self.values = values


class _RowBlock:
    """A square matrix that is zero outside ``rows x rows`` (a gated Gram matrix).

    Kept as the block alone so that adding it to a dense Gram matrix (Eq. 17:
    kinematic + gated quasi-static term) needs no second ``(n, n)`` array.
    """

    def __init__(self, n, rows, block):
        self.n, self.rows, self.block = n, rows, block


def _dense(value, n_rows, n_cols):
    """A value as an ``(n_rows, n_cols)`` array (a new one for scalars/diagonals)."""
    if isinstance(value, np.ndarray):
        return value
    if isinstance(value, _RowBlock):
        out = np.zeros((n_rows, n_cols))
        out[np.ix_(value.rows, value.rows)] = value.block
        return out
    if isinstance(value, _Diagonal):
        out = np.zeros((n_rows, n_cols))
        out[np.diag_indices(n_rows)] = value.values
        return out
    return np.full((n_rows, n_cols), float(value))


def _add(a, b, inplace):
    """a + b for values; reuses an array operand when ``inplace``."""
    if isinstance(a, _RowBlock) or isinstance(b, _RowBlock):
        if isinstance(a, _RowBlock):
            a, b = b, a
        if isinstance(a, np.ndarray):
            out = a if inplace else a.copy()
        else:  # a scalar, a diagonal or another gated block: a new array
            out = _dense(a, b.n, b.n)
        out[np.ix_(b.rows, b.rows)] += b.block
        return out
    if isinstance(a, _Diagonal) and isinstance(b, _Diagonal):
        return _Diagonal(a.values + b.values)
    if isinstance(b, np.ndarray) and not isinstance(a, np.ndarray):
        a, b = b, a
    if isinstance(a, np.ndarray):
        out = a if inplace else a.copy()
        if isinstance(b, _Diagonal):
            out[np.diag_indices_from(out)] += b.values
        else:
            out += b
        return out
    if isinstance(b, _Diagonal):
        a, b = b, a
    if isinstance(a, _Diagonal):  # scalar + diagonal
        out = np.full((len(a.values), len(a.values)), float(b))
        out[np.diag_indices_from(out)] += a.values
        return out
    return a + b


def _multiply(a, b, inplace):
    """Elementwise a * b for values; reuses an array operand when ``inplace``."""
    if isinstance(a, _RowBlock) or isinstance(b, _RowBlock):
        if isinstance(a, _RowBlock):
            a, b = b, a
        if isinstance(a, _RowBlock):  # two gated blocks: new dense arrays
            return _multiply(_dense(a, a.n, a.n), _dense(b, b.n, b.n), inplace=True)
        if np.ndim(a) == 0 and not isinstance(a, _Diagonal):  # c * gated block
            block = b.block if inplace else b.block.copy()
            block *= float(a)
            return _RowBlock(b.n, b.rows, block)
        return _multiply(a, _dense(b, b.n, b.n), inplace)
    if isinstance(b, _Diagonal) and not isinstance(a, _Diagonal):
        a, b = b, a
    if isinstance(a, _Diagonal):
        if isinstance(b, _Diagonal):
            return _Diagonal(a.values * b.values)
        if isinstance(b, np.ndarray):
            return _Diagonal(a.values * np.diag(b))
        return _Diagonal(a.values * b)
    if isinstance(b, np.ndarray) and not isinstance(a, np.ndarray):
        a, b = b, a
    if isinstance(a, np.ndarray):
        if inplace:
            a *= b
            return a
        return a * b
    return a * b


def mirror_upper(A, tile=256):
    """Copy the strict upper triangle of the square ``A`` onto its lower one, in place.

    Tile by tile, so that the transposed reads stay in cache (a plain
    ``A += A.T`` is several times slower for n in the thousands).
    Package-internal (not in ``__all__``): the GP's likelihood uses it too.
    """
    n = A.shape[0]
    for i in range(0, n, tile):
        i_end = min(i + tile, n)
        block = A[i:i_end, i:i_end]
        lower = np.tril_indices(i_end - i, -1)
        block[lower] = block.T[lower]
        for j in range(i_end, n, tile):
            j_end = min(j + tile, n)
            A[j:j_end, i:i_end] = A[i:i_end, j:j_end].T
    return A


#: Bytes of one row block of the fused Gram and gradient loops: small enough
#: to stay in a core's L2 cache while every elementwise step runs on it.
_BLOCK_BYTES = 256 * 1024


def _row_blocks(n_rows, n_cols):
    """Slices of ``n_rows`` rows, each of about :data:`_BLOCK_BYTES` at ``n_cols`` columns."""
    step = max(1, _BLOCK_BYTES // (8 * max(n_cols, 1)))
    return [slice(start, min(start + step, n_rows)) for start in range(0, n_rows, step)]


def _se_gram(Z, out, scaled=None, lower=False):
    r""":math:`K_{ij} = \exp(-\tfrac12 \|z_i - z_j\|^2)` for the rows of the centred ``Z``.

    Row block by row block of the lower triangle, so that all steps run on
    data in cache: one matrix product :math:`z_i^T z_j`, minus
    :math:`\tfrac12 \|z_i\|^2 + \tfrac12 \|z_j\|^2`, clipped at 0
    (round-off) and exponentiated, several times faster than separate passes
    over the ``(n, n)`` array; then mirrored (exactly symmetric) unless
    ``lower``. When the coordinates are so large that the expansion's
    round-off would matter (see :data:`_EXPANSION_MAX`), exact differences
    (``pdist``), as scikit-learn's ``RBF``.

    Parameters
    ----------
    Z : ndarray of shape (n, d)
        Scaled, centred inputs.
    out : ndarray of shape (n, n)
        C-contiguous array written over and returned.
    scaled : (float, ndarray of shape (n, n)), default=None
        ``(c, out_c)``: also write :math:`c K` into ``out_c`` (in the same pass).
    lower : bool, default=False
        Compute the lower triangle only (row block ``i:j``, columns ``:j``);
        the rest of ``out`` (and of ``out_c``) is left as it was.
    """
    half_norm = 0.5 * np.einsum("id,id->i", Z, Z)
    if np.max(half_norm, initial=0.0) > _EXPANSION_MAX:
        d = pdist(Z, metric="sqeuclidean")
        d *= -0.5
        out[...] = squareform(d)
        np.exp(out, out=out)
        if scaled is not None:
            np.multiply(out, scaled[0], out=scaled[1])
        return out
    Z_T = np.ascontiguousarray(Z.T)
    for rows in _row_blocks(*out.shape):
        cols = slice(0, rows.stop)
        block = out[rows, cols]
        np.matmul(Z[rows], Z_T[:, cols], out=block)
        block -= half_norm[rows, np.newaxis] + half_norm[cols]
        np.minimum(block, 0.0, out=block)
        np.exp(block, out=block)
        diagonal = np.arange(rows.stop - rows.start)
        block[diagonal, rows.start + diagonal] = 1.0
        if scaled is not None:
            np.multiply(block, scaled[0], out=scaled[1][rows, cols])
    if not lower:  # the transposes are Fortran-ordered with the triangle above
        mirror_upper(out.T)
        if scaled is not None:
            mirror_upper(scaled[1].T)
    return out


def _kept_array(owner, name, shape):
    """An array stored as ``owner.<name>``, reused while its shape stays ``shape``.

    Zeros when new, so that entries a lower-triangle plan never writes stay
    finite.
    """
    array = getattr(owner, name, None)
    if array is None or array.shape != shape:
        array = np.zeros(shape)
        setattr(owner, name, array)
    return array


def _weighted_total(W, K, lower):
    r""":math:`\sum_{ij} W_{ij} K_{ij}` for symmetric ``W`` and ``K`` (``K=None``: ones).

    With ``lower``, ``W`` holds its lower triangle and zeros above it: the
    total is twice the lower sum less the diagonal.
    """
    total = W.sum() if K is None else np.vdot(W, K)
    if not lower:
        return total
    diagonal = np.trace(W) if K is None else np.diag(W) @ np.diag(K)
    return 2.0 * total - diagonal


# -- nodes -----------------------------------------------------------------


class _Node:
    """Base of the compiled nodes.

    Methods
    -------
    set_theta(theta)
        Log-hyperparameters of this subtree (``kernel.theta`` layout).
    gram(X, keep)
        ``k(X, X)`` as a value; with ``keep`` the node keeps what
        :meth:`contract` needs and its returned arrays must not be modified.
    contract(W, scale)
        ``scale * sum_ij W_ij dK_ij/dtheta`` after ``gram(X, keep=True)``.
    prepare(S, weights)
        Cache support-side data (and the posterior weights) for predictions.
    cross(Q)
        ``k(Q, S)`` as a value.
    cross_dot(Q)
        ``k(Q, S) @ weights``, shape (n_queries,).
    diag(Q)
        Diagonal of ``k(Q, Q)``, a float or an array.
    terms(n_features)
        The node as a list of :class:`Term` for the streaming monitor, or
        None when it cannot be flattened.
    init_hyperparameters(X, rng, max_rows)
        Data-driven initial hyperparameters, set on the wrapped Kernel
        objects (the optimizer's starting point).

    Attributes
    ----------
    kernel : Kernel
        The kernel this node mirrors.
    """

    n_dims = 0
    #: while optimising (``gram(X, keep=True)`` and ``contract``), Gram
    #: matrices and W are valid in their lower triangle only
    lower = False

    def set_theta(self, theta):  # pragma: no cover - overridden when n_dims
        pass

    def is_scalar(self):
        """Whether every value of this node is one float (a constant)."""
        return False

    def zero_cross(self):
        """Whether ``k(Q, S)`` is identically zero (a ``WhiteKernel``)."""
        return False

    def cross_dot(self, Q):
        return _dense(self.cross(Q), Q.shape[0], self._n_support) @ self._weights

    def row_leaf(self):
        """The node whose ``cross_dot`` equals this one's, fewest calls down (after prepare)."""
        return self

    def children(self):
        """The child nodes (sum, product and gate nodes have some)."""
        return ()

    def terms(self, n_features):
        return None

    def init_hyperparameters(self, X, rng, max_rows):
        for child in self.children():
            child.init_hyperparameters(X, rng, max_rows)


class _Pair(_Node):
    """A node of two children whose theta is ``k1``'s followed by ``k2``'s."""

    def __init__(self, kernel):
        self.kernel = kernel
        self.k1, self.k2 = k1, k2 = _compile(kernel.k1), _compile(kernel.k2)
        self.n_dims = k1.n_dims + k2.n_dims

    def children(self):
        return (self.k1, self.k2)

    def set_theta(self, theta):
        self.k1.set_theta(theta[: self.k1.n_dims])
        self.k2.set_theta(theta[self.k1.n_dims :])


class _Sum(_Pair):
    """:math:`k_1 + k_2`."""

    def gram(self, X, keep):
        v1, v2 = self.k1.gram(X, keep), self.k2.gram(X, keep)
        # an array may be updated in place unless a child keeps it for
        # ``contract``; sums and products return arrays no other node keeps
        if isinstance(v1, np.ndarray):
            inplace = not keep or isinstance(self.k1, _Pair)
        else:  # _add puts an array v2 first
            inplace = not keep or isinstance(self.k2, _Pair)
        return _add(v1, v2, inplace=inplace)

    def contract(self, W, scale):
        parts = [k.contract(W, scale) for k in (self.k1, self.k2) if k.n_dims]
        return np.concatenate(parts) if parts else np.empty(0)

    def prepare(self, S, weights):
        self.k1.prepare(S, weights)
        self.k2.prepare(S, weights)
        # children with k(Q, S) == 0 (a WhiteKernel) are left out of k(Q, S) w
        self._live = [k for k in (self.k1, self.k2) if not k.zero_cross()]

    def zero_cross(self):
        return self.k1.zero_cross() and self.k2.zero_cross()

    def cross(self, Q):
        return _add(self.k1.cross(Q), self.k2.cross(Q), inplace=True)

    def row_leaf(self):
        return self._live[0].row_leaf() if len(self._live) == 1 else self

    def cross_dot(self, Q):
        if len(self._live) == 1:
            return self._live[0].cross_dot(Q)
        if not self._live:
            return np.zeros(Q.shape[0])
        return self.k1.cross_dot(Q) + self.k2.cross_dot(Q)

    def diag(self, Q):
        return self.k1.diag(Q) + self.k2.diag(Q)

    def terms(self, n_features):
        # a child that cannot be flattened is one term evaluated by its kernel
        return [t for k in (self.k1, self.k2) for t in flatten(k, n_features)]


class _Product(_Pair):
    r""":math:`k_1 k_2`; :math:`c\,K_{SE}` is computed in one pass while optimising."""

    def gram(self, X, keep):
        if keep and self._scaled_exponential() is not None:
            return self._scaled_exponential_gram(X)
        v1, v2 = self.k1.gram(X, keep), self.k2.gram(X, keep)
        if keep:
            self._v1, self._v2, self._n = v1, v2, X.shape[0]
        return _multiply(v1, v2, inplace=not keep)

    def _scaled_exponential(self):
        """``(constant, squared exponential)`` children of ``C * RBF``, else None."""
        for c, k in ((self.k1, self.k2), (self.k2, self.k1)):
            if isinstance(c, _Constant) and isinstance(k, _SquaredExponential):
                return c, k
        return None

    def _scaled_exponential_gram(self, X):
        """:math:`c K` while optimising: computed with the kept :math:`K` in one
        pass, into memory reused across evaluations of one size."""
        constant, exponential = self._scaled_exponential()
        n = X.shape[0]
        buffer = _kept_array(self, "_buffer", (n, n))
        c = constant.gram(X, True)
        K = exponential.gram(X, True, scaled=(c, buffer))
        self._v1, self._v2 = (c, K) if constant is self.k1 else (K, c)
        self._n = n
        return buffer

    def contract(self, W, scale):
        parts = {}
        # the constant last: its gradient, c sum(W o K), may come from K's contraction
        for child, other in sorted(((self.k1, self._v2), (self.k2, self._v1)),
                                   key=lambda pair: pair[0].is_scalar()):
            if not child.n_dims:
                continue
            if child.is_scalar() and isinstance(other, np.ndarray):
                # d(c K)/d log c = c K: the gradient is c sum(W o K), one dot
                # product instead of the (n, n) array W o K
                parts[id(child)] = [scale * child.value * self._weighted_sum(W, other)]
            elif isinstance(other, (np.ndarray, _Diagonal)):
                parts[id(child)] = child.contract(W * _dense(other, self._n, self._n), scale)
            else:  # a scalar factor: fold it into the scale
                parts[id(child)] = child.contract(W, scale * other)
        ordered = [parts[id(k)] for k in (self.k1, self.k2) if id(k) in parts]
        return np.concatenate(ordered) if ordered else np.empty(0)

    def _weighted_sum(self, W, K):
        r""":math:`\sum_{ij} W_{ij} K_{ij}`, from the other child's contraction if it has it."""
        for child in (self.k1, self.k2):
            total = getattr(child, "_W_dot_K", None)
            if total is not None and total[0] is W and child._K is K:
                return total[1]
        return _weighted_total(W, K, self.lower)

    def prepare(self, S, weights):
        self._n_support, self._weights = S.shape[0], weights
        self._buffer = self._v1 = self._v2 = None  # arrays of the fit
        # a constant factor c is folded into the weights: (c K) w = K (c w)
        self._other = None
        if self.k1.is_scalar():
            self._other = self.k2
            self.k2.prepare(S, self.k1.value * weights)
            self.k1.prepare(S, weights)
        elif self.k2.is_scalar():
            self._other = self.k1
            self.k1.prepare(S, self.k2.value * weights)
            self.k2.prepare(S, weights)
        else:
            self.k1.prepare(S, weights)
            self.k2.prepare(S, weights)

    def zero_cross(self):
        return self.k1.zero_cross() or self.k2.zero_cross()

    def cross(self, Q):
        return _multiply(self.k1.cross(Q), self.k2.cross(Q), inplace=True)

    def row_leaf(self):
        return self if self._other is None else self._other.row_leaf()

    def cross_dot(self, Q):
        if self._other is not None:
            return self._other.cross_dot(Q)
        return super().cross_dot(Q)

    def diag(self, Q):
        return self.k1.diag(Q) * self.k2.diag(Q)

    def terms(self, n_features):
        left, right = self.k1.terms(n_features), self.k2.terms(n_features)
        if left is None or right is None:
            return None
        products = [a * b for a in left for b in right]
        return None if any(t is None for t in products) else products


class _ScalarParameter(_Node):
    """A kernel of one positive hyperparameter, ``value`` (log-scale in theta)."""

    #: name of the kernel parameter held as ``value``
    parameter = None

    def __init__(self, kernel):
        self.kernel = kernel
        self.value = float(getattr(kernel, self.parameter))
        self.n_dims = kernel.n_dims

    def set_theta(self, theta):
        if self.n_dims:
            self.value = float(np.exp(theta[0]))


class _Constant(_ScalarParameter):
    """``ConstantKernel``: one float, never an array."""

    parameter = "constant_value"

    def gram(self, X, keep):
        return self.value

    def contract(self, W, scale):
        return np.array([scale * self.value * _weighted_total(W, None, self.lower)])

    def prepare(self, S, weights):
        self._n_support, self._weights = S.shape[0], weights
        self._weights_sum = float(np.sum(weights))

    def cross(self, Q):
        return self.value

    def cross_dot(self, Q):
        return np.full(Q.shape[0], self.value * self._weights_sum)

    def diag(self, Q):
        return self.value

    def is_scalar(self):
        return True

    def terms(self, n_features):
        return [Term(scale=self.value)]


class _White(_ScalarParameter):
    """``WhiteKernel``: a diagonal; no covariance between distinct arguments."""

    parameter = "noise_level"

    def gram(self, X, keep):
        return _Diagonal(np.full(X.shape[0], self.value))

    def contract(self, W, scale):
        return np.array([scale * self.value * np.trace(W)])

    def prepare(self, S, weights):
        self._n_support = S.shape[0]

    def cross(self, Q):  # scikit-learn: no noise between distinct arguments
        return 0.0

    def zero_cross(self):
        return True

    def cross_dot(self, Q):
        return np.zeros(Q.shape[0])

    def diag(self, Q):
        return self.value

    def terms(self, n_features):
        return []  # k(x, s) = 0 between a new point and the support points


class _SquaredExponential(_Node):
    r""":math:`\exp(-\tfrac12 \sum_d (x_d - x'_d)^2 / l_d^2)` on some columns (Eq. 11)."""

    def __init__(self, kernel):
        self.kernel = kernel
        columns = getattr(kernel, "columns", None)
        if columns is not None:
            columns = np.atleast_1d(np.asarray(columns))
            if columns.dtype.kind not in "iu":  # names: resolve_columns first
                raise _NotCompilable
        self.columns = None if columns is None else columns.astype(np.intp)
        self.length_scale = np.asarray(kernel.length_scale, dtype=float)
        self.anisotropic = is_anisotropic(kernel.length_scale)
        self.n_dims = kernel.n_dims

    def set_theta(self, theta):
        if self.n_dims:
            self.length_scale = np.exp(theta) if self.anisotropic else np.exp(theta[0])

    def _scaled(self, X):
        return (X if self.columns is None else X[:, self.columns]) / self.length_scale

    def gram(self, X, keep, scaled=None):
        """``k(X, X)``; with ``scaled=(c, out)`` also ``c * k(X, X)`` into ``out``."""
        Z = self._scaled(X)
        Z -= Z.mean(axis=0)  # centred: smaller round-off
        n = Z.shape[0]
        if not (keep and self.n_dims):
            K = _se_gram(Z, np.empty((n, n)), scaled)
        else:  # while optimising, K lives until the next evaluation: its memory is reused
            K = _se_gram(Z, _kept_array(self, "_K_buffer", (n, n)), scaled, self.lower)
            self._Z, self._K, self._W_dot_K = Z, K, None
        return K

    def contract(self, W, scale):
        r"""Per-length-scale gradient from :math:`M = W \circ K`, block by block.

        With :math:`D_d = (z_{id} - z_{jd})^2` and :math:`M` symmetric,
        :math:`\sum_{ij} M_{ij} D_d = 2 \sum_i z_{id}^2 (M 1)_i - 2 z_d^T M z_d`:
        one product :math:`M [Z, 1]` per row block of :math:`M`, which is never
        stored whole.
        """
        Z = self._Z
        Z_1 = np.empty((Z.shape[0], Z.shape[1] + 1))
        Z_1[:, :-1], Z_1[:, -1] = Z, 1.0
        MZ_1 = np.zeros_like(Z_1)
        blocks = _row_blocks(*W.shape)
        scratch = np.empty((blocks[0].stop, W.shape[1]))
        for rows in blocks:
            cols = slice(0, rows.stop if self.lower else W.shape[1])
            block = scratch[: rows.stop - rows.start, cols]
            np.multiply(W[rows, cols], self._K[rows, cols], out=block)
            if not self.lower:
                MZ_1[rows] = block @ Z_1
                continue
            # M = L + L^T with L the lower triangle, its diagonal halved
            # (W is zero above its diagonal)
            diagonal = np.arange(rows.stop - rows.start)
            block[diagonal, rows.start + diagonal] *= 0.5
            MZ_1[rows] += block @ Z_1[cols]
            MZ_1[cols] += block.T @ Z_1[rows]
        per_dim = (Z * Z).T @ (2.0 * MZ_1[:, -1]) - 2.0 * np.einsum("id,id->d", Z, MZ_1[:, :-1])
        self._W_dot_K = (W, float(MZ_1[:, -1].sum()))  # sum(W o K), for a constant factor
        per_dim *= scale
        return per_dim if self.anisotropic else np.array([per_dim.sum()])

    def prepare(self, S, weights):
        # the arrays of the fit are not needed for prediction
        self._K_buffer = self._K = self._Z = self._W_dot_K = None
        Z = self._scaled(S)
        self._center = Z.mean(axis=0) if len(Z) else 0.0
        self._S_T = np.ascontiguousarray((Z - self._center).T)
        self._half_norm = 0.5 * np.einsum("di,di->i", self._S_T, self._S_T)
        self._far_support = float(np.max(self._half_norm, initial=0.0)) > _EXPANSION_MAX
        self._weights = weights

    def _neg_half_sq_dists(self, Q):
        # -|z - s|^2 / 2 = z.s - |s|^2 / 2 - |z|^2 / 2, by one matrix product;
        # its round-off, ~eps |z|^2, is only negligible for moderate |z|: with
        # far-out (or very short length-scale) coordinates, exact differences
        Z = self._scaled(Q)
        Z -= self._center
        if len(Z) == 1:  # one query: a scalar (the einsum costs more than the row)
            half_norm = 0.5 * float(Z[0] @ Z[0])
            far = half_norm > _EXPANSION_MAX
        else:
            half_norm = 0.5 * np.einsum("id,id->i", Z, Z)[:, np.newaxis]
            far = np.max(half_norm, initial=0.0) > _EXPANSION_MAX
        if far or self._far_support:
            return -0.5 * cdist(Z, self._S_T.T, metric="sqeuclidean")
        D = Z @ self._S_T
        D -= self._half_norm
        D -= half_norm
        return D

    def cross(self, Q):
        D = self._neg_half_sq_dists(Q)
        np.minimum(D, 0.0, out=D)  # round-off can leave tiny positive values
        return np.exp(D, out=D)

    def cross_dot(self, Q):
        if Q.shape[0] == 1 and not self._far_support:  # one control tick
            value = self._row_dot(Q)
            if value is not None:
                return value
        D = self._neg_half_sq_dists(Q)
        return np.exp(D, out=D) @ self._weights

    def _row_dot(self, Q):
        r""":math:`k(q, S)\,w` for one query, or None for a far-out one.

        As :math:`e^{-\|z\|^2/2} \sum_j e^{z^T s_j - \|s_j\|^2/2} w_j`: the
        query's own factor is one float, not a pass over the support. The
        exponents are at most :math:`\|z\|^2/2`, so this is used while that is
        below :data:`_ROW_MAX_HALF_NORM` (no overflow).
        """
        # (ndarray.dot: less call overhead than @ on vectors, which matters here)
        z = (Q[0] if self.columns is None else Q[0, self.columns]) / self.length_scale
        z -= self._center
        half_norm = 0.5 * float(z.dot(z))
        if half_norm > _ROW_MAX_HALF_NORM:
            return None
        d = z.dot(self._S_T)
        d -= self._half_norm
        np.exp(d, out=d)
        return np.array([math.exp(-half_norm) * float(d.dot(self._weights))])

    def diag(self, Q):
        return 1.0

    def terms(self, n_features):
        columns = np.arange(n_features) if self.columns is None else self.columns
        length = np.broadcast_to(np.asarray(self.length_scale, dtype=float), columns.shape)
        return [Term(columns=columns, inv_sq=1.0 / length**2)]

    def init_hyperparameters(self, X, rng, max_rows):
        """Default length scales (1.0) from the spread of the data.

        Each column's scale becomes ``sqrt(n_columns)`` times the median
        absolute difference of random pairs of rows (their RMS for an
        isotropic kernel), clipped to the bounds; other values are kept.
        """
        kernel = self.kernel
        if kernel.hyperparameter_length_scale.fixed:
            return
        Xc = X if self.columns is None else X[:, self.columns]
        length_scale = np.atleast_1d(np.asarray(kernel.length_scale, dtype=float)).copy()
        default = length_scale == 1.0
        if len(Xc) < 2 or not default.any():
            return
        rows = rng.choice(len(Xc), size=min(len(Xc), max_rows), replace=False)
        half = len(rows) // 2
        spread = np.median(np.abs(Xc[rows[:half]] - Xc[rows[half : 2 * half]]), axis=0)
        if len(length_scale) == 1:  # isotropic: one scale for all columns
            spread = np.atleast_1d(np.sqrt(np.mean(spread**2)))
        heuristic = np.sqrt(Xc.shape[1] if len(length_scale) == 1 else len(spread)) * spread
        new = np.where(default & (heuristic > 0), heuristic, length_scale)
        low, high = kernel.length_scale_bounds
        new = np.clip(new, low, high)
        kernel.set_params(length_scale=new if len(new) > 1 else float(new[0]))
        self.length_scale = np.asarray(kernel.length_scale, dtype=float)


class _Gate(_Node):
    r""":math:`a(x) k(x, x') a(x')` (Eq. 16): the inner kernel on gated rows only."""

    def __init__(self, kernel):
        self.kernel = kernel
        column = kernel.velocity_column
        if not isinstance(column, (int, np.integer)) or isinstance(column, bool):
            raise _NotCompilable  # a name: resolve_columns first
        self.inner = _compile(kernel.kernel)
        self.column = int(column)
        self.sigma_v = float(kernel.sigma_v)
        self.n_dims = self.inner.n_dims

    def children(self):
        return (self.inner,)

    def terms(self, n_features):
        inner = self.inner.terms(n_features)
        if inner is None or any(t.kernel is not None for t in inner):
            return None
        gate = (self.column, self.sigma_v)
        return [Term(t.scale, t.columns, t.inv_sq, t.gates + (gate,)) for t in inner]

    def init_hyperparameters(self, X, rng, max_rows):
        self.inner.init_hyperparameters(X[self.rows(X)], rng, max_rows)

    def set_theta(self, theta):
        self.inner.set_theta(theta)

    def rows(self, X):
        """Indices of the rows with :math:`|\\dot q_\\ell| < \\sigma_v` (Eq. 15)."""
        return np.flatnonzero(quasi_static(X[:, self.column], self.sigma_v))

    def gram(self, X, keep):
        n = X.shape[0]
        rows = self.rows(X)
        if keep:
            self._rows, self._all = rows, len(rows) == n
        if len(rows) == n:
            return self.inner.gram(X, keep)
        if len(rows) == 0:
            return 0.0
        block = self.inner.gram(X[rows], keep)
        if isinstance(block, _Diagonal):
            values = np.zeros(n)
            values[rows] = block.values
            return _Diagonal(values)
        if not keep:  # the block alone; a sum adds it in place
            return _RowBlock(n, rows, _dense(block, len(rows), len(rows)))
        K = np.zeros((n, n))
        K[np.ix_(rows, rows)] = block
        return K

    def contract(self, W, scale):
        if self._all:
            return self.inner.contract(W, scale)
        if len(self._rows) == 0:
            return np.zeros(self.n_dims)
        return self.inner.contract(W[np.ix_(self._rows, self._rows)], scale)

    def prepare(self, S, weights):
        self._n_support = S.shape[0]
        self._support_rows = self.rows(S)
        self.inner.prepare(S[self._support_rows], weights[self._support_rows])

    def cross(self, Q):
        rows = self.rows(Q)
        out = np.zeros((Q.shape[0], self._n_support))
        if len(rows) and len(self._support_rows):
            block = self.inner.cross(Q[rows])
            block = _dense(block, len(rows), len(self._support_rows))
            out[np.ix_(rows, self._support_rows)] = block
        return out

    def cross_dot(self, Q):
        out = np.zeros(Q.shape[0])
        rows = self.rows(Q)
        if len(rows) and len(self._support_rows):  # skipped when the gate is 0
            out[rows] = self.inner.cross_dot(Q[rows])
        return out

    def diag(self, Q):
        out = np.zeros(Q.shape[0])
        rows = self.rows(Q)
        if len(rows):
            out[rows] = self.inner.diag(Q[rows])
        return out


class _Opaque(_Node):
    """Any other kernel: called as usual; gradient from its full array."""

    def __init__(self, kernel):
        self.kernel = kernel
        self.n_dims = kernel.n_dims

    def set_theta(self, theta):
        if self.n_dims:
            self.kernel = self.kernel.clone_with_theta(theta)

    def gram(self, X, keep):
        if keep and self.n_dims:  # one call for K and its gradient, for contract
            K, self._K_gradient = self.kernel(X, eval_gradient=True)
            return np.array(K, dtype=float)
        return np.array(self.kernel(X), dtype=float)

    def contract(self, W, scale):
        K_gradient, self._K_gradient = self._K_gradient, None
        return scale * np.einsum("ij,ijk->k", W, K_gradient)

    def prepare(self, S, weights):
        self._S, self._n_support, self._weights = S, S.shape[0], weights

    def cross(self, Q):
        return np.array(self.kernel(Q, self._S), dtype=float)

    def diag(self, Q):
        return np.asarray(self.kernel.diag(Q), dtype=float)


class _Parametric(_Opaque):
    r""":class:`~sklearn_gpcd.kernels.ParametricKernel` :math:`\Phi \Sigma \Phi^T`.

    Evaluated by its kernel object; its gradient is contracted from the
    design matrix, :math:`\sigma^2_j \sum_i (W \Phi)_{ij} \Phi_{ij}`, in
    O(n p) memory.
    """

    def gram(self, X, keep):
        if keep and self.n_dims:
            self._X = X
        return np.array(self.kernel(X), dtype=float)

    def contract(self, W, scale):
        kernel = self.kernel
        Phi = kernel.design_matrix(self._X)
        per_feature = kernel.weight_variances(Phi.shape[1]) * np.einsum("ij,ij->j", W @ Phi, Phi)
        per_feature *= scale
        return per_feature if kernel.anisotropic else np.array([per_feature.sum()])


def gram_matrix(plan, X, keep=False):
    """``k(X, X)`` of a compiled kernel as a new (writable) array.

    Parameters
    ----------
    plan : _Node
    X : ndarray of shape (n_samples, n_features)
    keep : bool, default=False
        Keep the parts needed by ``plan.contract``. The returned array is
        then safe to modify, but the plan reuses its memory at the next
        ``keep=True`` call of the same size (likelihood evaluations while
        optimising); when ``plan.lower``, only its lower triangle is
        computed (all that LAPACK's Cholesky factorisation reads).

    Returns
    -------
    K : ndarray of shape (n_samples, n_samples)
    """
    n = X.shape[0]
    K = plan.gram(X, keep)
    if isinstance(K, np.ndarray):  # sums and products return arrays no other node keeps
        return K.copy() if keep and not isinstance(plan, _Pair) else K
    return _dense(K, n, n)


# -- terms: the kernel flattened for the streaming monitor -----------------


class Term:
    r"""One summand ``scale * prod(gates) * exp(-0.5 sum_d inv_sq[d] (x_d - s_d)^2)``.

    :meth:`_Node.terms` flattens a kernel into such summands (sums,
    products with constants, squared exponentials and Eq. 15-16 gates), the
    form in which the streaming monitor batches one prediction per tick over
    outputs; a summand that cannot be flattened keeps its ``kernel``.

    Parameters
    ----------
    scale : float, default=1.0
        Constant factor.
    columns : ndarray of int, default=None
        Columns of the exponential factor; None: no exponential factor.
    inv_sq : ndarray of shape (len(columns),), default=None
        :math:`1 / l_d^2` per column.
    gates : tuple of (int, float), default=()
        ``(velocity column, sigma_v)`` of each gate factor
        (:func:`sklearn_gpcd._gate.quasi_static`).
    kernel : Kernel, default=None
        A summand evaluated by its kernel object (the other fields unused).

    Examples
    --------
    >>> import numpy as np
    >>> a = Term(scale=2.0, gates=((1, 0.01),))
    >>> b = Term(columns=np.array([0]), inv_sq=np.array([4.0]))
    >>> product = a * b
    >>> product.scale, product.columns.tolist(), product.gates
    (2.0, [0], ((1, 0.01),))
    """

    def __init__(self, scale=1.0, columns=None, inv_sq=None, gates=(), kernel=None):
        self.scale = scale
        self.columns = columns
        self.inv_sq = inv_sq
        self.gates = tuple(gates)
        self.kernel = kernel

    def __mul__(self, other):
        """The product of two flattened summands; None if either has a kernel."""
        if self.kernel is not None or other.kernel is not None:
            return None
        if self.columns is None or other.columns is None:
            source = self if other.columns is None else other
            columns, inv_sq = source.columns, source.inv_sq
        else:  # exp(-0.5 A) exp(-0.5 B) = exp(-0.5 (A + B))
            columns = np.union1d(self.columns, other.columns)
            inv_sq = np.zeros(columns.shape)
            for t in (self, other):
                np.add.at(inv_sq, np.searchsorted(columns, t.columns), t.inv_sq)
        return Term(self.scale * other.scale, columns, inv_sq, self.gates + other.gates)

    def gate_values(self, X):
        """The product of this term's gates (Eq. 15) at each row of ``X``."""
        a = np.ones(X.shape[0])
        for column, sigma_v in self.gates:
            a *= quasi_static(X[:, column], sigma_v)
        return a

    def gates_open(self, x):
        """Whether every gate of this term is open at the one input row ``x``."""
        return all(quasi_static(x[column], sigma_v) for column, sigma_v in self.gates)


def flatten(plan, n_features):
    """``plan.terms(n_features)``, or one term with the plan's kernel when it has none.

    Parameters
    ----------
    plan : _Node
        A compiled kernel (:func:`compile_kernel`).
    n_features : int
        Number of input columns (for kernels on all columns).

    Returns
    -------
    terms : list of Term
    """
    terms = plan.terms(n_features)
    return [Term(kernel=plan.kernel)] if terms is None else terms


# -- the registry ------------------------------------------------------------

register_node(Sum, _Sum)
register_node(Product, _Product)
register_node(ConstantKernel, _Constant)
register_node(WhiteKernel, _White)
register_node(RBF, _SquaredExponential)
register_node(ARDRBF, _SquaredExponential, ("length_scale", "columns", "length_scale_bounds"))
register_node(QuasiStaticGate, _Gate, ("kernel", "velocity_column", "sigma_v"))
register_node(ParametricKernel, _Parametric, ("features", "prior_cov", "prior_cov_bounds"))
register_node(Exponentiation, None)  # evaluated through the kernel object, by design
