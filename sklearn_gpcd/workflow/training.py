"""Training a collision-detection model on recordings: the one function behind
``gpcd train``.

:func:`train_model` turns collision-free recordings into a fitted estimator
(P_f, SP_S, SP_P, SP_C or the GP alone) *together with* the fitted
:class:`~sklearn_gpcd.features.CausalFeatures` that computes its inputs on
the robot, and a record of how it was trained. ``gpcd calibrate`` and
``gpcd monitor`` reuse that transformer, so the detector sees exactly the
inputs the model was fitted on; :func:`save_model` / :func:`load_model`
write and read that bundle.

Inputs (``inputs=``):

* ``"causal"`` (default): :class:`~sklearn_gpcd.features.CausalFeatures`,
  the rows the robot computes sample by sample (causal low-pass
  acceleration). Detection always runs on this path, so a model fitted on
  it is calibrated and monitored on the very inputs it was trained on.
* ``"zero-phase"``: :func:`~sklearn_gpcd.features.make_inputs` (zero-phase
  Savitzky-Golay derivatives, the paper's offline inputs), for offline
  analysis; the detector then feeds the model causal inputs it never saw (a
  lagged, noisier acceleration).

The rows that enter the fit, the support subset and the optimizer follow
:data:`TRAIN_RULE`.
"""

import contextlib
import os
import tempfile
import threading
import warnings
from dataclasses import dataclass, field

import numpy as np

from .._gate import DEFAULT_SIGMA_V
from ..io import Recording
from ..layout import block_columns

__all__ = ["INPUTS", "MAX_TRAIN_ROWS", "MODELS", "MODEL_KIND", "MODEL_SIGNALS", "OPTIMIZERS",
           "ROBOT_MODELS", "TRAIN_RULE", "TrainedModel", "TrainingSet", "acceleration_limit",
           "load_model", "save_model", "train_model", "training_report", "training_rows",
           "training_set"]

#: Estimators :func:`train_model` builds (``gpcd train --model``): the paper's
#: three, SP_C (the controller's target current as mean) and ``"gp"``, the GP
#: alone (SP_P's kernel on a constant mean, ``make_sp_p(None, ...)``: no
#: rigid-body model).
MODELS = ("sp_p", "sp_s", "p_f", "sp_c", "gp")
#: Models whose mean is the rigid-body features: they need the robot's model
#: (``gpcd train --robot``); SP_C and the GP alone need none.
ROBOT_MODELS = ("sp_p", "sp_s", "p_f")
#: Controller signals each model's inputs use (``CausalFeatures(signals=...)``):
#: SP_P and the GP alone (the augmented inputs of Eq. 13) and SP_C (the
#: target current) use the ones asked for (``train_model(signals=...)``, by
#: default every one the training recordings log); P_f and SP_S read only
#: ``[q, qd, qdd]``, so their model files do not require the controller's
#: signals of the recordings they monitor.
MODEL_SIGNALS = {"sp_p": "auto", "sp_s": (), "p_f": (), "sp_c": "auto", "gp": "auto"}
#: Training inputs (``gpcd train --inputs``); the first is the default.
INPUTS = ("causal", "zero-phase")
#: Hyperparameter optimizers (``gpcd train --optimizer``), see
#: :class:`~sklearn_gpcd.gp.SemiParametricGPRegressor`.
OPTIMIZERS = ("auto", "adam", "fmin_l_bfgs_b")
#: What a model file written by :func:`save_model` holds.
MODEL_KIND = "gpcd-model"
#: Training recordings shorter than this in all [s] warn in ``gpcd train``:
#: the README's recipe asks for 10 minutes or more of varied motion.
MIN_TRAINING_SECONDS = 600.0
#: Rows that enter a fit at most (see :data:`TRAIN_RULE`).
MAX_TRAIN_ROWS = 200_000
#: The rule :func:`train_model` (and ``gpcd train``) follows, safe on any log size.
TRAIN_RULE = (
    "Inputs: causal by default (the rows the robot computes sample by sample, on which "
    "gpcd calibrate and gpcd monitor run the model), or zero-phase (--inputs zero-phase: "
    "the paper's offline derivatives). "
    "Rows: at most 200,000 rows enter the fit; a longer log is thinned to every k-th row "
    "(k = ceil(rows / 200,000); at 500 Hz neighbouring rows are 2 ms apart and nearly "
    "identical). GP support: --n-support rows per joint (default 'auto': min(rows, 2000), "
    "drawn at random). Optimizer (--optimizer, default 'auto'): the regressor's rule -- "
    "L-BFGS-B on the exact likelihood of the support while support rows <= 3,000 and "
    "support rows x hyperparameters <= 60,000 (P_f: 1 hyperparameter), else minibatch Adam "
    "(min(512, support rows)-row minibatches from all rows, early stopping), so SP_P (57 "
    "hyperparameters on 6 joints) uses Adam from 1,053 support rows on. "
    "The parametric mean is fitted by least squares on every row that enters the fit."
)


def training_rows(n_rows, max_rows=MAX_TRAIN_ROWS):
    """Rows of :data:`TRAIN_RULE`: every k-th row, k = ceil(n_rows / max_rows).

    Parameters
    ----------
    n_rows : int
        Rows of all training recordings together.
    max_rows : int, default=MAX_TRAIN_ROWS
        Rows kept at most.

    Returns
    -------
    rows : slice

    Examples
    --------
    >>> training_rows(41707).stop, training_rows(1_800_000).step
    (41707, 9)
    """
    return slice(0, n_rows, max(1, -(-n_rows // max_rows)))


@dataclass
class TrainingSet:
    """GP inputs and currents of training recordings (from :func:`training_set`).

    Attributes
    ----------
    X : ndarray of shape (n_rows_used, 6 * n_joints)
        Inputs, in the layout of :mod:`sklearn_gpcd.layout` (Eq. 13).
    y : ndarray of shape (n_rows_used, n_joints)
        Motor currents.
    features : CausalFeatures
        Fitted on the training recordings: computes the detector's inputs
        (whatever ``inputs`` was).
    inputs : {"causal", "zero-phase"}
    names : list of str
        The recordings' names, in order.
    n_rows : int
        Rows of the recordings before thinning.
    step : int
        One row in ``step`` entered ``X`` (:func:`training_rows`).
    has_target_current : bool
        Every recording logs the controller's target current (SP_C needs it).
    sizes : tuple of int
        Rows of ``X`` from each recording, in order (for splits by
        recording, e.g. :func:`~sklearn_gpcd.workflow.compare_models`).
    sample_time : float or None
        Median time between consecutive rows of ``X`` [s] (the recordings'
        sample time times ``step``), for the alarm rule of
        :func:`~sklearn_gpcd.workflow.compare_models`.
    units : {"A", "Nm"}
        What ``y`` holds: motor currents [A] or joint torques [Nm]
        (``Recording.units``, from the column map's ``"units"``).
    signal_ranges : dict or None
        Per-joint ranges of q, qd and current of the recordings
        (:func:`~sklearn_gpcd.io.signal_ranges`): what the model knows, for
        the plausibility checks of ``gpcd calibrate`` and ``gpcd monitor``.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> t = np.arange(10) * 0.01
    >>> rec = Recording(time=t, q=np.zeros((10, 1)), qd=np.zeros((10, 1)),
    ...                 current=np.ones((10, 1)))
    >>> data = training_set([rec], max_rows=5)
    >>> data.n_rows, data.step, data.X.shape
    (10, 2, (5, 6))
    """

    X: np.ndarray
    y: np.ndarray
    features: object
    inputs: str
    names: list
    n_rows: int
    step: int
    has_target_current: bool = True
    sizes: tuple = ()
    sample_time: float = None
    units: str = "A"
    signal_ranges: dict = None


def training_set(recordings, inputs="causal", *, max_rows=MAX_TRAIN_ROWS,
                 allow_missing=False, progress=None, signals="auto"):
    """Inputs and currents of ``recordings`` for :func:`train_model`.

    Parameters
    ----------
    recordings : list of Recording
        Collision-free training recordings (the list is emptied as they
        are processed, to free memory on long logs; pass a copy to keep it).
        Warnings of the input computation are issued once per kind.
    inputs : {"causal", "zero-phase"}, default="causal"
        See the module docstring.
    max_rows : int, default=MAX_TRAIN_ROWS
        Longer logs are thinned to every k-th row (:func:`training_rows`).
    allow_missing : bool, default=False
        Passed to :class:`~sklearn_gpcd.features.CausalFeatures`: controller
        signals missing at transform time are filled with zeros.
    progress : callable or None, default=None
        ``progress(label, total)`` returning an object with ``update()``,
        called once per recording.
    signals : "auto" or tuple of str, default="auto"
        Passed to :class:`~sklearn_gpcd.features.CausalFeatures`: the
        controller signals the inputs use (and later require).

    Returns
    -------
    data : TrainingSet

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> t = np.arange(50) * 0.01
    >>> rec = Recording(time=t, q=np.zeros((50, 2)), qd=np.zeros((50, 2)),
    ...                 current=np.ones((50, 2)))
    >>> data = training_set([rec, rec])
    >>> data.X.shape, data.y.shape, data.inputs
    ((100, 12), (100, 2), 'causal')
    """
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..features import CausalFeatures, make_inputs
    from ..io import signal_ranges

    if inputs not in INPUTS:
        raise ValueError(f"inputs must be one of {INPUTS}, got {inputs!r}")
    recordings = recordings if isinstance(recordings, list) else list(recordings)
    if not recordings:
        raise ValueError("no training recordings")
    if len(units := {rec.units for rec in recordings}) > 1:
        torques = next(rec.name for rec in recordings if rec.units == "Nm")
        currents = next(rec.name for rec in recordings if rec.units != "Nm")
        raise ValueError(f"the training recordings mix joint torques [Nm] ({torques}) and "
                         f"motor currents [A] ({currents}): read them all with one column "
                         "map (its \"units\")")
    features = CausalFeatures(allow_missing=allow_missing, signals=signals).fit(recordings)
    names = [rec.name for rec in recordings]
    has_ic = all(rec.target_current is not None for rec in recordings)
    n_rows = sum(rec.n_samples for rec in recordings)
    step = training_rows(n_rows, max_rows).step
    bar = _bar(progress, f"computing GP inputs ({inputs})", len(recordings))
    unused = _unused_columns(features.signals_, features.n_joints_)
    X, y, sizes, offset, ranges = [], [], [], 0, None
    steps = np.concatenate([np.diff(np.asarray(rec.time, float)) for rec in recordings])
    sample_time = float(np.median(steps)) * step if steps.size else None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        while recordings:  # thin each block to the global every-step-th row, free as we go
            rec = recordings.pop(0)
            ranges = signal_ranges([rec], ranges)
            if inputs == "causal":
                Xr, yr = features.transform(rec), rec.current
            else:
                Xr, yr = make_inputs([rec], augmented=True)
                Xr[:, unused] = 0.0  # the columns of signals left out, as the causal path
            keep = slice((-offset) % step, None, step)
            X.append(Xr[keep].copy())
            sizes.append(len(X[-1]))
            y.append(np.asarray(yr, dtype=float)[keep].copy())
            offset += rec.n_samples
            del rec, Xr, yr
            bar.update()
    _warn_once_per_kind(caught, len(names))
    return TrainingSet(X=np.vstack(X), y=np.vstack(y), features=features, inputs=inputs,
                       names=names, n_rows=n_rows, step=step, has_target_current=has_ic,
                       sizes=tuple(sizes), sample_time=sample_time, units=units.pop(),
                       signal_ranges=ranges)


def _unused_columns(signals, n_joints):
    """Columns of the augmented layout that no signal of ``signals`` feeds."""
    blocks = [] if "target_current" in signals else ["i_c"]
    if "target_q" not in signals:
        blocks.append("e_q")
        if "target_qd" not in signals:
            blocks.append("de_q")
    return [c for b in blocks for c in block_columns(b, n_joints)]


@dataclass
class TrainedModel:
    """A fitted regressor, the causal features of its inputs, and how it was trained.

    Attributes
    ----------
    regressor : SemiParametricGPRegressor
        Fitted; predicts the currents of all joints from ``features``' rows.
    features : CausalFeatures
        Fitted on the training recordings: ``gpcd calibrate`` and ``gpcd
        monitor`` compute the detector's inputs with it.
    training : dict
        ``model``, ``inputs``, ``n_support``, ``optimizer`` (asked and
        used), ``batch_size``, ``seed``, ``sigma_v``, ``coulomb_width``,
        ``signals``, ``robot``,
        ``recordings``, ``n_rows``, ``n_rows_used``, ``step``,
        ``acceleration_limit`` (:func:`acceleration_limit`), ``units`` (of
        the target: "A" for motor currents, "Nm" for joint torques).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> t = np.arange(100) * 0.01
    >>> rec = Recording(time=t, q=np.sin(t)[:, None], qd=np.cos(t)[:, None],
    ...                 current=np.sin(t)[:, None], target_current=np.sin(t)[:, None])
    >>> trained = train_model([rec], model="sp_c", n_support=20)
    >>> type(trained).__name__, trained.features.signals_
    ('TrainedModel', ('target_current',))
    """

    regressor: object
    features: object
    training: dict = field(default_factory=dict)


def _build(model, robot, n_joints, params, coulomb_width=None):
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..dynamics import FrictionColumns, RigidBodyFeatures
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..gp import make_p_f, make_sp_c, make_sp_p, make_sp_s

    if model not in ROBOT_MODELS and coulomb_width is not None:
        raise ValueError(f"coulomb_width is a column of the rigid-body features; model "
                         f"{model!r} has none (use p_f, sp_s or sp_p)")
    if model == "sp_c":
        return make_sp_c(n_joints, **params)
    if model == "gp":
        return make_sp_p(None, n_joints, **params)
    if robot is None:
        raise ValueError(f"model {model!r} needs the robot (its rigid-body features); "
                         "models without one: 'sp_c', 'gp'")
    phi = [RigidBodyFeatures(robot, joint=j,
                             friction=FrictionColumns(coulomb_width=coulomb_width))
           for j in range(n_joints)]
    return {"sp_p": make_sp_p, "sp_s": make_sp_s, "p_f": make_p_f}[model](
        phi, n_joints, **params)


def _model_features(model, features):
    """``features`` for ``model``: without controller signals when it reads none.

    P_f and SP_S read only ``[q, qd, qdd]``; fitted on a :class:`TrainingSet`
    whose features use signals, their model file would still require them.
    A :class:`~sklearn_gpcd.features.CausalFeatures` using no signal depends
    only on the joint count, so it is fitted on a two-sample stand-in.
    """
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from sklearn.base import clone

    if MODEL_SIGNALS[model] != () or not features.signals_:
        return features
    n = features.n_joints_
    stand_in = Recording(time=[0.0, 1.0], q=np.zeros((2, n)), qd=np.zeros((2, n)),
                         current=np.zeros((2, n)))
    return clone(features).set_params(signals=()).fit([stand_in])


def acceleration_limit(data):
    """The largest ``|qdd|`` of the rows a model is fitted on [rad/s^2].

    Read from the training inputs ``data.X`` (with the default causal
    inputs, the accelerations the detector sees).

    Beyond it the model extrapolates: hard stops ring the current for about
    half a second and no training row shows how. ``gpcd calibrate
    --braking`` gives those samples a regime of their own
    (``Regimes(brake_limit=...)`` of an alarm rule).

    Parameters
    ----------
    data : TrainingSet
        The inputs of the training recordings (:func:`training_set`).

    Returns
    -------
    limit : float
        In rad/s^2.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> t = np.arange(100) * 0.01   # qdd = -sin(t), |qdd| <= 0.84 in the first second
    >>> data = training_set([Recording(time=t, q=np.sin(t)[:, None], qd=np.cos(t)[:, None],
    ...                                current=np.sin(t)[:, None])])
    >>> round(acceleration_limit(data), 2)   # causal: low-passed, a little lower
    0.82
    """
    n_joints = data.y.shape[1]
    return float(np.abs(data.X[:, block_columns("qdd", n_joints)]).max())


def train_model(recordings, robot=None, model="sp_p", *, inputs="causal", n_support="auto",
                optimizer="auto", sigma_v=None, seed=0, n_jobs=None,
                max_rows=MAX_TRAIN_ROWS, progress=None, coulomb_width=None, signals="auto"):
    """Fit P_f, SP_S, SP_P, SP_C or the GP alone on collision-free recordings.

    The rule is :data:`TRAIN_RULE`; ``gpcd train --model auto`` chooses the
    model first (:func:`~sklearn_gpcd.workflow.compare_models`).

    Parameters
    ----------
    recordings : list of Recording or TrainingSet
        Training recordings (emptied, see :func:`training_set`), or their
        inputs already computed (several models on the same data).
    robot : Robot or None, default=None
        For the rigid-body features of P_f, SP_S and SP_P (:data:`ROBOT_MODELS`;
        SP_C and the GP alone need none).
    model : {"sp_p", "sp_s", "p_f", "sp_c", "gp"}, default="sp_p"
        The estimator (:func:`~sklearn_gpcd.gp.make_sp_p` and its peers;
        ``"gp"``: ``make_sp_p(None, ...)``, no parametric mean).
    inputs : {"causal", "zero-phase"}, default="causal"
        Ignored when ``recordings`` is a :class:`TrainingSet`.
    n_support : int or "auto", default="auto"
        GP support rows per joint ("auto": at most 2,000).
    optimizer : {"auto", "adam", "fmin_l_bfgs_b"}, default="auto"
        Hyperparameter optimizer of the regressor ("auto": :data:`TRAIN_RULE`).
    sigma_v : float or None, default=None
        Quasi-static velocity threshold [rad/s] of the model's gates and
        masks and of the regimes of a detector calibrated on it (recorded in
        ``training["sigma_v"]``). None: the package's default 1e-2 rad/s
        (``DEFAULT_SIGMA_V``) for SP_P's and the GP's gates and for the
        regimes, while P_f, SP_S and SP_C keep the paper's unmasked friction.
    seed : int, default=0
        ``random_state`` of the regressor (support rows, minibatches).
    n_jobs : int or None, default=None
        Joints fitted in parallel (results do not depend on it).
    max_rows : int, default=MAX_TRAIN_ROWS
        Longer logs are thinned (:func:`training_rows`).
    progress : callable or None, default=None
        ``progress(label, total)`` returning an object with ``update(n=1)``:
        one bar for the inputs (one step per recording), one for the fit
        (one step per joint).
    coulomb_width : float > 0 or None, default=None
        Coulomb column ``tanh(qd / coulomb_width)`` of the rigid-body
        regressor instead of the paper's ``sign(qd)`` (P_f, SP_S, SP_P; see
        :class:`~sklearn_gpcd.dynamics.RigidBodyFeatures`).
    signals : "auto" or tuple of str, default="auto"
        Controller signals the inputs of SP_P, SP_C and the GP alone use
        (:class:`~sklearn_gpcd.features.CausalFeatures`): "auto", every one
        the recordings log; ``()`` none, so that the model file calibrates
        and monitors logs without them (``gpcd train --signals none``).
        Ignored when ``recordings`` is a :class:`TrainingSet`.

    Returns
    -------
    trained : TrainedModel

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> t = np.arange(200) * 0.01
    >>> q = np.column_stack([np.sin(t), np.cos(t)])
    >>> rec = Recording(time=t, q=q, qd=np.gradient(q, t, axis=0), current=q,
    ...                 target_current=0.9 * q)
    >>> trained = train_model([rec], model="sp_c", n_support=50)
    >>> trained.training["inputs"], trained.training["n_support"]
    ('causal', 50)
    >>> trained.regressor.predict(trained.features.transform(rec)).shape
    (200, 2)
    """
    if model not in MODELS:
        raise ValueError(f"model must be one of {MODELS}, got {model!r}")
    if optimizer not in OPTIMIZERS:
        raise ValueError(f"optimizer must be one of {OPTIMIZERS}, got {optimizer!r}")
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..gp import resolve_n_support

    data = recordings if isinstance(recordings, TrainingSet) else None
    if data is None:
        if not isinstance(recordings, list):
            recordings = list(recordings)
        if model == "sp_c" and (lacking := [r.name for r in recordings
                                            if r.target_current is None]):
            raise ValueError(f"model sp_c needs the target current; {lacking[0]} does not "
                             "log it")
        data = training_set(recordings, inputs, max_rows=max_rows, progress=progress,
                            signals=signals if MODEL_SIGNALS[model] == "auto" else ())
    if model == "sp_c" and "target_current" not in data.features.signals_:
        raise ValueError("model sp_c needs the target current; "
                         + ("the training recordings do not all log it"
                            if not data.has_target_current else
                            "the inputs were computed without it (signals)"))
    features = _model_features(model, data.features)
    n = data.y.shape[1]
    n_support = resolve_n_support(n_support, len(data.y))
    params = dict(n_support=n_support, optimizer=optimizer,
                  batch_size=min(512, n_support), random_state=seed, n_jobs=n_jobs)
    if sigma_v is not None or model in ("sp_p", "gp"):
        params["sigma_v"] = DEFAULT_SIGMA_V if sigma_v is None else sigma_v
    regressor = _build(model, robot, n, params, coulomb_width)
    bar = _bar(progress, f"fitting {model.upper()} ({n} joints)", n)
    with (_count_fitted_outputs(bar) if progress is not None else contextlib.nullcontext()):
        regressor.fit(data.X, data.y)
    training = {
        "model": model, "inputs": data.inputs, "n_support": int(n_support),
        "optimizer": optimizer, "optimizer_used": str(regressor.optimizer_),
        "batch_size": int(params["batch_size"]), "seed": seed,
        # the detector's regimes take it from here (calibrate_detector), given or not
        "sigma_v": params.get("sigma_v", DEFAULT_SIGMA_V), "coulomb_width": coulomb_width,
        "signals": list(features.signals_),
        "robot": None if robot is None else robot.name, "recordings": list(data.names),
        "n_rows": int(data.n_rows), "n_rows_used": int(len(data.y)), "step": int(data.step),
        "acceleration_limit": acceleration_limit(data), "units": data.units,
        "signal_ranges": data.signal_ranges,
    }
    return TrainedModel(regressor=regressor, features=features, training=training)


def training_report(trained):
    """What ``gpcd train`` prints about a trained model: data, fit and braking limit.

    Parameters
    ----------
    trained : TrainedModel

    Returns
    -------
    text : str

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> t = np.arange(100) * 0.01
    >>> rec = Recording(time=t, q=np.sin(t)[:, None], qd=np.cos(t)[:, None],
    ...                 current=np.sin(t)[:, None], target_current=np.sin(t)[:, None])
    >>> print(training_report(train_model([rec], model="sp_c", n_support=20)))
    ... # doctest: +ELLIPSIS
    trained SP_C without a robot model (1 joints) on 1 recording(s), 100 rows, causal inputs
      GP support 20 rows per joint, optimizer ...
    """
    info, regressor = trained.training, trained.regressor
    robot = info.get("robot")
    lml = np.atleast_1d(regressor.log_marginal_likelihood_value_)
    return "\n".join([
        f"trained {info['model'].upper()} "
        + (f"for robot {robot} " if robot is not None else "without a robot model ")
        + f"({trained.features.n_joints_} joints) on {len(info['recordings'])} recording(s), "
        f"{info['n_rows']} rows, {info['inputs']} inputs"
        + (f" (1 row in {info['step']} used: {info['n_rows_used']})"
           if info["step"] > 1 else ""),
        f"  GP support {info['n_support']} rows per joint, optimizer {regressor.optimizer_}, "
        f"iterations per joint {np.atleast_1d(regressor.n_iter_).tolist()}, "
        f"sigma_v {info['sigma_v'] if info['sigma_v'] is not None else '-'}, "
        + (f"Coulomb tanh(qd / {info['coulomb_width']:g}), "
           if info.get("coulomb_width") is not None else "")
        + f"seed {info['seed']}, controller signals {', '.join(info['signals']) or 'none'}",
        "  log marginal likelihood per joint: " + ", ".join(f"{v:.4g}" for v in lml),
        f"  largest |qdd| of the training rows {info['acceleration_limit']:.3g} rad/s^2 "
        "(the braking limit of gpcd calibrate --braking)"])


def save_model(trained, path):
    """Write a :class:`TrainedModel` (``.skops``, or ``.joblib`` / ``.pkl``).

    Parameters
    ----------
    trained : TrainedModel
        What :func:`train_model` returned.
    path : str or path-like
        The extension chooses the format.

    Returns
    -------
    path : Path

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from sklearn.linear_model import LinearRegression
    >>> trained = TrainedModel(LinearRegression().fit([[0.0], [1.0]], [0.0, 1.0]), None,
    ...                        {"model": "p_f"})
    >>> save_model(trained, pathlib.Path(tempfile.mkdtemp()) / "m.joblib").name
    'm.joblib'
    """
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..persistence import save

    return save({"kind": MODEL_KIND, "regressor": trained.regressor,
                 "features": trained.features, "training": trained.training}, path)


def load_model(path, trust_pickle=False):
    """Read a model file written by ``gpcd train`` (:func:`save_model`).

    Parameters
    ----------
    path : str or path-like
        A model file.
    trust_pickle : bool, default=False
        Load a ``.joblib`` / ``.pkl`` file (a pickle runs any code it
        carries; see :func:`sklearn_gpcd.load`).

    Returns
    -------
    trained : TrainedModel

    Raises
    ------
    ValueError
        If the file is not a model file (e.g. a detector file from ``gpcd
        calibrate``, or a bare regressor).
    MalformedFileError
        If the file is damaged, or holds values that are not finite or
        parameters out of range, or a regressor that does not predict: one
        line naming the field and the command that rebuilds the file.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from sklearn.linear_model import LinearRegression
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "model.joblib"
    >>> trained = TrainedModel(LinearRegression().fit([[0.0], [1.0]], [0.0, 1.0]), None,
    ...                        {"inputs": "causal"})
    >>> _ = save_model(trained, path)
    >>> load_model(path, trust_pickle=True).training  # our own pickle
    {'inputs': 'causal'}
    """
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ._file_checks import check_model_bundle, load_checked

    fix = f"rebuild it with gpcd train RECORDINGS -o {path}"
    bundle = load_checked(path, trust_pickle, fix)
    kind = bundle.get("kind") if isinstance(bundle, dict) else type(bundle).__name__
    if kind != MODEL_KIND:
        raise ValueError(f"{path}: not a model file written by gpcd train (it holds "
                         f"{kind!r}); train one with gpcd train")
    check_model_bundle(bundle, path, fix)
    return TrainedModel(bundle["regressor"], bundle["features"],
                        dict(bundle.get("training") or {}))


# ---------------------------------------------------------------- progress
class _NoBar:
    def update(self, n=1):
        pass


def _bar(progress, label, total):
    return _NoBar() if progress is None else progress(label, total)


@contextlib.contextmanager
def _count_fitted_outputs(progress):
    """Advance ``progress`` once per output a :class:`SemiParametricGPRegressor` fits.

    Outputs may be fitted in other processes (``n_jobs``): each finished
    output appends one byte to a temporary file, which a thread of this
    process polls.
    """
    # deferred: gpcd starts without scikit-learn (test_architecture.py)
    from ..gp import regressor

    fit_output = regressor._fit_output
    handle, ticks = tempfile.mkstemp(prefix="gpcd-progress-")
    os.close(handle)

    def counted(*args, **kwargs):
        result = fit_output(*args, **kwargs)
        with open(ticks, "a") as log:
            log.write(".")
        return result

    stop = threading.Event()

    def poll():
        seen = 0
        while True:
            stopped = stop.wait(0.5)
            now = os.path.getsize(ticks)
            if now > seen:
                progress.update(now - seen)
                seen = now
            if stopped:
                return

    watcher = threading.Thread(target=poll, daemon=True)
    regressor._fit_output = counted
    watcher.start()
    try:
        yield
    finally:
        regressor._fit_output = fit_output
        stop.set()
        watcher.join()
        os.unlink(ticks)


def _warn_once_per_kind(caught, n_recordings):
    """Re-issue recorded warnings, one per category (with how many recordings had it)."""
    by_kind = {}
    for w in caught:
        by_kind.setdefault(w.category, []).append(str(w.message))
    for category, messages in by_kind.items():
        more = (f" (and alike for {len(messages) - 1} more of the {n_recordings} recordings)"
                if len(messages) > 1 else "")
        warnings.warn(messages[0] + more, category, stacklevel=3)
