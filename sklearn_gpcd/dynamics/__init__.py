"""The physical torque model's features, base parameters and sklearn transformer;
the generalized-momentum observer.

>>> from sklearn_gpcd.dynamics import parameter_names
>>> parameter_names(6)[-1]
'viscous_5'
"""

from .base_parameters import base_parameters
from .controller import ControllerCurrent, ControllerFeatures
from .friction import stribeck_friction, stribeck_peak
from .torque_model import (
    FRICTION_TERMS,
    INERTIAL_PARAMETERS,
    friction_features,
    torque_features,
    inertial_features,
    parameter_names,
    parameter_vector,
)
from .observer import UR_OBSERVER_GAINS, MomentumObserver, MomentumObserverStream
from .rigid_body import FrictionColumns, RigidBodyFeatures

__all__ = [
    "ControllerCurrent",
    "ControllerFeatures",
    "RigidBodyFeatures",
    "FrictionColumns",
    "MomentumObserver",
    "MomentumObserverStream",
    "UR_OBSERVER_GAINS",
    "parameter_vector",
    "parameter_names",
    "torque_features",
    "inertial_features",
    "friction_features",
    "base_parameters",
    "FRICTION_TERMS",
    "INERTIAL_PARAMETERS",
    "stribeck_friction",
    "stribeck_peak",
]
