"""What a :class:`~sklearn_gpcd.monitoring.MonitorSession` saw: the events in
words, the live statistics in fixed memory, the figures and the report."""

import math
import warnings

from pathlib import Path

import numpy as np

from .._atomic import atomic_write

#: Line colours of the bands in a multi-band figure (C3, red, shades the events).
BAND_COLORS = ("C0", "C2", "C4", "C1", "C5", "C6", "C8", "C9")


class _LogHistogram:
    """Percentiles of positive values in fixed memory: geometric bins (1 % wide)."""

    LOW, HIGH, RATIO = 1e-7, 1e3, 1.01

    def __init__(self):
        self._log_ratio = math.log(self.RATIO)
        n = math.ceil(math.log(self.HIGH / self.LOW) / self._log_ratio) + 2
        self.counts = np.zeros(n, dtype=np.int64)
        self.n, self.max, self.min = 0, -math.inf, math.inf

    def add(self, value):
        if not value > 0:  # 0, negative or NaN: the lowest bin
            index = 0
        else:
            index = int(math.log(value / self.LOW) / self._log_ratio) + 1
            index = min(max(index, 0), self.counts.size - 1)
        self.counts[index] += 1
        self.n += 1
        self.max, self.min = max(self.max, value), min(self.min, value)

    def percentile(self, q):
        """The ``q``-th percentile (the bin's centre, clipped to the values seen)."""
        rank = q / 100.0 * (self.n - 1)
        index = int(np.searchsorted(np.cumsum(self.counts), math.floor(rank) + 1))
        centre = self.LOW * self.RATIO ** (index - 0.5) if index > 0 else 0.0
        return min(max(centre, self.min), self.max)


def _link_text(event):
    """The link estimate of an event, e.g. ``"link 2 (0.93)"``."""
    if event.get("link") is None:
        return "-"
    return f"{event['link_group']} ({event['link_confidence']:.2f})"


def _force_text(event):
    """The force estimate of an event [N], or ``"no model"``; ``*``: ill-conditioned."""
    force = event.get("force_N", "no model")
    if force is None:
        return "n/a"
    if isinstance(force, str):
        return force
    return f"{force:.0f}" + ("" if event.get("force_well_conditioned") else "*")


class _SessionReport:
    """Statistics, text, figures and the report dict of a session."""

    def events_text(self):
        """The events in words: counts, per band, and one row per event.

        Returns
        -------
        text : str
        """
        n_samples = sum(r["n_samples"] for r in self.recordings)
        n_faults = sum(r["n_sensor_faults"] for r in self.recordings)
        out = [f"{len(self.events)} alarm event(s) in {len(self.recordings)} recording(s), "
               f"{n_samples} samples ({n_faults} sensor faults)"]
        if self.task is not None:
            taught = sum(r.get("taught_s", 0.0) for r in self.recordings)
            untaught = sum(r.get("untaught_motion_s", 0.0) for r in self.recordings)
            moving = taught + untaught
            out.append(f"  taught task: {taught:.1f} s in taught motion, {untaught:.1f} s of "
                       f"untaught motion ({100 * untaught / moving if moving else 0:.0f} % of the "
                       "motion: the calibrated thresholds there)")
        out += self._protection_lines()
        if self.multiband:
            for b, label in enumerate(self.band_labels, start=1):
                n_events = sum(b in e["bands"] for e in self.events)
                out.append(f"  band {b} ({label}) alarmed in {n_events} event(s)")
        if not self.events:
            return "\n".join(out)
        width = max(9, *(len(e["recording"]) for e in self.events))
        columns = [("recording", f"<{width}", lambda e: e["recording"]),
                   ("start [s]", ">9", lambda e: f"{e['start_s']:.3f}"),
                   ("end [s]", ">9", lambda e: f"{e['end_s']:.3f}"),
                   ("joints", "<12", lambda e: ",".join(map(str, e["joints"]))),
                   (f"peak |m| [{self.units}]", ">12", lambda e: f"{e['peak_A']:.3f}"),
                   ("delay [s]", ">9", lambda e: f"{e['delay_s']:.3f}")]
        columns += [("link", "<18", _link_text), ("force [N]", ">9", _force_text)]
        if self.task is not None:
            columns.append(("taught", "<6", lambda e: "yes" if e.get("taught") else "no"))
        if self.multiband:
            columns.insert(4, ("bands", "<6", lambda e: ",".join(map(str, e["bands"]))))
        out.append("  ".join(f"{name:{spec}}" for name, spec, _ in columns))
        for e in self.events:
            out.append("  ".join(f"{value(e):{spec}}" for _, spec, value in columns))
        if any(_force_text(e).endswith("*") for e in self.events):
            out.append("  force *: the joints up to the link do not see every force "
                       "direction (rank < 3 or ill-conditioned): a lower bound")
        return "\n".join(out)

    def _protection_lines(self):
        """``protected at <= X N`` over the recordings' moving time (with a model)."""
        lines = []
        for name in ("taught", "untaught"):
            figures = [r["protected_N"][name] for r in self.recordings
                       if name in r.get("protected_N", {})]
            if figures:
                worst = max(figures, key=lambda f: f["median"])
                motion = f"{name} motion" if self.task is not None else "while moving"
                lines.append(f"  protected at <= {worst['median']:.0f} N at the flange "
                             f"{motion} (median; 90 % of the time <= {worst['p90']:.0f} N"
                             + (", worst recording" if len(figures) > 1 else "") + ")")
        never = sum(r.get("protected_N", {}).get("never_protected_samples", 0)
                    for r in self.recordings)
        if never:
            lines.append(f"  {never} moment(s) in motion where some force at the flange "
                         "is never seen (a singular pose)")
        return lines

    def summary_text(self, live=False):
        """:meth:`events_text`, then (``live``) the tick latency and drops, and the
        faults and how the stream ended when the exit status is not 0.

        Parameters
        ----------
        live : bool, default=False
            A live or replayed stream: add :meth:`live_statistics`.

        Returns
        -------
        text : str
        """
        out = [self.events_text()]
        stats = self.live_statistics() if live else None
        if stats is not None:
            out.append(f"  {stats['n_ticks']} ticks; latency receive -> decision p50 "
                       f"{stats['latency_ms_p50']:.3f} ms, p99 {stats['latency_ms_p99']:.3f} "
                       f"ms, max {stats['latency_ms_max']:.3f} ms; dropped samples "
                       f"{stats['dropped_samples']}; decisions at most "
                       f"{stats['behind_stream_ms_max']:.1f} ms behind the stream's clock")
        if self.exit_status:
            blind = sum(f["blind_s"] or 0.0 for f in self.faults)
            out.append(f"  {self.n_blind} fault(s): blind {blind:.3f} s in total"
                       + (f"; the stream ended abnormally: {self.end_reason}"
                          if self.abnormal_end else "")
                       + f" (exit status {self.exit_status})")
        return "\n".join(out)

    def plot(self, key, folder):
        """One figure of recording ``key`` (``keep_series``): one axis per joint,
        alarm events shaded, alarms marked.

        One band: the monitoring signal and its per-regime thresholds [A].
        Several bands: each band's ``|m|`` over its threshold (per regime), so
        that every band crosses at 1.

        Parameters
        ----------
        key : str
            The recording (its name in :meth:`start`).
        folder : path-like
            Where to write ``<key stem>.png``.

        Returns
        -------
        path : Path or None
            None (with a warning) when matplotlib is not installed.
        """
        try:
            import matplotlib

            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
        except ImportError:
            warnings.warn("matplotlib is not installed; no figure: pip install matplotlib "
                          "(or 'sklearn-gpcd[plot]'), or drop --plot", UserWarning,
                          stacklevel=2)
            return None
        s = self.series
        t = np.asarray(s["t"])
        signal, regime = np.asarray(s["signal"]), np.asarray(s["regime"], dtype=int)
        alarms = np.asarray(s["alarms"], dtype=bool)
        n = signal.shape[2] if signal.ndim == 3 else 0
        protected = np.asarray(s["protected"], dtype=float)
        extra = int(protected.size == t.size and np.isfinite(protected).any())
        fig, axes = plt.subplots(max(n, 1) + extra, 1,
                                 figsize=(9, 1.6 * (max(n, 1) + extra) + 0.8),
                                 sharex=True, squeeze=False)
        events = [e for e in self.events if e["recording"] == key]
        draw = self._draw_ratios if self.multiband else self._draw_signal
        for j in range(n):
            ax = axes[j, 0]
            for k, e in enumerate(events):
                ax.axvspan(e["start_s"], e["end_s"], color="C3", alpha=0.15,
                           label="alarm event" if k == 0 else None)
            ax.set_ylabel(draw(ax, t, signal[:, :, j], regime, j), fontsize=8)
            if alarms[:, j].any():
                ax.plot(t[alarms[:, j]], np.zeros(alarms[:, j].sum()), "|", color="k", ms=8,
                        label="alarm")
            ax.tick_params(labelsize=7)
            ax.legend(fontsize=6, loc="upper right")
        if extra:
            ax = axes[-1, 0]
            ax.plot(t, protected, lw=0.8, color="C2", label="moving (10 Hz)")
            ax.set_yscale("log")
            ax.set_ylabel("protected at\n<= X [N]", fontsize=8)
            ax.tick_params(labelsize=7)
            ax.legend(fontsize=6, loc="upper right")
        axes[-1, 0].set_xlabel("t [s]")
        fig.suptitle(f"{key}: " + ("each band's |m| over its threshold (per regime), alarms"
                                   if self.multiband else
                                   "causal monitoring signal, per-regime thresholds, alarms"),
                     fontsize=9)
        fig.tight_layout()
        path = Path(folder) / f"{Path(key).stem}.png"
        try:
            atomic_write(path, lambda handle: fig.savefig(handle, dpi=80, format="png"))
        finally:
            plt.close(fig)
        return path

    def _draw_signal(self, ax, t, signal, regime, j):
        """One band: joint ``j``'s signal and its thresholds ``+-`` (per regime); the y label."""
        ax.plot(t, signal[:, 0], lw=0.7, color="C0", label="monitoring signal m")
        band = self.thresholds[0][regime[:, 0], j]
        ax.plot(t, band, lw=0.7, color="C1",
                label="threshold (" + "/".join(self.regime_names) + ")")
        ax.plot(t, -band, lw=0.7, color="C1")
        return f"joint {j + 1} [{self.units}]"

    def _draw_ratios(self, ax, t, signal, regime, j):
        """Several bands: joint ``j``'s ``|m| / threshold`` per band, and 1; the y label."""
        for b, label in enumerate(self.band_labels):
            ratio = np.abs(signal[:, b]) / self.thresholds[b][regime[:, b], j]
            ax.plot(t, ratio, lw=0.7, color=BAND_COLORS[b % len(BAND_COLORS)],
                    label=f"band {b + 1} ({label})")
        ax.axhline(1.0, lw=0.7, ls="--", color="k", label="threshold")
        return f"joint {j + 1}\n|m| / threshold"

    # ------------------------------------------------------------ statistics
    def _statistics(self, t, received, decided):
        """Fixed-size live statistics: latency histogram, drops, lag behind the stream."""
        self._n_ticks += 1
        self._latency.add(decided - received)
        if not math.isfinite(t):
            return
        previous, self._stat_stamp = self._stat_stamp, t
        if previous is not None:
            step = t - previous
            if step > 0:
                if self._step is None:
                    self._steps.append(step)
                    if len(self._steps) == 100:
                        self._fix_step()
                else:
                    self._count_drops(step)
        rel = t - self.t0 if self.t0 is not None else 0.0
        if self._first_decided is None:
            self._first_decided, self._first_rel = decided, rel
        else:
            behind = (decided - self._first_decided) - (rel - self._first_rel)
            self._behind_max = max(self._behind_max, behind)

    def _fix_step(self):
        self._step = float(np.median(self._steps))
        for step in self._steps:
            self._count_drops(step)
        self._steps = []

    def _count_drops(self, step):
        if self._step > 0:
            self._dropped += max(round(step / self._step) - 1, 0)

    def live_statistics(self):
        """Tick latency (receive -> decision) percentiles and dropped samples.

        Returns
        -------
        stats : dict or None
            ``n_ticks``, ``latency_ms_p50``, ``latency_ms_p99``,
            ``latency_ms_max``, ``behind_stream_ms_max``, ``dropped_samples``
            (None without live ticks). Percentiles come from a histogram
            with 1 % wide bins (fixed memory).
        """
        if not self._n_ticks:
            return None
        if self._step is None and self._steps:
            self._fix_step()
        behind = self._behind_max if math.isfinite(self._behind_max) else 0.0
        return {"n_ticks": int(self._n_ticks),
                "latency_ms_p50": self._latency.percentile(50) * 1e3,
                "behind_stream_ms_max": behind * 1e3,
                "latency_ms_p99": self._latency.percentile(99) * 1e3,
                "latency_ms_max": self._latency.max * 1e3,
                "dropped_samples": int(self._dropped)}

    def report(self):
        """What the session saw, for the JSON report (on every exit path).

        Returns
        -------
        report : dict
            ``recordings``, ``events``, ``live`` (:meth:`live_statistics`),
            ``faults``, ``n_blind``, ``hook_failures``, ``signal_findings``
            (implausible signals of a live stream, per window), ``state``
            and ``end`` (``reason``, ``abnormal``, ``exit_status``).
        """
        self._reap()
        return {"recordings": self.recordings, "events": self.events,
                "live": self.live_statistics(), "faults": self.faults,
                "n_blind": self.n_blind, "hook_failures": self.hook_failures,
                "signal_findings": self.signal_findings, "state": self.state,
                "end": {"reason": self.end_reason, "abnormal": bool(self.abnormal_end),
                        "exit_status": self.exit_status}}
