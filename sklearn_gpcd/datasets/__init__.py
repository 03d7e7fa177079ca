"""Built-in robot simulator and the paper's data sets (Sec. III-C, Sec. V).

:class:`RobotSimulator` runs a built-in robot (pinocchio ABA) under a UR-like
1 kHz joint servo with motor currents, Stribeck friction and real stiction,
sensor noise, external contacts and injected effects, and logs a
:class:`~sklearn_gpcd.io.Recording` at 125 Hz. The ``simulate_*`` generators
simulate the paper's experiments on it. The effects the diagnosis tests
and studies inject besides (``_extra_effects``) are not public.
"""

from ._extra_effects import FrictionDelta
from .contacts import Contact, contact_labels
from .effect_registry import (
    DIAGNOSIS_ONLY,
    EFFECT_REGISTRY,
    SIMULATOR_ONLY,
    RegisteredEffect,
    registered_effect,
)
from .effects import (
    CurrentDelay,
    CurrentOffset,
    FrictionChange,
    JointSpring,
    Payload,
    TorqueConstantError,
)
from .friction import JointFriction, default_friction
from .generators import (
    reference_d1,
    reference_d2,
    reference_interaction_test,
    reference_joint1_cyclic,
    simulate_d1,
    simulate_d2,
    simulate_interaction_test,
    simulate_joint1_cyclic,
)
from .servo import ServoGains, feedforward_torque, servo_gains
from .simulator import RobotSimulator, simulate
from .trajectory import JointTrajectory
from .workspace import Hemisphere, inverse_kinematics

__all__ = [
    "FrictionDelta",
    "Contact",
    "DIAGNOSIS_ONLY",
    "EFFECT_REGISTRY",
    "RegisteredEffect",
    "SIMULATOR_ONLY",
    "registered_effect",
    "CurrentDelay",
    "CurrentOffset",
    "FrictionChange",
    "Hemisphere",
    "JointFriction",
    "JointSpring",
    "JointTrajectory",
    "Payload",
    "RobotSimulator",
    "ServoGains",
    "TorqueConstantError",
    "contact_labels",
    "default_friction",
    "feedforward_torque",
    "inverse_kinematics",
    "simulate_d1",
    "simulate_d2",
    "simulate_interaction_test",
    "simulate_joint1_cyclic",
    "reference_d1",
    "reference_d2",
    "reference_interaction_test",
    "reference_joint1_cyclic",
    "servo_gains",
    "simulate",
]
