"""Model files that cannot act (issue #35): every attack on a detector file is refused.

Each malicious file is crafted here. A skops file gets a node that *calls* a
named object when it is loaded (skops' ``ConstructorFromReduceNode``:
``name(*args)``); each test first shows that the payload really runs when
that name is trusted (plain ``skops.io.load`` told to trust it), then that
:func:`sklearn_gpcd.load` and ``gpcd monitor`` refuse the file without
running anything.
"""

import json
import pathlib
import sys
import zipfile

import pytest
from _live import free_runs, linear_bundle

from sklearn_gpcd.cli import main
from sklearn_gpcd.workflow import DETECTOR_KIND
from sklearn_gpcd.io import write_rtde_csv
from sklearn_gpcd.persistence import (
    UntrustedPickleError,
    UntrustedTypesError,
    load,
    save,
    trusted_types,
)

skops_io = pytest.importorskip("skops.io")


class _Call:
    """Stands for the call ``target(*args)`` in a crafted skops file."""

    def __init__(self, *args):
        self.args = args

    def __reduce__(self):
        return (_Call, self.args)


class _Payload:
    """Unpickling it writes ``marker`` (a pickle's payload runs while it loads)."""

    def __init__(self, marker):
        self.marker = pathlib.Path(marker)

    def __reduce__(self):
        return (pathlib.Path.write_text, (self.marker, "the payload ran"))


def craft_skops(path, obj, target):
    """Dump ``obj`` with skops, every :class:`_Call` in it turned into a call of
    ``target`` (``"module.name"``)."""
    skops_io.dump(obj, path)
    module, name = target.rsplit(".", 1)
    with zipfile.ZipFile(path) as archive:
        entries = {n: archive.read(n) for n in archive.namelist()}
    schema = json.loads(entries["schema.json"])

    def swap(node):
        if isinstance(node, dict):
            if node.get("__class__") == "_Call":
                node["__class__"], node["__module__"] = name, module
            for value in node.values():
                swap(value)
        elif isinstance(node, list):
            for value in node:
                swap(value)

    swap(schema)
    entries["schema.json"] = json.dumps(schema).encode()
    with zipfile.ZipFile(path, "w") as archive:
        for n, data in entries.items():
            archive.writestr(n, data)
    return path


@pytest.fixture(scope="module")
def parts(tmp_path_factory):
    """A valid detector bundle's parts and a recording to monitor."""
    folder = tmp_path_factory.mktemp("attacks")
    runs = free_runs(n=2, n_targets=1)
    detector, features = linear_bundle(runs)
    recordings = [write_rtde_csv(run, folder / f"run{k}.csv", robot_comment=True)
                  for k, run in enumerate(runs)]
    return {"folder": folder, "detector": detector, "features": features,
            "recording": recordings[0], "recordings": recordings}


def bundle(parts, **extra):
    return {"kind": DETECTOR_KIND, "detector": parts["detector"],
            "features": parts["features"], "calibration": {}, **extra}


def assert_monitor_refuses(path, parts, capsys, why):
    """``gpcd monitor FILE RECORDING``: exit 2, one error line, nothing monitored."""
    assert main(["monitor", str(path), str(parts["recording"])]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and why in err[0], err
    assert captured.out == ""  # no robots listed, no events: nothing ran


def test_valid_skops_detector_loads_without_trusted(parts, tmp_path):
    path = save(bundle(parts), tmp_path / "ok.skops")
    assert load(path)["kind"] == DETECTOR_KIND


def test_skops_file_calling_the_cli_is_refused(parts, tmp_path, capsys):
    """A detector whose features call ``sklearn_gpcd.cli.main`` (it could run
    ``gpcd monitor --hook CMD``); here the call lists the robots."""
    path = craft_skops(tmp_path / "cli.skops",
                       bundle(parts, features=_Call(["robots"])), "sklearn_gpcd.cli.main")
    named = skops_io.get_untrusted_types(file=path)
    assert "sklearn_gpcd.cli.main" in named
    skops_io.load(path, trusted=named)  # trusted, the payload runs ...
    assert "ur10e" in capsys.readouterr().out
    with pytest.raises(UntrustedTypesError, match=r"sklearn_gpcd\.cli\.main"):
        load(path)  # ... not here
    assert capsys.readouterr().out == ""
    assert_monitor_refuses(path, parts, capsys, "not trusted")


def test_skops_file_with_a_memmap_in_write_mode_is_refused(parts, tmp_path, capsys):
    """``numpy.memmap(victim, mode="w+")`` in a detector would overwrite a file."""
    victim = tmp_path / "victim.txt"
    path = craft_skops(tmp_path / "memmap.skops",
                       bundle(parts, calibration=_Call(str(victim), "uint8", "w+", 0, (4,))),
                       "numpy.memmap")
    victim.write_text("precious")
    skops_io.load(path, trusted=skops_io.get_untrusted_types(file=path))
    assert victim.read_bytes() == b"\0\0\0\0"  # trusted, the file is overwritten
    victim.write_text("precious")
    with pytest.raises(UntrustedTypesError, match=r"numpy\.memmap"):
        load(path)
    assert_monitor_refuses(path, parts, capsys, "not trusted")
    assert victim.read_text() == "precious"


def test_skops_file_naming_a_main_module_imports_nothing(parts, tmp_path, capsys):
    """Deciding trust must not import the modules a file names: importing
    ``numpy.f2py.__main__`` runs f2py and exits the process."""
    if "numpy.f2py.__main__" in sys.modules:
        pytest.skip("numpy.f2py.__main__ is imported already")
    path = craft_skops(tmp_path / "f2py.skops", bundle(parts, calibration=_Call()),
                       "numpy.f2py.__main__.main")
    with pytest.raises(UntrustedTypesError, match=r"numpy\.f2py\.__main__"):
        load(path)
    assert_monitor_refuses(path, parts, capsys, "not trusted")
    assert "numpy.f2py.__main__" not in sys.modules


def test_package_functions_are_not_trusted(tmp_path):
    """No function is trusted, the package's own included (a function can be
    called with the file's data); trusted names are classes only."""
    from sklearn.preprocessing import FunctionTransformer

    from sklearn_gpcd.features import make_inputs

    path = save(FunctionTransformer(make_inputs), tmp_path / "function.skops")
    with pytest.raises(UntrustedTypesError, match="make_inputs"):
        load(path)
    names = trusted_types()
    assert not any(n.startswith(("sklearn_gpcd.cli", "sklearn_gpcd.io",
                                 "sklearn_gpcd.monitoring")) for n in names)
    assert "numpy.memmap" not in names
    import importlib

    for name in names:
        module, _, attr = name.rpartition(".")
        assert isinstance(getattr(importlib.import_module(module), attr), type), name


def test_pickle_is_refused_unless_trusted(parts, tmp_path, capsys):
    """A valid detector carrying a payload: refused by load and by gpcd monitor
    without --trust-pickle (one line saying why), the payload never runs."""
    marker = tmp_path / "pwned.txt"
    path = save(bundle(parts, payload=_Payload(marker)), tmp_path / "detector.joblib")
    with pytest.raises(UntrustedPickleError, match="runs any code it carries"):
        load(path)
    assert_monitor_refuses(path, parts, capsys, "--trust-pickle")
    assert main(["calibrate", str(path), *map(str, parts["recordings"]),
                 "-o", str(tmp_path / "d.skops")]) == 2  # a model file: the same rule
    assert "--trust-pickle" in capsys.readouterr().err
    assert not marker.exists()
    load(path, trust_pickle=True)  # told to trust it: the payload runs
    assert marker.read_text() == "the payload ran"


def test_trusted_pickle_is_monitored(parts, tmp_path, capsys):
    path = save(bundle(parts), tmp_path / "ok.pkl")
    assert main(["monitor", str(path), str(parts["recording"]), "-q",
                 "--trust-pickle"]) == 0
    assert "0 alarm event(s) in 1 recording(s)" in capsys.readouterr().out
