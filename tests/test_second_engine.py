"""Opt-in (slow) checks of the diagnosis on a second physics engine (MuJoCo).

The plant and the cases live in ``benchmarks/`` (``_mujoco_plant.py``,
``second_engine.py``); MuJoCo is not a dependency of the package, so these
tests skip when it is not installed.
"""

import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.fixture(scope="module")
def engine():
    pytest.importorskip("mujoco")
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import second_engine
    finally:
        sys.path.remove(str(BENCHMARKS))
    return second_engine, second_engine.plant_setup()


def test_control_names_nothing_beyond_the_plant_friction(engine):
    module, setup = engine
    result = module.run_case("control", setup)
    assert result["extra"] == []
    assert set(result["all_named"]) <= module.PLANT_FRICTION


@pytest.mark.parametrize("case", ["coulomb_friction", "payload", "torque_constant",
                                  "joint_spring", "current_offset"])
def test_injected_effect_named_within_20_percent(engine, case):
    module, setup = engine
    result = module.run_case(case, setup)
    assert result["named_within_20_percent"], result["effects"]
    assert result["extra"] == [], result["extra"]


def test_rotor_inertia_is_never_read_as_a_heavy_link(engine):
    """Extra rotor inertia on the shoulder joints: rotor inertia (or "ambiguous"), never a
    link mass of tens of kg."""
    module, setup = engine
    result = module.run_case("rotor_inertia", setup)
    diagnosis = result["diagnosis"]
    links = [f for f in diagnosis.effects_ if f.name == "link_mass"]
    assert all(abs(f.parameters["delta_mass"][0]) < 5.0 for f in links)
    named = {f.name for f in diagnosis.effects_}
    ambiguous = {a["alternative_effect"] for a in diagnosis.ambiguities_} | {
        a["effect"] for a in diagnosis.ambiguities_}
    assert "rotor_inertia" in named or "rotor_inertia" in ambiguous


def test_stribeck_peak_is_positive(engine):
    module, setup = engine
    diagnosis = module.run_case("stribeck_friction", setup)["diagnosis"]
    peaks = [f.parameters["delta_stribeck"][0] for f in diagnosis.effects_
             if f.name == "stribeck_friction"]
    assert peaks and all(p > 0 for p in peaks)
