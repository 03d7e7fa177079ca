"""ROS 1 / ROS 2 bags with ``sensor_msgs/JointState`` messages.

Needs the optional ``rosbags`` package (``pip install
'sklearn-gpcd[rosbag]'``), imported only when a bag is read.
"""

from pathlib import Path

import numpy as np

from ._validation import finalize_recording

#: Files that make a path a ROS 2 bag (their folder is the bag).
ROS2_SUFFIXES = (".db3", ".mcap")


def _import_rosbags():
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError as exc:
        raise ImportError(
            "reading ROS bags needs the optional 'rosbags' package: "
            "pip install 'sklearn-gpcd[rosbag]' (or pip install rosbags)"
        ) from exc
    return AnyReader, Stores, get_typestore


def bag_path(path):
    """The path ``rosbags`` opens: a ``.bag`` file or a ROS 2 bag folder.

    Parameters
    ----------
    path : str or Path
        A ``.bag`` file, a ROS 2 bag folder, or a ``.db3`` / ``.mcap`` file
        inside one.

    Returns
    -------
    path : Path

    Examples
    --------
    >>> bag_path("run1/run1_0.db3").name
    'run1'
    >>> bag_path("log.bag").name
    'log.bag'
    """
    path = Path(path)
    return path.parent if path.suffix in ROS2_SUFFIXES else path


def read_rosbag(
    path,
    topic="/joint_states",
    effort_is="current",
    joint_names=None,
    *,
    n_joints=None,
    name=None,
    max_dropped=0.05,
    max_joint_speed=10.0,
    min_samples=2,
):
    """Read ``sensor_msgs/JointState`` messages of a ROS 1 or ROS 2 bag.

    ``position``, ``velocity`` and ``effort`` become ``q``, ``qd`` and
    ``current``. Time is ``header.stamp`` [s] when set, else the bag's
    receive time. Messages with none of the selected joints come from
    another publisher on the topic (a gripper, say): they are skipped and
    counted in ``metadata["other_messages"]``. Messages lacking some of the
    selected joints, or with empty or short velocity / effort arrays, are
    malformed and dropped; rows are
    then cleaned as in :func:`read_csv`, with message indices (0-based, in
    topic order) in messages and ``metadata["dropped_rows"]``.

    Parameters
    ----------
    path : str or Path
        ROS 1 ``.bag`` file, ROS 2 bag folder, or a ``.db3`` / ``.mcap`` file
        in one.
    topic : str, default="/joint_states"
        Topic with ``sensor_msgs/JointState`` messages.
    effort_is : {"current", "torque"}, default="current"
        What ``effort`` holds: motor currents (``units="A"``) or joint
        torques (``units="Nm"``).
    joint_names : list of str, default=None
        Joints to read, in this order; None takes the names (and order) of
        the first message.
    n_joints : int, default=None
        Joints the robot has; another count is an error.
    name : str, default=None
        Recording name; the bag's name when None.
    max_dropped, max_joint_speed, min_samples
        As for :func:`~sklearn_gpcd.io.read_csv` (messages instead of rows).

    Returns
    -------
    recording : Recording
        ``metadata`` holds ``joint_names``, ``topic`` and ``time_source``.

    Examples
    --------
    Reading a bag needs a bag file (and the ``rosbags`` package), so the
    first lines are not run here:

    >>> from sklearn_gpcd.io import read_rosbag
    >>> rec = read_rosbag("run_03.bag", effort_is="current")  # doctest: +SKIP
    >>> rec.metadata["joint_names"][:2]  # doctest: +SKIP
    ['shoulder_pan_joint', 'shoulder_lift_joint']

    The meaning of ``effort`` is checked before anything is read:

    >>> read_rosbag("run_03.bag", effort_is="voltage")
    Traceback (most recent call last):
    ...
    ValueError: effort_is must be 'current' or 'torque', got 'voltage'
    """
    if effort_is not in ("current", "torque"):
        raise ValueError(f"effort_is must be 'current' or 'torque', got {effort_is!r}")
    AnyReader, Stores, get_typestore = _import_rosbags()
    source = str(path)
    path = bag_path(path)
    if not path.exists():
        raise ValueError(f"{source}: no such bag")
    try:
        reader = AnyReader([path], default_typestore=get_typestore(Stores.LATEST))
        reader.open()
    except Exception as exc:  # rosbags raises its own error types
        raise ValueError(f"{source}: cannot open as a ROS bag ({exc})") from None
    try:
        connections = [c for c in reader.connections if c.topic == topic]
        if not connections:
            topics = sorted({c.topic for c in reader.connections})
            raise ValueError(f"{source}: no topic {topic!r}; the bag has {topics}")
        kinds = {c.msgtype for c in connections}
        if kinds != {"sensor_msgs/msg/JointState"}:
            raise ValueError(
                f"{source}: topic {topic!r} carries {sorted(kinds)}, not sensor_msgs/JointState")
        messages = [(stamp, reader.deserialize(raw, conn.msgtype))
                    for conn, stamp, raw in reader.messages(connections=connections)]
    finally:
        reader.close()
    if not messages:
        raise ValueError(f"{source}: topic {topic!r} has no messages (file is empty)")
    rows = _joint_rows(source, messages, joint_names)
    time, q, qd, effort, row_ids, malformed, names, time_source, other = rows
    labels = {
        "time": ["'header.stamp'" if time_source == "header.stamp" else "'receive time'"],
        "q": [f"'position' of joint {n!r}" for n in names],
        "qd": [f"'velocity' of joint {n!r}" for n in names],
        "current": [f"'effort' of joint {n!r}" for n in names],
    }
    return finalize_recording(
        source, {"time": time, "q": q, "qd": qd, "current": effort}, row_ids,
        column_labels=labels, malformed=malformed, n_rows=len(messages) - len(other),
        kind="message",
        n_joints=n_joints, units="A" if effort_is == "current" else "Nm",
        name=path.name if name is None else name,
        metadata={"format": "rosbag", "topic": topic, "joint_names": list(names),
                  "time_source": time_source, "other_messages": len(other)},
        max_dropped=max_dropped, max_joint_speed=max_joint_speed, min_samples=min_samples)


def _stamp(msg):
    stamp = msg.header.stamp
    return stamp.sec + stamp.nanosec * 1e-9


def _joint_rows(source, messages, joint_names):
    first = messages[0][1]
    names = list(joint_names) if joint_names is not None else list(first.name)
    if not names:
        names = [str(j) for j in range(len(first.position))]
    if not names:
        raise ValueError(f"{source}: message 0 has no joints (empty name and position)")
    use_header = all(_stamp(msg) > 0 for _, msg in messages)
    time_source = "header.stamp" if use_header else "receive time"
    time, q, qd, effort, row_ids, malformed, other = [], [], [], [], [], [], []
    for index, (stamp, msg) in enumerate(messages):
        order = list(msg.name) if len(msg.name) else [str(j) for j in range(len(msg.position))]
        lookup = {n: i for i, n in enumerate(order)}
        absent = [n for n in names if n not in lookup]
        if len(absent) == len(names):
            other.append(index)  # another publisher on the topic (e.g. a gripper)
            continue
        if absent:
            malformed.append((index, f"joint(s) {absent} missing (message has {order})"))
            continue
        pick = [lookup[n] for n in names]
        width = max(pick) + 1
        short = [f for f in ("position", "velocity", "effort") if len(getattr(msg, f)) < width]
        if short:
            malformed.append((index, f"{'/'.join(short)} shorter than the joint list"))
            continue
        time.append(_stamp(msg) if use_header else stamp * 1e-9)
        q.append(np.asarray(msg.position, dtype=float)[pick])
        qd.append(np.asarray(msg.velocity, dtype=float)[pick])
        effort.append(np.asarray(msg.effort, dtype=float)[pick])
        row_ids.append(index)
    if not row_ids:
        reason = malformed[0][1]
        raise ValueError(f"{source}: no usable JointState message; message 0: {reason}")
    k = len(names)
    arrays = [np.asarray(v, dtype=float).reshape(-1, k) for v in (q, qd, effort)]
    return (np.asarray(time), *arrays, np.asarray(row_ids), malformed, names, time_source,
            other)
