"""Quasi-static gates, motion regimes and contiguous segments.

The paper switches between a *dynamical* and a *quasi-static* model per joint
with the gate of Eq. 15,

.. math:: a_\\ell(x_k) = 1 \\text{ if } |\\dot q_{k\\ell}| < \\sigma_v,
   \\quad 0 \\text{ otherwise},

with :math:`\\sigma_v = 10^{-2}` rad/s (Sec. III-C). The same threshold
nulls the friction columns of :math:`\\bar\\phi_\\ell` (Eq. 17).
:func:`regimes` refines this into labels that explain where a model errs.
"""

import numpy as np

from .._gate import DEFAULT_SIGMA_V, check_sigma_v, quasi_static

#: Labels returned by :func:`regimes`, from lowest to highest precedence
#: (words of the package's one regime vocabulary, ``_gate.REGIME_WORDS``).
REGIMES = ("moving", "creep", "rest", "braking", "reversal")


def _as_float_array(value, name):
    value = np.asarray(value, dtype=float)
    if value.ndim not in (1, 2):
        raise ValueError(
            f"{name} must have shape (n_samples,) or (n_samples, n_joints), "
            f"got {value.shape}"
        )
    bad = np.argwhere(~np.isfinite(value))
    if bad.size:
        raise ValueError(
            f"{name} is NaN or inf at index {tuple(int(i) for i in bad[0])}"
        )
    return value


def _check_positive(value, name):
    if not np.isscalar(value) or not value > 0:
        raise ValueError(f"{name} must be a positive number, got {value!r}")


def quasi_static_mask(qd, sigma_v=DEFAULT_SIGMA_V):
    """Gate :math:`a_\\ell` of Eq. 15: True where :math:`|\\dot q_\\ell| < \\sigma_v`.

    Parameters
    ----------
    qd : array-like of shape (n_samples, n_joints) or (n_samples,)
        Joint velocities [rad/s].
    sigma_v : float, default=1e-2
        Velocity threshold [rad/s] between quasi-static and dynamical
        configurations (the paper's value, Sec. III-C).

    Returns
    -------
    mask : ndarray of bool, same shape as ``qd``
        ``mask[k, l]`` is True when joint ``l`` is quasi-static at sample
        ``k``.

    Examples
    --------
    >>> from sklearn_gpcd.features import quasi_static_mask
    >>> quasi_static_mask([[0.0, 0.5], [0.009, -0.01]]).tolist()
    [[True, False], [True, False]]
    """
    qd = _as_float_array(qd, "qd")
    check_sigma_v(sigma_v, "quasi_static_mask")
    return quasi_static(qd, sigma_v)


def contiguous_segments(mask):
    """Runs of True in a 1-D mask as half-open ``(start, stop)`` index pairs.

    Parameters
    ----------
    mask : array-like of bool, shape (n_samples,)
        E.g. one joint's quasi-static mask, or ``labels > 0``.

    Returns
    -------
    segments : list of tuple of int
        ``(start, stop)`` with ``mask[start:stop]`` all True and maximal, in
        increasing order.

    Examples
    --------
    >>> from sklearn_gpcd.features import contiguous_segments
    >>> contiguous_segments([0, 1, 1, 0, 1])
    [(1, 3), (4, 5)]
    """
    mask = np.asarray(mask)
    if mask.ndim != 1:
        raise ValueError(f"mask must be 1-D, got shape {mask.shape}")
    edges = np.diff(np.concatenate([[0], mask.astype(bool).astype(np.int8), [0]]))
    starts = np.flatnonzero(edges == 1)
    stops = np.flatnonzero(edges == -1)
    return [(int(a), int(b)) for a, b in zip(starts, stops)]


def _reversal_mask(qd, sigma_v, window):
    """True around direction reversals of a single joint's velocity ``qd``."""
    out = np.zeros(qd.shape, dtype=bool)
    moving = np.flatnonzero(~quasi_static(qd, sigma_v))
    if moving.size < 2:
        return out
    signs = np.sign(qd[moving])
    flips = np.flatnonzero((signs[:-1] != signs[1:]) & (np.diff(moving) <= window))
    half = window // 2
    for i in flips:
        start = max(moving[i] - half, 0)
        out[start : moving[i + 1] + half + 1] = True
    return out


def regimes(
    qd, qdd=None, sigma_v=DEFAULT_SIGMA_V, sigma_rest=None, brake_limit=5.0, reversal_window=10
):
    """Label every sample of every joint with its motion regime.

    Velocity bands (per joint :math:`\\ell`, with :math:`\\sigma_r` =
    ``sigma_rest``):

    * ``"rest"``: :math:`|\\dot q_\\ell| < \\sigma_r` (standing still, velocity
      at the sensor noise level);
    * ``"creep"``: :math:`\\sigma_r \\le |\\dot q_\\ell| < \\sigma_v`
      (moving, but quasi-static: static friction dominates);
    * ``"moving"``: :math:`|\\dot q_\\ell| \\ge \\sigma_v` (dynamical).

    so ``rest`` or ``creep`` is exactly :func:`quasi_static_mask` (Eq. 15).
    Two event labels override the bands:

    * ``"braking"``: :math:`|\\ddot q_\\ell| \\ge` ``brake_limit``, hard
      stops and starts (only when ``qdd`` is given; the detector's braking
      regime has the same meaning);
    * ``"reversal"`` (highest precedence): the joint changes direction. Two
      samples ``k1 < k2`` with :math:`|\\dot q_\\ell| \\ge \\sigma_v` and
      opposite signs, only quasi-static samples between them and
      ``k2 - k1 <= reversal_window``, mark samples ``k1 - w // 2`` to
      ``k2 + w // 2`` (``w = reversal_window``). A stop longer than the
      window followed by motion in the other direction is a rest, not a
      reversal.

    Parameters
    ----------
    qd : array-like of shape (n_samples, n_joints) or (n_samples,)
        Joint velocities [rad/s].
    qdd : array-like of the same shape as ``qd``, default=None
        Joint accelerations [rad/s^2]; without them no sample is
        ``"braking"``.
    sigma_v : float, default=1e-2
        Quasi-static threshold [rad/s] of Eq. 15.
    sigma_rest : float, default=None
        Rest threshold [rad/s]; ``None`` means ``sigma_v / 10`` (1e-3 rad/s,
        the rest level of the UR10e logs). Must not exceed ``sigma_v``.
    brake_limit : float, default=5.0
        Acceleration threshold [rad/s^2]. On the UR10e reference logs the
        Fourier excitation trajectories stay below about 4 rad/s^2 (99.9th
        percentile below 3, Savitzky-Golay derivative of ``qd``) while the
        abrupt starts/stops of the joint-wise friction runs reach about 10,
        so 5 flags impacts and aggressive starts/stops, not ordinary motion.
    reversal_window : int, default=10
        Window in samples (0.1 s at the UR10e's 100 Hz) for reversals.

    Returns
    -------
    labels : ndarray of str, same shape as ``qd``
        One of :data:`REGIMES` per sample and joint.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.features import regimes
    >>> qd = np.array([0.0, 0.005, 0.5, 0.5, 0.05, -0.05, -0.5])
    >>> regimes(qd, reversal_window=2).tolist()
    ['rest', 'creep', 'moving', 'reversal', 'reversal', 'reversal', 'reversal']
    """
    qd = _as_float_array(qd, "qd")
    check_sigma_v(sigma_v, "regimes")
    sigma_rest = sigma_v / 10 if sigma_rest is None else sigma_rest
    _check_positive(sigma_rest, "sigma_rest")
    if sigma_rest > sigma_v:
        raise ValueError(f"sigma_rest={sigma_rest!r} exceeds sigma_v={sigma_v!r}")
    if int(reversal_window) != reversal_window or reversal_window < 1:
        raise ValueError(
            f"reversal_window must be a positive integer, got {reversal_window!r}"
        )
    speed = np.abs(qd)
    labels = np.full(qd.shape, "moving", dtype=f"<U{max(map(len, REGIMES))}")
    labels[quasi_static(qd, sigma_v)] = "creep"
    labels[speed < sigma_rest] = "rest"
    if qdd is not None:
        qdd = _as_float_array(qdd, "qdd")
        if qdd.shape != qd.shape:
            raise ValueError(f"qdd has shape {qdd.shape}, qd has {qd.shape}")
        _check_positive(brake_limit, "brake_limit")
        labels[np.abs(qdd) >= brake_limit] = "braking"
    columns = qd.reshape(qd.shape[0], -1)
    reversal = np.column_stack(
        [_reversal_mask(col, sigma_v, int(reversal_window)) for col in columns.T]
    ).reshape(qd.shape)
    labels[reversal] = "reversal"
    return labels
