"""Shared test fixtures.

Real recordings live outside the repository (they carry no redistribution
license). Tests that read them use the ``real_data_dir`` fixture, which skips
cleanly when the folder is absent. Override the location with
``GPCD_REAL_DATA=/path/to/real``.
"""

import importlib.metadata
import importlib.util
import os
from pathlib import Path

import numpy as np
import pytest

_DEFAULT_REAL = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"


def _real_data_root():
    return Path(os.environ.get("GPCD_REAL_DATA", _DEFAULT_REAL)).resolve()


@pytest.fixture(scope="session")
def real_data_dir():
    root = _real_data_root()
    if not root.is_dir():
        pytest.skip(f"real data not found at {root} (set GPCD_REAL_DATA)")
    return root


@pytest.fixture(scope="session")
def ur10e_dir(real_data_dir):
    path = real_data_dir / "ur10e_mamedov"
    if not path.is_dir():
        pytest.skip(f"UR10e data not found at {path}")
    return path


@pytest.fixture
def rng():
    return np.random.default_rng(0)


def example_robot_data_urdf(relative):
    """Path of a file shipped by example-robot-data, or None.

    The PyPI wheel of example-robot-data 6 installs only data files (no
    importable ``example_robot_data`` module), so fall back to the
    distribution's file list when the module is missing.
    """
    if importlib.util.find_spec("example_robot_data") is not None:
        import example_robot_data

        try:
            return Path(example_robot_data.getModelPath(relative)) / relative.lstrip("/")
        except Exception:  # pragma: no cover - depends on the installed version
            pass
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        return None
    for f in dist.files or []:
        if str(f).endswith(relative):
            path = Path(dist.locate_file(f))
            return path if path.is_file() else None
    return None


@pytest.fixture(scope="session")
def ur10_urdf():
    """The UR10 URDF of example-robot-data (extra ``reference-robots``); skips if absent."""
    path = example_robot_data_urdf("ur_description/urdf/ur10_robot.urdf")
    if path is None:
        pytest.skip("example-robot-data (UR10 URDF) not installed")
    return path
