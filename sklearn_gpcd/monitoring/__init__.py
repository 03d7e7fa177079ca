"""Live collision monitoring you can leave running: :class:`MonitorSession`.

The per-sample loop behind ``gpcd monitor`` (recordings, a paced replay, a
live UR controller over RTDE), fail-safe: a monitor that cannot see says so
at once. A session is always in one of three states:

``monitoring``
    Valid samples arrive and every decision is that of the detector (the
    batch ``predict`` on the same rows).
``blind``
    No valid decision for longer than the stall bound ``max(3 control
    periods, 20 ms)``: the link is lost, the stream stalled, every sample is
    rejected (NaN currents, frozen or backward time stamps, malformed or
    unknown packages) or the controller clock jumped. Entering it prints one
    ``FAULT`` line, runs the hook with ``GPCD_FAULT``, ends the open alarm
    event and resets the monitor (:meth:`StreamingMonitor.reset
    <sklearn_gpcd.detection.StreamingMonitor.reset>`), so no decision is
    ever made on state from before the fault. RTDE reconnects with backoff.
``recovering``
    Valid samples again, the monitor restarted from the first of them (a
    ``RECOVERING`` line): its decisions equal the batch detector's on the
    valid rows from there on, but during the warm-up (the debounce window
    and one low-pass time constant, ``warmup_s``) a contact that began
    earlier may be missed. After it, a ``MONITORING`` line.

Statistics (tick latency percentiles, dropped samples, how far decisions
fall behind the stream) live in fixed-size structures, so memory does not
grow with the length of a shift; a report (:meth:`MonitorSession.report`)
is available on every exit path, and :attr:`MonitorSession.exit_status` is
non-zero when the session was ever blind or the stream ended abnormally.
"""

from .faults import BLIND, MONITORING, RECOVERING, stall_bound
from .session import HookWarning, MonitorSession, paced, recording_samples

__all__ = ["BLIND", "MONITORING", "RECOVERING", "HookWarning", "MonitorSession",
           "paced", "recording_samples", "stall_bound"]
