"""How stable a selection is: the selection rerun on block-bootstrap resamples.

The residual is autocorrelated, so samples are not resampled one by one:
each recording is cut into blocks of ``BLOCK_SECONDS`` and a resample draws
as many blocks of each recording with replacement (moving-block bootstrap
on a fixed grid). Per block only the sufficient statistics of the regression
(:math:`D^TD`, :math:`D^Tr`, :math:`r^Tr` per joint) of a *shortlist* of
candidates are kept: the effects named on all data, and the strongest
settings of the families that came closest; a resample's cross-validation
folds are its drawn blocks cut into ``n_splits`` contiguous groups.

Per resample the selection is a *backward thresholding* of one variant per
family (:func:`thresholded_selection`), as sequentially thresholded least
squares is in SINDy: every family's best plausible variant whose held-out
gain alone is positive enters, all are fitted together, and the weakest
term that fails the held-out test given all the others (``min_gain``,
``min_t`` or every fold, ``min_share``; the test of the all-data selection)
is removed and the rest refitted, until every term passes. Each term is
thus judged against every rival at once, not in the order a greedy pass
met them: a spurious term that only a chance fluctuation of a few blocks
lifts over the bar is named in a few resamples, and the inclusion cut
removes it -- the false discoveries the cut controls are those of this
per-resample rule (stability selection, Meinshausen & Buehlmann 2010).

Each family (effect and target) gets its *inclusion probability* (share of
resamples that name it, as in stability selection and ensemble-SINDy), and
for the resamples that name it the percentiles of its first parameter and
of its held-out gain. An effect named on all data is kept only when its
inclusion probability reaches ``MIN_INCLUSION``: a term that a few blocks of
the recording bring in or out is not a finding.

*Confounded alternatives are included as a group* (stability selection with
grouped variables). Families whose columns the recordings cannot tell apart
(:func:`~sklearn_gpcd.diagnosis.identifiability.confounded_families`: an
absolute correlation of at least ``CONFOUNDED_CORRELATION`` in the weighted
information matrix :math:`A = \\sum_\\ell w_\\ell D_\\ell^T D_\\ell` of the
shortlist, :math:`w_\\ell` the inverse mean squared residual of joint
:math:`\\ell`) compete in a resample as the settings of one family do: one
of them stands for the group. Otherwise a resample's fit splits the effect
between them at random (a concealed payload named as a forearm mass in some
resamples) and each alone falls under the cut although every resample names
one of them. The group of a named family :math:`F` is
:math:`G(F) = \\{F\\} \\cup \\{H \\text{ confounded with } F, H \\text{ not named}\\}`;
its inclusion probability is

.. math::

    \\hat\\Pi_{G} = \\frac{1}{B} \\sum_{b=1}^{B}
        \\mathbb{1}\\left[\\hat S_b \\cap G \\neq \\emptyset\\right],

:math:`\\hat S_b` the families resample :math:`b` names, and the member
reported is the one named most often (the named one on a tie).
"""

from dataclasses import replace

import numpy as np

from .identifiability import CONFOUNDED_CORRELATION, confounded_families
from .selection import FoldStatistics, given_others, one_standard_error, score_additions

#: Block length [s] of the bootstrap (several times the residual's correlation time);
#: shorter recordings get shorter blocks, ``MIN_BLOCKS`` each at least.
BLOCK_SECONDS, MIN_BLOCKS = 2.0, 20
#: Resamples.
N_RESAMPLES = 20
#: Inclusion probability an effect named on all data needs to be kept (set before
#: any case was looked at; 0.7 dropped a 4 Nm Stribeck peak named in 65 % of the
#: resamples of a 13 s run, tests/test_effect_registry.py).
MIN_INCLUSION = 0.6
#: Inclusion probability from which an effect the all-data selection missed is added.
ADD_INCLUSION = 0.8
#: Families beyond the named ones in the shortlist, and settings kept per family.
SHORTLIST_FAMILIES, SHORTLIST_SETTINGS = 8, 3


def block_index(signals, seconds=BLOCK_SECONDS):
    """Block of every sample and the blocks of each recording.

    Blocks last ``seconds``, or a recording's duration over ``MIN_BLOCKS``
    when that is shorter (a short recording still gives enough blocks to
    resample).

    Parameters
    ----------
    signals : Signals
    seconds : float, default=BLOCK_SECONDS

    Returns
    -------
    blocks : ndarray of int, shape (n_samples,)
    per_recording : list of ndarray of int

    Examples
    --------
    >>> import numpy as np
    >>> from types import SimpleNamespace
    >>> s = SimpleNamespace(time=np.r_[np.arange(0, 50, 1.0), np.arange(0, 3, 0.1)],
    ...                     segment=np.r_[np.zeros(50, int), np.ones(30, int)], n_samples=80)
    >>> blocks, per = block_index(s, 2.0)
    >>> [p.size for p in per]  # 2 s blocks; 2.9 s / 20 blocks for the short one
    [25, 21]
    """
    blocks = np.zeros(signals.n_samples, dtype=int)
    per_recording, offset = [], 0
    for seg in np.unique(signals.segment):
        rows = np.flatnonzero(signals.segment == seg)
        if signals.time is None:
            local = (np.arange(rows.size) * 20 // max(rows.size, 1)).astype(int)
        else:
            t = signals.time[rows]
            length = min(seconds, (t[-1] - t[0]) / MIN_BLOCKS) if t[-1] > t[0] else seconds
            local = np.floor((t - t[0]) / length).astype(int)
        blocks[rows] = local + offset
        per_recording.append(np.arange(offset, offset + local.max() + 1))
        offset += int(local.max()) + 1
    return blocks, per_recording


def shortlist(candidates, history, named_families, picked=()):
    """Candidates of the named families and of the strongest others (first-step evidence).

    Per family its ``SHORTLIST_SETTINGS`` best settings by first-step
    relative gain; the named families and the ``SHORTLIST_FAMILIES`` best
    others; the candidates ``picked`` on all data and their parts;
    composites whose parts are all in. Library order.
    """
    first = history[0] if history else []
    by_family = {}
    for step in sorted(first, key=lambda s: -s.relative_gain):
        if not step.candidate.parts:
            by_family.setdefault(step.candidate.family, []).append(step.candidate)
    others = [f for f in by_family if f not in named_families][:SHORTLIST_FAMILIES]
    keep = {id(c) for family in set(named_families) | set(others)
            for c in by_family.get(family, [])[:SHORTLIST_SETTINGS]}
    keep |= {id(p) for c in picked for p in (c.parts or (c,))}
    return [c for c in candidates if (not c.parts and id(c) in keep)
            or (c.parts and all(id(p) in keep for p in c.parts))]


def _reduce(candidates, design, chosen):
    """``chosen`` with their columns renumbered 0..k-1, and the design restricted to them."""
    base = [c for c in chosen if not c.parts]
    mapping, new, n = {}, [], 0
    for cand in base:
        cols = np.arange(n, n + cand.n_params)
        mapping.update({int(old): int(c) for old, c in zip(cand.columns, cols)})
        n += cand.n_params
        new.append(replace(cand, columns=cols))
    index = {id(c): k for k, c in enumerate(candidates)}
    old_to_new = {index[id(c)]: k for k, c in enumerate(base)}
    sub_design = [[(old_to_new[k], v) for k, v in entries if k in old_to_new]
                  for entries in design]
    parts = {id(c): new[k] for k, c in enumerate(base)}
    for cand in chosen:
        if cand.parts:
            new.append(replace(cand, columns=np.array([mapping[int(c)] for c in cand.columns]),
                               parts=tuple(parts[id(p)] for p in cand.parts)))
    return new, sub_design, n


def block_statistics(candidates, design, n_columns, residual, mask, blocks, n_blocks,
                     current):
    """Per-block sufficient statistics of a reduced design (a FoldStatistics of blocks)."""
    J = residual.shape[1]
    gram = np.zeros((n_blocks, J, n_columns, n_columns))
    cross = np.zeros((n_blocks, J, n_columns))
    rss, counts, variance = np.zeros((n_blocks, J)), np.zeros((n_blocks, J)), np.zeros(J)
    for j in range(J):
        used = np.flatnonzero(mask[:, j])
        variance[j] = np.var(current[used, j]) if used.size else np.nan
        entries = design[j]
        X = (np.hstack([v[used] for _, v in entries]) if entries
             else np.zeros((used.size, 0)))
        cols = (np.concatenate([candidates[k].columns for k, _ in entries]) if entries
                else np.zeros(0, int))
        r, b = residual[used, j], blocks[used]
        for block in np.unique(b):
            sel = b == block
            Xb, rb = X[sel], r[sel]
            gram[block, j][np.ix_(cols, cols)] = Xb.T @ Xb
            cross[block, j, cols] = Xb.T @ rb
            rss[block, j] = rb @ rb
            counts[block, j] = sel.sum()
    return FoldStatistics(gram, cross, rss, counts, variance)


def resample(stats, per_recording, n_splits, rng):
    """One block-bootstrap resample as cross-validation folds (see module docstring)."""
    J, P = stats.gram.shape[1], stats.gram.shape[2]
    gram = np.zeros((n_splits, J, P, P))
    cross = np.zeros((n_splits, J, P))
    rss, counts = np.zeros((n_splits, J)), np.zeros((n_splits, J))
    for blocks in per_recording:
        drawn = rng.choice(blocks, size=blocks.size, replace=True)
        folds = (np.arange(blocks.size) * n_splits) // blocks.size
        for f in range(n_splits):
            take = drawn[folds == f]
            gram[f] += stats.gram[take].sum(0)
            cross[f] += stats.cross[take].sum(0)
            rss[f] += stats.rss[take].sum(0)
            counts[f] += stats.counts[take].sum(0)
    return FoldStatistics(gram, cross, rss, counts, stats.variance)


def _family_key(candidate):
    return frozenset(p.family for p in (candidate.parts or (candidate,)))


def _clashes(key, families, confounded):
    """True when a family of ``key`` is in ``families`` or confounded with one there."""
    return bool(key & families) or any(set(confounded.get(f, ())) & families for f in key)


def best_variants(stats, candidates, guarded_stats, check=None, always=(), confounded=None):
    """Per family (or composite), its plausible variant that does best alone.

    Every candidate is scored alone (a rest-guarded one on ``guarded_stats``);
    per family the simplest variant within one paired standard error of the
    best held-out gain (:func:`~sklearn_gpcd.diagnosis.selection.one_standard_error`)
    among those with a positive gain whose fit is plausible (``check``), or,
    when none is, the variant with the best gain (it may show given the
    others; :func:`thresholded_selection` picks the variants again given the
    others and drops a family with no plausible gain then). The terms
    ``always`` (the all-data selection's picks) enter even when they show
    nothing alone.
    Then, strongest first, a composite enters only if none of its parts'
    families is in already (and a part only if its composite is not), and a
    family only if none it is ``confounded`` with is in (confounded
    alternatives compete as settings of one family do: the stronger alone
    stands for the group).

    Returns
    -------
    chosen : list of Candidate
        Composites split into their parts.
    """
    plain = [c for c in candidates if not c.effect.rest_guard]
    guard = [c for c in candidates if c.effect.rest_guard]
    steps = score_additions(stats, plain, np.zeros(0, int))
    if guard:
        steps += score_additions(guarded_stats, guard, np.zeros(0, int))
    by_key = {}
    for step in steps:
        by_key.setdefault(_family_key(step.candidate), []).append(step)
    picks = []
    for group in by_key.values():
        good = [st for st in group if st.gain > 0 and st.relative_gain > 0 and (
            check is None or check(st.candidate, st.theta) is None)]
        if good:
            picks.append(one_standard_error(good)[0])
    confounded = confounded or {}
    chosen, families = [], set()
    for step in sorted(picks, key=lambda st: -st.gain):
        key = _family_key(step.candidate)
        if _clashes(key, families, confounded):
            continue
        families |= key
        chosen.extend(step.candidate.parts or (step.candidate,))
    # the proposals of the all-data selection enter whatever they show alone: a term
    # may show only given the others (a friction peak next to an unmodelled payload);
    # not when an alternative it is confounded with (not itself proposed) stands in
    named = {c.family for c in always}
    for c in always:
        rivals = {f: v for f, v in confounded.get(c.family, {}).items() if f not in named}
        if c.family not in families and not _clashes({c.family}, families, rivals):
            chosen.append(c)
    return chosen


def _variants_given_others(stats, guarded_stats, chosen, candidates, check, confounded=None):
    """Each chosen term's variant picked again given all the other chosen terms.

    A variant chosen alone may fit what another effect explains (a Stribeck
    velocity scale picked next to an unmodelled payload); given the others,
    the simplest variant within one standard error of the best positive
    plausible gain (:func:`~sklearn_gpcd.diagnosis.selection.one_standard_error`)
    replaces it, and a family with none leaves the set. The families the
    term is ``confounded`` with (and no other chosen term holds) compete
    with its own: per family its variant as above, and of those the one
    with the largest held-out gain given the others stands for the group.
    """
    confounded = confounded or {}
    out = list(chosen)
    for k, term in enumerate(chosen):
        others = [c for c in out[:k] + out[k + 1:] if c is not None]
        taken = {c.family for c in others}
        members = {term.family} | (set(confounded.get(term.family, ())) - taken)
        variants = [c for c in candidates if not c.parts and c.family in members]
        base = np.concatenate([c.columns for c in others]) if others else np.zeros(0, int)
        on = guarded_stats if any(c.effect.rest_guard for c in (*others, *variants)) \
            else stats
        steps = [st for st in score_additions(on, variants, base, others)
                 if st.gain > 0 and (check is None or check(st.candidate, st.theta) is None)]
        per_family = {}
        for st in steps:
            per_family.setdefault(st.candidate.family, []).append(st)
        picks = [one_standard_error(group)[0] for group in per_family.values()]
        out[k] = max(picks, key=lambda st: st.gain).candidate if picks else None
    return [c for c in out if c is not None]


def thresholded_selection(stats, candidates, settings, guarded_stats=None):
    """One resample's selection: backward thresholding of the families' best variants.

    Starts from :func:`best_variants`, each variant picked again given the
    others, and removes, one at a time, the term
    with the smallest held-out relative gain among those that fail
    :meth:`~sklearn_gpcd.diagnosis.Step.eligible` given all the others
    (``min_gain``, ``min_t``, ``min_share`` of ``settings``), refitting
    after each removal, until every term passes. Terms are scored on the
    rest-guarded statistics when one of them is rest-guarded (a time delay).

    Parameters
    ----------
    stats, guarded_stats : FoldStatistics
    candidates : list of Candidate
    settings : dict
        ``min_gain``, ``min_t``, ``min_share``, ``check`` (plausibility of
        a variant's fit, or None), ``always`` (terms that enter whatever
        they show alone; default none) and ``confounded`` (per family the
        families it cannot be told from,
        :func:`~sklearn_gpcd.diagnosis.identifiability.confounded_families`;
        they enter as alternatives, one at a time; default none).

    Returns
    -------
    selected : list of Step
        Evidence of each kept term given all the others.

    Examples
    --------
    The viscous friction of joint 3 (index 2) is 0.5 A s/rad higher than
    modelled; Coulomb and viscous terms of every joint compete:

    >>> import numpy as np
    >>> from sklearn_gpcd.diagnosis import NominalModel, Signals, effect_library
    >>> from sklearn_gpcd.diagnosis import selection
    >>> gen, n = np.random.default_rng(7), 400
    >>> states = np.c_[gen.uniform(-2, 2, (n, 6)), gen.uniform(-1, 1, (n, 6)), np.zeros((n, 6))]
    >>> model = NominalModel("ur10")
    >>> sig = Signals.from_states(model, states)
    >>> sig.current = sig.reference + 0.02 * gen.normal(size=(n, 6)) + np.outer(
    ...     sig.qd[:, 2], [0, 0, 0.5, 0, 0, 0])
    >>> candidates, design = selection.build_candidates(
    ...     sig, model, effect_library(["coulomb_friction", "viscous_friction"]))
    >>> stats = selection.fold_statistics(
    ...     candidates, design, sig.current - sig.reference, np.ones((n, 6), bool),
    ...     selection.fold_index(sig, 5), 5, sig.current)
    >>> settings = {"min_gain": 0.02, "min_t": 3.0, "min_share": 0.01}
    >>> [st.candidate.label for st in thresholded_selection(stats, candidates, settings)]
    ['viscous_friction[joint 3]']
    """
    guarded_stats = stats if guarded_stats is None else guarded_stats
    confounded = settings.get("confounded")
    chosen = best_variants(stats, candidates, guarded_stats, settings.get("check"),
                           settings.get("always", ()), confounded)
    chosen = _variants_given_others(stats, guarded_stats, chosen, candidates,
                                    settings.get("check"), confounded)
    bar = (settings["min_gain"], settings["min_t"], settings["min_share"])
    while chosen:
        on = guarded_stats if any(c.effect.rest_guard for c in chosen) else stats
        evidence = given_others(on, chosen)
        failing = [st for st in evidence if not st.eligible(*bar)]
        if not failing:
            return evidence
        weakest = min(failing, key=lambda st: st.relative_gain if st.gain > 0 else -np.inf)
        chosen = [c for c in chosen if c is not weakest.candidate]
    return []


def recording_gains(stats, per_recording, n_splits, chosen):
    """Held-out relative gain of each chosen term on each recording, given the others.

    Each recording's blocks are cut into ``n_splits`` contiguous folds (fold
    ``f`` of every recording together, as in the selection); the terms are
    fitted with and without the term on the blocks outside fold ``f`` and the
    squared error of the term's joints summed over the blocks of fold ``f``
    of one recording. Per recording the gain is the share of the error
    without the term that it removes (NaN when the recording has none on its
    joints).

    Parameters
    ----------
    stats : FoldStatistics
        Per-block statistics (:func:`block_statistics`).
    per_recording : list of ndarray of int
        The blocks of each recording (:func:`block_index`).
    n_splits : int
    chosen : list of Candidate
        Terms (not composites), columns indexing ``stats``.

    Returns
    -------
    gains : list of ndarray of shape (n_recordings,)
        One per chosen term.

    Examples
    --------
    >>> import numpy as np
    >>> from types import SimpleNamespace
    >>> from sklearn_gpcd.diagnosis.selection import FoldStatistics
    >>> rng = np.random.default_rng(0)
    >>> x = rng.normal(size=(40, 25))  # 40 blocks of 25 samples, one joint, one column
    >>> r = 0.5 * x + 0.1 * rng.normal(size=x.shape)
    >>> stats = FoldStatistics((x * x).sum(1)[:, None, None, None],
    ...                        (x * r).sum(1)[:, None, None], (r * r).sum(1)[:, None],
    ...                        np.full((40, 1), 25.0), np.ones(1))
    >>> term = SimpleNamespace(columns=np.array([0]), joints=(0,))
    >>> g = recording_gains(stats, [np.arange(20), np.arange(20, 40)], 4, [term])
    >>> bool(np.all(g[0] > 0.9))
    True
    """
    n_blocks = stats.gram.shape[0]
    fold = np.zeros(n_blocks, dtype=int)
    for blocks in per_recording:
        fold[blocks] = (np.arange(blocks.size) * n_splits) // max(blocks.size, 1)
    owner = np.zeros(n_blocks, dtype=int)
    for k, blocks in enumerate(per_recording):
        owner[blocks] = k
    columns = np.concatenate([c.columns for c in chosen]) if chosen else np.zeros(0, int)
    weights = 1.0 / np.maximum(stats.rss.sum(0) / np.maximum(stats.counts.sum(0), 1),
                               1e-300)
    sse_all = _held_out_errors(stats, fold, n_splits, columns, weights)
    gains = []
    for cand in chosen:
        others = np.setdiff1d(columns, cand.columns)
        sse_without = _held_out_errors(stats, fold, n_splits, others, weights)
        joints = list(cand.joints)
        out = np.full(len(per_recording), np.nan)
        for k in range(len(per_recording)):
            mine = owner == k
            before = sse_without[mine][:, joints].sum()
            if before > 0:
                out[k] = (before - sse_all[mine][:, joints].sum()) / before
        gains.append(out)
    return gains


def _held_out_errors(stats, fold, n_splits, columns, weights):
    """Per block and joint: squared error of ``columns`` fitted without the block's fold."""
    c = np.asarray(columns, dtype=int)
    gram = stats.gram[:, :, c[:, None], c[None, :]]
    cross = stats.cross[:, :, c]
    sse = stats.rss.copy()
    if c.size == 0:
        return sse
    for f in range(n_splits):
        train, test = fold != f, fold == f
        A = np.einsum("j,bjkl->kl", weights, gram[train])
        theta = np.linalg.lstsq(A, np.einsum("j,bjk->k", weights, cross[train]),
                                rcond=None)[0]
        sse[test] = (stats.rss[test] - 2.0 * cross[test] @ theta
                     + np.einsum("k,bjkl,l->bj", theta, gram[test], theta))
    return np.maximum(sse, 0.0)


def _first_parameter(step, nominal):
    """The first physical parameter of a selected step's coefficients (NaN if unknown)."""
    cand = step.candidate
    if step.theta is None or cand.parts:
        return np.nan
    try:
        params = cand.effect.physical(np.asarray(step.theta, dtype=float),
                                      np.zeros((cand.n_params, cand.n_params)), cand.target,
                                      cand.settings, nominal)
        return float(params[cand.effect.parameter_names[0]][0])
    except (ValueError, KeyError, IndexError, ZeroDivisionError):
        return np.nan


def stability(candidates, design, residual, masks, signals, current, nominal, named,
              history, settings, picked=()):
    """Inclusion probability, size and held-out gain percentiles per family.

    Parameters
    ----------
    candidates : list of Candidate
        All candidates (``design`` indexes them).
    design : list of list of (int, ndarray)
    residual, current : ndarray of shape (n_samples, n_joints)
    masks : tuple of ndarray
        Rows used per joint: plain and rest-guarded.
    signals : Signals
    nominal : NominalModel
    named : list of FittedEffect
        The effects named on all data.
    history : list of list of Step
        The selection's evidence on all data (its first step ranks the
        shortlist).
    picked : sequence of Candidate
        The candidates the selection picked on all data (in the shortlist
        with their exact settings, composites included).
    settings : dict
        ``n_splits``, ``min_gain``, ``min_t``, ``min_share``, ``check``,
        ``n_resamples``, ``random_state``.

    Returns
    -------
    table : dict
        ``{(effect name, target): {"inclusion", "group_inclusion" (share of
        resamples naming the family or an alternative of its group, module
        docstring), "group" (``{family: inclusion}`` of the group's members,
        itself included), "labels" (their labels), "correlations" (of the
        others with it), "member" (the member named most often), "size" (2.5, 50, 97.5
        percentiles of the first parameter), "gain" (the same of the
        held-out relative gain), "recording_gains" (per recording, the
        held-out share of its error on the effect's joints that the effect
        removes given the others picked on all data; None for effects not
        picked there), "candidate" (the variant the resamples picked most
        often, None if none)}}`` for every family named in a resample or on
        all data.
    """
    families = {(f.name, f.target) for f in named}
    short = shortlist(candidates, history, families, picked)
    reduced, sub_design, n_columns = _reduce(candidates, design, short)
    blocks, per_recording = block_index(signals)
    n_blocks = int(blocks.max()) + 1
    plain = block_statistics(reduced, sub_design, n_columns, residual, masks[0], blocks,
                             n_blocks, current)
    guarded = None
    if any(c.effect.rest_guard for c in reduced):
        guarded = block_statistics(reduced, sub_design, n_columns, residual, masks[1],
                                   blocks, n_blocks, current)
    rng = np.random.default_rng(settings.get("random_state", 0))
    n_resamples = settings.get("n_resamples", N_RESAMPLES)
    base = [c for c in short if not c.parts]
    original = {id(r): c for r, c in zip(reduced, base)}
    named_terms = [reduced[k] for k, c in enumerate(base)
                   if any(c is part for pick in picked for part in (pick.parts or (pick,)))]
    weights = 1.0 / np.maximum(plain.rss.sum(0) / np.maximum(plain.counts.sum(0), 1), 1e-300)
    weights[plain.counts.sum(0) == 0] = 0.0
    confounded = confounded_families(reduced, plain.gram.sum(0), weights,
                                     settings.get("confounded_correlation",
                                                  CONFOUNDED_CORRELATION))
    settings = {**settings, "always": named_terms, "confounded": confounded}
    found, named_sets = {}, []
    for _ in range(n_resamples):
        state = rng.bit_generator.state
        stats = resample(plain, per_recording, settings["n_splits"], rng)
        guarded_stats = None
        if guarded is not None:
            rng.bit_generator.state = state  # the same blocks
            guarded_stats = resample(guarded, per_recording, settings["n_splits"], rng)
        selected = thresholded_selection(stats, reduced, settings, guarded_stats)
        named_sets.append({p.family for st in selected for p in (st.candidate.parts
                                                                 or (st.candidate,))})
        for step in selected:
            for part in (step.candidate.parts or (step.candidate,)):
                entry = found.setdefault(part.family, {"n": 0, "size": [], "gain": [],
                                                       "picks": []})
                entry["n"] += 1
                entry["picks"].append(original[id(part)])
                entry["gain"].append(float(step.relative_gain))
                if not step.candidate.parts:
                    entry["size"].append(_first_parameter(step, nominal))
    on = guarded if guarded is not None and any(c.effect.rest_guard for c in named_terms) \
        else plain
    per_term = dict(zip([c.family for c in named_terms],
                        recording_gains(on, per_recording, settings["n_splits"],
                                        named_terms)))
    table = {}
    for family in set(found) | families:
        entry = found.get(family, {"n": 0, "size": [], "gain": [], "picks": []})
        picks = entry["picks"]
        sizes = [v for v in entry["size"] if np.isfinite(v)]
        table[family] = {
            "inclusion": entry["n"] / n_resamples,
            "size": np.percentile(sizes, [2.5, 50, 97.5]).tolist() if sizes else None,
            "gain": np.percentile(entry["gain"], [2.5, 50, 97.5]).tolist()
            if entry["gain"] else None,
            "recording_gains": None if family not in per_term else
            [None if not np.isfinite(g) else float(g) for g in per_term[family]],
            "candidate": max(picks, key=lambda c: sum(p is c for p in picks))
            if picks else None}
    labels = {c.family: c.label for c in reduced if not c.parts}
    for family, row in table.items():
        row.update(_group_inclusion(family, families, confounded, named_sets, labels))
    return table


def _group_inclusion(family, named, confounded, named_sets, labels):
    """The group of ``family`` (module docstring): its inclusion, members' shares, member."""
    group = {family} | {f for f in confounded.get(family, ()) if f not in named}
    n = max(len(named_sets), 1)
    shares = {f: sum(f in s for s in named_sets) / n for f in sorted(group, key=str)}
    member = max(shares, key=lambda f: (shares[f], f == family))
    return {"group_inclusion": sum(bool(s & group) for s in named_sets) / n,
            "group": shares, "member": member,
            "labels": {f: labels.get(f, f[0]) for f in group},
            "correlations": {f: float(c) for f, c in confounded.get(family, {}).items()
                             if f in group}}
