"""From recordings to a running detector: the functions behind ``gpcd train``
and ``gpcd calibrate``.

* :func:`train_model` fits a model (P_f, SP_S, SP_P, SP_C or the GP alone)
  on collision-free recordings with the causal features of its inputs
  (:mod:`~sklearn_gpcd.workflow.training`); :func:`save_model` /
  :func:`load_model` write and read it;
* :func:`compare_models` and :func:`check_target_current` choose that model
  (``gpcd train --model auto``, :mod:`~sklearn_gpcd.workflow.model_choice`);
* :func:`calibrate_detector` chooses the detection thresholds of such a model
  across collision-free recordings (:mod:`~sklearn_gpcd.workflow.calibration`),
  never below the model's levels on its left-out training runs
  (:func:`training_levels`);
  :func:`save_detector` / :func:`load_detector` write and read the detector
  file ``gpcd monitor`` runs;
* :func:`teach_task` teaches such a detector one task from a few
  collision-free cycles (``gpcd teach``, :mod:`~sklearn_gpcd.workflow.teaching`).
"""

from .calibration import (
    DETECTOR_KIND,
    DETECTOR_RULE,
    MIN_CALIBRATION_SECONDS,
    MIN_REGIME_SECONDS,
    SELECT_GRID,
    CalibratedDetector,
    CalibrationWarning,
    band_label,
    band_settings,
    calibrate_detector,
    calibration_coverage,
    calibration_report,
    check_calibration_options,
    check_signals,
    fed_signal_check,
    load_detector,
    recording_keys,
    resolve_select,
    save_detector,
    signal_check,
    split_recordings,
    training_levels,
    untaught_detector,
)
from .model_choice import (
    CHOICE_RULE,
    FEEDBACK_LIMIT,
    FEEDBACK_MIN_WINDOWS,
    FEEDBACK_RULE,
    FEEDBACK_SPEED,
    FEEDBACK_WINDOW,
    FOLD_SUPPORT,
    SIGNALS,
    ModelComparison,
    TargetCurrentCheck,
    candidate_models,
    check_target_current,
    choose_model,
    compare_models,
    input_signals,
)
from .teaching import teach_report, teach_task, update_task
from .training import (
    INPUTS,
    MAX_TRAIN_ROWS,
    MODEL_KIND,
    MODEL_SIGNALS,
    MODELS,
    OPTIMIZERS,
    ROBOT_MODELS,
    TRAIN_RULE,
    TrainedModel,
    TrainingSet,
    acceleration_limit,
    load_model,
    save_model,
    train_model,
    training_report,
    training_rows,
    training_set,
)

# The public API: what a Python user of ``gpcd train`` / ``calibrate`` / ``teach``
# calls. The other names imported above are the command line's and the
# monitor's helpers (reports, option checks, rule texts, file kinds): public in
# their modules, not here (tests/test_architecture.py).
__all__ = [
    "MODELS", "MODEL_SIGNALS", "SIGNALS",
    "CalibratedDetector", "CalibrationWarning", "ModelComparison", "TargetCurrentCheck",
    "TrainedModel", "TrainingSet",
    "acceleration_limit", "calibrate_detector", "calibration_coverage", "candidate_models",
    "check_signals", "check_target_current", "choose_model", "compare_models",
    "input_signals", "load_detector", "load_model", "save_detector", "save_model",
    "signal_check", "teach_task", "train_model", "training_levels", "update_task",
    "training_set", "untaught_detector",
]
