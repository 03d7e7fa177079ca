"""Moving thresholds that follow the motion: the envelope of the residual.

Our extension of the paper (issue 38). One threshold per joint for the
whole ``moving`` regime is set by the worst motion of the calibration data
(on the real UR10e: a joint standing **still**, its dry friction holding any
torque up to breakaway, while another moves; hard accelerations), so a task
that moves all joints smoothly misses its collisions. The envelope makes the
moving threshold of joint :math:`\\ell` a function of the state,

.. math::

    \\sigma_{CD,\\ell}(x) = s_\\ell\\,\\big(1 + a_\\ell\\, e^{-(\\dot q_\\ell / v_0)^2}
        + b_\\ell\\, |\\ddot q_\\ell| + c_\\ell\\, |\\dot q_\\ell|\\big),

with :math:`s_\\ell` the level of the rule (a sliding joint at zero
acceleration) and non-negative :math:`a, b, c`: a joint that is stuck
(:math:`|\\dot q_\\ell| \\ll v_0`), accelerates hard or moves fast gets a
wider band, a smoothly sliding one a tight band. The coefficients are the
tightest non-negative envelope of the calibration residual: a linear
programme that minimises the mean envelope subject to lying above the peak
debounced ``|m|`` of every 0.25 s window of motion.
"""

import numpy as np
from scipy.optimize import linprog

from ._signal import window_segments

#: Columns of the envelope's features: 1, stuck, |qdd|, |qd|.
N_FEATURES = 4
#: Samples per window whose peak the envelope must cover (0.25 s at 100 Hz).
WINDOW = 25
#: Smallest level [signal units] of the envelope's constant term.
_FLOOR = 1e-6
#: Seconds the envelope holds its largest value: a band widened by a
#: velocity reversal or a burst of acceleration narrows again only after it,
#: so the decaying tail of one contact does not cross it twice.
HOLD_SECONDS = 0.25


def envelope_features(motion, n_joints, still_speed):
    """Per sample and joint: ``[1, exp(-(qd / v0)^2), |qdd|, |qd|]``, shape (n, n_joints, 4).

    ``motion``: velocities, then accelerations; ``still_speed``: :math:`v_0`
    [rad/s], below which a joint counts as stuck.
    """
    qd = np.abs(motion[:, :n_joints])
    qdd = np.abs(motion[:, n_joints:2 * n_joints])
    return np.stack([np.ones_like(qd), np.exp(-np.square(qd / still_speed)), qdd, qd],
                    axis=-1)


def envelope_factor(features, coef):
    """``1 + a stuck + b |qdd| + c |qd|`` per sample and joint (``coef``: (n_joints, 3))."""
    return 1.0 + np.einsum("nlk,lk->nl", features[..., 1:], coef)


def over_envelope(debounced, moving, features, coef, starts, hold):
    """``debounced`` over the envelope on the ``moving`` rows (1 elsewhere).

    What the levels of a rule with a motion envelope are taken on. The
    envelope holds its largest value for ``hold`` samples, restarting at the
    segment ``starts``.
    """
    factor = window_segments(envelope_factor(features, coef), hold, starts, np.max)
    return debounced / np.where(moving[:, None], factor, 1.0)


def window_peaks(debounced, moving, features):
    """The envelope's constraints of one recording: the peak of each window of motion.

    Returns ``(features, peaks)`` of shape (n_windows, n_joints, 4) and
    (n_windows, n_joints): per joint, the features at the sample where its
    debounced ``|m|`` peaks in the window.
    """
    rows = np.flatnonzero(moving)
    if rows.size == 0:
        return np.zeros((0, debounced.shape[1], N_FEATURES)), np.zeros((0, debounced.shape[1]))
    chunks = np.array_split(rows, max(1, rows.size // WINDOW))
    top = np.array([c[np.argmax(debounced[c], axis=0)] for c in chunks])  # (n_windows, J)
    joints = np.arange(debounced.shape[1])
    return features[top, joints], debounced[top, joints]


def fit_envelope(constraints):
    """The tightest non-negative envelope over the window peaks of several recordings.

    ``constraints``: :func:`window_peaks` of each recording. Returns
    ``(level, coef)``: the constant term :math:`s_\\ell` per joint (the
    threshold of a smoothly sliding joint at zero acceleration, before any
    margin) and :math:`a, b, c` relative to it, shape (n_joints, 3).
    """
    features = np.concatenate([c[0] for c in constraints])
    peaks = np.concatenate([c[1] for c in constraints])
    n_joints = peaks.shape[1]
    level, coef = np.ones(n_joints), np.zeros((n_joints, N_FEATURES - 1))
    for joint in range(n_joints):
        phi, y = features[:, joint], peaks[:, joint]
        if y.size == 0 or not np.any(y > 0):
            continue
        result = linprog(phi.mean(axis=0), A_ub=-phi, b_ub=-y, method="highs",
                         bounds=[(_FLOOR, None)] + [(0.0, None)] * (N_FEATURES - 1))
        if result.status != 0:  # pragma: no cover - the problem is always feasible
            level[joint] = y.max()
            continue
        level[joint] = result.x[0]
        coef[joint] = result.x[1:] / result.x[0]
    return level, coef
