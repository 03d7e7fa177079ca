"""Choosing detection thresholds on collision-free recordings: the one function
behind ``gpcd calibrate``.

:func:`calibrate_detector` wraps a model from :func:`~sklearn_gpcd.workflow.train_model`
in a :class:`~sklearn_gpcd.detection.CollisionDetector` that applies
:data:`DETECTOR_RULE` on the model's causal inputs, and chooses its
thresholds across recordings
(:func:`~sklearn_gpcd.detection.calibrate_across_recordings`: one level per
joint and regime, the largest excursion of the recordings, times a margin
chosen by leaving one recording out). It returns the fitted detector with the
model's :class:`~sklearn_gpcd.features.CausalFeatures` and a summary of the
calibration; :func:`save_detector` / :func:`load_detector` write and read
that bundle, the file ``gpcd monitor`` runs.

Options:

* ``select`` chooses the settle time and the rest reference among
  :data:`SELECT_GRID` (by default, unless they are given);
* ``bands`` adds bands (each with its own low-pass and debounce, calibrated
  by the same rule on the same model; a sample is a collision when any band
  alarms); ``band_candidates`` adds one more band whose settings are chosen
  among the candidates across the recordings;
* ``braking`` adds the braking regime; ``split`` cuts long logs into pieces
  that are left out in turn like recordings.
"""

import warnings
from collections import Counter
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..io import RecordingWarning, SignalCheck, signal_ranges

__all__ = ["DETECTOR_KIND", "DETECTOR_RULE", "MIN_CALIBRATION_SECONDS", "MIN_REGIME_SECONDS",
           "SELECT_GRID", "CalibratedDetector", "CalibrationWarning",
           "band_label", "band_settings", "calibrate_detector", "calibration_coverage",
           "calibration_report", "check_calibration_options", "check_signals",
           "fed_signal_check", "resolve_select",
           "load_detector", "recording_keys", "save_detector", "signal_check",
           "split_recordings", "training_levels", "untaught_detector"]

#: What a detector file holds (a dict saved with :func:`sklearn_gpcd.save`).
DETECTOR_KIND = "gpcd-detector"
#: The alarm rule :func:`calibrate_detector` applies
#: (:class:`~sklearn_gpcd.detection.AlarmRule` parameters): a 2 Hz causal
#: low-pass, a 5-sample debounce, one threshold per joint (and regime) with no
#: false alarm on the calibration recordings. The detector takes the sample
#: time of the data.
DETECTOR_RULE = dict(threshold="per_joint", false_alarm_rate=0.0, filter_cutoff=2.0,
                     min_duration=5)
#: The settings ``select=True`` chooses among (the rule's regimes): settle
#: time [s] x rest reference time constant [s].
SELECT_GRID = {"regimes__settle_time": [0.5, 1.0, 2.0, 3.0],
               "regimes__rest_reference": [None, 2.0, 5.0]}
#: Rest reference time constant [s] when none is given.
DEFAULT_REST_REFERENCE = 5.0
#: A good calibration has a leave-one-recording-out margin of at most this and
#: no expected false alarm; a summary that falls short warns
#: (:class:`CalibrationWarning`): the levels of the others do not cover some
#: recording, so the next day's data may not be covered either.
GOOD_MARGIN = 2.0
#: Calibration data shorter than this [s] warns (:class:`CalibrationWarning`).
MIN_CALIBRATION_SECONDS = 120.0
#: A regime with less calibration data than this [s] warns (moving, rest).
MIN_REGIME_SECONDS = 10.0
#: A regime with less calibration data than this [s] in all has no thresholds
#: of its own: it takes, joint by joint, the largest threshold of the regimes
#: with data (the detector's rule for a regime absent from the data). A few
#: samples would otherwise set thresholds 10-100x tighter than any seen motion.
MIN_REGIME_DATA_SECONDS = 1.0
#: A transient regime (settling, braking) seen fewer times than this warns.
MIN_REGIME_EPISODES = 5
#: The regimes that last a fixed time after an event: counted in episodes.
_TRANSIENT_REGIMES = ("settling", "braking")


class CalibrationWarning(UserWarning):
    """The calibration data cannot support the thresholds it set.

    Raised by :func:`calibrate_detector` (printed by ``gpcd calibrate``) when
    the data is short (:data:`MIN_CALIBRATION_SECONDS`), or a regime of the
    arm (moving, settling, rest, braking) has little time
    (:data:`MIN_REGIME_SECONDS`), none, or comes from one recording alone:
    leave-one-recording-out then cannot tell how another recording would
    differ; and when the summary falls short of a good calibration (a
    leave-one-recording-out margin above 2, or expected false alarms). The
    message gives the numbers and what to record.

    Examples
    --------
    >>> import warnings
    >>> from sklearn_gpcd.workflow import CalibrationWarning
    >>> issubclass(CalibrationWarning, UserWarning)
    True
    """


class CalibratedDetector(NamedTuple):
    """A detector with thresholds chosen across recordings, and how they were chosen.

    Attributes
    ----------
    detector : CollisionDetector
        Fitted on a frozen model; one alarm rule per band (several with
        ``bands`` or ``band_candidates``).
    features : CausalFeatures
        Computes the detector's inputs from raw samples (the model's own).
    calibration : dict
        The summary ``gpcd calibrate`` prints: recordings, hours, margin,
        thresholds (A, and Nm with torque constants), nested false alarms,
        settings, and per band the same.

    Examples
    --------
    >>> detector, features, calibration = CalibratedDetector(None, None, {})
    >>> calibration
    {}
    """

    detector: object
    features: object
    calibration: dict


def untaught_detector(detector):
    """The calibrated detector under a taught one (itself when untaught).

    Parameters
    ----------
    detector : CollisionDetector or TaughtTask

    Returns
    -------
    detector : CollisionDetector

    Examples
    --------
    >>> untaught_detector("a detector")
    'a detector'
    """
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..detection import TaughtTask

    return detector.detector if isinstance(detector, TaughtTask) else detector


def recording_keys(recordings):
    """Unique names of the recordings: their file names, numbered on a clash.

    Parameters
    ----------
    recordings : list of Recording

    Returns
    -------
    keys : list of str

    Examples
    --------
    >>> from types import SimpleNamespace as R
    >>> recording_keys([R(name="a/x.csv"), R(name="b/x.csv"), R(name=None)])
    ['x.csv', 'x.csv (2)', '#2']
    """
    keys = []
    for i, rec in enumerate(recordings):
        name = Path(str(rec.name or f"#{i}")).name
        keys.append(name if name not in keys else f"{name} ({i + 1})")
    return keys


def split_recordings(keys, recordings, seconds):
    """Each recording cut into pieces of at least ``seconds``, keyed ``"name#i"``.

    A recording shorter than ``2 * seconds`` stays whole. The pieces of a
    recording have about equal numbers of samples (``floor(duration / seconds)``
    of them); filters and debounce restart at each piece, as at the start of
    a recording.

    Parameters
    ----------
    keys : list of str
        Names of the recordings.
    recordings : list of Recording
    seconds : float
        Shortest piece [s].

    Returns
    -------
    keys, pieces : list of str, list of Recording

    Raises
    ------
    ValueError
        When the pieces are fewer than 2.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> rec = Recording(time=np.arange(1000) * 0.01, q=np.zeros((1000, 1)),
    ...                 qd=np.zeros((1000, 1)), current=np.zeros((1000, 1)))
    >>> keys, pieces = split_recordings(["free.csv"], [rec], 3.0)
    >>> keys, [p.n_samples for p in pieces]
    (['free.csv#1', 'free.csv#2', 'free.csv#3'], [333, 334, 333])
    """
    out_keys, pieces = [], []
    for key, rec in zip(keys, recordings):
        for piece_key, (start, stop) in piece_bounds(key, rec.n_samples, rec.duration, seconds):
            out_keys.append(piece_key)
            pieces.append(rec if piece_key == key else rec.slice(start, stop))
    _check_pieces(len(pieces), max(rec.duration for rec in recordings), seconds)
    return out_keys, pieces


def piece_bounds(key, n_samples, duration, seconds):
    """``[(key, (start, stop)), ...]``: the pieces :func:`split_recordings` cuts
    one recording into (its ``key`` alone when it stays whole).

    Examples
    --------
    >>> piece_bounds("a.csv", 1000, 9.99, 3.0)
    [('a.csv#1', (0, 333)), ('a.csv#2', (333, 667)), ('a.csv#3', (667, 1000))]
    """
    n_pieces = int(duration // seconds) if duration >= 2 * seconds else 1
    if n_pieces == 1:
        return [(key, (0, n_samples))]
    bounds = np.linspace(0, n_samples, n_pieces + 1).round().astype(int).tolist()
    return [(f"{key}#{i}", (start, stop))
            for i, (start, stop) in enumerate(zip(bounds[:-1], bounds[1:]), start=1)]


def _check_pieces(n_pieces, longest, seconds):
    if n_pieces < 2:
        raise ValueError(f"--split {seconds:g} leaves {n_pieces} piece: the longest "
                         f"recording lasts {longest:.1f} s; use a split of at most "
                         f"{longest / 2:.1f} s")


def band_settings(rule):
    """What sets a band apart: its low-pass filter and debounce.

    Parameters
    ----------
    rule : AlarmRule

    Returns
    -------
    settings : dict
        ``filter_cutoff_hz``, ``filter_order``, ``debounce_samples``.

    Examples
    --------
    >>> from sklearn_gpcd.detection import AlarmRule
    >>> band_settings(AlarmRule(filter_cutoff=10.0, min_duration=2))
    {'filter_cutoff_hz': 10.0, 'filter_order': 1, 'debounce_samples': 2}
    """
    return {"filter_cutoff_hz": rule.filter_cutoff, "filter_order": rule.filter_order,
            "debounce_samples": rule.min_duration}


def band_label(settings):
    """A band's settings in words, from :func:`band_settings`.

    Parameters
    ----------
    settings : dict
        ``filter_cutoff_hz``, ``filter_order``, ``debounce_samples``.

    Returns
    -------
    label : str

    Examples
    --------
    >>> band_label({"filter_cutoff_hz": 10.0, "filter_order": 1, "debounce_samples": 2})
    '10 Hz, order 1, debounce 2'
    """
    cutoff = settings["filter_cutoff_hz"]
    low_pass = "no low-pass" if cutoff is None else (f"{cutoff:g} Hz, order "
                                                     f"{settings['filter_order']}")
    return f"{low_pass}, debounce {settings['debounce_samples']}"


def calibrate_detector(trained, recordings, *, keys=None, regimes=True, rest_reference=None,
                       settle_time=None, select="auto", bands=(), band_candidates=(),
                       braking=None, split=None,
                       robot=None, progress=None, accept=()):
    """Thresholds for a trained model, chosen across collision-free recordings.

    The detector applies :data:`DETECTOR_RULE` to the model's causal inputs
    (its own :class:`~sklearn_gpcd.features.CausalFeatures`); each level is
    the largest excursion of the recordings in that joint and regime, times
    one margin chosen by leaving one recording out
    (:func:`~sklearn_gpcd.detection.calibrate_across_recordings`). The
    expected false alarms come from the nested version: each recording is
    scored with the margin and levels chosen without it. Each regime's
    thresholds are at least the model's level on its left-out training runs
    when ``gpcd train --model auto`` measured it (:func:`training_levels`):
    motions, stops and rests the calibration recordings do not cover meet
    the model's error there, not theirs. The nested false alarms are
    counted at those floored thresholds.

    Parameters
    ----------
    trained : TrainedModel
        What :func:`~sklearn_gpcd.workflow.train_model` (or
        :func:`~sklearn_gpcd.workflow.load_model`) returned.
    recordings : list of Recording
        Collision-free recordings, at least 2 (or one long one with ``split``).
    keys : list of str, default=None
        Their names in the summary (default: :func:`recording_keys`).
    regimes : bool, default=True
        One threshold per joint and per regime of the arm (moving, settling,
        rest); False: one per joint, no rest reference.
    rest_reference : float or None, default=None
        Time constant [s] of the rest re-reference; None takes 5 s, 0 none.
    settle_time : float or None, default=None
        Seconds the arm must be still after a motion before it is at rest
        (None: 0.5 s of :data:`DETECTOR_RULE`).
    select : bool or "auto", default="auto"
        Choose the settle time and the rest reference among
        :data:`SELECT_GRID` across the recordings. "auto" chooses them unless
        ``settle_time``, ``rest_reference``, ``bands``, ``band_candidates``
        or ``regimes=False`` fix the settings (:func:`resolve_select`).
    bands : sequence of dict, default=()
        Extra bands, each ``{"filter_cutoff": Hz, "filter_order": 1 or 2,
        "min_duration": samples}``.
    band_candidates : sequence of dict, default=()
        Candidates (same keys) for one more band chosen across the recordings.
    braking : None, "model" or float, default=None
        The braking regime above this acceleration [rad/s^2]; "model" takes
        the largest one the model was trained on.
    split : float or None, default=None
        Cut every recording into pieces of at least this many seconds, each
        left out in turn (:func:`split_recordings`).
    robot : Robot or None, default=None
        Named in the summary; its ``torque_constants`` (Nm/A) give the
        thresholds in Nm.
    progress : callable or None, default=None
        ``progress(label, total)`` returning an object with ``update()``.
    accept : collection of str, default=()
        Kinds of implausible signal to let through in the recordings
        (:func:`check_signals`: the ranges of the training and calibration
        data, the robot's limits, the model's prediction; stored in the
        summary's ``signal_ranges`` for ``gpcd monitor``).

    Returns
    -------
    calibrated : CalibratedDetector

    Raises
    ------
    ValueError
        Conflicting options, too few recordings, recordings the model cannot
        read.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> from sklearn_gpcd.workflow import calibrate_detector, train_model
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(600) * 0.01
    >>> def rec(phase):
    ...     q = np.sin(t + phase)[:, None]
    ...     i_c = 2 * q
    ...     return Recording(time=t, q=q, qd=np.cos(t + phase)[:, None],
    ...                      current=i_c + 0.05 * rng.normal(size=q.shape), target_current=i_c)
    >>> trained = train_model([rec(0.0)], model="sp_c", n_support=50)
    >>> calibrated = calibrate_detector(trained, [rec(1.0), rec(2.0), rec(3.0)])
    >>> calibrated.calibration["regimes"]
    ['moving', 'settling', 'rest', 'settling after 0.25 s']
    >>> np.shape(calibrated.detector.thresholds_)
    (4, 1)
    """
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..detection import stack_currents

    keys = recording_keys(recordings) if keys is None else list(keys)
    n_files = len(recordings)
    _check_files(n_files, split, {rec.units for rec in recordings})
    _check_model(trained)
    features = trained.features
    check_recordings(recordings, "the model", n_joints=features.n_joints_,
                     units=trained.training.get("units"))
    if split is not None:
        keys, recordings = split_recordings(keys, recordings, split)
    bar = progress("causal inputs", len(recordings)) if progress is not None else None
    blocks, times = {}, {}
    for key, rec in zip(keys, recordings):
        blocks[key] = stack_currents(features.transform(rec), rec.current)
        times[key] = rec.time
        if bar is not None:
            bar.update()
    ranges = signal_ranges(recordings, trained.training.get("signal_ranges"))
    return _calibrate_blocks(
        trained, blocks, times, dict(zip(keys, recordings)), ranges,
        units=recordings[0].units, n_files=n_files,
        split=split, robot=robot, accept=accept, options=dict(
            regimes=regimes, rest_reference=rest_reference, settle_time=settle_time,
            select=select, bands=bands, band_candidates=band_candidates, braking=braking))


def _check_files(n_files, split, units):
    if n_files < 2 and split is None:
        raise ValueError("thresholds are chosen across recordings (leave-one-recording-out): "
                         f"give at least 2 collision-free recordings, got {n_files} "
                         "(or cut a long one into pieces with --split SECONDS)")
    if len(units) > 1:
        raise ValueError(f"the calibration recordings log currents in {' and '.join(units)}; "
                         "give recordings in one unit (the column map's \"units\")")


def _check_model(trained):
    if trained.features is None:
        raise ValueError("the model file holds no input features (written by an earlier "
                         "gpcd train): train the model again with gpcd train")
    _check_model_inputs(trained.regressor, trained.features)


def _calibrate_blocks(trained, blocks, times, pieces, ranges, *, units, n_files, split, robot,
                      accept, options, folder=None):
    """:func:`calibrate_detector` from the detector inputs ``blocks`` of each
    recording (or piece), their ``times``, the recordings themselves
    (``pieces``, a mapping: read again for the signal checks) and their
    signal ``ranges``, the ``units`` of their currents; ``folder`` streams (see
    :func:`~sklearn_gpcd.detection.calibrate_across_recordings`)."""
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from sklearn.base import clone
    from sklearn.frozen import FrozenEstimator

    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..detection import AlarmRule, CollisionDetector, Regimes, calibrate_across_recordings

    regimes, rest_reference, settle_time, braking = (
        options[k] for k in ("regimes", "rest_reference", "settle_time", "braking"))
    bands = list(options["bands"] or ())
    band_candidates = list(options["band_candidates"] or ())
    select = resolve_select(options["select"], regimes=regimes, rest_reference=rest_reference,
                            settle_time=settle_time, bands=bands,
                            band_candidates=band_candidates)
    check_calibration_options(regimes=regimes, rest_reference=rest_reference,
                              settle_time=settle_time, select=select, bands=bands,
                              band_candidates=band_candidates, braking=braking)
    model, features, keys = trained.regressor, trained.features, list(blocks)
    tau = DEFAULT_REST_REFERENCE if rest_reference is None else rest_reference
    regime_params = {} if settle_time is None else {"settle_time": settle_time}
    main = AlarmRule(**DETECTOR_RULE, regimes=Regimes(
        rest_reference=tau if tau > 0 else None,
        brake_limit=_brake_limit(braking, trained.training), **regime_params)
        if regimes else None)
    # the chosen band is the last; its settings stand in until the grid's replace them
    rules = [main] + [clone(main).set_params(**band) for band in [*bands, *band_candidates[:1]]]
    grid = SELECT_GRID if select else None
    if band_candidates:
        grid = [{k: [v] for k, v in c.items()} for c in band_candidates]
    # the model's sigma_v (train_model records it) sets the regimes: the frozen model keeps
    # its own gates; None (a model file without it) means the regimes' default
    template = CollisionDetector(FrozenEstimator(model), n_joints=features.n_joints_,
                                 sample_time="auto", rules=rules,
                                 sigma_v=trained.training.get("sigma_v"))
    result = calibrate_across_recordings(
        template, blocks, times, param_grid=grid, folder=folder,
        floor=lambda rule: _training_floor(trained.training, rule, features.n_joints_))
    several = bool(bands or band_candidates)
    coverage = calibration_coverage(result, times, split=split is not None)
    without_data, one_log = _fill_regimes_without_data(result.detector, coverage)
    training_floor = _raise_to_floors(result.detector, [band.floor for band in result.bands])
    summary = _summary(result, trained, features, robot, keys=keys, split=split,
                       n_files=n_files, select=select, several=several,
                       chosen_band=bool(band_candidates))
    summary["regimes_without_data"] = without_data
    summary["stages_from_one_log"] = one_log
    summary["training_floor_A"] = training_floor
    summary["units"] = units  # of thresholds_A: "Nm" for torque logs
    if summary["units"] != "A":
        summary.pop("thresholds_Nm", None)  # torque constants convert A, not Nm
        for entry in summary.get("bands", []):
            entry.pop("thresholds_Nm", None)
    summary["coverage"] = coverage
    summary["signal_ranges"] = ranges
    _warn_coverage(summary)
    _warn_quality(summary)
    calibrated = CalibratedDetector(result.detector, features, summary)
    for key in keys:  # signals the thresholds were set on
        check_signals(pieces[key], calibrated, accept=accept, name=key)
    return calibrated


def _fill_regimes_without_data(detector, coverage):
    """Give the regimes with less than :data:`MIN_REGIME_DATA_SECONDS` of data, in
    every band of the fitted ``detector``, the largest threshold of the regimes
    with data (joint by joint), and a later settling stage without data, or
    seen in one log alone, that of the stage before it (the ring fades: no
    tighter band than the stage before where no left-out log checks it);
    returns ``(names without data, stages from one log)``."""
    names = list(coverage)
    empty = np.array([coverage[name]["seconds"] < MIN_REGIME_DATA_SECONDS for name in names])
    stages = detector.rules_[0].settling_rows()  # the coverage's regimes, in time order
    one_log = [k for k in stages[1:] if not empty[k] and coverage[names[k]]["logs"] < 2]
    fill = empty.any() and not empty.all()
    if not fill and not one_log:
        return [], []
    def fill_rows(rule, scale):
        if fill:
            scale[empty] = scale[~empty].max(axis=0)
        for before, k in zip(stages[:-1], stages[1:]):
            if (fill and empty[k]) or k in one_log:
                scale[k] = scale[before]

    _edit_scales(detector, detector.rules_, fill_rows)
    return ([name for name, e in zip(names, empty) if e] if fill else [],
            [names[k] for k in one_log])


def training_levels(training, rule=None):
    """Per regime and joint, the thresholds the alarm rule set across the left-out training runs.

    ``gpcd train --model auto`` fits each candidate model without one training
    recording and runs :data:`DETECTOR_RULE` on the recording it left out
    (:data:`~sklearn_gpcd.workflow.model_choice.CHOICE_RULE`): the chosen
    model's thresholds there are out-of-fold evidence of how the model errs
    on motions, stops and rests it was not fitted on, over the diverse motion
    of the training runs. Per regime ``g`` and joint ``j`` (:math:`L` the
    largest excursion, :math:`\\mu` the leave-one-recording-out margin):

    .. math:: T^{\\mathrm{train}}_{gj} = \\mu\\, L_{gj}

    * **moving** takes the time-weighted geometric mean over the regimes,
      :math:`\\exp \\sum_g \\frac{n_g}{n} \\log T^{\\mathrm{train}}_{gj}`
      (the score the model was chosen on): the moving row alone, the largest,
      delayed detection on MuJoCo seed 4529 for no fewer alarms.
    * **settling stages and rest** take their own row, where at least two
      left-out runs held that regime for :data:`MIN_REGIME_DATA_SECONDS` in
      all (one run alone has no left-out check).
    * For another ``rule`` (another settle time), a settling stage or rest
      takes the largest of the training rows whose windows after the stop
      overlap its own (:meth:`~sklearn_gpcd.detection.AlarmRule.since_stop`):
      its threshold covers that whole window.

    The fold models are smaller than the final one (200 support rows per
    joint), so the levels lean high: they are floors for what the
    calibration did not cover, never thresholds of their own.

    Parameters
    ----------
    training : dict
        A model's training record (``TrainedModel.training``).
    rule : AlarmRule or None, default=None
        A prepared rule (``regime_names_``) whose regimes to give levels
        for; None: the training rule's own.

    Returns
    -------
    levels : dict of str -> ndarray of shape (n_joints,)
        By regime name; empty when the model was not chosen across its
        training runs (an explicit ``--model``, or a model file from an
        earlier ``gpcd train``), and moving alone for a model file from
        before the regimes were recorded.

    Examples
    --------
    >>> from sklearn_gpcd.detection import AlarmRule, Regimes
    >>> from sklearn_gpcd.workflow import training_levels
    >>> choice = {"best": "sp_c", "models": ["p_f", "sp_c"],
    ...           "thresholds": [[0.9, 0.5], [0.6, 0.3]],
    ...           "regimes": ["moving", "settling", "rest"],
    ...           "regime_windows": [None, [0.0, 0.5], [0.5, None]],
    ...           "regime_thresholds": [[[1, 1], [1, 1], [1, 1]],
    ...                                 [[0.7, 0.4], [0.8, 0.5], [0.2, 0.1]]],
    ...           "regime_seconds": [40.0, 6.0, 3.0], "regime_logs": [4, 4, 1]}
    >>> {k: v.tolist() for k, v in training_levels({"model_choice": choice}).items()}
    {'moving': [0.6, 0.3], 'settling': [0.8, 0.5]}
    >>> rule = AlarmRule(regimes=Regimes(settle_time=1.0)).prepare(0.01)
    >>> sorted(training_levels({"model_choice": choice}, rule))
    ['moving', 'settling', 'settling after 0.25 s']
    >>> training_levels({"model": "p_f"})
    {}
    """
    choice = (training or {}).get("model_choice") or {}
    if choice.get("thresholds") is None or choice.get("best") not in choice.get("models", ()):
        return {}
    best = choice["models"].index(choice["best"])
    moving = np.asarray(choice["thresholds"][best], float)
    rows = []  # (window, level) of the stops' regimes with left-out evidence
    if choice.get("regime_windows") is not None:
        for window, level, seconds, logs in zip(
                choice["regime_windows"], choice["regime_thresholds"][best],
                choice["regime_seconds"], choice["regime_logs"]):
            if window is not None and logs >= 2 and seconds >= MIN_REGIME_DATA_SECONDS:
                rows.append((_window(window), np.asarray(level, float)))
    if rule is None:
        names = choice.get("regimes") or ["moving"]
        windows = [_window(w) for w in (choice.get("regime_windows") or [None] * len(names))]
    else:
        names, windows = list(rule.regime_names_), rule.since_stop()
    levels = {}
    for name, window in zip(names, windows):
        if name == "moving":
            levels[name] = moving
        elif window is not None:
            overlap = [level for (start, end), level in rows
                       if start < window[1] and window[0] < end]
            if overlap:
                levels[name] = np.max(overlap, axis=0)
    return {name: level for name, level in levels.items()
            if np.all(np.isfinite(level)) and np.all(level > 0)}


def _window(window):
    """A stored window after the stop (``[start, end]``, ``end`` None for rest) as
    :meth:`~sklearn_gpcd.detection.AlarmRule.since_stop` gives it."""
    return None if window is None else (window[0], np.inf if window[1] is None else window[1])


def _training_floor(training, rule, n_joints):
    """The smallest thresholds (regimes x joints, A; 0 where none) of a prepared
    band ``rule``: :func:`training_levels` for its regimes when the band has
    :data:`DETECTOR_RULE`'s filter and debounce, the rule the levels were set
    with; None when nothing is floored.

    The calibration logs set the thresholds from the motions, stops and
    rests they hold; another motion (another pose, another program) meets
    the model's error where it was not calibrated: other loads, other
    stops. The training runs' out-of-fold levels are that error over
    diverse motion, so each row is ``max(calibrated, training level)``: the
    calibration may widen it, never tighten it below what the model showed
    on runs it was not fitted on."""
    main = {k: DETECTOR_RULE[k] for k in ("filter_cutoff", "min_duration")}
    if rule.regimes is None or any(getattr(rule, k) != v for k, v in main.items()):
        return None  # one threshold per joint (--no-regimes), or another band
    levels = training_levels(training, rule)
    if not levels or any(len(level) != n_joints for level in levels.values()):
        return None
    names = list(rule.regime_names_)
    floor = np.zeros((len(names), n_joints))
    for name, level in levels.items():
        floor[names.index(name)] = level
    return floor


def _raise_to_floors(detector, floors):
    """Raise each band of the fitted ``detector`` to its floor (``floors``, one
    per band or None: the :func:`_training_floor` the nested count used, from
    :func:`~sklearn_gpcd.detection.calibrate_across_recordings`' bands),
    joint by joint; returns the levels applied to the first band
    (``{regime: list}``, A; empty when none)."""
    floor_of = {id(band): floor for band, floor in zip(detector.rules_, floors)
                if floor is not None and band.offset_ != 0}
    if not floor_of:
        return {}

    def raise_rows(band, scale):
        np.maximum(scale, floor_of[id(band)] / -band.offset_, out=scale)

    _edit_scales(detector, [band for band in detector.rules_ if id(band) in floor_of],
                 raise_rows)
    first = floor_of.get(id(detector.rules_[0]))
    names = detector.rules_[0].regime_names_
    return {} if first is None else {names[k]: [float(v) for v in row]
                                     for k, row in enumerate(first) if row.any()}


def _edit_scales(detector, rules, edit):
    """``edit(rule, scale)`` a copy of each of ``rules``' scales (regimes x joints)
    in place; store it with the thresholds it gives (``thresholds_ = gamma *
    scale_``, ``gamma = -offset_``) and keep the detector's in step with its
    first rule."""
    for rule in rules:
        scale = np.array(np.atleast_2d(rule.scale_), dtype=float, copy=True)
        edit(rule, scale)
        rule.scale_, rule.thresholds_ = scale, -rule.offset_ * scale
    detector.scale_, detector.thresholds_ = (detector.rules_[0].scale_,
                                             detector.rules_[0].thresholds_)


def calibration_coverage(result, times, split=False):
    """How much calibration data each regime of the arm had, and from how many recordings.

    Parameters
    ----------
    result : Bunch
        What :func:`~sklearn_gpcd.detection.calibrate_across_recordings`
        returned (its first band's regimes are read).
    times : dict of str -> ndarray
        Time stamps [s] of each recording.
    split : bool, default=False
        The recordings are pieces ``"name#i"`` of longer logs: count the logs.

    Returns
    -------
    coverage : dict of str -> dict
        Per regime name: ``seconds``, ``episodes`` (how many times the arm
        entered it), ``recordings`` (how many logs have at least 1 s of it),
        ``logs`` (how many have any of it) and ``largest`` (the log with the
        most of it) with its ``largest_share`` of the regime's time. ``"settling"`` counts the
        whole settling time, its later stages (``"settling after 0.25 s"``,
        ...) included; each stage also has its own entry.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.utils import Bunch
    >>> t = np.arange(300) * 0.1
    >>> series = {"a": (None, np.repeat([0, 2], 150), None),
    ...           "b": (None, np.full(300, 2), None)}
    >>> cov = calibration_coverage(Bunch(series=series, regime_names=("moving", "settling",
    ...                                                                 "rest")), {"a": t, "b": t})
    >>> cov["moving"]["seconds"], cov["moving"]["recordings"], cov["settling"]["seconds"]
    (15.0, 1, 0.0)
    """
    n_codes = len(result.regime_names)
    per_log, episodes = {}, np.zeros(n_codes, dtype=int)
    for key, (_, regime, _) in result.series.items():
        t = np.asarray(times[key], dtype=float)
        step = np.diff(t, append=t[-1] + np.median(np.diff(t))) if len(t) > 1 else np.ones(1)
        log = key.rsplit("#", 1)[0] if split else key
        seconds = np.bincount(regime, weights=step, minlength=n_codes)
        per_log[log] = per_log.get(log, 0.0) + seconds
        entered = np.flatnonzero(np.diff(regime, prepend=-1) != 0)
        episodes += np.bincount(regime[entered], minlength=n_codes)
    # "settling" covers its stages ("settling after 0.25 s", ...): every stop
    # enters it, and its data is that of the whole settling time
    family = [k for k, name in enumerate(result.regime_names) if name.startswith("settling")]
    coverage = {}
    for code, name in enumerate(result.regime_names):
        codes = family if name == "settling" else [code]
        seconds = {log: float(v[codes].sum()) for log, v in per_log.items()}
        total = sum(seconds.values())
        largest = max(seconds, key=seconds.get)
        coverage[name] = {"seconds": round(total, 3), "episodes": int(episodes[code]),
                          "recordings": sum(v >= 1.0 for v in seconds.values()),
                          "logs": sum(v > 0.0 for v in seconds.values()),
                          "largest": largest,
                          "largest_share": seconds[largest] / total if total > 0 else 0.0}
    return coverage


def _warn_coverage(summary):
    """:class:`CalibrationWarning` for short data and thin regimes (with the numbers)."""
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..metrics import rate_upper_bound

    seconds = summary["hours"] * 3600.0
    if seconds < MIN_CALIBRATION_SECONDS:
        count = summary["n_false_alarms_nested"]
        bound = rate_upper_bound(count, summary["hours"])
        warnings.warn(
            f"the calibration data lasts {seconds:.0f} s: with {count} false alarm(s) seen, "
            f"it bounds the false-alarm rate only by {bound:.0f} per hour (95 %); record at "
            f"least {MIN_CALIBRATION_SECONDS / 60:g} min of collision-free motion, in several "
            "recordings, and run gpcd calibrate on them", CalibrationWarning, stacklevel=4)
    several = summary["n_files"] > 1
    for name, cov in summary["coverage"].items():
        if name.startswith("settling after"):  # a stage: counted in "settling"
            continue
        if name in summary.get("regimes_without_data", ()) or cov["seconds"] == 0.0:
            problem = (f"no calibration data in the {name} regime ({cov['seconds']:.2f} s, "
                       f"less than {MIN_REGIME_DATA_SECONDS:g} s): its thresholds are, joint "
                       "by joint, the largest of the regimes with data")
        elif cov["recordings"] <= 1 and several:
            problem = (f"one recording alone ({cov['largest']}) set every {name} threshold "
                       f"({cov['seconds']:.0f} s): leaving it out, no other recording shows "
                       f"how {name} data varies")
        elif name in _TRANSIENT_REGIMES and cov["episodes"] < MIN_REGIME_EPISODES:
            problem = (f"the arm was {name} only {cov['episodes']} time(s) in the calibration "
                       f"data (fewer than {MIN_REGIME_EPISODES})")
        elif name not in _TRANSIENT_REGIMES and cov["seconds"] < MIN_REGIME_SECONDS:
            problem = (f"only {cov['seconds']:.1f} s of calibration data in the {name} regime "
                       f"(fewer than {MIN_REGIME_SECONDS:g} s)")
        else:
            continue
        warnings.warn(f"{problem}; add collision-free recordings with {_REGIME_ADVICE[name]} "
                      "to gpcd calibrate", CalibrationWarning, stacklevel=4)


#: Said of the nested false alarms when training floors were applied.
_AT_FLOORS = ", each threshold at least its training floor"


def _warn_quality(summary):
    """:class:`CalibrationWarning` when the summary falls short of a good
    calibration: a margin above :data:`GOOD_MARGIN` or expected false alarms."""
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..metrics import rate_upper_bound

    margin, count = summary["margin"], summary["n_false_alarms_nested"]
    alarms = summary["false_alarms_per_hour"] is not None and count > 0
    if margin <= GOOD_MARGIN and not alarms:
        return
    figures = [f"margin {margin:.2f}"]
    if alarms:
        bound = rate_upper_bound(count, summary["hours"])
        where = sorted(k for k, onsets in summary["nested_onsets_s"].items() if onsets)
        figures.append(f"{summary['false_alarms_per_hour']:.0f} expected false alarms per "
                       f"hour (95 % upper bound {bound:.0f}; on left-out {', '.join(where)})")
    warnings.warn(
        f"the calibration falls short of a good one (margin at most {GOOD_MARGIN:g}, no "
        f"expected false alarm): {', '.join(figures)}; a recording unlike the others sets "
        "them: add collision-free recordings of the motions the robot will make, or train "
        "the model on more varied motion with gpcd train, and run gpcd calibrate again",
        CalibrationWarning, stacklevel=4)


#: What to record for each regime, in the coverage warnings.
_REGIME_ADVICE = {
    "moving": "the motions the robot will make (its own task, or joint-by-joint moves)",
    "settling": "stops after motions (point-to-point moves with pauses)",
    "rest": "the arm standing still after motions, in several poses",
    "braking": "hard stops (or drop --braking)",
}


def resolve_select(select, *, regimes=True, rest_reference=None, settle_time=None, bands=(),
                   band_candidates=()):
    """Whether :func:`calibrate_detector` chooses the settle time and rest reference.

    The default ("auto") chooses them across the recordings: on the real
    UR10e benchmark the chosen pairs give P_f and SP_S 10/10 pushes and no
    nested false alarm on the 21 unseen recordings, against 9/10 and one at
    the fixed 0.5 s / no reference (results page, the "sel" monitors). Any
    option that fixes the settings (a settle time, a rest reference, bands,
    no regimes) turns it off.

    Parameters
    ----------
    select : bool or "auto"
    regimes, rest_reference, settle_time, bands, band_candidates
        As for :func:`calibrate_detector`.

    Returns
    -------
    select : bool

    Examples
    --------
    >>> resolve_select("auto"), resolve_select("auto", settle_time=3.0), resolve_select(False)
    (True, False, False)
    """
    if select != "auto":
        return bool(select)
    return bool(regimes and rest_reference is None and settle_time is None and not bands
                and not band_candidates)


def check_calibration_options(*, regimes=True, rest_reference=None, settle_time=None,
                              select=False, bands=(), band_candidates=(), braking=None):
    """Refuse options of :func:`calibrate_detector` that contradict each other.

    ``gpcd calibrate`` calls it before any work; the messages name the
    command-line options.

    Parameters
    ----------
    regimes, rest_reference, settle_time, select, bands, band_candidates, braking
        As for :func:`calibrate_detector`.

    Raises
    ------
    ValueError
        ``select=True`` with a settle time, a rest reference, no regimes or bands;
        ``braking`` without regimes.

    Examples
    --------
    >>> check_calibration_options(select=True, settle_time=2.0)
    Traceback (most recent call last):
    ...
    ValueError: --select chooses the settle time and the rest reference of the regimes: ...
    """
    select = select is True  # "auto" gives way to the options that fix the settings
    if select and (not regimes or rest_reference is not None or settle_time is not None):
        raise ValueError("--select chooses the settle time and the rest reference of the "
                         "regimes: drop " + ("--no-regimes" if not regimes
                                             else "--rest-reference" if settle_time
                                             is None else "--settle-time"))
    if select and (bands or band_candidates):
        raise ValueError("--select chooses the settings of one band; with --band or "
                         "--band-candidate there are several: drop --select or the bands")
    if braking is not None and not regimes:
        raise ValueError("--braking is a regime: drop --no-regimes")


#: What the current columns of a recording hold, by ``Recording.units``.
_UNITS_WORDS = {"A": "motor currents [A]", "Nm": "joint torques [Nm]"}


def check_recordings(recordings, source, *, n_joints=None, units=None):
    """Refuse recordings a model or detector was not trained for, naming the file.

    Parameters
    ----------
    recordings : list of Recording
    source : str
        The model or detector in the user's words, e.g. ``"the model model.skops"``.
    n_joints : int or None, default=None
        Joints it was trained on (None: not checked).
    units : {"A", "Nm"} or None, default=None
        What its currents are (``Recording.units`` of its training recordings;
        None: not recorded, not checked).

    Raises
    ------
    ValueError
        A recording with another number of joints, or currents in other units.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> rec = Recording(time=np.arange(5.0), q=np.zeros((5, 2)), qd=np.zeros((5, 2)),
    ...                 current=np.zeros((5, 2)), name="calib/a.csv")
    >>> check_recordings([rec], "the model m.skops", n_joints=2, units="Nm")
    Traceback (most recent call last):
    ...
    ValueError: calib/a.csv: its currents are read as motor currents [A], but the model ...
    """
    for rec in recordings:
        if n_joints is not None and rec.n_joints != n_joints:
            raise ValueError(
                f"{rec.name}: {rec.n_joints} joints, but {source} was trained on recordings "
                f"of {n_joints} joints: give recordings of the arm it was trained on, or "
                "train a model on this arm's recordings with gpcd train")
        if units is not None and rec.units != units:
            raise ValueError(
                f"{rec.name}: its currents are read as {_UNITS_WORDS.get(rec.units, rec.units)}"
                f", but {source} was trained on {_UNITS_WORDS.get(units, units)}: read it with "
                "the column map of the training recordings (--column-map, with "
                + (f'"units": "{units}")' if units != "A" else 'no "units": "Nm")'))


def _check_model_inputs(model, features):
    n_in = getattr(model, "n_features_in_", None)
    n_rows = (6 if features.augmented else 3) * features.n_joints_
    if n_in is not None and n_in != n_rows:
        raise ValueError(f"the model takes {n_in} input columns but the recordings "
                         f"give {n_rows} ({features.n_joints_} joints)")


def _brake_limit(braking, training):
    """``Regimes(brake_limit=...)`` from ``braking`` and the model's record."""
    if braking is None or braking != "model":
        return braking
    if (limit := training.get("acceleration_limit")) is None:
        raise ValueError("the model does not record the largest acceleration it was "
                         "trained on (written by an earlier gpcd train): give --braking "
                         "LIMIT in rad/s^2, or train the model again")
    return float(limit)


def _summary(result, trained, features, robot, *, keys, split, n_files, select, several,
             chosen_band):
    """The calibration summary: what ``gpcd calibrate`` prints and the file keeps."""
    torque_constants = None if robot is None else getattr(robot, "torque_constants", None)
    # one band: its figures are the calibration's (each recording's false alarms at
    # the settings chosen without it); several: each band's own
    figures = result.bands if several else [result]
    entries = [_band_entry(band.rule, fig, torque_constants)
               for band, fig in zip(result.bands, figures)]
    det = result.detector
    regimes = det.rules_[0].regimes
    summary = {
        "recordings": keys, "split_s": split, "n_files": n_files,
        "hours": result.hours, "margin": entries[0]["margin"],
        "margin_rule": "global", "regimes": list(result.regime_names),
        "settle_time_s": 0.5 if regimes is None else regimes.settle_time,
        "rest_reference_s": None if regimes is None else regimes.rest_reference,
        "brake_limit": None if regimes is None else regimes.brake_limit,
        "selected": bool(select),
        "candidates": [dict(c, params=_json_params(c["params"])) for c in result.candidates]
        if select else [],
        "fold_settings": ({k: _json_params(p) for k, p in result.fold_settings.items()}
                          if select else {}),
        "thresholds_A": entries[0]["thresholds_A"],
        "n_false_alarms_nested": result.n_false_alarms,
        "false_alarms_per_hour": result.false_alarms_per_hour,
        "nested_onsets_s": {k: f["onsets"] for k, f in result.folds.items()},
        "training": trained.training,
        "signals": list(features.signals_), "sample_time_s": float(det.sample_time_),
        "robot": None if robot is None else robot.name,
    }
    if torque_constants is not None:
        summary["thresholds_Nm"] = entries[0]["thresholds_Nm"]
    if several:
        summary["bands"] = entries
    if chosen_band:
        # deferred: gpcd starts without scikit-learn (test_architecture.py)
        from ..detection import AlarmRule

        summary["band_candidates"] = [
            {"params": band_settings(AlarmRule(**c["params"])),
             "n_false_alarms": c["n_false_alarms"], "score": c["score"], "rank": c["rank"]}
            for c in result.candidates]
        summary["fold_band_settings"] = {
            k: band_settings(AlarmRule(**p)) for k, p in result.fold_settings.items()}
    return summary


def _band_entry(rule, figures, torque_constants):
    """One band for the summary: its fitted ``rule`` and the ``margin`` and nested
    false alarms of ``figures`` (a band of a calibrate_across_recordings result)."""
    thresholds = np.atleast_2d(rule.thresholds_)
    entry = {**band_settings(rule), "margin": float(figures.margin.max()),
             "thresholds_A": thresholds.tolist(),
             "n_false_alarms_nested": figures.n_false_alarms,
             "false_alarms_per_hour": figures.false_alarms_per_hour}
    if torque_constants is not None:
        entry["thresholds_Nm"] = (thresholds * np.asarray(torque_constants)).tolist()
    return entry


def _json_params(params):
    """Candidate settings with JSON keys: ``regimes__settle_time`` -> ``settle_time_s``."""
    out = {}
    for key, value in params.items():
        key = key.removeprefix("regimes__")
        out[f"{key}_s" if key in ("settle_time", "rest_reference") else key] = value
    return out


def calibration_report(summary):
    """The calibration summary in words: what ``gpcd calibrate`` prints.

    Recordings and settings, the candidates (``select``, ``band_candidates``),
    the margin, the expected false alarms (nested leave-one-recording-out)
    and the thresholds per regime and joint in A (and Nm), per band.

    Parameters
    ----------
    summary : dict
        ``calibration`` of a :class:`CalibratedDetector`.

    Returns
    -------
    text : str

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> from sklearn_gpcd.workflow import calibrate_detector, calibration_report, train_model
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(600) * 0.01
    >>> def rec(phase):
    ...     q = np.sin(t + phase)[:, None]
    ...     return Recording(time=t, q=q, qd=np.cos(t + phase)[:, None],
    ...                      current=2 * q + 0.05 * rng.normal(size=q.shape),
    ...                      target_current=2 * q)
    >>> trained = train_model([rec(0.0)], model="sp_c", n_support=50)
    >>> summary = calibrate_detector(trained, [rec(1.0), rec(2.0), rec(3.0)]).calibration
    >>> print(calibration_report(summary))  # doctest: +ELLIPSIS
    calibrated on 3 collision-free recording(s), 0.3 min, sample time 0.01 s, ...
      expected false alarms: ... alarm onset(s) on left-out recordings in 0.3 min = ...
    """
    out = []
    _report_lines(summary, out)
    return "\n".join(out)


def _duration_text(seconds):
    return f"{seconds / 60:.1f} min" if seconds >= 60 else f"{seconds:.1f} s"


def _seconds_text(value):
    return "none" if value is None else f"{value:g} s"


def _report_lines(summary, out):
    n_recordings = len(summary["recordings"])
    if summary.get("split_s") is not None:
        out.append(f"cut {summary['n_files']} recording(s) into {n_recordings} pieces of at least "
              f"{summary['split_s']:g} s (--split), each left out in turn like a recording; "
              "pieces of one log are less independent than separate runs")
    out.append(f"calibrated on {n_recordings} collision-free recording(s), "
          f"{summary['hours'] * 60:.1f} min, sample time {summary['sample_time_s']:g} s, "
          f"controller signals used: {', '.join(summary['signals']) or 'none'}; settle "
          f"time {_seconds_text(summary['settle_time_s'])}, rest reference "
          f"{_seconds_text(summary['rest_reference_s'])}"
          + (" (chosen across the recordings)" if summary.get("selected") else "")
          + ("" if summary.get("brake_limit") is None else
             f"; braking above {summary['brake_limit']:.3g} rad/s^2"))
    if (coverage := summary.get("coverage")):
        out.append("  data per regime: " + ", ".join(
            f"{name} {_duration_text(c['seconds'])} from {c['recordings']} recording(s)"
            for name, c in coverage.items()))
    if (without := summary.get("regimes_without_data")):
        out.append(f"  no calibration data (less than {MIN_REGIME_DATA_SECONDS:g} s) in the "
                   f"{' and '.join(without)} regime"
                   + ("s: their" if len(without) > 1 else ": its")
                   + " thresholds are, joint by joint, the largest of the regimes with data")
    if (one_log := summary.get("stages_from_one_log")):
        out.append(f"  {' and '.join(one_log)}: seen in one log alone (no left-out log "
                   "checks it), the threshold of the settling stage before")
    if (floor := summary.get("training_floor_A")):
        out.append("  thresholds at least the model's levels on its left-out training runs "
                   "(gpcd train --model auto), for what the calibration did not cover: "
                   + "; ".join(f"{name} " + " ".join(f"{v:.3g}" for v in level)
                               for name, level in floor.items()))
    choice = (summary.get("training") or {}).get("model_choice") or {}
    if floor and choice.get("regime_thresholds") is None:  # a file from before the rows
        out.append("  the model file records no training levels per regime (written by an "
                   "earlier gpcd train): settling and rest keep the calibration's thresholds; "
                   "run gpcd train --model auto again to floor them too")
    if summary.get("candidates"):
        out.append("  candidates, best first (alarms: nested onsets at that fixed candidate, "
              "fewest first; score: time-weighted mean log threshold, smaller is tighter):")
        for c in sorted(summary["candidates"], key=lambda c: c["rank"]):
            settle, tau = c["params"]["settle_time_s"], c["params"]["rest_reference_s"]
            out.append(f"    settle {_seconds_text(settle):>6}, rest reference {_seconds_text(tau):>5}: "
                  f"alarms {c['n_false_alarms']}, score {c['score']:+.3f}, "
                  f"margin {c['margin']:.3f}" + ("  <- chosen" if c["rank"] == 0 else ""))
    if (info := summary.get("training")):
        out.append(f"  model: {info['model'].upper()} trained on {info['inputs']} inputs, "
              f"{info['n_support']} support rows per joint, optimizer {info['optimizer']}, "
              f"seed {info['seed']}")
    if "bands" not in summary:
        _margin_line(summary, "  ", out)
        _false_alarm_line(summary, out)
        _threshold_lines(summary, summary, "  ", out)
        return
    for b, band in enumerate(summary["bands"], start=1):
        out.append(f"  band {b} ({band_label(band)})" + (", the main one:" if b == 1 else ":"))
        _margin_line(band, "    ", out)
        if band["false_alarms_per_hour"] is not None:
            out.append(f"    nested false alarms of this band alone: "
                  f"{band['n_false_alarms_nested']} alarm onset(s) = "
                  f"{band['false_alarms_per_hour']:.2f} per hour")
        _threshold_lines(band, summary, "    ", out)
    if (table := summary.get("band_candidates")):
        out.append(f"  band {len(summary['bands'])} chosen across the recordings, candidates best "
              "first (alarms: nested onsets of the union; score: time-weighted mean log "
              "threshold of the band, smaller is tighter):")
        for c in sorted(table, key=lambda c: c["rank"]):
            out.append(f"    {band_label(c['params']):<28} alarms {c['n_false_alarms']}, score "
                  f"{c['score']:+.3f}" + ("  <- chosen" if c["rank"] == 0 else ""))
        folds = Counter(map(band_label, summary["fold_band_settings"].values()))
        if folds:
            out.append("    chosen without each recording (for the expected false alarms): "
                  + ", ".join(f"{label} {n}x" for label, n in folds.most_common()))
    _false_alarm_line(summary, out, " (any band)")


def _margin_line(entry, pad, out):
    out.append(f"{pad}margin (leave-one-recording-out, one for all joints and regimes): "
          f"{entry['margin']:.3f}")


def _false_alarm_line(summary, out, which=""):
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..metrics import rate_upper_bound

    if summary["false_alarms_per_hour"] is None:
        out.append(f"  expected false alarms{which} per hour: n/a (the nested figure needs >= 3 "
              "recordings)")
        return
    out.append(f"  expected false alarms{which}: {summary['n_false_alarms_nested']} alarm "
          f"onset(s) on left-out recordings in {summary['hours'] * 60:.1f} min = "
          f"{summary['false_alarms_per_hour']:.2f} per hour (nested leave-one-recording-"
          "out: each recording scored with margin"
          + (", levels and settings" if summary.get("selected")
             else ", levels and band" if summary.get("band_candidates") else " and levels")
          + " chosen without it"
          + (_AT_FLOORS if summary.get("training_floor_A") else "") + ")")
    bound = rate_upper_bound(summary["n_false_alarms_nested"], summary["hours"])
    out.append(f"    95 % upper bound: {bound:.3g} per hour (Poisson, from "
               f"{summary['n_false_alarms_nested']} onset(s) in {summary['hours'] * 60:.1f} min: "
               "longer calibration data tightens it)")


def _threshold_lines(entry, summary, pad, out):
    """The thresholds table(s) of ``entry`` (A, and Nm when known), one row per regime."""
    n = len(entry["thresholds_A"][0])
    units = [(summary.get("units", "A"), entry["thresholds_A"])]
    if "thresholds_Nm" in entry:
        units.append((f"Nm, torque constants of {summary['robot']}", entry["thresholds_Nm"]))
    for unit, table in units:
        out.append(f"{pad}thresholds [{unit}]:")
        out.append(f"{pad}  " + f"{'regime':<10}" + "".join(f"{f'joint {j + 1}':>10}"
                                                        for j in range(n)))
        for name, row in zip(summary["regimes"], table):
            out.append(f"{pad}  " + f"{name:<10}" + "".join(f"{v:>10.3f}" for v in row))


def save_detector(calibrated, path):
    """Write a :class:`CalibratedDetector` (``.skops``, or ``.joblib`` / ``.pkl``).

    Parameters
    ----------
    calibrated : CalibratedDetector
        What :func:`calibrate_detector` returned.
    path : str or path-like
        The extension chooses the format.

    Returns
    -------
    path : Path

    Examples
    --------
    >>> import tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "detector.joblib"
    >>> save_detector(CalibratedDetector(None, None, {"margin": 1.5}), path).name
    'detector.joblib'
    >>> load_detector(path, trust_pickle=True)  # our own pickle, but no detector in it
    Traceback (most recent call last):
    ...
    sklearn_gpcd.persistence.MalformedFileError: ...: field detector holds no fitted ...
    """
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..persistence import save

    return save({"kind": DETECTOR_KIND, "detector": calibrated.detector,
                 "features": calibrated.features, "calibration": calibrated.calibration}, path)


def load_detector(path, trust_pickle=False):
    """Read a detector file written by ``gpcd calibrate`` (:func:`save_detector`).

    Parameters
    ----------
    path : str or path-like
        ``.skops`` (or ``.joblib`` / ``.pkl``) file.
    trust_pickle : bool, default=False
        Load a ``.joblib`` / ``.pkl`` file (see :func:`sklearn_gpcd.load`).

    Returns
    -------
    calibrated : CalibratedDetector
        ``(detector, features, calibration)``: the fitted detector, the causal
        features that compute its inputs from raw samples (for
        :meth:`StreamingMonitor.update_raw
        <sklearn_gpcd.detection.StreamingMonitor.update_raw>`), and what
        ``gpcd calibrate`` printed (margin, thresholds, false alarms).

    Raises
    ------
    ValueError
        If the file is not a detector file (e.g. a model from ``gpcd train``).
    MalformedFileError
        If the file is damaged, or holds values a monitor must not run with
        (a threshold, scale or margin that is not finite and positive, an
        unstable filter, shapes that disagree with the joint count): one line
        naming the field and the command that rebuilds the file.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from sklearn_gpcd.persistence import save
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "not_a_detector.joblib"
    >>> _ = save({"kind": "something else"}, path)
    >>> load_detector(path, trust_pickle=True)
    Traceback (most recent call last):
    ...
    ValueError: ...not_a_detector.joblib: not a detector file written by gpcd calibrate...
    """
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ._file_checks import check_detector_bundle, load_checked

    fix = f"rebuild it with gpcd calibrate MODEL RECORDINGS -o {path}"
    bundle = load_checked(path, trust_pickle, fix)
    if not (isinstance(bundle, dict) and bundle.get("kind") == DETECTOR_KIND):
        raise ValueError(f"{path}: not a detector file written by gpcd calibrate (a model "
                         "from gpcd train goes through gpcd calibrate first)")
    check_detector_bundle(bundle, path, fix)
    return CalibratedDetector(bundle["detector"], bundle["features"],
                              bundle.get("calibration", {}))


#: Slack on the drives' current limits (``effort_limits / torque_constants``).
DRIVE_SLACK = 1.5
#: Rows per chunk when :func:`check_signals` reads a recording.
CHECK_CHUNK_ROWS = 50_000
#: At most this many rows of a recording are predicted for :func:`check_signals`
#: (every k-th row: the ratio test counts shares, a GP prediction costs).
CHECK_PREDICTED_ROWS = 2_000


def detector_robot(calibrated, robot=None):
    """The robot model a detector file names (its calibration's, else its model's).

    Parameters
    ----------
    calibrated : CalibratedDetector
        What :func:`calibrate_detector` or :func:`load_detector` returned.
    robot : Robot, str or None, default=None
        The robot when the file names none.

    Returns
    -------
    robot : Robot or None
        None when no robot is named, it cannot be loaded, or its number of
        joints is not the detector's.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> calibrated = CalibratedDetector(None, SimpleNamespace(n_joints_=6), {"robot": "ur10e"})
    >>> detector_robot(calibrated).name
    'ur10e'
    >>> detector_robot(calibrated._replace(calibration={})) is None
    True
    """
    # deferred: pinocchio, loaded when a robot is (gpcd starts without it)
    from ..robots import load_robot

    _, features, calibration = calibrated
    training = calibration.get("training") or {}
    name = calibration.get("robot") or training.get("robot") or robot
    if name is None:
        return None
    try:
        robot = load_robot(name) if isinstance(name, str) else name
    except (ValueError, OSError):
        return None
    return robot if robot.n_joints == features.n_joints_ else None


def signal_check(calibrated, robot=None):
    """A :class:`~sklearn_gpcd.io.SignalCheck` with what a detector file knows.

    The ranges of the training and calibration recordings (``calibration
    ["signal_ranges"]``), the robot's joint limits and drive limits (the
    robot named by the calibration or the model, or ``robot``), the
    detector's sample time and its loosest threshold per joint.

    Parameters
    ----------
    calibrated : CalibratedDetector
        What :func:`calibrate_detector` or :func:`load_detector` returned.
    robot : Robot, str or None, default=None
        The robot when the detector file names none (e.g. a recording's
        ``metadata["robot"]``).

    Returns
    -------
    check : SignalCheck

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> calibrated = CalibratedDetector(SimpleNamespace(sample_time_=0.002),
    ...                                 SimpleNamespace(n_joints_=6), {"robot": "ur10e"})
    >>> check = signal_check(calibrated)
    >>> round(float(check.position_limits[1][0]), 4), check.sample_time
    (6.2832, 0.002)
    >>> check.current_limits.round(1).tolist()   # 1.5 effort limit / torque constant [A]
    [41.3, 41.3, 22.9, 7.8, 7.8, 7.8]
    """
    detector, features, calibration = calibrated
    detector = untaught_detector(detector)
    training = calibration.get("training") or {}
    ranges = calibration.get("signal_ranges") or training.get("signal_ranges")
    robot = detector_robot(calibrated, robot)
    limits = current = None
    if robot is not None:
        limits = [robot.lower, robot.upper]
        kt = getattr(robot, "torque_constants", None)
        if kt is not None and (ranges or {}).get("units", "A") == "A":
            current = DRIVE_SLACK * np.asarray(robot.effort_limits) / np.asarray(kt)
    thresholds = [np.max(np.atleast_2d(rule.thresholds_), axis=0)
                  for rule in getattr(detector, "rules_", ())
                  if getattr(detector, "normalize", None) is None]  # else in std units
    return SignalCheck(features.n_joints_, ranges=ranges, position_limits=limits,
                       current_limits=current, sample_time=float(detector.sample_time_),
                       thresholds=np.max(thresholds, axis=0) if thresholds else None)


def fed_signal_check(recording, calibrated, *, name=None):
    """:func:`signal_check` fed with ``recording`` and the model's prediction of it.

    The prediction is made on at most :data:`CHECK_PREDICTED_ROWS` rows
    (none for a dynamic model that reads the currents); the recording is fed
    in chunks of :data:`CHECK_CHUNK_ROWS`.

    Parameters
    ----------
    recording : Recording
    calibrated : CalibratedDetector
    name : str, default=None
        The file named in the error on a joint count the detector lacks.

    Returns
    -------
    check : SignalCheck
        Read its :meth:`~sklearn_gpcd.io.SignalCheck.findings` or
        :meth:`~sklearn_gpcd.io.SignalCheck.statistics`.

    Examples
    --------
    >>> from sklearn_gpcd.workflow import calibrate_detector, train_model
    >>> from sklearn_gpcd.io import Recording
    >>> import numpy as np
    >>> time = np.arange(600) / 100
    >>> def run(phase):
    ...     s = np.c_[np.sin(time + phase)]
    ...     return Recording(time=time, q=s, qd=np.c_[np.cos(time + phase)], current=2 + s,
    ...                      target_current=2 + s)
    >>> model = train_model([run(0.0)], model="sp_c", n_support=30)
    >>> calibrated = calibrate_detector(model, [run(1.0), run(2.0)], select=False)
    >>> fed_signal_check(run(2.0), calibrated).statistics()["span_steps"]
    [0.0]
    """
    detector, features, _ = calibrated
    detector = untaught_detector(detector)
    source = name or recording.metadata.get("source") or recording.name
    if recording.n_joints != features.n_joints_:
        raise ValueError(f"{source}: {recording.n_joints} joints but the detector has "
                         f"{features.n_joints_}")
    check = signal_check(calibrated, robot=recording.metadata.get("robot"))
    step = -(-recording.n_samples // CHECK_PREDICTED_ROWS)
    inputs = features.transform(recording)[::step]
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..detection import reads_currents

    predicted = None  # a dynamic model (the momentum observer) is not compared
    if not reads_currents(detector.regressor_):
        predicted = np.full((recording.n_samples, recording.n_joints), np.nan)
        predicted[::step] = np.reshape(detector.regressor_.predict(inputs),
                                       (-1, recording.n_joints))
    for start in range(0, recording.n_samples, CHECK_CHUNK_ROWS):
        rows = slice(start, start + CHECK_CHUNK_ROWS)
        check.update(recording.time[rows], recording.q[rows], recording.qd[rows],
                     recording.current[rows], None if predicted is None else predicted[rows])
    return check


def check_signals(recording, calibrated, *, accept=(), name=None):
    """Refuse or warn about a recording whose signals a detector cannot trust.

    The checks of :class:`~sklearn_gpcd.io.SignalCheck` with what the
    detector knows (:func:`signal_check`), the model's prediction of the
    currents on at most :data:`CHECK_PREDICTED_ROWS` rows. Used by ``gpcd calibrate`` (on the
    calibration recordings) and ``gpcd monitor`` (before monitoring).

    Parameters
    ----------
    recording : Recording
    calibrated : CalibratedDetector
    accept : collection of str, default=()
        Kinds of finding to let through (``"units"``, ``"current"``,
        ``"limits"``, ``"time"``; ``gpcd --units-confirmed`` accepts all).
    name : str, default=None
        The file named in messages (default: the recording's source).

    Returns
    -------
    findings : list of Finding
        All of them; the warnings were issued as
        :class:`~sklearn_gpcd.io.RecordingWarning`.

    Raises
    ------
    ValueError
        On the first error not accepted, naming the file and the column.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> from sklearn_gpcd.workflow import calibrate_detector, train_model
    >>> t = np.arange(600) * 0.01
    >>> recs = [Recording(time=t, q=np.c_[np.sin(t + p)], qd=np.c_[np.cos(t + p)],
    ...                   current=np.c_[2 + np.sin(t + p)], target_current=np.c_[2 + np.sin(t + p)])
    ...         for p in (0.0, 1.0, 2.0)]
    >>> calibrated = calibrate_detector(train_model(recs[:1], model="sp_c", n_support=30),
    ...                                 recs[1:], select=False)
    >>> check_signals(recs[2], calibrated)
    []
    >>> flipped = Recording(time=t, q=recs[2].q, qd=recs[2].qd, current=-recs[2].current,
    ...                     target_current=recs[2].target_current)
    >>> check_signals(flipped, calibrated, name="today.csv")
    Traceback (most recent call last):
    ...
    ValueError: today.csv: current[0] has the opposite sign of the model's prediction...
    """
    source = name or recording.metadata.get("source") or recording.name
    check = fed_signal_check(recording, calibrated, name=source)
    findings = check.findings()
    for finding in findings:
        if finding.kind in accept:
            continue
        if finding.severity == "error":
            raise ValueError(f"{source}: {finding.sentence} Fix the column map (--column-map) "
                             "or the file, or accept it as it is: --units-confirmed "
                             f"(accept=[{finding.kind!r}] in Python)")
        warnings.warn(f"{source}: {finding.sentence}", RecordingWarning, stacklevel=2)
    return findings
