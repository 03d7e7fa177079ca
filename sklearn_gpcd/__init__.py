"""sklearn-gpcd: proprioceptive robot collision detection with Gaussian Processes.

Implements Dalla Libera et al., "Proprioceptive Robot Collision Detection
through Gaussian Process Regression" (ACC 2019) as scikit-learn estimators.

Public names are imported lazily from their submodules, so ``import
sklearn_gpcd`` stays fast and pinocchio is loaded only when a robot is.
"""

import importlib

from ._version import __version__

# public name -> submodule that defines it
_EXPORTS = {
    "Recording": "io",
    "load_recording": "io",
    "load_recordings": "io",
    "read_rtde_csv": "io",
    "write_rtde_csv": "io",
    "read_csv": "io",
    "read_npz": "io",
    "read_rosbag": "io",
    "RecordingWarning": "io",
    "load_robot": "robots",
    "Robot": "robots",
    "list_robots": "robots",
    "parameter_vector": "dynamics",
    "RigidBodyFeatures": "dynamics",
    "ControllerFeatures": "dynamics",
    "InverseDynamicsFeatures": "features",
    "CausalFeatures": "features",
    "make_inputs": "features",
    "quasi_static_mask": "features",
    "differentiate": "features",
    "ARDRBF": "kernels",
    "QuasiStaticGate": "kernels",
    "ParametricKernel": "kernels",
    "resolve_columns": "kernels",
    "contract_gradient": "kernels",
    "ParametricMean": "gp",
    "SemiParametricGPRegressor": "gp",
    "RobotSimulator": "datasets",
    "simulate": "datasets",
    "simulate_d1": "datasets",
    "simulate_d2": "datasets",
    "simulate_joint1_cyclic": "datasets",
    "simulate_interaction_test": "datasets",
    "make_p_f": "gp",
    "make_sp_s": "gp",
    "make_sp_p": "gp",
    "make_sp_c": "gp",
    "CollisionDetector": "detection",
    "StreamingMonitor": "detection",
    "CollisionThresholdCV": "detection",
    "stack_currents": "detection",
    "nmse": "metrics",
    "event_recall": "metrics",
    "detection_delay": "metrics",
    "false_alarms_per_hour": "metrics",
    "plot_monitoring": "plotting",
    "DynamicsDiagnosis": "diagnosis",
    "DiagnosedModel": "diagnosis",
    "residual_breakdown": "diagnosis",
    "align_recordings": "diagnosis",
    "save": "persistence",
    "load": "persistence",
    "GPCDVersionWarning": "persistence",
    "UntrustedTypesError": "persistence",
    "UntrustedPickleError": "persistence",
}

__all__ = ["__version__", *_EXPORTS]


def __getattr__(name):
    if name in _EXPORTS:
        module = importlib.import_module(f".{_EXPORTS[name]}", __name__)
        return getattr(module, name)
    raise AttributeError(f"module 'sklearn_gpcd' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
