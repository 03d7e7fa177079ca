"""Plausibility of a live stream's signals, window by window (issue #47, point 5).

A live stream cannot be checked before the work as a file is
(:func:`sklearn_gpcd.workflow.check_signals`): :class:`LiveSignalCheck`
buffers the valid samples and the model's prediction in preallocated
arrays, feeds them to a :class:`~sklearn_gpcd.io.SignalCheck` every
:data:`CHUNK_SECONDS` of stream time and judges every :data:`WINDOW_SECONDS`
(then starts over), so that a column that goes wrong mid-shift is named
within one window, memory stays fixed and a tick only copies three rows.
"""

import math

import numpy as np

#: Stream time [s] between verdicts (long enough that a push is a minority).
WINDOW_SECONDS = 10.0
#: Stream time [s] of samples buffered before they are fed to the check.
CHUNK_SECONDS = 0.5


class LiveSignalCheck:
    """Window-by-window :class:`~sklearn_gpcd.io.SignalCheck` of a live stream.

    Parameters
    ----------
    check : SignalCheck
        Configured with what the detector knows
        (:func:`sklearn_gpcd.workflow.signal_check`).
    sample_time : float
        The stream's sample time [s] (sizes the buffer).

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn_gpcd.io import SignalCheck
    >>> live = LiveSignalCheck(SignalCheck(1), sample_time=0.01)
    >>> found = []
    >>> for k in range(1100):      # at rest, qd and q swapped: qd = -1.5 rad/s
    ...     found += live.add(k * 0.01, [0.0], [-1.5], [1.0], [1.0])
    >>> [f.columns for f in found]
    [['q[0]', 'qd[0]']]
    """

    def __init__(self, check, sample_time):
        self.check = check
        n = max(2, int(math.ceil(CHUNK_SECONDS / sample_time)))
        joints = check.n_joints
        self._buffer = {"t": np.empty(n), **{k: np.empty((n, joints))
                                              for k in ("q", "qd", "current", "predicted")}}
        self._n = 0
        self._start = None

    def add(self, t, q, qd, current, predicted):
        """Buffer one valid sample; returns the findings of a window that just ended.

        Returns
        -------
        findings : list of Finding
            Empty except at the end of a window.
        """
        if self._start is None:
            self._start = t
        b, k = self._buffer, self._n
        b["t"][k] = t
        b["q"][k], b["qd"][k], b["current"][k], b["predicted"][k] = q, qd, current, predicted
        self._n += 1
        if self._n == len(b["t"]):
            self._flush()
        if t - self._start < WINDOW_SECONDS:
            return []
        self._flush()
        found = self.check.findings()
        self.check.reset()
        self._start = None
        return found

    def _flush(self):
        b, n = self._buffer, self._n
        if n:
            self.check.update(b["t"][:n], b["q"][:n], b["qd"][:n], b["current"][:n],
                              b["predicted"][:n])
        self._n = 0

    def reset(self):
        """Forget the open window (after a fault: the stream restarts)."""
        self._n, self._start = 0, None
        self.check.reset()
