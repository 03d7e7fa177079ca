"""Tests of the ``gpcd`` command line."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sklearn_gpcd.cli import build_parser, main
from sklearn_gpcd.io import read_rtde_csv

REPO = Path(__file__).resolve().parents[1]


def test_robots_lists_every_builtin(capsys):
    assert main(["robots"]) == 0
    out = capsys.readouterr().out
    for name in ("ur3", "ur5", "ur10", "ur3e", "ur5e", "ur10e", "ur16e"):
        assert name in out


def test_unknown_robot_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args(["simulate", "--robot", "ur99", "-o", "x.csv"])
    assert exc.value.code == 2
    assert "ur99" in capsys.readouterr().err


@pytest.mark.parametrize("command", ["reproduce", "simulate"])
def test_robot_option_takes_a_urdf_path(command, ur10_urdf):
    args = build_parser().parse_args([command, "--robot", str(ur10_urdf), "-o", "out"])
    assert args.robot.n_joints == 6
    assert args.robot.model.nq == 6


@pytest.mark.parametrize("command", ["reproduce", "simulate"])
def test_robot_option_takes_a_builtin_name(command):
    args = build_parser().parse_args([command, "--robot", "UR10e", "-o", "out"])
    assert args.robot.name == "ur10e"


def test_simulate_writes_an_rtde_csv_the_loader_reads(tmp_path, capsys):
    path = tmp_path / "cyclic.csv"
    assert main(["simulate", "--scenario", "joint1-cyclic", "-o", str(path)]) == 0
    assert "wrote" in capsys.readouterr().out
    rec = read_rtde_csv(path)
    assert rec.n_joints == 6
    assert rec.target_current is not None
    assert np.all(np.diff(rec.time) > 0)
    assert rec.metadata["robot"] == "ur10"  # kept, so later commands need no --robot


def test_simulate_with_a_urdf_robot(tmp_path, ur10_urdf):
    path = tmp_path / "urdf.csv"
    assert main(["simulate", "--robot", str(ur10_urdf), "--scenario", "joint1-cyclic",
                 "-o", str(path)]) == 0
    assert read_rtde_csv(path).n_samples > 100


def test_console_script_is_installed():
    out = subprocess.run([sys.executable, "-m", "sklearn_gpcd.cli", "--help"],
                         capture_output=True, text=True, check=True).stdout
    assert "reproduce" in out and "simulate" in out


def test_ci_runs_the_readme_test_command_verbatim():
    readme = (REPO / "README.md").read_text()
    block = readme.split("## Quick start", 1)[1].split("```bash", 1)[1].split("```", 1)[0]
    commands = [line for line in block.strip().splitlines() if line.strip()]
    assert len(commands) == 2, "the quick start must have exactly two commands"
    assert "gpcd reproduce" in commands[0]
    assert commands[1] in (REPO / ".ci" / "run").read_text().splitlines()


def test_tests_extra_lists_every_optional_package_the_tests_use():
    """A fresh ``pip install -e ".[tests]"`` must run the whole default suite."""
    import re

    pyproject = (REPO / "pyproject.toml").read_text()
    extras = dict(re.findall(r'^([a-z-]+) = \[(.*)\]$', pyproject, flags=re.M))
    tests_extra = {re.split(r"[\[<>=]", dep.strip().strip('"'))[0]
                   for dep in extras["tests"].split('", ')}
    docs_extra = {re.split(r"[\[<>=]", dep.strip().strip('"'))[0]
                  for dep in extras["docs"].split('", ')}
    used = set()
    for path in (REPO / "tests").glob("*.py"):
        used |= set(re.findall(r'importorskip\("([A-Za-z_]+)', path.read_text()))
    used |= {"example_robot_data"}  # tests/conftest.py: the reference UR10 URDF
    used -= {"sklearn_gpcd"}
    dists = {name.replace("_", "-") for name in used}
    docs_only = {"sphinx", "numpydoc", "sphinx-gallery", "pydata-sphinx-theme"}
    # opt-in extras feed only slow tests (`pytest -m slow`), never the default run
    opt_in = {re.split(r"[\[<>=]", dep.strip().strip('"'))[0]
              for dep in extras["second-engine"].split('", ')}
    assert dists - docs_only - opt_in <= tests_extra, dists - docs_only - opt_in - tests_extra
    assert docs_only <= docs_extra


def test_ci_runs_the_tests_in_a_fresh_virtual_environment():
    script = (REPO / ".ci" / "run").read_text()
    venv = script.index("python -m venv")
    activate = script.index("/bin/activate")
    install = script.index('python -m pip install -e ".[tests]"')
    assert venv < activate < install
    assert '"$status" -eq 5' in script  # pytest collecting nothing fails CI


def test_calibrate_help_gives_the_defaults_the_selection_uses():
    """--rest-reference / --settle-time: chosen among the --select grid by default,
    not a fixed number (issue 46: the help said "default 5")."""
    from sklearn_gpcd.cli import build_parser
    from sklearn_gpcd.workflow.calibration import DEFAULT_REST_REFERENCE, SELECT_GRID

    sub = next(a for a in build_parser()._actions if a.dest == "command")
    options = {a.dest: a.help for a in sub.choices["calibrate"]._actions}
    for name in ("rest_reference", "settle_time"):
        text = " ".join(options[name].split())
        grid = ", ".join("none" if v is None else f"{v:g}"
                         for v in SELECT_GRID[f"regimes__{name}"])
        assert f"default: chosen across the recordings among {grid} s (--select)" in text, text
    assert f"{DEFAULT_REST_REFERENCE:g} with --no-select" in options["rest_reference"]
    assert "default 5)" not in options["rest_reference"]
