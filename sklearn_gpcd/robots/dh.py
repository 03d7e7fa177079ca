"""Standard (distal) Denavit-Hartenberg transforms.

The transform from link frame ``i-1`` to link frame ``i`` is

.. math::

    {}^{i-1}T_i = R_z(\\theta_i)\\, T_z(d_i)\\, T_x(a_i)\\, R_x(\\alpha_i),

so joint ``i`` rotates about :math:`z_{i-1}`. Universal Robots publish
their arms in this convention (UR "a" is Wikipedia's "r").
"""

import numpy as np


def dh_transform(theta, d, a, alpha):
    """Homogeneous transform of one standard DH row.

    Parameters
    ----------
    theta, d, a, alpha : float
        Joint angle [rad], offset along :math:`z_{i-1}` [m], length along
        :math:`x_i` [m] and twist about :math:`x_i` [rad].

    Returns
    -------
    T : ndarray of shape (4, 4)
        :math:`R_z(\\theta) T_z(d) T_x(a) R_x(\\alpha)`.

    Examples
    --------
    >>> import numpy as np
    >>> T = dh_transform(0.0, 0.1, 0.5, np.pi / 2)
    >>> T[:3, 3].tolist()
    [0.5, 0.0, 0.1]
    """
    ct, st = np.cos(theta), np.sin(theta)
    ca, sa = np.cos(alpha), np.sin(alpha)
    return np.array([
        [ct, -st * ca, st * sa, a * ct],
        [st, ct * ca, -ct * sa, a * st],
        [0.0, sa, ca, d],
        [0.0, 0.0, 0.0, 1.0],
    ])


def dh_forward_kinematics(q, dh):
    """Flange pose from a standard DH table, as the product of row transforms.

    Parameters
    ----------
    q : array-like of shape (n_joints,)
        Joint angles [rad].
    dh : array-like of shape (n_joints, 3)
        Rows ``(d, a, alpha)``.

    Returns
    -------
    T : ndarray of shape (4, 4)
        :math:`{}^0T_n = \\prod_i {}^{i-1}T_i(q_i)`.

    Examples
    --------
    >>> dh_forward_kinematics([0.0], [[0.2, 0.3, 0.0]])[:3, 3].tolist()
    [0.3, 0.0, 0.2]
    """
    T = np.eye(4)
    for qi, (d, a, alpha) in zip(np.asarray(q, dtype=float), np.asarray(dh, dtype=float)):
        T = T @ dh_transform(qi, d, a, alpha)
    return T
