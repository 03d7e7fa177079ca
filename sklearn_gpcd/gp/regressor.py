"""Semi-parametric Gaussian Process regressor of Dalla Libera et al. (2019)."""

import math
import numbers
import warnings
from contextlib import nullcontext

import numpy as np
from joblib import Parallel, delayed
from sklearn.base import BaseEstimator, RegressorMixin, _fit_context, clone
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel
from sklearn.utils import check_random_state
from sklearn.utils._param_validation import HasMethods, Interval, StrOptions
from sklearn.utils.validation import check_is_fitted, validate_data

from .._gate import SIGMA_V_CONSTRAINT
from .._persistence import VersionedStateMixin
from ..kernels import resolve_columns
from ._likelihood import _log_marginal_likelihood, single_threaded_blas
from ._optimize import (
    REFINE_MAX_ITER,
    REFINE_MAX_SAMPLES,
    AdamSettings,
    OPTIMIZERS,
    _fit_hyperparameters,
    _fit_hyperparameters_adam,
    data_driven_init,
    resolve_optimizer,
)
from .mean import ParametricMean
from ._posterior import GPPosterior, _Posterior, target_scaling
from ._support import SUPPORT_SELECTIONS, resolve_n_support, select_support


def _default_kernel():
    """``ConstantKernel(1.0) * RBF(1.0) + WhiteKernel(1.0)``."""
    return ConstantKernel(1.0) * RBF(1.0) + WhiteKernel(1.0)


class SemiParametricGPRegressor(VersionedStateMixin, RegressorMixin, BaseEstimator):
    r"""Gaussian Process regression around a parametric mean, one GP per output.

    Each output column (e.g. the current of joint :math:`\ell`) is modelled
    independently (Sec. III-A) as

    .. math::

        y = m(x) + f(x) + e, \qquad f \sim \mathcal{GP}(0, k_\theta),
        \quad e \sim \mathcal N(0, \alpha),

    where :math:`m(x) = \bar\phi(x) w` is the parametric mean with
    deterministic parameters (option (i) of Sec. III-A, Eq. 10 and 17), fitted
    first on all training rows, and the GP models the residual
    :math:`y - m(x)` with the kernel of Eq. 11 (SP_S) or Eq. 16-17 (SP_P).
    Hyperparameters maximise the log marginal likelihood (type-II ML); the
    posterior may be conditioned on a support subset of ``n_support`` rows
    (the paper's :math:`D_{SDP}`). With ``mean=None`` and an exact optimizer
    this is exactly :class:`sklearn.gaussian_process.GaussianProcessRegressor`
    applied to each output column.

    **Which optimizer** (``optimizer="auto"``): with at most
    ``EXACT_MAX_SAMPLES = 3000`` support rows and at most
    ``EXACT_MAX_COST = 60000`` support rows times hyperparameters, L-BFGS-B
    on the exact LML of the support rows, from the kernel's hyperparameters
    (as scikit-learn); above, the paper's stochastic path: Adam on the LML of random
    minibatches of ``batch_size`` rows drawn from *all* training rows,
    normalised by ``batch_size``, early-stopped on a held-out minibatch, from
    median-heuristic length scales wherever the kernel has the default 1.0
    (see ``data_driven_init``). Its cost per step is
    :math:`O(\mathrm{batch\_size}^3)` whatever the number of rows, and no
    ``(n, n, n_theta)`` gradient array is ever formed (the LML gradient is
    accumulated per length scale).

    Parameters
    ----------
    kernel : kernel or list of kernels, default=None
        Covariance of the GP, one for all outputs or one per output. Column
        names in :class:`~sklearn_gpcd.kernels.ARDRBF` or
        :class:`~sklearn_gpcd.kernels.QuasiStaticGate` are resolved against
        the column names of ``X``. None means
        ``ConstantKernel(1.0) * RBF(1.0) + WhiteKernel(1.0)``.
    mean : regressor or list of regressors, default=None
        Parametric mean (typically :class:`ParametricMean`), one for all
        outputs or one per output; cloned and fitted before the GP. None means
        a zero mean.
    alpha : float or ndarray of shape (n_samples,), default=1e-10
        Value added to the diagonal of the kernel matrix (jitter or known
        noise variance), as in scikit-learn's GPR.
    optimizer : {"auto", "fmin_l_bfgs_b", "adam"}, callable or None, default="auto"
        Maximiser of the log marginal likelihood. "auto" is
        "fmin_l_bfgs_b" when the support has at most 3,000 rows and at most
        60,000 rows x hyperparameters, else "adam" (see above). "fmin_l_bfgs_b" and a callable maximise the exact LML of
        the support rows; a callable has signature
        ``optimizer(obj_func, initial_theta, bounds) -> (theta_opt, f_min)``
        where ``obj_func(theta, eval_gradient=True)`` returns the negative log
        marginal likelihood and its gradient. "adam" maximises the minibatch
        LML over all rows. None keeps the initial hyperparameters.
    n_restarts_optimizer : int, default=0
        Extra optimizer runs from theta drawn log-uniformly within the bounds
        (for "adam" the runs compete on the held-out minibatch LML).
    batch_size : int, default=512
        "adam": rows per minibatch, and in the held-out minibatch.
    max_iter : int, default=500
        "adam": maximum number of steps per run.
    learning_rate : float, default=0.05
        "adam": step size, in units of log-hyperparameters.
    tol : float, default=1e-3
        "adam": improvement of the held-out per-sample LML (checked every 10
        steps) that counts as progress.
    n_iter_no_change : int, default=5
        "adam": checks without progress before stopping early; the
        hyperparameters with the best held-out LML are kept.
    normalize_y : bool, default=False
        Standardise the residual ``y - m(x)`` before fitting the GP.
    n_support : int, "auto" or None, default=None
        Number of training rows the GP is fitted and conditioned on (all
        rows when None: an exact GP, O(n^2) memory). "auto" takes at most
        ``AUTO_SUPPORT = 2000`` rows, safe on any number of rows (the
        default of :func:`make_p_f`, :func:`make_sp_s` and
        :func:`make_sp_p`). The parametric mean always uses all rows. With
        ``support_selection="random"`` all outputs share one support draw
        (see ``random_state``).
    support_selection : {"random", "greedy"}, default="random"
        How the support rows are chosen: uniformly at random, or by
        farthest-point traversal in the metric of the initial kernel
        :math:`d(x, x')^2 = k(x,x) + k(x',x') - 2k(x,x')` (deterministic
        given ``random_state``, which draws the first row).
    sigma_v : float > 0 or None, default=None
        Quasi-static velocity threshold of the paper. When set, it overrides
        every ``sigma_v`` parameter inside the (cloned) kernels and means, so
        one value tunes the gates and the :math:`\bar\phi` masks of all
        outputs, e.g. ``GridSearchCV(pipe, {"gp__sigma_v": [...]})``.
    n_jobs : int or None, default=None
        Number of outputs fitted in parallel (joblib).
    random_state : int, RandomState instance or None, default=None
        Draws the optimizer restarts and the support rows. Every output gets
        the same stream: an int is used as is, so a multi-output fit equals
        one fit per column with that ``random_state``; None or a
        ``RandomState`` draws one seed per fit. So with
        ``support_selection="random"`` the outputs are conditioned on the
        same support rows (a uniform draw does not depend on the output, so
        one draw for all is as good as one per output), and the
        :class:`~sklearn_gpcd.detection.StreamingMonitor` reads those rows
        once per tick for all outputs (one matrix product). ``"greedy"``
        selects per output, in the metric of each output's kernel.
    verbose : int, default=0
        Print one line per fitted output when > 0, and Adam's progress (every
        10 steps: minibatch and held-out per-sample LML).

    Attributes
    ----------
    kernel_ : kernel or list of kernels
        Kernel with the fitted hyperparameters (a list when
        ``n_outputs_ > 1``).
    mean_ : regressor, list of regressors or None
        Fitted parametric mean(s).
    log_marginal_likelihood_value_ : float or ndarray of shape (n_outputs,)
        Log marginal likelihood of ``kernel_.theta`` per output, on the
        support rows.
    optimizer_ : str, callable or None
        The optimizer used (``optimizer`` with "auto" resolved).
    n_iter_ : int or ndarray of shape (n_outputs,)
        Iterations of the winning optimizer run per output: Adam steps, or
        L-BFGS-B iterations (0 for None or a callable).
    support_indices_ : ndarray of shape (n_support,) or list of ndarray
        Training rows the GP of each output is conditioned on.
    n_outputs_ : int
        Number of output columns.
    n_features_in_ : int
        Number of columns of ``X``.
    feature_names_in_ : ndarray of str
        Column names of ``X``, when it has string column names.

    See Also
    --------
    ParametricMean : the parametric part.
    make_sp_p : the paper's proposed estimator built from a feature layout.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.gp import ParametricMean, SemiParametricGPRegressor
    >>> rng = np.random.RandomState(0)
    >>> X = rng.uniform(-2, 2, size=(40, 1))
    >>> y = 1.5 * X[:, 0] + np.sin(3 * X[:, 0]) + 0.01 * rng.randn(40)
    >>> gp = SemiParametricGPRegressor(mean=ParametricMean(), random_state=0)
    >>> gp.fit(X, y).mean_.coef_.round(2)   # linear part w
    array([1.23])
    >>> mean, std = gp.predict(X[:2], return_std=True)
    >>> bool(np.allclose(mean, y[:2], atol=0.05))
    True
    """

    _parameter_constraints = {
        "kernel": [None, HasMethods(["__call__", "diag"]), list, tuple],
        "mean": [None, HasMethods(["fit", "predict"]), callable, list, tuple],
        "alpha": [Interval(numbers.Real, 0, None, closed="left"), "array-like"],
        "optimizer": [None, StrOptions(set(OPTIMIZERS)), callable],
        "n_restarts_optimizer": [Interval(numbers.Integral, 0, None, closed="left")],
        "batch_size": [Interval(numbers.Integral, 1, None, closed="left")],
        "max_iter": [Interval(numbers.Integral, 1, None, closed="left")],
        "learning_rate": [Interval(numbers.Real, 0, None, closed="neither")],
        "tol": [Interval(numbers.Real, 0, None, closed="left")],
        "n_iter_no_change": [Interval(numbers.Integral, 1, None, closed="left")],
        "normalize_y": ["boolean"],
        "n_support": [None, StrOptions({"auto"}), Interval(numbers.Integral, 1, None,
                                                             closed="left")],
        "support_selection": [StrOptions(set(SUPPORT_SELECTIONS))],
        "sigma_v": [None, SIGMA_V_CONSTRAINT],
        "n_jobs": [None, numbers.Integral],
        "random_state": ["random_state"],
        "verbose": ["verbose"],
    }

    def __init__(
        self,
        kernel=None,
        mean=None,
        *,
        alpha=1e-10,
        optimizer="auto",
        n_restarts_optimizer=0,
        batch_size=512,
        max_iter=500,
        learning_rate=0.05,
        tol=1e-3,
        n_iter_no_change=5,
        normalize_y=False,
        n_support=None,
        support_selection="random",
        sigma_v=None,
        n_jobs=None,
        random_state=None,
        verbose=0,
    ):
        self.kernel = kernel
        self.mean = mean
        self.alpha = alpha
        self.optimizer = optimizer
        self.n_restarts_optimizer = n_restarts_optimizer
        self.batch_size = batch_size
        self.max_iter = max_iter
        self.learning_rate = learning_rate
        self.tol = tol
        self.n_iter_no_change = n_iter_no_change
        self.normalize_y = normalize_y
        self.n_support = n_support
        self.support_selection = support_selection
        self.sigma_v = sigma_v
        self.n_jobs = n_jobs
        self.random_state = random_state
        self.verbose = verbose

    @_fit_context(prefer_skip_nested_validation=False)
    def fit(self, X, y):
        """Fit the parametric mean, then the GP hyperparameters and posterior.

        Parameters
        ----------
        X : array-like or DataFrame of shape (n_samples, n_features)
            Inputs, e.g. the augmented layout of :mod:`sklearn_gpcd.layout`.
        y : array-like of shape (n_samples,) or (n_samples, n_outputs)
            Targets; one independent GP per column.

        Returns
        -------
        self : SemiParametricGPRegressor
        """
        X_raw = X
        X, y = validate_data(self, X, y, multi_output=True, y_numeric=True, dtype=np.float64)
        Y = y.reshape(len(y), -1)
        self.n_outputs_ = Y.shape[1]
        alpha = self._check_alpha(len(y))
        kernels, means = self._prepare_models()
        X_mean = X_raw if hasattr(X_raw, "columns") else X  # keep names for the mean
        n_exact = resolve_n_support(self.n_support, len(y))
        n_theta = max(kernel.n_dims for kernel in kernels)
        self.optimizer_ = resolve_optimizer(self.optimizer, n_exact, n_theta)
        params = self._gp_params(n_exact)
        fits = Parallel(n_jobs=self.n_jobs)(
            delayed(_fit_output)(
                kernel, mean, X, X_mean, Y[:, j], alpha, seed, params,
                f"output {j}: " if self.n_outputs_ > 1 else "",
            )
            for j, (kernel, mean, seed) in enumerate(zip(kernels, means, self._seeds()))
        )
        self._outputs = fits
        pick = (lambda v: v[0]) if self.n_outputs_ == 1 else list
        self.kernel_ = pick([fit.posterior.kernel for fit in fits])
        self.mean_ = pick([fit.mean for fit in fits])
        self.support_indices_ = pick([fit.support for fit in fits])
        lml = np.array([fit.lml for fit in fits])
        self.log_marginal_likelihood_value_ = lml[0] if self.n_outputs_ == 1 else lml
        n_iter = np.array([fit.n_iter for fit in fits])
        self.n_iter_ = int(n_iter[0]) if self.n_outputs_ == 1 else n_iter
        if self.verbose > 0:
            for j, fit in enumerate(fits):
                print(f"[{type(self).__name__}] output {j}: log-marginal-likelihood "
                      f"{fit.lml:.6g}, kernel {fit.posterior.kernel}")
        return self

    def predict(self, X, return_std=False, return_cov=False):
        """Posterior mean (and std or covariance) at ``X``.

        Parameters
        ----------
        X : array-like or DataFrame of shape (n_samples, n_features)
            Query points, with the columns seen in :meth:`fit`.
        return_std : bool, default=False
            Also return the posterior standard deviation of :math:`m + f`
            (the parametric mean is deterministic; noise in the kernel, e.g.
            a ``WhiteKernel``, is included as in scikit-learn).
        return_cov : bool, default=False
            Also return the posterior covariance (not chunked: its size is
            ``n_samples**2``).

        Returns
        -------
        y_mean : ndarray of shape (n_samples,) or (n_samples, n_outputs)
        y_std : ndarray of shape (n_samples,) or (n_samples, n_outputs)
            Only when ``return_std`` is True.
        y_cov : ndarray of shape (n_samples, n_samples) or \
                (n_samples, n_samples, n_outputs)
            Only when ``return_cov`` is True.
        """
        if return_std and return_cov:
            raise ValueError("At most one of return_std or return_cov can be requested.")
        if self._is_valid_array(X):  # lean path, e.g. one sample per control tick
            X_mean = X
        else:
            check_is_fitted(self)
            X_raw = X
            X = validate_data(self, X, reset=False, dtype=np.float64)
            X_mean = X_raw if hasattr(X_raw, "columns") else X
        if len(self._outputs) == 1:
            return self._outputs[0].predict(X, X_mean, return_std, return_cov)
        preds = [fit.predict(X, X_mean, return_std, return_cov) for fit in self._outputs]
        if not (return_std or return_cov):
            return self._stack(preds)
        return self._stack([p[0] for p in preds]), self._stack([p[1] for p in preds])

    @property
    def posteriors_(self):
        """list of :class:`~sklearn_gpcd.gp.GPPosterior`: the fitted model of each output.

        Kernel, support inputs, weights (in target units), target offset and
        parametric mean of every output, so that
        ``predict(X)[:, j] == posteriors_[j].predict_mean(X)``.

        Examples
        --------
        >>> import numpy as np
        >>> from sklearn_gpcd.gp import SemiParametricGPRegressor
        >>> X = np.linspace(0, 1, 10)[:, None]
        >>> gp = SemiParametricGPRegressor(optimizer=None).fit(X, np.c_[X, -X])
        >>> len(gp.posteriors_)
        2
        """
        check_is_fitted(self)
        return [
            GPPosterior(
                kernel=fit.posterior.kernel,
                X_train=fit.posterior.X,
                alpha=fit.posterior.y_std * fit.posterior.weights,
                y_mean=fit.posterior.y_mean,
                mean=fit.mean,
            )
            for fit in self._outputs
        ]

    def log_marginal_likelihood(self, theta=None, eval_gradient=False, output=0):
        """Log marginal likelihood of the residual GP of one output.

        Parameters
        ----------
        theta : array-like of shape (n_theta,), default=None
            Log-hyperparameters of ``kernel_`` (of output ``output``). None
            returns ``log_marginal_likelihood_value_``.
        eval_gradient : bool, default=False
            Also return the gradient with respect to theta (needs theta).
        output : int, default=0
            Output column whose GP is evaluated.

        Returns
        -------
        log_likelihood : float
        log_likelihood_gradient : ndarray of shape (n_theta,)
            Only when ``eval_gradient`` is True.
        """
        check_is_fitted(self)
        if theta is None:
            if eval_gradient:
                raise ValueError("Gradient can only be evaluated for theta != None.")
            return self.log_marginal_likelihood_value_
        if not 0 <= output < self.n_outputs_:
            raise ValueError(f"output={output} is not in [0, {self.n_outputs_}).")
        post = self._outputs[output].posterior
        theta = np.asarray(theta, dtype=float)
        if theta.shape != post.kernel.theta.shape:
            raise ValueError(
                f"theta has shape {theta.shape}, expected {post.kernel.theta.shape} "
                f"for {post.kernel}."
            )
        return _log_marginal_likelihood(
            theta, post.kernel, post.X, post.y_train, post.alpha, eval_gradient
        )

    # -- helpers -----------------------------------------------------------

    def _is_valid_array(self, X):
        """Whether ``X`` is already what ``validate_data`` would return.

        True for a fitted model (without feature names) and a finite 2-D
        float64 ndarray with ``n_features_in_`` columns: then validation
        would neither change nor reject ``X``, and the lean path skips it.
        """
        return (
            type(X) is np.ndarray
            and X.ndim == 2
            and X.dtype == np.float64
            and "_outputs" in self.__dict__
            and X.shape[1] == self.n_features_in_
            and X.shape[0] > 0
            and "feature_names_in_" not in self.__dict__
            and math.isfinite(X.sum())  # NaN and inf propagate to the sum
        )

    def _stack(self, arrays):
        """Stack per-output results on a last axis; squeeze a single output."""
        return arrays[0] if self.n_outputs_ == 1 else np.stack(arrays, axis=-1)

    def _gp_params(self, n_support):
        return {
            "n_support": n_support,
            "support_selection": self.support_selection,
            "normalize_y": self.normalize_y,
            "optimizer": self.optimizer_,
            "n_restarts_optimizer": self.n_restarts_optimizer,
            "refine": (REFINE_MAX_SAMPLES, REFINE_MAX_ITER),
            "serial_blas": self.n_outputs_ > 1,
            "adam": AdamSettings(
                self.batch_size, self.max_iter, self.learning_rate, self.tol,
                self.n_iter_no_change, self.verbose,
            ),
        }

    def _seeds(self):
        """The seed of every output: one per fit, drawn up front so results ignore
        ``n_jobs``. All outputs share it, so a ``"random"`` support is one draw."""
        seed = self.random_state
        if not isinstance(seed, numbers.Integral):
            seed = int(check_random_state(seed).randint(np.iinfo(np.int32).max))
        return [seed] * self.n_outputs_

    def _check_alpha(self, n_samples):
        alpha = np.asarray(self.alpha, dtype=float)
        if alpha.ndim == 1 and len(alpha) == 1:
            alpha = alpha[0]
        if alpha.ndim > 1 or (alpha.ndim == 1 and len(alpha) != n_samples):
            raise ValueError(
                f"alpha must be a float or an array of shape ({n_samples},), "
                f"got shape {alpha.shape}."
            )
        if not np.all(np.isfinite(alpha)) or np.any(alpha < 0):
            raise ValueError("alpha must be finite and >= 0.")
        return alpha

    def _prepare_models(self):
        """Per-output clones of kernel and mean, with sigma_v and column names set."""
        kernels = _per_output(self.kernel, self.n_outputs_, "kernel")
        means = _per_output(self.mean, self.n_outputs_, "mean")
        kernels = [_default_kernel() if k is None else clone(k) for k in kernels]
        means = [None if m is None else _check_mean(clone(m)) for m in means]
        if self.sigma_v is not None:
            n_set = sum(_set_sigma_v(obj, self.sigma_v) for obj in kernels + means)
            if n_set == 0:
                raise ValueError(
                    f"sigma_v={self.sigma_v} was given but no kernel or mean has a "
                    "`sigma_v` parameter to set."
                )
        names = getattr(self, "feature_names_in_", None)
        kernels = [
            resolve_columns(k, feature_names=names, n_features=self.n_features_in_)
            for k in kernels
        ]
        return kernels, means

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.target_tags.multi_output = True
        return tags


class _OutputFit:
    """Fitted model of one output: mean, support rows, GP posterior, LML."""

    def __init__(self, mean, support, posterior, lml, n_iter=0):
        self.mean = mean
        self.support = support
        self.posterior = posterior
        self.lml = lml
        self.n_iter = n_iter

    def predict(self, X, X_mean, return_std, return_cov):
        if return_std or return_cov:
            with single_threaded_blas():  # serial triangular solves (see _fit_output)
                gp = self.posterior.predict(X, return_std=return_std, return_cov=return_cov)
        else:
            gp = self.posterior.predict(X)
            if self.mean is None:
                return gp
        m = 0.0 if self.mean is None else np.asarray(self.mean.predict(X_mean)).ravel()
        if return_std or return_cov:
            return gp[0] + m, gp[1]
        return gp + m


def _fit_output(kernel, mean, X, X_mean, y, alpha, seed, params, label=""):
    """Fit y = m(x) + f(x) + e for one output (Eq. 17 when built by make_sp_p).

    1. m: the parametric mean, fitted on all rows (option (i), Sec. III-A);
    2. the support rows D_SDP are chosen for the GP on the residual y - m;
    3. kernel hyperparameters by type-II ML on the (normalised) residual:
       exact on the support rows, or Adam on minibatches of all rows;
    4. posterior: Cholesky factor and weights cached for prediction.

    With several outputs BLAS runs single-threaded here: parallelism comes
    from ``n_jobs`` over outputs, and results do not depend on the number of
    workers. A single output has the cores to itself: BLAS keeps its threads.
    """
    rng = check_random_state(seed)
    with single_threaded_blas() if params["serial_blas"] else nullcontext():
        if mean is not None:
            y = y - np.asarray(_fit_predict(mean, X_mean, y)).ravel()
        support = select_support(
            kernel, X, params["n_support"], params["support_selection"], rng
        )
        X_s, r_s = X[support], y[support]
        alpha_s = alpha[support] if np.ndim(alpha) else alpha
        y_mean, y_std = target_scaling(r_s, params["normalize_y"])
        optimizer, n_iter = params["optimizer"], 0
        if optimizer == "adam" and kernel.n_dims:
            kernel = data_driven_init(kernel, X, rng)
            kernel_, info = _fit_hyperparameters_adam(
                kernel, X, (y - y_mean) / y_std, alpha, params["adam"],
                params["n_restarts_optimizer"], rng, label,
            )
            n_iter = info["n_iter"]
            refine = params["refine"]
            if refine:
                rows = np.arange(len(support))
                if len(rows) > refine[0]:
                    rows = np.sort(rng.choice(len(rows), refine[0], replace=False))
                kernel_, _, _ = _fit_hyperparameters(
                    kernel_, X_s[rows], (r_s[rows] - y_mean) / y_std,
                    alpha_s[rows] if np.ndim(alpha_s) else alpha_s,
                    "fmin_l_bfgs_b", 0, rng, max_iter=refine[1],
                )
        else:
            kernel_, lml, n_iter = _fit_hyperparameters(
                kernel, X_s, (r_s - y_mean) / y_std, alpha_s,
                None if optimizer == "adam" else optimizer,
                params["n_restarts_optimizer"], rng,
            )
        with single_threaded_blas():  # the same factor as when rebuilt for std
            posterior = _Posterior(kernel_, X_s, r_s, alpha_s, y_mean, y_std)
    if optimizer == "adam":
        lml = posterior.log_marginal_likelihood
    elif not np.isfinite(lml):  # K + alpha I singular at every theta tried
        warnings.warn(
            f"{label}the kernel matrix K + alpha I is singular at every theta tried, so "
            "the hyperparameters were not optimized; the posterior uses jitter "
            f"{posterior.jitter:.3g} and log_marginal_likelihood_value_ includes it. "
            "Increase `alpha` (duplicate inputs?).",
            ConvergenceWarning,
        )
        lml = posterior.log_marginal_likelihood
    return _OutputFit(mean, support, posterior, lml, n_iter)


def _fit_predict(mean, X, y):
    """``mean.fit(X, y).predict(X)`` (in one pass for a :class:`ParametricMean`)."""
    if isinstance(mean, ParametricMean):
        return mean._fit_predict(X, y)
    return mean.fit(X, y).predict(X)


def _per_output(value, n_outputs, name):
    """Repeat a single object for every output, or check a list's length."""
    if isinstance(value, (list, tuple)):
        if len(value) != n_outputs:
            raise ValueError(
                f"{name} is a list of {len(value)} items but y has {n_outputs} "
                f"output column(s); give one {name} per output or a single {name}."
            )
        return list(value)
    return [value] * n_outputs


def _check_mean(mean):
    if not (hasattr(mean, "fit") and hasattr(mean, "predict")):
        raise TypeError(
            f"mean must be a regressor with fit/predict or None, got {type(mean).__name__}."
        )
    return mean


def _set_sigma_v(obj, sigma_v):
    r"""Set every parameter named ``sigma_v`` (at any depth) of ``obj``.

    "Every" is safe because the name has one meaning in the package: the
    quasi-static threshold of Eq. 15 (the kernels' gates, a mean's
    :math:`\bar\phi` mask and its feature map's, e.g. a
    ``RigidBodyFeatures``). Depth is what ``get_params(deep=True)`` reaches
    (kernel operands, a mean's ``features`` estimator); an object kept in a
    plain list or a callable is not reached and keeps its own value.

    Returns the number of parameters set (0 for None).
    """
    if obj is None:
        return 0
    keys = [k for k in obj.get_params(deep=True) if k.split("__")[-1] == "sigma_v"]
    if keys:
        obj.set_params(**dict.fromkeys(keys, sigma_v))
    return len(keys)
