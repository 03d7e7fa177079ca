"""From recordings to a running detector: the functions behind ``gpcd train``
and ``gpcd calibrate``.

* :func:`train_model` fits a model (P_f, SP_S, SP_P or SP_C) on
  collision-free recordings with the causal features of its inputs
  (:mod:`~sklearn_gpcd.workflow.training`); :func:`save_model` /
  :func:`load_model` write and read it;
* :func:`calibrate_detector` chooses the detection thresholds of such a model
  across collision-free recordings (:mod:`~sklearn_gpcd.workflow.calibration`);
  :func:`save_detector` / :func:`load_detector` write and read the detector
  file ``gpcd monitor`` runs.
"""

from .calibration import (
    DETECTOR_KIND,
    DETECTOR_RULE,
    MIN_CALIBRATION_SECONDS,
    MIN_REGIME_SECONDS,
    MOTION_ENVELOPE_SPEED,
    SELECT_GRID,
    CalibratedDetector,
    CalibrationWarning,
    band_label,
    band_settings,
    calibrate_detector,
    calibration_coverage,
    calibration_report,
    check_calibration_options,
    load_detector,
    recording_keys,
    resolve_select,
    save_detector,
    split_recordings,
)
from .training import (
    INPUTS,
    MAX_TRAIN_ROWS,
    MODEL_KIND,
    MODEL_SIGNALS,
    MODELS,
    OPTIMIZERS,
    TRAIN_RULE,
    TrainedModel,
    TrainingSet,
    acceleration_limit,
    load_model,
    save_model,
    train_model,
    training_rows,
    training_set,
)

__all__ = [
    "DETECTOR_KIND", "DETECTOR_RULE", "INPUTS", "MAX_TRAIN_ROWS", "MIN_CALIBRATION_SECONDS",
    "MIN_REGIME_SECONDS", "MOTION_ENVELOPE_SPEED", "MODELS", "MODEL_KIND",
    "MODEL_SIGNALS", "OPTIMIZERS", "SELECT_GRID", "TRAIN_RULE", "CalibratedDetector",
    "CalibrationWarning", "TrainedModel", "TrainingSet", "acceleration_limit", "band_label",
    "band_settings", "calibrate_detector", "calibration_coverage", "calibration_report", "check_calibration_options", "load_detector", "load_model",
    "recording_keys", "resolve_select", "save_detector", "save_model", "split_recordings", "train_model",
    "training_rows", "training_set",
]
