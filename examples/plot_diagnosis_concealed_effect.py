"""
Diagnosing concealed physics: a payload and a Stribeck friction peak
=====================================================================

A simulation of a UR10 and "real" recordings of it disagree. Here the real
robot is the built-in simulator with two effects the nominal model does not
know: a 2.5 kg payload at the flange and a stronger low-speed friction peak
(Stribeck effect) on joint 2 (the shoulder). The diagnosis only sees the
nominal model and the recordings. It

1. locates the residual by joint, regime and time,
2. names the missing effects with their parameters and evidence,
3. returns a refined model, usable as the GP's parametric mean, and
4. shows the held-out nMSE before and after.
"""

# %%
# The nominal model and the concealed effects
# -------------------------------------------
# The nominal model is what the simulator itself assumes: the UR10's rigid
# body model, torque constants, reflected rotor inertias and nominal
# friction. The "real" robot carries a payload and a higher Stribeck peak.
import numpy as np

from sklearn_gpcd.datasets import FrictionDelta, Payload, default_friction, simulate_d1
from sklearn_gpcd.datasets.plant import drive_parameters
from sklearn_gpcd.diagnosis import DynamicsDiagnosis
from sklearn_gpcd.robots import load_robot

robot = load_robot("ur10")
torque_constants, rotor_inertias = drive_parameters(robot)
nominal_robot = load_robot("ur10", torque_constants=torque_constants,
                           rotor_inertias=rotor_inertias)
nominal_friction = default_friction(robot)

concealed = [Payload(2.5, com=(0.0, 0.02, 0.05)),
             FrictionDelta(static=[0.0, 6.0, 0.0, 0.0, 0.0, 0.0])]
train = simulate_d1("ur10", n_targets=10, effects=concealed, random_state=0)
test = simulate_d1("ur10", n_targets=6, effects=concealed, random_state=1)
print(f"training: {train.duration:.0f} s, held-out: {test.duration:.0f} s of robot time")

# %%
# Diagnose
# --------
# Thirteen effects (friction terms including a Stribeck peak and low-speed
# softening, rotor inertia, payload, link mass, gravity tilt, torque constant,
# current offset, time delay, joint spring, friction drift) compete in a
# forward selection scored on held-out time blocks; an effect is named only
# when its held-out gain is statistically and practically significant and its
# parameters are physically plausible. The report counts joints from 1.
diagnosis = DynamicsDiagnosis(nominal_robot, friction=nominal_friction).fit(train)
report = diagnosis.report(test)
print(report)

# %%
# The named effects and their parameters
# --------------------------------------
for effect in report.effects:
    print(effect["name"], "on joints", [j + 1 for j in effect["joints"]])  # JSON: 0-based
    for name, value in effect["parameters"].items():
        print(f"    {name} = {value} +- {effect['uncertainty'][name]} {effect['units'][name]}")

# %%
# The figure: where the nominal model was wrong and the fit before/after
# -----------------------------------------------------------------------
# Left: the nominal residual by joint and regime; middle: over time; right:
# the held-out nMSE per joint before and after.
fig = report.plot()

# %%
# The refined model as the GP's parametric mean
# ---------------------------------------------
# ``joint_features(l)`` maps states ``[q, qd, qdd]`` to the nominal current
# and the effect columns of joint ``l``; ``parametric_mean(l)`` wraps them in
# a :class:`~sklearn_gpcd.gp.ParametricMean`, whose least-squares fit on the
# GP's training data (here the moving samples of the training run)
# re-estimates the coefficients.
from sklearn_gpcd.metrics import nmse

moving = np.abs(train.qd[:, 1]) > 1e-3
X_train = np.hstack([train.q, train.qd, train.qdd])[moving]
mean = diagnosis.model_.parametric_mean(1).fit(X_train, train.current[moving, 1])
X_test = np.hstack([test.q, test.qd, test.qdd])
held = np.abs(test.qd[:, 1]) > 1e-3
print("held-out nMSE of joint 2 with the refined mean:",
      round(nmse(test.current[held, 1], mean.predict(X_test[held])), 5))
