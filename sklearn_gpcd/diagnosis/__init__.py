"""Diagnose what physics a nominal robot model is missing, from recordings.

When a simulation and real recordings differ, :class:`DynamicsDiagnosis`

1. **locates** the mismatch: the current residual by joint, regime
   (rest, creep, moving, reversals, high acceleration), configuration region
   and time (:func:`residual_breakdown`);
2. **names** the missing physics: a library of named effects
   (:mod:`~sklearn_gpcd.diagnosis.effects`: friction terms (Coulomb, viscous,
   Stribeck peak, low-speed softening), rotor inertia,
   payload, link mass, gravity tilt, torque constant, current offset, time
   delay, joint spring, friction drift) competes in a forward selection on
   held-out time blocks (:mod:`~sklearn_gpcd.diagnosis.selection`);
3. **models** it: :class:`DiagnosedModel`, the nominal model plus the fitted
   effects, usable as the GP's parametric mean;
4. **shows** the improvement: held-out nMSE before/after per joint, a plain
   text report, JSON and a figure (:class:`DiagnosisReport`);
5. **asks** for the recording it needs: what the information matrix of the
   candidates says these recordings cannot show
   (:mod:`~sklearn_gpcd.diagnosis.identifiability`) becomes a smooth
   excitation within the joint limits (:mod:`~sklearn_gpcd.diagnosis.plan`).

>>> from sklearn_gpcd.diagnosis import effect_library
>>> len(effect_library())
13
"""

from .align import align_recordings, estimate_lag
from .core import DynamicsDiagnosis, units_problem
from .effects import EFFECTS, Effect, effect_library
from .identifiability import identifiability
from .locate import ResidualBreakdown, residual_breakdown
from .model import DiagnosedModel, FittedEffect, JointFeatures, joint_fit
from .nominal import NominalModel, Signals
from .plan import ExcitationPlan, excitation_plan
from .report import DiagnosisReport
from .selection import Candidate, Step, forward_selection, plausibility_check, \
    separating_excitation

__all__ = [
    "Candidate",
    "DiagnosedModel",
    "DiagnosisReport",
    "DynamicsDiagnosis",
    "EFFECTS",
    "Effect",
    "ExcitationPlan",
    "FittedEffect",
    "JointFeatures",
    "NominalModel",
    "ResidualBreakdown",
    "Signals",
    "Step",
    "align_recordings",
    "effect_library",
    "estimate_lag",
    "excitation_plan",
    "forward_selection",
    "identifiability",
    "joint_fit",
    "plausibility_check",
    "residual_breakdown",
    "separating_excitation",
    "units_problem",
]
