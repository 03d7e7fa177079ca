"""
The diagnosis effect library, one concealed effect at a time
============================================================

:class:`~sklearn_gpcd.diagnosis.DynamicsDiagnosis` tests thirteen candidate
effects against the residual of a nominal robot model. This example checks
each of them in turn: the simulated UR10 is given one effect the nominal model
does not know (a payload, a friction change, a torque-constant error, a
delayed current log, ...), and the diagnosis must

* name that effect and nothing else,
* put it on the joints where it was injected,
* estimate its parameters within 20 % of the truth, and
* lower the held-out nMSE of the affected joints by at least 20 %.

A control run (nominal physics only) must yield no effect at all, and one
case conceals two effects at once (a payload and a Stribeck friction peak).
The recordings are short: about 26 s of robot time to train on and 17 s to
test on, from different random targets.
"""

# %%
# The nominal model
# -----------------
# The diagnosis sees what the simulator itself assumes: the UR10's rigid-body
# model with its torque constants and reflected rotor inertias, and the
# nominal friction.
import time

import matplotlib.pyplot as plt
import numpy as np

from sklearn_gpcd.datasets import (
    EFFECT_REGISTRY,
    default_friction,
    simulate_d1,
    registered_effect,
)
from sklearn_gpcd.datasets.plant import drive_parameters
from sklearn_gpcd.diagnosis import DynamicsDiagnosis
from sklearn_gpcd.robots import load_robot

start = time.perf_counter()
robot = load_robot("ur10")
torque_constants, rotor_inertias = drive_parameters(robot)
nominal_robot = load_robot("ur10", torque_constants=torque_constants,
                           rotor_inertias=rotor_inertias)
nominal_friction = default_friction(robot)
N_TRAIN, N_TEST = 8, 5  # random targets: ~26 s and ~17 s of robot time


def one_hot(joint, value, n=6):
    """A per-joint vector with ``value`` on ``joint`` and 0 elsewhere."""
    out = [0.0] * n
    out[joint] = value
    return out


# %%
# The cases
# ---------
# The effect registry (:data:`~sklearn_gpcd.datasets.EFFECT_REGISTRY`) pairs
# every library effect with the simulator effect that injects it, an example
# injection and the conversion of the injected parameters into the estimate
# the diagnosis should report, in its units (a +50 % viscous coefficient into
# ``delta_viscous`` in Nm s/rad, a spring's rest position into the joint
# position when it starts, ...). Per-joint effects (friction, rotor inertia,
# torque constant, offset, spring, drift) must be found on exactly the
# injected joints; shared effects (payload, link mass, gravity tilt, time
# delay) must cover at least the joints they visibly load on this trajectory.
LOADED_JOINTS = {"payload": [1, 2, 3, 4], "link_mass": [0, 1, 2], "gravity_tilt": [1, 2],
                 "time_delay": [0, 1, 2]}


def simulate(effects, seed=1):
    """A training and a held-out recording with the concealed effects."""
    plant = [e for e in effects if hasattr(e, "apply")]

    def run(n_targets, random_state):
        recording = simulate_d1("ur10", n_targets=n_targets, effects=plant,
                            random_state=random_state)
        for effect in effects:  # a logging delay acts on the finished recording
            if hasattr(effect, "apply_to_recording"):
                recording = effect.apply_to_recording(recording)
        return recording

    return run(N_TRAIN, seed), run(N_TEST, seed + 100)


def expectation(entry, effects, train, loaded=None):
    """``{name: (joints, true parameters)}`` from the registry's conversion.

    Parameters whose truth is 0 are left out of the table (it reports
    relative errors).
    """
    expected = entry.expected(effects, nominal_robot, nominal_friction, train)
    joints = sorted(expected) if entry.identifier.per_joint else (
        loaded or LOADED_JOINTS[entry.name])
    truths = next(iter(expected.values()))
    return {entry.name: (joints, {k: v for k, v in truths.items() if v != 0})}


# Each case: (simulator effects, function of the training run -> expected).
CASES = {"control (nominal physics)": ([], lambda train: {})}
for entry in EFFECT_REGISTRY:
    injected = entry.inject()
    CASES[entry.name] = (injected, lambda train, entry=entry, injected=injected:
                         expectation(entry, injected, train))
payload, peak = registered_effect("payload"), registered_effect("stribeck_friction")
payload_2kg = payload.inject(mass=2.0, com=(0.0, 0.0, 0.05))
peak_joint_2 = peak.inject(static=one_hot(1, 6.0))
CASES["payload + stribeck"] = (
    payload_2kg + peak_joint_2,
    lambda train: {**expectation(payload, payload_2kg, train, loaded=[1, 2, 3]),
                   **expectation(peak, peak_joint_2, train)})


# %%
# Scoring one case
# ----------------
# ``score`` compares the fitted effects with the expectation and returns one
# row per expected effect (or one row for the control), with its verdict.
def found_joints(fits):
    """Joints of the fitted instances of one effect."""
    if fits[0].effect.per_joint:
        return sorted(f.target for f in fits)
    return sorted(set(fits[0].joints))


def score(case, diagnosis, test, expected):
    """Rows of the result table for one case."""
    found = {}
    for fitted in diagnosis.effects_:
        found.setdefault(fitted.name, []).append(fitted)
    extra = sorted(set(found) - set(expected))
    scores = diagnosis.evaluate(test)
    before = np.asarray(scores["nmse_before"])
    after = np.asarray(scores["nmse_after"])
    touched = sorted({j for joints, _ in expected.values() for j in joints})
    improved = not touched or after[touched].sum() < 0.8 * before[touched].sum()
    nmse_joints = touched if touched else list(range(len(before)))
    nmse_text = f"{before[nmse_joints].sum():.4f} -> {after[nmse_joints].sum():.4f}"
    if not expected:
        ok = not found
        return [dict(case=case, effect="(none)", injected="-",
                     found=", ".join(f"{f.name}{[j + 1 for j in f.joints]}"
                                     for f in diagnosis.effects_)
                     or "-", params=[], nmse=nmse_text, nmse_pair=(before, after, nmse_joints),
                     verdict="OK: nothing found" if ok else "FAIL: spurious effect")]
    rows = []
    for name, (joints, truths) in expected.items():
        problems = []
        params = []
        if name not in found:
            got = "-"
            problems.append("not found")
        else:
            fits = found[name]
            got = found_joints(fits)
            if fits[0].effect.per_joint:
                if got != sorted(joints):
                    problems.append("wrong joints")
            elif not set(joints) <= set(got):
                problems.append("misses joints")
            for key, truth in truths.items():
                value = fits[0].parameters[key][0]
                error = 100 * abs(value - truth) / abs(truth)
                params.append((key, truth, value, error))
                if error > 20:
                    problems.append(f"{key} off")
        if extra:
            problems.append("also found " + ", ".join(extra))
        if not improved:
            problems.append("nMSE not improved")
        rows.append(dict(case=case, effect=name, injected=joints, found=got, params=params,
                         nmse=nmse_text, nmse_pair=(before, after, nmse_joints),
                         verdict="OK" if not problems else "FAIL: " + "; ".join(problems)))
    return rows


# %%
# Run every case
# --------------
def _from_one(joints):
    """Joint lists counted from 1 for the table (the arrays count from 0)."""
    return str([j + 1 for j in joints]) if isinstance(joints, list) else str(joints)


rows = []
for case, (effects, expected) in CASES.items():
    train, test = simulate(effects)
    diagnosis = DynamicsDiagnosis(nominal_robot, friction=nominal_friction).fit(train)
    rows.extend(score(case, diagnosis, test, expected(train)))

header = (f"{'case':<26} {'effect':<18} {'injected':<13} {'found':<19} "
          f"{'parameter: truth vs fit':<36} {'err %':>6}  {'nMSE before -> after':<20}  verdict")
print(header)
print("-" * len(header))
for row in rows:
    params = row["params"] or [None]
    for k, param in enumerate(params):
        if param is None:
            ptext, etext = "-", "-"
        else:
            key, truth, value, error = param
            ptext, etext = f"{key}: {truth:.4g} vs {value:.4g}", f"{error:.1f}"
        cells = ([row["case"], row["effect"], _from_one(row["injected"]),
                  _from_one(row["found"]), row["nmse"], row["verdict"]] if k == 0 else [""] * 6)
        print(f"{cells[0]:<26} {cells[1]:<18} {cells[2]:<13} {cells[3]:<19} "
              f"{ptext:<36} {etext:>6}  {cells[4]:<20}  {cells[5]}")
n_ok = sum(row["verdict"].startswith("OK") for row in rows)
print(f"\n{n_ok} of {len(rows)} rows pass; nMSE summed over the injected joints "
      f"(all joints for the control), held-out run; "
      f"{time.perf_counter() - start:.1f} s in all")

# %%
# The figure
# ----------
# Left: the parameter error of every estimated parameter, with the 20 % line.
# Right: the held-out nMSE (summed over the injected joints) before and after
# the diagnosis, on a log scale.
labels, errors, colors = [], [], []
for row in rows:
    for key, _, _, error in row["params"]:
        labels.append(f"{row['effect']}: {key}" if row["case"] == row["effect"]
                      else f"{row['case']} | {row['effect']}: {key}")
        errors.append(error)
        colors.append("C2" if error <= 20 else "C3")

cases = list(dict.fromkeys(row["case"] for row in rows))
pairs = {row["case"]: row["nmse_pair"] for row in rows}
nmse_before = [pairs[c][0][pairs[c][2]].sum() for c in cases]
nmse_after = [pairs[c][1][pairs[c][2]].sum() for c in cases]

fig, (ax_err, ax_nmse) = plt.subplots(1, 2, figsize=(12, 6.5),
                                      gridspec_kw={"width_ratios": [1.2, 1]})
y = np.arange(len(labels))
ax_err.barh(y, errors, color=colors)
ax_err.axvline(20, color="k", ls="--", lw=1, label="20 %")
ax_err.set_yticks(y, labels, fontsize=7)
ax_err.invert_yaxis()
ax_err.set_xlabel("parameter error [%]")
ax_err.set_title("Estimated parameters vs truth")
ax_err.legend(loc="lower right")

y = np.arange(len(cases))
ax_nmse.barh(y - 0.2, nmse_before, height=0.4, color="0.6", label="nominal model")
ax_nmse.barh(y + 0.2, nmse_after, height=0.4, color="C0", label="after diagnosis")
ax_nmse.set_yticks(y, cases, fontsize=8)
ax_nmse.invert_yaxis()
ax_nmse.set_xscale("log")
ax_nmse.set_xlabel("held-out nMSE, summed over injected joints")
ax_nmse.set_title("Held-out fit before and after")
ax_nmse.legend(loc="upper right")
fig.tight_layout()
plt.show()
