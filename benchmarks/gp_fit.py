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

    python benchmarks/gp_fit.py [--baseline /path/to/other/checkout]

``--baseline`` also fits and times *our* models with the package of another
checkout (e.g. the previous main), in a subprocess right after this run, and
reports both against the same sklearn fit and latency: "no speed lost"
measured in one run.
"""

import argparse
import json
import os
import subprocess
import sys
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


def baseline_figures(path):
    """Fit seconds, evaluations, LML and latency of our models with the package at ``path``."""
    env = dict(os.environ, PYTHONPATH=os.path.abspath(path))
    out = subprocess.run([sys.executable, __file__, "--ours-only"], env=env, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def ours_only():
    """``--ours-only``: our two fits and latencies, one JSON line (for ``--baseline``)."""
    X, y, X_test, _ = d1_state_problem()
    kernel = ConstantKernel(1.0) * RBF(np.ones(X.shape[1])) + WhiteKernel(1.0)
    figures = {"package": os.path.dirname(os.path.dirname(_optimize.__file__))}
    queries = [X_test[i : i + 1] for i in range(2000)]
    for name, optimizer in (("ours auto", "auto"), ("ours adam", "adam")):
        model = SemiParametricGPRegressor(kernel, normalize_y=True, optimizer=optimizer,
                                          random_state=0)
        with count_evaluations() as count:
            _, seconds = timed(model.fit, X, y)
        figures[name] = {"seconds": seconds, "evaluations": count[0],
                         "lml": float(model.log_marginal_likelihood_value_),
                         "latency_s": latency(model.predict, queries)}
    print(json.dumps(figures))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", default=None,
                        help="another checkout whose package is timed too (e.g. previous main)")
    parser.add_argument("--ours-only", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.ours_only:
        return ours_only()
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
    if args.baseline is None:
        return None
    base = baseline_figures(args.baseline)
    print(f"\n(c) the same fits with the package of {base['package']} (run right after), "
          "against the same sklearn figures")
    rows = []
    for name in ("ours auto", "ours adam"):
        b = base[name]
        rows.append([name, f"{b['seconds']:.1f}", f"{seconds['sklearn'] / b['seconds']:.1f}x",
                     f"{seconds['sklearn'] / seconds[name]:.1f}x", str(b["evaluations"]),
                     f"{b['lml']:.2f}", f"{1e6 * b['latency_s']:.1f}",
                     f"{t_ref / b['latency_s']:.1f}x"])
    table(rows, ["model", "baseline fit s", "baseline speed-up", "this speed-up",
                 "baseline evals", "baseline LML", "baseline us per sample",
                 "baseline lower than sklearn"])
    return base


if __name__ == "__main__":
    main()
