"""Build pinocchio models of Universal Robots arms from their DH tables.

Joint ``i`` of a standard-DH arm rotates about :math:`z_{i-1}`, so in
pinocchio (where a revolute joint rotates about the z axis of its own frame)

* joint ``i`` is an ``RZ`` joint placed, relative to joint ``i-1`` *after*
  its rotation, at :math:`S_{i-1} = T_z(d_{i-1}) T_x(a_{i-1}) R_x(\\alpha_{i-1})`
  (identity for the first joint), and
* the DH frame of link ``i`` sits at :math:`S_i` in joint ``i``'s frame.

Link inertias are given in the DH link frame and moved to the joint frame by
:math:`S_i`; the flange frame ``"flange"`` is :math:`S_n` on the last joint,
so the model reproduces :math:`\\prod_i R_z(q_i) S_i` exactly.
"""

import numpy as np
import pinocchio as pin

from .inertia import cylinder_inertia, symmetric_tensor
from .ur_parameters import UR_PARAMETERS

#: Radius [m] of the cylinders approximating unpublished link inertias
#: (ur_description uses 0.075 m for UR links).
CYLINDER_RADIUS = 0.075

_LINK_NAMES = ("shoulder_link", "upper_arm_link", "forearm_link",
               "wrist_1_link", "wrist_2_link", "wrist_3_link")


def dh_placement(d, a, alpha):
    """Fixed part of one standard DH row, :math:`T_z(d) T_x(a) R_x(\\alpha)`.

    Parameters
    ----------
    d, a, alpha : float
        DH offset [m], length [m] and twist [rad].

    Returns
    -------
    placement : pinocchio.SE3

    Examples
    --------
    >>> dh_placement(0.1, 0.5, 0.0).translation.tolist()
    [0.5, 0.0, 0.1]
    """
    c, s = np.cos(alpha), np.sin(alpha)
    rotation = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    return pin.SE3(rotation, np.array([a, 0.0, d], dtype=float))


def link_inertia(mass, com, d, a, alpha, tensor=None, radius=CYLINDER_RADIUS):
    """Spatial inertia of one UR link in its DH frame.

    When ``tensor`` (about the COM, DH-frame axes) is not published, the link
    is approximated by a solid cylinder of radius ``radius`` centred at the
    published COM: along :math:`x_i` with length :math:`|a_i|` for the upper
    arm and forearm (``a != 0``), otherwise along the link's own joint axis
    (:math:`z_{i-1} = (0, \\sin\\alpha_i, \\cos\\alpha_i)` in frame ``i``) with
    length :math:`d_i`.

    Parameters
    ----------
    mass : float
    com : array-like of shape (3,)
        Centre of mass in the DH frame of the link [m].
    d, a, alpha : float
        DH row of the link.
    tensor : array-like of shape (6,), default=None
        ``(Ixx, Ixy, Ixz, Iyy, Iyz, Izz)`` about the COM.
    radius : float, default=CYLINDER_RADIUS

    Returns
    -------
    inertia : pinocchio.Inertia

    Examples
    --------
    >>> I = link_inertia(2.0, [0.1, 0.0, 0.0], 0.0, -0.4, 0.0)
    >>> round(I.mass, 3), I.lever.tolist()
    (2.0, [0.1, 0.0, 0.0])
    """
    if tensor is not None:
        rotational = symmetric_tensor(*tensor)
    elif a != 0.0:
        rotational = cylinder_inertia(mass, radius, abs(a), [1.0, 0.0, 0.0])
    else:
        axis = [0.0, np.sin(alpha), np.cos(alpha)]
        rotational = cylinder_inertia(mass, radius, abs(d), axis)
    return pin.Inertia(float(mass), np.asarray(com, dtype=float), rotational)


def build_dh_model(params):
    """Pinocchio model of a standard-DH arm from a parameter dict.

    Parameters
    ----------
    params : dict
        One entry of :data:`~sklearn_gpcd.robots.ur_parameters.UR_PARAMETERS`
        (keys ``name, joint_names, d, a, alpha, mass, com, inertia,
        position_limits, velocity_limits, effort_limits``).

    Returns
    -------
    model : pinocchio.Model
        Revolute-Z joints, link bodies and frames, plus an operational frame
        ``"flange"`` at the DH frame of the last link.
    dh : ndarray of shape (n_joints, 3)
        The ``(d, a, alpha)`` table.

    Examples
    --------
    >>> from sklearn_gpcd.robots.ur_parameters import UR_PARAMETERS
    >>> model, dh = build_dh_model(UR_PARAMETERS["ur5"])
    >>> model.nv, dh.shape
    (6, (6, 3))
    """
    dh = np.column_stack([params["d"], params["a"], params["alpha"]]).astype(float)
    tensors = params.get("inertia") or [None] * len(dh)
    lo, hi = params["position_limits"]
    model = pin.Model()
    model.name = params["name"]
    parent, frame, placement = 0, 0, pin.SE3.Identity()
    for i, (d, a, alpha) in enumerate(dh):
        joint = model.addJoint(
            parent, pin.JointModelRZ(), placement, params["joint_names"][i],
            np.array([params["effort_limits"][i]]),
            np.array([params["velocity_limits"][i]]),
            np.array([lo]), np.array([hi]),
        )
        frame = model.addJointFrame(joint, frame)
        link_frame = dh_placement(d, a, alpha)
        body = link_inertia(params["mass"][i], params["com"][i], d, a, alpha, tensors[i])
        model.appendBodyToJoint(joint, link_frame.act(body), pin.SE3.Identity())
        frame = model.addBodyFrame(_LINK_NAMES[i], joint, link_frame, frame)
        parent, placement = joint, link_frame
    model.addFrame(pin.Frame("flange", parent, frame, placement, pin.FrameType.OP_FRAME))
    return model, dh


def list_ur_robots():
    """Names of the built-in Universal Robots models.

    Examples
    --------
    >>> list_ur_robots()[:3]
    ['ur3', 'ur5', 'ur10']
    """
    return list(UR_PARAMETERS)
