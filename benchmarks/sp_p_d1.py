"""Benchmark (c): full SP_P training on a D1-sized set (80,000 samples x 6 joints).

D1 is simulated with the paper's protocol (``simulate_d1("ur10", n_targets=200)``,
~80,000 samples at 125 Hz, ~30 s); the inputs are the augmented ``x^a`` of
Eq. 13 (36 columns). SP_P (``make_sp_p``: per joint ``C * ARDRBF(18 cols) +
C * QuasiStaticGate(ARDRBF(36 cols)) + White`` around the rigid-body +
friction mean) is trained with ``n_support=5000`` and the default
``optimizer="auto"`` (here: Adam on minibatches of all 80,000 rows, then
L-BFGS-B refinement). Prints the training wall time and the peak resident
memory (``resource.getrusage``): the joints are fitted in ``--n-jobs`` loky
worker processes, which are shut down after the fit so that their peak is
reported too; the printed bound is parent peak + n_jobs x worker peak (an
upper bound on the simultaneous total). Run::

    python benchmarks/sp_p_d1.py [--n-jobs 2]
"""

import argparse
import resource
import time

import numpy as np
from joblib.externals.loky import get_reusable_executor

from _common import table
from sklearn_gpcd import datasets
from sklearn_gpcd.dynamics import RigidBodyFeatures
from sklearn_gpcd.features import make_inputs
from sklearn_gpcd.gp import make_sp_p
from sklearn_gpcd.robots import resolve_robot


def peak_rss_mb(who=resource.RUSAGE_SELF):
    """Peak resident set size of this process (or its finished children), MB."""
    return resource.getrusage(who).ru_maxrss / 1024  # ru_maxrss is in KiB on Linux


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-jobs", type=int, default=2)
    args = parser.parse_args()
    tic = time.perf_counter()
    rec = datasets.simulate_d1("ur10", n_targets=200, random_state=0)
    X, Y = make_inputs(rec, augmented=True)
    t_sim = time.perf_counter() - tic
    rss_data = peak_rss_mb()
    print(f"(c) simulated D1: {X.shape[0]} samples x {Y.shape[1]} joints, {X.shape[1]} input "
          f"columns in {t_sim:.1f} s (peak RSS so far {rss_data:.0f} MB)", flush=True)
    robot = resolve_robot("ur10")
    features = [RigidBodyFeatures(robot, joint=j) for j in range(rec.n_joints)]
    model = make_sp_p(features, rec.n_joints, n_support=5000, random_state=0, n_jobs=args.n_jobs)
    tic = time.perf_counter()
    model.fit(X, Y)
    t_fit = time.perf_counter() - tic
    get_reusable_executor().shutdown(wait=True)  # reap the workers for RUSAGE_CHILDREN
    parent, worker = peak_rss_mb(), peak_rss_mb(resource.RUSAGE_CHILDREN)
    rss = parent + (args.n_jobs if args.n_jobs > 1 else 0) * worker
    print(f"peak RSS: parent {parent:.0f} MB, largest worker {worker:.0f} MB")
    held_out = np.ones(len(X), dtype=bool)
    resid = []
    for j in range(rec.n_joints):
        rows = held_out.copy()
        rows[model.support_indices_[j]] = False
        pred = model._outputs[j].predict(X[rows], X[rows], False, False)
        resid.append(np.mean((Y[rows, j] - pred) ** 2) / np.var(Y[rows, j]))
    table(
        [["SP_P fit (80k x 6, n_support=5000)", f"{t_fit:.1f}", f"{rss:.0f}",
          str(model.optimizer_), " ".join(str(i) for i in model.n_iter_)]],
        ["what", "wall s", "peak RSS MB", "optimizer", "Adam steps per joint"],
    )
    print("nMSE on D1 minus D_SDP per joint:", " ".join(f"{v:.4f}" for v in resid))
    print(f"targets: < 120 s wall, < 2048 MB peak -> "
          f"{'met' if t_fit < 120 and rss < 2048 else 'NOT met'}")


if __name__ == "__main__":
    main()
