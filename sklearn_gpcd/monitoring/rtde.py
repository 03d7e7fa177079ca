"""A :class:`~sklearn_gpcd.monitoring.MonitorSession` on a live UR controller (RTDE)."""

import gc
import math
import time

from .faults import BLIND


class _RTDERunning:
    """Connect to a UR controller and run the session on its stream."""

    def connect_rtde(self, host, port=30004, frequency=None):
        """A connected RTDE client of a live UR controller, for :meth:`run_rtde`.

        Parameters
        ----------
        host : str
        port : int, default=30004
        frequency : float or None, default=None
            Output rate [Hz]; None: the detector's, ``1 / sample_time``.

        Returns
        -------
        client : RTDEClient

        Raises
        ------
        ValueError
            When the detector does not have the 6 joints RTDE streams.
        OSError
            When no stream can be started.
        """
        from ..io import RTDEClient

        if self.monitor.n_joints != 6:
            raise ValueError(f"RTDE streams 6 joints; the detector has {self.monitor.n_joints}")
        client = RTDEClient(host, port, frequency or round(1.0 / self.sample_time, 6))
        try:
            return client.connect()
        except (OSError, ConnectionError) as exc:
            raise OSError(f"cannot start an RTDE stream from {host}:{port}: {exc} (check "
                          "--rtde HOST and --port)") from None

    def run_rtde(self, client, name, duration=None, reconnect_timeout=30.0):
        """Monitor a connected :class:`~sklearn_gpcd.io.RTDEClient` until the stream ends.

        Ends when the controller pauses the stream, after ``duration``
        seconds, or when the link stays lost for ``reconnect_timeout``
        seconds (then abnormally). A stall, a lost link (then reconnection
        with backoff: 50 ms doubling up to 2 s), a broken byte stream or a
        stream of rejected packages makes the session blind (:meth:`fault`).
        The client is closed on every exit path.

        Parameters
        ----------
        client : RTDEClient
            Connected (``client.connect()``).
        name : str
            Name of the stream in the events and lines.
        duration : float, default=None
            Wall-clock seconds to monitor; None until the stream ends.
        reconnect_timeout : float, default=30.0
            Give up after the link was lost this long [s].

        Returns
        -------
        summary : dict
            What :meth:`finish` returns.
        """
        from ..io import MalformedPackage, StreamPaused

        self.start(name)
        begin = time.perf_counter()
        end = math.inf if duration is None else begin + float(duration)
        connected, lost_at, backoff = True, None, 0.05
        self._last_ok = begin  # a connection that never sends data is a stall
        # the objects of the setup (modules, model) leave the garbage collector's
        # generations: a full collection then takes no longer than a tick's garbage
        gc.freeze()
        try:
            while True:
                now = time.perf_counter()
                if now >= end:
                    self.end(self.end_reason or "duration")
                    break
                if not connected:
                    if now - lost_at > reconnect_timeout:
                        self.end(f"link lost for more than {reconnect_timeout:g} s",
                                 abnormal=True)
                        break
                    time.sleep(max(min(backoff, end - now), 0.0))
                    backoff = min(backoff * 2, 2.0)
                    try:
                        client.connect()
                    except OSError:
                        continue
                    connected, backoff = True, 0.05
                    self._last_ok = time.perf_counter()
                    print(f"RECONNECTED {self.name}: stream restarted after "
                          f"{self._last_ok - lost_at:.3f} s", flush=True)
                    continue
                deadline = (now + 0.25 if self.state == BLIND
                            else self._last_ok + self.stall_timeout)
                try:
                    received, fields = client.receive(min(deadline, end))
                except TimeoutError:
                    now = time.perf_counter()
                    if now < end and self.state != BLIND:
                        unknown = getattr(client, "n_unknown", 0)
                        self.fault(f"no valid data for {(now - self._last_ok) * 1e3:.0f} ms "
                                   f"(stall; {unknown} packages of unknown type so far)",
                                   kind="stall", received=now)
                    continue
                except StreamPaused:
                    self.end("the controller paused the stream")
                    break
                except MalformedPackage as exc:
                    now = time.perf_counter()
                    self.n_samples += 1
                    self._rejected(str(exc), now)
                    continue
                except ConnectionError as exc:  # lost link or broken byte stream
                    lost_at = time.perf_counter()
                    kind = "protocol" if "RTDE package" in str(exc) else "link"
                    self.fault(f"link lost: {exc}", kind=kind, received=lost_at)
                    client.close()
                    connected = False
                    continue
                self.tick(fields.pop("time"), fields, received)
        finally:
            client.close()
            gc.unfreeze()
        return self.finish()
