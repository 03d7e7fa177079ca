"""The blind protocol's generator and scorer (``benchmarks/blind_protocol.py``).

The draw and the scoring rule run without any engine; simulating a case
needs MuJoCo and PyBullet (the ``second-engine`` extra) and is opt-in
(slow).
"""

import json
import sys
from pathlib import Path

import numpy as np
import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.fixture(scope="module")
def bp():
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import blind_protocol
    finally:
        sys.path.remove(str(BENCHMARKS))
    return blind_protocol


def test_seed_sets_are_disjoint_and_large_enough(bp):
    dev = set(bp.SEEDS["dev"]) | set(bp.SEEDS["dev2"]) | set(bp.SEEDS["dev_null"]) | \
        set(bp.SEEDS["dev_small"])
    score = set(bp.SEEDS["score4"])
    seen = set(bp.SEEDS["score1"]) | set(bp.SEEDS["score"]) | set(bp.SEEDS["score3"])
    assert not dev & score and not dev & seen and not score & seen
    assert not set(bp.SEEDS["score"]) & set(bp.SEEDS["score1"])
    assert len(score - bp.NULL_SEEDS) >= 40 and len(score & bp.NULL_SEEDS) >= 10


def test_score5_is_new_and_its_scored_prefix_fixed(bp):
    new = set(bp.SEEDS["score5"])
    assert all(not new & set(seeds) for name, seeds in bp.SEEDS.items() if name != "score5")
    assert len(new - bp.NULL_SEEDS) == 40 and len(new & bp.NULL_SEEDS) == 12
    order = bp.ORDER["score5"]
    assert sorted(order) == sorted(new)
    first = order[:bp.SCORE5_FIRST]
    assert len(set(first) - bp.NULL_SEEDS) == 20 and len(set(first) & bp.NULL_SEEDS) == 5


def test_null_and_small_cases(bp):
    assert all(bp.draw_case(s)["truth"] == {} for s in bp.SEEDS["dev_null"])
    small = [bp.draw_case(s) for s in bp.SEEDS["dev_small"]]
    assert all(len(c["truth"]) == 1 for c in small)
    # sizes from the lowest third of the ranges: torque-constant changes within 8-13.7 %
    changes = [abs(v) for c in small for v in c["truth"].get("torque_constant",
                                                             {"size": []})["size"]]
    assert changes and all(0.08 <= v <= 0.08 + 0.17 / 3 for v in changes)
    # the draws of the other sets are unchanged by the span argument (span=1)
    assert bp.draw_case(9201)["truth"]["coulomb_friction"]["size"][0] == \
        pytest.approx(3.18762228644524)


def test_a_case_is_a_function_of_its_seed_alone(bp):
    a, b = bp.draw_case(7001), bp.draw_case(7001)
    assert json.dumps(a, default=str) == json.dumps(b, default=str)
    cases = [bp.draw_case(s) for s in range(100, 140)]
    assert {c["engine"] for c in cases} == set(bp.ENGINES)
    assert {len(c["truth"]) for c in cases} == {1, 2}
    kinds = {k for c in cases for k in c["truth"]}
    assert kinds == set(bp.TYPES)


def _named(name, target, **parameters):
    return {"name": name, "target": target, "joints": [] if target is None else [target],
            "parameters": parameters}


def test_scoring_rule(bp):
    truth = {"engine": "mujoco", "effects": {
        "time_delay": {"joints": [], "size": 0.04},
        "viscous_friction": {"joints": [2], "size": [3.0]}}}
    right = [_named("time_delay", None, delay=0.036),
             _named("viscous_friction", 2, delta_viscous=3.3),
             _named("friction_softening", 0, softening=5.0, softening_velocity=0.004),
             _named("coulomb_friction", 1, delta_coulomb=0.1 * 12.0)]
    verdicts, invented = bp.score_case(truth, right)
    assert all(v["ok"] for v in verdicts.values()) and invented == []
    # the delay read as friction: not named, and a large viscous term elsewhere is invented
    wrong = [_named("viscous_friction", 2, delta_viscous=3.3),
             _named("viscous_friction", 0, delta_viscous=0.5 * 20.0),
             _named("stribeck_friction", 3, delta_stribeck=1.5, stribeck_velocity=0.45)]
    verdicts, invented = bp.score_case(truth, wrong)
    assert not verdicts["time_delay"]["ok"] and verdicts["viscous_friction"]["ok"]
    assert invented == ["viscous_friction[joint 1]", "stribeck_friction[joint 4]"]
    # sized 25 % off: not within 20 %
    off = [_named("time_delay", None, delay=0.05), _named("viscous_friction", 2,
                                                          delta_viscous=3.0)]
    assert not bp.score_case(truth, off)[0]["time_delay"]["ok"]


def test_torque_constant_scored_on_its_change(bp):
    truth = {"engine": "pybullet", "effects": {
        "torque_constant": {"joints": [4], "size": [-0.1]}}}
    # scale 0.95 is within 20 % of the scale 0.9 but half the change: not sized
    verdicts, _ = bp.score_case(truth, [_named("torque_constant", 4, scale=0.95)])
    assert not verdicts["torque_constant"]["ok"]
    verdicts, _ = bp.score_case(truth, [_named("torque_constant", 4, scale=0.91)])
    assert verdicts["torque_constant"]["ok"]


@pytest.mark.slow
def test_generate_and_diagnose_reads_only_the_cases(bp, tmp_path):
    pytest.importorskip("mujoco")
    pytest.importorskip("pybullet")
    bp.generate([100], tmp_path)
    truth = tmp_path / "truth" / "truth.json"
    hidden = tmp_path.parent / f"{tmp_path.name}_truth.json"
    truth.rename(hidden)  # the diagnosis step must not need it
    results = bp.diagnose(tmp_path)
    assert list(results) == ["case100"]
    assert (tmp_path / "plans" / "case100.csv").exists()
    bp.simulate_plans([100], tmp_path)  # the generator's second step reads the seed only
    second = bp.diagnose(tmp_path, stage=2)
    assert list(second) == ["case100"]
    hidden.rename(truth)
    summary = bp.score(tmp_path)
    assert summary["cases"] == 1 and bp.score(tmp_path, stage=2)["cases"] == 1
    assert np.isfinite(results["case100"]["nmse_after"]).all()
