"""sklearn-gpcd: proprioceptive robot collision detection with Gaussian Processes.

Implements Dalla Libera et al., "Proprioceptive Robot Collision Detection
through Gaussian Process Regression" (ACC 2019) as scikit-learn estimators.

Public names are imported lazily from their submodules, so ``import
sklearn_gpcd`` stays fast and pinocchio is loaded only when a robot is.
"""

import importlib

from ._version import __version__

# public name -> submodule that defines it: what the README, the user guide
# and the gallery use (tests/test_docs.py checks both); everything else is
# imported from its subpackage (``from sklearn_gpcd.io import read_csv``).
_EXPORTS = {
    # recordings
    "Recording": "io",
    "load_recording": "io",
    "load_recordings": "io",
    # the robot and the paper's inputs
    "load_robot": "robots",
    "Robot": "robots",
    "RigidBodyFeatures": "dynamics",
    "CausalFeatures": "features",
    "make_inputs": "features",
    # the models (Eq. 17) and their factories
    "SemiParametricGPRegressor": "gp",
    "make_p_f": "gp",
    "make_sp_s": "gp",
    "make_sp_p": "gp",
    "make_sp_c": "gp",
    # simulated recordings
    "simulate": "datasets",
    "simulate_d1": "datasets",
    # detection and its metrics
    "CollisionDetector": "detection",
    "StreamingMonitor": "detection",
    "CollisionThresholdCV": "detection",
    "stack_currents": "detection",
    "nmse": "metrics",
    "event_recall": "metrics",
    "detection_delay": "metrics",
    "false_alarms_per_hour": "metrics",
    "plot_monitoring": "plotting",
    # sim-to-real diagnosis
    "DynamicsDiagnosis": "diagnosis",
    # files
    "save": "persistence",
    "load": "persistence",
}

__all__ = ["__version__", *_EXPORTS]


def __getattr__(name):
    if name in _EXPORTS:
        module = importlib.import_module(f".{_EXPORTS[name]}", __name__)
        return getattr(module, name)
    raise AttributeError(f"module 'sklearn_gpcd' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
