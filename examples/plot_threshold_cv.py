"""
==================================================
Collision thresholds by cross-validation over runs
==================================================

A collision detector turns the monitoring signal ``s = i - i_hat`` into
alarms: joint ``l`` fires when ``|s_l|`` (optionally low-pass filtered)
stays above a threshold ``sigma_CD,l`` for ``min_duration`` samples. The
thresholds and the filter trade missed contacts against false alarms, and
the right trade-off is an application decision. With labelled recordings
(contacts known, ``Recording.labels > 0``),
:class:`~sklearn_gpcd.detection.CollisionThresholdCV` scores every setting by
cross-validation **over recordings** and picks the one with the best event
recall, then the fewest false alarms per hour, among those whose mean
detection delay stays below ``max_delay``.

The model of the collision-free currents is the paper's SP_P, fitted once on
a collision-free run and frozen
(:class:`sklearn.frozen.FrozenEstimator`): the search only tunes the
detector's post-processing, so every fold reuses the same model and the
thresholds of each fold are calibrated on the collision-free rows of its
training runs.
"""

# %%
# Labelled runs: pushes on link 1 at rest and while moving
# --------------------------------------------------------
# :class:`~sklearn_gpcd.datasets.Contact` is a force on a link over a time
# interval; the simulator labels its samples. Each run of the cyclic joint-1
# test gets one push during a rest and one while joint 1 moves, each up to
# 60 Nm on joint 1 (300 N at 0.2 m from the axis).
import matplotlib.pyplot as plt
import numpy as np
from sklearn.frozen import FrozenEstimator

from sklearn_gpcd.datasets import Contact, simulate_joint1_cyclic, reference_joint1_cyclic, simulate
from sklearn_gpcd.detection import (AlarmRule, CollisionDetector, CollisionThresholdCV,
                                    stack_currents)
from sklearn_gpcd.dynamics import RigidBodyFeatures
from sklearn_gpcd.features import make_inputs
from sklearn_gpcd.gp import make_sp_p
from sklearn_gpcd.plotting import plot_monitoring

reference = reference_joint1_cyclic("ur10", rest_duration=2.0)
rests = [p for p in reference.phases if p["kind"] == "rest"]
moves = [p for p in reference.phases if p["kind"] == "move"]


def push(start, direction):
    """A 1 s push on link 1, perpendicular to the link, 0.2 m from the axis."""
    return Contact(link=1, start=start, duration=1.0, force=[0.0, 300.0 * direction, 0.0],
                   point=[0.2, 0.0, 0.0], frame="local")


runs = []
for k in range(4):
    rest, move = rests[1 + k % 3], moves[k]
    direction = 1 if k % 2 else -1
    contacts = [push(rest["start"] + 0.5, direction),
                push(0.5 * (move["start"] + move["stop"]) - 0.5, -direction)]
    runs.append(simulate(reference, "ur10", contacts=contacts, name=f"pushed run {k}",
                         random_state=k))
X, y = make_inputs(runs)
labels = np.concatenate([run.labels for run in runs])
groups = np.concatenate([np.full(run.n_samples, k) for k, run in enumerate(runs)])
print(f"{len(runs)} runs, {len(y)} samples, "
      f"{sum(len(set(run.labels[run.labels > 0])) for run in runs)} contacts")

# %%
# The current model: SP_P fitted on a collision-free run
# ------------------------------------------------------
free = simulate_joint1_cyclic("ur10", rest_duration=2.0, random_state=10)
# (base_parameters=False: see the quick start)
features = [RigidBodyFeatures("ur10", joint=j, base_parameters=False) for j in range(6)]
model = make_sp_p(features, n_joints=6, n_support=150, random_state=0)
model.fit(*make_inputs(free))

# %%
# Search thresholds, filter and debounce
# --------------------------------------
# ``contamination`` sets each joint's threshold so that this fraction of the
# collision-free training samples would be flagged; ``filter_cutoff`` (Hz)
# low-pass filters the residual, whose moving-phase part is high-frequency;
# ``min_duration`` debounces. Detections more than 0.3 s after a contact's
# onset do not count.
detector = CollisionDetector(FrozenEstimator(model), n_joints=6, sample_time=1 / 125,
                             rules=AlarmRule())
search = CollisionThresholdCV(
    detector,
    {"rules__contamination": [1e-3, 1e-2], "rules__filter_cutoff": [None, 2.0],
     "rules__min_duration": [1, 5]},
    cv=4,
    max_delay=0.3,
)
search.fit(stack_currents(X, y), labels, groups=groups)

results = search.cv_results_
print(f"{'candidate':56s} recall  false alarms/h  delay [s]")
for params, recall, alarms, delay in zip(results["params"], results["mean_test_recall"],
                                         results["mean_test_false_alarms_per_hour"],
                                         results["mean_test_delay"]):
    text = ", ".join(f"{k.removeprefix('rules__')}={v}" for k, v in params.items())
    print(f"{text:56s} {recall:6.3f}  {alarms:14.0f}  {delay:9.3f}")
print("chosen:", search.best_params_)

# %%
# With four runs of 21 s each, one false alarm in a held-out run is about
# 170 per hour: these rates are coarse, and on a real robot hours of
# collision-free data are needed to tune for rare false alarms (see the
# ``threshold="false_alarm_rate"`` rule of
# :class:`~sklearn_gpcd.detection.CollisionDetector`).
#
# The refitted detector on one run
# --------------------------------
# ``search.best_estimator_`` has been refitted on the collision-free rows of
# all runs. Its monitoring signal on the first run, pushes shaded:
best = search.best_estimator_
run = runs[0]
Z = stack_currents(*make_inputs(run))
out = best.monitoring_signal(Z)
axes = plot_monitoring(run.time - run.time[0], run.current, out.predicted, run.qd, out.signal,
                       best.thresholds_, labels=run.labels, joint=0)
axes[0].figure.suptitle(f"{run.name}: joint 1, chosen detector")
axes[0].figure.tight_layout()
plt.show()
