"""The diagnosis on a second physics engine: 12 effects, a control and two combinations.

The reference plant (``benchmarks/_mujoco_plant.py``) runs on MuJoCo with its
own joint servo, dry friction as a constraint (``frictionloss``), viscous
damping, rotor inertia (``armature``) and sensor noise. Each case injects
effects there; the diagnosis is given only the nominal model (the robot,
its torque constants and rotor inertias, and the plant's nominal friction
levels as Coulomb/viscous) and sees one training run (16 random flange
targets, about 50 s) and one held-out run (5 targets).

A case counts as *named* when every injected effect is named on the right
joints with its parameters within 20 % of the injected values (per joint
where a list is given). The plant's
own friction (dry friction softening at low speed, Coulomb and viscous level
corrections) may be named in every run: anything else named is an *extra*
and is listed. An "ambiguous" verdict between the injected effect and
another counts as named when the injected one is reported.

Run ``python benchmarks/second_engine.py [--cases a,b] [--seed S] [--json OUT]``
(needs ``pip install mujoco``).
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _mujoco_plant import DAMPING, FRICTIONLOSS, Injection, simulate  # noqa: E402

from sklearn_gpcd.datasets.plant import drive_parameters  # noqa: E402
from sklearn_gpcd.diagnosis import DynamicsDiagnosis  # noqa: E402
from sklearn_gpcd.robots import load_robot  # noqa: E402

#: Random flange targets of the training and held-out runs (about 3.2 s each).
N_TRAIN, N_TEST = 16, 5
#: Effects the plant has in every run (its friction law), allowed in every case.
PLANT_FRICTION = {"coulomb_friction", "viscous_friction", "friction_softening"}

#: name -> (injection, expected {effect: (joints 0-based, {parameter: value})}).
CASES = {
    "control": (Injection(), {}),
    "coulomb_friction": (Injection(coulomb={2: 3.0}),
                         {"coulomb_friction": ([2], {"delta_coulomb": 3.0})}),
    "viscous_friction": (Injection(viscous={4: 2.0}),
                         {"viscous_friction": ([4], {"delta_viscous": 2.0})}),
    "stribeck_friction": (Injection(stribeck={1: (6.0, 0.03), 2: (4.0, 0.03)}),
                          {"stribeck_friction": ([1, 2], {"delta_stribeck": [6.0, 4.0],
                                                          "stribeck_velocity": 0.03})}),
    "rotor_inertia": (Injection(rotor={1: 0.6, 2: 0.6}),
                      {"rotor_inertia": ([1, 2], {"delta_rotor_inertia": 0.6})}),
    "payload": (Injection(payload=(3.0, (0.0, 0.03, 0.06))),
                {"payload": ([1, 2, 3, 4], {"mass": 3.0, "com_y": 0.03, "com_z": 0.06})}),
    "link_mass": (Injection(link_mass=(2, 2.0)),
                  {"link_mass": ([0, 1, 2], {"delta_mass": 2.0})}),
    "gravity_tilt": (Injection(tilt=(0.02, -0.015)),
                     {"gravity_tilt": ([1, 2], {"roll": 0.02, "pitch": -0.015})}),
    "torque_constant": (Injection(torque_scale={3: 0.85}),
                        {"torque_constant": ([3], {"scale": 0.85})}),
    "current_offset": (Injection(offset={4: 0.15}),
                       {"current_offset": ([4], {"offset": 0.15})}),
    "time_delay": (Injection(delay=0.016), {"time_delay": ([0, 1, 2], {"delay": 0.016})}),
    "joint_spring": (Injection(spring={3: (20.0, -np.pi / 2)}),
                     {"joint_spring": ([3], {"stiffness": 20.0,
                                             "rest_position": -np.pi / 2})}),
    "friction_drift": (Injection(drift={0: 0.1}),
                       {"friction_drift": ([0], {"coulomb_rate": 0.1})}),
    "payload+stribeck": (Injection(payload=(2.0, (0.0, 0.0, 0.05)), stribeck={1: (6.0, 0.03)}),
                         {"payload": ([1, 2, 3], {"mass": 2.0, "com_z": 0.05}),
                          "stribeck_friction": ([1], {"delta_stribeck": 6.0})}),
    "tilt+offset": (Injection(tilt=(0.02, -0.015), offset={4: 0.15}),
                    {"gravity_tilt": ([1, 2], {"roll": 0.02, "pitch": -0.015}),
                     "current_offset": ([4], {"offset": 0.15})}),
}


def plant_setup():
    """The robot, nominal torque constants and rotor inertias, and the nominal model."""
    robot = load_robot("ur10")
    k, rotor = drive_parameters(robot)
    nominal = load_robot("ur10", torque_constants=k, rotor_inertias=rotor)
    return robot, k, rotor, nominal


def judge(diagnosis, expected):
    """Per injected effect: named within 20 %?  Plus the extra effects named."""
    found = {}
    for fitted in diagnosis.effects_:
        found.setdefault(fitted.name, []).append(fitted)
    verdicts = {}
    for name, (joints, params) in expected.items():
        fits = found.get(name, [])
        errors = {}
        if fits and fits[0].effect.per_joint:
            by_joint = {f.target: f for f in fits}
            ok = all(j in by_joint for j in joints)
            for n, j in enumerate(joints):
                for key, truth in params.items():
                    truth = truth[n] if isinstance(truth, list) else truth
                    if j in by_joint:
                        value = by_joint[j].parameters[key][0]
                        errors[f"{key}[joint {j + 1}]"] = float(value / truth - 1)
        elif fits:
            ok = set(joints) <= set(fits[0].joints)
            for key, truth in params.items():
                errors[key] = float(fits[0].parameters[key][0] / truth - 1)
        else:
            ok = False
        within = ok and bool(errors) and all(abs(e) <= 0.2 for e in errors.values())
        verdicts[name] = {"named": bool(fits), "right_joints": ok, "relative_errors": errors,
                          "within_20_percent": within}
    extras = sorted({f"{f.name}" + (f"[joint {f.target + 1}]" if f.effect.per_joint else "")
                     for f in diagnosis.effects_
                     if f.name not in expected and f.name not in PLANT_FRICTION})
    return verdicts, extras


def run_case(name, setup, seed=1):
    """Simulate, diagnose and judge one case."""
    robot, k, rotor, nominal = setup
    injection, expected = CASES[name]
    train = simulate(robot, k, rotor, injection, n_targets=N_TRAIN, random_state=seed,
                     name="train")
    test = simulate(robot, k, rotor, injection, n_targets=N_TEST, random_state=seed + 100,
                    name="test")
    diagnosis = DynamicsDiagnosis(nominal, friction={"coulomb": FRICTIONLOSS,
                                                     "viscous": DAMPING}).fit(train)
    verdicts, extras = judge(diagnosis, expected)
    scores = diagnosis.evaluate(test)
    return {
        "named_within_20_percent": all(v["within_20_percent"] for v in verdicts.values()),
        "effects": verdicts,
        "extra": extras,
        "all_named": sorted({f.name for f in diagnosis.effects_}),
        "rejected": [f"{r['name']}: {r['reason']}" for r in diagnosis.rejected_effects_],
        "ambiguous": [f"{a['effect']} ~ {a['alternative_effect']} on joints "
                      f"{[j + 1 for j in a['joints']]}" for a in diagnosis.ambiguities_],
        "nmse_before": scores["nmse_before"], "nmse_after": scores["nmse_after"],
        "diagnosis": diagnosis,
    }


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default=None, help="comma-separated case names")
    parser.add_argument("--json", default=None, help="write the results here")
    parser.add_argument("--seed", type=int, default=1,
                        help="seed of the references and noise (held-out run: seed + 100)")
    args = parser.parse_args(argv)
    try:
        import mujoco  # noqa: F401
    except ImportError:
        print("mujoco is not installed (pip install mujoco): skipped")
        return 0
    names = list(CASES) if args.cases is None else args.cases.split(",")
    setup = plant_setup()
    results, start = {}, time.perf_counter()
    for name in names:
        t0 = time.perf_counter()
        r = run_case(name, setup, seed=args.seed)
        r.pop("diagnosis")
        results[name] = r
        verdict = "named within 20 %" if r["named_within_20_percent"] else "NOT named within 20 %"
        if name == "control":
            verdict = "names nothing else" if not r["extra"] else "names extra effects"
        print(f"{name:18s} {verdict}; named: {', '.join(r['all_named']) or '-'}"
              f"{'; EXTRA: ' + ', '.join(r['extra']) if r['extra'] else ''} "
              f"({time.perf_counter() - t0:.1f} s)")
        for effect, v in r["effects"].items():
            errs = ", ".join(f"{k} {100 * e:+.0f} %" for k, e in v["relative_errors"].items())
            print(f"{'':20s}{effect}: {errs or 'not named'}")
        for a in r["ambiguous"]:
            print(f"{'':20s}ambiguous: {a}")
    injected = [n for n in names if n != "control"]
    named = sum(results[n]["named_within_20_percent"] for n in injected)
    clean = sum(not results[n]["extra"] for n in names)
    control_ok = "control" in results and not results["control"]["extra"]
    print(f"\nsecond engine: {named}/{len(injected)} injected cases named within 20 %"
          + (f"; control names nothing beyond the plant's friction: {control_ok}"
             if "control" in results else "")
          + f"; {clean}/{len(names)} cases with no extra effect"
          f" ({time.perf_counter() - start:.0f} s)")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=2, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
