"""
===========================================================
Quick start: the monitoring signal of SP_S and SP_P at rest
===========================================================

The smallest complete use of the package, on the built-in UR10 simulator:

1. simulate the paper's cyclic actuation of joint 1 (Sec. III-C): rest, move
   joint 1, rest at another angle, ... -- once for training, once for testing;
2. build the augmented GP inputs ``x^a = [q, qd, qdd, e_q, de_q, i_c]``
   (Eq. 13) and the motor currents;
3. fit the standard semi-parametric estimator SP_S (Eq. 11) and the paper's
   proposed estimator SP_P (Eq. 17), one GP per joint around the rigid-body
   model with friction;
4. compare their monitoring signals ``s = i - i_hat`` on the test run.

During the rest phases the current of joint 1 is whatever static friction
(stiction) leaves it at, which depends on how the joint came to rest and not
only on ``(q, qd, qdd)``. SP_S cannot predict it; SP_P's quasi-static kernel,
switched on only when ``|qd_1| < sigma_v``, reads it from the controller's
errors and target current and does. This is the paper's Fig. 2.

The simulations are short (2 s rests) and the GPs are conditioned on 150
samples, so the whole script runs in a few seconds.
"""

# %%
# Simulate the training and test runs
# -----------------------------------
# ``simulate_joint1_cyclic`` returns a :class:`~sklearn_gpcd.io.Recording` sampled
# at 125 Hz, with the reference trajectory's phases in its metadata. The two
# runs differ in their sensor noise (``random_state``) and hence in where
# joint 1 sticks.
import matplotlib.pyplot as plt
import numpy as np

from sklearn_gpcd.datasets import simulate_joint1_cyclic
from sklearn_gpcd.dynamics import RigidBodyFeatures
from sklearn_gpcd.features import make_inputs
from sklearn_gpcd.gp import make_sp_p, make_sp_s

train = simulate_joint1_cyclic("ur10", rest_duration=2.0, random_state=0)
test = simulate_joint1_cyclic("ur10", rest_duration=2.0, random_state=1)
print(f"training run: {train.n_samples} samples, {train.duration:.1f} s, "
      f"{train.n_joints} joints")

X_train, y_train = make_inputs(train)  # x^a (Eq. 13) and the motor currents
X_test, y_test = make_inputs(test)
print("X:", X_train.shape, "y:", y_train.shape)

# %%
# Fit SP_S and SP_P
# -----------------
# Both share the parametric part: one
# :class:`~sklearn_gpcd.dynamics.RigidBodyFeatures` per joint, the
# rigid-body features of the built-in UR10 with Coulomb and viscous friction
# (Eq. 8-10). SP_P adds the gated quasi-static kernel (Eq. 14-16) and zeroes the
# friction columns at rest (the paper's :math:`\bar\phi`).
#
# ``base_parameters=False`` skips the reduction of the regressor to its
# identifiable columns, a QR decomposition that dominates the fit at this tiny
# size; the least-squares fit of the mean is minimum-norm, so the predictions
# are the same.
features = [RigidBodyFeatures("ur10", joint=j, base_parameters=False) for j in range(6)]
models = {
    "SP_S": make_sp_s(features, n_joints=6, n_support=150, random_state=0),
    "SP_P": make_sp_p(features, n_joints=6, sigma_v=1e-2, n_support=150,
                      random_state=0),
}
signals = {}
for name, model in models.items():
    model.fit(X_train, y_train)
    signals[name] = y_test - model.predict(X_test)  # monitoring signal s

# %%
# Compare the monitoring signals of joint 1
# -----------------------------------------
# Away from collisions the monitoring signal should be noise. At rest, SP_S
# leaves the stiction current in it; SP_P removes it.
t = test.time - test.time[0]
at_rest = np.all(np.abs(test.qd) < 1e-2, axis=1)
for name, s in signals.items():
    print(f"{name}: mean |s_1| at rest {np.abs(s[at_rest, 0]).mean():.3f} A, "
          f"while moving {np.abs(s[~at_rest, 0]).mean():.3f} A")

fig, axes = plt.subplots(3, 1, sharex=True, figsize=(7, 5.5))
limit = 1.1 * max(np.abs(s[:, 0]).max() for s in signals.values())
axes[0].plot(t, test.q[:, 0], color="k")
axes[0].set_ylabel("$q_1$ [rad]")
for ax, (name, s) in zip(axes[1:], signals.items()):
    ax.plot(t, s[:, 0], lw=0.8, color="C0" if name == "SP_S" else "C2")
    ax.set_ylabel(f"$s_1$ {name} [A]")
    ax.set_ylim(-limit, limit)
for ax in axes:
    ax.fill_between(t, 0, 1, where=at_rest, color="0.9", transform=ax.get_xaxis_transform(),
                    zorder=0)
axes[-1].set_xlabel("time [s] (rest phases shaded)")
fig.suptitle("Cyclic actuation of joint 1: monitoring signal at rest")
fig.tight_layout()
plt.show()
