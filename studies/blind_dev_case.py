"""Study: one *development* case of the blind protocol, with the selection's history.

Only for development seeds (benchmarks/blind_protocol.py SEEDS["dev"], ["dev2"]); never
run on the scoring set. ``python studies/blind_dev_case.py DIR case102 [label...]``
"""
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import blind_protocol as bp  # noqa: E402
from sklearn_gpcd.diagnosis import DynamicsDiagnosis  # noqa: E402

out, case = Path(sys.argv[1]), sys.argv[2]
assert int(case[4:]) in bp.SEEDS["dev"] + bp.SEEDS["dev2"], "development cases only"
folder = out / "cases" / case
nominal = json.loads((folder / "nominal.json").read_text())
with tempfile.TemporaryDirectory() as tmp:
    robot = bp._nominal_robot(nominal, tmp)
train = bp._load_recording(folder / "train.npz", "train")
d = DynamicsDiagnosis(robot, friction={"coulomb": np.array(nominal["coulomb"]),
                                       "viscous": np.array(nominal["viscous"])}).fit(train)
print(json.dumps(json.loads((out / "truth" / "truth.json").read_text())[case]["effects"]))
for f in d.effects_:
    print("NAMED", f.name, f.target, {k: round(v[0], 4) for k, v in f.parameters.items()})
for r in d.rejected_effects_:
    print("REJ", r["name"], r["reason"][:120])
labels = sys.argv[3:]
for k, steps in enumerate(d.history_):
    best = max(steps, key=lambda s: s.gain)
    print(f"step {k}: best {best.candidate.label} {best.candidate.settings} gain {best.gain:.4g}"
          f" rel {best.relative_gain:.3g} t {best.t:.3g} share {best.share:.3g}")
    for s in steps:
        if any(lab in s.candidate.label for lab in labels):
            print(f"    {s.candidate.label} {s.candidate.settings} gain {s.gain:.4g} rel "
                  f"{s.relative_gain:.3g} t {s.t:.3g} folds {s.folds_improved} share "
                  f"{s.share:.3g} theta {np.round(s.theta, 4)}")
for f in d.effects_:
    e = f.evidence
    if e is not None:
        print("EVID", f.name, f.target, f"rel {e.relative_gain:.3g} t {e.t:.3g} folds "
              f"{e.folds_improved} gains {np.round(e.fold_gains, 5)} share {f.joint_share:.3g}")
