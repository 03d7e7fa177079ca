"""The progress bar of the ``gpcd`` command (and of any caller that wants one).

One implementation for the package. On a terminal the bar is redrawn in
place; written to a file that is not a terminal (``gpcd train ... 2>
train.log``, CI) it prints one line at most every ``interval`` seconds,
which tqdm does not do (it prints nothing with ``disable=None`` or one line
of carriage-return-joined updates), hence our own.
"""

import sys
import time


class ProgressBar:
    """A progress bar with an ETA on stderr.

    On a terminal the bar is redrawn in place; otherwise (a log, a pipe) one
    line is printed at most every ``interval`` seconds and at the end.
    """

    def __init__(self, label, total, *, stream=None, interval=5.0, enabled=True):
        self.label, self.total, self.done = label, max(int(total), 1), 0
        self.stream = sys.stderr if stream is None else stream
        self.interval, self.enabled = interval, enabled
        self.start = self._last = time.perf_counter()
        self._tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._draw(force=True)

    def update(self, n=1):
        self.done = min(self.done + n, self.total)
        self._draw(force=self.done == self.total)

    def _draw(self, force=False):
        if not self.enabled:
            return
        now = time.perf_counter()
        if not (force or self._tty or now - self._last >= self.interval):
            return
        self._last = now
        elapsed = now - self.start
        width = 24
        filled = int(width * self.done / self.total)
        if self.done == self.total:
            tail = f"done in {seconds(elapsed)}"
        elif self.done:
            tail = f"{seconds(elapsed)} elapsed, ETA {seconds(elapsed * (self.total / self.done - 1))}"
        else:
            tail = "ETA after the first step"
        line = f"{self.label} [{'#' * filled}{'.' * (width - filled)}] {self.done}/{self.total} {tail}"
        end = "\n" if (not self._tty or self.done == self.total) else ""
        print(("\r" if self._tty else "") + line, end=end, file=self.stream, flush=True)


def seconds(value):
    value = int(round(value))
    return f"{value // 60}m{value % 60:02d}s" if value >= 60 else f"{value}s"
