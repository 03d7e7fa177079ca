"""Collision detection on the current residual (Dalla Libera et al., Sec. II-III).

* :class:`CollisionDetector` -- scikit-learn outlier detector: regressor of the
  collision-free currents, monitoring signal, thresholds ``sigma_CD``;
* :class:`StreamingMonitor` -- the same decisions one sample at a time, with
  bounded memory and a compiled single-sample GP prediction;
* :class:`CollisionThresholdCV` -- tunes thresholds, ``sigma_v`` and filter
  settings by grouped cross-validation over labelled recordings;
* regimes (``moving``, ``settling``, ``rest``) with per-regime thresholds and
  the rest re-reference (:mod:`~sklearn_gpcd.detection._regimes`, our
  extension for the history-dependent current at rest);
* :func:`calibrate_across_recordings` -- thresholds (and optionally settle
  time, rest reference, filter) chosen across recordings
  (leave-one-recording-out margin, nested false alarms);
* :class:`MultiBandDetector` / :class:`MultiBandMonitor` -- several bands
  (filter, debounce, thresholds) on one model, alarm when any does (short
  taps need a faster band than pushes);
* :func:`stack_currents` -- builds the detector input ``[inputs | currents]``.
"""

from ._regimes import REGIME_NAMES
from .calibration import (
    MARGIN_RULES,
    SELECTABLE_PARAMS,
    calibrate_across_recordings,
    loro_margin,
    nested_alarms,
    nested_false_alarms,
    regime_excursions,
    regime_levels,
)
from .detector import CollisionDetector, SampleTimeWarning, default_regressor, stack_currents
from .model_selection import CollisionThresholdCV, DetectionRefit, select_candidate
from .multiband import MultiBandDetector, MultiBandMonitor, calibrate_bands_across_recordings
from .streaming import MonitorStatus, StreamingMonitor

__all__ = [
    "CollisionDetector",
    "CollisionThresholdCV",
    "DetectionRefit",
    "MARGIN_RULES",
    "MonitorStatus",
    "MultiBandDetector",
    "MultiBandMonitor",
    "REGIME_NAMES",
    "SELECTABLE_PARAMS",
    "SampleTimeWarning",
    "StreamingMonitor",
    "calibrate_across_recordings",
    "calibrate_bands_across_recordings",
    "default_regressor",
    "loro_margin",
    "nested_alarms",
    "nested_false_alarms",
    "regime_excursions",
    "regime_levels",
    "select_candidate",
    "stack_currents",
]
