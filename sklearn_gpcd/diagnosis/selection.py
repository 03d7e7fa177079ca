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

* it is practically significant: fitted on all data, it removes at least
  ``min_share`` (default 1 %) of the nominal residual's sum of squares on
  one of its joints (a 0.1 % share is not a finding, however consistent;
  the nominal residual is a yardstick that does not shrink as effects are
  found, and an effect acting on every joint is judged on the joint where it
  shows most, so that a large effect elsewhere does not hide it), and
* its parameters are physically plausible (``check``, see
  :meth:`~sklearn_gpcd.diagnosis.Effect.implausible`); an implausible
  estimate is recorded as rejected, with the reason, and the next candidate
  is considered.

Among eligible candidates not worse than the best by more than one
standard error of their paired per-fold differences, the simplest (fewest
parameters, then library order) wins -- the one-standard-error rule.

Identifiability: when a candidate of *another* effect is within that one
standard error of the winner and their fitted contributions correlate by
at least :data:`AMBIGUOUS_CORRELATION` on these recordings, the data cannot
tell them apart; the pair is recorded as ambiguous (``ambiguities``) with the
excitation that would separate them (:func:`separating_excitation`).

Selection stops when no candidate is eligible; then a backward pass drops,
one at a time, any chosen effect that no longer removes ``min_gain`` of the
held-out loss of its joints with consistent per-fold gains (the same test
as when it was picked, ``min_t`` or every fold), or ``min_share`` of the
nominal residual of one of them, given all the others. The chosen set is refitted jointly on all data
(:func:`joint_fit`).
"""

from dataclasses import dataclass, field, replace

import numpy as np
from scipy import linalg

from .effects import EFFECTS, PAIR_SEPARATION, _joint_list  # noqa: F401 (PAIR_SEPARATION: API)

#: Default minimum share of the held-out loss (of the joints an effect acts
#: on) that an effect must remove to be selected.
MIN_GAIN = 0.02
#: Default minimum t-statistic of the per-fold gains.
MIN_T = 3.0
#: Default minimum share of the nominal residual's sum of squares (on one of the
#: effect's joints, all training rows) an effect must explain.
MIN_SHARE = 0.01
#: Correlation of two effects' fitted contributions from which they count as
#: not separable on the given recordings.
AMBIGUOUS_CORRELATION = 0.9

#: What excites each effect (for proposing a separating experiment): the
#: effects' own ``excitation`` (:class:`~sklearn_gpcd.diagnosis.Effect`).
EXCITATION = {cls.name: cls.excitation for cls in EFFECTS if cls.excitation}


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
    parts : tuple of Candidate
        For a composite (a Stribeck peak together with a low-speed softening
        on one joint, which can cancel each other when tried one at a
        time): its constituents, which share its columns; empty otherwise.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.diagnosis import Candidate, effect_library
    >>> c = Candidate(effect_library("coulomb_friction")[0], target=2, settings={},
    ...               joints=(2,), columns=np.array([5]), order=0)
    >>> c.label, c.n_params, c.family  # joints counted from 1 in labels
    ('coulomb_friction[joint 3]', 1, ('coulomb_friction', 2))
    """

    effect: object
    target: object
    settings: dict
    joints: tuple
    columns: np.ndarray
    order: int
    parts: tuple = ()

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
        """Readable name, joints and links counted from 1: ``"coulomb_friction[joint 3]"``."""
        name = "+".join(p.effect.name for p in self.parts) or self.effect.name
        if self.target is None:
            return name
        kind = self.effect.target_kind
        return f"{name}[{kind} {self.target + 1}]"


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
    return candidates + _friction_pairs(candidates), design


def _friction_pairs(candidates):
    """Composites of two terms of one target that can cancel each other.

    Each candidate's effect names the partners it leads a composite with
    (:meth:`~sklearn_gpcd.diagnosis.Effect.composite_partners`: a Coulomb
    change with the viscous change of its joint, a Stribeck peak with a
    slower softening). A composite shares the columns of its two parts (no
    new columns).
    """
    pairs = []
    for lead in candidates:
        for partner, settings in lead.effect.composite_partners(lead, candidates):
            pairs.append(Candidate(lead.effect, lead.target, settings, lead.joints,
                                   np.concatenate([lead.columns, partner.columns]),
                                   lead.order, parts=(lead, partner)))
    return pairs


def expand_composites(steps):
    """Selected steps with every composite replaced by its parts (same evidence).

    Parameters
    ----------
    steps : list of Step or Candidate

    Returns
    -------
    steps : list of Step or Candidate
    """
    out = []
    for step in steps:
        cand = step.candidate if hasattr(step, "candidate") else step
        if not cand.parts:
            out.append(step)
            continue
        start = 0
        for part in cand.parts:
            if hasattr(step, "candidate"):
                theta = None if step.theta is None else \
                    step.theta[start:start + part.n_params]
                out.append(replace(step, candidate=part, theta=theta))
            else:
                out.append(part)
            start += part.n_params
    return out


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
        """Statistics summed over folds: (gram, cross, rss, counts), computed once."""
        if "totals" not in self._cache:
            self._cache["totals"] = (self.gram.sum(0), self.cross.sum(0), self.rss.sum(0),
                                     self.counts.sum(0))
        return self._cache["totals"]


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


def _solve_many(A, b):
    """:func:`_solve` of a stack of systems ``A[f] x = b[f]``, one LAPACK call when regular."""
    if A.shape[-1] == 0:
        return np.zeros(b.shape)
    k = A.shape[-1]
    scale = np.trace(A, axis1=-2, axis2=-1) / k
    ridged = A + (1e-12 * scale)[:, None, None] * np.eye(k)
    try:
        theta = np.linalg.solve(ridged, b[..., None])[..., 0]
    except np.linalg.LinAlgError:
        theta = None
    if theta is None or not np.all(np.isfinite(theta)):
        theta = np.stack([_solve(a, v) for a, v in zip(A, b)])
    return theta


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
    gram_all, cross_all = stats.totals()[:2]
    c = np.asarray(columns, dtype=int)
    sub_gram = stats.gram[:, :, c[:, None], c[None, :]]  # (F, J, k, k)
    sub_cross = stats.cross[:, :, c]
    all_gram = gram_all[:, c[:, None], c[None, :]]
    all_cross = cross_all[:, c]
    A = np.einsum("j,fjab->fab", weights, all_gram[None] - sub_gram)
    b = np.einsum("j,fja->fa", weights, all_cross[None] - sub_cross)
    theta = _solve_many(A, b)  # (F, k): fitted without fold f
    sse = (stats.rss - 2.0 * np.einsum("fja,fa->fj", sub_cross, theta)
           + np.einsum("fa,fjab,fb->fj", theta, sub_gram, theta))
    losses = np.maximum(sse, 0.0) / np.maximum(stats.counts * stats.variance, 1e-300)
    # a joint that never moves (no rows, NaN variance) has nothing to explain
    return np.where(np.isfinite(losses), losses, 0.0)


def in_sample_mse(stats, columns, weights, return_theta=False):
    """Per-joint training MSE of the model fitted on all folds (and its coefficients).

    Memoised per columns and weights (a base set is scored against every candidate).
    """
    c = np.asarray(columns, dtype=int)
    key = ("in_sample", c.tobytes(), np.asarray(weights, dtype=float).tobytes())
    if key not in stats._cache:
        stats._cache[key] = _in_sample_fit(stats, c, weights)
    mse, theta = stats._cache[key]
    return (mse, theta) if return_theta else mse


def _in_sample_fit(stats, c, weights):
    """(per-joint MSE, coefficients) of the columns ``c`` fitted on all folds."""
    gram, cross, rss, counts = stats.totals()
    A = np.einsum("j,jab->ab", weights, gram[:, c[:, None], c[None, :]])
    theta = _solve(A, weights @ cross[:, c])
    sse = rss - 2.0 * cross[:, c] @ theta + np.einsum(
        "a,jab,b->j", theta, gram[:, c[:, None], c[None, :]], theta)
    return np.maximum(sse, 0.0) / np.maximum(counts, 1), theta


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
        Folds of the sign test (all but the first for a trend in time, see
        ``Effect.trend``).
    fold_gains : ndarray of shape (n_splits,)
        Per-fold loss decrease (sum over joints).
    delta_bic : float
        In-sample BIC change (negative favours the effect), for reference.
    share : float
        Largest share, over the candidate's joints, of a joint's nominal
        residual sum of squares it removes when fitted on all training rows
        (practical significance; a fixed yardstick, so that it does not relax
        as other effects are found); NaN when unknown.
    theta : ndarray
        The candidate's coefficients fitted on all training rows (with the
        effects already chosen).

    Examples
    --------
    A candidate that removes 40 % of its joints' held-out loss in all five
    folds is eligible:

    >>> import numpy as np
    >>> from sklearn_gpcd.diagnosis import Candidate, Step, effect_library
    >>> c = Candidate(effect_library("viscous_friction")[0], 1, {}, (1,), np.array([0]), 1)
    >>> step = Step(c, gain=0.2, std_error=0.01, t=8.0, relative_gain=0.4,
    ...             folds_improved=5, n_folds=5, share=0.3)
    >>> step.eligible(min_gain=0.02, min_t=3.0), step.eligible(min_gain=0.5, min_t=3.0)
    (True, False)

    A consistent gain that explains 0.1 % of the nominal residual is not a finding:

    >>> Step(c, 0.2, 0.01, 8.0, 0.4, 5, 5, share=0.001).eligible(0.02, 3.0, min_share=0.01)
    False
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
    share: float = np.nan
    theta: np.ndarray = None

    def eligible(self, min_gain, min_t, min_share=0.0):
        """True when the gain is statistically and practically significant.

        Statistically: the relative held-out gain reaches ``min_gain`` and
        the per-fold gains are consistent (t-statistic at least ``min_t``, or
        an improvement in every fold: a sign test, probability
        ``2**-n_folds`` under no effect). Practically: the candidate removes
        at least ``min_share`` of the nominal residual on one of its joints
        (``share``; not checked when NaN).
        """
        consistent = self.t >= min_t or self.folds_improved == self.n_folds
        practical = not (self.share < min_share)
        return (self.gain > 0 and self.relative_gain >= min_gain and consistent
                and practical)

    def to_dict(self):
        """JSON-ready evidence."""
        return {
            "criterion": "grouped time-block cross-validation",
            "heldout_gain_nmse": float(self.gain),
            "relative_gain": float(self.relative_gain),
            "t_statistic": float(self.t) if np.isfinite(self.t) else None,
            "folds_improved": f"{self.folds_improved}/{self.n_folds}",
            "delta_bic": float(self.delta_bic) if np.isfinite(self.delta_bic) else None,
            "share_of_nominal_residual": float(self.share) if np.isfinite(self.share) else None,
        }


def _evaluate(stats, candidate, base_columns, base_losses, weights, with_columns,
              yardstick=None):
    """Evidence for adding (or keeping) ``candidate`` to ``base_columns``.

    ``yardstick``: per-joint sum of squares for the practical significance
    (:func:`_yardstick`; None: the nominal residual).
    """
    losses = cv_losses(stats, with_columns, weights)
    d = (base_losses - losses).sum(axis=1)  # per fold, all joints
    F = len(d)
    gain = float(d.mean())
    se = float(d.std(ddof=1) / np.sqrt(F)) if F > 1 else np.inf
    # the sign test counts the folds where the effect has something to show: a trend from
    # the start of each recording has nothing in the first time block (fold 0)
    signed = d[1:] if candidate.effect.trend and F > 2 else d
    joints = list(candidate.joints)
    base_f = base_losses[:, joints].sum(axis=1)
    scale = base_f.mean()
    rel_f = (base_f - losses[:, joints].sum(axis=1)) / (scale if scale > 0 else np.inf)
    rel = float(rel_f.mean())
    rel_se = float(rel_f.std(ddof=1) / np.sqrt(F)) if F > 1 else np.inf
    t = rel / rel_se if rel_se > 0 else (np.inf if rel > 0 else 0.0)
    # BIC on the weighted in-sample fit, for reference
    n = stats.counts.sum()
    counts = stats.counts.sum(0)
    sse0 = in_sample_mse(stats, base_columns, weights) * counts
    sse1, theta = in_sample_mse(stats, with_columns, weights, return_theta=True)
    sse1 = sse1 * counts
    rss0, rss1 = (sse0 * weights).sum(), (sse1 * weights).sum()
    dbic = float(n * np.log(max(rss1, 1e-300) / max(rss0, 1e-300))
                 + candidate.n_params * np.log(n))
    # practical significance against a yardstick that does not shrink as effects are
    # found: the nominal residual (less what shared-parameter effects explain, see
    # _yardstick), on the joint where the effect shows most (a delay or a payload acts on
    # every joint, but a large effect on some of them would otherwise hide it)
    nominal_ss = (stats.rss.sum(0) if yardstick is None else yardstick)[joints]
    share = float(np.max((sse0 - sse1)[joints] / nominal_ss)) if np.all(nominal_ss > 0) \
        else np.nan
    return Step(candidate, gain, se, t, rel, int((signed > 0).sum()), len(signed), dbic, d,
                share,
                theta[-candidate.n_params:])


def _weights(stats, columns):
    mse = in_sample_mse(stats, columns, np.ones(stats.rss.shape[1]))
    return 1.0 / np.maximum(mse, 1e-12 * np.nanmax(stats.variance))


def _uses_guard(chosen):
    return any(getattr(c.effect, "rest_guard", False) for c in chosen)


def forward_selection(stats, candidates, min_gain=MIN_GAIN, min_t=MIN_T, max_effects=None,
                      guarded_stats=None, min_share=MIN_SHARE, check=None, rejections=None,
                      ambiguities=None):
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
    min_share : float, default=MIN_SHARE
        Minimum share of the nominal residual (on the candidate's joints)
        it must explain (practical significance).
    check : callable, default=None
        ``check(candidate, theta) -> reason or None``: why the coefficients
        ``theta`` fitted on all rows are implausible (see
        :func:`plausibility_check`). None accepts everything.
    rejections : list, default=None
        When given, receives one dict per implausible pick: ``name``,
        ``effect``, ``joints`` (0-based), ``reason``, ``implausible`` (True).
    ambiguities : list, default=None
        When given, receives one dict per pick that the data cannot tell from
        another effect's candidate (see :func:`separating_excitation`).

    Returns
    -------
    selected : list of Step
        Evidence of each selected candidate, given all the others (after the
        backward pass), in selection order.
    history : list of list of Step
        All candidates' evidence at each forward step.

    Examples
    --------
    Joint 2 (index 1) has 0.3 A of Coulomb friction the nominal model lacks;
    among the Coulomb and viscous candidates of all joints, only that one is
    selected (labels count joints from 1):

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
    ['coulomb_friction[joint 2]']
    >>> selected[0].folds_improved, len(history)
    (4, 2)
    """
    guarded_stats = stats if guarded_stats is None else guarded_stats
    selected, history = [], []
    families, banned = set(), set()
    rejections = [] if rejections is None else rejections
    ambiguities = [] if ambiguities is None else ambiguities

    def acceptable(step):
        """Plausibility of a pick; implausible ones are recorded and banned."""
        reason = None if check is None else check(step.candidate, step.theta)
        if reason is not None:
            banned.add(id(step.candidate))
            if all(r["name"] != step.candidate.label for r in rejections):
                rejections.append({"name": step.candidate.label,
                                   "effect": step.candidate.effect.name,
                                   "joints": [int(j) for j in step.candidate.joints],
                                   "reason": reason, "implausible": True})
        return reason is None

    def columns_of(chosen):
        if not chosen:
            return np.zeros(0, dtype=int)
        return np.concatenate([c.columns for c in chosen])

    while max_effects is None or len(selected) < max_effects:
        base = columns_of(selected)
        guarded_now = _uses_guard(selected)
        pool = [c for c in candidates if id(c) not in banned
                and not {c.family, *(p.family for p in c.parts)} & families]
        steps = score_additions(guarded_stats if guarded_now else stats, pool, base, selected)
        pick = None
        if not guarded_now and any(c.effect.rest_guard for c in pool):
            # guard effects compete with the others on the same (guarded) rows
            on_guarded = score_additions(guarded_stats, pool, base, selected)
            guard_steps = [s for s in on_guarded if s.candidate.effect.rest_guard]
            other = max((s.gain for s in on_guarded if not s.candidate.effect.rest_guard),
                        default=-np.inf)
            eligible = [s for s in guard_steps if s.eligible(min_gain, min_t, min_share)]
            while eligible and max(s.gain for s in eligible) > other:
                pick = max(eligible, key=lambda s: s.gain)
                if acceptable(pick):
                    break
                eligible.remove(pick)
                pick = None
            steps = [s for s in steps if not s.candidate.effect.rest_guard] + guard_steps
        history.append(steps)
        if pick is None:
            eligible = [s for s in steps if s.eligible(min_gain, min_t, min_share)
                        and (guarded_now or not s.candidate.effect.rest_guard)]
            while eligible:
                pick, close = one_standard_error(eligible)
                if acceptable(pick):
                    break
                eligible.remove(pick)
                pick = None
            if pick is None:
                break
            _record_ambiguity(stats, base, pick, close, ambiguities, check)
        # a composite enters as its parts: each is then re-tested on its own (with its own
        # practical significance) by the backward pass, given all the others
        selected.extend(pick.candidate.parts or [pick.candidate])
        families.update({pick.candidate.family, *(p.family for p in pick.candidate.parts)})

    # backward pass: drop the weakest effect that no longer earns its place
    while selected:
        evidence = given_others(guarded_stats if _uses_guard(selected) else stats, selected)
        # the same held-out test as when it was picked (gain, consistency), now given
        # every other effect: a small term picked next to a large one is re-tested
        failing = [s for s in evidence if not s.eligible(min_gain, min_t)]
        weakest = min(failing or evidence,
                      key=lambda s: s.relative_gain if s.gain > 0 else -np.inf)
        if not failing:
            thin = [s for s in evidence if s.share < min_share]
            if not thin:
                swap = _nested_swap(guarded_stats if _uses_guard(selected) else stats,
                                    selected, candidates, banned, min_gain, min_t, min_share)
                if swap is None:
                    return evidence, history
                k, simpler, extra = swap
                rejections.append({
                    "name": f"{selected[k].label} {selected[k].settings}",
                    "effect": selected[k].effect.name,
                    "joints": [int(j) for j in selected[k].joints], "implausible": False,
                    "reason": f"its extra columns over the simpler variant {simpler.settings} "
                              "do not pass the held-out test on their own (remove "
                              f"{100 * extra.relative_gain:.2g} % of its joints' held-out "
                              f"error, t = {extra.t:.2g}, {100 * extra.share:.2g} % of the "
                              "nominal residual): the simpler variant is kept"})
                selected[k] = simpler
                continue
            weakest = min(thin, key=lambda s: s.share)
        # the joint-wise account: a term picked and then dropped is reported with why
        if all(r["name"] != weakest.candidate.label for r in rejections):
            rejections.append({
                "name": weakest.candidate.label, "effect": weakest.candidate.effect.name,
                "joints": [int(j) for j in weakest.candidate.joints], "implausible": False,
                "reason": "given the other effects it no longer passes the held-out test "
                          f"(removes {100 * weakest.relative_gain:.2g} % of its joints' "
                          f"held-out error, t = {weakest.t:.2g}, better in "
                          f"{weakest.folds_improved}/{weakest.n_folds} folds, "
                          f"{100 * weakest.share:.2g} % of the nominal residual; needs "
                          f"{100 * min_gain:g} %, t >= {min_t:g} or every fold, "
                          f"{100 * min_share:g} %)"})
        selected.remove(weakest.candidate)
    return [], history


def _nested_swap(stats, selected, candidates, banned, min_gain, min_t, min_share):
    """A selected variant whose extra columns fail the held-out test, or None.

    A variant of an effect with more columns than another variant of the same
    effect and target (a friction drift of the dry and the viscous level
    against the dry level alone; a link mass with its centre of mass against
    the mass alone) is kept only when its extra columns pass the same test as
    any term (``min_gain``, ``min_t`` or every fold, ``min_share``) given the
    simpler variant and every other effect. Returns ``(index, simpler, evidence)``
    for the first one that fails.
    """
    all_cols = np.concatenate([c.columns for c in selected])
    weights = _weights(stats, all_cols)
    for k, cand in enumerate(selected):
        if cand.parts:
            continue
        simpler = [c for c in candidates if not c.parts and id(c) not in banned
                   and c.effect is cand.effect and c.target == cand.target
                   and c.n_params < cand.n_params]
        if not simpler:
            continue
        # the closest variant: most columns, then the most settings in common
        simple = max(simpler, key=lambda c: (c.n_params, sum(
            c.settings.get(key) == value for key, value in cand.settings.items())))
        others = [c for c in selected if c is not cand]
        base = np.concatenate([c.columns for c in (*others, simple)])
        extra = _evaluate(stats, cand, base, cv_losses(stats, base, weights), weights,
                          np.concatenate([base, cand.columns]), _yardstick(stats, others))
        if not extra.eligible(min_gain, min_t, min_share):
            return k, simple, extra
    return None


def _yardstick(stats, chosen):
    """Per-joint sum of squares practical significance is judged against.

    The nominal residual on each joint, less what the chosen effects with
    parameters shared by every joint and fixed by the configuration (payload,
    link mass, gravity tilt) explain there: a friction term of a joint is
    judged as if a payload found next to it were not there, not against a
    residual the payload dominates -- and not against what is left after the
    other terms of its own joint either, which would relax the bar as
    findings accumulate. A time delay is not subtracted: its term is the
    time derivative of every joint's current, and subtracting it left the
    delay's own approximation errors to be named as rotor inertia (measured
    on the package's simulator, a payload with a 32 ms delay).
    """
    rss = stats.rss.sum(0)
    shared = [c for c in chosen if not c.effect.per_joint and not c.effect.needs_time]
    if not shared:
        return rss
    columns = np.concatenate([c.columns for c in shared])
    mse = in_sample_mse(stats, columns, _weights(stats, np.zeros(0, dtype=int)))
    return np.minimum(mse * np.maximum(stats.counts.sum(0), 1), rss)


def score_additions(stats, candidates, base, chosen=()):
    """Evidence of adding each candidate to the columns ``base`` (of ``chosen``)."""
    weights = _weights(stats, base)
    base_losses = cv_losses(stats, base, weights)
    yardstick = _yardstick(stats, chosen)
    return [_evaluate(stats, c, base, base_losses, weights, np.concatenate([base, c.columns]),
                      yardstick)
            for c in candidates]


def one_standard_error(eligible):
    """The simplest eligible step not worse than the best by one paired standard error.

    Simplest: fewest parameters, then library order, then the default softening shape
    (:func:`_other_shape`), then the largest gain.

    Returns the pick and every step within that standard error of the best.
    """
    best = max(eligible, key=lambda s: s.gain)
    close = []
    for step in eligible:
        diff = best.fold_gains - step.fold_gains
        se = diff.std(ddof=1) / np.sqrt(diff.size) if diff.size > 1 else 0.0
        if diff.mean() <= se:
            close.append(step)
    pick = min(close, key=lambda s: (s.candidate.n_params, s.candidate.order,
                                     _other_shape(s.candidate), -s.gain))
    return pick, close


def _other_shape(candidate):
    """1 when the candidate uses a softening shape other than the default Gaussian, else 0.

    Within one standard error the Gaussian (the Stribeck law's shape) is kept: another
    shape must be clearly better on held-out data to be chosen.
    """
    parts = candidate.parts or (candidate,)
    return int(any(p.settings.get("shape", "gaussian") != "gaussian" for p in parts))


def _contribution_correlation(stats, base, a, b):
    """Correlation (over joints and training rows) of two candidates' fitted terms."""
    gram = stats.totals()[0]
    ca, cb = a.candidate.columns, b.candidate.columns
    ta, tb = a.theta, b.theta
    ab = np.einsum("a,jab,b->", ta, gram[:, ca[:, None], cb[None, :]], tb)
    aa = np.einsum("a,jab,b->", ta, gram[:, ca[:, None], ca[None, :]], ta)
    bb = np.einsum("a,jab,b->", tb, gram[:, cb[:, None], cb[None, :]], tb)
    return float(ab / np.sqrt(aa * bb)) if aa > 0 and bb > 0 else 0.0


def _record_ambiguity(stats, base, pick, close, ambiguities, check):
    """Record the other effects the data cannot tell from ``pick`` (module docstring)."""
    rivals = {}
    for step in close:
        other = step.candidate
        names = {c.effect.name for c in (pick.candidate, *pick.candidate.parts)}
        if names & {c.effect.name for c in (other, *other.parts)}:
            continue  # the same effect (or a composite holding it)
        if not set(other.joints) & set(pick.candidate.joints):
            continue
        if check is not None and check(other, step.theta) is not None:
            continue
        corr = _contribution_correlation(stats, base, pick, step)
        # both terms fit the same residual: confusable ones are positively correlated
        if corr >= AMBIGUOUS_CORRELATION and corr > rivals.get(other.effect.name, (0.0,))[0]:
            rivals[other.effect.name] = (corr, step)
    for name, (corr, step) in rivals.items():
        joints = sorted(set(pick.candidate.joints) | set(step.candidate.joints))
        ambiguities.append({
            "chosen": pick.candidate.label, "effect": pick.candidate.effect.name,
            "alternative": step.candidate.label, "alternative_effect": name,
            "joints": [int(j) for j in joints], "correlation": corr,
            "excitation": separating_excitation(pick.candidate.effect.name, name, joints),
        })


def separating_excitation(effect, other, joints):
    """The experiment that would tell ``effect`` from ``other`` on ``joints``.

    Parameters
    ----------
    effect, other : str
        Effect names (keys of :data:`EXCITATION`).
    joints : sequence of int
        Joints concerned (0-based).

    Returns
    -------
    text : str
        Plain words, joints counted from 1.

    Examples
    --------
    >>> separating_excitation("rotor_inertia", "link_mass", [1, 2])[:63]
    'on joints 2, 3, record (a) fast small oscillations of the joint'
    """
    first = EXCITATION.get(effect, "moves that excite it")
    second = EXCITATION.get(other, "moves that excite it")
    return (f"on {_joint_list(joints)}, record (a) {first}, which excites "
            f"{effect.replace('_', ' ')}, and (b) {second}, which excites "
            f"{other.replace('_', ' ')}; the two are then fitted on data where their "
            "terms differ")


def plausibility_check(nominal):
    """``check(candidate, theta)`` for :func:`forward_selection`: physical bounds.

    Converts the candidate's coefficients to physical parameters
    (:meth:`Effect.physical`) and asks :meth:`Effect.implausible`.

    Parameters
    ----------
    nominal : NominalModel

    Returns
    -------
    check : callable

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.diagnosis import Candidate, NominalModel, effect_library
    >>> from sklearn_gpcd.diagnosis.selection import plausibility_check
    >>> check = plausibility_check(NominalModel("ur10"))
    >>> c = Candidate(effect_library("torque_constant")[0], 3, {}, (3,), np.array([0]), 4)
    >>> check(c, np.array([0.1])) is None  # scale 1 / 1.1 = 0.91
    True
    >>> check(c, np.array([19.0]))  # scale 0.05
    'torque constant scale 0.05 outside [0.5, 1.5] (a motor that lost or gained 95 % of its torque)'
    """

    def check(candidate, theta):
        if theta is None:
            return None
        theta = np.asarray(theta, dtype=float)
        context, start = {}, 0
        # the parts of a composite in order: each is judged given what the earlier ones
        # tell it (a softening acts on the dry friction plus a peak before it)
        for part in candidate.parts or (candidate,):
            sub = theta[start:start + part.n_params]
            params = part.effect.physical(sub, np.zeros((sub.size, sub.size)), part.target,
                                          part.settings, nominal)
            reason = part.effect.implausible_among(params, part.target, nominal, context)
            if reason is not None:
                return (f"{part.effect.name.replace('_', ' ')}: {reason}" if candidate.parts
                        else reason)
            for key, value in part.effect.context(params).items():
                context[key] = context.get(key, 0.0) + value
            start += part.n_params
        return None

    return check


def given_others(stats, selected):
    """Evidence of each selected candidate given all the others."""
    out = []
    all_cols = np.concatenate([c.columns for c in selected])
    weights = _weights(stats, all_cols)
    for cand in selected:
        others = [c for c in selected if c is not cand]
        base = np.concatenate([c.columns for c in others]) if others else np.zeros(0, int)
        base_losses = cv_losses(stats, base, weights)
        out.append(_evaluate(stats, cand, base, base_losses, weights,
                             np.concatenate([base, cand.columns]), _yardstick(stats, others)))
    return out
