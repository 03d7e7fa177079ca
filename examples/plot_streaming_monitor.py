"""
======================================
Streaming monitor: one sample per tick
======================================

On the robot, samples arrive one at a time (125 Hz on the paper's UR10) and
the decision is needed before the next one.
:class:`~sklearn_gpcd.detection.StreamingMonitor` wraps a fitted
:class:`~sklearn_gpcd.detection.CollisionDetector` and makes, sample by
sample, exactly the decisions of the detector's batch ``predict``: same
residual, same causal filter, same debounce, same thresholds. Its state is
preallocated, a tick allocates no array, and the GP prediction is compiled
into a single-sample path. Missing or non-finite samples are reported as
``SENSOR_FAULT`` and skipped, without disturbing the filter.
"""

# %%
# Model and detector
# ------------------
# The detector fits the paper's SP_P on one collision-free run and sets each
# joint's threshold so that 0.1 % of that run's (low-pass filtered) residual
# samples would be flagged; a joint must stay above it for 5 samples (40 ms).
# To calibrate on data the model has not seen, wrap an already fitted model
# in :class:`sklearn.frozen.FrozenEstimator` (see
# :ref:`sphx_glr_auto_examples_plot_threshold_cv.py`).
import time

import matplotlib.pyplot as plt
import numpy as np

from sklearn_gpcd.datasets import Contact, simulate_joint1_cyclic, reference_joint1_cyclic, simulate
from sklearn_gpcd.detection import (
    AlarmRule,
    CollisionDetector,
    MonitorStatus,
    StreamingMonitor,
    stack_currents,
)
from sklearn_gpcd.dynamics import RigidBodyFeatures
from sklearn_gpcd.features import make_inputs
from sklearn_gpcd.gp import make_sp_p

# (base_parameters=False: see the quick start)
features = [RigidBodyFeatures("ur10", joint=j, base_parameters=False) for j in range(6)]
model = make_sp_p(features, n_joints=6, n_support=150, random_state=0)
training = simulate_joint1_cyclic("ur10", rest_duration=2.0, random_state=0)
rule = AlarmRule(contamination=1e-3, filter_cutoff=2.0, min_duration=5)
detector = CollisionDetector(model, n_joints=6, sample_time=1 / 125, rules=rule)
detector.fit(stack_currents(*make_inputs(training)))
print("thresholds [A]:", np.round(detector.thresholds_, 3))

# %%
# A run with two pushes, streamed
# -------------------------------
# A push on link 1 during the second rest and another while joint 1 moves.
# The inputs are built in batch here for brevity; on the robot each row would
# come from the controller's log as it is written. We also drop two samples
# (NaN) to show the fault handling.
reference = reference_joint1_cyclic("ur10", rest_duration=2.0)
rest = [p for p in reference.phases if p["kind"] == "rest"][1]
contacts = [
    Contact(link=1, start=rest["start"] + 0.5, duration=1.0, force=[0.0, 300.0, 0.0],
            point=[0.2, 0.0, 0.0], frame="local"),
    Contact(link=1, start=12.0, duration=1.0, force=[0.0, -300.0, 0.0],
            point=[0.2, 0.0, 0.0], frame="local"),
]
run = simulate(reference, "ur10", contacts=contacts, name="pushed", random_state=2)
X, current = make_inputs(run)
X[1000:1002] = np.nan  # a glitch in the log

monitor = StreamingMonitor(detector)
status = []
signal = np.empty(len(X))
tic = time.perf_counter()
for x, i in zip(X, current):
    status.append(monitor.update(x, current=i).value)  # "ok", "collision", "sensor_fault"
    signal[len(status) - 1] = monitor.signal[0]  # arrays are overwritten each tick
elapsed = time.perf_counter() - tic
status = np.array(status)
print(f"{len(X)} ticks in {elapsed:.2f} s ({1e6 * elapsed / len(X):.0f} us per tick, "
      f"the robot's period is 8000 us); predictor: {monitor.predictor_kind}")
print({s.value: int(np.sum(status == s.value)) for s in MonitorStatus})

# %%
# Same decisions as the batch detector
# ------------------------------------
# The batch ``predict`` on the valid rows gives the same alarms, since a
# faulty sample is skipped as if it had never arrived.
valid = status != "sensor_fault"
batch = detector.predict(stack_currents(X[valid], current[valid])) == -1
print("identical to batch predict:", bool(np.array_equal(batch, status[valid] == "collision")))

# %%
# Alarms against the pushes
# -------------------------
# Event-level scores (:mod:`sklearn_gpcd.metrics`): a push counts as detected
# when an alarm starts within 0.3 s of its onset; every other alarm onset is
# a false alarm. Thresholds calibrated on a single 21 s run are tight, so
# expect a few false alarms here; tune them on more data as in
# :ref:`sphx_glr_auto_examples_plot_threshold_cv.py`.
from sklearn_gpcd.metrics import event_recall, false_alarms_per_hour

t = run.time - run.time[0]
alarm = status == "collision"
print(f"pushes detected: {event_recall(run.labels, alarm, max_delay=0.3, time=t):.0%}, "
      f"false alarms: {false_alarms_per_hour(run.labels, alarm, max_delay=0.3, time=t):.0f} "
      "per hour of collision-free motion")
fig, axes = plt.subplots(2, 1, sharex=True, figsize=(7, 4.5))
axes[0].plot(t, run.q[:, 0], color="k")
axes[0].set_ylabel("$q_1$ [rad]")
axes[1].plot(t, signal, lw=0.8, label="filtered $s_1$")
for sign in (-1, 1):
    axes[1].axhline(sign * detector.thresholds_[0], color="C3", ls="--", lw=0.8)
axes[1].plot(t[alarm], np.zeros(alarm.sum()), "|", color="C3", ms=12, label="alarm (any joint)")
axes[1].set_ylabel("monitoring signal [A]")
axes[1].set_xlabel("time [s] (pushes shaded)")
for ax in axes:
    ax.fill_between(t, 0, 1, where=run.labels > 0, color="0.85",
                    transform=ax.get_xaxis_transform(), zorder=0)
axes[1].legend(loc="lower left")
fig.tight_layout()
plt.show()
