"""The paper's experiments on the simulator (Sec. III-C and Sec. V).

Each experiment has a planner ``reference_*`` (cheap: joint reference, and
contacts, no simulation) and a generator ``make_*`` that simulates it and
returns a :class:`~sklearn_gpcd.io.Recording` at 125 Hz with ``labels``.
Write one as a UR RTDE CSV file with :func:`sklearn_gpcd.io.write_rtde_csv`.

=============================  =============================================
:func:`simulate_d1`                200 random flange targets in a hemisphere,
                               ~80,000 samples (paper's D1)
:func:`simulate_d2`                50 random targets then a 30 cm circle at
                               30 mm/s, ~22,000 samples (paper's D2)
:func:`simulate_joint1_cyclic`     joint 1 alone between rests at q1 = pi/2,
                               2.09, pi/2, 0.52 rad (paper Sec. III-C)
:func:`simulate_interaction_test`  circle then rest, four pushes on link 1
                               (paper Sec. V-B)
=============================  =============================================
"""

import numpy as np
import pinocchio as pin
from sklearn.utils import check_random_state

from ..robots import resolve_robot
from .contacts import Contact
from .simulator import RobotSimulator
from .trajectory import JointTrajectory, quintic_duration
from .workspace import Hemisphere, circle_timing, inverse_kinematics

#: UR "home" posture: upper arm up, forearm forward, tool pointing down.
UR_HOME = np.array([0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, 0.0])
#: Paper Sec. III-C: q1 at the successive rests of the cyclic joint-1 test.
JOINT1_REST_POSITIONS = (np.pi / 2, 2.09, np.pi / 2, 0.52)
#: Nominal seconds per D1 target. Paper Sec. V-A: 80,000 samples / 200
#: targets at 125 Hz = 3.2 s per target; moves longer than the period
#: (long base turns) overflow it, and 3.0 s lands near 80,000 samples.
D1_PERIOD = 3.0
#: Nominal seconds per D2 target. Paper: 22,000 samples = 176 s, 64 s of which
#: are the circle; most D2 moves outlast the period (dwell then 0.3 s), which
#: gives about 23,500 samples.
D2_PERIOD = 1.5


def _robot(robot):
    return resolve_robot(robot)


def _home(robot):
    return UR_HOME.copy() if robot.n_joints == 6 else pin.neutral(robot.model)


def _flange_position(robot, q):
    model = robot.model
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    frame = model.getFrameId(robot.flange_frame)
    pin.updateFramePlacement(model, data, frame)
    return data.oMf[frame].copy()


def _within_limits(robot, q, margin=1e-6):
    return bool(np.all(q >= robot.lower + margin) and np.all(q <= robot.upper - margin))


def _well_conditioned(robot, q, min_singular_value=0.05):
    """Linear flange Jacobian far enough from singular."""
    model = robot.model
    data = model.createData()
    frame = model.getFrameId(robot.flange_frame)
    jac = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED)[:3]
    return bool(np.linalg.svd(jac, compute_uv=False)[-1] >= min_singular_value)


def _wrap(angle):
    return (angle + np.pi) % (2 * np.pi) - np.pi


def _seed_towards(robot, q, position):
    """Rotate the base joint so the flange azimuth points at ``position``."""
    seed = q.copy()
    current = _flange_position(robot, q).translation
    seed[0] += _wrap(np.arctan2(position[1], position[0]) - np.arctan2(current[1], current[0]))
    if seed[0] > robot.upper[0]:
        seed[0] -= 2 * np.pi
    elif seed[0] < robot.lower[0]:
        seed[0] += 2 * np.pi
    return seed


def _reach_target(robot, q, hemisphere, rng, max_tries=50):
    """A random target in the hemisphere and a joint solution reaching it."""
    home = _home(robot)
    for _ in range(max_tries):
        target = hemisphere.sample(1, rng)[0]
        seed = _seed_towards(robot, q, target)
        posture = seed.copy()
        posture[3:] = home[3:] + rng.uniform(-0.8, 0.8, size=home.size - 3)
        q_new, error = inverse_kinematics(robot, target, seed, posture=posture)
        if error < 1e-4 and _within_limits(robot, q_new) and _well_conditioned(robot, q_new):
            return target, q_new
    raise RuntimeError(
        f"no reachable target found in {max_tries} tries for robot {robot.name!r}; "
        f"check the hemisphere {hemisphere}"
    )


def _random_target_pieces(robot, q, n_targets, period, speed, max_acceleration, min_dwell,
                          hemisphere, rng):
    """Point-to-point moves through random targets, each followed by a dwell."""
    velocity = speed * np.asarray(robot.velocity_limits, dtype=float)
    pieces, targets = [], []
    for index in range(n_targets):
        target, q_new = _reach_target(robot, q, hemisphere, rng)
        duration = quintic_duration(q, q_new, velocity, max_acceleration)
        dwell = max(min_dwell, period - duration)
        info = {"target": target.tolist(), "target_index": index}
        pieces.append(JointTrajectory.point_to_point(q, q_new, duration, **info))
        pieces.append(JointTrajectory.rest(q_new, dwell, **info))
        targets.append(target)
        q = q_new
    return pieces, np.array(targets).reshape(-1, 3), q


def _check_positive(name, value, integer=False):
    if integer:
        if int(value) != value or value < 1:
            raise ValueError(f"{name} must be a positive integer, got {value!r}")
        return int(value)
    value = float(value)
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a positive number, got {value!r}")
    return value


def reference_d1(robot="ur10", n_targets=200, *, period=D1_PERIOD, speed=0.8,
                 max_acceleration=3.0, min_dwell=0.3, hemisphere=None, random_state=None):
    """Joint reference of D1: rest-to-rest moves through random flange targets.

    Targets are uniform in ``hemisphere``; each is reached by closed-loop IK
    (:func:`inverse_kinematics`, position only, seeded from the previous
    configuration with the base turned towards the target and a random
    wrist posture in the null space), accepted only within joint limits and
    away from singularities, and approached by a quintic move as fast as
    ``speed`` and ``max_acceleration`` allow, then held for
    ``max(min_dwell, period - move time)``: ``n_targets * period`` seconds
    plus the overflow of long moves, about 80,000 samples at 125 Hz for the
    defaults (paper: 80,000).

    Parameters
    ----------
    robot : str or Robot, default="ur10"
    n_targets : int, default=200
        Paper: 200.
    period : float, default=3.0
        Seconds per target (move + dwell).
    speed : float, default=0.5
        Peak joint speed as a fraction of the velocity limits.
    max_acceleration : float, default=2.0
        Peak joint acceleration [rad/s^2].
    min_dwell : float, default=0.3
        Shortest rest at a target [s].
    hemisphere : Hemisphere, default=None
        None means :meth:`Hemisphere.for_robot`.
    random_state : int, RandomState instance or None, default=None

    Returns
    -------
    reference : JointTrajectory
        Its ``phases`` carry ``"target"`` (flange position) for every move
        and rest.

    Examples
    --------
    >>> from sklearn_gpcd.datasets import reference_d1
    >>> ref = reference_d1("ur10", n_targets=3, random_state=0)
    >>> ref.duration >= 1.0 + 3 * 3.0  # initial second + n_targets * period
    True
    """
    robot = _robot(robot)
    n_targets = _check_positive("n_targets", n_targets, integer=True)
    period = _check_positive("period", period)
    rng = check_random_state(random_state)
    hemisphere = Hemisphere.for_robot(robot) if hemisphere is None else hemisphere
    q = _home(robot)
    pieces, _, _ = _random_target_pieces(
        robot, q, n_targets, period, speed, max_acceleration, min_dwell, hemisphere, rng
    )
    return JointTrajectory.concatenate([JointTrajectory.rest(q, 1.0, target=None), *pieces])


def _circle_piece(robot, q, rng, radius, tool_speed, n_turns, hemisphere, max_tries=10):
    """A horizontal circle of the flange, tool pointing down, inside the hemisphere."""
    home = _home(robot)
    home_pose = _flange_position(robot, home)

    def distances(height):
        """Range of the centre's distance from the base axis keeping the circle inside."""
        inner = np.sqrt(max(hemisphere.inner_radius**2 - height**2, 0.0))
        low = max(hemisphere.axis_clearance, inner) + radius
        high = np.sqrt(max(hemisphere.radius**2 - height**2, 0.0)) - radius
        return low, high

    low, high = distances(0.05 * hemisphere.radius)
    if low > high:
        raise ValueError(
            f"a circle of radius {radius} m does not fit in the hemisphere of robot "
            f"{robot.name!r} ({hemisphere}); use a smaller radius"
        )
    t, s = circle_timing(radius, tool_speed, n_turns)
    for _ in range(max_tries):
        azimuth = rng.uniform(-np.pi, np.pi)
        height = rng.uniform(0.05, 0.3) * hemisphere.radius
        low, high = distances(height)
        if low > high:
            height = 0.05 * hemisphere.radius
            low, high = distances(height)
        distance = rng.uniform(low, high)
        center = hemisphere.center + np.array(
            [distance * np.cos(azimuth), distance * np.sin(azimuth), height]
        )
        turn = _wrap(azimuth - np.arctan2(home_pose.translation[1], home_pose.translation[0]))
        rotation = pin.utils.rotate("z", turn) @ home_pose.rotation
        seed = home.copy()
        seed[0] += turn
        angle0 = azimuth + np.pi  # start on the side nearest the base
        path = center + radius * np.stack(
            [np.cos(angle0 + s / radius), np.sin(angle0 + s / radius), np.zeros_like(s)], axis=1
        )
        joints, ok = np.empty((s.size, robot.n_joints)), True
        q_k, error = inverse_kinematics(robot, path[0], seed, rotation=rotation, max_iter=300)
        for k in range(s.size):
            if k:
                q_k, error = inverse_kinematics(robot, path[k], q_k, rotation=rotation,
                                                max_iter=50)
            if error > 1e-4 or not _within_limits(robot, q_k) or (
                k and np.max(np.abs(q_k - joints[k - 1])) > 0.05
            ):
                ok = False
                break
            joints[k] = q_k
        if ok and hemisphere.contains(path).all():
            info = {"center": center.tolist(), "radius": radius, "tool_speed": tool_speed}
            return JointTrajectory.from_samples(t, joints, kind="circle", **info)
    raise RuntimeError(f"no feasible circle found in {max_tries} tries for robot {robot.name!r}")


def reference_d2(robot="ur10", n_targets=50, *, period=D2_PERIOD, radius=0.3, tool_speed=0.03,
                 n_turns=1.0, speed=0.8, max_acceleration=3.0, min_dwell=0.3, hemisphere=None,
                 random_state=None):
    """Joint reference of D2: random targets, then a horizontal circle.

    As :func:`reference_d1` for the targets, then a quintic move to the start
    of a circle of ``radius`` (tool pointing down, random centre inside the
    hemisphere) tracked at ``tool_speed`` with 1 s smooth start and stop
    (:func:`~sklearn_gpcd.datasets.workspace.circle_timing`; joint path by
    6-D IK every 20 ms and a cubic spline). Paper: 50 targets, r = 30 cm,
    30 mm/s, 22,000 samples in all.

    Parameters
    ----------
    robot : str or Robot, default="ur10"
    n_targets : int, default=50
    period : float, default=1.5
        Seconds per target.
    radius : float, default=0.3
        Circle radius [m].
    tool_speed : float, default=0.03
        [m/s].
    n_turns : float, default=1.0
        Circle turns (size knob).
    speed, max_acceleration, min_dwell, hemisphere, random_state
        As in :func:`reference_d1`.

    Returns
    -------
    reference : JointTrajectory
        The circle is the phase of kind ``"circle"``.

    Examples
    --------
    >>> from sklearn_gpcd.datasets import reference_d2
    >>> ref = reference_d2("ur10", n_targets=2, n_turns=0.1, random_state=0)
    >>> [p["kind"] for p in ref.phases][-2:]
    ['rest', 'circle']
    """
    robot = _robot(robot)
    n_targets = _check_positive("n_targets", n_targets, integer=True)
    period = _check_positive("period", period)
    rng = check_random_state(random_state)
    hemisphere = Hemisphere.for_robot(robot) if hemisphere is None else hemisphere
    q = _home(robot)
    pieces, _, q_end = _random_target_pieces(
        robot, q, n_targets, period, speed, max_acceleration, min_dwell, hemisphere, rng
    )
    circle = _circle_piece(robot, q_end, rng, _check_positive("radius", radius),
                           _check_positive("tool_speed", tool_speed),
                           _check_positive("n_turns", n_turns), hemisphere)
    velocity = speed * np.asarray(robot.velocity_limits, dtype=float)
    q_circle = circle.at(0.0)
    approach = JointTrajectory.point_to_point(
        q_end, q_circle, quintic_duration(q_end, q_circle, velocity, max_acceleration)
    )
    return JointTrajectory.concatenate(
        [JointTrajectory.rest(q, 1.0, target=None), *pieces, approach,
         JointTrajectory.rest(q_circle, min_dwell), circle]
    )


def reference_joint1_cyclic(robot="ur10", rest_positions=JOINT1_REST_POSITIONS, *, n_cycles=1,
                            rest_duration=6.0, speed=0.25, posture=None):
    """Joint reference of the cyclic joint-1 test (paper Sec. III-C, Fig. 2).

    The arm rests stretched parallel to the ground (``posture``, UR: all
    other joints at 0); in the moving phases only joint 1 turns (quintic
    moves), so that q1 at the successive rests is ``rest_positions``. The
    test starts at rest at the last of them, so with the defaults q1 visits
    pi/2 first from below and then from above.

    Parameters
    ----------
    robot : str or Robot, default="ur10"
    rest_positions : sequence of float, default=(pi/2, 2.09, pi/2, 0.52)
        q1 at the rests [rad].
    n_cycles : int, default=1
        Repetitions of the sequence.
    rest_duration : float, default=6.0
        Length of each rest [s].
    speed : float, default=0.25
        Peak joint-1 speed as a fraction of its velocity limit.
    posture : array-like of shape (n_joints,), default=None
        Other joints' positions (joint 1 ignored); None means all zeros.

    Returns
    -------
    reference : JointTrajectory
        Rest phases carry ``"q1"`` and ``"visit"`` (0, 1, ...).

    Examples
    --------
    >>> from sklearn_gpcd.datasets import reference_joint1_cyclic
    >>> ref = reference_joint1_cyclic(rest_duration=2.0)
    >>> [round(p["q1"], 2) for p in ref.phases if p["kind"] == "rest"]
    [0.52, 1.57, 2.09, 1.57, 0.52]
    """
    robot = _robot(robot)
    n_cycles = _check_positive("n_cycles", n_cycles, integer=True)
    rest_duration = _check_positive("rest_duration", rest_duration)
    rest_positions = [float(p) for p in rest_positions]
    if not rest_positions:
        raise ValueError("rest_positions must hold at least one joint-1 position")
    q = np.zeros(robot.n_joints) if posture is None else np.array(posture, dtype=float)
    if q.shape != (robot.n_joints,):
        raise ValueError(f"posture must have {robot.n_joints} values, got {q.shape}")
    q[0] = rest_positions[-1]
    q = q.astype(float)
    velocity = speed * float(robot.velocity_limits[0])
    pieces = [JointTrajectory.rest(q, rest_duration, q1=rest_positions[-1], visit=0)]
    visit = 1
    for _ in range(n_cycles):
        for q1 in rest_positions:
            q_new = q.copy()
            q_new[0] = q1
            duration = quintic_duration(q, q_new, velocity, 2.0)
            pieces.append(JointTrajectory.point_to_point(q, q_new, duration))
            pieces.append(JointTrajectory.rest(q_new, rest_duration, q1=q1, visit=visit))
            visit += 1
            q = q_new
    return JointTrajectory.concatenate(pieces)


def reference_interaction_test(robot="ur10", *, radius=0.3, tool_speed=0.03, n_turns=1.0,
                               rest_duration=30.0, push_torque=60.0, push_lever=0.2,
                               push_duration=1.5, hemisphere=None, random_state=None):
    """Reference and pushes of the human-interaction test (paper Sec. V-B).

    The flange tracks a circle (as in :func:`reference_d2`) and then rests;
    four pushes hit link 1 -- two while moving (at 1/3 and 2/3 of the
    circle), two at rest (at 1/3 and 2/3 of the rest) -- alternating in
    direction. Each push is a horizontal force ``push_torque / push_lever``
    on link 1 at ``push_lever`` from the base axis, perpendicular to the
    lever, with a ``sin^2`` profile, so joint 1 feels up to
    ``push_torque``. It must exceed twice the static friction of joint 1 to
    move it from rest whatever the holding torque (default friction of a
    UR10: 20 Nm).

    Parameters
    ----------
    robot : str or Robot, default="ur10"
    radius, tool_speed, n_turns : float
        Circle (see :func:`reference_d2`); ``n_turns`` is the size knob.
    rest_duration : float, default=30.0
        Rest after the circle [s].
    push_torque : float, default=60.0
        Peak joint-1 torque of each push [Nm].
    push_lever : float, default=0.2
        Distance of the contact point from the base axis [m].
    push_duration : float, default=1.5
        Length of each push [s] (capped to a sixth of the circle or rest).
    hemisphere, random_state
        As in :func:`reference_d1`.

    Returns
    -------
    reference : JointTrajectory
    contacts : list of Contact

    Examples
    --------
    >>> from sklearn_gpcd.datasets import reference_interaction_test
    >>> ref, pushes = reference_interaction_test("ur10", n_turns=0.1, rest_duration=3.0,
    ...                                          random_state=0)
    >>> len(pushes), {push.link for push in pushes}
    (4, {1})
    """
    robot = _robot(robot)
    rng = check_random_state(random_state)
    hemisphere = Hemisphere.for_robot(robot) if hemisphere is None else hemisphere
    circle = _circle_piece(robot, _home(robot), rng, _check_positive("radius", radius),
                           _check_positive("tool_speed", tool_speed),
                           _check_positive("n_turns", n_turns), hemisphere)
    rest_duration = _check_positive("rest_duration", rest_duration)
    lead = 1.0
    q_start, q_end = circle.at(0.0), circle.at(circle.duration)
    reference = JointTrajectory.concatenate(
        [JointTrajectory.rest(q_start, lead), circle,
         JointTrajectory.rest(q_end, rest_duration)]
    )
    force = _check_positive("push_torque", push_torque) / _check_positive("push_lever", push_lever)
    contacts = []
    windows = [(lead, circle.duration), (lead + circle.duration, rest_duration)]
    for start, length in windows:
        duration = min(_check_positive("push_duration", push_duration), length / 6)
        for fraction in (1 / 3, 2 / 3):
            sign = 1.0 if len(contacts) % 2 == 0 else -1.0
            contacts.append(
                Contact(link=1, start=start + fraction * length - duration / 2,
                        duration=duration, force=[0.0, sign * force, 0.0],
                        point=[push_lever, 0.0, 0.0], frame="local")
            )
    return reference, contacts


def _simulate(reference, robot, name, random_state, contacts=(), effects=(), **params):
    rng = check_random_state(random_state)
    simulator = RobotSimulator(robot, random_state=rng, **params)
    recording = simulator.run(reference, contacts=contacts, effects=effects, name=name)
    recording.metadata["generator"] = name
    return recording


def simulate_d1(robot="ur10", n_targets=200, *, period=D1_PERIOD, effects=(), random_state=None,
            **simulator_params):
    """Simulate the paper's D1: random flange targets in a hemisphere.

    Paper Sec. V-A: 200 targets, 80,000 samples at 125 Hz, no contacts
    (``labels`` all 0). Reference from :func:`reference_d1`.

    Parameters
    ----------
    robot : str or Robot, default="ur10"
    n_targets : int, default=200
        Size knob (about 400 samples per target with the default ``period``).
    period : float, default=3.0
        Seconds per target.
    effects : sequence, default=()
        Injected effects (:class:`Payload`, ...).
    random_state : int, RandomState instance or None, default=None
        Seeds targets and sensor noise.
    **simulator_params
        Passed to :class:`RobotSimulator` (e.g. ``current_noise_std``).

    Returns
    -------
    recording : Recording

    Examples
    --------
    >>> from sklearn_gpcd.datasets import simulate_d1
    >>> rec = simulate_d1("ur10", n_targets=2, random_state=0)
    >>> rec.n_joints, int(rec.labels.max()), rec.n_samples > 2 * 3.0 * 125
    (6, 0, True)
    """
    rng = check_random_state(random_state)
    reference = reference_d1(robot, n_targets, period=period, random_state=rng)
    return _simulate(reference, robot, "d1", rng, effects=effects, **simulator_params)


def simulate_d2(robot="ur10", n_targets=50, *, period=D2_PERIOD, radius=0.3, n_turns=1.0,
            effects=(), random_state=None, **simulator_params):
    """Simulate the paper's D2: 50 random targets, then a 30 cm circle at 30 mm/s.

    Paper Sec. V-A: about 22,000 samples at 125 Hz. Reference from
    :func:`reference_d2`.

    Parameters
    ----------
    robot : str or Robot, default="ur10"
    n_targets : int, default=50
    period : float, default=1.5
    radius : float, default=0.3
        Circle radius [m] (smaller arms than the UR10 need less).
    n_turns : float, default=1.0
        Circle turns (size knob).
    effects, random_state, **simulator_params
        As in :func:`simulate_d1`.

    Returns
    -------
    recording : Recording

    Examples
    --------
    >>> from sklearn_gpcd.datasets import simulate_d2
    >>> rec = simulate_d2("ur10", n_targets=1, n_turns=0.1, random_state=0)
    >>> rec.n_joints, int(rec.labels.max()), rec.metadata["phases"][-1]["kind"]
    (6, 0, 'circle')
    """
    rng = check_random_state(random_state)
    reference = reference_d2(robot, n_targets, period=period, radius=radius, n_turns=n_turns,
                             random_state=rng)
    return _simulate(reference, robot, "d2", rng, effects=effects, **simulator_params)


def simulate_joint1_cyclic(robot="ur10", *, n_cycles=1, rest_duration=6.0, effects=(),
                       random_state=None, **simulator_params):
    """Simulate the cyclic joint-1 test showing the stick-slip effect (Sec. III-C).

    Reference from :func:`reference_joint1_cyclic`. Because joint 1 sticks
    at each rest with whatever torque its servo integrator had reached, the
    holding current at q1 = pi/2 differs between the visit from below and
    the visit from above (the paper's Fig. 2 observation). The rests are in
    ``metadata["phases"]`` (kind ``"rest"``, keys ``"q1"``, ``"visit"``).

    Parameters
    ----------
    robot : str or Robot, default="ur10"
    n_cycles : int, default=1
    rest_duration : float, default=6.0
    effects, random_state, **simulator_params
        As in :func:`simulate_d1`.

    Returns
    -------
    recording : Recording

    Examples
    --------
    >>> from sklearn_gpcd.datasets import simulate_joint1_cyclic
    >>> rec = simulate_joint1_cyclic(rest_duration=2.0, random_state=0)
    >>> sorted({p["visit"] for p in rec.metadata["phases"] if p["kind"] == "rest"})
    [0, 1, 2, 3, 4]
    """
    reference = reference_joint1_cyclic(robot, n_cycles=n_cycles, rest_duration=rest_duration)
    return _simulate(reference, robot, "joint1_cyclic", random_state, effects=effects,
                     **simulator_params)


def simulate_interaction_test(robot="ur10", *, radius=0.3, n_turns=1.0, rest_duration=30.0,
                          push_torque=60.0, effects=(), random_state=None, **simulator_params):
    """Simulate the human-interaction test: circle, rest, four pushes on link 1.

    Paper Sec. V-B. Reference and contacts from
    :func:`reference_interaction_test`; ``labels`` are 1..4 during the
    pushes, 0 elsewhere.

    Parameters
    ----------
    robot : str or Robot, default="ur10"
    radius : float, default=0.3
        Circle radius [m].
    n_turns : float, default=1.0
        Circle turns (size knob).
    rest_duration : float, default=30.0
    push_torque : float, default=60.0
        Peak joint-1 torque of each push [Nm].
    effects, random_state, **simulator_params
        As in :func:`simulate_d1`.

    Returns
    -------
    recording : Recording

    Examples
    --------
    >>> from sklearn_gpcd.datasets import simulate_interaction_test
    >>> rec = simulate_interaction_test("ur10", n_turns=0.1, rest_duration=3.0, random_state=0)
    >>> sorted(set(rec.labels.tolist()))
    [0, 1, 2, 3, 4]
    """
    rng = check_random_state(random_state)
    reference, contacts = reference_interaction_test(
        robot, radius=radius, n_turns=n_turns, rest_duration=rest_duration,
        push_torque=push_torque, random_state=rng,
    )
    return _simulate(reference, robot, "interaction_test", rng, contacts=contacts,
                     effects=effects, **simulator_params)
