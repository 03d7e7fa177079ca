"""``gpcd calibrate`` on logs longer than memory: :func:`calibrate_detector_streamed`.

The same calibration as :func:`~sklearn_gpcd.workflow.calibrate_detector`,
with memory bounded by one recording (or ``--split`` piece), not by the
files' length:

1. each file is read in chunks (:func:`~sklearn_gpcd.io.iter_recording_chunks`)
   into raw float64 files of a work folder (:class:`RecordingSpool`; only the
   time stamps stay in memory), its signal ranges widened chunk by chunk;
2. the pieces are cut as :func:`~sklearn_gpcd.workflow.split_recordings`
   cuts them, and each piece's causal inputs are computed when the
   calibration asks for them, one piece at a time;
3. :func:`~sklearn_gpcd.detection.calibrate_across_recordings` with its
   ``folder``: each band's series in files, levels from the peaks.

Thresholds, margins, candidates and nested false alarms equal the whole
computation's (``tests/test_streaming_input.py``). What would not fit is
refused before the work, from each file's first chunk: a piece of more than
:data:`MAX_PIECE_ROWS` rows (the message gives the ``--split`` that fits),
or a work folder with too little free disk.
"""

import shutil
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..io import JOINT_SIGNALS, Recording, iter_recording_chunks, signal_ranges
from .calibration import (
    _calibrate_blocks,
    _check_files,
    _check_model,
    _check_pieces,
    check_recordings,
    piece_bounds,
    recording_keys,
)

#: Most rows of one recording or piece calibrated at a time (about 1.5 kB of
#: memory each at the peak: its signals, causal inputs, residual and series).
MAX_PIECE_ROWS = 300_000
#: The options of :func:`~sklearn_gpcd.workflow.calibrate_detector`, its defaults.
CALIBRATION_DEFAULTS = dict(regimes=True, rest_reference=None, settle_time=None,
                            select="auto", bands=(), band_candidates=(), braking=None)
#: Work-folder bytes per row and band (its signals, then each band's series).
SPOOL_ROW_BYTES, SERIES_ROW_BYTES = 8 * 25, 8 * 7


class RecordingSpool:
    """A recording read in chunks into raw float64 files of ``folder``.

    Only ``time`` stays in memory; :meth:`piece` reads rows back.

    Parameters
    ----------
    folder : Path
        Work folder (created).
    chunks : iterable of Recording
        The chunks, in time order.
    on_chunk : callable, default=None
        Called with each chunk (checks, ranges).

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib
    >>> from sklearn_gpcd.io import Recording
    >>> t = np.arange(6.0)
    >>> parts = [Recording(time=t[:3], q=np.c_[t[:3]], qd=np.c_[t[:3]], current=np.c_[t[:3]]),
    ...          Recording(time=t[3:], q=np.c_[t[3:]], qd=np.c_[t[3:]], current=np.c_[t[3:]])]
    >>> spool = RecordingSpool(pathlib.Path(tempfile.mkdtemp()), parts)
    >>> spool.n_samples, spool.piece(2, 5).q.ravel().tolist()
    (6, [2.0, 3.0, 4.0])
    """

    def __init__(self, folder, chunks, on_chunk=None):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        times, handles, self.widths = [], {}, {}
        try:
            for chunk in chunks:
                if on_chunk is not None:
                    on_chunk(chunk)
                if not times:
                    self.name, self.units = chunk.name, chunk.units
                    self.metadata = dict(chunk.metadata)
                    for key in JOINT_SIGNALS:
                        if getattr(chunk, key) is not None:
                            self.widths[key] = getattr(chunk, key).shape[1]
                            handles[key] = open(self.folder / f"{key}.f64", "wb")
                times.append(chunk.time)
                for key, handle in handles.items():
                    np.ascontiguousarray(getattr(chunk, key), dtype=float).tofile(handle)
        finally:
            for handle in handles.values():
                handle.close()
        self.time = np.concatenate(times)

    @property
    def n_samples(self):
        return len(self.time)

    @property
    def duration(self):
        return float(self.time[-1] - self.time[0])

    def piece(self, start, stop):
        """Rows ``start:stop`` as a :class:`~sklearn_gpcd.io.Recording`."""
        signals = {}
        for key, width in self.widths.items():
            signals[key] = np.fromfile(self.folder / f"{key}.f64", dtype=float,
                                       count=(stop - start) * width,
                                       offset=start * width * 8).reshape(-1, width)
        return Recording(time=self.time[start:stop], name=self.name, units=self.units,
                         metadata=self.metadata, **signals)


class _Pieces(Mapping):
    """Pieces of spooled recordings, read when asked: ``key -> Recording``
    (or, with ``features``, its detector input block)."""

    def __init__(self, bounds, features=None):
        self.bounds, self.features = bounds, features

    def __getitem__(self, key):
        spool, (start, stop) = self.bounds[key]
        rec = spool.piece(start, stop)
        if self.features is None:
            return rec
        # deferred: gpcd starts without scikit-learn (test_architecture.py)
        from ..detection import stack_currents

        return stack_currents(self.features.transform(rec), rec.current)

    def __iter__(self):
        return iter(self.bounds)

    def __len__(self):
        return len(self.bounds)


def check_fits_streamed(paths, split, folder, n_bands=1, reader=None, max_rows=None):
    """Refuse, before the work, a calibration whose pieces or work files would not fit.

    From each file's first chunk: its rows (file size over the chunk's bytes
    per row) and sample time give the rows of a piece (the file, or
    ``split`` seconds of it), at most :data:`MAX_PIECE_ROWS`; and the work
    folder needs :data:`SPOOL_ROW_BYTES` plus :data:`SERIES_ROW_BYTES` per
    band for each row.

    Parameters
    ----------
    paths : list of Path
    split : float or None
        ``--split`` [s].
    folder : Path
        Work folder (its disk).
    n_bands : int, default=1
        Band series kept per row (bands and candidates).
    reader : dict, default=None
        Reader options (column map, ...).
    max_rows : int, default=None
        Most rows of a piece (None: :data:`MAX_PIECE_ROWS`).

    Returns
    -------
    firsts : list of Recording
        The first chunk of each file (what the estimates were made on).

    Raises
    ------
    ValueError
        Naming the file and the ``--split`` that fits, or the folder and the
        room it needs (``TMPDIR``).

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib
    >>> from sklearn_gpcd.io import Recording, write_rtde_csv
    >>> t = np.arange(20_000) * 0.002
    >>> rec = Recording(time=t, q=np.c_[t], qd=np.c_[t * 0], current=np.c_[t * 0])
    >>> path = write_rtde_csv(rec, pathlib.Path(tempfile.mkdtemp()) / "a.csv")
    >>> len(check_fits_streamed([path], None, path.parent))
    1
    >>> check_fits_streamed([path], None, path.parent, max_rows=1000)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: ...a.csv: about 20002 rows (40 s at 0.002 s) calibrated at once: ... --split 2 ...
    """
    max_rows = MAX_PIECE_ROWS if max_rows is None else max_rows
    total, firsts = 0, []
    for path in paths:
        first = next(iter_recording_chunks(path, **(reader or {})))
        firsts.append(first)
        if first.n_samples < 2:
            continue
        step = float(np.median(np.diff(first.time)))
        size = Path(path).stat().st_size
        rows = int(size / (first.metadata.get("text_bytes", size) / first.n_samples))
        total += rows
        piece = rows if split is None else min(rows, int(split / step))
        if piece > max_rows:
            fits = max(1, int(max_rows * step * (1 + 1e-9)))
            raise ValueError(
                f"{path}: about {rows} rows ({rows * step:.0f} s at {step:g} s) calibrated at "
                f"once{'' if split is None else f' (pieces of --split {split:g} s)'}: more "
                f"than the {max_rows} rows a piece may have in memory; cut the log "
                f"into pieces with --split {fits:g} (seconds, or less)")
    need = total * (SPOOL_ROW_BYTES + n_bands * SERIES_ROW_BYTES)
    free = shutil.disk_usage(folder).free
    if need > free:
        raise ValueError(f"{folder}: the calibration of long logs needs about {need / 1e9:.1f} "
                         f"GB of work files there, {free / 1e9:.1f} GB are free; set TMPDIR "
                         "to a folder with more room")
    return firsts


def calibrate_detector_streamed(trained, paths, folder, *, reader=None, split=None,
                                robot=None, accept=(), on_read=None, **options):
    """:func:`~sklearn_gpcd.workflow.calibrate_detector` on files read in chunks.

    Parameters
    ----------
    trained : TrainedModel
    paths : list of Path
        Text recordings (RTDE or CSV), at least 2 or one with ``split``.
    folder : Path
        Work folder for the recordings' signals and the series (about
        :data:`SPOOL_ROW_BYTES` + :data:`SERIES_ROW_BYTES` per band and row;
        the caller removes it).
    reader : dict, default=None
        Reader options (``column_map``, ``accept``, ...) for
        :func:`~sklearn_gpcd.io.iter_recording_chunks`.
    split, robot, accept, **options
        As for :func:`~sklearn_gpcd.workflow.calibrate_detector`
        (``regimes``, ``rest_reference``, ``settle_time``, ``select``,
        ``bands``, ``band_candidates``, ``braking``).
    on_read : callable, default=None
        Called after each file is read (a progress bar's ``update``).

    Returns
    -------
    calibrated : CalibratedDetector

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib
    >>> from sklearn_gpcd.io import Recording, write_rtde_csv
    >>> from sklearn_gpcd.workflow import train_model
    >>> noise = np.random.default_rng(0).normal(scale=0.05, size=(3000, 1))
    >>> t = np.arange(3000) * 0.01
    >>> def rec(phase):  # one joint swinging, its current twice its angle
    ...     q = np.c_[np.sin(t + phase)]
    ...     return Recording(time=t, q=q, qd=np.c_[np.cos(t + phase)], current=2 * q + noise,
    ...                      target_current=2 * q)
    >>> trained = train_model([rec(0.0)], model="sp_c", n_support=50)
    >>> root = pathlib.Path(tempfile.mkdtemp())
    >>> path = write_rtde_csv(rec(1.0), root / "long.csv")
    >>> calibrated = calibrate_detector_streamed(trained, [path], root / "work", split=10.0,
    ...                                          select=False)
    >>> calibrated.calibration["recordings"]
    ['long.csv#1', 'long.csv#2']
    """
    paths = [Path(p) for p in paths]
    _check_files(len(paths), split, set())
    _check_model(trained)
    options = {**CALIBRATION_DEFAULTS, **options}
    features, folder = trained.features, Path(folder)
    ranges = [trained.training.get("signal_ranges")]
    known_noise = (ranges[0] or {}).get("current_noise")
    noises, chunk_noises = [], []

    def on_chunk(chunk):
        check_recordings([chunk], "the model", n_joints=features.n_joints_,
                         units=trained.training.get("units"))
        ranges[0] = signal_ranges([chunk], ranges[0])
        noise = signal_ranges([chunk]).get("current_noise")
        if noise is not None:
            chunk_noises.append(noise)

    spools = []
    for i, path in enumerate(paths):
        spools.append(RecordingSpool(folder / f"recording{i}",
                                     iter_recording_chunks(path, **(reader or {})), on_chunk))
        if chunk_noises:  # a recording's median step: the median of its chunks' (bounded)
            noises.append(np.median(chunk_noises, axis=0))
            chunk_noises.clear()
        if on_read is not None:
            on_read()
    if noises:
        noise = np.min(noises, axis=0)
        if known_noise is not None:
            noise = np.fmin(noise, known_noise)
        ranges[0]["current_noise"] = [float(v) for v in noise]
    _check_files(2, split, {spool.units for spool in spools})
    bounds = {}
    for key, spool in zip(recording_keys(spools), spools):
        cut = ([(key, (0, spool.n_samples))] if split is None
               else piece_bounds(key, spool.n_samples, spool.duration, split))
        bounds.update((k, (spool, span)) for k, span in cut)
    if split is not None:
        _check_pieces(len(bounds), max(spool.duration for spool in spools), split)
    times = {key: spool.time[start:stop] for key, (spool, (start, stop)) in bounds.items()}
    return _calibrate_blocks(
        trained, _Pieces(bounds, features), times, _Pieces(bounds), ranges[0],
        units=spools[0].units, n_files=len(paths), split=split, robot=robot, accept=accept,
        options=options, folder=folder / "series")
