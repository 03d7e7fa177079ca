"""Plausibility checks on the rows a reader keeps: gaps and units.

Nothing here drops or changes a row. Each check returns a sentence for the
file's single :class:`~sklearn_gpcd.io.RecordingWarning` (or None):

* :func:`find_gaps` -- time steps longer than :data:`GAP_WARNING_FACTOR`
  median sampling periods. Derivatives and filters interpolate across a
  gap, so the user should know where it is (and may split the recording).
* :func:`looks_like_degrees` -- joint positions beyond ``2 pi + 0.25`` rad
  on more than 5 % of the samples.
* :func:`velocity_gain` -- the least-squares gain :math:`g_j` in

  .. math:: q_j[k] - q_j[k-1] \\approx g_j \\,
            \\tfrac{1}{2}(\\dot q_j[k] + \\dot q_j[k-1]) \\, (t_k - t_{k-1}),

  on joints that move (correlation of the two sides >= 0.95). Consistent
  units give :math:`g_j = 1` (174 joint gains on the 45 UR10e logs: 0.997-1.004);
  :math:`180/\\pi` means ``q`` in degrees and ``qd`` in rad/s,
  :math:`\\pi/180` the reverse, :math:`10^{-3}` a time column in
  milliseconds. This catches degrees even where the magnitude test cannot
  (motion within +-6.5 deg).
"""

import numpy as np

#: Joint positions beyond this [rad] suggest degrees (UR joints span +-2 pi).
DEGREES_THRESHOLD = 2 * np.pi + 0.25
#: Fraction of samples that must exceed it before the degrees warning fires.
DEGREES_FRACTION = 0.05
#: Time steps longer than this many median sampling periods are reported.
GAP_WARNING_FACTOR = 10
#: Fewest time steps needed to judge sampling gaps and velocity units.
MIN_STEPS = 10
#: Correlation of dq with qd*dt above which a joint's gain is trusted.
MIN_CORRELATION = 0.95
#: A gain within this factor of 1 is consistent units.
GAIN_TOLERANCE = 1.25
#: Gains with a known cause, and the cause.
KNOWN_GAINS = (
    (180 / np.pi, "q looks like degrees while qd is in rad/s (convert q with numpy.deg2rad)"),
    (np.pi / 180, "qd looks like deg/s while q is in rad (convert qd with numpy.deg2rad)"),
    (1e-3, "time looks like milliseconds (pass time_scale=1e-3)"),
    (1e-6, "time looks like microseconds (pass time_scale=1e-6)"),
    (1e-9, "time looks like nanoseconds (pass time_scale=1e-9)"),
)
#: Items quoted in messages.
N_QUOTED = 5


def looks_like_degrees(q):
    """True when more than 5 % of the samples have ``|q_j| > 2 pi + 0.25``.

    Parameters
    ----------
    q : ndarray of shape (n_samples, n_joints)
        Joint positions.

    Returns
    -------
    degrees : bool

    A UR joint spans ``[-2 pi, 2 pi]`` rad, so positions beyond that on a
    sizeable share of the samples are almost surely degrees. A recording in
    degrees that stays within +-6.5 deg cannot be told apart this way (see
    :func:`velocity_gain`).

    Examples
    --------
    >>> import numpy as np
    >>> looks_like_degrees(np.array([[0.0, -90.0, 90.0]] * 10))
    True
    >>> looks_like_degrees(np.array([[0.0, -1.57, 1.57]] * 10))
    False
    """
    if q.size == 0:
        return False
    beyond = np.max(np.abs(q), axis=1) > DEGREES_THRESHOLD
    return bool(np.mean(beyond) > DEGREES_FRACTION)


def degrees_note(q):
    """Sentence for the warning when :func:`looks_like_degrees`, else None.

    Parameters
    ----------
    q : ndarray of shape (n_samples, n_joints)

    Returns
    -------
    note : str or None

    Examples
    --------
    >>> import numpy as np
    >>> degrees_note(np.array([[0.0, 90.0]] * 10))[:30]
    'joint positions reach |q| = 90'
    """
    if not looks_like_degrees(q):
        return None
    peak = float(np.max(np.abs(q)))
    return (f"joint positions reach |q| = {peak:.4g} with more than "
            f"{100 * DEGREES_FRACTION:.0f} % of the samples beyond 2*pi rad; the angles "
            "look like degrees (convert with numpy.deg2rad).")


def find_gaps(time, factor=GAP_WARNING_FACTOR):
    """Indices ``k`` where ``time[k + 1] - time[k]`` exceeds ``factor`` median steps.

    Parameters
    ----------
    time : ndarray of shape (n,)
        Strictly increasing time stamps.
    factor : float, default=10
        Gap threshold in median sampling periods.

    Returns
    -------
    gaps : ndarray of int
        Step indices; empty with fewer than :data:`MIN_STEPS` steps.
    median : float
        Median sampling period (NaN when too short).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.r_[np.arange(20) * 0.01, 5.0 + np.arange(20) * 0.01]
    >>> gaps, median = find_gaps(t)
    >>> gaps.tolist(), round(float(median), 3)
    ([19], 0.01)
    """
    steps = np.diff(time)
    if steps.size < MIN_STEPS:
        return np.empty(0, dtype=int), float("nan")
    median = float(np.median(steps))
    return np.flatnonzero(steps > factor * median), median


def gaps_note(time, row_ids, kind="line"):
    """Sentence naming every gap :func:`find_gaps` finds, and the gaps.

    Parameters
    ----------
    time : ndarray of shape (n,)
        Time stamps of the kept rows.
    row_ids : ndarray of int, shape (n,)
        Their line (row) numbers.
    kind : str, default="line"
        What ``row_ids`` count.

    Returns
    -------
    note : str or None
        None without gaps.
    gaps : list of [int, float]
        ``[row number after the gap, gap length in s]`` per gap.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.r_[np.arange(20) * 0.01, 3.0 + np.arange(20) * 0.01]
    >>> note, gaps = gaps_note(t, np.arange(40) + 2)
    >>> gaps
    [[22, 2.81]]
    >>> note[:46]
    '1 gap in time longer than 10 median sampling p'
    """
    idx, median = find_gaps(time)
    if idx.size == 0:
        return None, []
    steps = np.diff(time)
    gaps = [[int(row_ids[k + 1]), round(float(steps[k]), 9)] for k in idx]
    shown = "; ".join(f"{steps[k]:.4g} s before {kind} {row_ids[k + 1]} "
                      f"(t={float(time[k + 1])!r})" for k in idx[:N_QUOTED])
    more = f"; ... ({idx.size} in all)" if idx.size > N_QUOTED else ""
    plural = "s" if idx.size != 1 else ""
    note = (f"{idx.size} gap{plural} in time longer than {GAP_WARNING_FACTOR} median sampling "
            f"periods ({median:.4g} s): {shown}{more}. Nothing was dropped, but derivatives "
            "interpolate across a gap: split the recording there if the robot moved "
            "meanwhile (their rows are in recording.metadata['gaps']).")
    return note, gaps


def velocity_gain(time, q, qd):
    """Least-squares gain of position steps on velocity times time step, per joint.

    See the module docstring for the model. Joints whose steps correlate
    less than :data:`MIN_CORRELATION` with ``qd * dt`` (standing still,
    noise) get NaN, and so do all joints with fewer than :data:`MIN_STEPS`
    steps. Steps across a gap (:func:`find_gaps`) are left out.

    Parameters
    ----------
    time : ndarray of shape (n,)
    q, qd : ndarray of shape (n, n_joints)

    Returns
    -------
    gain : ndarray of shape (n_joints,)

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(100) * 0.01
    >>> q, qd = np.sin(t)[:, None], np.cos(t)[:, None]
    >>> np.round(velocity_gain(t, np.c_[q, np.rad2deg(q)], np.c_[qd, qd]), 2).tolist()
    [1.0, 57.3]
    """
    n_joints = q.shape[1]
    if time.shape[0] <= MIN_STEPS:
        return np.full(n_joints, np.nan)
    dt = np.diff(time)
    ok = ~np.isin(np.arange(dt.size), find_gaps(time)[0])
    dq = np.diff(q, axis=0)[ok]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        v = (0.5 * (qd[1:] + qd[:-1]) * dt[:, None])[ok]
        num = np.sum(dq * v, axis=0)
        den = np.sum(v * v, axis=0)
        corr = num / np.sqrt(den * np.sum(dq * dq, axis=0))
        gain = num / den
    return np.where(np.isfinite(corr) & (corr >= MIN_CORRELATION), gain, np.nan)


def units_note(time, q, qd, q_labels):
    """Sentence when :func:`velocity_gain` says q, qd and time disagree, else None.

    Parameters
    ----------
    time : ndarray of shape (n,)
    q, qd : ndarray of shape (n, n_joints)
    q_labels : list of str
        Column labels of ``q`` for the message.

    Returns
    -------
    note : str or None

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(100) * 0.01
    >>> units_note(t * 1000, np.sin(t)[:, None], np.cos(t)[:, None], ["'q'"])
    "position steps disagree with the velocities: dq = g * qd * dt with gain g (1 expected) \
of 'q' 0.001; time looks like milliseconds (pass time_scale=1e-3)."
    """
    gain = velocity_gain(time, q, qd)
    off = np.flatnonzero(np.isfinite(gain) & ((gain > GAIN_TOLERANCE)
                                              | (gain < 1 / GAIN_TOLERANCE)))
    if off.size == 0:
        return None
    typical = float(np.median(gain[off]))
    cause = next((why for value, why in KNOWN_GAINS
                  if value / GAIN_TOLERANCE <= typical <= value * GAIN_TOLERANCE),
                 "q, qd or time are in other units than rad, rad/s and s")
    cols = ", ".join(f"{q_labels[j]} {gain[j]:.4g}" for j in off[:N_QUOTED])
    more = f", ... ({off.size} joints)" if off.size > N_QUOTED else ""
    return (f"position steps disagree with the velocities: dq = g * qd * dt with gain g "
            f"(1 expected) of {cols}{more}; {cause}.")


#: Shortest recording [s] :func:`recording_problems` accepts by default.
MIN_DURATION = 1.0


def recording_problems(recording, min_duration=MIN_DURATION):
    """What makes a loaded recording suspect: degrees, other time units, too short.

    A reader only warns about these (:class:`~sklearn_gpcd.io.RecordingWarning`);
    a caller that should not go on (the ``gpcd`` command) turns them into
    errors unless the user confirms.

    Parameters
    ----------
    recording : Recording
    min_duration : float, default=1.0
        Shortest duration [s] that is not reported.

    Returns
    -------
    problems : list of (str, str)
        ``(kind, sentence)`` with kind ``"degrees"`` (:func:`degrees_note`),
        ``"units"`` (:func:`units_note`: milliseconds, deg/s, ...) or
        ``"short"``.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> t = np.arange(5) * 0.01
    >>> rec = Recording(time=t, q=np.full((5, 1), 90.0), qd=np.zeros((5, 1)),
    ...                 current=np.zeros((5, 1)))
    >>> [kind for kind, _ in recording_problems(rec)]
    ['degrees', 'short']
    """
    q_labels = [f"q[{j}]" for j in range(recording.n_joints)]
    units = units_note(recording.time, recording.q, recording.qd, q_labels)
    notes = {"degrees": [degrees_note(recording.q)], "units": [], "short": []}
    notes["degrees" if units and "deg" in units.rpartition(";")[2] else "units"].append(units)
    if recording.duration < min_duration:
        notes["short"].append(f"{recording.n_samples} samples over {recording.duration:.3g} "
                              f"s, shorter than {min_duration:g} s.")
    return [(kind, " ".join(n for n in found if n)) for kind, found in notes.items()
            if any(found)]
