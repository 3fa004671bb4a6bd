"""pdr.io.csvtable: the pandas fast path is taken on good tables and gives the values float() gives."""

from __future__ import annotations

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.io import csvtable


def test_good_table_takes_the_fast_path_with_exact_values(monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(5)
    values = rng.normal(size=(400, 2)) * 10.0 ** rng.integers(-12, 12, (400, 2))
    text = "t_ns,x,y\n" + "\n".join(f"{1_700_000_000_000_000_000 + i},{float(a)!r},{b:.17g}"
                                     for i, (a, b) in enumerate(values))

    def no_slow(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        raise AssertionError("the line-by-line path ran on a good table")

    monkeypatch.setattr(csvtable, "_slow", no_slow)
    table = csvtable.parse_table(text, "t.csv", int_columns=("t_ns",))
    lines = text.splitlines()[1:]
    assert table.column("t_ns").tolist() == [int(line.split(",")[0]) for line in lines]
    expected = np.array([[float(f) for f in line.split(",")[1:]] for line in lines])
    assert table.stack(["x", "y"]).tobytes() == expected.tobytes()


def test_float_precision_option_by_pandas_version() -> None:
    assert csvtable.float_precision_option("2.2.3") == "round_trip"
    assert csvtable.float_precision_option("3.0.1") == "round_trip"
    assert csvtable.float_precision_option("3.1.1") is None and csvtable.float_precision_option("4.0.0.dev0+12") is None


def test_bad_value_still_named_by_the_line_by_line_path() -> None:
    with pytest.raises(InputError, match="line 3.*'abc' is not a number|'abc' is not a number.*line 3"):
        csvtable.parse_table("t,x\n1,2.5\n2,abc\n", "t.csv")


def test_first_row_wider_than_the_header_skips_pandas(monkeypatch: pytest.MonkeyPatch) -> None:
    """An x-io log whose first row is 5 MB of commas ran for minutes and took gigabytes: pandas makes a column of every
    field of the row it takes the table's width from. That row is now named by the line-by-line path at once."""
    import pandas as pd

    def no_pandas(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        raise AssertionError("pandas parsed a row wider than the header")

    monkeypatch.setattr(pd, "read_csv", no_pandas)
    with pytest.raises(InputError, match="expected 2 fields .*found 200001") as err:
        csvtable.parse_table("t,x\n" + "," * 200_000 + "\n1,2\n", "t.csv")
    assert err.value.line == 2


def test_a_header_wider_than_any_sensor_log_is_refused_before_parsing(monkeypatch: pytest.MonkeyPatch) -> None:
    """A header of 200 000 columns took pandas 22 s and 577 MB; it is refused at once, naming the header line."""
    import pandas as pd

    def no_pandas(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        raise AssertionError("pandas parsed a table wider than any sensor log")

    monkeypatch.setattr(pd, "read_csv", no_pandas)
    header = ",".join(f"c{i}" for i in range(200_000))
    with pytest.raises(InputError, match="the header names 200000 columns, more than any sensor log has") as err:
        csvtable.parse_table(header + "\n" + ",".join(["1"] * 200_000) + "\n", "wide.csv")
    assert err.value.line == 1
    monkeypatch.undo()
    wide = ",".join(f"c{i}" for i in range(csvtable.MAX_COLUMNS))         # the limit itself is read
    table = csvtable.parse_table(wide + "\n" + ",".join(["1.5"] * csvtable.MAX_COLUMNS) + "\n", "w.csv")
    assert table.column(f"c{csvtable.MAX_COLUMNS - 1}").tolist() == [1.5]
