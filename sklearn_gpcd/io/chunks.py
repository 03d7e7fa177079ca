"""Long recordings read in chunks: memory bounded by the chunk, not the file.

:func:`iter_recording_chunks` reads a delimited text recording (UR RTDE CSV
or any CSV through a column map) a block of about :data:`CHUNK_BYTES` at a
time and yields each block as a :class:`Recording`, through the same reader
as :func:`load_recording` (every text reader reads the block it is given,
:data:`~sklearn_gpcd.io._text.READ_SPAN`). Memory is that of one chunk
(about ten times its text), whatever the file's length. ``gpcd calibrate``
and ``gpcd monitor`` stream files larger than :data:`STREAM_BYTES` this way.

What changes against one whole read: the row cleaning of
:mod:`sklearn_gpcd.io._validation` runs per chunk (an exact duplicate or a
glitch is found within its chunk, ``max_dropped`` holds per chunk, each
chunk that drops rows says so in its own warning), and a row at the start
of a chunk whose time stamp does not follow the previous chunk's last one is
dropped (out of order across the boundary). On a file with none of those the
chunks are the whole read cut in pieces, sample for sample.

Refused before any row is parsed, naming the file: a header of more than
:data:`MAX_COLUMNS` columns or a first line longer than
:data:`MAX_LINE_BYTES` (no robot log has that; a wrong delimiter or a
concatenated file does).
"""

import warnings
from pathlib import Path

import numpy as np

from ._text import (
    MAX_COLUMNS,
    READ_SPAN,
    Span,
    check_file,
    check_width,
    is_number,
    sniff_delimiter,
    split_fields,
    text_codec,
)
from ._validation import RecordingWarning
from .load import check_problems, detect_format, load_recording

#: Bytes of text per chunk (about 60k rows of a 25-column RTDE log).
CHUNK_BYTES = 16 * 2**20
#: Files larger than this are streamed by ``gpcd calibrate`` and ``gpcd monitor``.
STREAM_BYTES = 64 * 2**20
#: Longest first (header) line read [bytes].
MAX_LINE_BYTES = 2**20
#: The formats read in chunks; the others are read whole.
CHUNKED_FORMATS = ("rtde", "csv")


def _first_line(path, limit=MAX_LINE_BYTES):
    """``(number, text, end)`` of the first non-blank, non-comment line: its 1-based
    number, its stripped text and the byte offset after it."""
    number, offset = 0, 0
    with open(path, "rb") as handle:
        while True:
            raw = handle.readline(limit + 1)
            if not raw:
                raise ValueError(f"{path}: file is empty (only blank or comment lines)")
            number += 1
            offset += len(raw)
            if len(raw) > limit and not raw.endswith(b"\n"):
                raise ValueError(
                    f"{path}: line {number} is longer than {limit // 2**20} MiB: not a robot "
                    "log (no line break? a wrong delimiter?); keep only the columns the "
                    "model needs (e.g. with cut -d, -f) and give the file again")
            line = raw.decode("utf-8", "replace").strip()
            if line and not line.startswith("#"):
                return number, line, offset


def _check_width(path, line):
    fields = split_fields(line, sniff_delimiter(line))
    check_width(path, fields)
    return fields


def _has_header(fields, header):
    if header == "infer":
        return sum(not is_number(f) for f in fields) > len(fields) / 2
    return header is True


def _spans(path, header_number, header_line, header_end, has_header, chunk_bytes):
    """The :class:`Span` of each chunk: cut at the first line end after every
    ``chunk_bytes``; a tail shorter than a quarter chunk joins the last one."""
    size = Path(path).stat().st_size
    if has_header:
        start, first, head = header_end, header_number + 1, ((header_number, header_line),)
    else:
        start, first, head = 0, 1, ()
    with open(path, "rb") as handle:
        while start < size:
            stop = start + chunk_bytes
            if stop + chunk_bytes // 4 >= size:
                stop = size
            else:
                handle.seek(stop)
                handle.readline()
                stop = handle.tell()
            handle.seek(start)
            n_lines = handle.read(stop - start).count(b"\n")
            yield Span(start, stop, first, head)
            start, first = stop, first + n_lines


def iter_recording_chunks(path, format="auto", column_map=None, *, accept=None,
                          chunk_bytes=None, **kwargs):
    """Read a recording in chunks of about ``chunk_bytes`` of text each.

    Text recordings (:data:`CHUNKED_FORMATS`, UTF-8) are read chunk by chunk
    as described in the module docstring; other formats (and text with a
    UTF-16/32 byte-order mark) are read whole, as one chunk.

    Parameters
    ----------
    path : str or Path
    format, column_map, **kwargs
        As for :func:`~sklearn_gpcd.io.load_recording`.
    accept : collection of str, default=None
        As for :func:`~sklearn_gpcd.io.load_recordings`, checked per chunk
        (but for ``"short"``: a chunk may be short).
    chunk_bytes : int, default=None
        Text per chunk [bytes] (None: :data:`CHUNK_BYTES`).

    Yields
    ------
    chunk : Recording
        Consecutive pieces of the recording, time strictly increasing across
        them; ``metadata["chunk"]`` counts from 0, ``metadata["text_bytes"]``
        is the size of its text.

    Raises
    ------
    ValueError
        As the readers do, naming the file; and, before any row is parsed, a
        first line of more than :data:`MAX_COLUMNS` columns or
        :data:`MAX_LINE_BYTES` bytes.

    Examples
    --------
    >>> import numpy as np, pathlib, tempfile
    >>> from sklearn_gpcd import io
    >>> t = np.arange(5000) * 0.002
    >>> rec = io.Recording(time=t, q=np.c_[np.sin(t)], qd=np.c_[np.cos(t)], current=np.c_[t])
    >>> path = io.write_rtde_csv(rec, pathlib.Path(tempfile.mkdtemp()) / "long.csv")
    >>> chunks = list(io.iter_recording_chunks(path, chunk_bytes=30_000))
    >>> len(chunks), [c.n_samples for c in chunks][:3]
    (9, [564, 550, 547])
    >>> bool(np.array_equal(np.concatenate([c.current for c in chunks]), rec.current))
    True
    """
    path = Path(path)
    chunk_bytes = CHUNK_BYTES if chunk_bytes is None else int(chunk_bytes)
    fmt = detect_format(path) if format == "auto" else format
    if kwargs.get("time_scale", 1.0) != 1.0 and fmt == "rtde":
        raise ValueError(f"{path}: time_scale (--time-scale) applies to CSV, NPZ and "
                         "one-value-per-line logs only")
    bom = False
    if fmt in CHUNKED_FORMATS:
        check_file(path)
        with open(path, "rb") as handle:
            bom = text_codec(handle.read(4)) not in (None, "utf-8-sig")
    if fmt not in CHUNKED_FORMATS or bom:
        rec = load_recording(path, format=fmt, column_map=column_map, **kwargs)
        if accept is not None:
            check_problems(path, rec, accept)
        yield rec
        return
    number, line, end = _first_line(path)
    fields = _check_width(path, line)
    has_header = _has_header(fields, kwargs.get("header", "infer"))
    last = -np.inf
    for index, span in enumerate(_spans(path, number, line, end, has_header, chunk_bytes)):
        token = READ_SPAN.set(span)
        try:
            rec = load_recording(path, format=fmt, column_map=column_map, **kwargs)
        finally:
            READ_SPAN.reset(token)
        if accept is not None:  # a short chunk is not a short recording
            check_problems(path, rec, {*accept, "short"})
        first = int(np.searchsorted(rec.time, last, side="right"))
        if first:
            warnings.warn(f"{path}: {first} row(s) from line {span.first_line} on dropped: "
                          f"their time stamps do not follow {last!r} s of the rows before "
                          "(out of order)", RecordingWarning, stacklevel=2)
            if first == rec.n_samples:
                continue
            rec = rec.slice(first)
        last = float(rec.time[-1])
        rec.metadata.update(chunk=index, text_bytes=span.stop - span.start)
        yield rec


def streamed(paths, limit=None):
    """Whether any of ``paths`` is a text file larger than ``limit`` bytes.

    Parameters
    ----------
    paths : iterable of str or Path
    limit : int, default=None
        Bytes (None: :data:`STREAM_BYTES`).

    Returns
    -------
    big : bool

    Examples
    --------
    >>> streamed(["no/such/file.csv"])
    False
    """
    limit = STREAM_BYTES if limit is None else limit
    return any(Path(p).is_file() and Path(p).stat().st_size > limit for p in paths)
