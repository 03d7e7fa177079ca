"""The diagnosis estimator: locate, name, model and show missing physics."""

import os
import time as _time
from dataclasses import replace
from numbers import Integral, Real

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.utils._param_validation import HasMethods, Interval
from sklearn.utils.validation import check_is_fitted

from scipy import stats as _stats

from .._gate import DEFAULT_SIGMA_V, SIGMA_V_CONSTRAINT
from .._persistence import VersionedStateMixin
from ..robots import Robot
from ..io import degrees_note, units_note
from ..metrics import nmse
from .align import align_recordings
from .effects import IDENTIFIABLE_SE, effect_library, sample_period  # noqa: F401
from .identifiability import identifiability, needs, variance_inflation
from .locate import residual_breakdown
from .stability import ADD_INCLUSION, MIN_INCLUSION, N_RESAMPLES, stability
from .model import joint_fit
from .nominal import NominalModel, Signals, check_recordings
from .selection import EXCITATION, MIN_GAIN, MIN_SHARE, MIN_T, PAIR_SEPARATION, \
    build_candidates, expand_composites, fold_index, fold_statistics, forward_selection, \
    given_others, plausibility_check, separating_excitation

#: Times the selection is rerun after effects were dropped by the joint fit.
MAX_RESELECTIONS = 2
#: Significance level of the Wald test on a named effect's parameters
#: (autocorrelation-corrected covariance): the parameters must differ from
#: zero at this level.
WALD_LEVEL = 1e-3
#: A torque-constant change that the recordings could not show on a joint
#: (:meth:`TorqueConstantEffect.smallest_changes`) is reported as not identifiable from
#: them when it is larger than this (a 10 % error of a motor constant
#: matters for force estimation).
IDENTIFIABLE_CHANGE = 0.1
#: How far [rad] a plan may go beyond the range the recordings covered.
PLAN_MARGIN = 0.7


def _inseparable_friction(effects):
    """A Stribeck peak and a softening on one joint with velocity scales too close to tell.

    Returns ``[(index, reason)]`` for the one of the pair that explains less
    (the refit may move the two scales together, where their difference is
    only a reshaping of the friction curve), else an empty list.
    """
    velocity = {f.name: f.effect.velocity_parameter for f in effects
                if getattr(f.effect, "velocity_parameter", None)}
    by_joint = {}
    for k, f in enumerate(effects):
        if f.name in velocity:
            by_joint.setdefault(f.target, {})[f.name] = k
    out = []
    for pair in by_joint.values():
        if len(pair) < 2:
            continue
        (a, ka), (b, kb) = sorted(pair.items())
        va = effects[ka].parameters[velocity[a]][0]
        vb = effects[kb].parameters[velocity[b]][0]
        if max(va, vb) < PAIR_SEPARATION * min(va, vb):
            weak, other = sorted([ka, kb], key=lambda k: effects[k].explained_variance)
            out.append((weak, f"its velocity scale is within a factor {PAIR_SEPARATION:g} of "
                              f"the {effects[other].name.replace('_', ' ')} on the same joint "
                              f"({va:.3g} and {vb:.3g} rad/s): the recordings cannot separate "
                              "a peak from a softening there"))
    return out


def _group_words(row):
    """``" (any of X 70 %, Y 30 %)"``: the members of a group of confounded alternatives."""
    if len(row["group"]) < 2:
        return ""
    return " (any of " + ", ".join(
        f"{row['labels'][f]} {100 * p:.0f} %" for f, p in sorted(
            row["group"].items(), key=lambda kv: -kv[1])) + ")"


def _group_ambiguity(chosen, row, table):
    """An ``ambiguities_`` entry for a kept group: "cannot tell X from Y", each share."""
    others = [f for f in row["group"] if f != chosen.family]
    rival = max(others, key=lambda f: (row["group"][f], row["correlations"].get(f, 0.0)))
    alternative = table.get(rival, {}).get("candidate")
    joints = sorted(int(j) for j in set(chosen.joints) | set(getattr(alternative, "joints",
                                                                     ())))
    return {"chosen": chosen.label, "effect": chosen.effect.name,
            "alternative": row["labels"][rival], "alternative_effect": rival[0],
            "joints": joints,
            "correlation": max(row["correlations"].get(f, 0.0) for f in others),
            "inclusion": row["group_inclusion"],
            "shares": {row["labels"][f]: p for f, p in row["group"].items()},
            "text": f"cannot tell {chosen.label} from "
                    + " or ".join(row["labels"][f] for f in others)
                    + " in these recordings: the group is named in "
                      f"{100 * row['group_inclusion']:.0f} % of the resamples"
                    + _group_words(row),
            "excitation": separating_excitation(chosen.effect.name, rival[0], joints)}


def _fallback_variant(step, fitted, candidates):
    """The variant the effect falls back on when ``fitted`` is implausible, or None.

    :meth:`~sklearn_gpcd.diagnosis.Effect.fallback_variant` picks it among
    the candidates of the same effect and target (a softening of another
    shape falls back on the Gaussian one).
    """
    variants = [c for c in candidates if c.effect.name == fitted.name and not c.parts
                and c.target == fitted.target]
    k = fitted.effect.fallback_variant(fitted.settings, [c.settings for c in variants])
    if k is None:
        return None
    best = variants[k]
    return replace(step, candidate=best, theta=None) if hasattr(step, "candidate") else best


def units_problem(recording):
    """Why ``recording``'s units look wrong (degrees, milliseconds, ...), or None.

    The checks of the readers (:mod:`sklearn_gpcd.io`): positions beyond
    ``2 pi`` on many samples, or position steps that disagree with the
    velocities times the time steps.

    Parameters
    ----------
    recording : Recording

    Returns
    -------
    reason : str or None

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> t = np.arange(0, 2, 0.01)
    >>> q = np.c_[np.sin(t), np.cos(t)]
    >>> rec = Recording(time=t, q=q, qd=np.c_[np.cos(t), -np.sin(t)], current=q)
    >>> units_problem(rec) is None
    True
    >>> units_problem(Recording(time=t * 1000, q=q, qd=rec.qd, current=q))[-52:]
    'time looks like milliseconds (pass time_scale=1e-3).'
    """
    labels = [f"q{j + 1}" for j in range(recording.n_joints)]
    notes = [degrees_note(recording.q),
             units_note(recording.time, recording.q, recording.qd, labels)]
    notes = [n for n in notes if n]
    return " ".join(notes) if notes else None


class DynamicsDiagnosis(VersionedStateMixin, BaseEstimator):
    """Find the physics a nominal robot model is missing, from recordings.

    Given a nominal model ("the simulation": a robot, its torque constants and
    optionally its known friction) and real recordings, :meth:`fit`

    1. **locates** the residual between measured and nominal current by
       joint, regime, configuration region and time
       (:func:`~sklearn_gpcd.diagnosis.residual_breakdown`);
    2. **names** the missing effects: every effect of the library
       (:mod:`~sklearn_gpcd.diagnosis.effects`) competes in a greedy forward
       selection scored on held-out time blocks
       (:mod:`~sklearn_gpcd.diagnosis.selection`); an effect is kept only
       when it reliably lowers the held-out error;
    3. **models** them: the selected effects are refitted jointly into a
       :class:`~sklearn_gpcd.diagnosis.DiagnosedModel`, usable as the GP's
       parametric mean;
    4. **shows** the improvement: :meth:`evaluate` gives the per-joint nMSE
       before/after on held-out recordings and :meth:`report` a text/JSON
       report and figure.

    Instead of a model, the reference can be a simulated run of the same
    trajectory per real recording (``simulated`` in :meth:`fit`); it is
    time-aligned by :func:`~sklearn_gpcd.diagnosis.align_recordings`. The
    robot is still needed for the effects' columns.

    Parameters
    ----------
    robot : str, path or Robot, default="ur10"
        Built-in robot name, URDF path or :class:`~sklearn_gpcd.robots.Robot`
        (its ``model.armature`` holds the nominal rotor inertias).
    torque_constants : array-like of shape (n_joints,), default=None
        Nominal ``K`` [Nm/A]; None reads ``robot.torque_constants``.
    friction : None, dict, JointFriction-like or callable, default=None
        Known nominal friction (see :class:`NominalModel`). Without it,
        Coulomb/viscous friction are reported as missing.
    effects : "all" or list of str or Effect, default="all"
        Effects to test (names of :data:`~sklearn_gpcd.diagnosis.effects.EFFECTS`).
    sigma_rest : float, default=1e-3
        Rows where a joint is slower than this [rad/s] are left out of that
        joint's fit (sticking friction is not a function of the state).
    rest_guard : float, default=0.04
        Rows within this many seconds of such a rest are left out of the fit
        of effects that need it (a delayed log mixes in the holding current
        of the stuck joint; see ``Effect.rest_guard``) and of every effect
        once one of them is selected.
    sigma_v : float, default=1e-2
        Quasi-static threshold for the regime breakdown (paper Eq. 15).
    n_splits : int, default=5
        Time blocks per recording = cross-validation folds.
    min_gain : float, default=0.02
        Minimum share of the held-out error of its joints an effect must
        remove to be selected.
    min_t : float, default=3.0
        Minimum t-statistic of its per-fold gains.
    max_effects : int, default=None
        Upper bound on the number of selected effects.
    min_share : float, default=0.01
        Minimum share of the nominal residual's sum of squares on its joints
        an effect must explain (practical significance).
    check_units : bool, default=True
        Refuse recordings whose units look wrong (positions in degrees, time
        in milliseconds: :func:`units_problem`) with a ValueError. Set False
        only after confirming the units.
    base_model : DiagnosedModel, default=None
        A model refined by an earlier diagnosis (e.g. on unloaded runs) to
        diagnose against: its prediction is the reference current, and
        ``robot``, ``torque_constants`` and ``friction`` are taken from it.

    Attributes
    ----------
    nominal_ : NominalModel
    model_ : DiagnosedModel
        Nominal model plus the fitted effects.
    effects_ : list of FittedEffect
        The missing effects found (empty when nothing is missing).
    rejected_effects_ : list of dict
        Estimates rejected as physically implausible or insignificant:
        ``name``, ``effect``, ``joints`` (0-based), ``reason``, ``implausible``
        (False when rejected as insignificant).
    unidentifiable_ : list of dict
        Effects these recordings cannot show at a size that matters, said
        so rather than left unmentioned (a miss is not a finding of
        "nothing"). For now the torque constants: per joint where none was
        named and a change of up to ``IDENTIFIABLE_CHANGE`` (10 %) cannot be
        told from a friction change of the joint (it moves the part of the
        joint's current no friction term can mimic by less than 3
        autocorrelation-corrected standard errors, or by less than
        ``min_share`` / ``min_gain`` asks): ``effect``, ``joints`` (0-based),
        ``smallest_change`` (from which change on it could be told, as a
        fraction), ``friction_share`` (share of the joint's reference current
        that friction columns reproduce) and the ``excitation`` that would
        show it.
    identifiability_ : list of dict
        Per candidate family, from the information matrix of the candidates
        on these recordings given the named effects
        (:func:`~sklearn_gpcd.diagnosis.identifiability.identifiability`):
        smallest detectable size of its first parameter, condition, and the
        candidates it is confounded with (partial correlation >= 0.9).
    needs_ : list of dict
        Families not named whose smallest detectable size exceeds the size
        that matters (``effect``, ``joints``, ``reason``): what
        :meth:`plan` asks a new recording for.
    ambiguities_ : list of dict
        Effects the recordings cannot tell apart: ``chosen``,
        ``alternative``, their effect names, ``joints`` (0-based),
        ``correlation`` of their fitted terms and the ``excitation`` that
        would separate them.
    breakdown_ : ResidualBreakdown
        Residual of the nominal model on the training recordings.
    breakdown_after_ : ResidualBreakdown
        Residual of the refined model on the training recordings.
    history_ : list of list of Step
        Evidence of every candidate at every forward step.
    n_candidates_ : int
        Candidates tested (effect x joint/link x nonlinear setting).
    training_summary_ : dict
        Recordings, samples, duration, and time spent.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> from sklearn_gpcd.robots import load_robot
    >>> from sklearn_gpcd.diagnosis import DynamicsDiagnosis, NominalModel
    >>> robot = load_robot("ur10")
    >>> t = np.arange(0, 20, 0.01)
    >>> q = 0.5 * np.sin(np.outer(t, [0.5, 0.7, 0.9, 1.1, 1.3, 1.5]))
    >>> q += [0, -1.5, 1.5, -1.5, -1.5, 0]
    >>> qd = np.gradient(q, t, axis=0); qdd = np.gradient(qd, t, axis=0)
    >>> i = NominalModel(robot).current(q, qd, qdd) + 0.5 * np.sign(qd) / robot.torque_constants
    >>> rec = Recording(time=t, q=q, qd=qd, qdd=qdd, current=i + 0.01 * np.sin(50 * t)[:, None])
    >>> diag = DynamicsDiagnosis(robot, effects=["coulomb_friction", "payload"]).fit(rec)
    >>> sorted({e.name for e in diag.effects_})
    ['coulomb_friction']
    """

    _parameter_constraints = {
        "robot": [str, os.PathLike, Robot],
        "torque_constants": [None, "array-like"],
        "friction": "no_validation",            # None, dict, JointFriction-like or callable
        "effects": [str, list, tuple],
        "sigma_rest": [Interval(Real, 0, np.inf, closed="left")],
        "rest_guard": [Interval(Real, 0, np.inf, closed="left")],
        "sigma_v": [SIGMA_V_CONSTRAINT],
        "n_splits": [Interval(Integral, 2, None, closed="left")],
        "min_gain": [Interval(Real, 0, 1, closed="left")],
        "min_t": [Interval(Real, 0, np.inf, closed="left")],
        "max_effects": [None, Interval(Integral, 0, None, closed="left")],
        "min_share": [Interval(Real, 0, 1, closed="left")],
        "check_units": ["boolean"],
        "base_model": [None, HasMethods(["predict_signals"])],
    }

    def __init__(self, robot="ur10", torque_constants=None, friction=None, effects="all",
                 sigma_rest=1e-3, rest_guard=0.04, sigma_v=DEFAULT_SIGMA_V, n_splits=5,
                 min_gain=MIN_GAIN, min_t=MIN_T,
                 max_effects=None, min_share=MIN_SHARE, check_units=True, base_model=None):
        self.robot = robot
        self.torque_constants = torque_constants
        self.friction = friction
        self.effects = effects
        self.sigma_rest = sigma_rest
        self.rest_guard = rest_guard
        self.sigma_v = sigma_v
        self.n_splits = n_splits
        self.min_gain = min_gain
        self.min_t = min_t
        self.max_effects = max_effects
        self.min_share = min_share
        self.check_units = check_units
        self.base_model = base_model

    # ------------------------------------------------------------ helpers
    def _references(self, recordings, simulated, what):
        """Aligned simulated currents (or the base model's) for each recording."""
        if simulated is None:
            if self.base_model is not None:
                return list(self.base_model.predict(list(recordings))), None
            return None, None
        sims = check_recordings(simulated, self.nominal_.n_joints, f"{what} (simulated)")
        if len(sims) != len(recordings):
            raise ValueError(
                f"{what}: {len(recordings)} real recordings but {len(sims)} simulated runs; "
                "pass one simulated run per real recording"
            )
        pairs = [align_recordings(s, r) for s, r in zip(sims, recordings)]
        return [p[0] for p in pairs], [p[1] for p in pairs]

    def _signals(self, recordings, simulated, what):
        recordings = check_recordings(recordings, self.nominal_.n_joints, what)
        if self.check_units:
            for k, rec in enumerate(recordings):
                problem = units_problem(rec)
                if problem:
                    raise ValueError(
                        f"{what}: recording {rec.name or f'#{k}'!r}: {problem} The diagnosis "
                        "needs rad, rad/s and s; convert the recording, or confirm the units "
                        "with check_units=False (gpcd diagnose --units-confirmed)")
        references, lags = self._references(recordings, simulated, what)
        return Signals.from_recordings(self.nominal_, recordings, references), lags

    def _mask(self, signals, guard=False):
        """Rows used per joint: moving (and with ``guard``, not within ``rest_guard`` of a rest)."""
        rest = np.abs(signals.qd) < self.sigma_rest
        if not guard or signals.time is None or not self.rest_guard:
            return ~rest
        near = rest.copy()
        for seg in np.unique(signals.segment):
            rows = np.flatnonzero(signals.segment == seg)
            step = float(np.median(np.diff(signals.time[rows]))) if rows.size > 1 else 1.0
            width = int(np.ceil(self.rest_guard / step)) if step > 0 else 0
            if width == 0:
                continue
            kernel = np.ones(2 * width + 1)
            for j in range(signals.n_joints):
                hits = np.convolve(rest[rows, j].astype(float), kernel, mode="same")
                near[rows, j] = hits > 0.5
        return ~near

    # ---------------------------------------------------------------- API
    def fit(self, recordings, simulated=None):
        """Locate, name and model what the nominal model is missing.

        Parameters
        ----------
        recordings : Recording or list of Recording
            Real (measured) recordings.
        simulated : Recording or list of Recording, default=None
            One simulated run of the same trajectory per real recording; its
            time-aligned current replaces the nominal model's prediction.

        Returns
        -------
        self : DynamicsDiagnosis
        """
        start = _time.perf_counter()
        self._validate_params()
        if self.base_model is not None:
            self.nominal_ = self.base_model.nominal
        else:
            self.nominal_ = NominalModel(self.robot, self.torque_constants, self.friction)
        library = effect_library(self.effects)
        signals, lags = self._signals(recordings, simulated, "recordings")
        mask = self._mask(signals)
        units = self.units_ = check_recordings(recordings, self.nominal_.n_joints)[0].units
        residual = signals.current - signals.reference
        self._sample_period = sample_period(signals)
        self.breakdown_ = residual_breakdown(signals, residual, self.sigma_v, self.sigma_rest,
                                             units=units)
        prepared = _time.perf_counter()

        candidates, design = build_candidates(signals, self.nominal_, library)
        folds = fold_index(signals, self.n_splits)
        stats = fold_statistics(candidates, design, residual, mask, folds, self.n_splits,
                                signals.current)
        guarded_mask, guarded = mask, None
        if any(c.effect.rest_guard for c in candidates):
            guarded_mask = self._mask(signals, guard=True)
            guarded = fold_statistics(candidates, design, residual, guarded_mask, folds,
                                      self.n_splits, signals.current)
        self.rejected_effects_ = []
        plausible, banned = plausibility_check(self.nominal_), {}

        def check(candidate, theta):
            for name in (candidate.label, *(part.label for part in candidate.parts)):
                if name in banned:
                    return f"dropped after the joint fit: {banned[name]}"
            if theta is not None and np.size(theta):
                reason = candidate.effect.unresolved(float(np.ravel(theta)[0]),
                                                     self._sample_period)
                if reason:
                    return reason
            return plausible(candidate, theta)

        for _ in range(MAX_RESELECTIONS + 1):
            # an effect found implausible after the joint fit is banned and the selection
            # rerun, so that the next candidate (e.g. the payload after an implausible link
            # mass) is considered
            self.ambiguities_ = []
            selected, self.history_ = forward_selection(
                stats, candidates, self.min_gain, self.min_t, self.max_effects, guarded,
                min_share=self.min_share, check=check, rejections=self.rejected_effects_,
                ambiguities=self.ambiguities_)
            n_rejected = len(self.rejected_effects_)
            self.model_ = self._final_fit(signals, selected, mask, guarded_mask, candidates)
            # (a friction peak or softening flipping sign in the refit is left dropped: the
            # other friction terms of the joint cover it)
            final = {e.name for e in library if e.refit_drop_is_final}
            dropped = [r for r in self.rejected_effects_[n_rejected:] if r["implausible"]
                       and r["effect"] not in final]
            if not dropped:
                break
            banned.update({r["name"]: r["reason"] for r in dropped})
        self._stable(signals, candidates, design, residual, (mask, guarded_mask), check,
                     [step.candidate for step in selected],
                     (stats, stats if guarded is None else guarded))
        selection_done = _time.perf_counter()
        self.effects_ = self.model_.effects
        kept = {f.effect.name for f in self.effects_}
        self.ambiguities_ = [a for a in self.ambiguities_ if a["effect"] in kept]
        if any(f.effect.rest_guard for f in self.effects_):
            mask = guarded_mask
        after = signals.current - self.model_.predict_signals(signals)
        self.unidentifiable_ = []
        for effect in library:
            limits = effect.smallest_changes(signals, residual, after, mask, self.min_share,
                                             self.min_gain)
            named = {f.target for f in self.effects_ if f.name == effect.name}
            for j, change, mimicked in limits or ():
                if j in named or change <= IDENTIFIABLE_CHANGE:
                    continue
                self.unidentifiable_.append({
                    "effect": effect.name, "joints": [int(j)],
                    "smallest_change": change, "friction_share": mimicked,
                    "excitation": EXCITATION[effect.name]})
        self.identifiability_ = self._identifiability(candidates, stats, after, mask)
        self.needs_ = needs(self.identifiability_)
        self._poses = (np.median(signals.q, axis=0), signals.q.min(0), signals.q.max(0))
        self.breakdown_after_ = residual_breakdown(signals, after, self.sigma_v, self.sigma_rest,
                                                   units=units)
        self.n_candidates_ = len(candidates)
        self.nmse_train_before_ = nmse(signals.current, signals.reference, mask=mask)
        self.nmse_train_after_ = nmse(signals.current, self.model_.predict_signals(signals),
                                      mask=mask)
        end = _time.perf_counter()
        self.training_summary_ = {
            "recordings": list(signals.names),
            "n_samples": int(signals.n_samples),
            "duration": float(sum(signals.time[signals.segment == s][-1]
                                  for s in np.unique(signals.segment))),
            "alignment_lags": lags,
            "seconds": {"prepare": prepared - start, "select": selection_done - prepared,
                        "fit": end - selection_done, "total": end - start},
        }
        return self

    def _stable(self, signals, candidates, design, residual, masks, check, picked,
                stats):
        """Keep and add the effects a block bootstrap of the selection names often enough.

        :func:`~sklearn_gpcd.diagnosis.stability.stability` runs the
        per-resample selection on ``N_RESAMPLES`` block-bootstrap resamples;
        an effect named on all data whose group of confounded alternatives
        (itself and the unnamed families the recordings cannot tell it from)
        is named in fewer than ``MIN_INCLUSION`` of them is dropped (recorded
        in ``rejected_effects_``); a kept group is represented by its member
        named most often (when that is not the all-data pick, it replaces it),
        and when the resamples named more than one member ``ambiguities_``
        says "cannot tell X from Y" with each member's share. One the
        all-data selection missed, in no kept group, but that the resamples
        name in at least ``ADD_INCLUSION`` of them is
        added (in the variant they picked most often), and the set is
        refitted jointly (:meth:`_final_fit`: the same plausibility, share
        and Wald checks), so that an effect conditioned on the group (a delay
        next to a payload) is tested with the group's member in the model.
        """
        self.stability_ = stability(
            candidates, design, residual, masks, signals, signals.current, self.nominal_,
            self.model_.effects, self.history_,
            {"n_splits": self.n_splits, "min_gain": self.min_gain, "min_t": self.min_t,
             "min_share": self.min_share, "check": check,
             "n_resamples": N_RESAMPLES}, picked)
        steps, effects = self._kept_steps, self.model_.effects
        rows = [self.stability_[(f.name, f.target)] for f in effects]
        for f, row in zip(effects, rows):
            if row["group_inclusion"] < MIN_INCLUSION:
                self.rejected_effects_.append({
                    "name": f.name if f.target is None else f"{f.name}[joint {f.target + 1}]",
                    "effect": f.name, "joints": [int(j) for j in f.joints],
                    "reason": f"named in {100 * row['group_inclusion']:.0f} % of "
                              f"{N_RESAMPLES} block-bootstrap resamples"
                              f"{_group_words(row)} "
                              f"(needs {100 * MIN_INCLUSION:.0f} %)",
                    "implausible": False})
        kept, swapped = [], False
        for step, row in zip(steps, rows):
            if row["group_inclusion"] < MIN_INCLUSION:
                continue
            cand = getattr(step, "candidate", step)
            other = self.stability_.get(row["member"], {}).get("candidate")
            if row["member"] != cand.family and other is not None and \
                    all(k.family != other.family for k in kept):  # (not twice)
                cand, swapped = other, True
            kept.append(cand)
            if sum(share > 0 for share in row["group"].values()) > 1:
                # the resamples did not settle on one member (a member every resample
                # names beats an alternative the fit rejects by its sign or size)
                self.ambiguities_.append(_group_ambiguity(cand, row, self.stability_))
        families = {c.family for c in kept} | {(f.name, f.target) for f in effects}
        families |= {g for row in rows if row["group_inclusion"] >= MIN_INCLUSION
                     for g in row["group"]}
        added = [row["candidate"] for family, row in self.stability_.items()
                 if family not in families and row["inclusion"] >= ADD_INCLUSION
                 and row["candidate"] is not None]
        if not added and len(kept) == len(steps) and not swapped:
            return
        chosen = kept + sorted(added, key=lambda c: c.order)
        on = stats[1] if any(c.effect.rest_guard for c in chosen) else stats[0]
        evidence = given_others(on, chosen) if chosen else []
        self.model_ = self._final_fit(signals, evidence, masks[0], masks[1], candidates)

    def _identifiability(self, candidates, stats, after, mask):
        """The identifiability table of the candidates given the named effects."""
        variance = np.array([np.var(after[mask[:, j], j]) if mask[:, j].any() else np.nan
                             for j in range(after.shape[1])])
        weights = np.where(np.isfinite(variance) & (variance > 0), 1.0 / variance, 0.0)
        named = []
        for f in self.effects_:
            family = [c for c in candidates if not c.parts and c.family == (f.name, f.target)]
            if family:
                named.append(min(family, key=lambda c: sum(
                    abs(np.log(max(abs(float(v)), 1e-9) / max(abs(float(f.settings.get(k, v))),
                                                                1e-9)))
                    for k, v in c.settings.items() if isinstance(v, (int, float)))))
        return identifiability(candidates, stats.totals()[0], weights, named, self.nominal_,
                               variance_inflation(after, mask))

    def plan(self, max_seconds=180.0, velocity_limits=None, acceleration_limits=None,
             random_state=0):
        """The recording to make next: an excitation for what these recordings could not show.

        One segment per kind of need of :attr:`needs_` (most needed first,
        :mod:`~sklearn_gpcd.diagnosis.plan`), about the recordings' median
        pose, within the robot's position limits (and the recorded range
        widened by ``PLAN_MARGIN``), its velocity limits and
        ``acceleration_limits``, at the recordings' sample period; a slow
        all-joint confirmation segment closes it.

        Parameters
        ----------
        max_seconds : float, default=180
        velocity_limits : array-like, default=None
            [rad/s] per joint; None reads the robot's.
        acceleration_limits : float or array-like, default=None
            [rad/s^2]; None gives ``plan.MAX_ACCELERATION``.
        random_state : int, default=0

        Returns
        -------
        plan : ExcitationPlan
        """
        from .plan import excitation_plan, robot_limits  # deferred: the plan's own, opt-in

        check_is_fitted(self, "model_")
        center, low, high = self._poses
        limits = robot_limits(self.nominal_.robot, velocity_limits, acceleration_limits)
        limits.lower = np.maximum(limits.lower, low - PLAN_MARGIN)
        limits.upper = np.minimum(limits.upper, high + PLAN_MARGIN)
        wanted = self.needs_
        period = self._sample_period or 0.008
        return excitation_plan(wanted, self.nominal_, center, period, limits, max_seconds,
                               random_state)

    def _final_fit(self, signals, selected, mask, guarded_mask, candidates=()):
        """Joint fit; effects implausible or insignificant after it are dropped, one at a time.

        After the joint refit an effect must still be physically plausible
        (:meth:`Effect.implausible`), explain at least ``min_share`` of the
        nominal residual on its joints, and its parameters must differ from
        zero (Wald test at :data:`WALD_LEVEL` with the autocorrelation-
        corrected covariance).
        """
        selected = expand_composites(selected)
        while True:
            guard = any(s.candidate.effect.rest_guard for s in selected)
            model = joint_fit(signals, self.nominal_, selected,
                              guarded_mask if guard else mask)
            problems = [(k, reason) for k, f in enumerate(model.effects)
                        if (reason := self._problem(f, model.effects))] or \
                _inseparable_friction(model.effects)
            implausible = {k for k, f in enumerate(model.effects)
                           if self._implausible(f, model.effects)}
            if not problems:
                self._kept_steps = selected
                return model
            k, reason = min(problems, key=lambda p: model.effects[p[0]].explained_variance)
            fitted = model.effects[k]
            label = selected[k].candidate.label if hasattr(selected[k], "candidate") else \
                fitted.name
            reason += fitted.effect.variant_note(fitted.settings)
            if all(r["name"] != label or r["reason"] != reason
                   for r in self.rejected_effects_):  # not the verdict of an earlier fit
                self.rejected_effects_.append({
                    "name": label, "effect": fitted.name,
                    "joints": [int(j) for j in fitted.joints], "reason": reason,
                    "implausible": k in implausible})
            fallback = _fallback_variant(selected[k], fitted, candidates) \
                if k in implausible else None
            if fallback is None:
                del selected[k]
            else:
                # a softening of another shape that grew implausible in the refit: the
                # joint's dry friction still softens, try the Gaussian shape (once)
                selected[k] = fallback

    def _implausible(self, fitted, effects):
        """Why a jointly fitted effect is physically implausible, or None.

        Finer than the recordings resolve (:meth:`Effect.unresolved`), or
        implausible given what the other effects on its target tell it
        (:meth:`Effect.implausible_among`, :meth:`Effect.context`).
        """
        first = fitted.effect.parameter_names[0] if fitted.effect.parameter_names else None
        if first in fitted.parameters:
            reason = fitted.effect.unresolved(fitted.parameters[first][0],
                                              getattr(self, "_sample_period", 0.0))
            if reason:
                return reason
        context = {}
        for f in effects:
            if f is not fitted and f.target == fitted.target:
                for key, value in f.effect.context(f.parameters).items():
                    context[key] = context.get(key, 0.0) + value
        return fitted.effect.implausible_among(fitted.parameters, fitted.target, self.nominal_,
                                               context)

    def _problem(self, fitted, effects=()):
        """Why a jointly fitted effect is not reported, or None."""
        reason = self._implausible(fitted, effects)
        if reason:
            return reason
        # practical significance on the joint where the effect shows most (a fixed
        # yardstick: the nominal residual; see selection.MIN_SHARE)
        share = fitted.joint_share if np.isfinite(fitted.joint_share) else \
            fitted.explained_variance
        if np.isfinite(share) and share < self.min_share:
            return (f"explains {100 * share:.2g} % of the nominal residual on its joints "
                    f"(needs {100 * self.min_share:g} %)")
        theta, cov = np.asarray(fitted.theta), np.asarray(fitted.cov)
        wald = float(theta @ np.linalg.pinv(cov) @ theta) if theta.size else 0.0
        p_value = float(_stats.chi2.sf(wald, max(theta.size, 1)))
        if p_value > WALD_LEVEL:
            return (f"its parameters do not differ from zero (Wald test p = {p_value:.2g}, "
                    f"needs <= {WALD_LEVEL:g})")
        return None

    def predict(self, recordings, simulated=None):
        """Refined currents of recordings (see :meth:`DiagnosedModel.predict`).

        Parameters
        ----------
        recordings : Recording or list of Recording
        simulated : Recording or list of Recording, default=None
            Paired simulated runs (when the diagnosis was fitted with them).

        Returns
        -------
        current : ndarray or list of ndarray
        """
        check_is_fitted(self, "model_")
        single = not isinstance(recordings, (list, tuple))
        recs = check_recordings(recordings, self.nominal_.n_joints)
        refs, _ = self._references(recs, None if simulated is None else
                                   ([simulated] if single else simulated), "recordings")
        out = self.model_.predict(recs, refs)
        return out[0] if single else out

    def evaluate(self, recordings, simulated=None):
        """Held-out nMSE per joint before (nominal) and after (refined model).

        The main figures are over the samples where the joint moves
        (``|qd| >= sigma_rest``); ``*_all`` use every sample (where a
        sticking joint's holding current is unpredictable by any model of
        the state).

        Parameters
        ----------
        recordings : Recording or list of Recording
            Held-out recordings.
        simulated : Recording or list of Recording, default=None
            Paired simulated runs.

        Returns
        -------
        scores : dict
            ``nmse_before``, ``nmse_after``, ``nmse_before_all``,
            ``nmse_after_all`` (lists, one per joint), ``n_samples``,
            ``recordings``.
        """
        check_is_fitted(self, "model_")
        if simulated is not None and not isinstance(simulated, (list, tuple)):
            simulated = [simulated]
        signals, _ = self._signals(recordings, simulated, "test recordings")
        mask = self._mask(signals)
        after = self.model_.predict_signals(signals)
        every = np.ones_like(mask)
        return {
            "recordings": list(signals.names),
            "n_samples": int(signals.n_samples),
            "nmse_before": nmse(signals.current, signals.reference, mask=mask).tolist(),
            "nmse_after": nmse(signals.current, after, mask=mask).tolist(),
            "nmse_before_all": nmse(signals.current, signals.reference, mask=every).tolist(),
            "nmse_after_all": nmse(signals.current, after, mask=every).tolist(),
        }

    def report(self, test=None, test_simulated=None):
        """The diagnosis report (text, JSON, figure).

        Parameters
        ----------
        test : Recording or list of Recording, default=None
            Held-out recordings for the before/after nMSE; None uses the
            training recordings (in-sample, said so in the report).
        test_simulated : Recording or list of Recording, default=None
            Paired simulated runs of ``test``.

        Returns
        -------
        report : DiagnosisReport
        """
        from .report import DiagnosisReport

        check_is_fitted(self, "model_")
        scores = None if test is None else self.evaluate(test, test_simulated)
        return DiagnosisReport.from_diagnosis(self, scores)
