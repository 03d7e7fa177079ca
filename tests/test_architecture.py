"""The package's shape: no import cycle (function-level imports included), the
layers import only upwards, and no module reaches into another's private names."""

import ast
from pathlib import Path

import pytest

import sklearn_gpcd

ROOT = Path(sklearn_gpcd.__file__).parent
#: Top-level parts of the package by layer: a part imports only from its own
#: layer or from earlier ones (CONTRIBUTING.md); "" is the package's __init__.
LAYERS = [
    {"_version", "layout", "_gate", "_progress", "_atomic"},
    {"_persistence", "io", "metrics", "persistence"},
    {"robots", "dynamics"},
    {"features"},
    {"kernels", "gp"},
    {"detection", "diagnosis", "datasets", "contact", "plotting"},
    {"experiments", "workflow", "monitoring"},
    {"cli"},
    {""},
]


def _module_name(path):
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules():
    return {_module_name(p): p for p in ROOT.rglob("*.py")}


def _imports(name, path, modules):
    """``(module, imported names)`` of every import statement of the module, at any depth."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, ()
        elif isinstance(node, ast.ImportFrom):
            base = package
            for _ in range(node.level - 1):
                base = base.rpartition(".")[0]
            target = (base + "." + node.module if node.module else base) if node.level \
                else node.module
            names = [a.name for a in node.names]
            submodules = [f"{target}.{n}" for n in names if f"{target}.{n}" in modules]
            if len(submodules) < len(names):
                yield target, [n for n in names if f"{target}.{n}" not in modules]
            for sub in submodules:
                yield sub, ()


def _graph():
    modules = _modules()
    graph = {}
    for name, path in modules.items():
        graph[name] = {target for target, _ in _imports(name, path, modules)
                       if target in modules and target != name}
    return graph


def _cycle(graph):
    """One import cycle as a list of modules, or None."""
    state = {}

    def visit(node, stack):
        state[node] = "open"
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == "open":
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state and (found := visit(nxt, stack)):
                return found
        stack.pop()
        state[node] = "done"
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node, [])):
            return found
    return None


def _part(module):
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def test_no_import_cycle():
    graph = _graph()
    # a package's __init__ re-exports its submodules: importing the package from one of its
    # own submodules is the cycle we look for, so keep those edges
    assert _cycle(graph) is None, " -> ".join(_cycle(graph))


def test_layers_import_only_upwards():
    layer = {part: k for k, parts in enumerate(LAYERS) for part in parts}
    offences = []
    for module, targets in _graph().items():
        own = _part(module)
        if own not in layer:
            offences.append(f"{module}: part {own!r} is in no layer")
            continue
        for target in targets:
            theirs = _part(target)
            if theirs != own and layer.get(theirs, 99) > layer[own]:
                offences.append(f"{module} imports {target}")
    assert not offences, "\n".join(sorted(offences))


@pytest.mark.parametrize("prefix", ["sklearn_gpcd.detection"])
def test_no_module_imports_private_names_of_another_part(prefix):
    """Other parts of the package use a part's public interface only."""
    modules = _modules()
    offences = []
    for name, path in modules.items():
        if name.startswith(prefix):
            continue
        for target, names in _imports(name, path, modules):
            if target.startswith(prefix):
                private = [n for n in names if n.startswith("_")]
                if private or target.rpartition(".")[2].startswith("_"):
                    offences.append(f"{name}: from {target} import {names}")
    assert not offences, "\n".join(offences)


def test_the_package_names_no_benchmark_or_study_script():
    """The package stands on its own: no module points into benchmarks/ or studies/."""
    offences = [str(p.relative_to(ROOT)) for p in ROOT.rglob("*.py")
                if "benchmarks/" in p.read_text() or "studies/" in p.read_text()]
    assert not offences


def _private_methods(path, class_name):
    tree = ast.parse(path.read_text())
    for node in tree.body:
        if isinstance(node, ast.ClassDef) and node.name == class_name:
            return {f.name for f in node.body if isinstance(f, ast.FunctionDef)
                    and f.name.startswith("_") and not f.name.startswith("__")}
    raise AssertionError(f"{class_name} not found in {path}")


@pytest.mark.parametrize("module, class_name", [
    ("detection/detector.py", "CollisionDetector"),
    ("detection/rules.py", "AlarmRule"),
    ("detection/streaming.py", "StreamingMonitor"),
])
def test_no_module_calls_the_detectors_private_methods(module, class_name):
    """The detector's parts talk through public methods (fit_residuals, calibrate,
    residuals, stages, ...), not through each other's private ones."""
    private = _private_methods(ROOT / module, class_name)
    offences = []
    for path in ROOT.rglob("*.py"):
        if path == ROOT / module:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if (isinstance(node, ast.Attribute) and node.attr in private
                    and not (isinstance(node.value, ast.Name)
                             and node.value.id in ("self", "cls"))):
                offences.append(f"{path.relative_to(ROOT)}:{node.lineno} .{node.attr}")
    assert not offences, "\n".join(offences)
