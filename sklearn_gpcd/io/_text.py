"""Delimited text tables: delimiter and header sniffing, numeric parsing.

Lines are counted from 1 as an editor shows them (split on ``"\\n"``).
Blank lines and lines starting with ``#`` carry no data and are skipped.
Text is UTF-8; a byte-order mark selects UTF-8-with-BOM (Excel's "CSV
UTF-8"), UTF-16 or UTF-32 instead (:func:`decode_text`).
A data line whose field count differs from the header (or, without a
header, from the most common field count) is *malformed*; so is one with a
non-number in a column the caller asks for, and a copy of the header line
(a restarted logger appending to the same file). Malformed lines are returned
with a reason, never silently discarded.
"""

from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: Delimiters tried in this order; None means "runs of whitespace".
DELIMITERS = (",", ";", "\t")


@dataclass
class TextTable:
    """The data lines of a delimited text file.

    Attributes
    ----------
    source : str
        File path, for messages.
    names : list of str or None
        Header names, None for a headerless file.
    delimiter : str or None
        Field separator; None splits on whitespace.
    n_fields : int
        Expected fields per line.
    lines : list of str
        Well-formed data lines (right field count).
    line_numbers : ndarray of int
        1-based line number of each entry of ``lines``.
    malformed : list of (int, str)
        Lines with the wrong field count, or repeating the header line:
        (line number, reason).
    """

    source: str
    names: list
    delimiter: str
    n_fields: int
    lines: list
    line_numbers: np.ndarray
    malformed: list

    @property
    def n_rows(self):
        """Data lines in the file, well-formed or not."""
        return len(self.lines) + len(self.malformed)


def split_fields(line, delimiter):
    """Fields of one line (whitespace-split when ``delimiter`` is None).

    Examples
    --------
    >>> split_fields("1.0  2.0 3", None)
    ['1.0', '2.0', '3']
    >>> split_fields("a,b,", ",")
    ['a', 'b', '']
    """
    return line.split() if delimiter is None else line.split(delimiter)


def sniff_delimiter(line):
    """First of ``, ; TAB`` found in ``line``, else None (whitespace).

    Examples
    --------
    >>> sniff_delimiter("timestamp actual_q_0 actual_q_1") is None
    True
    >>> sniff_delimiter("0.1,0.2")
    ','
    """
    for delimiter in DELIMITERS:
        if delimiter in line:
            return delimiter
    return None


def is_number(text):
    """True when ``float(text)`` succeeds.

    Examples
    --------
    >>> is_number(" 1e-3 "), is_number("actual_q_0")
    (True, False)
    """
    try:
        float(text)
    except ValueError:
        return False
    return True


#: Byte-order marks and the codec each selects, longest first.
BOMS = (
    (b"\xff\xfe\x00\x00", "utf-32"),
    (b"\x00\x00\xfe\xff", "utf-32"),
    (b"\xef\xbb\xbf", "utf-8-sig"),
    (b"\xff\xfe", "utf-16"),
    (b"\xfe\xff", "utf-16"),
)
#: Largest share of undecodable UTF-8 bytes still read as text (the bad
#: cells then fail as non-numbers, row by row).
MAX_BAD_BYTES = 0.01


def text_codec(raw):
    """Codec named by the byte-order mark ``raw`` starts with, else None.

    Parameters
    ----------
    raw : bytes

    Returns
    -------
    codec : str or None

    Examples
    --------
    >>> text_codec("x".encode("utf-16")), text_codec(b"x")
    ('utf-16', None)
    """
    return next((codec for bom, codec in BOMS if raw.startswith(bom)), None)


def check_file(path):
    """Raise ValueError unless ``path`` is an existing regular file.

    Parameters
    ----------
    path : Path

    Examples
    --------
    >>> import tempfile, pathlib
    >>> check_file(pathlib.Path(tempfile.mkdtemp()))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: ...: is a folder, not a file
    """
    if path.is_dir():
        raise ValueError(f"{path}: is a folder, not a file")
    if not path.exists():
        raise ValueError(f"{path}: no such file")
    if not path.is_file():
        raise ValueError(f"{path}: not a regular file")


def decode_text(raw, source):
    """Decode the bytes of a text recording.

    A byte-order mark picks the codec (:data:`BOMS`); otherwise the bytes
    must be UTF-8 (ASCII is UTF-8). A NUL byte in the first 4 KiB without a
    BOM means a binary file (a NUL further on only spoils its row). Up to
    1 % undecodable bytes (say a Latin-1 ``\\xb0`` in a comment or one
    corrupted cell) are replaced by U+FFFD so that the row they sit in is
    reported and dropped like any other malformed row; more is an error.

    Parameters
    ----------
    raw : bytes
        File content.
    source : str or Path
        File name for messages.

    Returns
    -------
    text : str

    Raises
    ------
    ValueError
        Empty content, binary content or text in another encoding.

    Examples
    --------
    >>> decode_text(b"\\xef\\xbb\\xbftimestamp,actual_q_0\\n", "a.csv")[:9]
    'timestamp'
    >>> decode_text("t,q\\n".encode("utf-16"), "b.csv")
    't,q\\n'
    >>> decode_text(bytes(range(0x80, 0x100)), "c.csv")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: c.csv: not UTF-8 text: 128 of 128 bytes (100 %) ...
    """
    codec = text_codec(raw)
    if codec is not None:
        try:
            text = raw.decode(codec)
        except UnicodeDecodeError as exc:
            raise ValueError(
                f"{source}: starts with a {codec.upper()} byte-order mark but byte "
                f"{exc.start} is not {codec.upper()} ({exc.reason})") from None
    else:
        if not raw.strip():
            raise ValueError(f"{source}: file is empty")
        nul = raw.find(b"\x00", 0, 4096)
        if nul >= 0:
            raise ValueError(
                f"{source}: binary file, not delimited text (NUL byte at offset {nul}; UR "
                "RTDE binary recordings are not supported, record with the CSV writer)")
        text = raw.decode("utf-8", errors="replace")
        n_bad = text.count("\ufffd") - raw.decode("utf-8", errors="ignore").count("\ufffd")
        if n_bad > MAX_BAD_BYTES * len(raw):
            offset = _first_bad_byte(raw)
            raise ValueError(
                f"{source}: not UTF-8 text: {n_bad} of {len(raw)} bytes "
                f"({100 * n_bad / len(raw):.0f} %) are not valid UTF-8, the first at byte "
                f"offset {offset}; save the file as UTF-8 (another encoding or binary data?)")
    if not text.strip():
        raise ValueError(f"{source}: file is empty")
    return text


def _first_bad_byte(raw):
    try:
        raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        return exc.start
    return -1


#: Peak memory of reading a text recording, in multiples of its size (measured on
#: main ffd0123: 1M rows, 255 MB, peaked at 2.6 GB; 10M rows passed 4.2 GB).
TEXT_MEMORY_FACTOR = 10.0


def available_memory():
    """Bytes of memory available to a new allocation (``MemAvailable``), or None.

    Examples
    --------
    >>> available_memory() is None or available_memory() > 0
    True
    """
    try:
        with open("/proc/meminfo") as info:
            for line in info:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def check_fits(path, factor=TEXT_MEMORY_FACTOR, available=None):
    """Refuse, before reading, a text file whose reading would not fit in memory.

    Reading keeps the text, its lines and the parsed values at once: about
    ``factor`` times the file size at the peak.

    Parameters
    ----------
    path : Path
    factor : float, default=TEXT_MEMORY_FACTOR
    available : int or None, default=None
        Bytes available (None: :func:`available_memory`; no check when
        unknown).

    Raises
    ------
    ValueError
        Naming the file, its size, the estimate and what to do.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "big.csv"
    >>> _ = path.write_text("0,1,2\\n" * 1000)
    >>> check_fits(path, available=10**9)
    >>> check_fits(path, available=1000)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: ...big.csv: 6 kB of text needs about 60 kB of memory to read, ...
    """
    available = available_memory() if available is None else available
    size = path.stat().st_size
    need = factor * size
    if available is not None and need > available:
        raise ValueError(
            f"{path}: {_bytes(size)} of text needs about {_bytes(need)} of memory to read, "
            f"more than the {_bytes(available)} available; split the file into shorter "
            "recordings (e.g. split -l), or keep only the columns the model needs")


def _bytes(n):
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.3g} {unit}"
        n /= 1000


@dataclass(frozen=True)
class Span:
    """Bytes ``start:stop`` of a text file, read as if they followed ``head``.

    Attributes
    ----------
    start, stop : int
        Byte offsets of the data lines (``stop`` at a line end or the end of
        the file).
    first_line : int
        1-based line number of the line at ``start``.
    head : tuple of (int, str)
        Numbered lines put first (the header line, when the file has one).
    """

    start: int
    stop: int
    first_line: int
    head: tuple = ()


#: The :class:`Span` :func:`read_lines` reads instead of the whole file (set
#: by :func:`sklearn_gpcd.io.iter_recording_chunks` around each chunk, so that
#: every text reader reads chunks unchanged); None: the whole file.
READ_SPAN = ContextVar("READ_SPAN", default=None)


#: Most columns a text recording may have (UR RTDE logs every output: a few hundred).
MAX_COLUMNS = 10_000


def check_width(source, fields):
    """Refuse a first line of more than :data:`MAX_COLUMNS` fields, naming the file.

    Examples
    --------
    >>> check_width("wide.csv", ["x"] * 20_000)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: wide.csv: the first line has 20000 columns, more than the 10000 ...
    """
    if len(fields) > MAX_COLUMNS:
        raise ValueError(
            f"{source}: the first line has {len(fields)} columns, more than the "
            f"{MAX_COLUMNS} a robot log has (a wrong delimiter or files pasted side by "
            "side?); keep only the columns the model needs (time, q, qd, current and the "
            "controller signals, e.g. with cut -d, -f) and give the file again")


def read_lines(path):
    """Numbered non-blank, non-comment lines of a text file (or of :data:`READ_SPAN`).

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    numbered : list of (int, str)
        1-based line number and stripped text.

    Raises
    ------
    ValueError
        For a missing path, a folder, an empty or binary file, bytes that
        are not text (see :func:`decode_text`), or a file that would not fit
        in memory (:func:`check_fits`).
    """
    path = Path(path)
    check_file(path)
    span = READ_SPAN.get()
    if span is None:
        check_fits(path)
        text, first, numbered = decode_text(path.read_bytes(), path), 1, []
    else:  # one chunk of a streamed file (sklearn_gpcd.io.iter_recording_chunks)
        with open(path, "rb") as handle:
            handle.seek(span.start)
            text = decode_text(handle.read(span.stop - span.start), path)
        first, numbered = span.first_line, list(span.head)
    for number, line in enumerate(text.split("\n"), start=first):
        line = line.strip()
        if line and not line.startswith("#"):
            numbered.append((number, line))
    if not numbered:
        raise ValueError(f"{path}: file is empty (only blank or comment lines)")
    return numbered


def read_text_table(path, header="infer", delimiter=None):
    """Split a delimited text file into header and well-formed data lines.

    Parameters
    ----------
    path : str or Path
    header : {"infer", None, True}, default="infer"
        ``"infer"``: the first line is a header when most of its fields are
        not numbers (a data line with one garbage cell stays data).
        ``True``: it is a header. ``None``: no header.
    delimiter : str, default=None
        Field separator; None sniffs ``, ; TAB`` and falls back to whitespace.

    Returns
    -------
    table : TextTable
    """
    source = str(path)
    numbered = read_lines(path)
    first_number, first_line = numbered[0]
    if delimiter is None:
        delimiter = sniff_delimiter(first_line)
    elif delimiter == " ":
        delimiter = None
    first_fields = split_fields(first_line, delimiter)
    check_width(source, first_fields)
    if header == "infer":
        n_text = sum(not is_number(f) for f in first_fields)
        has_header = n_text > len(first_fields) / 2
    elif header is None or header is False:
        has_header = False
    elif header is True:
        has_header = True
    else:
        raise ValueError(f"header must be 'infer', True or None, got {header!r}")
    names = None
    if has_header:
        names = [f.strip().strip("\"'") for f in first_fields]
        numbered = numbered[1:]
        if not numbered:
            raise ValueError(
                f"{source}: too short, only a header (line {first_number}) and no data rows")
    numbered, repeats = _split_off_repeated_header(numbered, first_line, first_number, names)
    counts = np.array([len(split_fields(line, delimiter)) for _, line in numbered])
    if names is not None:
        n_fields = len(names)
    else:
        values, freq = np.unique(counts, return_counts=True)
        n_fields = int(values[np.argmax(freq)])
    good = counts == n_fields
    lines = [line for (_, line), ok in zip(numbered, good) if ok]
    line_numbers = np.array([number for (number, _), ok in zip(numbered, good) if ok], dtype=int)
    expected = "the header has" if names is not None else "most lines have"
    malformed = [
        (number, f"{count} field{'s' if count != 1 else ''}, {expected} {n_fields}")
        for (number, _), count, ok in zip(numbered, counts.tolist(), good)
        if not ok
    ]
    malformed = sorted(malformed + repeats)
    return TextTable(source, names, delimiter, n_fields, lines, line_numbers, malformed)


def _split_off_repeated_header(numbered, header_line, header_number, names):
    """Data lines equal to the header (a restarted logger appending) -> malformed."""
    if names is None:
        return numbered, []
    repeats = [(number, f"repeats the header (line {header_number}); a second recording "
                "appended?") for number, line in numbered if line == header_line]
    if not repeats:
        return numbered, []
    return [(n, line) for n, line in numbered if line != header_line], repeats


def parse_columns(table, indices, labels):
    """Parse the chosen columns of the well-formed lines as float64.

    Fast path: :func:`numpy.loadtxt` on all lines. If that fails, each line
    is parsed alone and a line with a non-number in a chosen column becomes
    malformed (the reason names the column and the text found).

    Parameters
    ----------
    table : TextTable
    indices : list of int
        0-based column indices to parse.
    labels : list of str
        Column labels for messages (``"'actual_q_0'"``, ``"3 (q[2])"``).

    Returns
    -------
    values : ndarray of shape (n_good, len(indices))
    line_numbers : ndarray of int, shape (n_good,)
    malformed : list of (int, str)
        The table's malformed lines plus the non-numeric ones, by line.
    """
    indices = list(indices)
    if not table.lines:
        return np.empty((0, len(indices))), table.line_numbers, list(table.malformed)
    try:
        values = np.loadtxt(table.lines, delimiter=table.delimiter, usecols=indices,
                            ndmin=2, dtype=float, comments=None)
        return values, table.line_numbers, list(table.malformed)
    except ValueError:
        pass
    rows, keep, malformed = [], [], list(table.malformed)
    for number, line in zip(table.line_numbers.tolist(), table.lines):
        fields = split_fields(line, table.delimiter)
        row = []
        for index, label in zip(indices, labels):
            try:
                row.append(float(fields[index]))
            except ValueError:
                text = fields[index].strip()
                shown = text if len(text) <= 40 else text[:37] + "..."
                malformed.append((number, f"column {label}: {shown!r} is not a number"))
                break
        else:
            rows.append(row)
            keep.append(number)
    malformed.sort(key=lambda item: item[0])
    values = np.array(rows, dtype=float).reshape(len(rows), len(indices))
    return values, np.array(keep, dtype=int), malformed
