"""Motion regimes of the arm, the rest re-reference and the per-sample alarm state.

Our extension of the paper (the user guide's real-robot page: "History at
rest"). Per sample the arm is ``moving`` (some :math:`|\\dot q_\\ell| \\ge
\\sigma_v`), ``settling`` (all still for less than ``settle`` samples since
it stopped; split into stages by the time since the stop,
:data:`SETTLE_STAGES_S`, each a regime of its own), at ``rest`` (still for
longer, or since the stream started) or,
with a braking limit, ``braking`` (for ``hold`` samples after some
:math:`|\\ddot q_\\ell|` exceeds it). At rest the monitoring signal is
re-referenced: at rest entry, or once :math:`|m_\\ell| \\le B_\\ell` has held for
``EVENT_HOLD_S`` after it, :math:`b_\\ell = m_\\ell` (before that,
:math:`b_\\ell = \\mathrm{clip}(m_\\ell, -B_\\ell, B_\\ell)`), then

.. math::

    \\tilde m_{k\\ell} = m_{k\\ell} - b_{k\\ell}, \\qquad
    b_{k+1,\\ell} = b_{k\\ell} + \\beta\\,\\tilde m_{k\\ell}, \\qquad
    \\beta = 1 - e^{-T/\\tau},

so a contact shows in full while the slow relaxation of the current held
after a stop does not. :math:`B_\\ell`, the rest band, is the largest
:math:`|m_\\ell|` at a rest entry of the collision-free recordings, times
their leave-one-recording-out factor (``AlarmRule.rest_band_``): the held
current static friction can leave is taken into the reference; a push that
is on at rest entry beyond that band is not: what exceeds the band shows,
with its own sign, and the reference is taken once the push has let go (no
mirror image at its release). :class:`AlarmState`: one band's per-sample decision,
shared by batch and streaming. :class:`EventHold`: one event per contact, the
same on every path.
"""

import contextlib

import numpy as np

from .._gate import quasi_static

#: Regime names, indexed by the codes of :func:`regime_pass` ("braking" only
#: with a braking limit); words of the package's one vocabulary
#: (``_gate.REGIME_WORDS``), which the features' regimes share.
REGIME_NAMES = ("moving", "settling", "rest", "braking")
MOVING, SETTLING, REST, BRAKING = 0, 1, 2, 3
#: Settling stages [s]: the settling regime splits at each of these times
#: since the stop that is shorter than the settle time, each stage with its
#: own thresholds (the current rings after a stop and fades: one threshold
#: set by the first tenths of a second would cover the last seconds too).
SETTLE_STAGES_S = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0)



def stage_name(start):
    """Name of the settling stage that starts ``start`` seconds after the stop."""
    return f"settling after {start:g} s"


def settle_stages(settle_time):
    """Start [s] of each settling stage after the first, for ``settle_time``.

    Examples
    --------
    >>> settle_stages(3.0)
    (0.25, 0.5, 1.0, 2.0)
    """
    return tuple(t for t in SETTLE_STAGES_S if t < settle_time)


_TINY = np.finfo(float).tiny
_NO_CONTEXT = contextlib.nullcontext()

#: Release level of an event (ratio of the signal to its threshold).
RELEASE = 0.5
#: Seconds below the release level that end an event.
EVENT_HOLD_S = 0.2


class EventHold:
    """One event per contact: open at an alarm, closed after a hold below release.

    An event opens where some joint's ratio (signal over threshold) exceeds
    1 and stays open while the largest ratio is above ``RELEASE`` or has
    been below it for fewer than ``hold`` samples: a contact whose signal
    dips under the threshold for a moment is one event, and the next
    contact, which starts from below the release level, is another
    (hysteresis and a hold time).

    A second contact can start before the first has let go (a push while
    the tail of the one before is still above release). A new alarm, after
    ``hold`` samples where no joint alarmed, on a joint that has not fired
    in the open event and is *quiet* (below the release level for ``hold``
    samples since it last alarmed) is the onset of a new event even while
    one is open: the new contact loads joints the open one did not. A
    contact whose alarm moves from joint to joint within the hold, or whose
    own joints ring again as the arm recovers, stays one event.

    Parameters
    ----------
    hold : int
        Samples below release that end an event (and that let a joint go).

    Attributes
    ----------
    open : bool
        Whether an event is open after the last sample.
    onset : bool
        Whether an event began at the last sample (a new one, or a new
        contact while one was open).

    Examples
    --------
    >>> hold = EventHold(3)
    >>> ratios = [0.2, 1.3, 0.8, 1.1, 0.4, 0.3, 0.2, 0.1, 1.2, 0.1]
    >>> [int(hold.step(r)) for r in ratios]
    [0, 1, 1, 1, 1, 1, 0, 0, 1, 1]

    Two joints: joint 2 alarms while joint 1's contact still holds the event
    open above release, after joint 2 had let go: a second event.

    >>> hold = EventHold(2)
    >>> rows = [(1.5, 0.0), (0.7, 0.1), (0.7, 0.1), (0.6, 1.4), (0.6, 1.6)]
    >>> [(int(hold.step(r)), int(hold.onset)) for r in rows]
    [(1, 1), (1, 0), (1, 0), (1, 1), (1, 0)]

    Within the hold of the last alarm, or on a joint the event fired, the
    same contact:

    >>> hold = EventHold(2)
    >>> rows = [(1.5, 0.0), (0.7, 0.1), (0.6, 1.4)]
    >>> [(int(hold.step(r)), int(hold.onset)) for r in rows]
    [(1, 1), (1, 0), (1, 0)]
    >>> hold = EventHold(2)
    >>> rows = [(1.5, 0.0), (0.1, 0.7), (0.1, 0.7), (1.2, 0.7)]
    >>> [(int(hold.step(r)), int(hold.onset)) for r in rows]
    [(1, 1), (1, 0), (1, 0), (1, 0)]
    """

    def __init__(self, hold):
        self.hold = int(hold)
        self.open = False
        self.onset = False
        self._below = 0
        self._since_alarm = 0   # samples since some joint last alarmed
        self._quiet = None      # per joint, samples in a row at or below release
        self._released = None   # per joint, let go since it last alarmed
        self._fired = None      # per joint, fired in the open event

    def step(self, ratio, restart=False):
        """One sample's ``ratio`` (per joint, or one number); ``restart``
        closes any open event first.

        Returns
        -------
        open : bool
        """
        r = np.asarray(ratio, dtype=float).ravel().tolist()
        if restart or self._quiet is None or len(self._quiet) != len(r):
            self.open, self._below, self._since_alarm = False, 0, 0
            self._quiet = [0] * len(r)
            self._released = [True] * len(r)
            self._fired = [False] * len(r)
        alarm = [x > 1.0 for x in r]
        any_alarm = any(alarm)
        self.onset = False
        if any_alarm:
            self.onset = not self.open or (self._since_alarm >= self.hold and any(
                a and q and not f for a, q, f in zip(alarm, self._released, self._fired)))
            if self.onset:
                self._fired = [False] * len(r)
            self.open, self._below = True, 0
            self._fired = [f or a for f, a in zip(self._fired, alarm)]
        elif self.open:
            self._below = self._below + 1 if max(r) <= RELEASE else 0
            if self._below >= self.hold:
                self.open, self._below = False, 0
        self._quiet = [n + 1 if x <= RELEASE else 0 for n, x in zip(self._quiet, r)]
        self._released = [(q or n >= self.hold) and not a
                          for q, n, a in zip(self._released, self._quiet, alarm)]
        self._since_alarm = 0 if any_alarm else self._since_alarm + 1
        return self.open


def ratio_over_level(bands):
    """Per joint, each band's ratio over its level, the largest over the bands.

    Above 1 where a band alarms: what :class:`EventHold` holds an event on.
    ``bands``: objects with ``ratio`` (per joint, or rows x joints) and
    ``level`` (the detector's stages, or a streaming monitor's bands).
    """
    out = None
    for band in bands:
        level = max(float(band.level), _TINY)
        with np.errstate(over="ignore") if level < 1.0 else _NO_CONTEXT:
            ratio = np.asarray(band.ratio, dtype=float) / level   # inf past a tiny level
        out = ratio if out is None else np.maximum(out, ratio)
    return out


def event_rows(ratio, starts, hold):
    """:class:`EventHold` over a batch, restarting at every segment start.

    ``ratio``: (n,) or (n, n_joints) the signal over its threshold (1: the
    threshold); returns the rows of an open event and the rows where an
    event begins (both bool, (n,)).
    """
    events = EventHold(hold)
    n = len(ratio)
    restart = np.zeros(n, dtype=bool)
    restart[np.asarray(starts, dtype=np.intp)] = True
    rows, onsets = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    for k, (r, s) in enumerate(zip(np.asarray(ratio, dtype=float).tolist(), restart.tolist())):
        rows[k] = events.step(r, s)
        onsets[k] = events.onset
    return rows, onsets


class RegimeState:
    """Regime of the arm and rest reference, carried from sample to sample.

    ``sigma_v`` [rad/s]: a joint below it is still; ``settle``: samples
    still after a motion before rest; ``beta``: the tracker gain ``1 -
    exp(-T / tau)`` (0: a fixed reference, None: no re-reference);
    ``brake_limit`` [rad/s^2]: the arm brakes above it, and ``brake_hold``
    samples more (None: no braking regime; with a limit, :meth:`step` reads
    the accelerations after the velocities); ``alarm_hold``: samples at most
    that an alarm holds the regime of its onset (0: no hold); ``rest_band``:
    per joint, the largest reference taken at rest entry (None: no bound);
    ``entry_hold``: samples within the band before a joint that entered rest
    beyond it takes its reference; ``stages``: ``(samples, code)`` pairs in
    increasing order, a settling sample still for more than ``samples`` has
    that regime code (the settling stages; empty: one settling regime).
    """

    def __init__(self, sigma_v, settle, beta, n_joints, brake_limit=None, brake_hold=0,
                 alarm_hold=0, rest_band=None, entry_hold=0, stages=()):
        self.sigma_v = float(sigma_v)
        self.settle = int(settle)
        self.stages = tuple((int(samples), int(code)) for samples, code in stages)
        self.beta = beta
        self.n_joints = int(n_joints)
        self.brake_limit = None if brake_limit is None else float(brake_limit)
        self.brake_hold = int(brake_hold)
        self.alarm_hold = int(alarm_hold)
        self.rest_band = None if rest_band is None else np.asarray(rest_band, dtype=float)
        self.entry_hold = int(entry_hold)
        self.reference = np.zeros(n_joints)
        self._taken = np.zeros(n_joints, dtype=bool)
        self._inside_for = np.zeros(n_joints, dtype=np.intp)
        self._step = np.zeros(n_joints)
        self.reset()

    def reset(self):
        """A new stream: no motion seen yet, no reference."""
        self._still_for = 0
        self._moved = False
        self._referenced = False
        self._braking_for = 0
        self._held_for = 0
        self.reference[:] = 0.0

    def braking(self, qdd):
        """Advance the braking counter with one acceleration row; True while braking
        (a sample with some ``|qdd_l| > brake_limit`` and the ``brake_hold`` after it)."""
        limit = self.brake_limit
        if any([abs(a) > limit for a in qdd.tolist()]):
            self._braking_for = self.brake_hold + 1
        if self._braking_for:
            self._braking_for -= 1
            return True
        return False

    def regime(self, qd):
        """Advance the still-counter with one velocity row; the regime code
        among moving, the settling stages and rest."""
        sigma_v = self.sigma_v  # per joint on floats: no array call on a few values
        if all([quasi_static(v, sigma_v) for v in qd.tolist()]):
            self._still_for += 1
            if not self._moved or self._still_for > self.settle:
                return REST
            code = SETTLING
            for samples, stage in self.stages:
                if self._still_for <= samples:
                    break
                code = stage
            return code
        self._still_for = 0
        self._moved = True
        return MOVING

    def step(self, motion, signal, hold=None):
        """Regime of one sample (``motion``: velocities, then accelerations with a
        braking limit); ``signal`` is re-referenced in place at rest.

        Braking overrides the others for the thresholds only: the rest
        reference follows the motion regimes. **A contact never relaxes its
        own threshold**: while the band is in alarm the caller passes the
        regime of the alarm's onset as ``hold``, returned (at rest the
        reference subtracted, not tracked) for ``alarm_hold`` samples at most
        while the counters advance.
        """
        n = self.n_joints
        regime = self.regime(motion[:n])
        braking = self.brake_limit is not None and self.braking(motion[n:])
        self._held_for = self._held_for + 1 if hold is not None else 0
        if hold is not None and self._held_for <= self.alarm_hold:
            if hold == REST and self._referenced:
                if not self._taken.all():
                    self._take(signal)
                np.subtract(signal, self.reference, out=signal)
            return hold
        self._reference(regime, signal)
        return BRAKING if braking else regime

    def _reference(self, regime, signal):
        """Re-reference ``signal`` in place at rest (Eq. above), track ``b``."""
        if self.beta is None:
            return
        if regime != REST:
            self._referenced = False
            self.reference[:] = 0.0
            return
        if not self._referenced:
            self._taken[:] = False
            self._inside_for[:] = self.entry_hold  # at entry: in band, taken at once
            self._referenced = True
        if self._taken.all():
            np.subtract(signal, self.reference, out=signal)  # m~ = m - b
            np.multiply(signal, self.beta, out=self._step)
            self.reference += self._step  # b += beta m~
            return
        self._take(signal)
        np.subtract(signal, self.reference, out=signal)
        self.reference[self._taken] += self.beta * signal[self._taken]

    def _take(self, signal):
        """Take ``b_l = m_l`` for each joint not yet referenced once ``|m_l| <= B_l``
        for ``entry_hold`` samples (a push letting go has passed); until then
        ``b_l`` is the nearest value static friction can hold (the excess shows,
        with its sign)."""
        new = ~self._taken
        if self.rest_band is None:
            take = new
        else:
            inside = np.abs(signal) <= self.rest_band
            self._inside_for = np.where(new & inside, self._inside_for + 1, 0)
            take = new & (self._inside_for > self.entry_hold)
        self.reference[take] = signal[take]
        self._taken |= take
        wait = new & ~take
        if wait.any():
            self.reference[wait] = np.clip(signal[wait], -self.rest_band[wait],
                                           self.rest_band[wait])


def regime_pass(signal, motion, starts, sigma_v, settle, beta, brake_limit=None,
                brake_hold=0, alarm_hold=0, rest_band=None, entry_hold=0, stages=()):
    """:class:`RegimeState` over a batch, restarting at every segment start.

    Returns ``(referenced, regimes, reference)``: a copy of the signal
    re-referenced at rest, the regime codes and the reference subtracted (0
    outside rest). No alarm, so ``alarm_hold`` is not used.
    """
    settings = dict(sigma_v=sigma_v, settle=settle, beta=beta, brake_limit=brake_limit,
                    brake_hold=brake_hold, alarm_hold=alarm_hold, rest_band=rest_band,
                    entry_hold=entry_hold, stages=stages)
    out = np.array(signal, dtype=float, copy=True)
    regimes = np.empty(signal.shape[0], dtype=np.intp)
    bounds = np.append(starts, signal.shape[0])
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        state = RegimeState(n_joints=signal.shape[1], **settings)
        for k in range(lo, hi):
            regimes[k] = state.step(motion[k], out[k])
    return out, regimes, signal - out


def rest_entry_peaks(reference, regimes, starts):
    """Largest ``|b_l|`` taken at a rest entry, per recording: (n_recordings, n_joints).

    ``reference``, ``regimes``: those of :func:`regime_pass`; ``starts``: the
    recordings' first rows. A recording with no rest entry gives zeros.
    """
    rest = regimes == REST
    entry = rest & ~np.r_[False, rest[:-1]]
    entry[np.asarray(starts, dtype=np.intp)] = rest[np.asarray(starts, dtype=np.intp)]
    bounds = np.append(starts, len(regimes))
    out = np.zeros((len(starts), reference.shape[1]))
    for r, (lo, hi) in enumerate(zip(bounds[:-1], bounds[1:])):
        rows = np.flatnonzero(entry[lo:hi]) + lo
        if rows.size:
            out[r] = np.abs(reference[rows]).max(axis=0)
    return out


class AlarmState:
    """One band's decision, sample by sample: the state batch and streaming share.

    Per sample: the regime (:class:`RegimeState` with ``settings``, None: no
    regimes), the debounce over the last ``min_duration`` samples (a ring),
    the ratio to the regime's scale, and the joints above ``level``. While
    an alarm lasts its regime is frozen; it ends at the first sample at or
    below the level. A sample allocates no array.
    """

    def __init__(self, n_joints, settings, scales, level, min_duration):
        self.regimes = None if settings is None else RegimeState(n_joints=n_joints, **settings)
        self.scales = np.atleast_2d(np.asarray(scales, dtype=float))
        self.level = float(level)
        self.window = np.zeros((min_duration, n_joints))
        self.ratio = np.full(n_joints, np.nan)
        self.alarms = np.zeros(n_joints, dtype=bool)
        self._bind()
        self.reset()

    def __getstate__(self):
        return {k: v for k, v in self.__dict__.items() if k not in ("_rows", "_scale_rows")}

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._bind()

    def _bind(self):
        """Row views of the ring and the scales (rebuilt on load: a pickle copies views)."""
        self._rows, self._scale_rows = list(self.window), list(self.scales)

    def reset(self):
        """A new stream: no regime, debounce or alarm history."""
        self.window[:] = 0.0
        self.position, self.regime = 0, 0
        self.clear()
        if self.regimes is not None:
            self.regimes.reset()

    def clear(self):
        """No alarm (a new stream, or a rejected sample)."""
        self.alarms[:] = False
        self.alarmed = False

    def step(self, signal, motion):
        """One sample; returns the largest ratio over the joints.

        ``signal`` (the filtered residual) is re-referenced in place at rest.
        """
        if self.regimes is not None:
            self.regime = self.regimes.step(motion, signal,
                                            self.regime if self.alarmed else None)
        np.abs(signal, out=self._rows[self.position])
        self.position = (self.position + 1) % len(self._rows)
        np.minimum.reduce(self.window, axis=0, out=self.ratio)
        self.ratio /= self._scale_rows[self.regime]
        top = max(self.ratio.tolist())
        if top > self.level:
            np.greater(self.ratio, self.level, out=self.alarms)
            self.alarmed = True
        elif self.alarmed:
            self.clear()
        return top


def held_regime_pass(signal, motion, settings, scales, level, min_duration):
    """:class:`AlarmState` over one segment, as a streaming monitor runs it.

    Returns those of :func:`regime_pass`, then ``ratio`` (debounced ``|m|``
    over the scale of each sample's regime) and ``alarms`` (bool, joints in
    alarm).
    """
    out = np.array(signal, dtype=float, copy=True)
    regimes = np.empty(signal.shape[0], dtype=np.intp)
    ratio = np.empty_like(out)
    alarms = np.zeros(signal.shape, dtype=bool)
    state = AlarmState(signal.shape[1], settings, scales, level, min_duration)
    for k in range(signal.shape[0]):
        state.step(out[k], motion[k])
        regimes[k], ratio[k], alarms[k] = state.regime, state.ratio, state.alarms
    return out, regimes, signal - out, ratio, alarms
