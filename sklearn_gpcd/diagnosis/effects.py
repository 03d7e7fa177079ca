"""The library of named physical effects a nominal model may be missing.

Every effect adds a term to the predicted current of some joints that is
linear in a few parameters :math:`\\theta`:

.. math::

    i_\\ell = \\hat i_\\ell + \\sum_{e} D_{e,\\ell}(x)\\, \\theta_e ,

where :math:`\\hat i` is the nominal (reference) current and the columns
:math:`D_{e,\\ell}` are torques divided by the torque constant
:math:`K_\\ell` (so :math:`\\theta_e` is in physical units), the nominal
current itself (torque constant), ones (current offset) or its time
derivative (time delay, first order in the delay; the final fit iterates
the exact shift to a fixed point). The
Stribeck velocity is a nonlinear parameter found by a 1-D search, and the
payload's centre of mass enters its inertia quadratically (fixed point).

=====================  ======================================================
``coulomb_friction``   :math:`\\Delta F_c\\,\\mathrm{sign}(\\dot q_\\ell)`, per joint
``viscous_friction``   :math:`\\Delta F_v\\,\\dot q_\\ell`, per joint
``stribeck_friction``  :math:`\\Delta F_s\\,\\mathrm{sign}(\\dot q_\\ell)
                       e^{-(\\dot q_\\ell/v_s)^2}`, per joint; :math:`v_s` by
                       1-D search; a peak: :math:`\\Delta F_s \\ge 0`
``friction_softening`` the same law with :math:`-\\Delta F_0 \\le 0`: dry
                       friction softening at low speed (regularised or
                       constraint-based friction)
``rotor_inertia``      :math:`\\Delta J\\,\\ddot q_\\ell`, per joint
``payload``            point mass ``m`` with centre of mass ``c`` at the flange:
                       last link's regressor times a fixed map of ``(m, m c)``
``link_mass``          extra mass at a link's nominal centre of mass plus a
                       first-moment change ``(dm, d(m c))``, links 1..n-2
``gravity_tilt``       base tilted by small roll/pitch: gravity torques of unit
                       gravity along base x and y
``torque_constant``    :math:`c\\,\\hat i_\\ell`: true constant is
                       :math:`K_\\ell / (1 + c)`, per joint
``current_offset``     constant current bias, per joint
``time_delay``         logged current lags by ``d``:
                       :math:`-d\\, d\\hat i/dt` (all joints, one ``d``)
``joint_spring``       :math:`-k(q_\\ell - q_0)`, per joint
``friction_drift``     Coulomb and viscous levels changing linearly with time
                       since the start of the recording (warm-up), per joint
=====================  ======================================================

Each effect is a small class with :meth:`Effect.targets` (the joints or links
it may act on), :meth:`Effect.design` (the columns) and
:meth:`Effect.physical` (parameters with uncertainty in physical units).
The classes are named ``<Thing>Effect``; the simulator's injectors
(:mod:`sklearn_gpcd.datasets`) are named after the change they make, and
:data:`sklearn_gpcd.datasets.EFFECT_REGISTRY` pairs the two (a new library
effect needs an entry there, or in ``DIAGNOSIS_ONLY`` with the reason).
"""

import numpy as np
import pinocchio as pin

from ..dynamics.friction import stribeck_peak

#: Standard gravity [m/s^2] used to convert gravity components into tilt angles.
STANDARD_GRAVITY = 9.81
#: Velocity [rad/s] below which a joint counts as resting in predictions.
REST_VELOCITY = 1e-3
#: Default grid of logged-current delays [s] searched by ``time_delay``.
DELAYS = (-0.016, -0.008, 0.004, 0.008, 0.016, 0.032, 0.064)
#: Velocity scales [rad/s] below which a drifting dry friction level is not
#: developed, tried by ``friction_drift`` (0: the plain sign).
SLIDING_VELOCITIES = (0.0, 0.005, 0.01, 0.02)
#: Default grid of Stribeck velocities [rad/s] searched by ``stribeck_friction``.
STRIBECK_VELOCITIES = tuple(np.geomspace(0.004, 0.25, 10).round(5))
#: Shapes of the low-speed softening of dry friction tried by
#: ``friction_softening`` (see :func:`softening_shape`).
SOFTENING_SHAPES = ("gaussian", "exponential", "linear")
#: Largest velocity scale [rad/s] tried for the shapes other than the Gaussian.
SOFTENING_MAX_VELOCITY = 0.03
#: Standard errors a change must reach to count as shown
#: (:meth:`TorqueConstantEffect.smallest_changes`).
IDENTIFIABLE_SE = 3.0
#: Velocity scales [rad/s] of the low-speed friction columns a torque-constant
#: change competes with (softening and peak, next to Coulomb and viscous).
_LOW_SPEED = (0.004, 0.02, 0.08)
#: A composite Stribeck peak + softening pairs a peak at ``v_s`` with a
#: softening at ``v_0 <= v_s / PAIR_SEPARATION`` (apart enough to be told apart).
PAIR_SEPARATION = 3.0
#: Rated payload [kg] of the built-in robots (manufacturer data sheets); the
#: ``payload`` bound is twice this. Other robots use :data:`DEFAULT_RATED_PAYLOAD`.
RATED_PAYLOAD = {"ur3": 3.0, "ur5": 5.0, "ur10": 10.0, "ur3e": 3.0, "ur5e": 5.0,
                 "ur10e": 12.5, "ur16e": 16.0}
#: Rated payload [kg] assumed for robots not in :data:`RATED_PAYLOAD`.
DEFAULT_RATED_PAYLOAD = 20.0
#: Physical bounds of the plausibility check (see :meth:`Effect.implausible`).
BOUNDS = {
    "torque_constant_scale": (0.5, 1.5),
    "delay": 0.2,  # |d| [s]
    "tilt": 0.1,  # |roll|, |pitch| [rad] (5.7 deg)
    "stribeck_velocity": (0.002, 0.5),  # [rad/s]
    "rotor_inertia": 5.0,  # |delta J| [kg m^2]
    "payload_com": 0.5,  # |c| [m]
    "payload_fraction": 0.05,  # smallest payload named, share of the rated payload
    "joint_position": 2 * np.pi + 0.25,  # |q_0| [rad]: a UR joint spans +-2 pi
    "coulomb_rate": 1.0,  # |rate| [Nm/s]
}


def rated_payload(robot):
    """Rated payload [kg] of ``robot`` (:data:`RATED_PAYLOAD`, else the default).

    Examples
    --------
    >>> from sklearn_gpcd.robots import load_robot
    >>> rated_payload(load_robot("ur10e"))
    12.5
    """
    return float(RATED_PAYLOAD.get(str(getattr(robot, "name", "")).lower(),
                                   DEFAULT_RATED_PAYLOAD))


def nominal_friction_levels(nominal, joint):
    """Nominal (Coulomb, viscous) friction of ``joint`` [Nm, Nm s/rad]; zeros without one.

    Read off the nominal friction law at +-1e-6 rad/s and +-1 rad/s.

    Examples
    --------
    >>> from sklearn_gpcd.diagnosis import NominalModel
    >>> nominal = NominalModel("ur10", friction={"coulomb": [2.0] * 6, "viscous": [0.5] * 6})
    >>> [round(v, 6) for v in nominal_friction_levels(nominal, 1)]
    [2.0, 0.5]
    """
    if nominal.friction is None:
        return 0.0, 0.0
    qd = np.zeros((4, nominal.n_joints))
    qd[:, joint] = [1e-6, -1e-6, 1.0, -1.0]
    tau = np.asarray(nominal.friction(qd), dtype=float)[:, joint]
    slow, fast = 0.5 * (tau[0] - tau[1]), 0.5 * (tau[2] - tau[3])  # c + v * speed
    viscous = (fast - slow) / (1.0 - 1e-6)
    return float(slow - 1e-6 * viscous), float(viscous)


def _delta(func, theta, cov, eps=1e-7):
    """Values of ``func(theta)`` and their std by the delta method (numeric Jacobian)."""
    theta = np.asarray(theta, dtype=float)
    value = np.asarray(func(theta), dtype=float)
    jac = np.empty((value.size, theta.size))
    for k in range(theta.size):
        step = eps * max(1.0, abs(theta[k]))
        shifted = theta.copy()
        shifted[k] += step
        jac[:, k] = (np.asarray(func(shifted), dtype=float).ravel() - value.ravel()) / step
    var = np.einsum("ij,jk,ik->i", jac, cov, jac)
    return value.ravel(), np.sqrt(np.maximum(var, 0.0))


def _per_joint_column(signals, joint, values):
    """One-joint design: ``{joint: values / K_joint}`` with ``values`` of shape (n, k)."""
    values = np.asarray(values, dtype=float).reshape(signals.n_samples, -1)
    return {joint: values / signals.torque_constants[joint]}


def sample_period(signals):
    """Median sample period of the recordings [s] (0 without time stamps).

    Examples
    --------
    >>> import numpy as np
    >>> from types import SimpleNamespace
    >>> s = SimpleNamespace(time=np.arange(0, 1, 0.008), segment=np.zeros(125, int),
    ...                     n_samples=125)
    >>> round(sample_period(s), 4)
    0.008
    """
    if signals.time is None or signals.n_samples < 2:
        return 0.0
    steps = [np.diff(signals.time[signals.segment == seg]) for seg in np.unique(signals.segment)]
    steps = np.concatenate([d for d in steps if d.size]) if steps else np.zeros(0)
    return float(np.median(steps)) if steps.size else 0.0


class Effect:
    """Base class of a named effect: a group of torque-feature columns.

    Subclasses set the class attributes and implement :meth:`design` and,
    when the parameters are not reported as fitted, :meth:`physical`.

    Attributes
    ----------
    name : str
        Identifier used in reports and JSON (``"payload"``).
    title : str
        Plain-words description.
    per_joint : bool
        True when the effect acts on one joint at a time.
    parameter_names : tuple of str
        Names of the physical parameters :meth:`physical` reports.
    units : tuple of str
        Their units.
    needs_time : bool
        True when the columns depend on time (not a function of the state).
    rest_guard : bool
        True when rows next to a joint's rest must be left out of its fit.
    trend : bool
        True for a trend in time from the start of each recording (its
        held-out test leaves out the first time block, where it has nothing
        to show).
    target_kind : str
        What a target is called in labels: ``"joint"`` or ``"link"``.
    refit_drop_is_final : bool
        True when an estimate the joint refit finds implausible (a friction
        peak or softening whose sign flipped) stays dropped without a new
        selection: the joint's other friction terms cover it.
    excitation : str or None
        What excites the effect, in words (a separating experiment).
    plan_segment : str or None
        The segment of a plan that shows it (:mod:`~sklearn_gpcd.diagnosis.plan`:
        ``"low_speed"``, ``"gravity_load"``, ``"chirp"``, ``"steady"``; None:
        a generic Fourier segment).

    The methods below the physical ones are the effect's behaviour in the
    diagnosis (plausibility given the other effects on its target, the
    resolution of the recordings, the composites it leads, the variant to
    fall back on, settings read from the linear fit, what recordings could
    not show); their defaults do nothing, so that a new effect is one class.

    Examples
    --------
    A library effect gives one column per joint it acts on:

    >>> import numpy as np
    >>> from sklearn_gpcd.diagnosis import Effect, NominalModel, Signals, effect_library
    >>> nominal = NominalModel("ur10")
    >>> signals = Signals.from_states(nominal, np.ones((3, 18)))
    >>> effect = effect_library("coulomb_friction")[0]
    >>> isinstance(effect, Effect), effect.name, effect.per_joint
    (True, 'coulomb_friction', True)
    >>> columns = effect.design(signals, nominal, target=2)
    >>> list(columns), columns[2].shape
    ([2], (3, 1))

    A new effect subclasses :class:`Effect` and implements :meth:`design`:

    >>> class Backlash(Effect):
    ...     name, parameter_names, units = "backlash", ("gap",), ("rad",)
    ...     def design(self, signals, nominal, target, **settings):
    ...         return {target: np.sign(signals.qd[:, [target]])}
    >>> Backlash().design(signals, nominal, 0)[0].ravel().tolist()
    [1.0, 1.0, 1.0]
    """

    name = ""
    title = ""
    per_joint = True
    parameter_names = ()
    units = ()
    needs_time = False
    rest_guard = False
    trend = False
    target_kind = "joint"
    refit_drop_is_final = False
    excitation = None
    plan_segment = None

    def targets(self, nominal):
        """What the effect may act on: joints for per-joint effects, else ``[None]``.

        Parameters
        ----------
        nominal : NominalModel

        Returns
        -------
        targets : list
        """
        return list(range(nominal.n_joints)) if self.per_joint else [None]

    def settings_grid(self):
        """Values of the nonlinear settings tried in the selection (``[{}]`` if none)."""
        return [{}]

    def design(self, signals, nominal, target, **settings):
        """Columns of the effect.

        Parameters
        ----------
        signals : Signals
        nominal : NominalModel
        target : int or None
            Joint (per-joint effects), link (``link_mass``) or None.
        **settings
            Nonlinear settings (e.g. ``stribeck_velocity``).

        Returns
        -------
        columns : dict
            ``{joint: ndarray of shape (n_samples, n_params)}`` for each joint
            whose current the effect changes.
        """
        raise NotImplementedError

    def prediction(self, signals, nominal, target, theta, settings):
        """The effect's term in the predicted current, shape (n_samples, n_joints).

        ``design(...) @ theta`` by default.
        """
        out = np.zeros((signals.n_samples, signals.n_joints))
        for j, cols in self.design(signals, nominal, target, **settings).items():
            out[:, j] = cols @ theta
        return out

    def physical(self, theta, cov, target, settings, nominal):
        """Physical parameters with standard deviations.

        Parameters
        ----------
        theta : ndarray of shape (n_params,)
            Fitted column coefficients.
        cov : ndarray of shape (n_params, n_params)
            Their covariance.
        target, settings, nominal
            As in :meth:`design`.

        Returns
        -------
        params : dict
            ``{name: (value, std)}`` in :attr:`parameter_names` order.
        """
        std = np.sqrt(np.maximum(np.diag(cov), 0.0))
        return {n: (float(v), float(s)) for n, v, s in zip(self.parameter_names, theta, std)}

    def refine(self, objective, settings):
        """Improve the nonlinear settings given ``objective(settings) -> loss``.

        The default has nothing to refine and returns ``settings``.
        """
        return settings

    def implausible(self, params, target, nominal):
        """Why fitted parameters are physically implausible, or None when they are not.

        Each library effect checks its parameters against physical bounds
        (:data:`BOUNDS`, signs of friction terms, the robot's rated payload
        and link masses); an estimate outside them is rejected rather than
        reported. The base class accepts everything.

        Parameters
        ----------
        params : dict
            ``{name: (value, std)}`` from :meth:`physical`.
        target : int or None
        nominal : NominalModel

        Returns
        -------
        reason : str or None
        """
        return None

    def implausible_among(self, params, target, nominal, context):
        """:meth:`implausible` given what other effects on the same target tell it.

        ``context`` merges the :meth:`context` of the other effects fitted on
        the target (summed per key). The default ignores it.
        """
        return self.implausible(params, target, nominal)

    def context(self, params):
        """What this fitted effect tells other effects on its target (``{}``)."""
        return {}

    def unresolved(self, value, sample_period):
        """Why a first parameter ``value`` is finer than the recordings resolve, or None."""
        return None

    def settings_from_fit(self, settings, theta):
        """Nonlinear settings read off the linear coefficients ``theta``, or None."""
        return None

    def variant_note(self, settings):
        """Words naming the variant in a rejection reason (``""``)."""
        return ""

    def fallback_variant(self, settings, variants):
        """Which of ``variants`` (settings of this effect on the same target) to try when
        the fitted variant ``settings`` is implausible: an index, or None."""
        return None

    def composite_partners(self, candidate, candidates):
        """``[(partner, settings)]``: composites this candidate leads.

        A composite joins two terms of one target that can cancel each other
        when tried one at a time; it shares their columns. The default leads none.
        """
        return []

    def smallest_changes(self, signals, residual, after, mask, min_share, min_gain):
        """Per target, the smallest change the recordings could show, or None (not assessed).

        Returns ``[(target, smallest change, share of the signal other effects
        mimic)]``; see :meth:`TorqueConstantEffect.smallest_changes`.
        """
        return None

    def size_that_matters(self, nominal, target):
        """Smallest size of the first parameter worth finding, or None (not assessed).

        The identifiability check (:mod:`~sklearn_gpcd.diagnosis.identifiability`)
        asks for a recording where the recordings at hand could not show
        this size.
        """
        return None

    def sentence(self, params, joints):
        """One plain-words sentence about the fitted effect (see subclasses)."""
        values = ", ".join(f"{k} = {_pm(*v)}" for k, v in params.items())
        return f"{self.title} ({values})"

    def __repr__(self):
        return f"{type(self).__name__}()"


def _pm(value, std, digits=3):
    """``value +- std`` with a sensible number of digits."""
    return f"{value:.{digits}g} +- {std:.2g}"


def _joint_list(joints):
    """Joints in words, numbered from 1: ``[1]`` -> ``"joint 2"``, ``[0, 1, 2]`` ->
    ``"joints 1-3"``, ``[0, 2]`` -> ``"joints 1, 3"``."""
    js = sorted(int(j) + 1 for j in joints)
    if len(js) == 1:
        return f"joint {js[0]}"
    if len(js) > 2 and js == list(range(js[0], js[-1] + 1)):
        return f"joints {js[0]}-{js[-1]}"
    return "joints " + ", ".join(map(str, js))


class CoulombFrictionEffect(Effect):
    """Missing Coulomb friction :math:`\\Delta F_c\\,\\mathrm{sign}(\\dot q_\\ell)` [Nm].

    Examples
    --------
    >>> CoulombFrictionEffect().parameter_names
    ('delta_coulomb',)
    """

    name = "coulomb_friction"
    excitation = ("constant-speed sweeps in both directions at 3-4 speeds (0.05-1 rad/s),"
                  " 5 s each")
    plan_segment = "low_speed"
    title = "Coulomb (dry) friction"
    parameter_names = ("delta_coulomb",)
    units = ("Nm",)

    def design(self, signals, nominal, target, **settings):
        return _per_joint_column(signals, target, np.sign(signals.qd[:, target]))

    def composite_partners(self, candidate, candidates):
        """The viscous change of the joint: a Coulomb change of one sign and a viscous
        change of the other cancel at some speed (one at a time neither explains much)."""
        viscous = {c.target: c for c in candidates if c.effect.name == "viscous_friction"}
        return [(viscous[candidate.target], {})] if candidate.target in viscous else []

    def implausible(self, params, target, nominal):
        total = nominal_friction_levels(nominal, target)[0] + params["delta_coulomb"][0]
        if total < 0:
            return (f"the total dry friction would be {total:.3g} Nm: dry friction opposes "
                    "the motion, it cannot be negative")
        return None

    def size_that_matters(self, nominal, target):
        level = nominal_friction_levels(nominal, target)[0]
        return 0.2 * level if level > 0 else None

    def sentence(self, params, joints):
        value, std = params["delta_coulomb"]
        word = "more" if value > 0 else "less"
        return (f"{_joint_list(joints)} has {abs(value):.3g} +- {std:.2g} Nm {word} dry "
                "(Coulomb) friction than the model")


class ViscousFrictionEffect(Effect):
    """Missing viscous friction :math:`\\Delta F_v\\,\\dot q_\\ell` [Nm s/rad].

    Examples
    --------
    >>> ViscousFrictionEffect().units
    ('Nm s/rad',)
    """

    name = "viscous_friction"
    excitation = ("constant-speed sweeps at 5 speeds up to the joint's limit, 5 s each, "
                  "both directions")
    title = "viscous friction"
    parameter_names = ("delta_viscous",)
    units = ("Nm s/rad",)

    def design(self, signals, nominal, target, **settings):
        return _per_joint_column(signals, target, signals.qd[:, target])

    def implausible(self, params, target, nominal):
        total = nominal_friction_levels(nominal, target)[1] + params["delta_viscous"][0]
        if total < 0:
            return (f"the total viscous friction would be {total:.3g} Nm s/rad: viscous "
                    "friction dissipates energy, it cannot be negative")
        return None

    def size_that_matters(self, nominal, target):
        level = nominal_friction_levels(nominal, target)[1]
        return 0.2 * level if level > 0 else None

    def sentence(self, params, joints):
        value, std = params["delta_viscous"]
        word = "more" if value > 0 else "less"
        return (f"{_joint_list(joints)} has {abs(value):.3g} +- {std:.2g} Nm s/rad {word} "
                "viscous friction than the model")


class StribeckFrictionEffect(Effect):
    """Missing low-speed friction peak (Stribeck effect).

    .. math::

        \\tau = \\Delta F_s\\, \\mathrm{sign}(\\dot q_\\ell)\\,
            e^{-(\\dot q_\\ell / v_s)^2}

    linear in the amplitude :math:`\\Delta F_s` [Nm] for a fixed Stribeck
    velocity :math:`v_s` [rad/s]; the selection tries ``velocities`` and the
    final fit refines :math:`v_s` by a bounded 1-D search on
    :math:`\\log v_s` (its standard deviation from the curvature of the
    weighted sum of squares there).

    Parameters
    ----------
    velocities : sequence of float, default=STRIBECK_VELOCITIES
        Grid of Stribeck velocities [rad/s].

    Examples
    --------
    >>> len(StribeckFrictionEffect().settings_grid())
    10
    """

    name = "stribeck_friction"
    excitation = "slow sweeps through zero velocity (0.002-0.1 rad/s, 10 reversals)"
    plan_segment = "low_speed"
    title = "Stribeck (low-speed) friction peak"
    parameter_names = ("delta_stribeck", "stribeck_velocity")
    units = ("Nm", "rad/s")
    refit_drop_is_final = True
    #: Its parameter of velocity scale (a peak and a softening too close to tell).
    velocity_parameter = "stribeck_velocity"

    def __init__(self, velocities=STRIBECK_VELOCITIES):
        self.velocities = velocities

    def settings_grid(self):
        return [{"stribeck_velocity": float(v)} for v in self.velocities]

    def design(self, signals, nominal, target, stribeck_velocity=0.02, **ignored):
        peak = stribeck_peak(signals.qd[:, target], stribeck_velocity)
        return _per_joint_column(signals, target, peak)

    def physical(self, theta, cov, target, settings, nominal):
        return {"delta_stribeck": (float(theta[0]), float(np.sqrt(max(cov[0, 0], 0.0)))),
                "stribeck_velocity": (float(settings["stribeck_velocity"]),
                                      float(settings.get("stribeck_velocity_std", np.nan)))}

    def refine(self, objective, settings):
        from scipy.optimize import minimize_scalar

        v0 = settings["stribeck_velocity"]
        lo, hi = np.log(v0 / 2.0), np.log(v0 * 2.0)
        fixed = {k: v for k, v in settings.items() if k not in ("stribeck_velocity",
                                                                 "stribeck_velocity_std")}

        def f(s):
            return objective({**fixed, "stribeck_velocity": float(np.exp(s))})

        res = minimize_scalar(f, bounds=(lo, hi), method="bounded", options={"xatol": 1e-3})
        # std of log v_s from the curvature of the weighted SSE (a chi-square)
        h = 0.05
        curvature = (f(res.x + h) + f(res.x - h) - 2.0 * f(res.x)) / h**2
        v = float(np.exp(res.x))
        std = v * np.sqrt(2.0 / curvature) if curvature > 0 else np.nan
        return {**fixed, "stribeck_velocity": v, "stribeck_velocity_std": float(std)}

    def implausible(self, params, target, nominal):
        value = params["delta_stribeck"][0]
        vs = params["stribeck_velocity"][0]
        lo, hi = BOUNDS["stribeck_velocity"]
        if value < 0:
            return (f"a negative peak ({value:.3g} Nm) is not a Stribeck effect (friction "
                    "above the dry level at low speed): it is the low-speed softening of "
                    "dry friction")
        if not lo <= vs <= hi:
            return f"Stribeck velocity {vs:.3g} rad/s outside [{lo:g}, {hi:g}] rad/s"
        return None

    def context(self, params):
        """The peak [Nm]: the dry friction a softening of the joint acts on grows by it."""
        return {"peak": params["delta_stribeck"][0]}

    def composite_partners(self, candidate, candidates):
        """Softenings of the joint at least ``PAIR_SEPARATION`` times slower: a peak
        added to friction that softens at lower speed cancels part of the softening."""
        vs = candidate.settings.get("stribeck_velocity")
        out = []
        for soft in candidates:
            if soft.effect.name != "friction_softening":
                continue
            v0 = soft.settings.get("stribeck_velocity")
            if soft.target != candidate.target or vs is None or v0 is None or \
                    v0 * PAIR_SEPARATION > vs:
                continue
            out.append((soft, {**candidate.settings, "softening_velocity": v0,
                               "softening_shape": soft.settings.get("shape", "gaussian")}))
        return out

    def size_that_matters(self, nominal, target):
        level = nominal_friction_levels(nominal, target)[0]
        return 0.3 * level if level > 0 else None

    def sentence(self, params, joints):
        value, std = params["delta_stribeck"]
        vs = params["stribeck_velocity"][0]
        word = "higher" if value > 0 else "lower"
        return (f"{_joint_list(joints)} has a {word} breakaway (Stribeck) friction peak: "
                f"{abs(value):.3g} +- {std:.2g} Nm below about {vs:.3g} rad/s")


def softening_shape(qd, velocity, shape="gaussian"):
    """How dry friction softens at low speed, per Nm of softening.

    Parameters
    ----------
    qd : array-like
        Joint velocities [rad/s].
    velocity : float
        Velocity scale ``v_0`` [rad/s].
    shape : {"gaussian", "exponential", "linear"}, default="gaussian"
        ``sign(qd)`` times ``exp(-(qd/v_0)^2)``, ``exp(-|qd|/v_0)`` or
        ``max(0, 1 - |qd|/v_0)``.

    Returns
    -------
    column : ndarray
        Same shape as ``qd`` (zero where ``qd == 0``).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.diagnosis.effects import softening_shape
    >>> v = np.array([-0.01, 0.0, 0.005, 0.02])
    >>> [softening_shape(v, 0.01, s).round(3).tolist() for s in SOFTENING_SHAPES]
    [[-0.368, 0.0, 0.779, 0.018], [-0.368, 0.0, 0.607, 0.135], [-0.0, 0.0, 0.5, 0.0]]
    """
    qd = np.asarray(qd, dtype=float)
    if shape == "gaussian":
        return stribeck_peak(qd, velocity)
    a = np.abs(qd) / velocity
    if shape == "exponential":
        return np.sign(qd) * np.exp(-a)
    if shape == "linear":
        return np.sign(qd) * np.maximum(0.0, 1.0 - a)
    raise ValueError(f"unknown softening shape {shape!r}; use one of {SOFTENING_SHAPES}")


class FrictionSofteningEffect(StribeckFrictionEffect):
    """Dry friction that softens at low speed (regularised or constraint-based friction).

    .. math::

        \\tau = -\\Delta F_0\\, \\mathrm{sign}(\\dot q_\\ell)\\,
            e^{-(\\dot q_\\ell / v_0)^2}, \\qquad \\Delta F_0 \\ge 0

    The friction is :math:`\\Delta F_0` below the Coulomb level as the
    velocity goes to zero, over a velocity scale :math:`v_0` (the smooth
    ``tanh``/saturated laws of simulators, the soft friction constraint of
    MuJoCo, the pre-sliding regime of a real gearbox). The columns have the
    opposite, physically constrained sign of :class:`StribeckFrictionEffect`'s:
    a Stribeck peak raises the friction at low speed, softening lowers it; a
    fit of one with the other's sign is rejected. How the friction softens
    depends on the mechanism, so the shape is a setting
    (:data:`SOFTENING_SHAPES`, :func:`softening_shape`): ``"gaussian"``
    (:math:`e^{-(\\dot q/v_0)^2}`, the Stribeck law's), ``"exponential"``
    (:math:`e^{-|\\dot q|/v_0}`, a regularised constraint such as MuJoCo's
    ``frictionloss``) and ``"linear"`` (:math:`\\max(0, 1 - |\\dot q|/v_0)`,
    a velocity motor whose force saturates at the dry level, PyBullet's).
    With the Gaussian only, a peak next to the plant's own softening came
    out 22-40 % low on some blind development cases (the misfit of the
    shape goes into the peak); all shapes sized one of them right (case202:
    -36 % -> -8 %) but cost the second engine's viscous case (see
    ``shapes``).

    Parameters
    ----------
    velocities : sequence of float, default=STRIBECK_VELOCITIES
        Grid of velocity scales [rad/s].
    shapes : sequence of str, default=("gaussian",)
        Shapes tried (any of :data:`SOFTENING_SHAPES`). Opt-in: with all
        three, the second engine's viscous change of joint 5 was named a
        Coulomb change (an exponential softening of 3.4 Nm on a 2.5 Nm dry
        level left Coulomb and viscous within one standard error), so the
        default stays the Gaussian; pass
        ``FrictionSofteningEffect(shapes=SOFTENING_SHAPES)`` in ``effects``
        to try them all.

    Examples
    --------
    >>> FrictionSofteningEffect().name, FrictionSofteningEffect().parameter_names
    ('friction_softening', ('softening', 'softening_velocity'))
    """

    name = "friction_softening"
    excitation = None
    plan_segment = "low_speed"
    title = "low-speed softening of dry friction"
    parameter_names = ("softening", "softening_velocity")
    units = ("Nm", "rad/s")
    velocity_parameter = "softening_velocity"

    def __init__(self, velocities=STRIBECK_VELOCITIES, shapes=("gaussian",)):
        self.velocities = velocities
        self.shapes = shapes

    def settings_grid(self):
        # the other shapes are those of a simulator's or a controller's regularised dry
        # friction, which softens below a few hundredths of a rad/s (fewer candidates)
        return [{"stribeck_velocity": float(v), "shape": str(shape)}
                for shape in self.shapes for v in self.velocities
                if shape == "gaussian" or v <= SOFTENING_MAX_VELOCITY]

    def design(self, signals, nominal, target, stribeck_velocity=0.02, shape="gaussian",
               **ignored):
        column = -softening_shape(signals.qd[:, target], stribeck_velocity, shape)
        return _per_joint_column(signals, target, column)

    def physical(self, theta, cov, target, settings, nominal):
        peak = super().physical(theta, cov, target, settings, nominal)
        return dict(zip(self.parameter_names, peak.values()))

    def implausible(self, params, target, nominal, peak=0.0):
        """Why the softening is implausible, or None (see :meth:`Effect.implausible`).

        ``peak`` [Nm] is a Stribeck peak named on the same joint: the dry
        friction that softens is then the Coulomb level plus that peak.
        """
        value, vs = params["softening"][0], params["softening_velocity"][0]
        lo, hi = BOUNDS["stribeck_velocity"]
        if value < 0:
            return (f"a negative softening ({value:.3g} Nm) is a Stribeck peak, not a softening "
                    "of dry friction")
        coulomb = nominal_friction_levels(nominal, target)[0]
        dry = coulomb + max(float(peak), 0.0)
        if coulomb > 0 and value > 1.5 * dry:
            return (f"softening of {value:.3g} Nm exceeds 1.5 times the dry friction "
                    f"({dry:.3g} Nm)")
        if not lo <= vs <= hi:
            return f"softening velocity {vs:.3g} rad/s outside [{lo:g}, {hi:g}] rad/s"
        return None

    def implausible_among(self, params, target, nominal, context):
        return self.implausible(params, target, nominal, peak=context.get("peak", 0.0))

    def context(self, params):
        return {}

    def composite_partners(self, candidate, candidates):
        return []

    def variant_note(self, settings):
        return f" ({settings.get('shape', 'gaussian')} shape)"

    def fallback_variant(self, settings, variants):
        """The Gaussian shape nearest in velocity scale, for a softening of another shape
        that grew implausible in the refit (the joint's dry friction still softens)."""
        if settings.get("shape", "gaussian") == "gaussian":
            return None
        v0 = settings.get("stribeck_velocity", 0.004)
        gaussian = [k for k, v in enumerate(variants) if v.get("shape", "gaussian") == "gaussian"]
        if not gaussian:
            return None
        return min(gaussian, key=lambda k: abs(np.log(variants[k]["stribeck_velocity"] / v0)))

    def size_that_matters(self, nominal, target):
        return None  # a shape of the dry friction, not a finding of its own

    def sentence(self, params, joints):
        value, std = params["softening"]
        vs = params["softening_velocity"][0]
        return (f"the dry friction of {_joint_list(joints)} softens at low speed: "
                f"{value:.3g} +- {std:.2g} Nm below the Coulomb level under about {vs:.3g} rad/s")


class RotorInertiaEffect(Effect):
    """Missing reflected rotor inertia :math:`\\Delta J\\,\\ddot q_\\ell` [kg m^2] (Eq. 4).

    Examples
    --------
    >>> RotorInertiaEffect().name
    'rotor_inertia'
    """

    name = "rotor_inertia"
    excitation = ("fast small oscillations of the joint alone (amplitude 0.1 rad, 2-3 Hz,"
                  " accelerations above 10 rad/s^2) at a fixed pose, 20 s")
    plan_segment = "chirp"
    title = "reflected rotor (motor and gear) inertia"
    parameter_names = ("delta_rotor_inertia",)
    units = ("kg m^2",)

    def design(self, signals, nominal, target, **settings):
        return _per_joint_column(signals, target, signals.qdd[:, target])

    def implausible(self, params, target, nominal):
        value = params["delta_rotor_inertia"][0]
        armature = getattr(nominal.robot.model, "armature", None)
        nominal_j = float(armature[target]) if armature is not None and len(armature) > \
            target else 0.0
        if nominal_j + value < 0:
            return (f"the total rotor inertia would be {nominal_j + value:.3g} kg m^2 "
                    "(negative)")
        if abs(value) > BOUNDS["rotor_inertia"]:
            return (f"a change of {value:.3g} kg m^2 exceeds {BOUNDS['rotor_inertia']:g} "
                    "kg m^2, far beyond the reflected rotor inertia of a robot joint")
        return None

    def sentence(self, params, joints):
        value, std = params["delta_rotor_inertia"]
        word = "more" if value > 0 else "less"
        return (f"{_joint_list(joints)} has {abs(value):.3g} +- {std:.2g} kg m^2 {word} "
                "reflected rotor inertia than the model")


def _point_mass_parameters(mass, first_moment, origin, rotation=np.eye(3), quadratic=None):
    """Dynamic parameters (pinocchio order) of a point mass, linearised in (m, m c).

    The mass ``m`` sits at ``x = origin + R c`` of the link frame, so
    :math:`h = m x = m\\,\\mathrm{origin} + R (m c)` and, about the link
    frame origin, :math:`I = m(|x|^2 \\mathbb 1 - x x^T)`. Writing
    :math:`m x x^T = m\\,o o^T + o (R h_c)^T + (R h_c) o^T + m R c c^T R^T`
    with :math:`h_c = m c`, every term but the last is linear in
    :math:`(m, h_c)`; the last (second order in the offset ``c``) is dropped,
    or taken from ``quadratic`` (a fixed ``c``) when given.
    """
    o = np.asarray(origin, dtype=float)
    hc = rotation @ np.asarray(first_moment, dtype=float)
    outer = mass * np.outer(o, o) + np.outer(o, hc) + np.outer(hc, o)
    if quadratic is not None:
        c = rotation @ np.asarray(quadratic, dtype=float)
        outer = outer + mass * np.outer(c, c)
    inertia = np.trace(outer) * np.eye(3) - outer
    h = mass * o + hc
    return np.array([mass, h[0], h[1], h[2], inertia[0, 0], inertia[0, 1], inertia[1, 1],
                     inertia[0, 2], inertia[1, 2], inertia[2, 2]])


def _shared_columns(signals, link_columns, mapping):
    """``{joint: Y_link @ mapping / K}`` for the joints the link's parameters move."""
    cols = np.einsum("njp,pk->njk", link_columns, mapping)
    cols = cols / signals.torque_constants[None, :, None]
    scale = np.abs(cols).max() if cols.size else 0.0
    return {j: cols[:, j, :] for j in range(cols.shape[1])
            if scale > 0 and np.abs(cols[:, j, :]).max() > 1e-9 * scale}


class PayloadEffect(Effect):
    """A payload at the flange: mass ``m`` and centre of mass ``c`` (flange frame).

    Its torques are the last link's rigid-body features times the dynamic
    parameters of a point mass at the flange (``flange_frame`` placement
    ``(R, p)`` in the last joint frame), which are linear in ``(m, m c)``
    when the term ``m c c^T`` of the inertia about the joint origin is
    neglected (see :func:`_point_mass_parameters`). The payload's own
    rotational inertia about its centre of mass is neglected as well (a
    compact payload; both terms are second order in its size). The final
    fit re-evaluates the ``m c c^T`` term at the fitted ``c`` (fixed point).

    Parameters (physical): ``mass`` [kg], ``com_x``, ``com_y``, ``com_z``
    [m] in the flange frame.

    Examples
    --------
    >>> PayloadEffect().parameter_names
    ('mass', 'com_x', 'com_y', 'com_z')
    """

    name = "payload"
    excitation = ("slow moves of the wrist joints through many orientations (gravity "
                  "torques), 60 s")
    plan_segment = "gravity_load"
    title = "payload at the flange"
    per_joint = False
    parameter_names = ("mass", "com_x", "com_y", "com_z")
    units = ("kg", "m", "m", "m")

    def _mapping(self, nominal, com=None):
        robot = nominal.robot
        frame = robot.model.frames[robot.flange_frame_id]
        placement = frame.placement
        link = int(frame.parentJoint) - 1
        basis = np.eye(4)
        mapping = np.column_stack([
            _point_mass_parameters(b[0], b[1:], placement.translation, placement.rotation,
                                   None if com is None or k > 0 else com)
            for k, b in enumerate(basis)])
        return link, mapping

    def design(self, signals, nominal, target, com=None):
        link, mapping = self._mapping(nominal, com)
        Y = signals.rigid_body_features(nominal.robot.model)
        return _shared_columns(signals, Y[:, :, 10 * link:10 * link + 10], mapping)

    def settings_from_fit(self, settings, theta):
        """The centre of mass of the fitted first moment over the mass."""
        if theta.size == 4 and abs(theta[0]) > 0:
            return {**settings, "com": tuple(float(c) for c in theta[1:] / theta[0])}
        return None

    def physical(self, theta, cov, target, settings, nominal):
        def convert(t):
            m = t[0]
            return np.concatenate([[m], t[1:] / m if m != 0 else np.full(3, np.nan)])

        values, stds = _delta(convert, theta, cov)
        return {n: (float(v), float(s)) for n, v, s in zip(self.parameter_names, values, stds)}

    def refine(self, objective, settings):
        return settings  # the m c c^T fixed point is done by joint_fit

    def implausible(self, params, target, nominal):
        m = params["mass"][0]
        rated = rated_payload(nominal.robot)
        if not 0 < m <= 2.0 * rated:
            return (f"payload mass {m:.3g} kg outside (0, {2.0 * rated:g}] kg (twice the rated "
                    "payload)")
        if m < BOUNDS["payload_fraction"] * rated:
            return (f"payload mass {m:.3g} kg is below {100 * BOUNDS['payload_fraction']:g} % "
                    f"of the rated payload ({rated:g} kg): within what link-mass and "
                    "friction calibration errors produce, not a finding")
        com = np.array([params[k][0] for k in ("com_x", "com_y", "com_z")])
        if not np.all(np.isfinite(com)) or np.linalg.norm(com) > BOUNDS["payload_com"]:
            return (f"centre of mass {np.linalg.norm(com):.3g} m from the flange (more than "
                    f"{BOUNDS['payload_com']:g} m)")
        return None

    def size_that_matters(self, nominal, target):
        return BOUNDS["payload_fraction"] * rated_payload(nominal.robot)

    def sentence(self, params, joints):
        m, sm = params["mass"]
        com = ", ".join(f"{params[k][0]:.3f}" for k in ("com_x", "com_y", "com_z"))
        return (f"a payload of {m:.3g} +- {sm:.2g} kg is carried at the flange "
                f"(centre of mass at ({com}) m in the flange frame)")


class LinkMassEffect(Effect):
    """A link heavier or lighter than the model (e.g. cables, a tool bracket).

    Parameters of link ``k``: ``delta_mass`` [kg], added at the link's
    nominal centre of mass ``c_k`` (with its point-mass inertia about the
    joint origin), and a first-moment change ``delta_first_moment_x/y/z``
    [kg m] in the link frame (the centre of mass moving). Linear in the
    link's 10 inertial parameters: ``Y_k @ [dm [1, c_k, I(c_k)] + [0, dh, 0]]``.

    Two variants compete: the mass change alone (at the nominal centre of
    mass, one parameter; the first-moment changes are reported as 0) and
    with the centre of mass moving (four parameters, weakly told apart from
    the mass by gravity alone); the selection prefers the simpler one unless
    the other is clearly better.

    Only links ``1 .. n-2`` (0-based) are candidates: the mass of link 0
    does not load the (vertical) base joint, and a change of the last link is
    the ``payload`` effect. A payload whose centre of mass lies on the last
    joint's axis loads the joints like a mass on link ``n-2``; the selection
    then prefers the payload (listed first, same size).

    Examples
    --------
    >>> LinkMassEffect().name
    'link_mass'
    """

    name = "link_mass"
    excitation = ("slow moves of the joint through its whole range at several poses of "
                  "the outer joints (gravity torques, accelerations below 1 rad/s^2), 60 "
                  "s")
    plan_segment = "gravity_load"
    target_kind = "link"
    title = "link mass"
    per_joint = False
    parameter_names = ("delta_mass", "delta_first_moment_x", "delta_first_moment_y",
                       "delta_first_moment_z")
    units = ("kg", "kg m", "kg m", "kg m")

    def targets(self, nominal):
        return list(range(1, nominal.n_joints - 1))

    def settings_grid(self):
        # mass at the nominal centre of mass only, or with the centre of mass moving;
        # the one-standard-error rule prefers the first (1 parameter against 4)
        return [{"com_shift": False}, {"com_shift": True}]

    def design(self, signals, nominal, target, com_shift=True, **settings):
        com = nominal.robot.model.inertias[target + 1].lever
        mapping = np.column_stack([_point_mass_parameters(1.0, np.zeros(3), com)]
                                  + ([np.r_[0.0, e, np.zeros(6)] for e in np.eye(3)]
                                     if com_shift else []))
        Y = signals.rigid_body_features(nominal.robot.model)
        return _shared_columns(signals, Y[:, :, 10 * target:10 * target + 10], mapping)

    def physical(self, theta, cov, target, settings, nominal):
        params = super().physical(theta, cov, target, settings, nominal)
        for name in self.parameter_names[len(theta):]:
            params[name] = (0.0, 0.0)  # centre of mass kept (com_shift=False)
        return params

    def implausible(self, params, target, nominal):
        dm = params["delta_mass"][0]
        link = float(nominal.robot.model.inertias[target + 1].mass)
        if abs(dm) > link:
            return (f"a mass change of {dm:.3g} kg on a link of {link:.3g} kg (more than the "
                    "link's own mass)")
        return None

    def sentence(self, params, joints):
        m, sm = params["delta_mass"]
        word = "heavier" if m > 0 else "lighter"
        return f"a link is {abs(m):.3g} +- {sm:.2g} kg {word} than the model"


class GravityTiltEffect(Effect):
    """The robot base is tilted: gravity is not along the base's -z axis.

    For a base rotated by small roll ``a`` (about x) and pitch ``b`` (about
    y), gravity in the base frame is :math:`g_b = R^T g \\approx
    (g_0 b, -g_0 a, -g_0)`; gravity torques are linear in the gravity
    vector, so the columns are the generalized gravity torques for unit
    gravity along base x and y and the coefficients are
    :math:`(g_0 b, -g_0 a)` (exact to first order in the angles).

    Parameters (physical): ``roll``, ``pitch`` [rad].

    Examples
    --------
    >>> GravityTiltEffect().parameter_names
    ('roll', 'pitch')
    """

    name = "gravity_tilt"
    excitation = ("slow moves of the base joint through a full turn with the arm "
                  "stretched out, 60 s")
    title = "tilted robot base (gravity direction)"
    per_joint = False
    parameter_names = ("roll", "pitch")
    units = ("rad", "rad")

    def design(self, signals, nominal, target, **settings):
        if "gravity_tilt" not in signals._cache:
            signals._cache["gravity_tilt"] = self._columns(signals, nominal)
        return signals._cache["gravity_tilt"]

    def _columns(self, signals, nominal):
        model = pin.Model(nominal.robot.model)
        cols = np.empty((signals.n_samples, signals.n_joints, 2))
        for k, direction in enumerate(np.eye(3)[:2]):
            model.gravity = pin.Motion(direction, np.zeros(3))  # unit gravity along x or y
            data = model.createData()
            for i, q in enumerate(signals.q):
                cols[i, :, k] = pin.computeGeneralizedGravity(model, data, q)
        cols /= signals.torque_constants[None, :, None]
        scale = np.abs(cols).max()
        return {j: cols[:, j, :] for j in range(signals.n_joints)
                if np.abs(cols[:, j, :]).max() > 1e-9 * scale}

    def physical(self, theta, cov, target, settings, nominal):
        g0 = STANDARD_GRAVITY
        values, stds = _delta(lambda t: np.array([-t[1] / g0, t[0] / g0]), theta, cov)
        return {n: (float(v), float(s)) for n, v, s in zip(self.parameter_names, values, stds)}

    def implausible(self, params, target, nominal):
        worst = max(abs(params["roll"][0]), abs(params["pitch"][0]))
        if worst > BOUNDS["tilt"]:
            return (f"a tilt of {np.degrees(worst):.1f} deg (more than "
                    f"{np.degrees(BOUNDS['tilt']):.1f} deg would be visible)")
        return None

    def sentence(self, params, joints):
        roll, pitch = (np.degrees(params[k][0]) for k in ("roll", "pitch"))
        sr, sp = (np.degrees(params[k][1]) for k in ("roll", "pitch"))
        return (f"the robot base is tilted: roll {roll:.2f} +- {sr:.2f} deg, "
                f"pitch {pitch:.2f} +- {sp:.2f} deg")


class TorqueConstantEffect(Effect):
    """A wrong torque constant: current scaled per joint.

    If the true constant is :math:`K_\\ell s`, the current is
    :math:`\\tau/(K_\\ell s) = \\hat i_\\ell (1 + c)` with
    :math:`c = 1/s - 1`: the column is the reference current itself.
    Reported: ``scale`` ``s`` (true / nominal) and ``torque_constant``
    [Nm/A].

    Examples
    --------
    >>> TorqueConstantEffect().parameter_names
    ('scale', 'torque_constant')
    """

    name = "torque_constant"
    excitation = ("moves at several payload-free torque levels: fast and slow "
                  "accelerations at the same poses, 30 s")
    plan_segment = "gravity_load"
    title = "torque constant"
    parameter_names = ("scale", "torque_constant")
    units = ("", "Nm/A")

    def design(self, signals, nominal, target, **settings):
        return {target: signals.reference[:, [target]]}

    def physical(self, theta, cov, target, settings, nominal):
        k = nominal.torque_constants[target]
        values, stds = _delta(lambda t: np.array([1 / (1 + t[0]), k / (1 + t[0])]), theta, cov)
        return {n: (float(v), float(s)) for n, v, s in zip(self.parameter_names, values, stds)}

    def implausible(self, params, target, nominal):
        scale = params["scale"][0]
        lo, hi = BOUNDS["torque_constant_scale"]
        if not lo <= scale <= hi:
            return (f"torque constant scale {scale:.3g} outside [{lo:g}, {hi:g}] (a motor that "
                    f"lost or gained {abs(100 * (scale - 1)):.0f} % of its torque)")
        return None

    def smallest_changes(self, signals, residual, after, mask, min_share, min_gain):
        """Per joint: the smallest torque-constant change the recordings could show.

        A change ``c`` of joint ``l``'s constant scales its whole reference
        current, but the part of that current a friction change can mimic
        (Coulomb, viscous, low-speed columns) is no evidence for it: only ``x_perp``, the
        reference current with those columns regressed out on the joint's moving
        rows, is. The change must (a) be ``IDENTIFIABLE_SE`` standard errors of
        the regression of the remaining residual on ``x_perp`` (Newey-West,
        Bartlett weights over 0.5 s: the residual is autocorrelated) and (b)
        explain ``min_share`` of the nominal residual and ``min_gain`` of the
        remaining one on the joint (what the selection asks of every effect).
        Returns ``(joint, smallest change, share of the reference current the
        friction columns reproduce)`` per joint.
        """
        out = []
        dt = sample_period(signals)
        lags = int(round(0.5 / dt)) if dt > 0 else 0
        for j in range(signals.n_joints):
            rows = np.flatnonzero(mask[:, j])
            if rows.size < 20:
                continue
            x = signals.reference[rows, j]
            qd = signals.qd[rows, j]
            friction = np.column_stack([np.sign(qd), qd]
                                       + [stribeck_peak(qd, v) for v in _LOW_SPEED])
            x_perp = x - friction @ np.linalg.lstsq(friction, x, rcond=None)[0]
            power = float(x_perp @ x_perp)
            if power <= 0:
                out.append((j, np.inf, 1.0))
                continue
            r = after[rows, j]
            u = x_perp * (r - x_perp * float(x_perp @ r) / power)
            hac = float(u @ u)
            for lag in range(1, min(lags, rows.size - 1) + 1):
                hac += 2.0 * (1.0 - lag / (lags + 1)) * float(u[lag:] @ u[:-lag])
            se = np.sqrt(max(hac, 0.0)) / power
            practical = max(min_share * float(residual[rows, j] @ residual[rows, j]),
                            min_gain * float(r @ r))
            change = max(IDENTIFIABLE_SE * se, np.sqrt(practical / power))
            mimicked = 1.0 - power / max(float(x @ x), 1e-300)
            out.append((j, float(change), float(mimicked)))
        return out

    def size_that_matters(self, nominal, target):
        return 0.1

    def sentence(self, params, joints):
        s, ss = params["scale"]
        k, sk = params["torque_constant"]
        return (f"the torque constant of {_joint_list(joints)} is {k:.4g} +- {sk:.2g} Nm/A, "
                f"{100 * (s - 1):+.1f} % off the nominal value")


class CurrentOffsetEffect(Effect):
    """A constant bias of the logged current (sensor offset) [A].

    Examples
    --------
    >>> CurrentOffsetEffect().units
    ('A',)
    """

    name = "current_offset"
    excitation = "holds at several poses where the gravity torque changes sign, 5 s each"
    plan_segment = "gravity_load"
    title = "current sensor offset"
    parameter_names = ("offset",)
    units = ("A",)

    def design(self, signals, nominal, target, **settings):
        return {target: np.ones((signals.n_samples, 1))}

    def sentence(self, params, joints):
        value, std = params["offset"]
        return f"the current of {_joint_list(joints)} is offset by {value:.3g} +- {std:.2g} A"


class TimeDelayEffect(Effect):
    """The logged current lags the motion by ``d`` seconds (all joints).

    If the logged current is :math:`i(t) = i^*(t - d)`, with :math:`i^*` the
    current that drives the joints, its residual against the reference is
    :math:`\\hat i(t - d) - \\hat i(t)` wherever the joint moved at
    :math:`t - d`. The column is :math:`(\\hat i(t - d) - \\hat i(t)) / d`
    with coefficient ``d`` (about :math:`-\\dot{\\hat i}` for small ``d``);
    the selection tries the ``delays`` grid, the final fit iterates ``d`` to
    a fixed point (a 1-D search).

    Parameters
    ----------
    delays : sequence of float, default=DELAYS
        Grid of delays [s] tried by the selection (negative: the current
        leads). Right after a rest
    the logged current is the holding current of the stuck joint, which no
    model of the state knows: those rows are left out (``rest_guard``, see
    :class:`~sklearn_gpcd.diagnosis.DynamicsDiagnosis`), and predictions
    shift the reference only where the joint moved ``d`` seconds earlier.
    Needs time stamps.

    Examples
    --------
    >>> TimeDelayEffect().needs_time
    True
    """

    name = "time_delay"
    excitation = "fast reversals (torque steps), 20 s"
    plan_segment = "chirp"
    title = "time delay of the logged current"
    per_joint = False
    parameter_names = ("delay",)
    units = ("s",)
    needs_time = True
    rest_guard = True

    def __init__(self, delays=DELAYS):
        self.delays = delays

    def settings_grid(self):
        return [{"delay": float(d)} for d in self.delays]

    def refine(self, objective, settings):
        return settings  # fixed point done by joint_fit

    def design(self, signals, nominal, target, delay=None, **settings):
        if signals.reference_rate is None:
            raise ValueError("time_delay needs time stamps (recordings, not bare states)")
        if delay:
            cols = (_shift(signals, signals.reference, delay) - signals.reference) / delay
        else:
            cols = -signals.reference_rate
        return {j: cols[:, [j]] for j in range(signals.n_joints)}

    def prediction(self, signals, nominal, target, theta, settings):
        if signals.time is None:
            raise ValueError("time_delay needs time stamps (recordings, not bare states)")
        delay = float(theta[0])
        term = _shift(signals, signals.reference, delay) - signals.reference
        # where the joint was at rest d seconds ago the reference misses the
        # holding current: leave the reference unshifted there
        moving_then = np.abs(_shift(signals, signals.qd, delay)) >= REST_VELOCITY
        return np.where(moving_then & (np.abs(signals.qd) >= REST_VELOCITY), term, 0.0)

    def implausible(self, params, target, nominal):
        d = params["delay"][0]
        if abs(d) >= BOUNDS["delay"]:
            return f"a delay of {d:.3g} s (at least {BOUNDS['delay']:g} s)"
        return None

    def unresolved(self, value, sample_period):
        """Why a lead of the current shorter than half the sample period is not reported.

        The current of one control cycle drives the motion up to the next
        sample, so a logged current may lead the logged state by a fraction of
        a sample (which sample of the cycle each carries: the logger's or the
        integrator's convention; PyBullet's current leads its state by about
        1.4 ms at 125 Hz). That is no delay of the log; a lag (the current
        logged late) is reported at any length.
        """
        if sample_period > 0 and -0.5 * sample_period < value < 0:
            return (f"the current leads the state by {-1000 * value:.2g} ms, less than half "
                    f"the sample period ({1000 * sample_period:.3g} ms): which sample of the "
                    "control cycle the current and the state carry, not a delay of the log")
        return None

    def settings_from_fit(self, settings, theta):
        """The fitted delay (clipped to +-0.2 s) becomes the shift of the columns."""
        if theta.size != 1:
            return None
        delay = float(np.clip(theta[0], -0.2, 0.2))
        return {**settings, "delay": delay} if abs(delay) > 1e-4 else settings

    def size_that_matters(self, nominal, target):
        return 0.005

    def sentence(self, params, joints):
        value, std = params["delay"]
        word = "lags" if value > 0 else "leads"
        return (f"the logged current {word} the motion by {1000 * abs(value):.3g} +- "
                f"{1000 * std:.2g} ms")


def _shift(signals, values, delay):
    """``values(t - delay)`` per recording, linear interpolation, edges held."""
    out = np.empty_like(values)
    for seg in np.unique(signals.segment):
        rows = np.flatnonzero(signals.segment == seg)
        t = signals.time[rows]
        for j in range(values.shape[1]):
            out[rows, j] = np.interp(t - delay, t, values[rows, j])
    return out


class JointSpringEffect(Effect):
    """A spring (e.g. a cable or a gravity compensator) on a joint: :math:`-k(q_\\ell - q_0)`.

    The motor must add :math:`k(q_\\ell - q_0)` to hold against it: columns
    ``[q_l, 1] / K`` with coefficients ``(k, -k q_0)``; reported
    ``stiffness`` ``k`` [Nm/rad] and ``rest_position`` ``q_0`` [rad].

    Examples
    --------
    >>> JointSpringEffect().parameter_names
    ('stiffness', 'rest_position')
    """

    name = "joint_spring"
    excitation = ("slow moves over the joint's full range at a constant pose of the "
                  "others, 60 s")
    title = "joint spring"
    parameter_names = ("stiffness", "rest_position")
    units = ("Nm/rad", "rad")

    def design(self, signals, nominal, target, **settings):
        q = signals.q[:, target]
        return _per_joint_column(signals, target, np.column_stack([q, np.ones_like(q)]))

    def physical(self, theta, cov, target, settings, nominal):
        values, stds = _delta(lambda t: np.array([t[0], -t[1] / t[0] if t[0] else np.nan]),
                              theta, cov)
        return {n: (float(v), float(s)) for n, v, s in zip(self.parameter_names, values, stds)}

    def implausible(self, params, target, nominal):
        k, q0 = params["stiffness"][0], params["rest_position"][0]
        if not k > 0:
            return f"stiffness {k:.3g} Nm/rad: a spring pulls towards its rest position (k > 0)"
        if not abs(q0) <= BOUNDS["joint_position"]:
            return (f"rest position {q0:.3g} rad outside the joint's range (+-2 pi; positions "
                    "in degrees?)")
        return None

    def sentence(self, params, joints):
        k, sk = params["stiffness"]
        q0 = params["rest_position"][0]
        return (f"{_joint_list(joints)} behaves as if a spring of {k:.3g} +- {sk:.2g} Nm/rad "
                f"pulled it towards {q0:.3g} rad")


class FrictionDriftEffect(Effect):
    """Friction changing linearly with time (warm-up of the gearbox grease).

    Columns ``[t s_v(qd_l), t qd_l] / K`` with ``t`` the time since the
    start of the recording; reported ``coulomb_rate`` [Nm/s] and
    ``viscous_rate`` [Nm s/rad per s]. Needs time stamps. Two variants
    compete (``settings_grid``): the dry friction level alone drifting
    (``with_viscous=False``, one column; ``viscous_rate`` is then reported
    as 0) and both levels drifting; the selection prefers the simpler one
    unless the second column earns its place.

    The dry level acts where the joint slides: below a velocity scale
    :math:`v` (pre-sliding, the soft or regularised friction of a servo or
    a simulator) the friction is less than the level, and so is a change
    of the level. The shape is :math:`s_v(\\dot q) = \\mathrm{sign}(\\dot q)
    (1 - e^{-(\\dot q / v)^2})` (``sliding_velocity`` :math:`v`, tried on
    ``sliding_velocities``; 0 is the plain sign). With the plain sign only,
    dry-friction drifts injected in the blind protocol's development cases
    (MuJoCo and PyBullet plants, whose dry friction is soft at low speed)
    came out up to 76 % small: the many samples at a few hundredths of a
    rad/s, where the drifting level is not developed, pulled the rate down.

    Parameters
    ----------
    sliding_velocities : sequence of float, default=(0.0, 0.005, 0.01, 0.02)
        Velocity scales [rad/s] below which the dry level is not developed.

    Examples
    --------
    >>> FrictionDriftEffect().needs_time
    True
    >>> FrictionDriftEffect(sliding_velocities=(0.0,)).settings_grid()
    [{'with_viscous': False, 'sliding_velocity': 0.0}, {'with_viscous': True, 'sliding_velocity': 0.0}]
    """

    name = "friction_drift"
    excitation = "the same moves repeated over at least 20 minutes from a cold start"
    plan_segment = "steady"
    title = "friction drifting with time"
    parameter_names = ("coulomb_rate", "viscous_rate")
    units = ("Nm/s", "Nm s/rad/s")
    needs_time = True
    trend = True

    def __init__(self, sliding_velocities=SLIDING_VELOCITIES):
        self.sliding_velocities = sliding_velocities

    def settings_grid(self):
        return [{"with_viscous": w, "sliding_velocity": float(v)}
                for w in (False, True) for v in self.sliding_velocities]

    def design(self, signals, nominal, target, with_viscous=True, sliding_velocity=0.0,
               **settings):
        if signals.time is None:
            raise ValueError("friction_drift needs time stamps (recordings, not bare states)")
        qd, t = signals.qd[:, target], signals.time
        dry = np.sign(qd)
        if sliding_velocity > 0:
            dry = dry * (1.0 - np.exp(-(qd / sliding_velocity) ** 2))
        cols = [t * dry, t * qd] if with_viscous else [t * dry]
        return _per_joint_column(signals, target, np.column_stack(cols))

    def physical(self, theta, cov, target, settings, nominal):
        std = np.sqrt(np.maximum(np.diag(cov), 0.0))
        out = {"coulomb_rate": (float(theta[0]), float(std[0])),
               "viscous_rate": (0.0, 0.0)}
        if theta.size > 1:
            out["viscous_rate"] = (float(theta[1]), float(std[1]))
        return out

    def implausible(self, params, target, nominal):
        rate = params["coulomb_rate"][0]
        if abs(rate) > BOUNDS["coulomb_rate"]:
            return f"dry friction changing by {rate:.3g} Nm/s ({60 * rate:.3g} Nm per minute)"
        return None

    def sentence(self, params, joints):
        rate, std = params["coulomb_rate"]
        word = "rises" if rate > 0 else "falls"
        vrate, vstd = params["viscous_rate"]
        text = (f"the friction of {_joint_list(joints)} {word} over time: Coulomb level by "
                f"{abs(rate) * 60:.3g} +- {std * 60:.2g} Nm per minute")
        if vrate == 0 and vstd == 0:  # the dry-friction-only variant
            return text + " (a trend in time, not a constant level)"
        return text + (f", viscous coefficient by {vrate * 60:.3g} +- {vstd * 60:.2g} Nm s/rad "
                       "per minute")


#: The effect library, in order of prior plausibility: on ties within one
#: standard error the selection prefers the effect listed first.
EFFECTS = (CoulombFrictionEffect, ViscousFrictionEffect, StribeckFrictionEffect,
           FrictionSofteningEffect, PayloadEffect, TorqueConstantEffect, CurrentOffsetEffect,
           RotorInertiaEffect, GravityTiltEffect, TimeDelayEffect, JointSpringEffect,
           FrictionDriftEffect, LinkMassEffect)


def effect_library(names="all"):
    """Instances of the named effects, in library order.

    Parameters
    ----------
    names : "all" or iterable of str or Effect, default="all"
        Effect names (``"payload"``, ...) or :class:`Effect` instances.

    Returns
    -------
    effects : list of Effect

    Examples
    --------
    >>> [e.name for e in effect_library(["payload", "coulomb_friction"])]
    ['coulomb_friction', 'payload']
    """
    known = {cls.name: cls for cls in EFFECTS}
    if isinstance(names, str):
        if names != "all":
            names = [names]
        else:
            return [cls() for cls in EFFECTS]
    out = []
    for item in names:
        if isinstance(item, Effect):
            out.append(item)
        elif item in known:
            out.append(known[item]())
        else:
            raise ValueError(f"unknown effect {item!r}; known effects: {list(known)}")
    order = {cls.name: k for k, cls in enumerate(EFFECTS)}
    return sorted(out, key=lambda e: order.get(e.name, len(order)))
