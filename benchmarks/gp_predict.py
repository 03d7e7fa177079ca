"""Benchmark (b): single-sample predict latency, ours vs scikit-learn, same model.

Ours is fitted (``optimizer="auto"``) on n = 3,000 rows of a simulated D1
with an 18-dim ARD RBF + noise; scikit-learn's ``GaussianProcessRegressor``
is then fitted with ``optimizer=None`` and our fitted kernel on the same
rows, so both hold the same model (their predictions are compared too).
Latency: ``predict`` on one row at a time, 2,000 rows, median of 5 passes.
(``benchmarks/gp_fit.py`` measures the same on the models of benchmark (a).)
Run::

    python benchmarks/gp_predict.py
"""

import numpy as np
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

from _common import d1_state_problem, latency, table, timed
from sklearn_gpcd.gp import SemiParametricGPRegressor


def main():
    X, y, X_test, _ = d1_state_problem()
    kernel = ConstantKernel(1.0) * RBF(np.ones(X.shape[1])) + WhiteKernel(1.0)
    ours, t_fit = timed(SemiParametricGPRegressor(kernel, normalize_y=True, random_state=0).fit, X, y)
    theirs = GaussianProcessRegressor(ours.kernel_, normalize_y=True, optimizer=None).fit(X, y)
    gap = np.max(np.abs(ours.predict(X_test) - theirs.predict(X_test)))
    print(f"(b) n_support = {len(X)}, kernel {ours.kernel_} (ours fitted in {t_fit:.1f} s); "
          f"max |ours - sklearn| prediction gap {gap:.2e}")
    queries = [X_test[i : i + 1] for i in range(2000)]
    t_ref = latency(theirs.predict, queries)
    t_ours = latency(ours.predict, queries)
    table(
        [["sklearn GaussianProcessRegressor", f"{1e6 * t_ref:.1f}", "1.0x"],
         ["ours SemiParametricGPRegressor", f"{1e6 * t_ours:.1f}", f"{t_ref / t_ours:.1f}x"]],
        ["model", "us per sample", "lower than sklearn"],
    )


if __name__ == "__main__":
    main()
