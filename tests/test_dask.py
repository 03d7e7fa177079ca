"""Scale-out on dask (issue #9): the same results as the local joblib backend.

A two-process ``LocalCluster`` is started once for the module. Under
``joblib.parallel_config(backend="dask")`` the three parallel entry points

1. the per-joint fits of SP_P (``SemiParametricGPRegressor(n_jobs=...)``),
2. ``GridSearchCV`` over ``sigma_v`` of a Pipeline holding SP_P,
3. ``CollisionThresholdCV`` (folds x candidates, GridSearchCV),

must give bit-identical results to the default (loky) backend, and the
scheduler's task stream must show that the work ran on the cluster's
workers: the number of joblib calls of each function is counted from the
task keys, so a backend that was silently bypassed fails the test. The
cluster recipe of ``docs/user_guide/scale.rst`` is executed as written,
with the scheduler address of the local cluster.
"""

import re
from collections import Counter
from pathlib import Path

import joblib
import numpy as np
import pytest
from sklearn.base import clone
from sklearn.model_selection import GridSearchCV, GroupKFold
from sklearn.pipeline import Pipeline

from sklearn_gpcd import datasets
from sklearn_gpcd.detection import (
    AlarmRule,
    CollisionDetector,
    CollisionThresholdCV,
    stack_currents,
)
from sklearn_gpcd.dynamics import RigidBodyFeatures
from sklearn_gpcd.features import make_inputs
from sklearn_gpcd.gp import make_sp_p
from sklearn_gpcd.robots import load_robot

distributed = pytest.importorskip("dask.distributed")

SCALE_PAGE = Path(__file__).resolve().parents[1] / "docs" / "user_guide" / "scale.rst"
DOCS_ADDRESS = '"tcp://scheduler:8786"'
N_JOINTS = 6


# ---------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        yield cluster


@pytest.fixture(scope="module")
def client(cluster):
    with distributed.Client(cluster) as client:
        yield client


@pytest.fixture(scope="module")
def robot_data():
    """Three 2-s simulated UR10 recordings (D1-like, random targets)."""
    robot = load_robot("ur10")
    recordings = [datasets.simulate_d1(robot, n_targets=1, random_state=s).slice(0, 250)
                  for s in range(3)]
    X, y = make_inputs(recordings)
    groups = np.repeat(np.arange(3), [r.n_samples for r in recordings])
    features = [RigidBodyFeatures(robot, joint=j) for j in range(N_JOINTS)]
    return X, y, groups, features


def sp_p(features, **params):
    """A small SP_P; the searches use short Adam runs (random minibatches)."""
    params = {"optimizer": "adam", "batch_size": 64, "max_iter": 30, **params}
    return make_sp_p(features, N_JOINTS, n_support=40, random_state=0, **params)


def joblib_calls(task_stream):
    """Number of joblib calls per function among the tasks the workers ran.

    joblib's dask backend names each task ``batch_of_<function>_<n>_calls``.
    """
    calls = Counter()
    for task in task_stream.data:
        match = re.match(r"batch_of_(\w+?)_(\d+)_calls", task["key"])
        if match:
            calls[match.group(1)] += int(match.group(2))
    return calls


def run_on_dask(client, function):
    """``function()`` under the dask backend; its result, joblib calls and workers."""
    with distributed.get_task_stream(client) as stream:
        with joblib.parallel_config(backend="dask"):
            result = function()
    workers = {task["worker"] for task in stream.data}
    assert workers and workers <= set(client.scheduler_info()["workers"])
    return result, joblib_calls(stream)


def assert_same_results(local, remote, keys):
    for key in keys:
        a, b = local[key], remote[key]
        if key == "params":
            assert a == b
        else:
            assert np.array_equal(a, b, equal_nan=True), key


# ------------------------------------------------------------------ tests
def test_per_joint_fits_run_on_the_workers(client, robot_data):
    X, y, _, features = robot_data
    model = sp_p(features, optimizer="fmin_l_bfgs_b", n_jobs=2)  # exact LML
    local = clone(model).fit(X, y)  # default backend (loky processes)
    remote, calls = run_on_dask(client, lambda: clone(model).fit(X, y))
    assert calls == {"_fit_output": N_JOINTS}  # one task per joint
    assert np.array_equal(remote.predict(X), local.predict(X))
    for a, b in zip(local.kernel_, remote.kernel_):
        assert np.array_equal(a.theta, b.theta)
    for a, b in zip(local.support_indices_, remote.support_indices_):
        assert np.array_equal(a, b)
    assert np.array_equal(local.log_marginal_likelihood_value_,
                          remote.log_marginal_likelihood_value_)


def test_grid_search_over_sigma_v_runs_on_the_workers(client, robot_data):
    X, y, groups, features = robot_data
    search = GridSearchCV(
        Pipeline([("gp", sp_p(features))]), {"gp__sigma_v": [3e-3, 3e-2]},
        cv=GroupKFold(3), n_jobs=2,
    )
    local = clone(search).fit(X, y, groups=groups)
    remote, calls = run_on_dask(client, lambda: clone(search).fit(X, y, groups=groups))
    # 2 candidates x 3 folds; the estimator's n_jobs=None follows the dask
    # backend too, so the per-joint fits of every fold and of the refit are
    # tasks of their own
    assert calls == {"_fit_and_score": 6, "_fit_output": (6 + 1) * N_JOINTS}
    assert remote.best_params_ == local.best_params_
    keys = ["params", "mean_test_score", "rank_test_score"]
    keys += [f"split{k}_test_score" for k in range(3)]
    assert_same_results(local.cv_results_, remote.cv_results_, keys)
    assert np.array_equal(remote.predict(X), local.predict(X))


def labelled(robot_data):
    """Detector input with a 3 A bump on joint 1 in every recording."""
    X, y, groups, _ = robot_data
    current = y.copy()
    labels = np.zeros(len(y), dtype=int)
    for k, start in enumerate(np.flatnonzero(np.diff(groups, prepend=-1))):
        rows = slice(start + 120, start + 140)
        current[rows, 1] += 3.0
        labels[rows] = k + 1
    return stack_currents(X, current), labels, groups


def test_threshold_search_runs_on_the_workers(client, robot_data):
    Z, labels, groups = labelled(robot_data)
    search = CollisionThresholdCV(
        CollisionDetector(sp_p(robot_data[3]), n_joints=N_JOINTS, rules=AlarmRule()),
        {"sigma_v": [3e-3, 3e-2], "rules__min_duration": [1, 3]}, cv=3, max_delay=0.2,
        n_jobs=2,
    )
    local = clone(search).fit(Z, labels, groups=groups)
    remote, calls = run_on_dask(client, lambda: clone(search).fit(Z, labels, groups=groups))
    # GridSearchCV: 3 folds x 4 candidates, then the refit
    assert calls == {"_fit_and_score": 12, "_fit_output": (12 + 1) * N_JOINTS}
    assert remote.best_params_ == local.best_params_
    assert_same_results(local.cv_results_, remote.cv_results_, list(local.cv_results_))
    assert np.all(remote.cv_results_["mean_test_recall"] > 0)  # the bumps are found
    assert np.array_equal(remote.predict(Z), local.predict(Z))


def test_blas_limit_works_on_a_worker(client):
    def blas_threads():
        from threadpoolctl import threadpool_info

        from sklearn_gpcd.gp._likelihood import single_threaded_blas

        with single_threaded_blas():
            return [pool["num_threads"] for pool in threadpool_info()
                    if pool["user_api"] == "blas"]

    threads = client.submit(blas_threads, pure=False).result()
    assert threads and set(threads) == {1}


def docs_recipe():
    """The code block of scale.rst that connects to a cluster."""
    text = SCALE_PAGE.read_text()
    for block in text.split(".. code-block:: python")[1:]:
        lines = []
        for line in block.splitlines()[1:]:
            if line.strip() and not line.startswith("    "):
                break
            lines.append(line[4:])
        code = "\n".join(lines)
        if f"Client({DOCS_ADDRESS})" in code:
            return code
    raise AssertionError(f"no code block with Client({DOCS_ADDRESS}) in {SCALE_PAGE}")


def test_docs_cluster_recipe_runs_as_written(cluster, client, robot_data, capsys):
    X, y, groups, features = robot_data
    code = docs_recipe()
    assert "scatter=[X, y]" in code
    code = code.replace(DOCS_ADDRESS, repr(cluster.scheduler_address))
    namespace = {"model": sp_p(features), "X": X, "y": y, "groups": groups}
    with distributed.get_task_stream(client) as stream:
        try:
            exec(compile(code, str(SCALE_PAGE), "exec"), namespace)
        finally:
            if "client" in namespace:
                namespace["client"].close()
    search = namespace["search"]
    n_fits = len(search.cv_results_["params"]) * search.n_splits_
    assert joblib_calls(stream)["_fit_and_score"] == n_fits
    local = clone(search).set_params(n_jobs=2).fit(X, y, groups=groups)
    assert search.best_params_ == local.best_params_
    assert_same_results(local.cv_results_, search.cv_results_,
                        ["params", "mean_test_score", "rank_test_score"])
    assert str(search.best_params_) in capsys.readouterr().out
