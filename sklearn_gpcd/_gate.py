r"""The quasi-static gate of the paper (Eq. 15) and its threshold, written once.

The indicator of joint :math:`\ell`

.. math::
    a_\ell(x) = \begin{cases} 1 & |\dot q_\ell| < \sigma_v \\
                              0 & |\dot q_\ell| \geq \sigma_v \end{cases}

switches the static-friction kernel on (Eq. 16) and the friction columns of
the parametric model off (:math:`\bar\phi`, Eq. 17). Every place of the
package that evaluates it -- the kernel
:class:`~sklearn_gpcd.kernels.QuasiStaticGate` and its compiled node, the
parametric mean, the friction features of ``dynamics``, the public
:func:`~sklearn_gpcd.features.quasi_static_mask`, the streaming monitor and
the experiments -- calls :func:`quasi_static`; every ``sigma_v`` parameter
defaults to :data:`DEFAULT_SIGMA_V` and is validated by :func:`check_sigma_v`
(functions) or :data:`SIGMA_V_CONSTRAINT` (estimators' parameter
constraints): a finite real > 0. Zero is refused: no velocity is below it, so
the gate would never open and no sample would ever be quasi-static; where
"no gate" is meaningful a parameter takes None instead.

The motion regimes built on the gate have one vocabulary,
:data:`REGIME_WORDS`: the labels of :func:`sklearn_gpcd.features.regimes`
(per joint and sample, for where a model errs, used by the diagnosis) and the
regimes of the detector's thresholds
(:class:`sklearn_gpcd.detection.Regimes`, for the whole arm) are words of it,
with the meaning written there.

This module imports nothing of the package, so every layer may use it.
"""

import numbers

import numpy as np

__all__ = ["DEFAULT_SIGMA_V", "REGIME_WORDS", "SIGMA_V_CONSTRAINT", "quasi_static",
           "check_sigma_v", "check_velocity"]

#: The default velocity threshold :math:`\sigma_v` [rad/s] of the whole package
#: (Sec. III-C of the paper: :math:`10^{-2}` rad/s for a UR10 at 125 Hz): the
#: gates and masks of the model, the detector's regimes, the analyses.
DEFAULT_SIGMA_V = 1e-2

#: The one vocabulary of motion regimes: word -> meaning. ``features.regimes``
#: labels each joint with moving / creep / rest / braking / reversal; the
#: detector's regimes label the arm moving / settling / rest (/ braking).
REGIME_WORDS = {
    "moving": "|qd| >= sigma_v: the dynamical side of the gate (for the arm: some joint)",
    "creep": "sigma_rest <= |qd| < sigma_v: quasi-static, yet not still (one joint)",
    "settling": "every joint quasi-static for less than the settle time after a motion",
    "rest": "standing still: |qd| < sigma_rest for a joint; for the arm, every joint "
            "quasi-static for longer than the settle time (or since the start)",
    "braking": "some |qdd| above the braking limit (hard stops and starts), and for the "
               "arm the hold after it",
    "reversal": "a joint changes direction within a short window",
}


def __getattr__(name):
    """``SIGMA_V_CONSTRAINT``, built on first use: the parameter constraint of
    every estimator's ``sigma_v`` (``[None, SIGMA_V_CONSTRAINT]`` where None
    means "no gate"), accepting what :func:`check_sigma_v` accepts.

    Built lazily because it needs scikit-learn, which ``gpcd``'s start-up
    (the workflow reads :data:`DEFAULT_SIGMA_V`) does not import.
    """
    if name != "SIGMA_V_CONSTRAINT":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    # deferred: scikit-learn is heavy and the CLI's start-up imports this module
    from sklearn.utils._param_validation import Interval

    class PositiveVelocity(Interval):
        """``Interval(Real, 0, inf, closed="neither")`` refusing bools, as
        :func:`check_velocity` does."""

        def is_satisfied_by(self, val):
            return not isinstance(val, (bool, np.bool_)) and super().is_satisfied_by(val)

    constraint = PositiveVelocity(numbers.Real, 0, np.inf, closed="neither")
    globals()[name] = constraint
    return constraint


def quasi_static(velocity, sigma_v):
    r"""The gate :math:`a_\ell` of Eq. 15: ``|velocity| < sigma_v``.

    The one place the comparison is written. It takes either an array (a
    boolean array of the same shape is returned) or a Python float (a
    ``bool``, without numpy call overhead, for per-tick callers).

    Parameters
    ----------
    velocity : float or ndarray
        Joint velocities [rad/s].
    sigma_v : float
        Velocity threshold [rad/s] (finite and > 0, see :func:`check_sigma_v`).

    Returns
    -------
    open : bool or ndarray of bool
        True where the joint is quasi-static.

    Examples
    --------
    >>> import numpy as np
    >>> quasi_static(np.array([0.0, -0.005, 0.01, 0.5]), 0.01).tolist()
    [True, True, False, False]
    >>> quasi_static(-0.02, 0.01)
    False
    """
    return abs(velocity) < sigma_v


def check_sigma_v(sigma_v, owner="sigma_v", allow_none=False):
    """Validate a velocity threshold: a finite real number > 0.

    Parameters
    ----------
    sigma_v : object
        The value to check.
    owner : str, default="sigma_v"
        Prefix of the error message, naming the parameter's owner.
    allow_none : bool, default=False
        Accept None (meaning "no gate") as well.

    Returns
    -------
    sigma_v : float or None

    Raises
    ------
    ValueError
        Unless ``sigma_v`` is a finite real > 0 (or None when allowed);
        bools are rejected.

    Examples
    --------
    >>> check_sigma_v(0.01)
    0.01
    >>> check_sigma_v(0.0, "QuasiStaticGate")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: QuasiStaticGate: sigma_v must be a finite velocity threshold > 0, ...
    """
    return check_velocity(sigma_v, "sigma_v", "velocity threshold", owner, allow_none)


def check_velocity(value, name, what, owner, allow_none=False):
    """Validate a velocity parameter (e.g. ``sigma_v``, ``coulomb_width``): a
    finite real number > 0, bools rejected.

    Parameters
    ----------
    value : object
        The value to check.
    name, what : str
        The parameter's name and what it is, for the error message.
    owner : str
        Prefix of the error message, naming the parameter's owner.
    allow_none : bool, default=False
        Accept None as well.

    Returns
    -------
    value : float or None

    Examples
    --------
    >>> check_velocity(0.01, "coulomb_width", "velocity scale", "RigidBodyFeatures")
    0.01
    >>> check_velocity(-1, "coulomb_width", "velocity scale", "RigidBodyFeatures")
    Traceback (most recent call last):
    ...
    ValueError: RigidBodyFeatures: coulomb_width must be a finite velocity scale > 0, got -1
    """
    if value is None and allow_none:
        return None
    valid = (
        isinstance(value, numbers.Real)
        and not isinstance(value, bool)
        and np.isfinite(value)
        and value > 0
    )
    if not valid:
        allowed = " (or None)" if allow_none else ""
        raise ValueError(f"{owner}: {name} must be a finite {what} > 0{allowed}, got {value!r}")
    return float(value)
