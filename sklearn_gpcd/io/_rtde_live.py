"""A minimal RTDE client (protocol version 2) and a loopback RTDE server.

Universal Robots' Real-Time Data Exchange streams controller data over TCP
(port 30004). Every package is ``uint16 size`` (bytes, header included) +
``uint8 type`` + payload, big endian. The client here speaks only what a
monitor needs:

1. ``V`` (86) request protocol version 2 -> ``uint8 accepted``;
2. ``O`` (79) setup outputs: ``double frequency`` + comma-separated names ->
   ``uint8 recipe_id`` + comma-separated types (``NOT_FOUND`` for an
   unknown name);
3. ``S`` (83) start -> ``uint8 accepted``;
4. ``U`` (85) data packages: ``uint8 recipe_id`` + the fields (``DOUBLE`` =
   ``>d``, ``VECTOR6D`` = ``>6d``) until ``P`` (80) pause or the socket
   closes.

The client never ends quietly: :meth:`RTDEClient.receive` waits for a data
package up to a deadline (``TimeoutError``: a stall), a closed or reset
link is a ``ConnectionError``, a package size outside ``3..MAX_PACKAGE``
bytes, an unexpected answer or a malformed output recipe an
:class:`RTDEProtocolError` (one line), a data package that does not match
the recipe a :class:`MalformedPackage` (the stream goes on), and a pause
package (``P``) :class:`StreamPaused`, the clean end.

:class:`LoopbackRTDEServer` answers the same messages on 127.0.0.1 and
streams a :class:`~sklearn_gpcd.io.Recording` at its own time stamps (real
time), then pauses; it serves a client that reconnects, and injects the
link and stream faults of ``FAULT_KINDS`` on request: the seam tests,
``tests/test_monitoring.py`` and the loopback benchmark drive it
to run ``gpcd monitor --rtde`` end to end without a robot.
"""

import socket
import struct
import threading
import time

import numpy as np

RTDE_PORT = 30004
PROTOCOL_VERSION = 2
REQUEST_PROTOCOL_VERSION = 86
GET_URCONTROL_VERSION = 118
TEXT_MESSAGE = 77
DATA_PACKAGE = 85
SETUP_OUTPUTS = 79
START = 83
PAUSE = 80

#: Outputs ``gpcd monitor --rtde`` asks for, and the recording fields they fill.
OUTPUTS = ("timestamp", "actual_q", "actual_qd", "actual_current", "target_current",
           "target_q", "target_qd")
FIELDS = ("time", "q", "qd", "current", "target_current", "target_q", "target_qd")
_TYPES = {"timestamp": "DOUBLE", "actual_q": "VECTOR6D", "actual_qd": "VECTOR6D",
          "actual_current": "VECTOR6D", "target_current": "VECTOR6D",
          "target_q": "VECTOR6D", "target_qd": "VECTOR6D"}
_FORMATS = {"DOUBLE": "d", "VECTOR6D": "6d"}
_HEADER = struct.Struct(">HB")
#: Largest package the client accepts [bytes] (a data package of OUTPUTS has 298).
MAX_PACKAGE = 4096


class RTDEProtocolError(ConnectionError):
    """The controller sent something RTDE protocol 2 does not allow.

    A package size shorter than its header or longer than ``MAX_PACKAGE``,
    an answer of the wrong type during the handshake, or an output recipe
    the client cannot read: the byte stream cannot be trusted any more, so
    the connection is dropped (the message says why, in one line).

    Examples
    --------
    >>> from sklearn_gpcd.io._rtde_live import RTDEProtocolError
    >>> isinstance(RTDEProtocolError("package size 1"), OSError)
    True
    """


class MalformedPackage(ValueError):
    """A data package that does not match the recipe (wrong length or recipe id).

    The framing is intact (the package had a valid size), so the stream goes
    on: the sample is lost, as a sensor fault.

    Examples
    --------
    >>> from sklearn_gpcd.io._rtde_live import MalformedPackage
    >>> str(MalformedPackage("data package of 20 bytes"))
    'data package of 20 bytes'
    """


class StreamPaused(Exception):
    """The controller paused the stream (a ``P`` package): the stream ended cleanly.

    Examples
    --------
    >>> from sklearn_gpcd.io._rtde_live import StreamPaused
    >>> issubclass(StreamPaused, OSError)
    False
    """


def _package(kind, payload=b""):
    return _HEADER.pack(_HEADER.size + len(payload), kind) + payload


def _read_exactly(stream, n):
    data = stream.read(n)
    if data is None or len(data) < n:
        raise ConnectionError("RTDE connection closed")
    return data


def _read_package(stream):
    size, kind = _HEADER.unpack(_read_exactly(stream, _HEADER.size))
    if not _HEADER.size <= size <= MAX_PACKAGE:
        raise RTDEProtocolError(f"RTDE package of type {kind} claims {size} bytes (a "
                                f"package has {_HEADER.size} to {MAX_PACKAGE})")
    return kind, _read_exactly(stream, size - _HEADER.size)


class _Reader:
    """Whole packages from a socket, each read bounded by a deadline.

    A read that times out keeps the bytes received so far (unlike a socket
    file, which cannot be read again after a timeout), so waiting for a
    package in slices of a stall bound loses nothing.
    """

    def __init__(self, sock):
        self.sock, self.buffer = sock, bytearray()

    def _fill(self, n, deadline):
        while len(self.buffer) < n:
            remaining = None if deadline is None else deadline - time.perf_counter()
            if remaining is not None and remaining <= 0:
                raise TimeoutError("no RTDE data")
            self.sock.settimeout(remaining)
            try:
                chunk = self.sock.recv(65536)
            except TimeoutError:  # socket.timeout
                raise TimeoutError("no RTDE data") from None
            if not chunk:
                raise ConnectionError("connection closed by the controller")
            self.buffer += chunk

    def package(self, deadline=None):
        """``(kind, body)`` of the next package; TimeoutError after ``deadline``."""
        self._fill(_HEADER.size, deadline)
        size, kind = _HEADER.unpack_from(self.buffer)
        if not _HEADER.size <= size <= MAX_PACKAGE:
            raise RTDEProtocolError(f"RTDE package of type {kind} claims {size} bytes (a "
                                    f"package has {_HEADER.size} to {MAX_PACKAGE})")
        self._fill(size, deadline)
        body = bytes(self.buffer[_HEADER.size:size])
        del self.buffer[:size]
        return kind, body


class RTDEClient:
    """Receive ``OUTPUTS`` from a UR controller (or :class:`LoopbackRTDEServer`).

    Parameters
    ----------
    host : str
        Controller address.
    port : int, default=30004
    frequency : float, default=500.0
        Output frequency asked for [Hz] (500 on e-Series, 125 on CB3).
    timeout : float, default=5.0
        Socket timeout [s] for connecting and the handshake (and for each
        package in :meth:`samples`).

    Attributes
    ----------
    n_unknown : int
        Packages of a type the client does not use (text messages
        excluded), skipped.

    Examples
    --------
    >>> from sklearn_gpcd.io._rtde_live import OUTPUTS, RTDEClient
    >>> OUTPUTS[0]
    'timestamp'
    """

    def __init__(self, host, port=RTDE_PORT, frequency=500.0, timeout=5.0):
        self.host, self.port = host, int(port)
        self.frequency, self.timeout = float(frequency), float(timeout)
        self._sock = self._reader = None
        self.n_unknown = 0

    def _request(self, kind, payload=b""):
        self._sock.sendall(_package(kind, payload))
        deadline = time.perf_counter() + self.timeout
        while True:
            try:
                got, body = self._reader.package(deadline)
            except TimeoutError:
                raise TimeoutError(f"{self.host}: no answer to RTDE request {kind} within "
                                   f"{self.timeout:g} s") from None
            if got == kind:
                if not body:
                    raise RTDEProtocolError(f"{self.host}: empty answer to RTDE request "
                                            f"{kind}")
                return body
            if got != TEXT_MESSAGE:  # text messages may come at any time
                raise RTDEProtocolError(f"unexpected RTDE package type {got} (wanted "
                                        f"{kind})")

    def connect(self):
        """Connect, negotiate protocol 2, set up the outputs and start the stream.

        Raises
        ------
        OSError
            When the controller cannot be reached, or answers something the
            client cannot use (:class:`RTDEProtocolError`, one line).
        """
        self.close()
        self._sock = socket.create_connection((self.host, self.port), timeout=self.timeout)
        try:
            self._handshake()
        except BaseException:
            self.close()
            raise
        return self

    def _handshake(self):
        self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._reader = _Reader(self._sock)
        if not self._request(REQUEST_PROTOCOL_VERSION, struct.pack(">H", PROTOCOL_VERSION))[0]:
            raise ConnectionError(f"{self.host}: RTDE protocol version 2 refused")
        body = self._request(SETUP_OUTPUTS,
                             struct.pack(">d", self.frequency) + ",".join(OUTPUTS).encode())
        self.recipe_id = body[0]
        types = body[1:].decode("ascii", "replace").split(",")
        missing = [n for n, t in zip(OUTPUTS, types) if t == "NOT_FOUND"]
        if missing:
            raise ConnectionError(f"{self.host}: the controller has no output "
                                  f"{', '.join(missing)}")
        expected = [_TYPES[n] for n in OUTPUTS]
        if types != expected:
            shown = ",".join(types)[:80]
            raise RTDEProtocolError(f"{self.host}: malformed output recipe: types "
                                    f"{shown!r} for {','.join(OUTPUTS)} (expected "
                                    f"{','.join(expected)})")
        self._data = struct.Struct(">B" + "".join(_FORMATS[t] for t in types))
        if not self._request(START)[0]:
            raise ConnectionError(f"{self.host}: RTDE start refused")

    def receive(self, deadline=None):
        """The next data package: ``(received, fields)``.

        Parameters
        ----------
        deadline : float, default=None
            :func:`time.perf_counter` value after which to give up waiting;
            None waits up to ``timeout`` seconds.

        Returns
        -------
        received : float
            :func:`time.perf_counter` when the package was read.
        fields : dict
            ``FIELDS`` names to a float (``time``) or a 6-vector.

        Raises
        ------
        TimeoutError
            No data package before ``deadline`` (bytes of a partial package
            are kept for the next call).
        ConnectionError
            The link is lost (closed, reset) or the byte stream is broken
            (:class:`RTDEProtocolError`).
        MalformedPackage
            A data package that does not match the recipe: lost, the stream
            goes on.
        StreamPaused
            The controller paused the stream.
        """
        if self._reader is None:
            raise ConnectionError("not connected")
        if deadline is None:
            deadline = time.perf_counter() + self.timeout
        data = self._data
        while True:
            try:
                kind, body = self._reader.package(deadline)
            except (TimeoutError, ConnectionError):
                raise
            except OSError as exc:  # reset, broken pipe, ...
                raise ConnectionError(f"link lost: {exc}") from None
            if kind == DATA_PACKAGE:
                break
            if kind == PAUSE:
                raise StreamPaused("the controller paused the stream")
            if kind != TEXT_MESSAGE:
                self.n_unknown += 1
        received = time.perf_counter()
        if len(body) != data.size or body[0] != self.recipe_id:
            raise MalformedPackage(
                f"data package of {len(body)} bytes for recipe {body[:1].hex() or '-'} "
                f"(expected {data.size} bytes for recipe {self.recipe_id})")
        values = data.unpack(body)
        out, k = {"time": values[1]}, 2
        for name in FIELDS[1:]:
            out[name] = np.array(values[k:k + 6])
            k += 6
        return received, out

    def samples(self):
        """Yield ``(received, fields)`` per data package until the stream is paused.

        ``received`` is :func:`time.perf_counter` when the package was
        read; ``fields`` maps ``FIELDS`` names to a float (``time``) or a
        6-vector. Malformed data packages are skipped.

        Raises
        ------
        TimeoutError
            No package for ``timeout`` seconds.
        ConnectionError
            The link is lost or the byte stream is broken (never a quiet end).
        """
        while True:
            try:
                yield self.receive()
            except StreamPaused:
                return
            except MalformedPackage:
                continue

    def close(self):
        """Ask for a pause (best effort) and close the socket."""
        if self._sock is None:
            return
        try:
            self._sock.settimeout(0.05)
            self._sock.sendall(_package(PAUSE))
        except OSError:
            pass
        self._sock.close()
        self._sock = self._reader = None


#: Faults :class:`LoopbackRTDEServer` can inject, and what their value means.
FAULT_KINDS = {
    "drop": "reset the connection before this sample (value unused); the next client "
            "gets the stream from this sample on",
    "kill": "reset the connection before this sample and stop serving (a controller "
            "that died)",
    "stall": "send nothing for value seconds before this sample (no sample lost)",
    "gap": "skip value samples (lost: the time stamps jump forward)",
    "clock_jump": "add value seconds to this and every later time stamp",
    "freeze": "value samples from this one repeat the last time stamp sent",
    "nan": "value samples from this one carry NaN currents",
    "inf_time": "value samples from this one carry an infinite time stamp",
    "unknown": "value packages of an unknown type instead of this many samples",
    "malformed": "value data packages of the wrong length instead of this many samples",
    "bad_size": "a package header claiming 1 byte (the byte stream breaks; the "
                "connection is dropped)",
}


class LoopbackRTDEServer:
    """Serve a recording over RTDE on 127.0.0.1, at its own time stamps.

    Answers the handshake of :class:`RTDEClient` and sends one data package
    per sample at ``t0 + (time[k] - time[0]) / speed`` (a timed wait, no
    busy-wait; ``speed=0``: as fast as the client reads), then a pause
    package (``P``: the stream ended cleanly) and closes. A client that
    reconnects after a dropped connection gets the stream from where it
    broke. ``faults`` injects the link and stream faults of
    ``FAULT_KINDS`` at given samples, for fail-safe tests. It stops by
    itself after ``max_duration`` seconds in any case.

    Parameters
    ----------
    recording : Recording
        Six joints; missing target signals are sent as zeros.
    speed : float, default=1.0
        Time-stamp speed factor (1 = real time, 0 = no pacing).
    max_duration : float, default=120.0
        Hard limit [s] on the whole session.
    faults : list of (int, str, float), default=None
        ``(sample, kind, value)``: inject fault ``kind`` (a key of
        ``FAULT_KINDS``) at sample index ``sample`` of the whole stream.
    repeat : int, default=1
        Send the recording this many times in a row, the time stamps
        continuing (a long shift from a short recording).

    Attributes
    ----------
    port : int
        The port to connect to (chosen by the system).
    n_sent : int
        Data packages sent (valid or not).
    n_connections : int
        Clients served.
    max_send_lag : float
        Largest delay [s] of a send behind its schedule.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> from sklearn_gpcd.io._rtde_live import LoopbackRTDEServer, RTDEClient
    >>> t = np.arange(5) * 0.002
    >>> z = np.zeros((5, 6))
    >>> rec = Recording(time=t, q=z, qd=z, current=z)
    >>> with LoopbackRTDEServer(rec) as server:
    ...     client = RTDEClient("127.0.0.1", server.port).connect()
    ...     stamps = [fields["time"] for _, fields in client.samples()]
    ...     client.close()
    >>> stamps == t.tolist()
    True
    """

    def __init__(self, recording, speed=1.0, max_duration=120.0, faults=None, repeat=1):
        self.recording = recording
        self.speed = float(speed)
        self.max_duration = float(max_duration)
        self.repeat = int(repeat)
        self.faults = {}
        for sample, kind, value in faults or ():
            if kind not in FAULT_KINDS:
                raise ValueError(f"unknown fault {kind!r}; one of {sorted(FAULT_KINDS)}")
            self.faults.setdefault(int(sample), []).append((kind, value))
        self.n_sent, self.n_connections, self.max_send_lag = 0, 0, 0.0
        self._listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self._listener.bind(("127.0.0.1", 0))
        self._listener.listen(1)
        self.port = self._listener.getsockname()[1]
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self.stop()

    def stop(self):
        """Stop streaming (connections are closed without a pause) and wait."""
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout=self.max_duration + 5.0)
        self._listener.close()

    def join(self, timeout=None):
        """Wait until the server has sent the whole stream (or stopped)."""
        self._thread.join(timeout)

    def _serve(self):
        deadline = time.monotonic() + self.max_duration
        self._listener.settimeout(0.05)
        self._table = None
        self._next, self._offset, self._last_stamp = 0, 0.0, None
        self._pending = []  # [kind, remaining] of freeze / nan / inf_time in progress
        self._total = self.recording.n_samples * self.repeat
        while not self._stop.is_set() and time.monotonic() < deadline:
            try:
                conn, _ = self._listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            self.n_connections += 1
            if self._connection(conn, deadline):
                self._listener.close()  # over: a client that reconnects is refused
                return

    def _connection(self, conn, deadline):
        """Serve one client; True when the stream is over (sent whole or stopped)."""
        with conn:
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            conn.settimeout(max(deadline - time.monotonic(), 0.1))
            stream = conn.makefile("rb")
            try:
                data = self._handshake(conn, stream)
                if data is None:
                    return False
                outcome = self._stream_data(conn, data, deadline)
                if outcome == "sent":
                    conn.sendall(_package(PAUSE))
                return outcome != "dropped"
            except OSError:
                return self._stop.is_set()
            finally:
                stream.close()

    def _handshake(self, conn, stream):
        """Answer requests until START; return the data Struct (None on failure)."""
        data = None
        while True:
            kind, body = _read_package(stream)
            if kind == REQUEST_PROTOCOL_VERSION:
                version = struct.unpack(">H", body[:2])[0]
                conn.sendall(_package(kind, bytes([version == PROTOCOL_VERSION])))
            elif kind == GET_URCONTROL_VERSION:
                conn.sendall(_package(kind, struct.pack(">IIII", 5, 11, 0, 0)))
            elif kind == SETUP_OUTPUTS:
                names = body[8:].decode().split(",")
                types = [_TYPES.get(n, "NOT_FOUND") for n in names]
                conn.sendall(_package(kind, bytes([1]) + ",".join(types).encode()))
                if "NOT_FOUND" not in types:
                    self._names = names
                    data = struct.Struct(">B" + "".join(_FORMATS[t] for t in types))
            elif kind == START:
                conn.sendall(_package(kind, bytes([data is not None])))
                return data
            else:
                return None

    def _build_table(self):
        rec = self.recording
        zeros = np.zeros((rec.n_samples, rec.n_joints))
        by_output = {"timestamp": rec.time[:, None]}
        for name, field in zip(OUTPUTS[1:], FIELDS[1:]):
            value = getattr(rec, field)
            by_output[name] = zeros if value is None else value
        self._table = np.hstack([by_output[n] for n in self._names])
        self._current = [i for i, n in enumerate(self._names) if n == "actual_current"]
        self._period = (rec.time[-1] - rec.time[0]) + (
            float(np.median(np.diff(rec.time))) if rec.n_samples > 1 else 0.0)

    def _row(self, k):
        """Values of stream sample ``k`` (recording repeated, faults applied)."""
        n = self.recording.n_samples
        row = self._table[k % n].copy()
        row[0] += (k // n) * self._period + self._offset
        for item in self._pending:
            kind = item[0]
            if kind == "freeze" and self._last_stamp is not None:
                row[0] = self._last_stamp
            elif kind == "inf_time":
                row[0] = np.inf
            elif kind == "nan":
                column = 1 + 6 * (self._current[0] - 1)  # after the time stamp
                row[column:column + 6] = np.nan
            item[1] -= 1
        self._pending = [item for item in self._pending if item[1] > 0]
        return row

    def _stream_data(self, conn, data, deadline):
        """Send from sample ``_next`` on: ``"sent"`` (all of it), ``"dropped"``
        (the connection, by a fault) or ``"stopped"``."""
        if self._table is None:
            self._build_table()
        rec = self.recording
        header = _HEADER.pack(_HEADER.size + data.size, DATA_PACKAGE)
        start, first = time.perf_counter(), self._next
        while self._next < self._total:
            k = self._next
            if self._stop.is_set() or time.monotonic() > deadline:
                return "stopped"
            for kind, value in self.faults.pop(k, ()):
                if kind in ("drop", "kill"):
                    conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER,
                                    struct.pack("ii", 1, 0))  # close with a reset
                    return "dropped" if kind == "drop" else "stopped"
                if kind == "bad_size":
                    conn.sendall(_HEADER.pack(1, DATA_PACKAGE))
                    return "dropped"
                if kind == "stall":
                    if self._stop.wait(float(value)):
                        return "stopped"
                    start += float(value) * (self.speed > 0)
                elif kind == "gap":
                    self._next = k = k + int(value)
                elif kind == "clock_jump":
                    self._offset += float(value)
                elif kind == "unknown":
                    for _ in range(int(value)):
                        conn.sendall(_package(42, b"\x00" * 8))
                    self._next = k = k + int(value)
                elif kind == "malformed":
                    for _ in range(int(value)):
                        conn.sendall(_package(DATA_PACKAGE, b"\x01" * 10))
                        self.n_sent += 1
                    self._next = k = k + int(value)
                else:  # freeze, nan, inf_time: the next `value` samples
                    self._pending.append([kind, int(value)])
            if k >= self._total:
                break
            if self.speed > 0:
                n = rec.n_samples
                t = (k // n) * self._period + rec.time[k % n]
                t_first = (first // n) * self._period + rec.time[first % n]
                due = start + (t - t_first) / self.speed
                if (wait := due - time.perf_counter()) > 0 and self._stop.wait(wait):
                    return "stopped"  # no busy-wait: the client may share this process
                self.max_send_lag = max(self.max_send_lag, time.perf_counter() - due)
            row = self._row(k)
            conn.sendall(header + data.pack(1, *row))
            if np.isfinite(row[0]):
                self._last_stamp = row[0]
            self.n_sent += 1
            self._next = k + 1
        return "sent"
