"""Shared text-reader helpers: int64 nanosecond timestamps from parsed numbers; the array view of a text's lines
(:class:`pdr.io.text.Lines`): the lines :meth:`str.splitlines` finds and each line's record tag."""

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.io.text import ascii_lines, parse_float_rows, timestamps_ns


def test_timestamps_ns_is_exact_for_integer_units_and_rounds_seconds():
    ms = np.array([1574246849288.0, 1574246849308.0])
    assert timestamps_ns(ms, "f", "t", multiplier=1_000_000).tolist() == [1574246849288000000, 1574246849308000000]
    assert timestamps_ns(np.array([0.0000000014, -1.5]), "f", "t", scale=1e9).tolist() == [1, -1500000000]


@pytest.mark.parametrize("bad", [1e60, -1e60, 9.3e18])
def test_timestamps_far_in_the_future_or_past_are_an_input_error_naming_the_line(bad):
    with pytest.raises(InputError, match="out of range") as err:
        timestamps_ns(np.array([1.0, bad]), "log.txt", "time", line_numbers=[7, 8])
    assert (err.value.line, err.value.field) == (8, "time")


def test_numeric_rows_equal_the_line_by_line_values() -> None:
    from pdr.io.text import numeric_rows, utf8_lines
    rng = np.random.default_rng(11)
    values = np.concatenate([rng.normal(size=300) * 10.0 ** rng.integers(-9, 9, 300), [0.0, -0.0, 1e-30]])
    fields = [f"{v:.9g}" for v in values] + [repr(float(v)) for v in values[:19]] + [" 7.171631E-4 ", "1_0"]
    rows = [fields[i:i + 3] for i in range(0, len(fields), 3)]
    body = [",".join(r) for r in rows]
    text = "#skipped\n" + "\n".join(body[:50]) + "\r\n\n" + "\n".join(body[50:])
    got = numeric_rows(text.encode(), 3, skip_lines=1)
    assert got is not None
    lines = text.splitlines()
    numbers = [n for n in range(2, len(lines) + 1) if lines[n - 1]]
    assert got[1].tolist() == numbers
    assert got[0].tobytes() == parse_float_rows([lines[n - 1].split(",") for n in numbers], numbers, "t",
                                                ["a", "b", "c"]).tobytes()
    assert utf8_lines("\u00e9\n1\n".encode()) is not None
    for bad in ("1,2,3\n4,5\n", "1,2,x\n", "1,2,nan\n", "1,2,3\n\u2028\n", "\u00e9\r1\n"):
        assert numeric_rows(bad.encode(), 3) is None, bad
    assert numeric_rows("1,2,3\n".encode("utf-16"), 3) is None


@pytest.mark.parametrize("seed", range(4))
def test_lines_and_their_tags_are_those_of_the_text(seed):
    rng = np.random.default_rng(seed)
    for _ in range(800):
        raw = bytes(rng.choice(list(b"ab;7\n\n"), int(rng.integers(0, 40))).tolist())
        if rng.random() < 0.3:
            raw = raw.replace(b"\n", b"\r\n")
        if rng.random() < 0.5:
            raw = raw.rstrip(b"\r\n")
        lines = ascii_lines(raw)
        assert lines is not None
        want = [x.encode() for x in raw.decode().splitlines()]
        assert [lines.text(i) for i in range(lines.start.size)] == want
        code, fifth = lines.head_code()
        assert code.tolist() == [int.from_bytes(x[:4], "little") for x in want]
        assert fifth.tolist() == [x[4] if len(x) > 4 else 0 for x in want]


def test_a_text_is_read_in_place_when_it_ends_its_last_line():
    raw = b"ACCE;1\nGYRO;2\n"
    lines = ascii_lines(raw)
    assert lines is not None
    assert not lines.buf.flags.writeable
    assert lines.buf.tobytes() == raw
    assert lines.start.tolist() == [0, 7] and lines.length.tolist() == [6, 6]
    empty = ascii_lines(b"")
    assert empty is not None and empty.start.size == 0 and empty.head_code()[0].size == 0
