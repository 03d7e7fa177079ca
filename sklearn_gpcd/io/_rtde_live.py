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

:class:`LoopbackRTDEServer` answers the same messages on 127.0.0.1 and
streams a :class:`~sklearn_gpcd.io.Recording` at its own time stamps (real
time): the seam tests and the loopback benchmark drive it to run
``gpcd monitor --rtde`` end to end without a robot.
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


def _package(kind, payload=b""):
    return _HEADER.pack(_HEADER.size + len(payload), kind) + payload


def _read_exactly(stream, n):
    data = stream.read(n)
    if data is None or len(data) < n:
        raise ConnectionError("RTDE connection closed")
    return data


def _read_package(stream):
    size, kind = _HEADER.unpack(_read_exactly(stream, _HEADER.size))
    return kind, _read_exactly(stream, size - _HEADER.size)


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
        Socket timeout [s] for connecting, the handshake and each package.

    Examples
    --------
    >>> from sklearn_gpcd.io._rtde_live import OUTPUTS, RTDEClient
    >>> OUTPUTS[0]
    'timestamp'
    """

    def __init__(self, host, port=RTDE_PORT, frequency=500.0, timeout=5.0):
        self.host, self.port = host, int(port)
        self.frequency, self.timeout = float(frequency), float(timeout)
        self._sock = self._stream = None

    def _request(self, kind, payload=b""):
        self._sock.sendall(_package(kind, payload))
        while True:
            got, body = _read_package(self._stream)
            if got == kind:
                return body
            if got != TEXT_MESSAGE:  # text messages may come at any time
                raise ConnectionError(f"unexpected RTDE package type {got} (wanted {kind})")

    def connect(self):
        """Connect, negotiate protocol 2, set up the outputs and start the stream."""
        self._sock = socket.create_connection((self.host, self.port), timeout=self.timeout)
        self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._stream = self._sock.makefile("rb")
        if not self._request(REQUEST_PROTOCOL_VERSION, struct.pack(">H", PROTOCOL_VERSION))[0]:
            raise ConnectionError(f"{self.host}: RTDE protocol version 2 refused")
        body = self._request(SETUP_OUTPUTS,
                             struct.pack(">d", self.frequency) + ",".join(OUTPUTS).encode())
        self.recipe_id = body[0]
        types = body[1:].decode().split(",")
        missing = [n for n, t in zip(OUTPUTS, types) if t == "NOT_FOUND"]
        if missing:
            raise ConnectionError(f"{self.host}: the controller has no output "
                                  f"{', '.join(missing)}")
        self._data = struct.Struct(">B" + "".join(_FORMATS[t] for t in types))
        if not self._request(START)[0]:
            raise ConnectionError(f"{self.host}: RTDE start refused")
        self._sock.settimeout(self.timeout)
        return self

    def samples(self):
        """Yield ``(received, fields)`` per data package until the stream ends.

        ``received`` is :func:`time.perf_counter` when the package was
        read; ``fields`` maps ``FIELDS`` names to a float (``time``) or a
        6-vector.
        """
        stream, data = self._stream, self._data
        while True:
            try:
                kind, body = _read_package(stream)
            except (ConnectionError, OSError):
                return
            received = time.perf_counter()
            if kind != DATA_PACKAGE:
                continue
            values = data.unpack(body)
            out, k = {"time": values[1]}, 2
            for name in FIELDS[1:]:
                out[name] = np.array(values[k:k + 6])
                k += 6
            yield received, out

    def close(self):
        """Ask for a pause (best effort) and close the socket."""
        if self._sock is None:
            return
        try:
            self._sock.sendall(_package(PAUSE))
        except OSError:
            pass
        self._stream.close()
        self._sock.close()
        self._sock = None


class LoopbackRTDEServer:
    """Serve a recording over RTDE on 127.0.0.1, at its own time stamps.

    Accepts one client, answers the handshake of :class:`RTDEClient` and
    sends one data package per sample at ``t0 + (time[k] - time[0]) /
    speed`` (``time.sleep``, no busy-wait), then closes. It stops by
    itself after ``max_duration`` seconds in any case.

    Parameters
    ----------
    recording : Recording
        Six joints; missing target signals are sent as zeros.
    speed : float, default=1.0
        Time-stamp speed factor (1 = real time).
    max_duration : float, default=120.0
        Hard limit [s] on the whole session.

    Attributes
    ----------
    port : int
        The port to connect to (chosen by the system).
    n_sent : int
        Data packages sent.
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

    def __init__(self, recording, speed=1.0, max_duration=120.0):
        self.recording = recording
        self.speed = float(speed)
        self.max_duration = float(max_duration)
        self.n_sent, self.max_send_lag = 0, 0.0
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
        """Stop streaming and wait for the server thread."""
        self._stop.set()
        self._thread.join(timeout=self.max_duration + 5.0)
        self._listener.close()

    def _serve(self):
        deadline = time.monotonic() + self.max_duration
        self._listener.settimeout(1.0)
        conn = None
        while conn is None and not self._stop.is_set() and time.monotonic() < deadline:
            try:
                conn, _ = self._listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
        if conn is None:
            return
        with conn:
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            conn.settimeout(max(deadline - time.monotonic(), 0.1))
            stream = conn.makefile("rb")
            try:
                data = self._handshake(conn, stream)
                if data is not None:
                    self._stream_data(conn, data, deadline)
            except OSError:
                pass
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

    def _stream_data(self, conn, data, deadline):
        rec = self.recording
        zeros = np.zeros((rec.n_samples, rec.n_joints))
        by_output = {"timestamp": rec.time[:, None]}
        for name, field in zip(OUTPUTS[1:], FIELDS[1:]):
            value = getattr(rec, field)
            by_output[name] = zeros if value is None else value
        table = np.hstack([by_output[n] for n in self._names])
        header = _HEADER.pack(_HEADER.size + data.size, DATA_PACKAGE)
        start = time.perf_counter()
        t0 = rec.time[0]
        for k in range(rec.n_samples):
            if self._stop.is_set() or time.monotonic() > deadline:
                break
            due = start + (rec.time[k] - t0) / self.speed
            if (wait := due - time.perf_counter()) > 0:
                time.sleep(wait)  # no busy-wait: the client may share this process
            self.max_send_lag = max(self.max_send_lag, time.perf_counter() - due)
            conn.sendall(header + data.pack(1, *table[k]))
            self.n_sent += 1
