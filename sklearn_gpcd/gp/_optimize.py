r"""Type-II maximum likelihood: choose kernel hyperparameters by maximising
the log marginal likelihood.

Two paths:

* **exact** (``"fmin_l_bfgs_b"`` or a callable, with restarts, as scikit-learn's
  GPR): the LML of the ``n`` support rows, cubic in ``n``;
* **stochastic** (``"adam"``, the paper's choice for its 80,000 samples):
  Adam (Kingma & Ba, 2015) on the LML of random minibatches of ``b`` rows,
  normalised by ``b``,

  .. math::

      \hat\ell_B(\theta) = \tfrac1b \log p(y_B \mid X_B, \theta),

  an estimate of the per-sample LML of the data that costs
  :math:`O(b^3)` per step whatever the number of rows. Early stopping watches
  :math:`\hat\ell_V` on a fixed held-out minibatch :math:`V` (never used for
  steps) and keeps the best theta seen.

``optimizer="auto"`` picks the exact path when the support has at most
:data:`EXACT_MAX_SAMPLES` rows, else the stochastic path.
"""

import warnings

import numpy as np
import scipy.optimize
from sklearn.base import clone
from sklearn.exceptions import ConvergenceWarning

from ..kernels.plan import compile_kernel
from ._likelihood import _log_marginal_likelihood

OPTIMIZERS = ("auto", "fmin_l_bfgs_b", "adam")

#: ``optimizer="auto"`` uses L-BFGS-B on the exact LML up to this many support rows...
EXACT_MAX_SAMPLES = 3000
#: ... and while ``n_support_rows * n_hyperparameters`` stays at most this.
EXACT_MAX_COST = 60_000
#: The stochastic path ends with L-BFGS-B on the exact LML of at most this many
#: support rows (a random subset of them) ...
REFINE_MAX_SAMPLES = 1000
#: ... for at most this many iterations.
REFINE_MAX_ITER = 50

#: Correction pairs kept by L-BFGS-B (scipy's default is 10). ARD kernels have
#: tens of hyperparameters; a longer memory halves the number of likelihood
#: evaluations to the same optimum (n = 1,000 rows of D1, 18-dim ARD RBF +
#: noise: 173 evaluations with 10 pairs, 77 with 50).
LBFGS_MEMORY = 50

# held-out LML checked every this many Adam steps
_VALIDATION_INTERVAL = 10
# Adam's moment decay rates and epsilon (Kingma & Ba's defaults)
_BETA1, _BETA2, _EPS = 0.9, 0.999, 1e-8


def resolve_optimizer(optimizer, n_exact, n_theta):
    """The optimizer ``"auto"`` stands for.

    The exact path costs :math:`O(n^3)` per evaluation and L-BFGS-B needs
    roughly proportionally more evaluations with more hyperparameters, so
    "auto" is exact while both are small: ``n_exact <= 3000`` and
    ``n_exact * n_theta <= 60000``. At the corner, 3,000 rows of an 18-dim
    ARD RBF + noise, the exact fit reaches scikit-learn's likelihood while
    Adam stops at a clearly lower one (measured against scikit-learn by the
    project's GP-fit benchmark).

    Parameters
    ----------
    optimizer : str, callable or None
    n_exact : int
        Rows of the exact LML (the support set).
    n_theta : int
        Number of free hyperparameters.

    Returns
    -------
    optimizer : str, callable or None
        ``"fmin_l_bfgs_b"`` or ``"adam"`` for "auto"; any other value is
        returned unchanged.

    Examples
    --------
    >>> resolve_optimizer("auto", 3000, 20), resolve_optimizer("auto", 3001, 3)
    ('fmin_l_bfgs_b', 'adam')
    >>> resolve_optimizer("auto", 1500, 57)  # the paper's SP_P for 6 joints
    'adam'
    """
    if isinstance(optimizer, str) and optimizer == "auto":
        cheap = n_exact <= EXACT_MAX_SAMPLES and n_exact * n_theta <= EXACT_MAX_COST
        return "fmin_l_bfgs_b" if cheap else "adam"
    return optimizer


def lbfgs_b_result(obj_func, initial_theta, bounds, max_iter=None):
    """scipy's L-BFGS-B with :data:`LBFGS_MEMORY` correction pairs (an OptimizeResult)."""
    options = {"maxcor": LBFGS_MEMORY}
    if max_iter is not None:
        options["maxiter"] = max_iter
    return scipy.optimize.minimize(
        obj_func, initial_theta, method="L-BFGS-B", jac=True, bounds=bounds, options=options
    )


def lbfgs_b(obj_func, initial_theta, bounds):
    """The exact path's optimizer as a scikit-learn ``optimizer`` callable.

    ``GaussianProcessRegressor(kernel, optimizer=lbfgs_b)`` runs the same
    algorithm as ``SemiParametricGPRegressor(kernel,
    optimizer="fmin_l_bfgs_b")``, for like-for-like comparisons.

    Parameters
    ----------
    obj_func : callable
        ``obj_func(theta) -> (f, grad)`` to minimise.
    initial_theta : ndarray of shape (n_theta,)
    bounds : ndarray of shape (n_theta, 2)

    Returns
    -------
    theta_opt : ndarray of shape (n_theta,)
    f_min : float

    Examples
    --------
    >>> import numpy as np
    >>> theta, f = lbfgs_b(lambda t: (float(t @ t), 2 * t), np.ones(2), np.array([[-5, 5]] * 2))
    >>> np.allclose(theta, 0), float(f) < 1e-12
    (True, True)
    """
    res = lbfgs_b_result(obj_func, initial_theta, bounds)
    return res.x, res.fun


def _minimize(obj_func, initial_theta, bounds, optimizer, max_iter=None):
    """Minimise ``obj_func(theta) -> (f, grad)`` from ``initial_theta``.

    ``max_iter`` caps the L-BFGS-B iterations (then without a warning when
    the cap is hit).

    Returns
    -------
    theta_opt : ndarray of shape (n_theta,)
    f_min : float
    n_iter : int
        L-BFGS-B iterations (0 for a callable).
    """
    if optimizer == "fmin_l_bfgs_b":
        res = lbfgs_b_result(obj_func, initial_theta, bounds, max_iter)
        if not res.success and max_iter is None:
            warnings.warn(
                f"L-BFGS-B failed to converge ({res.message}); increase the "
                "number of restarts or rescale the data.",
                ConvergenceWarning,
            )
        return res.x, res.fun, res.nit
    if callable(optimizer):
        theta_opt, f_min = optimizer(obj_func, initial_theta, bounds=bounds)
        return theta_opt, f_min, 0
    raise ValueError(f"unknown optimizer {optimizer!r}")  # pragma: no cover - fit checks


def _restart_thetas(kernel, n_restarts, rng):
    """Initial thetas: ``kernel.theta``, then draws uniform in the log bounds."""
    bounds = kernel.bounds
    starts = [kernel.theta]
    if n_restarts > 0:
        if not np.isfinite(bounds).all():
            raise ValueError(
                "n_restarts_optimizer > 0 requires finite bounds on every "
                f"hyperparameter of {kernel}."
            )
        starts += [rng.uniform(bounds[:, 0], bounds[:, 1]) for _ in range(n_restarts)]
    return starts


def _fit_hyperparameters(kernel, X, y, alpha, optimizer, n_restarts, rng, max_iter=None):
    """Maximise the exact log marginal likelihood over ``kernel.theta``.

    The first run starts from ``kernel.theta``; each of the ``n_restarts``
    further runs starts from theta drawn uniformly in the (log-space) bounds
    with ``rng``. The best run wins.

    Parameters
    ----------
    kernel : Kernel
        Initial kernel; not modified.
    X : ndarray of shape (n_samples, n_features)
    y : ndarray of shape (n_samples,)
    alpha : float or ndarray of shape (n_samples,)
    optimizer : "fmin_l_bfgs_b", callable or None
        None keeps the initial hyperparameters.
    n_restarts : int
    rng : numpy.random.RandomState
    max_iter : int, default=None
        Cap on the L-BFGS-B iterations of each run.

    Returns
    -------
    kernel_ : Kernel
        Clone of ``kernel`` with the optimal theta.
    lml : float
        Log marginal likelihood at the optimum.
    n_iter : int
        Iterations of the winning run (0 without optimization).
    """
    plan = compile_kernel(kernel)
    if optimizer is None or kernel.n_dims == 0:
        return kernel.clone_with_theta(kernel.theta), _log_marginal_likelihood(
            kernel.theta, kernel, X, y, alpha, plan=plan
        ), 0

    def obj_func(theta, eval_gradient=True):
        if eval_gradient:
            lml, grad = _log_marginal_likelihood(theta, kernel, X, y, alpha, True, plan)
            return -lml, -grad
        return -_log_marginal_likelihood(theta, kernel, X, y, alpha, plan=plan)

    starts = _restart_thetas(kernel, n_restarts, rng)
    optima = [
        _minimize(obj_func, theta0, kernel.bounds, optimizer, max_iter) for theta0 in starts
    ]
    theta, f_min, n_iter = min(optima, key=lambda opt: opt[1])
    return kernel.clone_with_theta(theta), -f_min, n_iter


class AdamSettings:
    """Settings of the stochastic path (validated by the regressor).

    Parameters
    ----------
    batch_size : int
        Rows per minibatch (and in the held-out minibatch).
    max_iter : int
        Maximum number of Adam steps per start.
    learning_rate : float
        Adam step size in log-hyperparameter units.
    tol : float
        Minimum improvement of the held-out per-sample LML that resets the
        patience counter.
    n_iter_no_change : int
        Held-out checks (one every 10 steps) without such an improvement
        before stopping.
    verbose : int
        Progress lines when > 0.
    """

    def __init__(self, batch_size, max_iter, learning_rate, tol, n_iter_no_change, verbose):
        self.batch_size = batch_size
        self.max_iter = max_iter
        self.learning_rate = learning_rate
        self.tol = tol
        self.n_iter_no_change = n_iter_no_change
        self.verbose = verbose


def _fit_hyperparameters_adam(kernel, X, y, alpha, settings, n_restarts, rng, label="",
                              bounds=None):
    r"""Maximise the minibatch LML with Adam, early-stopped on held-out rows.

    Each step draws ``b = batch_size`` training rows without replacement and
    ascends :math:`\hat\ell_B = \frac1b \log p(y_B \mid X_B, \theta)`
    (gradient as in the exact path, on the minibatch) with Adam,

    .. math::

        m \leftarrow \beta_1 m + (1-\beta_1) g, \quad
        v \leftarrow \beta_2 v + (1-\beta_2) g^2, \quad
        \theta \leftarrow \Pi\Big(\theta + \eta
            \frac{m / (1-\beta_1^t)}{\sqrt{v / (1-\beta_2^t)} + \epsilon}\Big),

    :math:`\Pi` clipping to the bounds. Every 10 steps the held-out
    :math:`\hat\ell_V` is evaluated; the run stops after ``n_iter_no_change``
    checks without an improvement of at least ``tol``, and returns the theta
    with the best :math:`\hat\ell_V`. Restarts (from theta drawn in the bounds)
    compete on :math:`\hat\ell_V` too.

    Parameters
    ----------
    kernel : Kernel
        Initial kernel (after :func:`data_driven_init`); not modified.
    X : ndarray of shape (n_samples, n_features)
        All training rows.
    y : ndarray of shape (n_samples,)
        Targets (residuals of the mean, normalised when requested).
    alpha : float or ndarray of shape (n_samples,)
    settings : AdamSettings
    n_restarts : int
    rng : numpy.random.RandomState
    label : str
        Prefix of the progress lines.

    Returns
    -------
    kernel_ : Kernel
        Clone of ``kernel`` with the best theta.
    info : dict
        ``n_iter`` (steps of the winning run), ``validation_lml`` (its best
        held-out per-sample LML) and ``history`` (one
        ``(step, minibatch_lml, held_out_lml)`` per check).
    """
    n = X.shape[0]
    b = min(settings.batch_size, n)
    if n >= 2 * b:
        perm = rng.permutation(n)
        val, train = perm[:b], perm[b:]
    else:  # too few rows for a disjoint held-out batch: validate on a batch
        val, train = rng.choice(n, size=b, replace=False), np.arange(n)
    alpha_of = (lambda rows: alpha[rows]) if np.ndim(alpha) else (lambda rows: alpha)
    plan = compile_kernel(kernel)

    def batch_lml(theta, rows, eval_gradient):
        out = _log_marginal_likelihood(
            theta, kernel, X[rows], y[rows], alpha_of(rows), eval_gradient, plan
        )
        if eval_gradient:
            return out[0] / len(rows), out[1] / len(rows)
        return out / len(rows)

    best = None
    bounds = kernel.bounds if bounds is None else bounds
    for start, theta0 in enumerate(_restart_thetas(kernel, n_restarts, rng)):
        run = _adam_run(theta0, bounds, batch_lml, train, val, b, settings, rng,
                        f"{label}start {start}: " if n_restarts else label)
        if best is None or run["validation_lml"] > best["validation_lml"]:
            best = run
    return kernel.clone_with_theta(best.pop("theta")), best


def _adam_run(theta, bounds, batch_lml, train, val, b, settings, rng, label):
    """One Adam run from ``theta``; see :func:`_fit_hyperparameters_adam`."""
    theta = np.clip(np.asarray(theta, dtype=float), bounds[:, 0], bounds[:, 1])
    m, v = np.zeros_like(theta), np.zeros_like(theta)
    best_theta, best_val = theta.copy(), batch_lml(theta, val, False)
    recent, history, stale, failures = [], [], 0, 0
    step = 0
    for step in range(1, settings.max_iter + 1):
        rows = rng.choice(train, size=b, replace=False) if len(train) > b else train
        lml, grad = batch_lml(theta, rows, True)
        if not np.isfinite(lml):  # K not PD on this batch: skip the step
            failures += 1
            if failures > settings.max_iter // 2:
                break
            continue
        recent.append(lml)
        m = _BETA1 * m + (1 - _BETA1) * grad
        v = _BETA2 * v + (1 - _BETA2) * grad * grad
        m_hat = m / (1 - _BETA1**step)
        v_hat = v / (1 - _BETA2**step)
        theta = np.clip(
            theta + settings.learning_rate * m_hat / (np.sqrt(v_hat) + _EPS),
            bounds[:, 0], bounds[:, 1],
        )
        if step % _VALIDATION_INTERVAL and step != settings.max_iter:
            continue
        val_lml = batch_lml(theta, val, False)
        history.append((step, float(np.mean(recent)), float(val_lml)))
        if val_lml > best_val + settings.tol:
            stale = 0
        else:
            stale += 1
        if val_lml > best_val:
            best_theta, best_val = theta.copy(), val_lml
        if settings.verbose > 0:
            print(f"[Adam] {label}step {step:5d}  minibatch LML/n {np.mean(recent):9.4f}  "
                  f"held-out LML/n {val_lml:9.4f}  best {best_val:9.4f}", flush=True)
        recent = []
        if stale >= settings.n_iter_no_change:
            break
    return dict(theta=best_theta, validation_lml=float(best_val), n_iter=step,
                history=history)


def data_driven_init(kernel, X, rng, max_rows=1000):
    r"""Median-heuristic initial length scales where the kernel has defaults.

    Every length scale of an ``RBF`` / :class:`~sklearn_gpcd.kernels.ARDRBF`
    that is not fixed and still equals its default ``1.0`` is replaced by

    .. math::

        l_d = \sqrt{D}\; \operatorname{median}_{i \ne j} |x_{id} - x_{jd}|,

    over at most ``max_rows`` random rows (those with the gate open, inside a
    :class:`~sklearn_gpcd.kernels.QuasiStaticGate`), :math:`D` the number of
    columns of the block, so that the typical scaled squared distance
    :math:`\sum_d (x_d - x'_d)^2 / l_d^2` is about 1 whatever :math:`D`.
    Columns without spread keep 1.0; values are clipped to the bounds. Used by
    the stochastic path only (the exact path starts from the kernel as given,
    like scikit-learn).

    Parameters
    ----------
    kernel : Kernel
        Kernel with integer columns; not modified.
    X : ndarray of shape (n_samples, n_features)
    rng : numpy.random.RandomState
    max_rows : int, default=1000

    Returns
    -------
    kernel : Kernel
        A clone with the new initial length scales.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.kernels import ARDRBF
    >>> X = np.random.RandomState(0).normal(scale=[1.0, 10.0], size=(500, 2))
    >>> init = data_driven_init(ARDRBF([1.0, 1.0]), X, np.random.RandomState(0))
    >>> init.length_scale.round(1)  # sqrt(2) * median |x_i - x_j| per column
    array([ 1.3, 15.4])
    """
    kernel = clone(kernel)
    # each node sets its kernel's initial hyperparameters (kernels/plan.py)
    compile_kernel(kernel).init_hyperparameters(X, rng, max_rows)
    return kernel
