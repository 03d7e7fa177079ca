"""Which effects are missing: greedy forward selection by grouped cross-validation.

Setting
-------
Joint :math:`\\ell`'s residual :math:`r_\\ell = i_\\ell - \\hat i_\\ell`
(measured minus reference current) is regressed on the columns of a set
:math:`S` of candidate effects (:mod:`~sklearn_gpcd.diagnosis.effects`),
jointly over all joints because some effects (payload, gravity tilt, time
delay) share their parameters across joints. With per-joint weights
:math:`w_\\ell = 1/\\hat\\sigma_\\ell^2` (residual variance of the current
model) the parameters solve the weighted normal equations

.. math::

    \\Big(\\sum_\\ell w_\\ell D_\\ell^T D_\\ell\\Big)\\theta
        = \\sum_\\ell w_\\ell D_\\ell^T r_\\ell .

Samples where joint :math:`\\ell` is slower than ``sigma_rest`` are left out
of its rows: a sticking joint's friction holds whatever torque it must, it
is not a function of the state.

Held-out score
--------------
Each recording is cut into ``n_splits`` contiguous time blocks; fold ``f``
holds block ``f`` of every recording (grouped K-fold over time blocks, so a
test block is never interleaved with its training samples). The loss of a
set :math:`S` on fold ``f`` is the sum over joints of the held-out nMSE
(paper Eq. 18, normalised by the variance of the measured current). Only
per-block sufficient statistics :math:`D^TD`, :math:`D^Tr`, :math:`r^Tr`
are kept, so trying a candidate costs a few small solves.

Selection
---------
Candidates compete greedily. At each step every candidate not yet chosen is
added to :math:`S` in turn; its gain per fold is the loss decrease. It is
*eligible* when

* it removes at least ``min_gain`` of the held-out loss of the joints it
  acts on (per-fold loss decrease over the mean per-fold loss, averaged),
  and
* these per-fold relative gains are consistent: a t-statistic (mean over
  its standard error across folds) of at least ``min_t``, or a gain in
  every fold (sign test; large effects vary in size between folds, which
  inflates the standard error).

Among eligible candidates not worse than the best by more than one
standard error of their paired per-fold differences, the simplest (fewest
parameters, then library order) wins -- the one-standard-error rule.
Selection stops when no candidate is eligible; then a backward pass drops,
one at a time, any chosen effect that no longer removes ``min_gain`` of the
held-out loss of its joints given all the others. The chosen set is
refitted jointly on all data
(:func:`joint_fit`).
"""

from dataclasses import dataclass, field

import numpy as np
from scipy import linalg

#: Default minimum share of the held-out loss (of the joints an effect acts
#: on) that an effect must remove to be selected.
MIN_GAIN = 0.02
#: Default minimum t-statistic of the per-fold gains.
MIN_T = 3.0


@dataclass
class Candidate:
    """One effect on one target with fixed nonlinear settings.

    Attributes
    ----------
    effect : Effect
    target : int or None
        Joint (per-joint effects), link (``link_mass``) or None.
    settings : dict
        Nonlinear settings (e.g. ``{"stribeck_velocity": 0.02}``).
    joints : tuple of int
        Joints whose current the columns change.
    columns : ndarray of int
        Indices of its columns in the stacked design.
    order : int
        Position of the effect in the library (prior plausibility).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.diagnosis import Candidate, effect_library
    >>> c = Candidate(effect_library("coulomb_friction")[0], target=2, settings={},
    ...               joints=(2,), columns=np.array([5]), order=0)
    >>> c.label, c.n_params, c.family
    ('coulomb_friction[joint 2]', 1, ('coulomb_friction', 2))
    """

    effect: object
    target: object
    settings: dict
    joints: tuple
    columns: np.ndarray
    order: int

    @property
    def n_params(self):
        """Number of linear parameters."""
        return len(self.columns)

    @property
    def family(self):
        """Candidates of one family exclude each other (same effect and target)."""
        return (self.effect.name, self.target)

    @property
    def label(self):
        """Readable name, e.g. ``"coulomb_friction[joint 2]"``."""
        if self.target is None:
            return self.effect.name
        kind = "link" if self.effect.name == "link_mass" else "joint"
        return f"{self.effect.name}[{kind} {self.target}]"


def build_candidates(signals, nominal, effects):
    """All candidates of ``effects`` and their columns per joint.

    Parameters
    ----------
    signals : Signals
    nominal : NominalModel
    effects : list of Effect

    Returns
    -------
    candidates : list of Candidate
    design : list of list of (int, ndarray)
        ``design[l]`` pairs a candidate index with its columns on joint ``l``
        (shape ``(n_samples, n_params)``).
    """
    candidates, design, n_columns = [], [[] for _ in range(signals.n_joints)], 0
    for order, effect in enumerate(effects):
        if effect.needs_time and signals.time is None:
            continue
        for target in effect.targets(nominal):
            for settings in effect.settings_grid():
                cols = effect.design(signals, nominal, target, **settings)
                if not cols:
                    continue
                k = next(iter(cols.values())).shape[1]
                cand = Candidate(effect, target, dict(settings), tuple(sorted(cols)),
                                 np.arange(n_columns, n_columns + k), order)
                n_columns += k
                for j, values in cols.items():
                    design[j].append((len(candidates), values))
                candidates.append(cand)
    return candidates, design


@dataclass
class FoldStatistics:
    """Sufficient statistics of the stacked regression per fold and joint.

    Attributes
    ----------
    gram : ndarray of shape (n_folds, n_joints, n_columns, n_columns)
        :math:`D^T D` per fold and joint.
    cross : ndarray of shape (n_folds, n_joints, n_columns)
        :math:`D^T r`.
    rss : ndarray of shape (n_folds, n_joints)
        :math:`r^T r` (residual of the reference).
    counts : ndarray of shape (n_folds, n_joints)
        Rows used.
    variance : ndarray of shape (n_joints,)
        Variance of the measured current over the rows used (nMSE scale).
    """

    gram: np.ndarray
    cross: np.ndarray
    rss: np.ndarray
    counts: np.ndarray
    variance: np.ndarray
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def n_folds(self):
        """Number of folds."""
        return self.gram.shape[0]

    def totals(self):
        """Statistics summed over folds: (gram, cross, rss, counts)."""
        return self.gram.sum(0), self.cross.sum(0), self.rss.sum(0), self.counts.sum(0)


def fold_index(signals, n_splits):
    """Fold of every sample: block ``floor(n_splits (t - t_0) / T)`` of its recording.

    Parameters
    ----------
    signals : Signals
    n_splits : int

    Returns
    -------
    folds : ndarray of int, shape (n_samples,)
    """
    folds = np.zeros(signals.n_samples, dtype=int)
    for seg in np.unique(signals.segment):
        rows = np.flatnonzero(signals.segment == seg)
        if signals.time is None:
            position = np.arange(rows.size) / max(rows.size, 1)
        else:
            t = signals.time[rows]
            position = (t - t[0]) / max(t[-1] - t[0], 1e-12)
        folds[rows] = np.minimum((position * n_splits).astype(int), n_splits - 1)
    return folds


def fold_statistics(candidates, design, residual, mask, folds, n_folds, current):
    """Per-fold, per-joint sufficient statistics (see :class:`FoldStatistics`).

    Parameters
    ----------
    candidates : list of Candidate
    design : list of list of (int, ndarray)
        From :func:`build_candidates`.
    residual : ndarray of shape (n_samples, n_joints)
        Measured minus reference current.
    mask : ndarray of bool, shape (n_samples, n_joints)
        Rows used per joint.
    folds : ndarray of int, shape (n_samples,)
    n_folds : int
    current : ndarray of shape (n_samples, n_joints)
        Measured current (for the nMSE scale).

    Returns
    -------
    stats : FoldStatistics
    """
    n_joints = residual.shape[1]
    n_columns = sum(c.n_params for c in candidates)
    gram = np.zeros((n_folds, n_joints, n_columns, n_columns))
    cross = np.zeros((n_folds, n_joints, n_columns))
    rss = np.zeros((n_folds, n_joints))
    counts = np.zeros((n_folds, n_joints))
    variance = np.zeros(n_joints)
    for j in range(n_joints):
        entries = design[j]
        cols = (np.concatenate([candidates[c].columns for c, _ in entries]) if entries
                else np.zeros(0, dtype=int))
        X = np.hstack([v for _, v in entries]) if entries else np.zeros((len(residual), 0))
        used = mask[:, j]
        variance[j] = np.var(current[used, j]) if used.any() else np.nan
        for f in range(n_folds):
            rows = used & (folds == f)
            Xf, rf = X[rows], residual[rows, j]
            gram[f, j][np.ix_(cols, cols)] = Xf.T @ Xf
            cross[f, j, cols] = Xf.T @ rf
            rss[f, j] = rf @ rf
            counts[f, j] = rows.sum()
    return FoldStatistics(gram, cross, rss, counts, variance)


def _solve(A, b):
    """Least-squares solution of a small symmetric system (rank-deficient safe)."""
    if A.size == 0:
        return np.zeros(0)
    scale = np.trace(A) / max(A.shape[0], 1)
    try:
        return linalg.solve(A + 1e-12 * scale * np.eye(A.shape[0]), b, assume_a="pos")
    except (linalg.LinAlgError, ValueError):
        return np.linalg.lstsq(A, b, rcond=None)[0]


def cv_losses(stats, columns, weights):
    """Held-out nMSE per fold and joint of the model with ``columns``.

    Parameters
    ----------
    stats : FoldStatistics
    columns : ndarray of int
        Stacked-design columns in the model.
    weights : ndarray of shape (n_joints,)
        Per-joint weights of the fit.

    Returns
    -------
    losses : ndarray of shape (n_folds, n_joints)
        Held-out SSE / (rows * variance of the current).
    """
    F, J = stats.rss.shape
    gram_all = stats._cache.get("gram_all")
    if gram_all is None:
        gram_all = stats._cache["gram_all"] = stats.gram.sum(0)
        stats._cache["cross_all"] = stats.cross.sum(0)
    cross_all = stats._cache["cross_all"]
    c = np.asarray(columns, dtype=int)
    losses = np.empty((F, J))
    sub_gram = stats.gram[:, :, c[:, None], c[None, :]]  # (F, J, k, k)
    sub_cross = stats.cross[:, :, c]
    all_gram = gram_all[:, c[:, None], c[None, :]]
    all_cross = cross_all[:, c]
    for f in range(F):
        A = np.einsum("j,jab->ab", weights, all_gram - sub_gram[f])
        b = weights @ (all_cross - sub_cross[f])
        theta = _solve(A, b)
        sse = (stats.rss[f] - 2.0 * sub_cross[f] @ theta
               + np.einsum("a,jab,b->j", theta, sub_gram[f], theta))
        losses[f] = np.maximum(sse, 0.0) / np.maximum(stats.counts[f] * stats.variance, 1e-300)
    return losses


def in_sample_mse(stats, columns, weights):
    """Per-joint training MSE of the model fitted on all folds."""
    gram, cross, rss, counts = stats.totals()
    c = np.asarray(columns, dtype=int)
    A = np.einsum("j,jab->ab", weights, gram[:, c[:, None], c[None, :]])
    theta = _solve(A, weights @ cross[:, c])
    sse = rss - 2.0 * cross[:, c] @ theta + np.einsum(
        "a,jab,b->j", theta, gram[:, c[:, None], c[None, :]], theta)
    return np.maximum(sse, 0.0) / np.maximum(counts, 1)


@dataclass
class Step:
    """Evidence for one candidate at one selection step.

    Attributes
    ----------
    candidate : Candidate
    gain : float
        Mean over folds of the held-out loss decrease (sum of per-joint nMSE).
    std_error : float
        Its standard error across folds.
    t : float
        Mean over its standard error of the per-fold relative gains (share
        of each fold's held-out loss on the candidate's joints removed).
    relative_gain : float
        Mean over folds of the share of the held-out loss of the
        candidate's joints it removes.
    folds_improved : int
        Folds where it lowered the loss.
    n_folds : int
    fold_gains : ndarray of shape (n_folds,)
        Per-fold loss decrease (sum over joints).
    delta_bic : float
        In-sample BIC change (negative favours the effect), for reference.

    Examples
    --------
    A candidate that removes 40 % of its joints' held-out loss in all five
    folds is eligible:

    >>> import numpy as np
    >>> from sklearn_gpcd.diagnosis import Candidate, Step, effect_library
    >>> c = Candidate(effect_library("viscous_friction")[0], 1, {}, (1,), np.array([0]), 1)
    >>> step = Step(c, gain=0.2, std_error=0.01, t=8.0, relative_gain=0.4,
    ...             folds_improved=5, n_folds=5)
    >>> step.eligible(min_gain=0.02, min_t=3.0), step.eligible(min_gain=0.5, min_t=3.0)
    (True, False)
    >>> step.to_dict()["folds_improved"]
    '5/5'
    """

    candidate: Candidate
    gain: float
    std_error: float
    t: float
    relative_gain: float
    folds_improved: int
    n_folds: int
    delta_bic: float = np.nan
    fold_gains: np.ndarray = None

    def eligible(self, min_gain, min_t):
        """True when the relative gain reaches ``min_gain`` and the gains are consistent.

        Consistent: t-statistic at least ``min_t``, or an improvement in every
        fold (a sign test: probability ``2**-n_folds`` under no effect).
        """
        consistent = self.t >= min_t or self.folds_improved == self.n_folds
        return self.gain > 0 and self.relative_gain >= min_gain and consistent

    def to_dict(self):
        """JSON-ready evidence."""
        return {
            "criterion": "grouped time-block cross-validation",
            "heldout_gain_nmse": float(self.gain),
            "relative_gain": float(self.relative_gain),
            "t_statistic": float(self.t) if np.isfinite(self.t) else None,
            "folds_improved": f"{self.folds_improved}/{self.n_folds}",
            "delta_bic": float(self.delta_bic) if np.isfinite(self.delta_bic) else None,
        }


def _evaluate(stats, candidate, base_columns, base_losses, weights, with_columns):
    """Evidence for adding (or keeping) ``candidate`` to ``base_columns``."""
    losses = cv_losses(stats, with_columns, weights)
    d = (base_losses - losses).sum(axis=1)  # per fold, all joints
    F = len(d)
    gain = float(d.mean())
    se = float(d.std(ddof=1) / np.sqrt(F)) if F > 1 else np.inf
    joints = list(candidate.joints)
    base_f = base_losses[:, joints].sum(axis=1)
    scale = base_f.mean()
    rel_f = (base_f - losses[:, joints].sum(axis=1)) / (scale if scale > 0 else np.inf)
    rel = float(rel_f.mean())
    rel_se = float(rel_f.std(ddof=1) / np.sqrt(F)) if F > 1 else np.inf
    t = rel / rel_se if rel_se > 0 else (np.inf if rel > 0 else 0.0)
    # BIC on the weighted in-sample fit, for reference
    n = stats.counts.sum()
    rss0 = (in_sample_mse(stats, base_columns, weights) * stats.counts.sum(0) * weights).sum()
    rss1 = (in_sample_mse(stats, with_columns, weights) * stats.counts.sum(0) * weights).sum()
    dbic = float(n * np.log(max(rss1, 1e-300) / max(rss0, 1e-300))
                 + candidate.n_params * np.log(n))
    return Step(candidate, gain, se, t, rel, int((d > 0).sum()), F, dbic, d)


def _weights(stats, columns):
    mse = in_sample_mse(stats, columns, np.ones(stats.rss.shape[1]))
    return 1.0 / np.maximum(mse, 1e-12 * np.nanmax(stats.variance))


def _uses_guard(chosen):
    return any(getattr(c.effect, "rest_guard", False) for c in chosen)


def forward_selection(stats, candidates, min_gain=MIN_GAIN, min_t=MIN_T, max_effects=None,
                      guarded_stats=None):
    """Greedy forward selection with the one-standard-error rule, then a backward pass.

    Parameters
    ----------
    stats : FoldStatistics
    candidates : list of Candidate
    min_gain : float, default=MIN_GAIN
        Minimum relative held-out gain on the candidate's joints.
    min_t : float, default=MIN_T
        Minimum t-statistic of the per-fold relative gains.
    max_effects : int, default=None
        Stop after this many selections.
    guarded_stats : FoldStatistics, default=None
        Statistics without the rows next to a joint's rest. Effects with
        ``rest_guard = True`` (time delay) are scored on them, and so is
        every candidate once such an effect is selected. None uses ``stats``.

    Returns
    -------
    selected : list of Step
        Evidence of each selected candidate, given all the others (after the
        backward pass), in selection order.
    history : list of list of Step
        All candidates' evidence at each forward step.

    Examples
    --------
    Joint 1 has 0.3 A of Coulomb friction the nominal model lacks; among the
    Coulomb and viscous candidates of all joints, only that one is selected:

    >>> import numpy as np
    >>> from sklearn_gpcd.diagnosis import (NominalModel, Signals, effect_library,
    ...                                     forward_selection)
    >>> from sklearn_gpcd.diagnosis.selection import (build_candidates, fold_index,
    ...                                               fold_statistics)
    >>> rng = np.random.default_rng(0)
    >>> nominal = NominalModel("ur10")
    >>> X = np.hstack([rng.uniform(-1, 1, (300, 12)), np.zeros((300, 6))])
    >>> s = Signals.from_states(nominal, X)
    >>> s.current = s.reference + 0.01 * rng.normal(size=(300, 6))
    >>> s.current[:, 1] += 0.3 * np.sign(s.qd[:, 1])
    >>> candidates, design = build_candidates(
    ...     s, nominal, effect_library(["coulomb_friction", "viscous_friction"]))
    >>> mask = np.ones((300, 6), dtype=bool)
    >>> stats = fold_statistics(candidates, design, s.current - s.reference, mask,
    ...                         fold_index(s, 4), 4, s.current)
    >>> selected, history = forward_selection(stats, candidates)
    >>> [step.candidate.label for step in selected]
    ['coulomb_friction[joint 1]']
    >>> selected[0].folds_improved, len(history)
    (4, 2)
    """
    guarded_stats = stats if guarded_stats is None else guarded_stats
    selected, history = [], []
    families = set()

    def columns_of(chosen):
        if not chosen:
            return np.zeros(0, dtype=int)
        return np.concatenate([c.columns for c in chosen])

    while max_effects is None or len(selected) < max_effects:
        base = columns_of(selected)
        guarded_now = _uses_guard(selected)
        pool = [c for c in candidates if c.family not in families]
        steps = _score(guarded_stats if guarded_now else stats, pool, base)
        pick = None
        if not guarded_now and any(c.effect.rest_guard for c in pool):
            # guard effects compete with the others on the same (guarded) rows
            on_guarded = _score(guarded_stats, pool, base)
            guard_steps = [s for s in on_guarded if s.candidate.effect.rest_guard]
            other = max((s.gain for s in on_guarded if not s.candidate.effect.rest_guard),
                        default=-np.inf)
            eligible = [s for s in guard_steps if s.eligible(min_gain, min_t)]
            if eligible and max(s.gain for s in eligible) > other:
                pick = max(eligible, key=lambda s: s.gain)
            steps = [s for s in steps if not s.candidate.effect.rest_guard] + guard_steps
        history.append(steps)
        if pick is None:
            eligible = [s for s in steps if s.eligible(min_gain, min_t)
                        and (guarded_now or not s.candidate.effect.rest_guard)]
            if not eligible:
                break
            pick = _one_standard_error(eligible)
        selected.append(pick.candidate)
        families.add(pick.candidate.family)

    # backward pass: drop the weakest effect that no longer earns its place
    while selected:
        evidence = _given_others(guarded_stats if _uses_guard(selected) else stats, selected)
        weakest = min(evidence, key=lambda s: s.relative_gain if s.gain > 0 else -np.inf)
        if weakest.gain > 0 and weakest.relative_gain >= min_gain:
            return evidence, history
        selected.remove(weakest.candidate)
    return [], history


def _score(stats, candidates, base):
    """Evidence of adding each candidate to the columns ``base``."""
    weights = _weights(stats, base)
    base_losses = cv_losses(stats, base, weights)
    return [_evaluate(stats, c, base, base_losses, weights, np.concatenate([base, c.columns]))
            for c in candidates]


def _one_standard_error(eligible):
    """The simplest eligible step not worse than the best by one paired standard error."""
    best = max(eligible, key=lambda s: s.gain)
    close = []
    for step in eligible:
        diff = best.fold_gains - step.fold_gains
        se = diff.std(ddof=1) / np.sqrt(diff.size) if diff.size > 1 else 0.0
        if diff.mean() <= se:
            close.append(step)
    return min(close, key=lambda s: (s.candidate.n_params, s.candidate.order, -s.gain))


def _given_others(stats, selected):
    """Evidence of each selected candidate given all the others."""
    out = []
    all_cols = np.concatenate([c.columns for c in selected])
    weights = _weights(stats, all_cols)
    for cand in selected:
        others = [c for c in selected if c is not cand]
        base = np.concatenate([c.columns for c in others]) if others else np.zeros(0, int)
        base_losses = cv_losses(stats, base, weights)
        out.append(_evaluate(stats, cand, base, base_losses, weights,
                             np.concatenate([base, cand.columns])))
    return out
