"""Shared test fixtures.

Real recordings live outside the repository (they carry no redistribution
license). Tests that read them use the ``real_data_dir`` fixture, which skips
cleanly when the folder is absent. Override the location with
``GPCD_REAL_DATA=/path/to/real``.
"""

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
