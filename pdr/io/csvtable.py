"""Numeric CSV tables with a header row: fast parsing, and exact line/field diagnostics on bad input.

The fast path hands the text to pandas' C parser; when that fails or the result is suspicious (a short
row filled with NaN, a non-finite value), the table is parsed again line by line with
:func:`pdr.io.text.parse_float_rows` so that the :class:`~pdr.errors.InputError` names the first bad
line and column. Floats are parsed with round-trip precision, integer columns (nanosecond timestamps)
as exact int64.
"""

from __future__ import annotations

import csv
import io
import re
import warnings
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.io.text import drop_cut_off_last_line, parse_float_rows
from pdr.io.time_order import keep_increasing

#: Most columns a table may have: the sensor logs read here have at most 13 (a SensorConnect export), and pandas takes
#: seconds and hundreds of MB for a header of 100 000 (a header of 200 000 columns: 22 s, 577 MB).
MAX_COLUMNS = 1000


@dataclass(frozen=True)
class Table:
    """A parsed table: column name -> (N,) array, and the 1-based file line of every data row."""

    header: tuple[str, ...]
    columns: dict[str, np.ndarray]
    first_line: int
    source: str

    def __len__(self) -> int:
        return int(next(iter(self.columns.values())).size) if self.columns else 0

    def line(self, row: int) -> int:
        """1-based file line number of data row ``row``."""
        return self.first_line + int(row)

    def column(self, name: str) -> np.ndarray:
        """The column called ``name``; :class:`InputError` listing the header if absent."""
        if name not in self.columns:
            raise InputError(f"missing column '{name}' (header has {list(self.header)})", source=self.source,
                             line=self.first_line - 1, field=name)
        return self.columns[name]

    def stack(self, names: Sequence[str]) -> NDArray[np.float64]:
        """(N, len(names)) float64 array of the named columns."""
        return np.column_stack([np.asarray(self.column(n), dtype=np.float64) for n in names]) if names else \
            np.empty((len(self), 0))

    def stack_scaled(self, names: Sequence[str], factor: float, unit: str) -> NDArray[np.float64]:
        """(N, len(names)) float64 array of the named columns (in ``unit``) times ``factor`` (to SI);
        :class:`InputError` naming line and column of a value the factor takes beyond a float (1e308 g).
        """
        raw = self.stack(names)
        with np.errstate(over="ignore"):
            values = raw * factor
        bad = ~np.isfinite(values)
        if bad.any():
            row, col = (int(i) for i in np.argwhere(bad)[0])
            raise InputError(f"value {raw[row, col]:g} {unit} is beyond any float once converted to SI "
                             f"(x {factor:g})", source=self.source, line=self.line(row), field=names[col])
        return values

    def lines(self) -> NDArray[np.int64]:
        """(N,) 1-based file line of every data row."""
        return self.first_line + np.arange(len(self), dtype=np.int64)

    def keep_increasing(self, name: str, notes: list[str]) -> NDArray[np.bool_]:
        """Mask of the rows to keep: rows whose column ``name`` repeats or goes back are dropped with a warning
        naming the line (:func:`pdr.io.time_order.keep_increasing`).
        """
        return keep_increasing(self.column(name), self.source, name, notes, lines=self.lines())


def split_header(line: str, delimiter: str = ",", source: str | None = None) -> list[str]:
    """Field names of a header line (quotes removed, surrounding blanks stripped)."""
    try:
        return [f.strip() for f in next(csv.reader([line], delimiter=delimiter))]
    except csv.Error as exc:
        raise InputError(f"unreadable header line ({exc})", source=source, line=1) from None


def parse_table(text: str, source: str, *, header_line: int = 1, delimiter: str = ",",
                int_columns: Collection[str] = (), nan_columns: Collection[str] = (),
                rename: dict[str, str] | None = None, decimal: str = ".", notes: list[str] | None = None,
                terminated: bool = False, value_form: re.Pattern[str] | None = None) -> Table:
    """Parse a CSV text whose line ``header_line`` (1-based) names the columns and whose later lines are numbers.

    Parameters
    ----------
    text
        The whole file.
    source
        File name for messages.
    header_line
        1-based line of the header; lines before it are ignored.
    delimiter, decimal
        Field separator and decimal mark.
    int_columns
        Columns parsed as exact int64 (after renaming).
    nan_columns
        Columns where an empty field or ``nan`` is allowed (NaN); elsewhere every value must be finite.
    rename
        Header name -> column name, applied before the other options.
    notes
        A reader's warnings: when given, a last line cut off mid-line (:func:`pdr.io.text.drop_cut_off_last_line`)
        is dropped and reported there instead of refused.
    terminated
        With ``notes``: the writer ends every row with a line break, so a last line without one is dropped even
        when it has all its fields (its last value may be cut short).
    value_form
        With ``notes``: the writer's fixed form of every value; a last line without a line break whose last value
        lacks it (and the line before's has it) is dropped.

    Raises
    ------
    InputError
        Empty file or no header, a row with the wrong number of fields, a non-numeric or non-finite value,
        naming file, line and column.
    """
    if notes is not None:
        text = drop_cut_off_last_line(text, source, delimiter, notes, terminated=terminated, value_form=value_form)
    lines = text.splitlines()
    while lines and not lines[-1].strip():
        lines.pop()
    if len(lines) < header_line or not lines[header_line - 1].strip():
        raise InputError("empty file: no header line", source=source, line=header_line)
    raw_header = split_header(lines[header_line - 1], delimiter, source)
    if len(raw_header) > MAX_COLUMNS:
        raise InputError(f"the header names {len(raw_header)} columns, more than any sensor log has (at most "
                         f"{MAX_COLUMNS})", source=source, line=header_line)
    rename = rename or {}
    header = tuple(rename.get(h, h) for h in raw_header)
    if len(set(header)) != len(header):
        dup = next(h for h in header if header.count(h) > 1)
        raise InputError(f"column '{dup}' appears twice in the header", source=source, line=header_line, field=dup)
    data_lines = lines[header_line:]
    first = header_line + 1
    ints = [h for h in header if h in int_columns]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            arrays = _fast(data_lines, header, delimiter, decimal, ints)
    except (ValueError, TypeError, OverflowError, Warning):   # pandas' ParserError is a ValueError
        arrays = None
    if arrays is None or not _plausible(arrays, len(data_lines), header, nan_columns):
        arrays = _slow(data_lines, first, header, source, delimiter, decimal, ints, nan_columns)
    return Table(header, arrays, first, source)


def _fast(data_lines: list[str], header: tuple[str, ...], delimiter: str, decimal: str,
          ints: list[str]) -> dict[str, np.ndarray] | None:
    if not data_lines:
        return {h: np.empty(0, dtype=np.int64 if h in ints else np.float64) for h in header}
    if data_lines[0].count(delimiter) >= len(header):
        # More fields than the header: the exact path names the line. pandas would first make a column of every field
        # of this line, the one it takes the table's width from (a line of 5 million commas: minutes and gigabytes).
        return None
    import pandas as pd  # half a second of imports: only when a table is parsed (not to sniff a format)

    # Integer columns are read as text and converted by numpy, which takes plain integers only: pandas' int64
    # parser would also take "1.7e18", which the exact path refuses as "not an integer".
    dtypes = {i: (str if h in ints else np.float64) for i, h in enumerate(header)}
    frame = pd.read_csv(io.StringIO("\n".join(data_lines)), sep=delimiter, header=None, dtype=dtypes,
                        engine="c", skip_blank_lines=False, decimal=decimal, na_filter=True, keep_default_na=True,
                        float_precision=float_precision_option(pd.__version__))
    if frame.shape[1] != len(header):
        return None
    out: dict[str, np.ndarray] = {}
    for i, h in enumerate(header):
        column = frame.iloc[:, i]
        if h in ints:
            try:
                out[h] = column.to_numpy(dtype=str).astype(np.int64)
            except (ValueError, OverflowError):
                return None  # the exact path names the line and field
        else:
            out[h] = column.to_numpy()
    return out


def float_precision_option(version: str) -> Literal["round_trip"] | None:
    """The ``read_csv`` option for the values :func:`float` gives: ``"round_trip"`` before pandas 3.1; None (the
    default) from 3.1, where every mode uses that converter and the option is deprecated (a warning, which sent
    every table to the slow path here).
    """
    major, minor = (int(p) for p in version.split(".")[:2])
    return "round_trip" if (major, minor) < (3, 1) else None


def _plausible(arrays: dict[str, np.ndarray], n: int, header: tuple[str, ...], nan_columns: Collection[str]) -> bool:
    for h in header:
        a = arrays[h]
        if a.shape != (n,):
            return False
        if a.dtype.kind == "f" and h not in nan_columns and not np.all(np.isfinite(a)):
            return False
        if a.dtype.kind not in "fi":
            return False
    return True


def _slow(data_lines: list[str], first: int, header: tuple[str, ...], source: str, delimiter: str, decimal: str,
          ints: list[str], nan_columns: Collection[str]) -> dict[str, np.ndarray]:
    """Line-by-line parse that reports the first bad line and field."""
    rows: list[list[str]] = []
    for i, line in enumerate(data_lines):
        if not line.strip():
            raise InputError("empty line inside the table", source=source, line=first + i)
        fields = line.split(delimiter)
        if len(fields) != len(header):
            raise InputError(f"expected {len(header)} fields ({', '.join(header)}), found {len(fields)}",
                             source=source, line=first + i)
        fields = [f.strip().strip('"') for f in fields]
        if decimal != ".":
            fields = [f.replace(decimal, ".") for f in fields]
        rows.append(fields)
    line_numbers = list(range(first, first + len(rows)))
    out: dict[str, np.ndarray] = {}
    float_idx = [j for j, h in enumerate(header) if h not in ints and h not in nan_columns]
    if float_idx:
        arr = parse_float_rows([[r[j] for j in float_idx] for r in rows], line_numbers, source,
                               [header[j] for j in float_idx])
        for k, j in enumerate(float_idx):
            out[header[j]] = arr[:, k]
    for j, h in enumerate(header):
        if h in ints:
            vals = np.empty(len(rows), dtype=np.int64)
            for i, r in enumerate(rows):
                try:
                    vals[i] = int(r[j])
                except (ValueError, OverflowError):
                    raise InputError(f"'{r[j][:40]}' is not an integer", source=source, line=first + i,
                                     field=h) from None
            out[h] = vals
        elif h in nan_columns:
            fvals = np.empty(len(rows))
            for i, r in enumerate(rows):
                try:
                    fvals[i] = float(r[j]) if r[j] else np.nan
                except ValueError:
                    raise InputError(f"'{r[j][:40]}' is not a number", source=source, line=first + i,
                                     field=h) from None
            if np.isinf(fvals).any():
                i = int(np.flatnonzero(np.isinf(fvals))[0])
                raise InputError(f"value {fvals[i]} is not finite", source=source, line=first + i, field=h)
            out[h] = fvals
    return {h: out[h] for h in header}
