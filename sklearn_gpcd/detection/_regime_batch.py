"""The regime pass over a whole batch at once: :func:`batch_regime_pass`.

:func:`~sklearn_gpcd.detection._regimes.regime_pass` steps a
:class:`~sklearn_gpcd.detection._regimes.RegimeState` sample by sample (a
Python loop of about 25 us a sample on the reference machine). Without an
alarm (what calibration reads) the state is a function of the batch that
array operations give, to the last bit:

* **regime**: a sample is still when every :math:`|\\dot q_\\ell| <
  \\sigma_v`; with :math:`j(k)` the last moving sample at or before
  :math:`k` in its segment, ``still_for`` is :math:`k - j(k)`, and a still
  sample is at rest when no motion came before it in the segment or
  :math:`k - j(k) >` ``settle``, settling otherwise, in the stage of the
  last ``(samples, code)`` of ``stages`` with :math:`k - j(k) >` ``samples``;
* **braking**: some :math:`|\\ddot q_\\ell| >` ``brake_limit`` at a sample
  :math:`i` of the segment with :math:`k - i \\le` ``brake_hold``;
* **rest reference**: each run of rest samples (the motion regimes; braking
  does not interrupt it) takes :math:`b_\\ell = m_\\ell` at the sample
  where joint :math:`\\ell` is taken (at entry, or with a rest band once
  :math:`|m_\\ell| \\le B_\\ell` has held for ``entry_hold`` samples; before
  that :math:`\\tilde m = m - \\mathrm{clip}(m, -B, B)`), then follows
  :math:`\\tilde m_k = m_k - b_k,\\ b_{k+1} = b_k + \\beta \\tilde m_k`. That
  recursion is sequential: it runs on the rest samples only, per joint, on
  Python floats (the same IEEE double operations, in the same order, as
  the state's numpy arrays).

Decisions equal the sample-by-sample pass bit for bit
(``tests/test_regime_batch.py``).
"""

import numpy as np

from .._gate import quasi_static
from ._regimes import BRAKING, MOVING, REST, SETTLING


def batch_regime_pass(signal, motion, starts, sigma_v, settle, beta, brake_limit=None,
                      brake_hold=0, alarm_hold=0, rest_band=None, entry_hold=0, stages=()):
    """:func:`~sklearn_gpcd.detection._regimes.regime_pass` with array operations.

    Same arguments and returns: ``(referenced, regimes, reference)``.
    ``alarm_hold`` is not used (no alarm).
    """
    signal = np.asarray(signal, dtype=float)
    n_joints = signal.shape[1]
    out = np.array(signal, dtype=float, copy=True)
    regimes = np.empty(signal.shape[0], dtype=np.intp)
    bounds = np.append(np.asarray(starts, dtype=np.intp), signal.shape[0])
    band = None if rest_band is None else np.asarray(rest_band, dtype=float)
    for lo, hi in zip(bounds[:-1].tolist(), bounds[1:].tolist()):
        if hi <= lo:
            continue
        seg_motion = motion[lo:hi]
        motion_regime = _motion_regimes(seg_motion[:, :n_joints], sigma_v, settle, stages)
        regimes[lo:hi] = motion_regime
        if brake_limit is not None:
            braking = _braking(seg_motion[:, n_joints:], float(brake_limit), int(brake_hold))
            regimes[lo:hi][braking] = BRAKING
        if beta is not None:
            _rest_reference(signal[lo:hi], out[lo:hi], motion_regime == REST, beta, band,
                            int(entry_hold))
    return out, regimes, signal - out


def _last_true(flags):
    """Index of the last True at or before each row (-1 before the first)."""
    index = np.where(flags, np.arange(len(flags)), -1)
    return np.maximum.accumulate(index) if len(index) else index


def _motion_regimes(qd, sigma_v, settle, stages=()):
    """Moving, a settling stage or rest of each sample of one segment
    (``RegimeState.regime``)."""
    still = quasi_static(qd, sigma_v).all(axis=1)
    last_move = _last_true(~still)
    still_for = np.arange(len(still)) - last_move
    rest = (last_move < 0) | (still_for > settle)
    settling = np.full(len(still), SETTLING, dtype=np.intp)
    for samples, code in stages:
        settling[still_for > samples] = code
    return np.where(still, np.where(rest, REST, settling), MOVING).astype(np.intp)


def _braking(qdd, limit, hold):
    """Braking samples of one segment (``RegimeState.braking``): within ``hold``
    samples after one with some ``|qdd_l| > limit``."""
    exceed = (np.abs(qdd) > limit).any(axis=1)
    last = _last_true(exceed)
    return (last >= 0) & (np.arange(len(exceed)) - last <= hold)


def _runs(flags):
    """``(start, stop)`` of each run of True."""
    edges = np.diff(np.concatenate([[0], flags.astype(np.int8), [0]]))
    return zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist())


def _rest_reference(signal, out, rest, beta, band, entry_hold):
    """Re-reference ``out`` (a copy of ``signal``) in place on each rest run."""
    for lo, hi in _runs(rest):
        for joint in range(signal.shape[1]):
            m = signal[lo:hi, joint]
            take = 0 if band is None else _take_row(m, band[joint], entry_hold)
            if band is not None:  # before the take: the excess over the band shows
                clipped = m[:take]
                out[lo:lo + take, joint] = clipped - np.clip(clipped, -band[joint],
                                                            band[joint])
            if take < len(m):
                out[lo + take:hi, joint] = _tracked(m[take:].tolist(), beta)


def _take_row(m, band, entry_hold):
    """Row of a rest run where a joint takes its reference (``len(m)``: never):
    at once when ``|m| <= band`` at entry, else after ``entry_hold + 1`` rows
    in a row within it (``RegimeState._take``)."""
    inside = np.abs(m) <= band
    if inside.size and inside[0]:
        return 0
    outside = _last_true(~inside)
    streak = np.arange(len(m)) - outside  # rows inside in a row, ending at each row
    rows = np.flatnonzero(streak > entry_hold)
    return int(rows[0]) if rows.size else len(m)


def _tracked(m, beta):
    """``m - b`` along one joint's rest run from the row where ``b = m`` is
    taken: the tracker ``b <- b + beta (m - b)`` on Python floats."""
    b = m[0]
    first = b - b
    b = b + beta * first
    out = [first]
    append = out.append
    for value in m[1:]:
        d = value - b
        append(d)
        b = b + d * beta
    return out

