"""One rule for samples whose timestamp repeats or goes backwards, shared by every reader.

Phones repeat a timestamp now and then (a resaved file, a jittery ``SENSOR_DELAY_FASTEST`` clock, a MobiFall
gyroscope file that repeats one time once) and sometimes step back by a sample. Such a sample is dropped with a
warning naming the file and the line (or the field of a JSON message): a sample is kept when its time is strictly
after every earlier kept sample, so the first of a repeated timestamp is kept. The data are refused (an
:class:`~pdr.errors.InputError` naming the first offending line) only when they are unusable: when more than
:data:`MAX_BACKWARD_FRACTION` of the samples (and more than one) go back before an earlier one, the clock is broken
(one sample far in the future would otherwise silently drop everything after it). Repeats alone never make data
unusable.

Times are compared as the stream will hold them: a reader whose file gives float seconds applies the rule to the
int64 nanoseconds it stores (:func:`pdr.io.text.timestamps_ns`), so rows less than 1 ns apart (a clock repeating at
the file's resolution, 12.3456789012 then 12.34567890121 s) are repeats, dropped, not a stream the data model refuses.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError

#: Largest fraction of a stream's samples that may go back in time before the clock is considered broken.
MAX_BACKWARD_FRACTION = 0.01


def file_name(source: str) -> str:
    """The file part of a reader's source (``archive.zip:folder/file.csv`` -> ``file.csv``), for warnings."""
    return source.replace("\\", "/").rsplit("/", 1)[-1].rsplit(":", 1)[-1]


def keep_increasing(t: NDArray[np.generic], source: str, field: str, warnings: list[str], *,
                    lines: Sequence[int] | NDArray[np.int64] | None = None,
                    places: Sequence[str] | None = None, what: str = "",
                    keep_repeats: bool = False) -> NDArray[np.bool_]:
    """Mask of the samples to keep: those strictly later than every earlier kept sample.

    Parameters
    ----------
    t
        (N,) timestamps in the file's own unit, in file order.
    source, field
        File (as the reader names it) and time column, for the warning and the error.
    warnings
        The reader's warnings; one line is appended when samples are dropped.
    lines
        (N,) 1-based file line of each sample.
    places
        (N,) where each sample is in a message (``payload[3]``), when there are no lines; without either, samples
        are named by index (``field[i]``).
    what
        Prefix naming the stream inside a multi-stream file (``GYRO``), or empty.
    keep_repeats
        Keep samples that repeat the latest time (only those going back are dropped), for a reader that merges
        repeats itself (the driving magnetometer's two readings per timestamp are averaged).

    Raises
    ------
    InputError
        More than one sample and more than :data:`MAX_BACKWARD_FRACTION` of them go back in time (a broken clock).
    """
    t = np.asarray(t)
    keep = np.ones(t.size, dtype=bool)
    if t.size < 2:
        return keep
    latest = np.maximum.accumulate(t)[:-1]
    keep[1:] = t[1:] >= latest if keep_repeats else t[1:] > latest
    if keep.all():
        return keep
    dropped = np.flatnonzero(~keep)
    back = dropped[t[dropped] < latest[dropped - 1]]
    backward = int(back.size)
    prefix = f"{what} " if what else ""

    def where(i: int) -> tuple[int | None, str, str, str]:
        """Line (or None), place, where it is said and the times of sample ``i`` after the latest before it."""
        line = int(lines[i]) if lines is not None else None
        place = f"{field}[{i}]" if places is None else f"{places[i]}.{field}"
        return line, place, f"line {line}" if line is not None else place, f"{latest[i - 1]} then {t[i]}"

    if backward > max(1.0, MAX_BACKWARD_FRACTION * t.size):
        line, place, at, example = where(int(back[0]))      # the first going back, not an earlier repeat
        raise InputError(f"{prefix}time goes backwards in {backward} of {t.size} samples (first at {at}: "
                         f"{example}): the clock is broken", source=source, line=line,
                         field=field if line is not None else place)
    _, _, at, example = where(int(dropped[0]))
    warnings.append(f"{file_name(source)}: {prefix}dropped {dropped.size} of {t.size} samples whose time repeats "
                    f"({dropped.size - backward}) or goes backwards ({backward}), first at {at} ({example})")
    return keep


def keep_lines(lines: Sequence[int] | NDArray[np.int64], keep: NDArray[np.bool_]) -> list[int]:
    """The line numbers of the kept samples."""
    return [int(n) for n, k in zip(lines, keep, strict=True) if k]
