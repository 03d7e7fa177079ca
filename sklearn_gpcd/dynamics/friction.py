"""The Stribeck friction law of a sliding joint, written once for the whole package.

The simulator's joints (:class:`~sklearn_gpcd.datasets.JointFriction`), the
diagnosis effects that name a missing low-speed peak or softening
(:mod:`sklearn_gpcd.diagnosis.effects`) and the second-engine benchmark all
evaluate these two functions.
"""

import numpy as np


def stribeck_peak(qd, stribeck_velocity):
    """Shape of the low-speed friction peak, :math:`\\mathrm{sign}(\\dot q) e^{-(\\dot q/v_s)^2}`.

    It is 1 in magnitude just off zero speed and fades within a few ``v_s``:
    the friction above (peak) or below (softening) the Coulomb level per Nm of
    amplitude.

    Parameters
    ----------
    qd : array-like
        Joint velocities [rad/s].
    stribeck_velocity : float or array-like
        Stribeck velocity ``v_s`` [rad/s], broadcast against ``qd``.

    Returns
    -------
    shape : ndarray
        Dimensionless, same shape as ``qd`` (zero where ``qd == 0``).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.dynamics import stribeck_peak
    >>> stribeck_peak(np.array([-1e-9, 0.0, 0.02]), 0.02).round(3).tolist()
    [-1.0, 0.0, 0.368]
    """
    qd = np.asarray(qd, dtype=float)
    return np.sign(qd) * np.exp(-((qd / stribeck_velocity) ** 2))


def stribeck_friction(qd, coulomb, static, viscous, stribeck_velocity):
    """Sliding friction torque of the Stribeck law (zero where ``qd == 0``).

    .. math::

        \\tau_f(\\dot q) = \\left[F_c + (F_s - F_c) e^{-(\\dot q / v_s)^2}\\right]
            \\mathrm{sign}(\\dot q) + F_v \\dot q

    It falls from the breakaway level ``F_s`` to the Coulomb level ``F_c``
    within a few ``v_s``. What holds a joint that sticks (``qd == 0``) is not
    a function of the velocity and is not part of this law.

    Parameters
    ----------
    qd : array-like of shape (..., n_joints)
        Joint velocities [rad/s].
    coulomb : array-like of shape (n_joints,)
        Coulomb (kinetic) friction ``F_c`` [Nm].
    static : array-like of shape (n_joints,)
        Static (breakaway) friction ``F_s`` [Nm].
    viscous : array-like of shape (n_joints,)
        Viscous coefficient ``F_v`` [Nm s/rad].
    stribeck_velocity : array-like of shape (n_joints,)
        Stribeck velocity ``v_s`` [rad/s].

    Returns
    -------
    tau_f : ndarray of shape (..., n_joints)
        Friction torque [Nm], opposing the motion.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.dynamics import stribeck_friction
    >>> stribeck_friction(np.array([1.0, 1e-6, 0.0]), 10.0, 13.0, 2.0, 0.02).round(3).tolist()
    [12.0, 13.0, 0.0]
    """
    qd = np.asarray(qd, dtype=float)
    peak = np.subtract(static, coulomb)
    return (np.multiply(coulomb, np.sign(qd)) + peak * stribeck_peak(qd, stribeck_velocity)
            + np.multiply(viscous, qd))
