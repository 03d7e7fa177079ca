"""
=====================================
Real UR10e logs: train, test, monitor
=====================================

The same workflow on a real robot: the UR10e recordings of Mamedov et al.
(*Practical Aspects of Model-Based Collision Detection*, Frontiers in
Robotics and AI, 2020; github.com/shamilmamedov/dynamic_calibration). They
log time, joint positions, velocities, motor currents, target currents and
target torques at about 100 Hz (jittered) in headerless CSV files, which
:func:`~sklearn_gpcd.io.load_recording` recognises (the ``"ur10e_mamedov"``
column preset).

These data have **no redistribution licence**: they are not part of the
package and this example is **not run** when the documentation is built. It
looks for them in ``$GPCD_REAL_DATA/ur10e_mamedov`` or
``../shared/data/real/ur10e_mamedov`` next to the repository, and exits with a
message when they are absent. Run it with::

    python examples/ur10e_real_data.py

It takes a minute or two on a laptop. The full benchmark, with all files and
the numbers of the documentation's results page, is
``benchmarks/real_ur10e.py``.
"""

# %%
# Find the data
# -------------
import sys
import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np


sys.path.insert(0, str(Path(__file__).resolve().parent if "__file__" in globals()
                       else Path.cwd()))
from _real_data import find_data  # noqa: E402  (examples/_real_data.py)

DATA = find_data("ur10e_mamedov")
if DATA is None:
    print("The UR10e recordings were not found (set GPCD_REAL_DATA to the folder that "
          "holds ur10e_mamedov/). Skipping this example.")
    sys.exit(0)

from sklearn_gpcd.detection import AlarmRule, CollisionDetector, stack_currents
from sklearn_gpcd.dynamics import RigidBodyFeatures  # noqa: E402
from sklearn_gpcd.features import make_inputs  # noqa: E402
from sklearn_gpcd.gp import make_sp_p, make_sp_s  # noqa: E402
from sklearn_gpcd.io import load_recording  # noqa: E402
from sklearn_gpcd.metrics import nmse  # noqa: E402
from sklearn_gpcd.plotting import plot_monitoring  # noqa: E402

# %%
# Load the recordings
# -------------------
# Training: four unloaded Fourier-excitation runs (about two minutes of
# motion, starting and ending at rest). Test: the robot standing
# still in ten poses (quasi-static, where SP_S and SP_P differ) and a
# point-to-point run through them. The loader drops malformed rows and
# out-of-order time stamps, with one ``RecordingWarning`` per file; the logs
# have the target current ``i_c`` but not ``target_q`` / ``target_qd``, so
# ``e_q`` and ``de_q`` of Eq. 13 are zero (``MissingSignalWarning``).
warnings.simplefilter("ignore")  # the two notes above, once per file
TRAIN = ["ur-20_01_31-unload.csv", "ur-20_02_05-20sec_12harm.csv",
         "ur-20_02_06-20sec_10harm.csv", "ur-20_02_10-30sec_12harm.csv"]
train = [load_recording(DATA / "identification_data" / name) for name in TRAIN]
still = [load_recording(DATA / "validation_data" / f"ur-20_01_17-p{k}.csv") for k in range(1, 11)]
ptp = load_recording(DATA / "validation_data" / "ur-20_01_17-ptp_10_points.csv")
print("training:", [rec.name for rec in train])

X, y = make_inputs(train)
print(f"{len(y)} training samples")

# %%
# Fit SP_S and SP_P on the UR10e model
# ------------------------------------
# The built-in ``"ur10e"`` model (published kinematic and inertial
# parameters) provides the rigid-body features; the GPs correct what it
# misses. 500 support samples keep the fit short.
# (base_parameters=False: see the quick start)
features = [RigidBodyFeatures("ur10e", joint=j, base_parameters=False) for j in range(6)]
models = {
    "SP_S": make_sp_s(features, n_joints=6, n_support=500, random_state=0),
    "SP_P": make_sp_p(features, n_joints=6, sigma_v=1e-2, n_support=500, random_state=0),
}
for model in models.values():
    model.fit(X, y)

# %%
# nMSE (Eq. 18) on the still poses and the point-to-point run
# -----------------------------------------------------------
tests = {"still poses p1..p10": make_inputs(still), "point-to-point": make_inputs(ptp)}
for test_name, (X_test, y_test) in tests.items():
    for name, model in models.items():
        scores = nmse(y_test, model.predict(X_test))
        print(f"{test_name:20s} {name}: nMSE per joint", np.round(scores, 3))

# %%
# Monitoring a human pushing the robot
# ------------------------------------
# The ``collision_push_pose`` files hold a pose while a person pushes the
# arm three times. The files have **no labels**; the shaded intervals are the
# data README's estimates by inspection, not ground truth. Thresholds come
# from the still poses (collision-free, unseen in training).
rule = AlarmRule(contamination=1e-3, filter_cutoff=2.0, min_duration=5)
detector = CollisionDetector(models["SP_P"], n_joints=6, sample_time=0.01, rules=rule)
detector.fit(stack_currents(*make_inputs(still + train)))
push = load_recording(DATA / "collision_push_pose" / "ur-20_01_22-push_pose_1.csv")
t = push.time - push.time[0]
labels = np.zeros(push.n_samples, dtype=int)
for k, (start, stop) in enumerate([(4.7, 5.7), (8.7, 9.3), (12.0, 13.1)], start=1):
    labels[(t >= start) & (t <= stop)] = k
out = detector.monitoring_signal(stack_currents(*make_inputs(push)))
joint = int(np.argmax(np.abs(out.residual).max(axis=0)))
axes = plot_monitoring(t, push.current, out.predicted, push.qd, out.signal,
                       detector.thresholds_, labels=labels, joint=joint)
axes[0].figure.suptitle(f"UR10e push_pose_1, joint {joint + 1} (pushes: README estimates)")
axes[0].figure.tight_layout()
plt.show()
