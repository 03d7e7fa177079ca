"""Stop signals of a supervisor, handled like Ctrl-C: :func:`stop_signals`.

systemd, docker and every process supervisor stop a service with SIGTERM (and
a closed terminal sends SIGHUP). Inside :func:`stop_signals` each raises
:class:`StopSignal` in the main thread, so that ``gpcd monitor`` ends the way
it does on Ctrl-C: the open event closed, the report written with ``end``
naming the signal, exit status ``128 + signal number`` (143 for SIGTERM, 129
for SIGHUP), the shell's convention.
"""

import contextlib
import signal
import threading

#: Signals handled like Ctrl-C (SIGHUP where the platform has it).
STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP")
                     if hasattr(signal, name))


class StopSignal(BaseException):
    """A stop signal arrived (a :class:`BaseException`, like KeyboardInterrupt,
    so that no ``except Exception`` of the loop swallows it).

    Parameters
    ----------
    signum : int

    Attributes
    ----------
    signum : int
    name : str
        ``"SIGTERM"`` or ``"SIGHUP"``.
    exit_status : int
        ``128 + signum``.

    Examples
    --------
    >>> import signal
    >>> from sklearn_gpcd.monitoring.stops import StopSignal
    >>> stop = StopSignal(signal.SIGTERM)
    >>> stop.name, stop.exit_status
    ('SIGTERM', 143)
    """

    def __init__(self, signum):
        self.signum = int(signum)
        self.name = signal.Signals(self.signum).name
        self.exit_status = 128 + self.signum
        super().__init__(f"stopped by {self.name}")


@contextlib.contextmanager
def stop_signals():
    """Within the block, SIGTERM and SIGHUP raise :class:`StopSignal` (main thread only;
    elsewhere the block runs unchanged). The previous handlers come back after it.

    The first stop signal wins: from it on, the stop signals are ignored
    (:func:`hold_stop_signals`), so that a second one (a supervisor that
    insists) cannot cut the clean-up on the way out (a temporary folder
    half removed, a report half written).

    Examples
    --------
    >>> import os, signal
    >>> from sklearn_gpcd.monitoring.stops import StopSignal, stop_signals
    >>> try:
    ...     with stop_signals():
    ...         os.kill(os.getpid(), signal.SIGTERM)
    ... except StopSignal as stop:
    ...     print(stop)
    stopped by SIGTERM
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {signum: signal.getsignal(signum) for signum in STOP_SIGNALS}

    def raise_stop(signum, frame):
        hold_stop_signals()
        raise StopSignal(signum)

    for signum in STOP_SIGNALS:
        signal.signal(signum, raise_stop)
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def hold_stop_signals():
    """Ignore SIGTERM and SIGHUP from now on (while the report of a stop is
    written; :func:`stop_signals` restores the handlers at its end)."""
    if threading.current_thread() is threading.main_thread():
        for signum in STOP_SIGNALS:
            signal.signal(signum, signal.SIG_IGN)
