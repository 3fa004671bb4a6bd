"""The state codec: exact round trips of nested states with numpy arrays, and clear errors on bad bytes."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from pdr import state_codec
from pdr.errors import InputError

arrays = st.one_of(
    hnp.arrays(np.float64, hnp.array_shapes(min_dims=0, max_dims=3, max_side=5),
               elements=st.floats(allow_nan=True, allow_infinity=True)),
    hnp.arrays(np.int64, hnp.array_shapes(max_dims=2, max_side=5)),
    hnp.arrays(np.bool_, hnp.array_shapes(max_dims=2, max_side=5)),
)


@given(a=arrays, scalar=st.floats(allow_nan=False) | st.integers(-2**62, 2**62) | st.text() | st.none())
def test_round_trip_is_bit_exact(a, scalar):
    state = {"a": a, "nested": [{"b": a[..., ::-1] if a.ndim else a}, scalar], "s": "x"}
    back = state_codec.loads(state_codec.dumps(state))
    for got, want in ((back["a"], a), (back["nested"][0]["b"], state["nested"][0]["b"])):
        assert got.dtype == want.dtype and got.shape == want.shape
        assert got.tobytes() == np.ascontiguousarray(want).tobytes()
        assert got.flags.writeable
    assert back["nested"][1] == scalar and back["s"] == "x"


def test_arrays_are_much_smaller_and_numpy_scalars_become_numbers():
    a = np.random.default_rng(0).normal(size=(3000, 4))
    blob = state_codec.dumps({"a": a, "n": np.float64(1.5), "k": np.int64(3)})
    assert len(blob) < 8 * a.size + 200  # raw bytes plus a small header, vs ~19 characters per number as text
    back = state_codec.loads(blob)
    assert back["n"] == 1.5 and back["k"] == 3


def _corrupt(header: bytes, data: bytes = b"") -> bytes:
    return state_codec.MAGIC + len(header).to_bytes(4, "little") + header + data


@pytest.mark.parametrize("blob", [
    b"not a state", b'{"x": 1}', b"\xff\xfe", state_codec.MAGIC, state_codec.MAGIC + b"\x05\x00\x00\x00{",
    _corrupt(b'{"x": {"__ndarray__": ["zz", [1], 0, 8]}}', bytes(8)),       # unknown dtype
    _corrupt(b'{"x": {"__ndarray__": ["f8", [2], 0, 16]}}', bytes(8)),      # truncated data
    _corrupt(b'{"x": {"__ndarray__": ["f8", [3], 0, 16]}}', bytes(16)),     # shape and size disagree
])
def test_bad_bytes_are_an_input_error(blob):
    with pytest.raises(InputError, match="not a stored processing state"):
        state_codec.loads(blob)


def test_unsupported_objects_are_refused_when_writing():
    with pytest.raises(TypeError, match="cannot store"):
        state_codec.dumps({"x": object()})
    with pytest.raises(TypeError, match="dtype"):
        state_codec.dumps({"x": np.array(["a"])})


@pytest.mark.parametrize("dtype", [np.int8, np.int16, np.uint8, np.uint16, np.uint32, np.float16])
def test_small_integer_and_half_float_arrays_round_trip(dtype):
    a = np.arange(-3, 9).reshape(3, 4).astype(dtype)
    back = state_codec.loads(state_codec.dumps({"a": a}))["a"]
    assert back.dtype == a.dtype and back.tobytes() == a.tobytes()
