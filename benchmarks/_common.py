"""Shared data and timing helpers of the GP benchmarks (run on demand).

The data are simulated by :func:`sklearn_gpcd.datasets.simulate_d1` (UR10, the
paper's D1 protocol): inputs ``x = [q, qd, qdd]`` of the 6 joints (the 18
state columns the SP_S kernel of Eq. 11 sees) and the current of one joint.
"""

import time

import numpy as np

from sklearn_gpcd import datasets
from sklearn_gpcd.layout import state_columns
from sklearn_gpcd.features import make_inputs


def d1_state_problem(n_train=3000, n_test=3000, joint=1, n_targets=40, random_state=0):
    """``(X_train, y_train, X_test, y_test)``: disjoint random rows of a simulated D1."""
    rec = datasets.simulate_d1("ur10", n_targets=n_targets, random_state=random_state)
    X, Y = make_inputs(rec, augmented=True)
    X = X[:, state_columns(rec.n_joints)]
    rows = np.random.RandomState(random_state).permutation(len(X))
    if len(rows) < n_train + n_test:
        raise ValueError(f"simulated D1 has {len(rows)} rows; raise n_targets")
    train, test = rows[:n_train], rows[n_train : n_train + n_test]
    return X[train], Y[train, joint], X[test], Y[test, joint]


def timed(func, *args, **kwargs):
    """``(result, seconds)`` of one call."""
    tic = time.perf_counter()
    result = func(*args, **kwargs)
    return result, time.perf_counter() - tic


def latency(predict, rows, repeat=5):
    """Median over ``repeat`` passes of the mean time of ``predict(row)`` per row (s)."""
    for row in rows[:20]:
        predict(row)
    passes = []
    for _ in range(repeat):
        tic = time.perf_counter()
        for row in rows:
            predict(row)
        passes.append((time.perf_counter() - tic) / len(rows))
    return float(np.median(passes))


def nmse(y, y_pred):
    """Normalised mean squared error (paper, Eq. 18)."""
    return float(np.mean((y - y_pred) ** 2) / np.var(y))


def table(rows, header):
    """Print a plain-text table."""
    widths = [max(len(str(r[i])) for r in [header] + rows) for i in range(len(header))]
    line = "  ".join(f"{{:<{w}}}" for w in widths)
    print(line.format(*header))
    print(line.format(*["-" * w for w in widths]))
    for r in rows:
        print(line.format(*r))


# -- real-data benchmarks ---------------------------------------------------
def real_data_path(dataset, explicit=None):
    """Folder of a real data set: ``explicit``, else ``$GPCD_REAL_DATA/dataset``,
    else ``../shared/data/real/dataset`` next to the repository."""
    import os
    from pathlib import Path

    if explicit:
        return Path(explicit).resolve()
    base = os.environ.get("GPCD_REAL_DATA")
    if base:
        return (Path(base) / dataset).resolve()
    repo = Path(__file__).resolve().parents[1]
    return (repo / ".." / "shared" / "data" / "real" / dataset).resolve()


def require_data(root, description, files=()):
    """Exit 0 with a clear message when the data (or one of ``files``) is absent."""
    import sys

    missing = [str(f) for f in files if not (root / f).exists()]
    if not root.is_dir() or missing:
        what = f"{root}" if not root.is_dir() else ", ".join(missing[:3])
        print(f"{description} not found ({what}): nothing to benchmark. Point --data or "
              "GPCD_REAL_DATA at the data; it is never shipped with the package.")
        sys.exit(0)


def _cell(value):
    if isinstance(value, float):
        return "n/a" if not np.isfinite(value) else f"{value:.3g}"
    return str(value)


def rst_table(header, rows):
    """A reStructuredText grid table of ``rows`` under ``header`` (floats to 3 digits)."""
    cells = [[_cell(v) for v in header]] + [[_cell(v) for v in row] for row in rows]
    widths = [max(len(r[k]) for r in cells) for k in range(len(header))]
    rule = "+" + "+".join("-" * (w + 2) for w in widths) + "+"
    line = lambda r: "| " + " | ".join(c.ljust(w) for c, w in zip(r, widths)) + " |"  # noqa: E731
    out = [rule, line(cells[0]), rule.replace("-", "=")]
    for r in cells[1:]:
        out += [line(r), rule]
    return "\n".join(out)


def write_json(path, obj):
    """``obj`` as JSON, numpy arrays and scalars converted, NaN as null."""
    import json

    from sklearn_gpcd.experiments.paper import _jsonable

    with open(path, "w") as fh:
        json.dump(_jsonable(obj), fh, indent=2)
