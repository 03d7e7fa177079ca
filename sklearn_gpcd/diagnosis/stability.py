"""How stable a selection is: the selection rerun on block-bootstrap resamples.

The residual is autocorrelated, so samples are not resampled one by one:
each recording is cut into blocks of ``BLOCK_SECONDS`` and a resample draws
as many blocks of each recording with replacement (moving-block bootstrap
on a fixed grid). Per block only the sufficient statistics of the regression
(:math:`D^TD`, :math:`D^Tr`, :math:`r^Tr` per joint) of a *shortlist* of
candidates are kept: the effects named on all data, and the strongest
settings of the families that came closest; a resample's cross-validation
folds are its drawn blocks cut into ``n_splits`` contiguous groups. The same
selection (:func:`~sklearn_gpcd.diagnosis.selection.forward_selection`,
same thresholds, same plausibility check) runs on every resample.

Each family (effect and target) gets its *inclusion probability* (share of
resamples that name it, as in stability selection and ensemble-SINDy), and
for the resamples that name it the percentiles of its first parameter and
of its held-out gain. An effect named on all data is kept only when its
inclusion probability reaches ``MIN_INCLUSION``: a term that a few blocks of
the recording bring in or out is not a finding.
"""

from dataclasses import replace

import numpy as np

from .selection import FoldStatistics, forward_selection

#: Block length [s] of the bootstrap (several times the residual's correlation time);
#: shorter recordings get shorter blocks, ``MIN_BLOCKS`` each at least.
BLOCK_SECONDS, MIN_BLOCKS = 2.0, 20
#: Resamples.
N_RESAMPLES = 20
#: Inclusion probability an effect needs to be kept.
MIN_INCLUSION = 0.6
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
        ``n_splits``, ``min_gain``, ``min_t``, ``max_effects``,
        ``min_share``, ``check``, ``n_resamples``, ``random_state``.

    Returns
    -------
    table : dict
        ``{(effect name, target): {"inclusion", "size" (2.5, 50, 97.5
        percentiles of the first parameter), "gain" (the same of the
        held-out relative gain)}}`` for every family named in a resample or
        on all data.
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
    found = {}
    for _ in range(n_resamples):
        state = rng.bit_generator.state
        stats = resample(plain, per_recording, settings["n_splits"], rng)
        guarded_stats = None
        if guarded is not None:
            rng.bit_generator.state = state  # the same blocks
            guarded_stats = resample(guarded, per_recording, settings["n_splits"], rng)
        selected, _ = forward_selection(
            stats, reduced, settings["min_gain"], settings["min_t"],
            settings.get("max_effects"), guarded_stats, min_share=settings["min_share"],
            check=settings.get("check"))
        for step in selected:
            for part in (step.candidate.parts or (step.candidate,)):
                entry = found.setdefault(part.family, {"n": 0, "size": [], "gain": []})
                entry["n"] += 1
                entry["gain"].append(float(step.relative_gain))
                if not step.candidate.parts:
                    entry["size"].append(_first_parameter(step, nominal))
    table = {}
    for family in set(found) | families:
        entry = found.get(family, {"n": 0, "size": [], "gain": []})
        sizes = [v for v in entry["size"] if np.isfinite(v)]
        table[family] = {
            "inclusion": entry["n"] / n_resamples,
            "size": np.percentile(sizes, [2.5, 50, 97.5]).tolist() if sizes else None,
            "gain": np.percentile(entry["gain"], [2.5, 50, 97.5]).tolist()
            if entry["gain"] else None}
    return table
