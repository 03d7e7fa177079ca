"""The simulated plant: drive-train defaults and the mutable true-robot state."""

import numpy as np
import pinocchio as pin

#: Reflected rotor inertia ``K_r^2 J_m`` [kg m^2] per Nm of effort limit, used
#: when the robot has no ``rotor_inertias``: 1.5 kg m^2 on a UR10 base joint
#: (a ~1.5e-4 kg m^2 rotor behind a 101:1 gear), 0.25 kg m^2 on its wrists.
#: A plausible value, not an identified one.
DEFAULT_ROTOR_INERTIA_PER_NM = 0.0045
#: Peak motor current [A] used to derive ``torque_constants = effort / 20 A``
#: when the robot has none (UR10: 27.5 A on the base joint).
DEFAULT_PEAK_CURRENT = 20.0


def drive_parameters(robot):
    """Torque constants and reflected rotor inertias, with documented defaults.

    Parameters
    ----------
    robot : Robot
        Uses ``torque_constants`` and ``rotor_inertias`` when they are not
        None, else ``effort_limits / DEFAULT_PEAK_CURRENT`` and
        ``DEFAULT_ROTOR_INERTIA_PER_NM * effort_limits``.

    Returns
    -------
    torque_constants : ndarray of shape (n_joints,)
        ``K_eq`` [Nm/A] (paper Eq. 4).
    rotor_inertias : ndarray of shape (n_joints,)
        ``K_r^2 J_m`` [kg m^2] (paper Eq. 4).

    Examples
    --------
    >>> from sklearn_gpcd.robots import load_robot
    >>> from sklearn_gpcd.datasets.plant import drive_parameters
    >>> k, rotor = drive_parameters(load_robot("ur10"))
    >>> float(k[0]), float(rotor[0].round(3))
    (11.976, 1.485)
    """
    effort = np.asarray(robot.effort_limits, dtype=float)
    k = getattr(robot, "torque_constants", None)
    k = effort / DEFAULT_PEAK_CURRENT if k is None else np.asarray(k, dtype=float)
    rotor = getattr(robot, "rotor_inertias", None)
    rotor = DEFAULT_ROTOR_INERTIA_PER_NM * effort if rotor is None else np.asarray(rotor, float)
    return k.copy(), rotor.copy()


def plant_model(robot):
    """A private copy of the robot's pinocchio model with rotor inertias as armature.

    With ``model.armature = K_r^2 J_m``, pinocchio's CRBA, ABA and RNEA work
    with ``M_eq = M + K_r^2 J_m`` (paper Eq. 4).

    Parameters
    ----------
    robot : Robot

    Returns
    -------
    model : pinocchio.Model
    """
    model = pin.Model(robot.model)
    model.armature = drive_parameters(robot)[1]
    return model


class Plant:
    """Mutable parameters of the simulated (true) robot; effects change them.

    See :mod:`sklearn_gpcd.datasets.effects` for how effects use it.

    Parameters
    ----------
    robot : Robot
        The robot simulated.
    model : pinocchio.Model
        The plant's own model copy (payloads are added to it).
    friction : JointFriction
        True friction.
    servo_period : float
        Servo tick [s].
    q : ndarray of shape (n_joints,)
        Joint positions now (updated when effects start).

    Attributes
    ----------
    torque_constants : ndarray of shape (n_joints,)
        True ``K_eq`` [Nm/A].
    current_offset : ndarray of shape (n_joints,)
        Bias on the measured current [A].
    current_delay : int
        Servo ticks between commanded current and current loop.
    spring_stiffness, spring_rest : ndarray of shape (n_joints,)
        Joint springs.
    flange_joint : int
        Parent joint id of the flange frame.
    flange_placement : pinocchio.SE3
        Flange frame in its parent joint frame (identity on the last joint
        when the robot names no flange frame).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.robots import load_robot
    >>> from sklearn_gpcd.datasets import default_friction
    >>> from sklearn_gpcd.datasets.plant import Plant, plant_model
    >>> robot = load_robot("ur10")
    >>> plant = Plant(robot, plant_model(robot), default_friction(robot), 1e-3, np.zeros(6))
    >>> plant.flange_joint
    6
    """

    def __init__(self, robot, model, friction, servo_period, q):
        self.n_joints = robot.n_joints
        self.model = model
        self.friction = friction
        self.torque_constants = drive_parameters(robot)[0]
        self.current_offset = np.zeros(self.n_joints)
        self.current_delay = 0
        self.spring_stiffness = np.zeros(self.n_joints)
        self.spring_rest = np.zeros(self.n_joints)
        self.servo_period = servo_period
        self.q = q
        frame_name = getattr(robot, "flange_frame", None)
        if frame_name is not None and model.existFrame(frame_name):
            frame = model.frames[model.getFrameId(frame_name)]
            self.flange_joint, self.flange_placement = int(frame.parentJoint), frame.placement
        else:
            self.flange_joint, self.flange_placement = model.njoints - 1, pin.SE3.Identity()
