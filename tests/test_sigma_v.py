"""``sigma_v`` has one home (issue 46): one default, one constraint, and the value a
model was trained with reaches the regimes of the detector calibrated on it."""

import ast
import inspect
import re
from pathlib import Path

import numpy as np
import pytest
from sklearn.base import BaseEstimator
from sklearn.utils._param_validation import InvalidParameterError

import sklearn_gpcd
from sklearn_gpcd._gate import DEFAULT_SIGMA_V, SIGMA_V_CONSTRAINT, check_sigma_v
from sklearn_gpcd.cli import main
from sklearn_gpcd.datasets import simulate_d1
from sklearn_gpcd.features import quasi_static_mask, regimes
from sklearn_gpcd.io import write_rtde_csv
from sklearn_gpcd.kernels import ARDRBF, QuasiStaticGate
from sklearn_gpcd.workflow import load_detector, load_model, save_model

ROOT = Path(sklearn_gpcd.__file__).parent
#: Valid and invalid velocity thresholds: zero is refused (no velocity is below it,
#: the gate would never open), as are bools, infinities and NaN.
VALID = [0.05, 1e-3, 2, np.float64(0.01)]
INVALID = [0.0, -0.01, np.inf, np.nan, True, "0.01"]


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    """Two simulated UR10e runs, an SP_C model trained by ``gpcd train --sigma-v 0.05``
    and a detector calibrated on it by ``gpcd calibrate``."""
    folder = tmp_path_factory.mktemp("sigma_v")
    free = [write_rtde_csv(simulate_d1("ur10e", n_targets=2, random_state=seed),
                           folder / f"free{seed}.csv", robot_comment=True)
            for seed in range(2)]
    model = folder / "model.skops"
    assert main(["train", *map(str, free), "--model", "sp_c", "--n-support", "30",
                 "--sigma-v", "0.05", "-q", "-o", str(model)]) == 0
    detector = folder / "detector.skops"
    assert main(["calibrate", str(model), *map(str, free), "-q", "-o", str(detector)]) == 0
    return {"folder": folder, "free": free, "model": model, "detector": detector}


def test_train_sigma_v_reaches_the_regimes_of_calibrate(work):
    assert load_model(work["model"]).training["sigma_v"] == 0.05
    calibrated = load_detector(work["detector"])
    assert calibrated.detector.sigma_v == 0.05
    for rule in calibrated.detector.rules_:
        assert rule.regime_settings()["sigma_v"] == 0.05


def test_the_regimes_change_with_the_models_sigma_v(work, capsys):
    """The same model recorded with the default: its detector sees more motion
    (a joint at 0.02 rad/s moves at 0.01 and is still at 0.05)."""
    trained = load_model(work["model"])
    trained.training["sigma_v"] = DEFAULT_SIGMA_V
    model = save_model(trained, work["folder"] / "default.skops")
    detector = work["folder"] / "default_detector.skops"
    assert main(["calibrate", str(model), *map(str, work["free"]), "-q",
                 "-o", str(detector)]) == 0
    default = load_detector(detector)
    assert default.detector.rules_[0].regime_settings()["sigma_v"] == DEFAULT_SIGMA_V
    moving = {name: load_detector(path).calibration["coverage"]["moving"]["seconds"]
              for name, path in [("0.05", work["detector"]), ("default", detector)]}
    assert moving["0.05"] < moving["default"]


def test_train_model_records_the_default_when_none_is_given():
    from sklearn_gpcd.io import Recording
    from sklearn_gpcd.workflow import train_model

    t = np.arange(200) * 0.01
    q = np.column_stack([np.sin(t), np.cos(t)])
    rec = Recording(time=t, q=q, qd=np.gradient(q, t, axis=0), current=q,
                    target_current=0.9 * q)
    assert train_model([rec], model="sp_c", n_support=20).training["sigma_v"] \
        == DEFAULT_SIGMA_V


def _estimators_with_sigma_v():
    seen = {}
    for path in ROOT.rglob("*.py"):
        name = ".".join(path.relative_to(ROOT.parent).with_suffix("").parts)
        module = __import__(name.removesuffix(".__init__"), fromlist=["_"])
        for cls in vars(module).values():
            if (inspect.isclass(cls) and issubclass(cls, BaseEstimator)
                    and cls.__module__.startswith("sklearn_gpcd")
                    and "sigma_v" in inspect.signature(cls.__init__).parameters):
                seen[cls.__qualname__] = cls
    return seen


def test_every_estimator_constrains_sigma_v_with_the_one_constraint():
    estimators = _estimators_with_sigma_v()
    assert {"CollisionDetector", "SemiParametricGPRegressor", "ParametricMean",
            "RigidBodyFeatures", "DynamicsDiagnosis"} <= set(estimators)
    offences = {name: cls._parameter_constraints["sigma_v"]
                for name, cls in estimators.items()
                if [c for c in cls._parameter_constraints["sigma_v"] if c is not None]
                != [SIGMA_V_CONSTRAINT]}
    assert not offences


def _accepts(check, value):
    try:
        check(value)
    except (ValueError, TypeError, InvalidParameterError):
        return False
    return True


@pytest.mark.parametrize("value", VALID + INVALID, ids=repr)
def test_every_validator_agrees(value):
    """The parameter constraint, the function check and the public functions and
    kernel that validate ``sigma_v`` accept exactly the same values."""
    expected = value in VALID
    qd = np.array([0.0, 0.5])
    X = np.array([[0.0, 0.0], [0.0, 0.5]])
    checks = {
        "check_sigma_v": check_sigma_v,
        "SIGMA_V_CONSTRAINT": lambda v: (SIGMA_V_CONSTRAINT.is_satisfied_by(v)
                                         or (_ for _ in ()).throw(ValueError(v))),
        "quasi_static_mask": lambda v: quasi_static_mask(qd, sigma_v=v),
        "regimes": lambda v: regimes(qd, sigma_v=v),
        "QuasiStaticGate": lambda v: QuasiStaticGate(ARDRBF(1.0), 1, sigma_v=v)(X),
    }
    got = {name: _accepts(check, value) for name, check in checks.items()}
    assert got == dict.fromkeys(checks, expected)


def _numeric_sigma_v_defaults(tree):
    """Numbers written as a ``sigma_v`` default (argument, keyword or field)."""
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            args = node.args
            positional = args.posonlyargs + args.args
            pairs = list(zip(positional[len(positional) - len(args.defaults):],
                             args.defaults)) + list(zip(args.kwonlyargs, args.kw_defaults))
            for arg, default in pairs:
                if arg.arg == "sigma_v" and isinstance(default, ast.Constant) \
                        and default.value is not None:
                    yield node.lineno
        elif isinstance(node, ast.AnnAssign) and getattr(node.target, "id", "") == "sigma_v" \
                and isinstance(node.value, ast.Constant):
            yield node.lineno
        elif isinstance(node, ast.keyword) and node.arg == "sigma_v" \
                and isinstance(node.value, ast.Constant) and node.value.value is not None:
            yield node.lineno


def _docstrings(tree):
    return {id(node.body[0].value) for node in ast.walk(tree)
            if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef,
                                 ast.AsyncFunctionDef))
            and ast.get_docstring(node, clean=False) is not None}


def test_the_default_sigma_v_is_written_once():
    """Only ``_gate.DEFAULT_SIGMA_V`` holds the number; every default refers to it."""
    offences = []
    for path in ROOT.rglob("*.py"):
        text = path.read_text()
        tree, lines = ast.parse(text), text.splitlines()
        where = str(path.relative_to(ROOT))
        offences += [f"{where}:{line}" for line in _numeric_sigma_v_defaults(tree)]
        if path.name != "_gate.py":
            docs = _docstrings(tree)
            offences += [f"{where}:{node.lineno}" for node in ast.walk(tree)
                         if isinstance(node, ast.Constant) and type(node.value) is float
                         and node.value == DEFAULT_SIGMA_V and id(node) not in docs
                         and "sigma_v" in lines[node.lineno - 1].lower()]
    assert not offences, offences


def test_docstring_defaults_say_the_one_default():
    """Docstrings that name a number as ``sigma_v``'s default name this one."""
    text = "\n".join(p.read_text() for p in ROOT.rglob("*.py"))
    stated = {float(v) for v in re.findall(
        r"sigma_v : float[^\n]*default=([0-9.e-]+)", text)}
    assert stated <= {DEFAULT_SIGMA_V}
