"""What the recordings at hand can show: the information matrix of the candidates.

With per-joint weights :math:`w_\\ell` (inverse residual variance after the
fitted model) the candidates' stacked columns have the information matrix

.. math::

    A = \\sum_\\ell w_\\ell D_\\ell^T D_\\ell .

Given the effects already named (columns :math:`S`), a candidate's columns
:math:`c` are judged on the Schur complement
:math:`A_{c|S} = A_{cc} - A_{cS} A_{SS}^{-1} A_{Sc}` (what is left of them
once the named effects are fitted; for a candidate not named, given also
the unnamed candidates it is confounded with, below). Its covariance is
:math:`\\kappa A_{c|S}^{-1}`, with :math:`\\kappa` the variance inflation of
the autocorrelated residual (Bartlett weights over ``lags`` samples), and
the *smallest detectable size* of its first physical parameter is
``DETECTABLE_SE`` standard deviations of it (delta method at zero, through
:meth:`Effect.physical`).

Two candidates of different effects or targets are *confounded* in these
recordings when the partial correlation of their columns given the named
effects (the largest entry between their column groups of
:math:`A_{\\cdot|S}` normalised to unit diagonal) reaches
``CONFOUNDED_CORRELATION``: no fit can tell which of the two moved the
current. For a named effect, the partial correlation is taken given the
*other* named effects.
"""

import numpy as np

#: Standard deviations a size must reach to be told from zero.
DETECTABLE_SE = 3.0
#: Partial correlation from which two candidates count as confounded.
CONFOUNDED_CORRELATION = 0.9
#: Lags [samples] of the autocorrelation correction.
LAGS = 50


def variance_inflation(residual, mask, lags=LAGS):
    """Mean over joints of the Bartlett variance inflation of the residual.

    :math:`\\kappa_\\ell = 1 + 2 \\sum_{k \\le L} (1 - k/(L+1)) \\rho_\\ell(k)`
    (at least 1), over each joint's used rows.

    Parameters
    ----------
    residual : ndarray of shape (n_samples, n_joints)
    mask : ndarray of bool, same shape
    lags : int, default=50

    Returns
    -------
    kappa : float

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> white = rng.normal(size=(5000, 1))
    >>> smooth = np.convolve(white[:, 0], np.ones(20), "same")[:, None]
    >>> ones = np.ones((5000, 1), bool)
    >>> variance_inflation(white, ones) < 1.5 < variance_inflation(smooth, ones)
    True
    """
    out = []
    weights = 1.0 - np.arange(1, lags + 1) / (lags + 1.0)
    for j in range(residual.shape[1]):
        r = residual[mask[:, j], j]
        r = r - r.mean() if r.size else r
        denom = float(r @ r)
        if r.size <= lags + 1 or denom <= 0:
            continue
        rho = np.array([(r[:-k] @ r[k:]) / denom for k in range(1, lags + 1)])
        out.append(max(1.0, 1.0 + 2.0 * float(weights @ rho)))
    return float(np.mean(out)) if out else 1.0


def column_correlation(gram, weights):
    """Absolute correlations of the candidates' columns in the information matrix.

    :math:`|A_{ab}| / \\sqrt{A_{aa} A_{bb}}` with
    :math:`A = \\sum_\\ell w_\\ell D_\\ell^T D_\\ell` (uncentred: the columns
    enter the current without an intercept).

    Parameters
    ----------
    gram : ndarray of shape (n_joints, n_columns, n_columns)
        :math:`D_\\ell^T D_\\ell` per joint.
    weights : ndarray of shape (n_joints,)
        :math:`w_\\ell`, per joint.

    Returns
    -------
    corr : ndarray of shape (n_columns, n_columns)
        Ones on the diagonal.

    Examples
    --------
    Two columns that differ by a small ripple, and a third one:

    >>> import numpy as np
    >>> x = np.linspace(-1, 1, 50)
    >>> D = np.c_[x, x + 0.01 * np.cos(9 * x), np.cos(9 * x)]
    >>> np.round(column_correlation((D.T @ D)[None], np.ones(1)), 2)[0]
    array([1., 1., 0.])
    """
    A = np.einsum("j,jab->ab", np.asarray(weights, dtype=float), gram)
    d = np.sqrt(np.maximum(np.diag(A), 1e-300))
    return np.abs(A / np.outer(d, d))


def confounded_families(candidates, gram, weights, limit=CONFOUNDED_CORRELATION):
    """Per family, the other families the recordings cannot tell it from.

    Two families (effect, target) are confounded when the largest
    :func:`column_correlation` between the columns of any of their settings
    reaches ``limit``: some setting of one moves the current as a setting of
    the other does, and no fit on these recordings can tell which it was.
    The relation is not made transitive (a Coulomb step confounded with a
    torque constant that is confounded with a viscous term does not make the
    Coulomb step and the viscous term alternatives).

    Parameters
    ----------
    candidates : list of Candidate
        Composites are skipped (their parts are judged).
    gram : ndarray of shape (n_joints, n_columns, n_columns)
    weights : ndarray of shape (n_joints,)
    limit : float, default=CONFOUNDED_CORRELATION

    Returns
    -------
    confounded : dict
        ``{family: {other family: correlation}}``, only families with one.

    Examples
    --------
    >>> import numpy as np
    >>> from types import SimpleNamespace
    >>> x = np.linspace(-1, 1, 50)
    >>> D = np.c_[x, x + 0.01 * np.cos(9 * x), np.cos(9 * x)]
    >>> cands = [SimpleNamespace(family=f, parts=(), columns=np.array([k]))
    ...          for k, f in enumerate(["a", "b", "c"])]
    >>> sorted(confounded_families(cands, (D.T @ D)[None], np.ones(1)))
    ['a', 'b']
    """
    corr = column_correlation(gram, weights)
    columns = {}
    for cand in candidates:
        if not cand.parts:
            columns.setdefault(cand.family, []).extend(int(c) for c in cand.columns)
    families = list(columns)
    out = {}
    for a, fa in enumerate(families):
        for fb in families[a + 1:]:
            c = float(corr[np.ix_(columns[fa], columns[fb])].max())
            if c >= limit:
                out.setdefault(fa, {})[fb] = c
                out.setdefault(fb, {})[fa] = c
    return out


def _first_std(candidate, cov, nominal):
    """Standard deviation of the candidate's first physical parameter at zero."""
    theta = np.zeros(candidate.n_params)
    try:
        with np.errstate(all="ignore"):
            params = candidate.effect.physical(theta, cov, candidate.target,
                                               candidate.settings, nominal)
        name = candidate.effect.parameter_names[0]
        std = float(params[name][1])
    except (ValueError, ZeroDivisionError, KeyError, IndexError, np.linalg.LinAlgError):
        std = float("nan")
    if not np.isfinite(std):
        std = float(np.sqrt(max(cov[0, 0], 0.0)))
    return std


def identifiability(candidates, gram, weights, named, nominal, inflation=1.0):
    """Per candidate family: smallest detectable size, its error and what it is confounded with.

    Parameters
    ----------
    candidates : list of Candidate
        All candidates (composites are skipped: their parts are judged).
    gram : ndarray of shape (n_joints, n_columns, n_columns)
        :math:`D_\\ell^T D_\\ell` over the rows used (all folds).
    weights : ndarray of shape (n_joints,)
        Per-joint weights (inverse residual variance).
    named : list of Candidate
        The candidates of the named effects.
    nominal : NominalModel
    inflation : float, default=1.0
        Variance inflation of the autocorrelated residual
        (:func:`variance_inflation`).

    Returns
    -------
    table : list of dict
        One per family (effect, target), its best-excited setting:
        ``effect``, ``target``, ``joints``, ``label``, ``named`` (bool),
        ``parameter``, ``std`` (of the first parameter), ``detectable``
        (``DETECTABLE_SE`` times it), ``matters`` (the effect's
        :meth:`~sklearn_gpcd.diagnosis.Effect.size_that_matters`, or None),
        ``condition`` (of the normalised information of its columns given
        the named ones) and ``confounded_with``: ``[{"label", "correlation"}]``.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.diagnosis import (Candidate, NominalModel, Signals,
    ...                                     effect_library)
    >>> nominal = NominalModel("ur10")
    >>> rng = np.random.default_rng(0)
    >>> signals = Signals.from_states(nominal, rng.normal(size=(200, 18)))
    >>> lib = effect_library(["coulomb_friction", "viscous_friction"])
    >>> from sklearn_gpcd.diagnosis.selection import build_candidates
    >>> cands, design = build_candidates(signals, nominal, lib)
    >>> cands = [c for c in cands if not c.parts]
    >>> gram = np.zeros((6, 12, 12))
    >>> for j in range(6):
    ...     X = np.hstack([v for _, v in design[j]])
    ...     cols = np.concatenate([cands[c].columns for c, _ in design[j]])
    ...     gram[j][np.ix_(cols, cols)] = X.T @ X
    >>> table = identifiability(cands, gram, np.ones(6), [], nominal)
    >>> len(table), table[0]["label"], table[0]["confounded_with"]
    (12, 'coulomb_friction[joint 1]', [])
    """
    base = [c for c in candidates if not c.parts]
    if not base:
        return []
    A = np.einsum("j,jab->ab", np.asarray(weights, dtype=float), gram)
    named_keys = {(c.family, tuple(c.columns)) for c in named}

    def given(cols):
        """Schur complement of the whole matrix given ``cols``."""
        if cols.size == 0:
            return A
        inv = np.linalg.pinv(A[np.ix_(cols, cols)])
        return A - A[:, cols] @ inv @ A[cols, :]

    def columns(cands):
        return np.concatenate([c.columns for c in cands]) if cands else np.zeros(0, int)

    schur = given(columns(named))
    rows = []
    for cand in base:
        is_named = (cand.family, tuple(cand.columns)) in named_keys
        info = given(columns([n for n in named if n.family != cand.family])) \
            if is_named else schur
        block = info[np.ix_(cand.columns, cand.columns)]
        left = np.diag(block) / np.maximum(np.diag(A)[cand.columns], 1e-300)
        if np.any(left < 1e-6):  # the named effects (or nothing) already hold its columns
            std, condition = np.inf, np.inf
        else:
            d = np.sqrt(np.diag(block))
            condition = float(np.linalg.cond(block / np.outer(d, d)))
            std = _first_std(cand, inflation * np.linalg.pinv(block), nominal)
        rows.append({"candidate": cand, "named": is_named, "std": std,
                     "condition": condition})
    best = {}
    for row in rows:  # a named family by its named setting, others by their worst setting
        old = best.get(row["candidate"].family)
        if old is None or (row["named"] and not old["named"]) or \
                (row["named"] == old["named"] and not row["named"]
                 and row["std"] > old["std"]):
            best[row["candidate"].family] = row
    chosen = list(best.values())
    cols = [r["candidate"].columns for r in chosen]
    corr = column_correlation(gram, weights)
    table = []
    for row, own in zip(chosen, cols):
        cand = row["candidate"]
        confounded = []
        for other, theirs in zip(chosen, cols):
            if other is row or other["candidate"].family == cand.family or (
                    not other["named"]
                    and other["candidate"].effect.size_that_matters(
                        nominal, other["candidate"].target) is None):
                continue
            c = float(corr[np.ix_(own, theirs)].max())
            if c >= CONFOUNDED_CORRELATION:
                confounded.append({"label": other["candidate"].label, "correlation": c,
                                   "named": bool(other["named"])})
        std = row["std"]
        rivals = [o["candidate"] for o in chosen
                  if o["candidate"].label in {c["label"] for c in confounded} and not o["named"]]
        if rivals and not row["named"] and np.isfinite(std):
            # an unnamed confounder may be there as well: judge the candidate given it too
            info = given(columns(list(named) + rivals))
            block = info[np.ix_(own, own)]
            left = np.diag(block) / np.maximum(np.diag(A)[own], 1e-300)
            std = np.inf if np.any(left < 1e-6) else \
                _first_std(cand, inflation * np.linalg.pinv(block), nominal)
        table.append({
            "effect": cand.effect.name, "target": None if cand.target is None
            else int(cand.target), "joints": [int(j) for j in cand.joints],
            "label": cand.label, "named": bool(row["named"]), "settings": dict(cand.settings),
            "parameter": cand.effect.parameter_names[0] if cand.effect.parameter_names
            else "", "std": std, "detectable": DETECTABLE_SE * std,
            "matters": cand.effect.size_that_matters(nominal, cand.target),
            "condition": row["condition"],
            "confounded_with": sorted(confounded, key=lambda c: -c["correlation"])})
    return table


def needs(table):
    """What to ask a new recording for: families too weak or confounded, most needed first.

    A family is needed when it was not named and the smallest size it could
    show (given the named effects) exceeds the size that matters; what it
    is confounded with is named in the reason. Families whose effect
    assesses no size are skipped.

    Parameters
    ----------
    table : list of dict
        From :func:`identifiability`.

    Returns
    -------
    needs : list of dict
        ``effect``, ``joints``, ``reason``, ``ratio`` (detectable over
        matters), sorted by ``ratio``, largest first.

    Examples
    --------
    >>> needs([{"effect": "time_delay", "joints": [0], "label": "time_delay",
    ...         "named": False, "detectable": 0.01, "matters": 0.005,
    ...         "confounded_with": [], "parameter": "delay"}])[0]["reason"]
    'time_delay: these recordings show only delay beyond 0.01 (matters from 0.005)'
    """
    out = []
    for e in table:
        if e["named"] or e["matters"] is None:
            continue
        ratio = e["detectable"] / e["matters"] if e["matters"] > 0 else np.inf
        if ratio <= 1.0:
            continue
        size = "no size" if not np.isfinite(e["detectable"]) else \
            f"only {e['parameter']} beyond {e['detectable']:.3g}"
        reason = f"{e['label']}: these recordings show {size} (matters from {e['matters']:.3g})"
        if e["confounded_with"]:
            other = e["confounded_with"][0]
            reason = (f"cannot tell {e['label']} from {other['label']} (correlation "
                      f"{other['correlation']:.2f}); " + reason.split(": ", 1)[1])
        out.append({"effect": e["effect"], "joints": e["joints"], "ratio": float(ratio),
                    "reason": reason})
    return sorted(out, key=lambda n: -n["ratio"])
