"""Type-II maximum likelihood: choose kernel hyperparameters by maximising
the log marginal likelihood, with restarts, like scikit-learn's GPR.

Optimizers that only need ``obj_func(theta) -> (f, grad)`` plug into
:func:`_minimize` by name. A stochastic one (e.g. minibatch Adam for the
paper's n = 80,000 samples) branches in :func:`_fit_hyperparameters`, which
has the data, and evaluates :func:`._likelihood._log_marginal_likelihood` on
minibatches; register its name in ``OPTIMIZERS``.
"""

import warnings

import numpy as np
import scipy.optimize
from sklearn.exceptions import ConvergenceWarning

from ._likelihood import _log_marginal_likelihood

OPTIMIZERS = ("fmin_l_bfgs_b",)


def _check_optimizer(optimizer):
    """Raise a ValueError naming ``optimizer`` unless it is supported."""
    if optimizer is None or callable(optimizer) or optimizer in OPTIMIZERS:
        return
    raise ValueError(
        f"Unknown optimizer {optimizer!r}; expected one of {OPTIMIZERS}, None "
        "or a callable(obj_func, initial_theta, bounds) -> (theta, f)."
    )


def _minimize(obj_func, initial_theta, bounds, optimizer):
    """Minimise ``obj_func(theta) -> (f, grad)`` from ``initial_theta``.

    Returns
    -------
    theta_opt : ndarray of shape (n_theta,)
    f_min : float
    """
    if optimizer == "fmin_l_bfgs_b":
        res = scipy.optimize.minimize(
            obj_func, initial_theta, method="L-BFGS-B", jac=True, bounds=bounds
        )
        if not res.success:
            warnings.warn(
                f"L-BFGS-B failed to converge ({res.message}); increase the "
                "number of restarts or rescale the data.",
                ConvergenceWarning,
            )
        return res.x, res.fun
    if callable(optimizer):
        return optimizer(obj_func, initial_theta, bounds=bounds)
    _check_optimizer(optimizer)  # pragma: no cover - validated in fit


def _fit_hyperparameters(kernel, X, y, alpha, optimizer, n_restarts, rng):
    """Maximise the log marginal likelihood over ``kernel.theta``.

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

    Returns
    -------
    kernel_ : Kernel
        Clone of ``kernel`` with the optimal theta.
    lml : float
        Log marginal likelihood at the optimum.
    """
    if optimizer is None or kernel.n_dims == 0:
        return kernel.clone_with_theta(kernel.theta), _log_marginal_likelihood(
            kernel.theta, kernel, X, y, alpha
        )

    def obj_func(theta, eval_gradient=True):
        if eval_gradient:
            lml, grad = _log_marginal_likelihood(theta, kernel, X, y, alpha, True)
            return -lml, -grad
        return -_log_marginal_likelihood(theta, kernel, X, y, alpha)

    bounds = kernel.bounds
    starts = [kernel.theta]
    if n_restarts > 0:
        if not np.isfinite(bounds).all():
            raise ValueError(
                "n_restarts_optimizer > 0 requires finite bounds on every "
                f"hyperparameter of {kernel}."
            )
        starts += [rng.uniform(bounds[:, 0], bounds[:, 1]) for _ in range(n_restarts)]
    optima = [_minimize(obj_func, theta0, bounds, optimizer) for theta0 in starts]
    theta, f_min = min(optima, key=lambda opt: opt[1])
    return kernel.clone_with_theta(theta), -f_min
