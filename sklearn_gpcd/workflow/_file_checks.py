"""What a loaded model or detector file must hold before anything runs on it.

A detector whose threshold was edited to NaN never alarms; one with a
negative scale alarms always; an unstable filter flags every sample as a
sensor fault. The loaders of the model and detector files (:func:`load_checked`
then :func:`check_model_bundle` / :func:`check_detector_bundle`) refuse such a
file with one :class:`~sklearn_gpcd.persistence.MalformedFileError` naming the
field and the command that rebuilds the file:

- every number of the fitted objects is finite (``rest_reference`` may be
  ``inf``: never at rest), every parameter meets its estimator's constraints;
- thresholds, scales, margins, sample time, filter cut-off, kernel length
  scales and constants, the output scale of a GP are positive;
- the low-pass filter is stable: the poles (roots of ``a``) lie inside the
  unit circle, ``|p| < 1``, so the filtered signal stays bounded;
- the shapes agree with the joint count: ``(n_regimes, n_joints)`` for the
  per-regime thresholds, ``n_joints`` for the features;
- the regressor predicts finite values on an input row of zeros;
- no rule holds an option since removed whose thresholds hold only with it
  (:data:`REMOVED_FIELDS`): such a file is calibrated again, never run
  without it.
"""

import math
import numbers

import numpy as np

from ..detection.task import LEARN_LIMIT
from ..persistence import MalformedFileError, load

#: Fields that must be positive wherever they occur in a loaded file.
POSITIVE_FIELDS = ("thresholds_", "scale_", "margin_", "sample_time_", "filter_cutoff",
                   "y_std", "length_scale", "constant_value", "torque_constants", "level_",
                   "feature_scale_", "cutoff", "period_", "rest_band_")
#: Fields that may be ``+inf`` (``rest_reference``: the arm is never at rest).
INFINITE_FIELDS = ("rest_reference",)
#: Deepest nesting of objects walked in a loaded file.
MAX_DEPTH = 64
#: Fields of an alarm rule (or of its regimes) that files written before an
#: option was removed may hold, and the option. Its thresholds were calibrated
#: over it (the motion envelope widened the moving thresholds by a factor of the
#: motion; issue 45 removed it): without it they are not the calibrated ones.
REMOVED_FIELDS = {"envelope_": "gpcd calibrate --motion-envelope",
                  "regimes.motion_envelope": "gpcd calibrate --motion-envelope"}


def load_checked(path, trust_pickle, fix):
    """:func:`sklearn_gpcd.persistence.load`, its refusals saying how to rebuild the file."""
    try:
        return load(path, trust_pickle=trust_pickle)
    except MalformedFileError as exc:
        raise MalformedFileError(path, exc.reason, fix=fix) from None


def check_detector_bundle(bundle, path, fix):
    """Refuse a detector bundle (``kind``, ``detector``, ``features``, ``calibration``)
    that a monitor must not run with; see the module docstring."""
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..detection import CollisionDetector, TaughtTask
    from ..features import CausalFeatures

    task = bundle.get("detector") if isinstance(bundle.get("detector"), TaughtTask) else None
    if task is not None:  # gpcd teach: the task's numbers, then its calibrated detector
        _check_task(task, path, fix)
        bundle = {**bundle, "detector": task.detector}
    _need(isinstance(bundle.get("detector"), CollisionDetector)
          and hasattr(bundle["detector"], "rules_"), path, fix,
          "field detector holds no fitted CollisionDetector")
    _need(isinstance(bundle.get("features"), CausalFeatures)
          and hasattr(bundle["features"], "n_joints_"), path, fix,
          "field features holds no fitted CausalFeatures")
    _need(isinstance(bundle.get("calibration", {}), dict), path, fix,
          "field calibration is not a mapping")
    detector, features = bundle["detector"], bundle["features"]
    _check_values(bundle, path, fix)
    n_joints = detector.n_joints
    _need(isinstance(n_joints, numbers.Integral) and n_joints > 0, path, fix,
          f"field detector.n_joints is {n_joints!r}, not a positive integer")
    _need(features.n_joints_ == n_joints, path, fix,
          f"field features.n_joints_ is {features.n_joints_!r} but the detector has "
          f"{n_joints} joints")
    _need(isinstance(detector.rules_, list) and detector.rules_, path, fix,
          "field detector.rules_ holds no alarm rule")
    for where, part in [("detector", detector)] + [
            (f"detector.rules_[{k}]", rule) for k, rule in enumerate(detector.rules_)]:
        _check_rule_shapes(part, where, n_joints, path, fix)
    for k, rule in enumerate(detector.rules_):
        _check_removed(rule, f"detector.rules_[{k}]", path, fix)
    _check_predicts(detector.regressor_, "detector.regressor_", path, fix)


def _check_task(task, path, fix):
    """A taught task (``gpcd teach``): fitted, its arrays the shapes its joints need."""
    _need(hasattr(task, "coef_") and hasattr(task, "taught_states_"), path, fix,
          "field detector holds a TaughtTask that was never taught")
    _check_values({"detector": task}, path, fix)
    n_joints = getattr(task.detector, "n_joints", None)
    _need(task.n_joints_ == n_joints, path, fix,
          f"field detector.n_joints_ is {task.n_joints_!r} but its detector has "
          f"{n_joints!r} joints")
    for name in ("thresholds_", "bias_", "intercept_"):
        shape = np.shape(getattr(task, name))
        _need(shape == (n_joints,), path, fix,
              f"field detector.{name} has shape {shape}, not ({n_joints},) (joints)")
    _need(task.coef_.shape[1:] == (n_joints,)
          and task.local_residual_.shape[1:] == (n_joints,), path, fix,
          "field detector.coef_ or local_residual_ has no column per joint")
    if hasattr(task, "drift_"):   # learned by partial_fit (gpcd teach --update)
        _need(np.shape(task.drift_) == (2, n_joints), path, fix,
              f"field detector.drift_ has shape {np.shape(task.drift_)}, not (2, {n_joints})")
        _need(bool(np.all(np.abs(task.drift_).sum(axis=0)
                          <= LEARN_LIMIT * task.thresholds_ * (1 + 1e-9))), path, fix,
              "field detector.drift_ exceeds its bound (LEARN_LIMIT of the thresholds)")
        pending = getattr(task, "pending_drift_", None)
        _need(pending is None or (np.shape(pending) == (2, n_joints)
                                  and bool(np.all(np.isfinite(pending)))), path, fix,
              "field detector.pending_drift_ is not a finite (2, joints) array")


def check_model_bundle(bundle, path, fix):
    """Refuse a model bundle (``kind``, ``regressor``, ``features``, ``training``)
    with values the detector must not be built on; see the module docstring."""
    regressor = bundle.get("regressor")
    _need(hasattr(regressor, "predict") and hasattr(regressor, "n_features_in_"), path, fix,
          "field regressor holds no fitted regressor")
    _need(isinstance(bundle.get("training") or {}, dict), path, fix,
          "field training is not a mapping")
    _check_values(bundle, path, fix)
    features = bundle.get("features")
    n_outputs = getattr(regressor, "n_outputs_", None)
    n_joints = getattr(features, "n_joints_", None)
    _need(n_outputs is None or n_joints is None or n_outputs == n_joints, path, fix,
          f"field regressor.n_outputs_ is {n_outputs!r} but the features have "
          f"{n_joints} joints")
    _check_predicts(regressor, "regressor", path, fix)


def _need(condition, path, fix, reason):
    if not condition:
        raise MalformedFileError(path, reason, fix=fix)


def _check_values(bundle, path, fix):
    """Every number finite, every positive field positive, filters stable,
    every estimator's parameters within its constraints."""
    seen, stack = set(), [(bundle, "", 0)]
    while stack:
        obj, where, depth = stack.pop()
        if id(obj) in seen or depth > MAX_DEPTH:
            continue
        seen.add(id(obj))
        field = where.rpartition(".")[2].split("[")[0]
        if isinstance(obj, (bool, np.bool_, str, bytes, type(None))):
            continue
        if isinstance(obj, (numbers.Real, np.ndarray)):
            _check_number(obj, where, field, path, fix)
            continue
        if isinstance(obj, dict):
            stack.extend((v, f"{where}.{k}" if where else str(k), depth + 1)
                         for k, v in obj.items())
        elif isinstance(obj, (list, tuple)):
            if field == "filter_coefficients_":
                _check_filter(obj, where, path, fix)
            stack.extend((v, f"{where}[{k}]", depth + 1) for k, v in enumerate(obj))
        elif type(obj).__module__.split(".")[0] in ("sklearn_gpcd", "sklearn"):
            _check_parameters(obj, where, path, fix)
            stack.extend((v, f"{where}.{k}", depth + 1) for k, v in vars(obj).items()
                         if not k.startswith("__"))


def _check_number(value, where, field, path, fix):
    array = np.asarray(value)
    if array.dtype.kind not in "fiuc" or array.size == 0:
        return
    bad = ~np.isfinite(array)
    if field in INFINITE_FIELDS:
        bad &= ~np.isposinf(array)
    if bad.any():
        first = array.reshape(-1)[np.flatnonzero(bad.reshape(-1))[0]]
        raise MalformedFileError(path, f"field {where} holds {first.item()!r} (must be finite)",
                                 fix=fix)
    if field in POSITIVE_FIELDS and not (array > 0).all():
        raise MalformedFileError(path, f"field {where} holds {array.reshape(-1).min().item()!r} "
                                 "(must be positive)", fix=fix)


def _check_filter(coefficients, where, path, fix):
    """A low-pass filter ``(b, a)``: ``a[0] != 0`` and every pole inside the unit circle."""
    try:
        b, a = (np.asarray(c, dtype=float) for c in coefficients)
    except (TypeError, ValueError):
        raise MalformedFileError(path, f"field {where} is not a filter (b, a)",
                                 fix=fix) from None
    if b.ndim != 1 or a.ndim != 1 or b.shape != a.shape:
        raise MalformedFileError(path, f"field {where} is not a filter (b, a) of two "
                                 f"vectors of one length (shapes {b.shape}, {a.shape})",
                                 fix=fix)
    finite = np.isfinite(b).all() and np.isfinite(a).all()
    if not (finite and a.size and a[0] != 0 and b.size):
        raise MalformedFileError(path, f"field {where} holds no filter (b, a) with "
                                 "finite coefficients and a[0] != 0", fix=fix)
    poles = np.roots(a) if a.size > 1 else np.array([])
    if poles.size and np.abs(poles).max() >= 1.0:
        raise MalformedFileError(path, f"field {where} is an unstable filter (a pole at "
                                 f"|p| = {np.abs(poles).max():.4g} >= 1)", fix=fix)


def _check_parameters(obj, where, path, fix):
    """A scikit-learn estimator's parameters within its ``_parameter_constraints``."""
    if not hasattr(obj, "_parameter_constraints") or not hasattr(obj, "get_params"):
        return
    try:
        obj._validate_params()
    except Exception as exc:  # noqa: BLE001 -- InvalidParameterError, or a broken object
        raise MalformedFileError(path, f"field {where or 'the file'}: "
                                 f"{' '.join(str(exc).split())}", fix=fix) from None


def _check_removed(rule, where, path, fix):
    """Refuse a rule that holds a field of :data:`REMOVED_FIELDS` (set, not None)."""
    for field, option in REMOVED_FIELDS.items():
        owner, _, name = field.rpartition(".")
        value = getattr(getattr(rule, owner, None) if owner else rule, name, None)
        _need(value is None, path, fix,
              f"field {where}.{field} is set: the file was calibrated with {option}, which "
              "was removed, and its thresholds hold only with it")


def _check_rule_shapes(part, where, n_joints, path, fix):
    names = getattr(part, "regime_names_", None)
    _need(isinstance(names, tuple) and names, path, fix,
          f"field {where}.regime_names_ names no regime")
    shapes = [(len(names), n_joints)] + ([(n_joints,)] if len(names) == 1 else [])
    for name in ("thresholds_", "scale_", "margin_"):
        value = getattr(part, name, None)
        shape = np.shape(value) if value is not None else None
        _need(shape in shapes, path, fix,
              f"field {where}.{name} has shape {shape}, not ({len(names)}, {n_joints}) "
              "(regimes, joints)")
    sample_time = getattr(part, "sample_time_", None)
    _need(isinstance(sample_time, numbers.Real) and math.isfinite(sample_time)
          and sample_time > 0, path, fix,
          f"field {where}.sample_time_ is {sample_time!r}, not a positive time")


def _check_predicts(regressor, where, path, fix):
    """The regressor's prediction on a row of zeros: finite, one value per output."""
    n_features = getattr(regressor, "n_features_in_", None)
    _need(isinstance(n_features, numbers.Integral) and n_features > 0, path, fix,
          f"field {where}.n_features_in_ is {n_features!r}, not a positive integer")
    try:
        prediction = np.asarray(regressor.predict(np.zeros((1, n_features))), dtype=float)
    except Exception as exc:  # noqa: BLE001 -- what a damaged regressor raises
        raise MalformedFileError(path, f"field {where} does not predict "
                                 f"({type(exc).__name__}: {' '.join(str(exc).split())[:200]})",
                                 fix=fix) from None
    _need(np.isfinite(prediction).all(), path, fix,
          f"field {where} predicts non-finite values")
