"""The recording a diagnosis asks for: a smooth excitation for what it could not see.

Each need (an effect too weak or too confounded in the recordings at hand,
on some joints) maps to a *segment* of a periodic Fourier-series motion
(Swevers et al. 1997) about a pose:

.. math::

    q_j(t) = c_j + w(t) \\sum_k a_{jk} \\sin(2 \\pi f_k t + \\varphi_{jk}),

with a quintic smooth-step window :math:`w` (0 at both ends with zero
first and second derivatives) so that every segment starts and ends at
rest at its pose; segments are joined by quintic rest-to-rest moves. The
whole plan is twice continuously differentiable (continuous acceleration).
Position, velocity and acceleration are linear in the amplitudes of a
joint, so each joint's amplitudes are scaled by one factor that brings the
worst sample within the limits (:func:`fourier_segment`).

Segments by need (:data:`SEGMENTS`):

* ``low_speed`` (Stribeck peak, softening, Coulomb): slow sweeps of the
  joint through zero velocity, peak speed ``LOW_SPEED`` rad/s;
* ``gravity_load`` (torque constant, payload, link mass, offset): the pose
  of the recordings' range where gravity loads the joint most, moved about
  it so that the load changes (a change of the torque constant scales it;
  friction cannot mimic a load that changes at constant speed sign);
* ``chirp`` (time delay, rotor inertia): a multisine of all joints up to
  ``CHIRP_MAX_HZ``, acceleration-limited (a delay shows as a phase lag that
  grows with frequency);
* ``steady`` (friction drift): one period of a slow all-joint motion
  repeated, so that a change in time is not a change in pose;
* ``fourier`` (other effects): a slow all-joint motion.
"""

from dataclasses import dataclass, field

import numpy as np

from .effects import EFFECTS

#: Longest plan [s].
PLAN_SECONDS = 180.0
#: Peak speed of the low-speed sweeps [rad/s].
LOW_SPEED = 0.15
#: Highest frequency of the chirp segment [Hz].
CHIRP_MAX_HZ = 2.0
#: Share of the velocity limit and of the position range a plan may use.
LIMIT_SHARE = 0.8
#: Default acceleration limit [rad/s^2] when none is given.
MAX_ACCELERATION = 2.0
#: Duration of the window's ramps at each end of a segment [s].
RAMP = 2.0
#: Segment per effect (the effects' own ``plan_segment``), and its duration [s].
SEGMENTS = {cls.name: cls.plan_segment for cls in EFFECTS if cls.plan_segment}
DURATIONS = {"low_speed": 30.0, "gravity_load": 30.0, "chirp": 20.0, "steady": 60.0,
             "fourier": 30.0}


def smooth_window(t, duration, ramp=RAMP):
    """Quintic smooth-step window and its first two derivatives.

    ``w = s(t / ramp)`` rising, ``s((duration - t) / ramp)`` falling, 1 in
    between, with ``s(x) = 10 x^3 - 15 x^4 + 6 x^5`` (zero slope and
    curvature at both ends).

    Parameters
    ----------
    t : ndarray
        Times [s] in ``[0, duration]``.
    duration, ramp : float
        Segment length and ramp length [s] (ramp capped at half the length).

    Returns
    -------
    w, wd, wdd : ndarray

    Examples
    --------
    >>> import numpy as np
    >>> w, wd, wdd = smooth_window(np.array([0.0, 1.0, 5.0, 10.0]), 10.0, ramp=2.0)
    >>> w.tolist(), np.abs(wd[[0, 2, 3]]).tolist()
    ([0.0, 0.5, 1.0, 0.0], [0.0, 0.0, 0.0])
    """
    t = np.asarray(t, dtype=float)
    ramp = min(ramp, duration / 2.0)
    w, wd, wdd = np.ones_like(t), np.zeros_like(t), np.zeros_like(t)
    for x, sign in (((t) / ramp, 1.0), ((duration - t) / ramp, -1.0)):
        inside = x < 1.0
        xi = np.clip(x[inside], 0.0, 1.0)
        w[inside] *= 10 * xi ** 3 - 15 * xi ** 4 + 6 * xi ** 5
        wd[inside] = sign * (30 * xi ** 2 - 60 * xi ** 3 + 30 * xi ** 4) / ramp
        wdd[inside] = (60 * xi - 180 * xi ** 2 + 120 * xi ** 3) / ramp ** 2
    return w, wd, wdd


def fourier_segment(center, amplitudes, frequencies, phases, duration, period, limits):
    """One windowed Fourier-series segment, scaled per joint into the limits.

    Parameters
    ----------
    center : ndarray of shape (n_joints,)
        Pose the segment moves about [rad].
    amplitudes, phases : ndarray of shape (n_joints, n_harmonics)
        Sine amplitudes [rad] (before scaling) and phases [rad].
    frequencies : ndarray of shape (n_harmonics,)
        [Hz].
    duration, period : float
        Length and sample period [s].
    limits : Limits

    Returns
    -------
    t, q, qd, qdd : ndarray
        Times from 0 and positions, velocities, accelerations
        ``(n_samples, n_joints)``.

    Examples
    --------
    >>> import numpy as np
    >>> lim = Limits(lower=-np.ones(1), upper=np.ones(1), velocity=np.ones(1),
    ...              acceleration=np.ones(1))
    >>> t, q, qd, qdd = fourier_segment(np.zeros(1), np.array([[5.0]]), np.array([0.5]),
    ...                                 np.zeros((1, 1)), 10.0, 0.01, lim)
    >>> bool(np.abs(qd).max() <= 0.8 + 1e-9 and np.abs(qdd).max() <= 1.0 + 1e-9)
    True
    """
    t = np.arange(0.0, duration + 0.5 * period, period)
    w, wd, wdd = smooth_window(t, duration)
    arg = 2 * np.pi * np.outer(t, frequencies)[:, None, :] + phases[None]  # (n, J, K)
    omega = 2 * np.pi * np.asarray(frequencies)
    s = np.einsum("njk,jk->nj", np.sin(arg), amplitudes)
    sd = np.einsum("njk,jk->nj", np.cos(arg), amplitudes * omega)
    sdd = -np.einsum("njk,jk->nj", np.sin(arg), amplitudes * omega ** 2)
    x = w[:, None] * s
    xd = wd[:, None] * s + w[:, None] * sd
    xdd = wdd[:, None] * s + 2 * wd[:, None] * sd + w[:, None] * sdd
    room = np.minimum(center - limits.lower, limits.upper - center) * LIMIT_SHARE
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.nanmin(np.vstack([
            np.ones_like(center),
            room / np.abs(x).max(0),
            LIMIT_SHARE * limits.velocity / np.abs(xd).max(0),
            limits.acceleration / np.abs(xdd).max(0)]), axis=0)
    scale = np.where(np.isfinite(scale), np.maximum(scale, 0.0), 0.0)
    return t, center + x * scale, xd * scale, xdd * scale


def rest_to_rest(q0, q1, period, limits):
    """Quintic rest-to-rest move from ``q0`` to ``q1`` within the limits.

    Returns ``t, q, qd, qdd`` as :func:`fourier_segment` (its duration is
    the shortest multiple of ``period`` meeting the limits, at least 1 s).

    Examples
    --------
    >>> import numpy as np
    >>> lim = Limits(lower=-np.ones(1) * 3, upper=np.ones(1) * 3, velocity=np.ones(1),
    ...              acceleration=np.ones(1))
    >>> t, q, qd, qdd = rest_to_rest(np.zeros(1), np.ones(1), 0.01, lim)
    >>> float(q[-1, 0]), float(qd[-1, 0]), bool(np.abs(qdd).max() <= 1.0)
    (1.0, 0.0, True)
    """
    dq = np.abs(np.asarray(q1) - np.asarray(q0))
    with np.errstate(divide="ignore", invalid="ignore"):
        need = np.concatenate([15.0 / 8.0 * dq / (LIMIT_SHARE * limits.velocity),
                               np.sqrt(10.0 / np.sqrt(3.0) * dq / limits.acceleration), [1.0]])
    duration = period * np.ceil(np.nanmax(need) / period)
    t = np.arange(0.0, duration + 0.5 * period, period)
    x = t / duration
    s = 10 * x ** 3 - 15 * x ** 4 + 6 * x ** 5
    sd = (30 * x ** 2 - 60 * x ** 3 + 30 * x ** 4) / duration
    sdd = (60 * x - 180 * x ** 2 + 120 * x ** 3) / duration ** 2
    d = np.asarray(q1) - np.asarray(q0)
    return t, q0 + np.outer(s, d), np.outer(sd, d), np.outer(sdd, d)


@dataclass
class Limits:
    """Joint limits a plan stays within.

    Attributes
    ----------
    lower, upper : ndarray of shape (n_joints,)
        Position limits [rad].
    velocity, acceleration : ndarray of shape (n_joints,)
        [rad/s], [rad/s^2].

    Examples
    --------
    >>> import numpy as np
    >>> Limits(-np.ones(2), np.ones(2), np.ones(2), np.ones(2)).lower.tolist()
    [-1.0, -1.0]
    """

    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray


@dataclass
class ExcitationPlan:
    """A joint trajectory to record, and why.

    Attributes
    ----------
    time : ndarray of shape (n_samples,)
        [s], from 0, at the recordings' sample period.
    q, qd, qdd : ndarray of shape (n_samples, n_joints)
        Target positions [rad], velocities [rad/s] and accelerations [rad/s^2].
    segments : list of dict
        ``start``, ``stop`` [s], ``kind``, ``effects``, ``joints`` (0-based),
        ``reason``.

    Examples
    --------
    >>> import numpy as np
    >>> plan = ExcitationPlan(np.arange(3) * 0.1, np.zeros((3, 2)), np.zeros((3, 2)),
    ...                       np.zeros((3, 2)))
    >>> plan.to_csv().splitlines()[0]
    'timestamp,target_q_0,target_q_1'
    """

    time: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    segments: list = field(default_factory=list)

    @property
    def duration(self):
        """Length [s]."""
        return float(self.time[-1]) if len(self.time) else 0.0

    def to_csv(self, path=None):
        """The plan as CSV (``timestamp,target_q_0,...``; s, rad); written to ``path`` if given."""
        header = ",".join(["timestamp"] + [f"target_q_{j}" for j in range(self.q.shape[1])])
        rows = [header] + [",".join([f"{t:.6f}"] + [f"{v:.8f}" for v in q])
                           for t, q in zip(self.time, self.q)]
        text = "\n".join(rows) + "\n"
        if path is not None:
            with open(path, "w", encoding="utf-8") as fh:
                fh.write(text)
        return text

    def text(self):
        """One line per segment: when, what it is for and why."""
        lines = [f"excitation plan: {self.duration:.0f} s"]
        for s in self.segments:
            joints = ", ".join(str(j + 1) for j in s["joints"]) or "all"
            reasons = [r for r in s.get("reason", "").split("; ") if r]
            more = f"; {len(reasons) - 1} more" if len(reasons) > 1 else ""
            lines.append(f"  {s['start']:6.1f}-{s['stop']:6.1f} s  {s['kind']:12s} joints "
                         f"{joints}: {', '.join(e.replace('_', ' ') for e in s['effects'])}"
                         + (f" ({reasons[0]}{more})" if reasons else ""))
        return "\n".join(lines)


def robot_limits(robot, velocity=None, acceleration=None):
    """The robot's position and velocity limits, the given acceleration limit.

    Parameters
    ----------
    robot : Robot
    velocity : array-like, default=None
        [rad/s] per joint; None reads the robot's (URDF) limits.
    acceleration : float or array-like, default=None
        [rad/s^2]; None gives :data:`MAX_ACCELERATION`.

    Returns
    -------
    limits : Limits

    Examples
    --------
    >>> from sklearn_gpcd.robots import load_robot
    >>> lim = robot_limits(load_robot("ur10"))
    >>> lim.acceleration.tolist()
    [2.0, 2.0, 2.0, 2.0, 2.0, 2.0]
    """
    n = robot.n_joints
    lower, upper = robot.lower.copy(), robot.upper.copy()
    lower = np.where(np.isfinite(lower), lower, -2 * np.pi)
    upper = np.where(np.isfinite(upper), upper, 2 * np.pi)
    v = robot.velocity_limits if velocity is None else np.asarray(velocity, dtype=float)
    v = np.where(np.isfinite(v) & (v > 0), v, 1.0) * np.ones(n)
    a = MAX_ACCELERATION if acceleration is None else acceleration
    return Limits(lower, upper, v, np.asarray(a, dtype=float) * np.ones(n))


def _gravity_pose(nominal, center, joints, limits):
    """The pose near ``center`` where gravity loads ``joints`` most (a small search).

    The shoulder/elbow (joints 2, 3) and the joints themselves are tried at
    offsets of 0, +-0.6 rad (within the limits); the pose that maximises the
    smallest gravity current over ``joints`` (relative to its torque
    constant) wins.
    """
    n = len(center)
    offsets = np.array([0.0, 0.6, -0.6])
    movable = sorted({j for j in (1, 2) if j < n} | set(joints))
    grid = np.array(np.meshgrid(*[offsets] * len(movable))).reshape(len(movable), -1).T
    poses = np.repeat(center[None], len(grid), axis=0)
    poses[:, movable] += grid
    margin = 0.2 * (limits.upper - limits.lower) * (1 - LIMIT_SHARE)
    inside = np.all((poses > limits.lower + margin) & (poses < limits.upper - margin), axis=1)
    poses = poses[inside] if inside.any() else center[None]
    zeros = np.zeros_like(poses)
    load = np.abs(nominal.robot.rnea(poses, zeros, zeros)) / nominal.torque_constants
    return poses[int(np.argmax(load[:, joints].min(1)))]


def _segment(kind, joints, center, nominal, limits, period, rng):
    """Samples ``(t, q, qd, qdd)`` and its start pose of a segment of ``kind`` on ``joints``."""
    n = len(center)
    duration = DURATIONS[kind]
    active = list(joints) or list(range(n))
    amplitudes = np.zeros((n, 3))
    phases = rng.uniform(0, 2 * np.pi, size=(n, 3))
    if kind == "low_speed":
        frequencies = np.array([0.2, 0.47, 0.73])
        for j in active:  # peak speed ~LOW_SPEED at the base harmonic
            amplitudes[j] = LOW_SPEED / (2 * np.pi * frequencies) * np.array([0.7, 0.2, 0.1])
    elif kind == "chirp":
        frequencies = np.array([0.5, 1.2, CHIRP_MAX_HZ])
        amplitudes[:] = 0.2 / (1 + np.arange(3))
    else:
        base = 1.0 / (DURATIONS["steady"] / 4 if kind == "steady" else duration / 3)
        frequencies = base * np.array([1.0, 2.0, 3.0])
        amplitudes[active] = np.array([0.8, 0.4, 0.2])
        if kind == "gravity_load":
            center = _gravity_pose(nominal, center, active, limits)
    t, q, qd, qdd = fourier_segment(center, amplitudes, frequencies, phases, duration,
                                    period, limits)
    return (t, q, qd, qdd), center


def excitation_plan(needs, nominal, center, period, limits, max_seconds=PLAN_SECONDS,
                    random_state=0):
    """A plan of segments for ``needs``, in their order, until ``max_seconds``.

    A slow all-joint segment closes the plan when time is left (the named
    effects seen on other motion).

    Parameters
    ----------
    needs : list of dict
        ``effect`` (name), ``joints`` (0-based; empty for all) and ``reason``;
        most needed first. Needs of one segment kind are merged.
    nominal : NominalModel
        For the gravity loads of the poses.
    center : array-like of shape (n_joints,)
        Pose the plan starts from and returns to [rad] (the recordings'
        middle pose, where the robot is known to move freely).
    period : float
        Sample period [s].
    limits : Limits
    max_seconds : float, default=180
    random_state : int, default=0
        Phases of the harmonics.

    Returns
    -------
    plan : ExcitationPlan

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.diagnosis import NominalModel
    >>> from sklearn_gpcd.robots import load_robot
    >>> robot = load_robot("ur10")
    >>> center = np.array([0.0, -1.6, 1.6, -1.6, -1.6, 0.0])
    >>> plan = excitation_plan([{"effect": "time_delay", "joints": [], "reason": ""}],
    ...                        NominalModel(robot), center, 0.008, robot_limits(robot))
    >>> plan.segments[0]["kind"], plan.duration <= 180
    ('chirp', True)
    """
    rng = np.random.default_rng(random_state)
    center = np.asarray(center, dtype=float)
    merged = {}
    for need in needs:
        kind = SEGMENTS.get(need["effect"], "fourier")
        key = (kind,) if kind in ("chirp", "steady", "fourier") else (kind, "joints")
        entry = merged.setdefault(key, {"kind": kind, "effects": [], "joints": set(),
                                        "reasons": []})
        if need["effect"] not in entry["effects"]:
            entry["effects"].append(need["effect"])
        entry["joints"] |= set(need.get("joints", ()))
        if need.get("reason"):
            entry["reasons"].append(need["reason"])
    entries = list(merged.values())
    if not any(e["kind"] == "fourier" for e in entries):  # time left: confirm on other motion
        entries.append({"kind": "fourier", "effects": ["confirmation"], "joints": set(),
                        "reasons": ["the named effects on other motion"]})
    pieces, segments, pose, elapsed = [], [], center, 0.0
    for entry in entries:
        joints = sorted(entry["joints"]) if entry["kind"] not in ("chirp", "steady") else []
        (t, q, qd, qdd), start = _segment(entry["kind"], joints, center, nominal, limits,
                                          period, rng)
        move_in = rest_to_rest(pose, start, period, limits)
        move_out = rest_to_rest(start, center, period, limits)
        if elapsed + move_in[0][-1] + t[-1] + move_out[0][-1] > max_seconds:
            continue
        pieces += [move_in, (t, q, qd, qdd)]
        segments.append({"start": elapsed + move_in[0][-1],
                         "stop": elapsed + move_in[0][-1] + t[-1],
                         "kind": entry["kind"], "effects": entry["effects"],
                         "joints": joints, "reason": "; ".join(entry["reasons"])})
        elapsed += move_in[0][-1] + t[-1]
        pose = q[-1]
    pieces.append(rest_to_rest(pose, center, period, limits))
    return _join(pieces, period, segments)


def _join(pieces, period, segments):
    """Concatenate sampled pieces (each starts at rest where the last ended, at rest).

    The first sample of every piece after the first repeats the last one's
    end and is dropped.
    """
    qs, qds, qdds = [], [], []
    for k, (t, q, qd, qdd) in enumerate(pieces):
        qs.append(q[k > 0:])
        qds.append(qd[k > 0:])
        qdds.append(qdd[k > 0:])
    q = np.vstack(qs)
    return ExcitationPlan(np.arange(len(q)) * period, q, np.vstack(qds), np.vstack(qdds),
                          segments)
