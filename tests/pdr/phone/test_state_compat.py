"""Saved session states of the layout before the stage classes (format 1, written by that pipeline: see
``tools/regen_golden.py``) resume and continue the walk exactly as that pipeline did; states that cannot be resumed
are refused with a message saying to reprocess."""

import gzip
import json

import pytest

from pdr import state_codec
from pdr.errors import InputError
from pdr.phone.pipeline import STATE_FORMAT, PdrPipeline
from tests.conftest import load_tool

regen_golden = load_tool("regen_golden")
same_rows = regen_golden.same_rows


def test_same_rows_tolerates_rounding_only():
    assert same_rows([{"t": 1.0630590752148663, "m": "walk"}], [{"t": 1.063059075215051, "m": "walk"}])
    assert not same_rows([{"t": 1.0631}], [{"t": 1.0630}])
    assert not same_rows([{"m": "walk"}], [{"m": "stand"}])
    assert not same_rows([{"t": 1.0}], [{"t": 1.0, "u": 2.0}])


def _old_state(name: str) -> dict:
    return state_codec.loads(gzip.decompress(regen_golden.state_path(name).read_bytes()))


@pytest.mark.parametrize("name", sorted(regen_golden.STATE_WALKS))
def test_a_format_1_state_resumes_and_gives_the_golden_rows(name):
    old = _old_state(name)
    assert "format" not in old and old["pending"] is not None      # written by the old layout, mid-walk
    rows = regen_golden.resumed_rows(name)
    golden = json.loads(regen_golden.rows_path(name).read_text())
    assert sum(r["type"] == "step" for r in golden) >= 10
    assert same_rows(rows, golden)
    # Saved again, it is a current state with the same content.
    p = PdrPipeline.from_state(old)
    again = p.state()
    # prev_q (the pocket's attitude at the previous stride) is obsolete since the device-frame continuity.
    assert again["format"] == STATE_FORMAT and set(old) - {"prev_q"} <= set(again)


@pytest.mark.parametrize(("edit", "match"), [
    (lambda d: d.pop("history"), r"KeyError: 'history'.*reprocess the session"),
    (lambda d: d.update(pending={"s": 1}), r"TypeError.*reprocess the session"),
    (lambda d: d.update(format=STATE_FORMAT + 1), r"format 3; this version reads formats 1 to 2.*reprocess"),
    (lambda d: d.update(format="2"), r"format '2'.*reprocess"),
])
def test_a_state_that_cannot_be_resumed_is_refused_with_a_reprocess_message(edit, match):
    d = _old_state("hand_escalator")
    edit(d)
    with pytest.raises(InputError, match=match):
        PdrPipeline.from_state(d)
    with pytest.raises(InputError, match="must be an object.*reprocess"):
        PdrPipeline.from_state([])  # type: ignore[arg-type]
