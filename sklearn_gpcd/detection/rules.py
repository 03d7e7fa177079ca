"""Alarm rules: from the current residual to alarms (paper Sec. II-III).

An :class:`AlarmRule` turns the residual :math:`s_l = i_l - \\hat i_l` of a
:class:`~sklearn_gpcd.detection.CollisionDetector` into alarms:

1. **signal** -- the residual (normalised where the detector asks so),
   low-pass filtered (the moving-phase residual is high-frequency, Sec.
   IV-C) and, with :class:`Regimes`, re-referenced at rest: :math:`m_l`;
2. **ratio** -- :math:`r_l = \\tilde m_l / \\text{scale}_{g l}`, with
   :math:`\\tilde m_l` the smallest :math:`|m_l|` over the last
   ``min_duration`` samples and :math:`g` the sample's regime;
3. **alarm** -- joint :math:`l` fires when :math:`r_l > \\gamma` (the
   paper's :math:`f_{CD}`, Sec. II, :math:`\\sigma_{CD,l} =
   \\gamma\\,\\text{scale}_l`).

:meth:`AlarmRule.calibrate` sets ``scale_`` and :math:`\\gamma` from
collision-free residuals. Several rules on one residual model are several
*bands*; the detector alarms when any does.
"""

from numbers import Integral, Real

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.utils._param_validation import Interval, Options, StrOptions

from .._gate import DEFAULT_SIGMA_V
from ._regime_batch import batch_regime_pass
from ._regimes import (BRAKING, EVENT_HOLD_S, REGIME_NAMES, SETTLING, held_regime_pass,
                       rest_entry_peaks, settle_stages, stage_name)
from ._signal import filter_segments, lowpass_coefficients, segment_starts, window_segments
from ._thresholds import (
    contamination_level,
    fading_stages,
    false_alarm_level,
    fill_absent_regimes,
    loro_factors,
    recording_peaks,
    rest_band,
    rms_scale,
)

__all__ = ["THRESHOLD_RULES", "AlarmRule", "Regimes"]

#: The rules that set the thresholds (``AlarmRule(threshold=...)``).
THRESHOLD_RULES = ("contamination", "false_alarm_rate", "per_joint", "std")


class Regimes(BaseEstimator):
    """Separate thresholds for the arm's motion regimes, and the rest re-reference.

    The residual of a still arm is small and slow, that of a moving one
    large and fast: one band for both is blind at rest or noisy in motion.
    Per sample the arm is ``moving``, ``settling`` (still for less than
    ``settle_time``) or at ``rest``, by the detector's :math:`\\sigma_v` on
    the joint velocities, or ``braking`` (with ``brake_limit``). Settling
    is split into stages by the time since the stop (``"settling after
    0.25 s"``, 0.5, 1, 2, 4, 8 s, those shorter than ``settle_time``), each
    with its own thresholds: the current rings after a stop and fades, so a
    push seconds after a stop is judged against the fading ring, not its
    first tenths of a second. Our extension of the paper.

    Parameters
    ----------
    settle_time : float, default=0.5
        Seconds the arm must be still after a motion before it is at rest.
    rest_reference : float or None, default=None
        Re-reference the monitoring signal at rest entry, the reference
        following it with this time constant [s] (``numpy.inf``: fixed). It
        removes the history-dependent offset of a still joint's held current
        (stiction), which no pose feature predicts.
    brake_limit : float or None, default=None
        A fourth regime, ``braking``, with its own thresholds, from a sample
        where some joint's acceleration exceeds it [rad/s^2] (hard stops ring
        the current for about half a second). Set it to the largest
        acceleration the model was trained on (``training["acceleration_limit"]``
        of :func:`~sklearn_gpcd.workflow.train_model`). Needs the ``qdd``
        block of the paper's layout among the inputs.
    brake_hold : float, default=0.5
        Seconds the braking regime lasts after the last sample above
        ``brake_limit``.
    alarm_hold : float, default=1.0
        Seconds at most that an alarm holds the regime (and rest reference)
        of its onset: a push that moves a still arm is judged at the rest
        thresholds while it lasts. 0: no hold. (A contact whose force dips
        below the threshold for a moment is one *event*:
        :class:`~sklearn_gpcd.detection.EventHold`, on every path.)

    Attributes
    ----------
    names : tuple of str
        The regimes in use, indexed by their codes: moving, settling (its
        first stage), rest, braking (with a braking limit), then the later
        settling stages.

    Examples
    --------
    >>> from sklearn_gpcd.detection import Regimes
    >>> Regimes(brake_limit=5.0).names
    ('moving', 'settling', 'rest', 'braking', 'settling after 0.25 s')
    >>> Regimes(settle_time=0.2).names
    ('moving', 'settling', 'rest')
    """

    _parameter_constraints = {
        "settle_time": [Interval(Real, 0, None, closed="left")],
        "rest_reference": [None, Interval(Real, 0, None, closed="neither"),
                           Options(Real, {np.inf})],
        "brake_limit": [None, Interval(Real, 0, None, closed="neither")],
        "brake_hold": [Interval(Real, 0, None, closed="left")],
        "alarm_hold": [Interval(Real, 0, None, closed="left")],
    }

    def __init__(self, settle_time=0.5, rest_reference=None, brake_limit=None, brake_hold=0.5,
                 alarm_hold=1.0):
        self.settle_time = settle_time
        self.rest_reference = rest_reference
        self.brake_limit = brake_limit
        self.brake_hold = brake_hold
        self.alarm_hold = alarm_hold

    @property
    def names(self):
        base = REGIME_NAMES if self.brake_limit is not None else REGIME_NAMES[:BRAKING]
        return base + tuple(stage_name(t) for t in settle_stages(self.settle_time))

    @property
    def reads_accelerations(self):
        """Whether the regimes read the joint accelerations (braking)."""
        return self.brake_limit is not None


class AlarmRule(BaseEstimator):
    """Filter, debounce, regimes and thresholds: how a residual becomes alarms.

    Joint ``l`` fires when its monitoring signal leaves the band,
    :math:`|m_l| > \\sigma_{CD,l}` for ``min_duration`` consecutive samples
    (the paper's :math:`f_{CD}`, Sec. II). Fitted by :meth:`calibrate` on the
    residuals of collision-free rows (a
    :class:`~sklearn_gpcd.detection.CollisionDetector` does it in ``fit``).

    Parameters
    ----------
    threshold : {"contamination", "false_alarm_rate", "per_joint", "std"}, \
            default="contamination"
        Rule that sets :math:`\\sigma_{CD}` from the calibration residuals:

        - ``"contamination"``: ``scale_`` is the RMS of each joint's signal,
          the level flags the fraction ``contamination`` of the calibration
          samples (IsolationForest convention);
        - ``"false_alarm_rate"``: same scale, the smallest level whose alarm
          onsets stay within ``false_alarm_rate`` per hour;
        - ``"per_joint"``: a level per joint (and regime), each the smallest
          whose onsets stay within an equal share of ``false_alarm_rate``,
          times ``margin``;
        - ``"std"``: ``k`` predictive standard deviations (with
          ``normalize="std"`` the band follows :math:`\\sigma_l(x)`).
    contamination : float in (0, 0.5], default=0.001
        Fraction of calibration samples flagged by ``"contamination"``.
    false_alarm_rate : float >= 0, default=1.0
        Alarm onsets per hour allowed on the calibration data.
    k : float > 0, default=3.0
        Band width in predictive standard deviations, for ``"std"``.
    margin : float >= 1, array-like or "loro", default=1.0
        Factor on the levels of ``"per_joint"``: a scalar, one per joint or
        per regime and joint; ``"loro"`` learns it by leaving one recording
        out (:func:`~sklearn_gpcd.detection.loro_margin`).
    filter_cutoff : float or None, default=None
        Cut-off frequency [Hz] of the causal low-pass filter (None: none).
    filter_order : {1, 2}, default=1
        First-order lag or second-order Butterworth filter.
    min_duration : int, default=1
        Samples the band must be exceeded in a row before a joint fires.
    regimes : Regimes or None, default=None
        Separate thresholds per motion regime of the arm (and the rest
        re-reference); None: one threshold per joint.

    Attributes
    ----------
    sample_time_ : float
        Sampling period [s] the rule was calibrated at.
    sigma_v_ : float or None
        Velocity threshold the regimes use (None: the default 1e-2).
    filter_coefficients_ : tuple of ndarray or None
        ``(b, a)`` of the low-pass filter.
    regime_names_ : tuple of str
        Rows of ``scale_`` / ``thresholds_`` (``("all",)`` without regimes).
    scale_ : ndarray of shape (n_joints,) or (n_regimes, n_joints)
        Per-joint scale of the monitoring signal.
    margin_ : ndarray of the shape of ``scale_``
        Margin applied to the levels (1 for rules other than ``"per_joint"``).
    offset_ : float
        :math:`-\\gamma`: a joint fires when ``ratio > -offset_``.
    thresholds_ : ndarray of the shape of ``scale_``
        :math:`\\sigma_{CD}` per joint (and regime) in units of the signal.
    rest_band_ : ndarray of shape (n_joints,) or None
        The rest band :math:`B_\\ell`: the largest reference a joint takes at
        rest entry (:meth:`learn_rest_band`; None without a rest reference or
        with fewer than 2 recordings that enter rest).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.detection import AlarmRule
    >>> rng = np.random.default_rng(0)
    >>> residual = 0.1 * rng.normal(size=(1000, 2))
    >>> rule = AlarmRule("false_alarm_rate", false_alarm_rate=0.0, min_duration=3)
    >>> rule = rule.calibrate(residual, sample_time=0.01)
    >>> bool(rule.stages(residual)["alarms"].any())     # no alarm on its own data
    False
    >>> residual[500:520, 1] += 1.0                       # a push on joint 2
    >>> rule.stages(residual)["alarms"][:, 1].nonzero()[0][:1].tolist()
    [502]
    """

    _parameter_constraints = {
        "threshold": [StrOptions(set(THRESHOLD_RULES))],
        "contamination": [Interval(Real, 0, 0.5, closed="right")],
        "false_alarm_rate": [Interval(Real, 0, None, closed="left")],
        "k": [Interval(Real, 0, None, closed="neither")],
        "margin": [StrOptions({"loro"}), Interval(Real, 1, None, closed="left"), "array-like"],
        "filter_cutoff": [None, Interval(Real, 0, None, closed="neither")],
        "filter_order": [Options(Integral, {1, 2})],
        "min_duration": [Interval(Integral, 1, None, closed="left")],
        "regimes": [None, Regimes],
    }

    def __init__(self, threshold="contamination", *, contamination=0.001, false_alarm_rate=1.0,
                 k=3.0, margin=1.0, filter_cutoff=None, filter_order=1, min_duration=1,
                 regimes=None):
        self.threshold = threshold
        self.contamination = contamination
        self.false_alarm_rate = false_alarm_rate
        self.k = k
        self.margin = margin
        self.filter_cutoff = filter_cutoff
        self.filter_order = filter_order
        self.min_duration = min_duration
        self.regimes = regimes

    # ------------------------------------------------------------ checks
    def check(self):
        """Check the parameters (and those of ``regimes``); return self.

        Raises
        ------
        ValueError
            A parameter out of its range, ``margin="loro"`` without
            ``threshold="per_joint"``, or regimes with ``threshold="std"``.
        """
        self._validate_params()
        if self.regimes is not None:
            self.regimes._validate_params()
            if self.threshold == "std":
                raise ValueError("AlarmRule: regimes cannot be combined with threshold='std'")
        loro = isinstance(self.margin, str)  # the only string the constraints allow
        if (self.threshold != "per_joint") if loro else not _valid_margin(self.margin):
            raise ValueError("AlarmRule: margin must be a float >= 1, an array of floats >= 1 "
                             f"or 'loro' (with threshold='per_joint'), got {self.margin!r}")
        return self

    @property
    def needs_std(self):
        """Whether :meth:`calibrate` reads the predictive std (``threshold="std"``)."""
        return self.threshold == "std"

    # ------------------------------------------------------------ stages
    def prepare(self, sample_time, sigma_v=None):
        """Set ``sample_time_``, ``sigma_v_``, ``filter_coefficients_`` and
        ``regime_names_``: what :meth:`signal` needs before calibration.

        Parameters
        ----------
        sample_time : float
            Sampling period [s].
        sigma_v : float or None, default=None
            Velocity threshold of the regimes [rad/s] (None: 1e-2).

        Returns
        -------
        self : AlarmRule
        """
        self.check()
        self.sample_time_ = float(sample_time)
        self.sigma_v_ = sigma_v
        self.filter_coefficients_ = None
        if self.filter_cutoff is not None:
            self.filter_coefficients_ = lowpass_coefficients(
                self.filter_cutoff, self.sample_time_, self.filter_order)
        self.regime_names_ = self.regimes.names if self.regimes is not None else ("all",)
        self.rest_band_ = None
        return self

    def regime_settings(self):
        """Keyword arguments of the regime pass (None without regimes).

        Returns
        -------
        settings : dict or None
            ``sigma_v`` (``DEFAULT_SIGMA_V`` when the detector gives none); ``settle``,
            ``brake_hold`` and ``alarm_hold`` in samples; ``beta`` (the rest
            reference's smoothing factor, None without it), ``brake_limit``,
            ``rest_band`` (``rest_band_``), ``entry_hold`` (samples of
            ``EVENT_HOLD_S``) and ``stages`` (the settling stages among
            ``regime_names_``: samples since the stop, regime code).
        """
        regimes, dt = self.regimes, self.sample_time_
        if regimes is None:
            return None
        beta = None
        if regimes.rest_reference is not None:
            beta = float(-np.expm1(-dt / regimes.rest_reference))
        return {
            "sigma_v": DEFAULT_SIGMA_V if self.sigma_v_ is None else float(self.sigma_v_),
            "settle": int(round(regimes.settle_time / dt)),
            "beta": beta,
            "brake_limit": regimes.brake_limit,
            "brake_hold": int(round(regimes.brake_hold / dt)),
            "alarm_hold": int(round(regimes.alarm_hold / dt)),
            # files saved before the rest band have none: no bound, as they were
            "rest_band": getattr(self, "rest_band_", None),
            "entry_hold": self.event_hold_samples(),
            "stages": self._stages(),
        }

    def settling_rows(self):
        """Rows of the settling stages in ``regime_names_``, in time order
        (``"settling"``, then ``"settling after 0.25 s"``, ...); empty without
        regimes.

        Returns
        -------
        rows : tuple of int

        Examples
        --------
        >>> from sklearn_gpcd.detection import AlarmRule, Regimes
        >>> rule = AlarmRule(regimes=Regimes(settle_time=1.0)).prepare(0.01)
        >>> rule.regime_names_
        ('moving', 'settling', 'rest', 'settling after 0.25 s', 'settling after 0.5 s')
        >>> rule.settling_rows()
        (1, 3, 4)
        """
        if self.regimes is None:
            return ()
        return (SETTLING,) + tuple(code for _, code in self._stages())

    def since_stop(self):
        """Each regime's time window after the arm stops [s], in ``regime_names_``'s order.

        ``(start, end)`` for the settling stages and rest (``end`` is inf for
        rest), None for moving and braking: what lets thresholds of rules
        with other settle times be compared time for time.

        Returns
        -------
        windows : list of tuple or None
            Empty without regimes.

        Examples
        --------
        >>> from sklearn_gpcd.detection import AlarmRule, Regimes
        >>> rule = AlarmRule(regimes=Regimes(settle_time=0.5)).prepare(0.01)
        >>> dict(zip(rule.regime_names_, rule.since_stop()))
        {'moving': None, 'settling': (0.0, 0.25), 'rest': (0.5, inf), \
'settling after 0.25 s': (0.25, 0.5)}
        """
        if self.regimes is None:
            return []
        settle = float(self.regimes.settle_time)
        starts = [0.0, *self._stage_starts()]
        ends = starts[1:] + [settle]
        windows = [None] * len(self.regime_names_)
        for row, start, end in zip(self.settling_rows(), starts, ends):
            windows[row] = (start, end)
        windows[self.regime_names_.index("rest")] = (settle, float("inf"))
        return windows

    def _stage_starts(self):
        """Start [s] after the stop of each settling stage after the first among
        ``regime_names_`` (files saved before the stages have none: one
        settling regime, as they were)."""
        return tuple(t for t in settle_stages(self.regimes.settle_time)
                     if stage_name(t) in self.regime_names_)

    def _stages(self):
        """``(samples, code)`` of each settling stage after the first
        (:meth:`_stage_starts`)."""
        names, dt = self.regime_names_, self.sample_time_
        return tuple((int(round(t / dt)), names.index(stage_name(t)))
                     for t in self._stage_starts())

    def signal(self, u, starts=None, motion=None):
        """Monitoring signal :math:`m`, regime codes and rest reference, without
        the alarm hold of :meth:`stages`: what calibration reads.

        Parameters
        ----------
        u : ndarray of shape (n_samples, n_joints)
            The residual, normalised by the detector where it asks so.
        starts : ndarray of int, default=None
            Rows where a new recording begins (None: one recording).
        motion : ndarray of shape (n_samples, n_motion), default=None
            Joint velocities, then accelerations where the regimes read them.

        Returns
        -------
        signal : ndarray of shape (n_samples, n_joints)
        regime : ndarray of int of shape (n_samples,)
            All 0 without regimes.
        reference : ndarray or None
            Rest reference subtracted (None without regimes).
        """
        starts = _starts(u, starts)
        u = self._filtered(u, starts)
        if self.regimes is None:
            return u, np.zeros(u.shape[0], dtype=np.intp), None
        return batch_regime_pass(u, self._motion(motion), starts, **self.regime_settings())

    def _filtered(self, u, starts):
        if self.filter_coefficients_ is None:
            return u
        return filter_segments(u, *self.filter_coefficients_, starts)

    @staticmethod
    def _motion(motion):
        if motion is None:
            raise ValueError("an AlarmRule with regimes needs the joint velocities (motion)")
        return motion

    def debounced(self, signal, starts=None):
        """:math:`\\tilde m`: the smallest ``|m|`` over the last ``min_duration`` samples.

        Parameters
        ----------
        signal : ndarray of shape (n_samples, n_joints)
        starts : ndarray of int, default=None
            As for :meth:`signal`.

        Returns
        -------
        debounced : ndarray of shape (n_samples, n_joints)
        """
        return window_segments(np.abs(signal), self.min_duration, _starts(signal, starts), np.min,
                               pad=0.0)

    def _ratio(self, signal, regime, starts=None):
        """Debounced ``|m|`` over the scale of each sample's regime."""
        return self.debounced(signal, starts) / np.atleast_2d(self.scale_)[regime]

    def stages(self, u, starts=None, motion=None):
        """Every stage from the residual to the alarms.

        With regimes, the regime of an alarm's onset is held while it lasts
        (a contact never relaxes its own threshold): the recordings with an
        alarm run again sample by sample, as a streaming monitor runs.

        Parameters
        ----------
        u, starts, motion
            As for :meth:`signal`.

        Returns
        -------
        stages : dict
            ``signal``, ``regime``, ``reference``, ``ratio`` and ``alarms``
            (bool, joints that fired).
        """
        starts = _starts(u, starts)
        signal, regime, reference = self.signal(u, starts, motion)
        ratio = self._ratio(signal, regime, starts)
        level = -self.offset_
        alarms = ratio > level
        if self.regimes is not None and alarms.any():
            signal, regime, reference, ratio, alarms = self._held(
                u, starts, motion, alarms, (signal, regime, reference, ratio, alarms))
        return {"signal": signal, "regime": regime, "reference": reference, "ratio": ratio,
                "alarms": alarms}

    def _held(self, u, starts, motion, alarms, stages):
        """``stages`` (signal, regime, reference, ratio, alarms) with the segments
        that alarm run again with the alarm hold and release."""
        signal, regime, reference, ratio, held = (np.array(a, copy=True) for a in stages)
        filtered, motion = self._filtered(u, starts), self._motion(motion)
        scales = np.atleast_2d(self.scale_)
        bounds = np.append(starts, len(u))
        for lo, hi in zip(bounds[:-1], bounds[1:]):
            if not alarms[lo:hi].any():
                continue
            rows = slice(lo, hi)
            (signal[rows], regime[rows], reference[rows], ratio[rows],
             held[rows]) = held_regime_pass(
                filtered[rows], motion[rows], self.regime_settings(), scales, -self.offset_,
                self.min_duration)
        return signal, regime, reference, ratio, held

    def event_hold_samples(self):
        """Samples below the release level that end a contact event (``EVENT_HOLD_S``)."""
        return max(1, int(round(EVENT_HOLD_S / self.sample_time_)))

    # ------------------------------------------------------- calibration
    def calibrate(self, u, starts=None, motion=None, *, sample_time, sigma_v=None, std=None,
                  normalized=False, recordings=None):
        """Set the scale, margin and level from collision-free residuals.

        Parameters
        ----------
        u : ndarray of shape (n_samples, n_joints)
            Residual of the collision-free calibration rows (normalised by
            the detector where it asks so).
        starts, motion
            As for :meth:`signal`.
        sample_time, sigma_v
            As for :meth:`prepare`.
        std : ndarray of shape (n_samples, n_joints), default=None
            Predictive std, for ``threshold="std"``.
        normalized : bool, default=False
            Whether ``u`` is the residual over the predictive std (then the
            ``"std"`` rule's scale is 1).
        recordings : ndarray of int of shape (n_samples,), default=None
            Recording index of each row, for ``margin="loro"``.

        Returns
        -------
        self : AlarmRule
        """
        self.prepare(sample_time, sigma_v)
        starts = _starts(u, starts)
        n_joints = u.shape[1]
        signal, regimes, reference = self.signal(u, starts, motion)
        margin = 1.0
        if self.threshold == "std":
            if std is None and not normalized:
                raise ValueError("threshold='std' needs the predictive std")
            self.scale_ = np.ones(n_joints) if normalized else rms_scale(std)
            gamma = float(self.k)
        elif self.threshold == "per_joint":
            debounced = self.debounced(signal, starts)
            levels = fading_stages(self._joint_levels(debounced, regimes, starts),
                                   self.settling_rows())
            margin = self._margin(debounced, regimes, recordings, levels.shape)
            self.scale_ = margin * levels
            gamma = 1.0
        else:
            self.scale_ = self._regime_rows(lambda rows: rms_scale(signal[rows]), regimes,
                                            n_joints)
            peak = self._ratio(signal, regimes, starts).max(axis=1)
            if self.threshold == "contamination":
                gamma = contamination_level(peak, self.contamination)
            else:
                gamma = false_alarm_level(peak, starts, self.sample_time_, self.false_alarm_rate)
        self.margin_ = np.broadcast_to(margin, np.shape(self.scale_)).copy()
        self.offset_ = -gamma
        self.thresholds_ = gamma * self.scale_
        self.learn_rest_band(reference, regimes, starts)
        return self

    def learn_rest_band(self, reference, regimes, starts):
        """Set ``rest_band_`` from a regime pass of collision-free recordings.

        :func:`~sklearn_gpcd.detection._thresholds.rest_band` of the references
        taken at their rest entries (None without a rest reference). The
        factor is at least each recording's peak over the others' largest, so
        no calibration recording is clipped, left out or not: the thresholds
        it calibrated stand.

        Parameters
        ----------
        reference : ndarray of shape (n_samples, n_joints) or None
            The rest reference of :meth:`signal` (None without regimes).
        regimes : ndarray of int of shape (n_samples,)
        starts : ndarray of int
            First row of each recording.

        Returns
        -------
        self : AlarmRule
        """
        self.rest_band_ = None
        if reference is not None and self.regimes.rest_reference is not None:
            self.rest_band_ = rest_band(rest_entry_peaks(reference, regimes, starts))
        return self

    def _margin(self, debounced, regimes, recordings, shape):
        """The given margin, checked against the levels' shape, or the LORO one."""
        n_joints = debounced.shape[1]
        if not isinstance(self.margin, str):  # checked: a string is "loro"
            margin = np.asarray(self.margin, dtype=float)
            if margin.shape not in ((), (n_joints,), shape):
                raise ValueError(
                    f"margin has shape {margin.shape}; expected a scalar, ({n_joints},) "
                    f"or {shape} (regimes x joints)"
                )
            return margin
        n_recordings = 0 if recordings is None else int(recordings.max()) + 1
        if n_recordings < 2:
            raise ValueError(
                "margin='loro' leaves one recording out: pass groups= naming at least 2 "
                f"recordings to fit, got {n_recordings}"
            )
        peaks = fading_stages(
            recording_peaks(debounced, regimes, recordings, len(self.regime_names_)),
            self.settling_rows())
        return loro_factors(peaks, "global").reshape(shape)

    def _regime_rows(self, per_regime, regimes, n_joints):
        """``per_regime(rows)`` for each regime, stacked (one row without regimes); an
        absent regime takes the largest value of the others (no data, no tighter band)."""
        if self.regimes is None:
            return per_regime(slice(None))
        n_rows = len(self.regime_names_)
        table = np.zeros((n_rows, n_joints))
        present = np.zeros(n_rows, dtype=bool)
        for code in range(n_rows):
            rows = regimes == code
            if rows.any():
                table[code], present[code] = per_regime(rows), True
        return fill_absent_regimes(table, present)

    def _joint_levels(self, debounced, regimes, starts):
        """Per joint (and regime) false-alarm levels of the debounced ``|m|``: joint
        ``l``'s level in regime ``g`` is that of its ``|m_l|`` set to zero outside
        ``g``, with an equal share of ``false_alarm_rate`` per joint and regime present."""
        n_joints = debounced.shape[1]
        n_regimes = len(np.unique(regimes)) if self.regimes is not None else 1
        share = self.false_alarm_rate / (n_joints * n_regimes)
        tiny = np.finfo(float).tiny

        def levels(rows):
            out = np.empty(n_joints)
            for joint in range(n_joints):
                peak = np.where(rows, debounced[:, joint], 0.0)
                out[joint] = false_alarm_level(peak, starts, self.sample_time_, share)
            return np.maximum(out, tiny)

        if self.regimes is None:
            return levels(np.ones(debounced.shape[0], dtype=bool))
        return self._regime_rows(levels, regimes, n_joints)


def _starts(u, starts):
    """Segment starts (row indices): the given ones, or one segment."""
    return segment_starts(len(u)) if starts is None else starts


def _valid_margin(margin):
    """A number or an array of numbers, all finite and >= 1."""
    try:
        values = np.asarray(margin, dtype=float)
    except (TypeError, ValueError):
        return False
    return values.size > 0 and bool(np.all(np.isfinite(values) & (values >= 1.0)))
