"""Collision detection on the current residual (Dalla Libera et al., Sec. II-III).

* :class:`CollisionDetector` -- scikit-learn outlier detector: a residual
  model (a regressor of the collision-free currents, optionally normalised
  by its predictive std) and one :class:`AlarmRule` per band (filter,
  debounce, :class:`Regimes`, thresholds ``sigma_CD``); a sample is a
  collision when any band alarms;
* :class:`StreamingMonitor` -- the same decisions one sample at a time;
* :func:`calibrate_across_recordings` -- thresholds (and the settings of the
  last rule) chosen across recordings (leave-one-recording-out margin,
  nested false alarms);
* :class:`CollisionThresholdCV` -- ``GridSearchCV`` over labelled recordings
  with the detection scorer of :mod:`sklearn_gpcd.metrics`;
* :class:`TaughtTask` -- a task taught from a few collision-free cycles: a
  reference of the residual in the task's states, one conformal level;
* :func:`stack_currents` -- builds the detector input ``[inputs | currents]``.
"""

from ._regimes import REGIME_NAMES, EventHold
from .calibration import (
    MARGIN_RULES,
    calibrate_across_recordings,
    loro_margin,
    nested_alarms,
    nested_false_alarms,
    regime_excursions,
    regime_levels,
)
from .detector import (
    CollisionDetector,
    SampleTimeWarning,
    default_regressor,
    reads_currents,
    stack_currents,
)
from .model_selection import CollisionThresholdCV
from .rules import THRESHOLD_RULES, AlarmRule, Regimes
from .streaming import BandState, MonitorStatus, StreamingMonitor
from .task import TaskStream, TaughtTask, task_features, task_period

__all__ = [
    "EventHold",
    "TaskStream",
    "TaughtTask",
    "task_features",
    "task_period",
    "AlarmRule",
    "BandState",
    "CollisionDetector",
    "CollisionThresholdCV",
    "MARGIN_RULES",
    "MonitorStatus",
    "REGIME_NAMES",
    "Regimes",
    "SampleTimeWarning",
    "StreamingMonitor",
    "THRESHOLD_RULES",
    "calibrate_across_recordings",
    "default_regressor",
    "loro_margin",
    "nested_alarms",
    "nested_false_alarms",
    "reads_currents",
    "regime_excursions",
    "regime_levels",
    "stack_currents",
]
