"""Benchmark (a) and (b): hyperparameter fit and single-sample latency vs sklearn.

(a) fit with hyperparameter optimization, n = 3,000 rows of a simulated D1,
    18-dim ARD RBF + noise (``C * RBF(ones(18)) + WhiteKernel``,
    ``normalize_y=True``): wall time and log marginal likelihood (LML, of the
    3,000 training rows) of scikit-learn's ``GaussianProcessRegressor``, of
    ours with the default ``optimizer="auto"`` (which picks the exact path
    here, 3,000 rows x 20 hyperparameters: same start and objective as
    sklearn, L-BFGS-B keeping 50 correction pairs where sklearn keeps scipy's
    default 10) and of ours with ``optimizer="adam"`` (the stochastic path:
    Adam on minibatches, then L-BFGS-B refinement on 1,000 rows);
    nMSE on 3,000 held-out rows, and the number of likelihood evaluations
    (sklearn's final ``log_marginal_likelihood`` call at the optimum counts
    as one).
(b) single-sample ``predict`` latency of the same fitted models.

All measured in one run on the same data. sklearn's fit takes ~11 min on an
idle 2-core machine. Run::

    python benchmarks/gp_fit.py
"""

from contextlib import contextmanager

import numpy as np
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

from _common import d1_state_problem, latency, nmse, table, timed
from sklearn_gpcd.gp import SemiParametricGPRegressor, _optimize


@contextmanager
def count_evaluations():
    """Count log-marginal-likelihood evaluations of sklearn's GPR and of ours."""
    count = [0]
    ours = _optimize._log_marginal_likelihood
    theirs = GaussianProcessRegressor.log_marginal_likelihood

    def ours_counted(*args, **kwargs):
        count[0] += 1
        return ours(*args, **kwargs)

    def theirs_counted(self, *args, **kwargs):
        count[0] += 1
        return theirs(self, *args, **kwargs)

    _optimize._log_marginal_likelihood = ours_counted
    GaussianProcessRegressor.log_marginal_likelihood = theirs_counted
    try:
        yield count
    finally:
        _optimize._log_marginal_likelihood = ours
        GaussianProcessRegressor.log_marginal_likelihood = theirs


def main():
    X, y, X_test, y_test = d1_state_problem()
    kernel = ConstantKernel(1.0) * RBF(np.ones(X.shape[1])) + WhiteKernel(1.0)
    print(f"(a) n = {len(X)}, {X.shape[1]}-dim ARD RBF + noise; nMSE on {len(X_test)} held-out rows")
    models = {
        "ours auto": SemiParametricGPRegressor(kernel, normalize_y=True, random_state=0),
        "ours adam": SemiParametricGPRegressor(
            kernel, normalize_y=True, optimizer="adam", random_state=0
        ),
        "sklearn": GaussianProcessRegressor(kernel, normalize_y=True, random_state=0),
    }
    seconds, evaluations = {}, {}
    for name, model in models.items():
        with count_evaluations() as count:
            _, seconds[name] = timed(model.fit, X, y)
        evaluations[name] = count[0]
        print(f"  fitted {name} in {seconds[name]:.1f} s ({count[0]} likelihood evaluations)",
              flush=True)
    ref = models["sklearn"]
    rows = []
    for name, model in models.items():
        lml = float(model.log_marginal_likelihood_value_)
        rows.append([
            name, f"{seconds[name]:.1f}", f"{seconds['sklearn'] / seconds[name]:.1f}x",
            str(evaluations[name]), f"{seconds[name] / max(evaluations[name], 1):.2f}",
            f"{lml:.2f}", f"{lml - ref.log_marginal_likelihood_value_:+.2f}",
            f"{nmse(y_test, model.predict(X_test)):.4f}",
        ])
    table(rows, ["model", "fit s", "speed-up", "LML evals", "s per eval", "LML",
                 "LML - sklearn", "nMSE"])
    print(f"  ours auto used optimizer {models['ours auto'].optimizer_!r}")

    print("\n(b) single-sample predict latency (same fitted models, 2,000 rows, one at a time)")
    queries = [X_test[i : i + 1] for i in range(2000)]
    t_ref = latency(ref.predict, queries)
    rows = []
    for name, model in models.items():
        t = latency(model.predict, queries)
        rows.append([name, f"{1e6 * t:.1f}", f"{t_ref / t:.1f}x"])
    table(rows, ["model", "us per sample", "lower than sklearn"])


if __name__ == "__main__":
    main()
