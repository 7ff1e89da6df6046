"""Reads a numeric table (CSV or whitespace-separated) with a header row, naming the bad cell on error."""

from __future__ import annotations

import io
import re
import warnings
from pathlib import Path

import numpy as np

from dampnet.data.types import DataError


def sniff_delimiter(header: str) -> str | None:
    """',' or ';' or tab if the header uses it, else None (any whitespace)."""
    for d in (",", ";", "\t"):
        if d in header:
            return d
    return None


def split_header(header: str, delimiter: str | None) -> list[str]:
    parts = header.split(delimiter) if delimiter else header.split()
    return [p.strip().strip('"').strip("'") for p in parts]


def read_table(path: Path, skip_lines: int = 0, has_header: bool = True
               ) -> tuple[list[str], np.ndarray, int]:
    """(column names, data [n, k] float64, number of lines before the data) of a text table.

    Blank lines are not allowed inside data. Raises DataError naming file, line
    and column of the first cell that is not a number or a row of wrong length.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except UnicodeDecodeError as e:
        raise DataError(f"{path}: not a text file ({e.reason}): expected CSV or whitespace-separated text")
    lines = text.splitlines()
    while lines and not lines[-1].strip():
        lines.pop()
    if len(lines) <= skip_lines:
        raise DataError(f"{path}: empty: expected a header row and data rows")
    first = lines[skip_lines]
    delimiter = sniff_delimiter(first) if has_header else (sniff_delimiter(first) if "," in first or ";" in first or "\t" in first else None)
    if has_header:
        names = split_header(first, delimiter)
        if any(not n for n in names):
            raise DataError(f"{path}: line {skip_lines + 1}: empty column name in header: expected a name for every column")
        n_before = skip_lines + 1
    else:
        names = []
        n_before = skip_lines
    body = lines[n_before:]
    if not body:
        raise DataError(f"{path}: no data rows after line {n_before}: expected numeric rows")
    ncol = len(names) if names else len(split_header(body[0], delimiter))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            data = np.loadtxt(io.StringIO("\n".join(body)), delimiter=delimiter, ndmin=2, dtype=np.float64)
        if data.shape[1] != ncol:
            raise ValueError
        return (names or [f"col{k}" for k in range(ncol)]), data, n_before
    except (ValueError, UserWarning):
        pass
    # slow path: locate the problem
    for i, line in enumerate(body):
        cells = split_header(line, delimiter)
        lineno = n_before + i + 1
        if len(cells) != ncol:
            raise DataError(f"{path}: line {lineno}: expected {ncol} columns, got {len(cells)}")
        for j, c in enumerate(cells):
            try:
                float(c)
            except ValueError:
                col = names[j] if names else f"{j + 1}"
                raise DataError(f"{path}: line {lineno}, column {col!r}: expected a number, got {c!r}") from None
    raise DataError(f"{path}: could not be read as a numeric table")  # pragma: no cover


_SAFE = re.compile(r"^[A-Za-z0-9_.\-]+$")


def safe_name(s: str) -> bool:
    """True if `s` can be a file name or column name without quoting."""
    return bool(_SAFE.match(s))
