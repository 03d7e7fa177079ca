"""Study: does a direct estimator identify a torque-constant change? (development seeds only)

``python studies/blind_torque_constant_estimator.py DIR [DIR...]`` (the
blind protocol's development folders, ``benchmarks/blind_protocol.py``).
For every development case with a torque-constant change, and every joint
where it was injected, joint ``j``'s residual (measured minus reference
current) on its moving rows is regressed on the joint's own reference
current (the torque-constant column, coefficient ``c = 1/s - 1``) together
with the friction columns a torque-constant change competes with
(Coulomb, viscous, a low-speed peak/softening at 0.002-0.08 rad/s), over
all samples. The standard error of ``c`` is the Newey-West (HAC) one
(Bartlett weights, 0.5 s of lags: the residual is far from white), next
to the white-noise one ``noise / (sqrt(N) rms(x_perp))``. Printed: the
estimate against the truth, both standard errors, and the size of the
change that would be 3 HAC standard errors.
"""
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import blind_protocol as bp  # noqa: E402
from sklearn_gpcd.diagnosis import NominalModel, Signals  # noqa: E402

VELOCITIES = (0.002, 0.004, 0.008, 0.015, 0.03, 0.08)


def hac_se(X, r, lags):
    """OLS coefficients and their Newey-West standard errors."""
    XtX_inv = np.linalg.inv(X.T @ X)
    beta = XtX_inv @ X.T @ r
    u = (r - X @ beta)[:, None] * X
    S = u.T @ u
    for lag in range(1, lags + 1):
        g = u[lag:].T @ u[:-lag]
        S += (1 - lag / (lags + 1)) * (g + g.T)
    cov = XtX_inv @ S @ XtX_inv
    return beta, np.sqrt(np.diag(cov)), r - X @ beta


def load_case(out, case):
    """The nominal model's signals of a development case's training run."""
    folder = Path(out) / "cases" / case
    nominal = json.loads((folder / "nominal.json").read_text())
    with tempfile.TemporaryDirectory() as tmp:
        robot = bp._nominal_robot(nominal, tmp)
    model = NominalModel(robot, None, {"coulomb": np.array(nominal["coulomb"]),
                                       "viscous": np.array(nominal["viscous"])})
    return Signals.from_recordings(model, [bp._load_recording(folder / "train.npz", "train")])


def main(folders):
    rows = []
    for out in map(Path, folders):
        truth = json.loads((out / "truth" / "truth.json").read_text())
        for case, t in sorted(truth.items()):
            assert t["seed"] in bp.SEEDS["dev"] + bp.SEEDS["dev2"], "development cases only"
            if "torque_constant" not in t["effects"]:
                continue
            s = load_case(out, case)
            dt = float(np.median(np.diff(s.time)))
            tc = t["effects"]["torque_constant"]
            others = sorted(set(t["effects"]) - {"torque_constant"})
            for j, change in zip(tc["joints"], tc["size"]):
                qd = s.qd[:, j]
                moving = np.abs(qd) > 1e-3
                x = s.reference[moving, j]
                v = qd[moving]
                friction = [np.sign(v), v] + [np.sign(v) * np.exp(-(v / vs) ** 2)
                                              for vs in VELOCITIES]
                X = np.column_stack([x] + friction)
                r = s.current[moving, j] - x
                beta, se, e = hac_se(X, r, int(round(0.5 / dt)))
                F = np.column_stack(friction)
                x_perp = x - F @ np.linalg.lstsq(F, x, rcond=None)[0]
                noise = float(np.std(e))
                white = noise / np.sqrt(x.size) / float(np.sqrt(np.mean(x_perp ** 2)))
                scale = 1.0 / (1.0 + beta[0])
                est = scale - 1.0
                rows.append((case, t["engine"], j, change, est, se[0], white, others))
                print(f"{case} {t['engine']:8s} joint {j + 1}: true {100 * change:+.1f} %, "
                      f"estimate {100 * est:+.1f} % (error {100 * (est / change - 1):+.0f} %), "
                      f"HAC SE {100 * se[0]:.1f} %, white-noise SE {100 * white:.2f} %, "
                      f"3 SE = {300 * se[0]:.0f} %; N = {x.size}, rms x_perp "
                      f"{np.sqrt(np.mean(x_perp ** 2)):.4f} A, residual sd {noise:.4f} A"
                      + (f"; also injected: {', '.join(others)}" if others else ""),
                      flush=True)
    wrist = [r for r in rows if r[2] >= 3]
    ok = [r for r in wrist if abs(r[4] / r[3] - 1) <= 0.2]
    print(f"\nwrist joints 4-6: {len(ok)}/{len(wrist)} within 20 %; median HAC SE "
          f"{100 * np.median([r[5] for r in wrist]):.1f} %")
    return rows


if __name__ == "__main__":
    main(sys.argv[1:])
