"""Entry points: :func:`load_robot` and :func:`list_robots`."""

import contextlib
import os
import sys
from numbers import Integral
from pathlib import Path

import numpy as np
import pinocchio as pin

from .robot import Robot
from .ur import build_dh_model, list_ur_robots
from .ur_parameters import UR_PARAMETERS

_OVERRIDES = ("torque_constants", "gear_ratios", "rotor_inertias", "flange_frame", "name",
              "joints")


def list_robots():
    """Names accepted by :func:`load_robot` (besides URDF paths).

    Returns
    -------
    names : list of str

    Examples
    --------
    >>> list_robots()
    ['ur3', 'ur5', 'ur10', 'ur3e', 'ur5e', 'ur10e', 'ur16e']
    """
    return list_ur_robots()


def _is_urdf(spec):
    if isinstance(spec, Path):
        return True
    return str(spec).lower().endswith(".urdf") or Path(str(spec)).is_file()


def _default_urdf_flange(model):
    """``tool0`` when the URDF has it (ROS-Industrial convention), else the last frame."""
    if model.existFrame("tool0"):
        return "tool0"
    return model.frames[len(model.frames) - 1].name


def _load_urdf(path):
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"URDF file not found: {path}")
    try:
        model = pin.buildModelFromUrdf(str(path))
    except Exception as exc:  # pinocchio raises RuntimeError/ValueError variants
        raise ValueError(f"could not parse URDF {path}: {exc}") from exc
    return {
        "name": path.stem,
        "model": model,
        "flange_frame": _default_urdf_flange(model),
        "citation": str(path),
    }


def _select_joints(model, joints, source="robot"):
    """The model with only ``joints`` movable; the others locked at zero.

    A URDF often has more joints than a log: a Franka Emika Panda URDF with
    its gripper has 9 (7 arm joints and 2 finger joints) while its logs have
    7. Keeping the arm's joints makes the model match the log.

    Parameters
    ----------
    model : pinocchio.Model
    joints : int or sequence of str
        The first ``joints`` joints in the model's order, or joint names.
    source : str, default="robot"
        Name for the error messages.

    Returns
    -------
    model : pinocchio.Model
        A reduced model (the input when every joint is kept).

    Examples
    --------
    >>> from sklearn_gpcd.robots import load_robot
    >>> _select_joints(load_robot("ur5").model, 3).nv
    3
    """
    names = [model.names[i] for i in range(1, model.njoints)]
    if isinstance(joints, Integral) and not isinstance(joints, bool):
        if not 1 <= joints <= len(names):
            raise ValueError(f"{source}: joints={joints}, but the model has {len(names)} "
                             f"joints ({', '.join(names)})")
        keep = names[:joints]
    else:
        keep = [str(name) for name in joints]
        unknown = [name for name in keep if name not in names]
        if unknown or not keep:
            raise ValueError(f"{source}: no joint named {', '.join(unknown) or '(none given)'}; "
                             f"its joints are {', '.join(names)}")
    lock = [model.getJointId(name) for name in names if name not in keep]
    if not lock:
        return model
    return pin.buildReducedModel(model, lock, pin.neutral(model))


def _load_builtin(name):
    params = UR_PARAMETERS[name]
    model, dh = build_dh_model(params)
    tc = params["torque_constants"]
    return {
        "name": name,
        "model": model,
        "flange_frame": "flange",
        "dh": dh,
        "torque_constants": None if tc is None else np.array(tc, dtype=float),
        "citation": params["citation"],
    }


def load_robot(name_or_urdf, **overrides):
    """Load a built-in robot by name or any robot from a URDF file.

    Built-in robots are the Universal Robots UR3, UR5, UR10 (CB3) and UR3e,
    UR5e, UR10e, UR16e, built without network, meshes or extra packages from
    the manufacturer's DH table, link masses and centres of mass (see
    :mod:`sklearn_gpcd.robots.ur_parameters`). Link inertia tensors are the
    published ones for the UR10e and UR16e and a solid-cylinder approximation
    for the others (:func:`sklearn_gpcd.robots.ur.link_inertia`).

    Parameters
    ----------
    name_or_urdf : str or path-like
        A name from :func:`list_robots` (case-insensitive) or a path to a URDF
        file (meshes are not needed).
    **overrides
        ``torque_constants``, ``gear_ratios``, ``rotor_inertias`` (one value
        per joint), ``flange_frame`` (frame name), ``name``, or ``joints``:
        the joints to keep, a count (the first ones) or joint names, the
        others locked at zero (e.g. ``joints=7`` for
        a Panda URDF with gripper fingers against 7-joint logs).

    Returns
    -------
    robot : Robot

    Raises
    ------
    ValueError
        Unknown name (the message lists the known ones), missing or invalid
        URDF file, or malformed override values.
    TypeError
        Unknown override keyword.

    Examples
    --------
    >>> robot = load_robot("UR10e", torque_constants=[13.5] * 6)
    >>> robot.name, robot.torque_constants.tolist()[:2]
    ('ur10e', [13.5, 13.5])
    >>> load_robot("ur5", joints=3).n_joints
    3
    """
    unknown = sorted(set(overrides) - set(_OVERRIDES))
    if unknown:
        raise TypeError(f"load_robot got unknown keyword(s) {unknown}; allowed: {list(_OVERRIDES)}")
    if isinstance(name_or_urdf, Robot):
        raise TypeError("load_robot expects a name or a URDF path, got a Robot instance")
    key = str(name_or_urdf).strip().lower()
    if key in UR_PARAMETERS:
        spec = _load_builtin(key)
    elif _is_urdf(name_or_urdf):
        with _quiet_c_stderr():  # urdfdom prints its parse errors on fd 2 itself
            spec = _load_urdf(name_or_urdf)
    else:
        raise ValueError(
            f"unknown robot {str(name_or_urdf)!r}: known robots are {list_robots()}, "
            "or pass the path of a .urdf file"
        )
    joints = overrides.pop("joints", None)
    if joints is not None:
        spec["model"] = _select_joints(spec["model"], joints, spec["name"])
        spec.pop("dh", None)  # the DH table describes the full arm
        if spec.get("torque_constants") is not None:
            spec["torque_constants"] = spec["torque_constants"][:spec["model"].nv] if (
                isinstance(joints, Integral)) else None
    spec.update({k: v for k, v in overrides.items()})
    return Robot(**spec)


def resolve_robot(robot):
    """Return ``robot`` itself if it is a :class:`Robot`, else ``load_robot(robot)``.

    Parameters
    ----------
    robot : str, Path or Robot
        A built-in robot name, a URDF path or an already loaded robot.

    Returns
    -------
    robot : Robot
        ``robot`` unchanged when it is a :class:`Robot`.

    Raises
    ------
    TypeError
        For any other type.

    Examples
    --------
    >>> resolve_robot("ur5").name
    'ur5'
    >>> robot = load_robot("ur10")
    >>> resolve_robot(robot) is robot
    True
    """
    if isinstance(robot, Robot):
        return robot
    if isinstance(robot, (str, Path)):
        return load_robot(robot)
    raise TypeError(f"robot must be a name, a URDF path or a Robot, got {type(robot).__name__}")


@contextlib.contextmanager
def _quiet_c_stderr():
    """Send what C/C++ libraries write on file descriptor 2 to /dev/null.

    Python's own ``sys.stderr`` is flushed first and restored after, so
    only third-party noise (urdfdom's parser messages) is dropped: a URDF
    that does not load is a ValueError that says why.
    """
    try:
        fd = sys.__stderr__.fileno() if sys.__stderr__ is not None else 2
        saved = os.dup(fd)
    except (OSError, ValueError, AttributeError):
        yield  # no real stderr (embedded interpreter): nothing to silence
        return
    with contextlib.suppress(Exception):
        sys.stderr.flush()
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, fd)
        yield
    finally:
        os.dup2(saved, fd)
        os.close(saved)
        os.close(devnull)
