"""Rigid-body inertia approximations for links whose tensor is not published."""

import numpy as np


def cylinder_inertia(mass, radius, length, axis):
    """Rotational inertia of a solid cylinder about its centre of mass.

    .. math::

        I = \\tfrac{m}{12}(3r^2 + h^2)\\,(\\mathbb{1} - u u^T)
            + \\tfrac{m r^2}{2}\\, u u^T,

    with ``u`` the unit cylinder axis. This is the approximation
    ur_description uses for UR links (radius 0.075 m).

    Parameters
    ----------
    mass : float
        Link mass [kg].
    radius, length : float
        Cylinder radius and length [m].
    axis : array-like of shape (3,)
        Cylinder axis in the frame the tensor is expressed in.

    Returns
    -------
    inertia : ndarray of shape (3, 3)
        Symmetric positive definite tensor [kg m^2].

    Examples
    --------
    >>> I = cylinder_inertia(2.0, 0.1, 0.0, [0, 0, 1])
    >>> round(float(I[2, 2]), 6), round(float(I[0, 0]), 6)
    (0.01, 0.005)
    """
    u = np.asarray(axis, dtype=float)
    u = u / np.linalg.norm(u)
    uu = np.outer(u, u)
    transverse = mass * (3.0 * radius**2 + length**2) / 12.0
    axial = 0.5 * mass * radius**2
    return transverse * (np.eye(3) - uu) + axial * uu


def symmetric_tensor(ixx, ixy, ixz, iyy, iyz, izz):
    """3x3 symmetric tensor from its six independent entries.

    Examples
    --------
    >>> symmetric_tensor(1, 2, 3, 4, 5, 6).tolist()
    [[1.0, 2.0, 3.0], [2.0, 4.0, 5.0], [3.0, 5.0, 6.0]]
    """
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]], dtype=float)
