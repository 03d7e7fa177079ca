"""The effect registry: complete, and every entry round-trips simulator -> diagnosis.

The round trip is generated from :data:`sklearn_gpcd.datasets.EFFECT_REGISTRY`:
inject the entry's example into the simulator, give the diagnosis only the
nominal model (the simulator's robot, torque constants, rotor inertias and
nominal friction) and the recordings, and compare what it reports with the
entry's conversion of the injected parameters.

* fast (default run): a short run (4 random targets, ~13 s of robot time),
  the diagnosis restricted to the entry's identifier;
* slow: 8 training and 5 test targets, the whole effect library competing:
  only the injected effect named, parameters within 20 %, held-out nMSE
  improved on the joints it loads.
"""

import importlib
import inspect
import pkgutil

import numpy as np
import pytest

import sklearn_gpcd
from sklearn_gpcd.datasets import (
    DIAGNOSIS_ONLY,
    EFFECT_REGISTRY,
    SIMULATOR_ONLY,
    _extra_effects,
    default_friction,
    effects,
    simulate_d1,
    registered_effect,
)
from sklearn_gpcd.datasets.plant import drive_parameters
from sklearn_gpcd.diagnosis import EFFECTS, DynamicsDiagnosis
from sklearn_gpcd.robots import load_robot

NAMES = [entry.name for entry in EFFECT_REGISTRY]
#: Joints each non-per-joint example loads clearly on the D1 trajectory (slow check).
LOADED_JOINTS = {"payload": [1, 2, 3, 4], "link_mass": [0, 1, 2], "gravity_tilt": [1, 2],
                 "time_delay": [0, 1, 2]}


@pytest.fixture(scope="module")
def nominal():
    """The simulator's own nominal model: robot with its drive data and friction."""
    robot = load_robot("ur10")
    k, rotor = drive_parameters(robot)
    return load_robot("ur10", torque_constants=k, rotor_inertias=rotor), default_friction(robot)


def _injectors():
    """Every simulator injector class (a plant or a recording effect; a private base
    class such as ``effects._FrictionEffect`` is none)."""
    found = set()
    for module in (effects, _extra_effects):
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if cls.__module__ == module.__name__ and not cls.__name__.startswith("_") and (
                    hasattr(cls, "apply") or hasattr(cls, "apply_to_recording")):
                found.add(cls)
    return found


def test_registry_is_complete():
    registered = {entry.injector for entry in EFFECT_REGISTRY}
    injectors = _injectors()
    assert len(injectors) >= 10
    assert injectors <= registered | set(SIMULATOR_ONLY), injectors - registered
    assert not set(SIMULATOR_ONLY) & registered
    identifiers = [entry.identifier for entry in EFFECT_REGISTRY]
    assert sorted(identifiers + list(DIAGNOSIS_ONLY), key=str) == sorted(EFFECTS, key=str)
    assert NAMES == [cls.name for cls in EFFECTS if cls not in DIAGNOSIS_ONLY]
    assert all(reason for reason in {**SIMULATOR_ONLY, **DIAGNOSIS_ONLY}.values())


def test_no_injector_shares_a_name_with_an_identifier():
    assert not {cls.__name__ for cls in _injectors()} & {cls.__name__ for cls in EFFECTS}


def test_no_two_package_classes_share_a_name():
    """A class name means one thing in the whole package (issue #17)."""
    modules = {}
    for info in pkgutil.walk_packages(sklearn_gpcd.__path__, "sklearn_gpcd."):
        try:
            module = importlib.import_module(info.name)
        except ImportError:  # an optional dependency (the tests of that module say so)
            continue
        for name, cls in inspect.getmembers(module, inspect.isclass):
            if cls.__module__ == module.__name__ and not name.startswith("_"):
                modules.setdefault(name, set()).add(module.__name__)
    shared = {name: sorted(where) for name, where in modules.items() if len(where) > 1}
    assert not shared, shared


def test_expected_parameters_are_the_identifiers(nominal):
    """The conversion reports exactly the identifier's parameters, on a simulated run."""
    recording = simulate_d1("ur10", n_targets=1, random_state=0)
    for entry in EFFECT_REGISTRY:
        expected = entry.expected(entry.inject(), *nominal, recording)
        assert expected, entry.name
        for params in expected.values():
            assert list(params) == list(entry.identifier.parameter_names), entry.name


def test_unknown_name_is_refused():
    with pytest.raises(ValueError, match="known"):
        registered_effect("backlash")


def _simulate(entry, n_targets, seed):
    injected = entry.inject()
    plant = [e for e in injected if hasattr(e, "apply")]
    recording = simulate_d1("ur10", n_targets=n_targets, effects=plant, random_state=seed)
    for effect in injected:
        if hasattr(effect, "apply_to_recording"):
            recording = effect.apply_to_recording(recording)
    return injected, recording


def _assert_close(fitted, truth, name, rel=0.2):
    """Within ``rel`` of the truth; a zero truth within 4 standard errors."""
    for key, value in truth.items():
        estimate, std = fitted.parameters[key]
        if value == 0:
            assert abs(estimate) <= 4 * std + 1e-12, (name, key, estimate, std)
        else:
            assert estimate == pytest.approx(value, rel=rel), (name, key, estimate, value)


def _assert_round_trip(entry, fits, expected):
    """The identifier found on the expected targets with the expected estimates."""
    assert fits, f"{entry.name} not found"
    assert all(isinstance(f.effect, entry.identifier) for f in fits)
    if None in expected:
        assert len(fits) == 1, [f.target for f in fits]
        _assert_close(fits[0], expected[None], entry.name)
        return
    assert sorted(f.target for f in fits) == sorted(expected), entry.name
    for fitted in fits:
        _assert_close(fitted, expected[fitted.target], entry.name)


@pytest.mark.parametrize("name", NAMES)
def test_round_trip_fast(nominal, name):
    entry = registered_effect(name)
    robot, friction = nominal
    injected, train = _simulate(entry, n_targets=4, seed=1)
    diag = DynamicsDiagnosis(robot, friction=friction, effects=[name]).fit(train)
    _assert_round_trip(entry, diag.effects_, entry.expected(injected, robot, friction, train))


@pytest.mark.slow
@pytest.mark.parametrize("name", NAMES)
def test_round_trip_whole_library(nominal, name):
    entry = registered_effect(name)
    robot, friction = nominal
    injected, train = _simulate(entry, n_targets=8, seed=1)
    _, test = _simulate(entry, n_targets=5, seed=101)
    diag = DynamicsDiagnosis(robot, friction=friction).fit(train)
    assert [f.name for f in diag.effects_] == [name] * len(diag.effects_), \
        [f"{f.name}{f.joints}" for f in diag.effects_]
    expected = entry.expected(injected, robot, friction, train)
    _assert_round_trip(entry, diag.effects_, expected)
    if None in expected or entry.name == "link_mass":
        loaded = LOADED_JOINTS[name]
        assert set(loaded) <= set(diag.effects_[0].joints), (name, diag.effects_[0].joints)
    else:
        loaded = sorted(expected)
    scores = diag.evaluate(test)
    before, after = np.array(scores["nmse_before"]), np.array(scores["nmse_after"])
    assert after[loaded].sum() < 0.8 * before[loaded].sum(), (before, after)


def test_no_effect_name_branches_outside_the_effects_module():
    """Each effect owns its behaviour (issue 48, item 4): the diagnosis modules other than
    ``effects.py`` never branch on an effect's name (``name == "payload"``); they ask the
    effect (``Effect.implausible_among``, ``unresolved``, ``composite_partners``, ...)."""
    import re
    from pathlib import Path

    folder = Path(sklearn_gpcd.__file__).parent / "diagnosis"
    names = "|".join(cls.name for cls in EFFECTS)
    branch = re.compile(r"""name\s*(==|!=)\s*["']|name\s+(not\s+)?in\s*[\(\{\[]\s*["']"""
                        rf"""|(==|!=|\bin)\s*[\(\{{\[]?\s*["']({names})["']""")
    offences = [f"{path.name}:{k}: {line.strip()}"
                for path in sorted(folder.glob("*.py")) if path.name != "effects.py"
                for k, line in enumerate(path.read_text().splitlines(), 1)
                if branch.search(line)]
    assert offences == []


def test_effects_lead_the_composites_the_selection_tries():
    """Coulomb + viscous of each joint, and each Stribeck peak with every softening of its
    joint at least PAIR_SEPARATION times slower: the pairs each effect asks for."""
    from sklearn_gpcd.diagnosis import NominalModel, Signals, effect_library
    from sklearn_gpcd.diagnosis.effects import PAIR_SEPARATION
    from sklearn_gpcd.diagnosis.selection import build_candidates

    nominal = NominalModel("ur10")
    rng = np.random.default_rng(0)
    signals = Signals.from_states(nominal, np.c_[rng.uniform(-1, 1, (50, 12)),
                                                 np.zeros((50, 6))])
    candidates, _ = build_candidates(signals, nominal, effect_library(
        ["coulomb_friction", "viscous_friction", "stribeck_friction", "friction_softening"]))
    pairs = [c for c in candidates if c.parts]
    singles = [c for c in candidates if not c.parts]
    kinds = {(p.parts[0].effect.name, p.parts[1].effect.name) for p in pairs}
    assert kinds == {("coulomb_friction", "viscous_friction"),
                     ("stribeck_friction", "friction_softening")}
    peaks = [c for c in singles if c.effect.name == "stribeck_friction"]
    softs = [c for c in singles if c.effect.name == "friction_softening"]
    expected = 6 + sum(1 for p in peaks for s in softs if s.target == p.target
                       and s.settings["stribeck_velocity"] * PAIR_SEPARATION
                       <= p.settings["stribeck_velocity"])
    assert len(pairs) == expected
    for pair in pairs:
        lead, partner = pair.parts
        assert lead.target == partner.target == pair.target
        assert list(pair.columns) == [*lead.columns, *partner.columns]
        if lead.effect.name == "stribeck_friction":
            assert pair.settings["softening_velocity"] == partner.settings["stribeck_velocity"]
