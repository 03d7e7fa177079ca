"""Published kinematic and dynamic parameters of the Universal Robots arms.

One dict per robot, keyed by lowercase name. Every number here is data copied
from a cited public source; the code that turns it into a model lives in
:mod:`sklearn_gpcd.robots.ur`.

Sources
-------
[UR-DH]
    Universal Robots support article "DH Parameters for calculations of
    kinematics and dynamics" (universal-robots.com/articles/ur/
    application-installation/dh-parameters-for-calculations-of-kinematics-
    and-dynamics/). Standard (distal) DH table ``d, a, alpha`` per joint,
    link masses [kg] and centres of mass [m] expressed in the DH frame of
    the link (frame ``i`` after the ``i``-th DH transform). The same numbers
    are used, with per-field comments showing the conversion, in
    Universal_Robots_ROS2_Description ``config/<robot>/physical_parameters.yaml``.
[UR-ROS2]
    Universal_Robots_ROS2_Description, ``config/<robot>/physical_parameters.yaml``
    (inertia tensors of the UR10e and UR16e, about the centre of mass, in axes
    parallel to the DH link frame, as UR lists them in later revisions of
    [UR-DH]) and ``config/<robot>/joint_limits.yaml`` (velocity and effort
    limits from the UR user manuals and the UR article "Max. joint torques").
[MAMEDOV]
    Mamedov et al., "Practical Aspects of Model-Based Collision Detection",
    Frontiers in Robotics and AI, 2020; drive gains identified on a real
    UR10e in the authors' repository shamilmamedov/dynamic_calibration
    (file ``UR10E_parameters``, ``drvGains``), in Nm/A.

Notes
-----
* ``position_limits`` are the +-360 deg of the user manuals for every joint
  (the ROS description halves the elbow range only for motion planning).
* Inertia tensors are not published for most models; where ``inertia`` is
  ``None`` the model builder uses the solid-cylinder approximation of
  :func:`sklearn_gpcd.robots.inertia.cylinder_inertia` (the approximation
  ur_description uses). Treat those tensors as rough priors.
* ``torque_constants`` map motor current [A] to joint torque [Nm]
  (``K_tau K_r`` of the paper, Eq. 4). UR does not publish them. The UR10e
  values come from the UR10e controller (see ``_UR10E_TORQUE_CONSTANTS``);
  the UR10 and UR16e reuse them (same joint sizes on joints 1-2 and 4-6),
  uncertain by roughly +-20 %. The smaller arms have none (``None``): pass
  ``load_robot(name, torque_constants=[...])`` once identified.
"""

import numpy as np

_DEG = np.pi / 180.0
_FULL_TURN = 2.0 * np.pi
_ALPHA = (np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0)
_JOINT_NAMES = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)

# Nm/A, UR10e. Joints 2, 3 and 4-5: the ratio of the controller's target
# joint torque to its target motor current on the ten still poses of the
# [MAMEDOV] recordings (11.976, 9.839, 10.763; exact to 3 decimals there, so
# this is the firmware's own gain). Joint 1 assumed equal to joint 2 and
# joint 6 to joints 4-5 (same joint sizes). The least-squares slope of the
# model's gravity torque against the *measured* current on the same poses is
# within 3 % (tests/test_robots.py prints it). [MAMEDOV]'s own identification
# gives 10.0, 10.70, 8.46, 9.00, 9.48, 10.12, i.e. about 10-15 % lower.
_UR10E_TORQUE_CONSTANTS = (11.976, 11.976, 9.839, 10.763, 10.763, 10.763)


def _limits(velocity_deg, effort):
    return {
        "position_limits": (-_FULL_TURN, _FULL_TURN),
        "velocity_limits": tuple(v * _DEG for v in velocity_deg),
        "effort_limits": tuple(float(e) for e in effort),
    }


def _robot(name, d, a, mass, com, velocity_deg, effort, inertia=None,
           torque_constants=None, citation="[UR-DH], [UR-ROS2]"):
    return {
        "name": name,
        "joint_names": _JOINT_NAMES,
        "d": tuple(d),
        "a": tuple(a),
        "alpha": _ALPHA,
        "mass": tuple(mass),
        "com": tuple(tuple(c) for c in com),
        # symmetric tensor about the COM in DH-frame axes:
        # (Ixx, Ixy, Ixz, Iyy, Iyz, Izz) per link, or None (cylinder approx.)
        "inertia": None if inertia is None else tuple(tuple(i) for i in inertia),
        "torque_constants": torque_constants,
        "citation": citation,
        **_limits(velocity_deg, effort),
    }


_COM_UR3 = ((0, -0.02, 0), (0.13, 0, 0.1157), (0.05, 0, 0.0238),
            (0, 0, 0.01), (0, 0, 0.01), (0, 0, -0.02))
_COM_UR5 = ((0, -0.02561, 0.00193), (0.2125, 0, 0.11336), (0.15, 0, 0.0265),
            (0, -0.0018, 0.01634), (0, 0.0018, 0.01634), (0, 0, -0.001159))
_COM_UR10 = ((0.021, 0, 0.027), (0.38, 0, 0.158), (0.24, 0, 0.068),
             (0, 0.007, 0.018), (0, 0.007, 0.018), (0, 0, -0.026))

#: Parameters of every built-in robot, keyed by lowercase name.
UR_PARAMETERS = {
    # ---------------- CB3 series ----------------
    "ur3": _robot(
        "ur3",
        d=(0.1519, 0, 0, 0.11235, 0.08535, 0.0819),
        a=(0, -0.24365, -0.21325, 0, 0, 0),
        mass=(2.0, 3.42, 1.26, 0.8, 0.8, 0.35),
        com=_COM_UR3,
        velocity_deg=(180, 180, 180, 360, 360, 360),
        effort=(56, 56, 28, 12, 12, 12),
    ),
    "ur5": _robot(
        "ur5",
        d=(0.089159, 0, 0, 0.10915, 0.09465, 0.0823),
        a=(0, -0.425, -0.39225, 0, 0, 0),
        mass=(3.7, 8.393, 2.33, 1.219, 1.219, 0.1879),
        com=_COM_UR5,
        velocity_deg=(180, 180, 180, 180, 180, 180),
        effort=(150, 150, 150, 28, 28, 28),
    ),
    "ur10": _robot(
        "ur10",
        d=(0.1273, 0, 0, 0.163941, 0.1157, 0.0922),
        a=(0, -0.612, -0.5723, 0, 0, 0),
        mass=(7.1, 12.7, 4.27, 2.0, 2.0, 0.365),
        com=_COM_UR10,
        velocity_deg=(120, 120, 180, 180, 180, 180),
        effort=(330, 330, 150, 56, 56, 56),
        # UR10 and UR10e share joint sizes; reuse the UR10e estimate.
        torque_constants=_UR10E_TORQUE_CONSTANTS,
        citation="[UR-DH], [UR-ROS2], torque constants: UR10e estimate",
    ),
    # ---------------- e-Series ----------------
    "ur3e": _robot(
        "ur3e",
        d=(0.15185, 0, 0, 0.13105, 0.08535, 0.0921),
        a=(0, -0.24355, -0.2132, 0, 0, 0),
        mass=(1.98, 3.4445, 1.437, 0.871, 0.805, 0.261),
        com=_COM_UR3,
        velocity_deg=(180, 180, 180, 360, 360, 360),
        effort=(56, 56, 28, 12, 12, 12),
    ),
    "ur5e": _robot(
        "ur5e",
        d=(0.1625, 0, 0, 0.1333, 0.0997, 0.0996),
        a=(0, -0.425, -0.3922, 0, 0, 0),
        mass=(3.761, 8.058, 2.846, 1.37, 1.3, 0.365),
        com=_COM_UR5,
        velocity_deg=(180, 180, 180, 180, 180, 180),
        effort=(150, 150, 150, 28, 28, 28),
    ),
    "ur10e": _robot(
        "ur10e",
        d=(0.1807, 0, 0, 0.17415, 0.11985, 0.11655),
        a=(0, -0.6127, -0.57155, 0, 0, 0),
        mass=(7.369, 13.051, 3.989, 2.1, 1.98, 0.615),
        com=_COM_UR10,
        velocity_deg=(120, 120, 180, 180, 180, 180),
        effort=(330, 330, 150, 56, 56, 56),
        inertia=(
            (0.03408, 0.00002, -0.00425, 0.03529, 0.00008, 0.02156),
            (0.02814, 0.00005, -0.01561, 0.77068, 0.00002, 0.76943),
            (0.01014, 0.00008, 0.00916, 0.30928, 0.0, 0.30646),
            (0.00296, -0.00001, 0.0, 0.00222, -0.00024, 0.00258),
            (0.00296, -0.00001, 0.0, 0.00222, -0.00024, 0.00258),
            (0.00040, 0.0, 0.0, 0.00041, 0.0, 0.00034),
        ),
        torque_constants=_UR10E_TORQUE_CONSTANTS,
        citation="[UR-DH], [UR-ROS2], torque constants from the UR10e controller",
    ),
    "ur16e": _robot(
        "ur16e",
        d=(0.1807, 0, 0, 0.17415, 0.11985, 0.11655),
        a=(0, -0.4784, -0.36, 0, 0, 0),
        mass=(7.369, 10.45, 4.321, 2.18, 2.033, 0.907),
        com=((0, -0.016, 0.030), (0.302, 0, 0.160), (0.194, 0, 0.065),
             (0, -0.009, 0.011), (0, 0.018, 0.012), (0, 0, -0.044)),
        velocity_deg=(120, 120, 180, 180, 180, 180),
        effort=(330, 330, 150, 54, 54, 54),
        inertia=(
            (0.03351, 0.00002, -0.00001, 0.03374, 0.00374, 0.02100),
            (0.02796, -0.00010, -0.00720, 0.47558, 0.00003, 0.47635),
            (0.01091, 0.00006, 0.01012, 0.12060, 0.00001, 0.11714),
            (0.00609, -0.00001, 0.0, 0.00245, 0.00083, 0.00579),
            (0.00389, -0.00001, 0.0, 0.00219, -0.00045, 0.00363),
            (0.00117, 0.0, 0.0, 0.00118, 0.0, 0.00084),
        ),
        # same joint sizes as the UR10e on joints 1-2; rough estimate
        torque_constants=_UR10E_TORQUE_CONSTANTS,
        citation="[UR-DH], [UR-ROS2], torque constants: UR10e estimate",
    ),
}
