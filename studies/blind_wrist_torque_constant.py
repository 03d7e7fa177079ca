"""Study: can the recordings show a torque-constant change on a joint? (development seeds only)

``python studies/blind_wrist_torque_constant.py DIR case115:5 case107:2 ...``
(joints counted from 1). For each case and joint of the blind protocol's
development cases (``benchmarks/blind_protocol.py``), the joint's reference
current on moving rows is regressed on the friction columns (Coulomb,
viscous, a low-speed softening at 0.004 rad/s): the share they reproduce,
and how far a 10 % change of the torque constant moves what they cannot
reproduce, against the sample noise of the residual (its first differences
over sqrt 2).
"""
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import blind_protocol as bp  # noqa: E402
from blind_torque_constant_estimator import load_case  # noqa: E402

out = Path(sys.argv[1])
for spec in sys.argv[2:]:
    case, joint = spec.split(":")
    assert int(case[4:]) in bp.SEEDS["dev"] + bp.SEEDS["dev2"], "development cases only"
    j = int(joint) - 1
    s = load_case(out, case)
    qd = s.qd[:, j]
    moving = np.abs(qd) > 1e-3
    ref = s.reference[moving, j]
    friction = np.column_stack([np.sign(qd), qd,
                                np.sign(qd) * np.exp(-(qd / 0.004) ** 2)])[moving]
    rest = ref - friction @ np.linalg.lstsq(friction, ref, rcond=None)[0]
    residual = s.current[moving, j] - ref
    noise = np.std(np.diff(residual)) / np.sqrt(2)
    rms = float(np.sqrt(np.mean(rest ** 2)))
    print(f"{case} joint {j + 1}: friction columns reproduce "
          f"{100 * (1 - rest.var() / ref.var()):.1f} % of the reference current "
          f"(rms {np.sqrt(np.mean(ref ** 2)):.3f} A); a 10 % torque-constant change moves "
          f"the rest by {0.1 * rms:.4f} A rms against a sample noise of {noise:.4f} A")
