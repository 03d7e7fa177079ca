"""
=====================================================
Choosing sigma_v: Pipeline and GridSearchCV over runs
=====================================================

``sigma_v`` is the velocity (rad/s) below which a joint counts as
quasi-static (paper Eq. 15): below it SP_P switches on its quasi-static
kernel and zeroes the friction columns of the parametric part. The paper
uses ``1e-2``; on another robot, another encoder or another velocity filter
the right value can differ. Since one parameter of the estimator
(:class:`~sklearn_gpcd.gp.SemiParametricGPRegressor`'s ``sigma_v``) sets
every gate and every friction mask, scikit-learn's
:class:`~sklearn.model_selection.GridSearchCV` tunes it like any other
hyperparameter.

Two details matter for robot data:

* **folds by recording** -- neighbouring samples of a time series are almost
  copies of each other, so a shuffled K-fold would score the GP on its own
  training data. :class:`~sklearn.model_selection.GroupKFold` with one group
  per recording keeps each run whole;
* **the score** -- the stiction current only matters for the joint that
  moves and stops (joint 1 here), and it is a small part of the total
  variance, so we score the nMSE (Eq. 18) of joint 1.

The input matrix carries the 36 model inputs ``q_0 ... i_c_5`` plus a last
bookkeeping column, the run each sample came from; the pipeline's first step
drops it, so the same matrix serves the model and the fold assignment.
"""

# %%
# Three short runs of the cyclic joint-1 test
# -------------------------------------------
import matplotlib.pyplot as plt
import numpy as np
from sklearn.compose import ColumnTransformer
from sklearn.metrics import make_scorer
from sklearn.model_selection import GridSearchCV, GroupKFold
from sklearn.pipeline import Pipeline

from sklearn_gpcd.datasets import simulate_joint1_cyclic
from sklearn_gpcd.dynamics import RigidBodyFeatures
from sklearn_gpcd.features import InverseDynamicsFeatures, targets
from sklearn_gpcd.gp import make_sp_p
from sklearn_gpcd.metrics import nmse

runs = [simulate_joint1_cyclic("ur10", rest_duration=2.0, random_state=seed) for seed in range(3)]
inputs = InverseDynamicsFeatures().fit(runs)
run_id = np.concatenate([np.full(run.n_samples, k) for k, run in enumerate(runs)])
X = np.column_stack([inputs.transform(runs), run_id])
y = targets(runs)
names = list(inputs.get_feature_names_out())
print(X.shape, "columns", names[:3], "...", names[-3:], "+ run")

# %%
# The pipeline and the search
# ---------------------------
# ``make_sp_p`` returns the paper's SP_P estimator; its ``sigma_v`` parameter
# overrides the threshold of the six gates and the six friction masks at
# once, so the grid is over ``gp__sigma_v``.
# (base_parameters=False: see the quick start)
features = [RigidBodyFeatures("ur10", joint=j, base_parameters=False) for j in range(6)]
pipe = Pipeline([
    ("inputs", ColumnTransformer([("drop_run", "drop", [X.shape[1] - 1])],
                                 remainder="passthrough")),
    ("gp", make_sp_p(features, n_joints=6, n_support=100, random_state=0)),
])


def joint1_nmse(y_true, y_pred):
    """nMSE (Eq. 18) of joint 1's current."""
    return nmse(y_true[:, 0], y_pred[:, 0])


search = GridSearchCV(
    pipe,
    {"gp__sigma_v": [1e-3, 1e-2, 1e-1]},
    cv=GroupKFold(n_splits=3),
    scoring=make_scorer(joint1_nmse, greater_is_better=False),
    n_jobs=2,  # candidates x folds in parallel (joblib)
)
search.fit(X, y, groups=run_id)
print("best:", search.best_params_)
for sigma_v, score in zip(search.cv_results_["param_gp__sigma_v"],
                          search.cv_results_["mean_test_score"]):
    print(f"sigma_v={sigma_v:g}: held-out nMSE of joint 1 = {-score:.2e}")

# %%
# Held-out nMSE against sigma_v
# -----------------------------
# A threshold far below the velocity noise leaves the gate shut during most
# rests, and the stiction current stays unexplained. The refitted best
# pipeline (``search.best_estimator_``) is ready to predict.
fig, ax = plt.subplots(figsize=(5, 3.2))
ax.semilogx(search.cv_results_["param_gp__sigma_v"].astype(float),
            -search.cv_results_["mean_test_score"], "o-")
ax.set_xlabel("sigma_v [rad/s]")
ax.set_ylabel("held-out nMSE, joint 1")
ax.set_title("GridSearchCV over sigma_v (3 runs, GroupKFold)")
fig.tight_layout()
plt.show()
