"""One table pairing each simulator effect with the diagnosis effect that names it.

The simulator injects physics the nominal model does not know
(:mod:`sklearn_gpcd.datasets.effects`); the diagnosis names what a nominal
model is missing (:mod:`sklearn_gpcd.diagnosis.effects`). Each
:class:`RegisteredEffect` of :data:`EFFECT_REGISTRY` ties the two together:
the diagnosis name, the injector, the identifier, an example injection and
the conversion from the injector's parameters to the estimate the
identifier should report (e.g. a :class:`FrictionChange` multiplier of the
viscous coefficient to ``delta_viscous`` in Nm s/rad). The round-trip test
(``tests/test_effect_registry.py``) is generated from this table: inject
with the simulator, identify with the diagnosis, compare through the
conversion.

What exists on one side only is listed with the reason in
:data:`SIMULATOR_ONLY` and :data:`DIAGNOSIS_ONLY`.

The table lives in :mod:`sklearn_gpcd.datasets` because the simulator is the
ground truth of the diagnosis: ``datasets`` imports ``diagnosis`` and never
the other way round, so the diagnosis, which runs on real robot logs, does
not depend on the simulator and the import graph stays acyclic.
"""

from dataclasses import dataclass, field

import numpy as np

from ..diagnosis import effects as identifiers
from ._extra_effects import (
    FrictionDelta,
    GravityTilt,
    LinkMass,
    LoggedCurrentDelay,
    RotorInertiaChange,
    friction_drift,
)
from .effects import (
    CurrentDelay,
    CurrentOffset,
    FrictionChange,
    JointSpring,
    Payload,
    TorqueConstantError,
    _per_joint,
)


def _one_hot(joint, value, n_joints=6):
    out = [0.0] * n_joints
    out[joint] = value
    return out


def _per_joint_values(values, **params):
    """``{joint: {name: value}}`` for the joints where ``values`` is not zero."""
    return {int(j): {k: float(v[j]) for k, v in params.items()}
            for j in np.flatnonzero(np.asarray(values) != 0)}


def _friction_after(effects, friction):
    """(nominal, true) friction levels after the friction effects among ``effects``."""
    after = friction
    for effect in effects:
        after = effect.changed(after)
    return friction, after


def _coulomb(effects, robot, friction, recording):
    before, after = _friction_after(effects, friction)
    delta = after.coulomb - before.coulomb
    return _per_joint_values(delta, delta_coulomb=delta)


def _viscous(effects, robot, friction, recording):
    before, after = _friction_after(effects, friction)
    delta = after.viscous - before.viscous
    return _per_joint_values(delta, delta_viscous=delta)


def _peak_change(effects, friction):
    """Change of the Stribeck peak ``F_s - F_c`` [Nm] and the true ``v_s`` [rad/s]."""
    before, after = _friction_after(effects, friction)
    peak = (after.static - after.coulomb) - (before.static - before.coulomb)
    return peak, after.stribeck_velocity


def _stribeck(effects, robot, friction, recording):
    peak, velocity = _peak_change(effects, friction)
    return _per_joint_values(np.maximum(peak, 0.0), delta_stribeck=peak,
                             stribeck_velocity=velocity)


def _softening(effects, robot, friction, recording):
    peak, velocity = _peak_change(effects, friction)
    return _per_joint_values(np.minimum(peak, 0.0), softening=-peak,
                             softening_velocity=velocity)


def _payload(effects, robot, friction, recording):
    (payload,) = effects
    com = np.asarray(payload.com, dtype=float)
    return {None: {"mass": float(payload.mass), "com_x": com[0], "com_y": com[1],
                   "com_z": com[2]}}


def _link_mass(effects, robot, friction, recording):
    (change,) = effects
    moment = float(change.mass) * np.asarray(change.offset, dtype=float)
    return {int(change.link): {"delta_mass": float(change.mass),
                               "delta_first_moment_x": moment[0],
                               "delta_first_moment_y": moment[1],
                               "delta_first_moment_z": moment[2]}}


def _per_joint_parameter(attribute, parameter):
    """Conversion of an injector's per-joint ``attribute``, reported as is as ``parameter``."""
    def expected(effects, robot, friction, recording):
        (effect,) = effects
        values = _per_joint(getattr(effect, attribute), recording.n_joints,
                            f"{type(effect).__name__}.{attribute}")
        return _per_joint_values(values, **{parameter: values})

    return expected


def _gravity_tilt(effects, robot, friction, recording):
    (tilt,) = effects
    return {None: {"roll": float(tilt.roll), "pitch": float(tilt.pitch)}}


def _torque_constant(effects, robot, friction, recording):
    (error,) = effects
    constants = np.asarray(robot.torque_constants, dtype=float)
    scale = _per_joint(error.scale, constants.shape[0], "TorqueConstantError.scale")
    return _per_joint_values(scale - 1.0, scale=scale, torque_constant=constants * scale)


def _time_delay(effects, robot, friction, recording):
    (delay,) = effects
    return {None: {"delay": float(delay.delay)}}


def _joint_spring(effects, robot, friction, recording):
    (spring,) = effects
    n = recording.n_joints
    stiffness = _per_joint(spring.stiffness, n, "JointSpring.stiffness")
    if spring.rest is None:  # the positions when the spring starts acting
        rest = recording.q[np.searchsorted(recording.time, spring.start)]
    else:
        rest = _per_joint(spring.rest, n, "JointSpring.rest")
    return _per_joint_values(stiffness, stiffness=stiffness, rest_position=rest)


def _friction_drift(effects, robot, friction, recording):
    steps = sorted(effects, key=lambda e: e.start)
    period = steps[1].start - steps[0].start
    n = recording.n_joints
    coulomb = _per_joint(steps[0].coulomb, n, "FrictionDelta.coulomb") / period
    viscous = _per_joint(steps[0].viscous, n, "FrictionDelta.viscous") / period
    return _per_joint_values(np.abs(coulomb) + np.abs(viscous), coulomb_rate=coulomb,
                             viscous_rate=viscous)


@dataclass(frozen=True)
class RegisteredEffect:
    """One effect as the simulator injects it and the diagnosis names it.

    Parameters
    ----------
    name : str
        The diagnosis name (``identifier.name``), e.g. ``"payload"``.
    injector : type or callable
        Simulator class (or factory such as :func:`friction_drift`) that
        injects the effect; ``injector(**example)`` builds an injection.
    identifier : type
        The :class:`~sklearn_gpcd.diagnosis.Effect` subclass that names it.
    expected : callable
        ``expected(effects, robot, friction, recording) -> {target:
        {parameter: value}}``: the estimate the identifier should report for
        the injected ``effects`` (list), given the nominal model the
        diagnosis is given (``robot`` with its torque constants, the
        simulator's nominal ``friction``, a :class:`JointFriction`) and the
        simulated ``recording``; ``target`` is the joint (per-joint
        effects), the link (``link_mass``) or None, values in the
        identifier's units (``identifier.units``).
    example : dict
        Keyword arguments of a typical injection on a 6-joint robot, large
        enough for the diagnosis to name it on a short simulated run.

    Examples
    --------
    >>> from sklearn_gpcd.datasets import default_friction, registered_effect
    >>> from sklearn_gpcd.robots import load_robot
    >>> entry = registered_effect("viscous_friction")
    >>> entry.injector.__name__, entry.identifier.__name__
    ('FrictionChange', 'ViscousFrictionEffect')
    >>> robot = load_robot("ur10")
    >>> expected = entry.expected(entry.inject(), robot, default_friction(robot), None)
    >>> {j: round(p["delta_viscous"], 3) for j, p in expected.items()}  # 0.5 * 0.07 * 56 Nm s/rad
    {4: 1.96}
    """

    name: str
    injector: object
    identifier: type
    expected: object = field(repr=False)
    example: dict = field(default_factory=dict, repr=False)

    def inject(self, **overrides):
        """The injection: a list of effects for the simulator (and the recording).

        Parameters
        ----------
        **overrides
            Replace keyword arguments of :attr:`example`.

        Returns
        -------
        effects : list
            Plant effects (``apply(plant)``, for ``effects=`` of the
            simulator) and recording effects (``apply_to_recording``).

        Examples
        --------
        >>> from sklearn_gpcd.datasets import registered_effect
        >>> registered_effect("payload").inject(mass=1.0)[0].mass
        1.0
        """
        made = self.injector(**{**self.example, **overrides})
        return list(made) if isinstance(made, (list, tuple)) else [made]


#: The registered effects, in the diagnosis library's order
#: (:data:`sklearn_gpcd.diagnosis.EFFECTS`).
EFFECT_REGISTRY = (
    RegisteredEffect("coulomb_friction", FrictionDelta, identifiers.CoulombFrictionEffect,
                     _coulomb, {"coulomb": _one_hot(2, 3.0), "static": _one_hot(2, 3.0)}),
    RegisteredEffect("viscous_friction", FrictionChange, identifiers.ViscousFrictionEffect,
                     _viscous, {"viscous": [1.0, 1.0, 1.0, 1.0, 1.5, 1.0]}),
    RegisteredEffect("stribeck_friction", FrictionDelta, identifiers.StribeckFrictionEffect,
                     _stribeck, {"static": _one_hot(2, 4.0)}),
    RegisteredEffect("friction_softening", FrictionDelta, identifiers.FrictionSofteningEffect,
                     _softening, {"static": _one_hot(2, -2.0)}),
    RegisteredEffect("payload", Payload, identifiers.PayloadEffect, _payload,
                     {"mass": 3.0, "com": (0.0, 0.03, 0.06)}),
    RegisteredEffect("torque_constant", TorqueConstantError, identifiers.TorqueConstantEffect,
                     _torque_constant, {"scale": [1.0, 1.0, 1.0, 0.85, 1.0, 1.0]}),
    RegisteredEffect("current_offset", CurrentOffset, identifiers.CurrentOffsetEffect,
                     _per_joint_parameter("offset", "offset"),
                     {"offset": _one_hot(4, 0.15)}),
    RegisteredEffect("rotor_inertia", RotorInertiaChange, identifiers.RotorInertiaEffect,
                     _per_joint_parameter("delta", "delta_rotor_inertia"),
                     {"delta": _one_hot(1, 0.6)}),
    RegisteredEffect("gravity_tilt", GravityTilt, identifiers.GravityTiltEffect,
                     _gravity_tilt, {"roll": 0.02, "pitch": -0.015}),
    RegisteredEffect("time_delay", LoggedCurrentDelay, identifiers.TimeDelayEffect,
                     _time_delay, {"delay": 0.016}),
    RegisteredEffect("joint_spring", JointSpring, identifiers.JointSpringEffect,
                     _joint_spring, {"stiffness": _one_hot(3, 20.0)}),
    RegisteredEffect("friction_drift", friction_drift, identifiers.FrictionDriftEffect,
                     _friction_drift, {"coulomb_rate": _one_hot(0, 0.1), "duration": 40.0}),
    RegisteredEffect("link_mass", LinkMass, identifiers.LinkMassEffect, _link_mass,
                     {"link": 2, "mass": 2.0}),
)

#: Simulator effects no diagnosis effect names, with the reason.
SIMULATOR_ONLY = {
    CurrentDelay: "delays the current command: the logged current still drives the joints, "
                  "so the relation between logged current and motion is unchanged and there "
                  "is nothing to name (see LoggedCurrentDelay for a delayed log)",
}

#: Diagnosis effects the simulator cannot inject, with the reason.
DIAGNOSIS_ONLY = {}


def registered_effect(name):
    """The :class:`RegisteredEffect` of a diagnosis effect name.

    Parameters
    ----------
    name : str
        Diagnosis name, e.g. ``"joint_spring"``.

    Returns
    -------
    entry : RegisteredEffect

    Examples
    --------
    >>> from sklearn_gpcd.datasets import registered_effect
    >>> registered_effect("joint_spring").injector.__name__
    'JointSpring'
    """
    for entry in EFFECT_REGISTRY:
        if entry.name == name:
            return entry
    raise ValueError(f"no registered effect {name!r}; known: "
                     f"{[e.name for e in EFFECT_REGISTRY]}")
