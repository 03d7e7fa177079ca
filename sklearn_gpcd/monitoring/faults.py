"""The fault state machine of a :class:`~sklearn_gpcd.monitoring.MonitorSession`.

Monitoring, blind, recovering (see :mod:`sklearn_gpcd.monitoring`): the stall
bound, the checks of live time stamps, rejected samples, the fault records,
how the stream ended and the exit status.
"""

import math
import time

#: State of a session whose decisions are those of the detector.
MONITORING = "monitoring"
#: State of a session without a valid decision for longer than the stall bound.
BLIND = "blind"
#: State of a session restarted after a blind period, during its warm-up.
RECOVERING = "recovering"
#: Control periods without a valid decision after which a session is blind.
STALL_PERIODS = 3
#: Shortest stall bound [s] (OS scheduling makes shorter bounds meaningless).
MIN_STALL = 0.02
#: Exit status of a session that was blind at some time or ended abnormally.
FAULT_EXIT_STATUS = 3
#: Fault records kept in full in the report (later ones are only counted).
MAX_FAULT_RECORDS = 1000


def stall_bound(sample_time):
    """Longest time without a valid decision before a session is blind [s].

    ``max(STALL_PERIODS * sample_time, MIN_STALL)``: 3 control periods, or
    20 ms, whichever is larger.

    Parameters
    ----------
    sample_time : float
        Control period [s].

    Returns
    -------
    bound : float

    Examples
    --------
    >>> stall_bound(0.002), stall_bound(0.008), stall_bound(0.1)
    (0.02, 0.024, 0.30000000000000004)
    """
    return max(STALL_PERIODS * float(sample_time), MIN_STALL)


class _FaultStates:
    """The states of a session: stamp checks, rejected samples, faults, the end."""

    def _check_stamp(self, t, received):
        """Why a live sample's time stamp is stale (None if it may go to the monitor).

        A jump back or forward by more than the stall bound from the
        previous sample's stamp is a fault of its own (the monitor restarts
        on the new clock at once); a stamp that is not after the last valid
        one (frozen, repeated, out of order) is rejected here, so that no
        monitor reset lets it through.
        """
        previous, before = self._prev_stamp, self._prev_received
        if not math.isfinite(t):
            return None  # the monitor rejects it
        self._prev_stamp, self._prev_received = t, received
        if previous is not None and abs(t - previous) > self.stall_timeout:
            step = t - previous
            wall = received - before
            if step < 0 or wall < step - self.stall_timeout:
                self.fault(f"controller clock jumped {step:+.3f} s", kind="clock_jump",
                           received=received)
                last_rel = self._last_rel if self._last_rel is not None else 0.0
                self.t0 = t - (last_rel + max(wall, self.sample_time))  # rel goes on
                self._stat_stamp = None  # a new clock: no samples dropped
            else:
                lost = round(step / self.sample_time) - 1
                self.fault(f"time stamps jump {step:+.3f} s: about {lost} samples lost",
                           kind="gap", received=received)
            self._last_stamp = None  # the monitor restarts on this stamp
            return None
        last = self._last_stamp
        if last is not None and t <= last:
            return f"time stamp {t!r} does not advance (last valid {last!r})"
        return None

    def _rejected(self, reason, received):
        """A live sample that gave no decision; blind when they last too long."""
        self.n_faults += 1
        self._run += 1
        if self.state == BLIND:
            self._lost += 1
            return "sensor_fault"
        waited = received - self._last_ok if self._last_ok is not None else 0.0
        bound = self.stall_timeout - 1e-9  # the bound itself included
        if waited >= bound or self._run * self.sample_time >= bound:
            run = self._run
            self.fault(f"{run} rejected samples in a row ({reason})", kind="rejected",
                       received=received)
            self._lost = run
        return "sensor_fault"

    def _valid_tick(self, rel, t):
        """State after a valid live tick: blind -> recovering -> monitoring."""
        if self.state == BLIND:
            record = self._open_fault
            blind = (self._last_ok - self._blind_since) if self._last_ok is not None else 0.0
            if record is not None:
                record.update(blind_s=blind, samples_lost=self._lost, recovered_s=rel,
                              recovered_stamp=t)
            self.state, self._warm = RECOVERING, 0
            print(f"RECOVERING {self.name} t={rel:.3f} s: valid samples again after "
                  f"{blind:.3f} s blind; monitor restarted, full sensitivity after "
                  f"{self.warmup_s:.3f} s", flush=True)
        elif self.state == RECOVERING:
            self._warm += 1
            if self._warm * self.sample_time >= self.warmup_s:
                self.state = MONITORING
                print(f"MONITORING {self.name} t={rel:.3f} s: warm-up over", flush=True)

    def fault(self, reason, kind="link", received=None):
        """Enter the blind state now: ``FAULT`` line, hook, event closed, monitor reset.

        Nothing happens when the session is blind already (one line per
        blind period).

        Parameters
        ----------
        reason : str
            One line saying what happened.
        kind : str, default="link"
            ``"link"``, ``"stall"``, ``"rejected"``, ``"clock_jump"``,
            ``"gap"`` or ``"protocol"``.
        received : float, default=None
            :func:`time.perf_counter` of the fault (now when None).
        """
        if self.state == BLIND:
            return
        now = time.perf_counter() if received is None else received
        rel = self._last_rel if self._last_rel is not None else 0.0
        if self._last_ok is not None:
            rel += max(now - self._last_ok, 0.0)  # stream time of the fault, roughly
        self.state, self._blind_since, self._lost = BLIND, now, 0
        self.n_blind += 1
        self._open_fault = None
        if len(self.faults) < MAX_FAULT_RECORDS:
            self._open_fault = {"recording": self.name, "start_s": rel, "kind": kind,
                                "reason": reason, "last_stamp": self._valid_stamp,
                                "blind_s": None, "samples_lost": None,
                                "recovered_s": None, "recovered_stamp": None}
            self.faults.append(self._open_fault)
        if self.open is not None:
            self._close()
        self.cross_start = None
        self.monitor.reset()
        self._run = 0
        print(f"FAULT {self.name} t={rel:.3f} s: {reason}; blind, monitor reset", flush=True)
        self._run_hook({"GPCD_FAULT": reason, "GPCD_FAULT_TIME": f"{rel:.6f}"})

    def end(self, reason, abnormal=False):
        """Record how the stream ended (``abnormal``: the exit status is non-zero).

        Parameters
        ----------
        reason : str
        abnormal : bool, default=False
        """
        self.end_reason = reason
        self.abnormal_end = self.abnormal_end or abnormal

    @property
    def exit_status(self):
        return FAULT_EXIT_STATUS if (self.n_blind or self.abnormal_end) else 0

