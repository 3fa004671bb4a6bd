"""Shared text-reader helpers: int64 nanosecond timestamps from parsed numbers."""

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.io.text import timestamps_ns


def test_timestamps_ns_is_exact_for_integer_units_and_rounds_seconds():
    ms = np.array([1574246849288.0, 1574246849308.0])
    assert timestamps_ns(ms, "f", "t", multiplier=1_000_000).tolist() == [1574246849288000000, 1574246849308000000]
    assert timestamps_ns(np.array([0.0000000014, -1.5]), "f", "t", scale=1e9).tolist() == [1, -1500000000]


@pytest.mark.parametrize("bad", [1e60, -1e60, 9.3e18])
def test_timestamps_far_in_the_future_or_past_are_an_input_error_naming_the_line(bad):
    with pytest.raises(InputError, match="out of range") as err:
        timestamps_ns(np.array([1.0, bad]), "log.txt", "time", line_numbers=[7, 8])
    assert (err.value.line, err.value.field) == (8, "time")
