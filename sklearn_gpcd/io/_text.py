"""Delimited text tables: delimiter and header sniffing, numeric parsing.

Lines are counted from 1 as an editor shows them (split on ``"\\n"``).
Blank lines and lines starting with ``#`` carry no data and are skipped.
A data line whose field count differs from the header (or, without a
header, from the most common field count) is *malformed*; so is one with a
non-number in a column the caller asks for. Malformed lines are returned
with a reason, never silently discarded.
"""

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
        Lines with the wrong field count: (line number, reason).
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


def read_lines(path):
    """Numbered non-blank, non-comment lines of a text file.

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
        For a missing, empty or binary file.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such file")
    raw = path.read_bytes()
    if not raw.strip():
        raise ValueError(f"{path}: file is empty")
    if b"\x00" in raw[:4096]:
        raise ValueError(
            f"{path}: binary file, not delimited text (UR RTDE binary recordings are not "
            "supported; record with the CSV writer)"
        )
    text = raw.decode("utf-8", errors="replace")
    numbered = []
    for number, line in enumerate(text.split("\n"), start=1):
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
        (number, f"{count} fields, {expected} {n_fields}")
        for (number, _), count, ok in zip(numbered, counts.tolist(), good)
        if not ok
    ]
    return TextTable(source, names, delimiter, n_fields, lines, line_numbers, malformed)


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
