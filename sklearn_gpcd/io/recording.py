"""One in-memory type for every robot log the package reads or writes."""

from dataclasses import dataclass, field, replace

import numpy as np

#: Per-joint signals of a :class:`Recording`, each ``(n_samples, n_joints)`` or None.
JOINT_SIGNALS = (
    "q",
    "qd",
    "qdd",
    "current",
    "target_q",
    "target_qd",
    "target_qdd",
    "target_current",
    "target_torque",
)


@dataclass(frozen=True)
class Recording:
    """A time series of joint states and motor currents.

    Every loader in :mod:`sklearn_gpcd.io` returns this type and the simulator
    in :mod:`sklearn_gpcd.datasets` produces it, so downstream code never
    cares where a log came from. Arrays are float64, rows are samples sorted
    by strictly increasing ``time``; optional signals are ``None`` when the
    source does not log them.

    Parameters
    ----------
    time : ndarray of shape (n_samples,)
        Time stamps in seconds, strictly increasing (need not be uniform).
    q, qd : ndarray of shape (n_samples, n_joints)
        Measured joint positions [rad] and velocities [rad/s].
    current : ndarray of shape (n_samples, n_joints)
        Measured motor currents [A] (or joint torques [Nm] for robots that
        log torque; see ``units``).
    qdd : ndarray of shape (n_samples, n_joints), default=None
        Joint accelerations [rad/s^2], when logged or computed.
    target_q, target_qd, target_qdd : ndarray, default=None
        Controller set-points (UR RTDE ``target_*``).
    target_current : ndarray, default=None
        Current requested by the joint controller, the paper's ``i_c``.
    target_torque : ndarray, default=None
        Controller torque (UR ``target_moment``).
    labels : ndarray of shape (n_samples,), default=None
        Ground-truth contact labels: 0 free motion, k > 0 inside contact
        event ``k``.
    name : str, default=""
        Where the recording came from (file name or generator).
    units : str, default="A"
        Unit of ``current``: ``"A"`` for motor currents, ``"Nm"`` for torques.
    metadata : dict, default={}
        Anything else worth keeping (robot name, sample rate, dropped rows).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import Recording
    >>> t = np.arange(4) * 0.008
    >>> rec = Recording(time=t, q=np.zeros((4, 2)), qd=np.zeros((4, 2)),
    ...                 current=np.ones((4, 2)))
    >>> rec.n_samples, rec.n_joints
    (4, 2)
    """

    time: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    current: np.ndarray
    qdd: np.ndarray = None
    target_q: np.ndarray = None
    target_qd: np.ndarray = None
    target_qdd: np.ndarray = None
    target_current: np.ndarray = None
    target_torque: np.ndarray = None
    labels: np.ndarray = None
    name: str = ""
    units: str = "A"
    metadata: dict = field(default_factory=dict)

    def __post_init__(self):
        time = np.asarray(self.time, dtype=float)
        if time.ndim != 1:
            raise ValueError(f"Recording {self.name!r}: time must be 1-D, got shape {time.shape}")
        object.__setattr__(self, "time", time)
        n_joints = None
        for key in JOINT_SIGNALS:
            value = getattr(self, key)
            if value is None:
                continue
            value = np.asarray(value, dtype=float)
            if value.ndim == 1:
                value = value[:, None]
            if value.ndim != 2 or value.shape[0] != time.shape[0]:
                raise ValueError(
                    f"Recording {self.name!r}: {key} must have shape "
                    f"({time.shape[0]}, n_joints), got {value.shape}"
                )
            if n_joints is None:
                n_joints = value.shape[1]
            elif value.shape[1] != n_joints:
                raise ValueError(
                    f"Recording {self.name!r}: {key} has {value.shape[1]} joints, "
                    f"q has {n_joints}"
                )
            object.__setattr__(self, key, value)
        if self.labels is not None:
            labels = np.asarray(self.labels)
            if labels.shape != time.shape:
                raise ValueError(
                    f"Recording {self.name!r}: labels must have shape {time.shape}, "
                    f"got {labels.shape}"
                )
            object.__setattr__(self, "labels", labels)

    def __repr__(self):
        """A one-line summary; the arrays themselves are never printed.

        Examples
        --------
        >>> import numpy as np
        >>> from sklearn_gpcd.io import Recording
        >>> t = np.arange(1000) * 0.002
        >>> Recording(time=t, q=np.zeros((1000, 6)), qd=np.zeros((1000, 6)),
        ...           current=np.ones((1000, 6)), name="run.csv",
        ...           metadata={"robot": "ur10e"})
        Recording('run.csv', 1000 samples x 6 joints, 2.00 s at 500 Hz, signals q, qd, current, current in A, robot ur10e)
        """
        parts = [f"{self.n_samples} samples x {self.n_joints} joints"]
        if self.n_samples > 1:
            rate = (self.n_samples - 1) / self.duration if self.duration > 0 else float("nan")
            parts.append(f"{self.duration:.2f} s at {rate:.4g} Hz")
        parts.append(f"signals {', '.join(self.available())}")
        parts.append(f"current in {self.units}")
        if self.labels is not None:
            parts.append(f"{len(np.unique(self.labels[self.labels > 0]))} labelled events")
        if self.metadata.get("robot"):
            parts.append(f"robot {self.metadata['robot']}")
        return f"Recording({self.name!r}, {', '.join(parts)})"

    __str__ = __repr__

    @property
    def n_samples(self):
        """Number of samples."""
        return self.time.shape[0]

    @property
    def n_joints(self):
        """Number of joints."""
        return self.q.shape[1]

    @property
    def duration(self):
        """Time span in seconds."""
        return float(self.time[-1] - self.time[0]) if self.n_samples else 0.0

    def available(self):
        """Names of the per-joint signals that are present.

        Examples
        --------
        >>> import numpy as np
        >>> from sklearn_gpcd.io import Recording
        >>> Recording(time=[0.0, 1.0], q=[[0], [0]], qd=[[0], [0]],
        ...           current=[[1], [1]]).available()
        ['q', 'qd', 'current']
        """
        return [k for k in JOINT_SIGNALS if getattr(self, k) is not None]

    def equals(self, other, atol=0.0):
        """True when ``other`` holds the same samples (``name`` and ``metadata`` aside).

        Compares ``time``, every per-joint signal (present in both or in
        neither), ``labels`` and ``units``; values may differ by ``atol``.

        Parameters
        ----------
        other : Recording
        atol : float, default=0.0
            Absolute tolerance on every value.

        Returns
        -------
        equal : bool

        Examples
        --------
        >>> import numpy as np
        >>> from sklearn_gpcd.io import Recording
        >>> a = Recording(time=[0.0, 1.0], q=[[0.0], [1.0]], qd=[[0.0], [0.0]],
        ...               current=[[1.0], [1.0]])
        >>> a.equals(a.replace(name="copy")), a.equals(a.replace(time=[0.0, 2.0]))
        (True, False)
        """
        if not isinstance(other, Recording) or self.units != other.units:
            return False
        for key in ("time",) + JOINT_SIGNALS + ("labels",):
            mine, theirs = getattr(self, key), getattr(other, key)
            if (mine is None) != (theirs is None):
                return False
            if mine is None:
                continue
            if mine.shape != theirs.shape or not np.allclose(mine, theirs, rtol=0.0, atol=atol):
                return False
        return True

    def replace(self, **changes):
        """A copy with some fields replaced (validated again)."""
        return replace(self, **changes)

    def slice(self, start=None, stop=None):
        """Samples ``start:stop`` as a new recording.

        Examples
        --------
        >>> import numpy as np
        >>> from sklearn_gpcd.io import Recording
        >>> rec = Recording(time=np.arange(5.0), q=np.zeros((5, 1)),
        ...                 qd=np.zeros((5, 1)), current=np.zeros((5, 1)))
        >>> rec.slice(1, 3).n_samples
        2
        """
        sl = np.s_[start:stop]
        changes = {"time": self.time[sl]}
        for key in JOINT_SIGNALS + ("labels",):
            value = getattr(self, key)
            if value is not None:
                changes[key] = value[sl]
        return replace(self, **changes)

    @classmethod
    def concatenate(cls, recordings):
        """Join recordings in time; optional signals kept only if all have them.

        Time stamps of each later recording are shifted to follow the previous
        one, so the result is strictly increasing.

        Examples
        --------
        >>> import numpy as np
        >>> from sklearn_gpcd.io import Recording
        >>> r = Recording(time=np.arange(3.0), q=np.zeros((3, 1)),
        ...               qd=np.zeros((3, 1)), current=np.zeros((3, 1)))
        >>> Recording.concatenate([r, r]).n_samples
        6
        """
        recordings = list(recordings)
        if not recordings:
            raise ValueError("concatenate needs at least one recording")
        times, offset = [np.empty(0)], 0.0
        for rec in recordings:
            if rec.n_samples == 0:  # nothing to shift (and no time[0])
                continue
            t = rec.time - rec.time[0] + offset
            times.append(t)
            step = np.median(np.diff(rec.time)) if rec.n_samples > 1 else 1e-3
            offset = t[-1] + step
        out = {"time": np.concatenate(times)}
        for key in JOINT_SIGNALS + ("labels",):
            values = [getattr(r, key) for r in recordings]
            if all(v is not None for v in values):
                out[key] = np.concatenate(values)
        names = ",".join(r.name for r in recordings if r.name)
        return cls(name=names, units=recordings[0].units, **out)
