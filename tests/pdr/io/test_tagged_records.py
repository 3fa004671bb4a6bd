"""pdr.io.tagged_records: the one-pass scan of a tagged text log gives what the array path over its lines gives (the
IPIN reader's two compiled paths), and stops, for the caller's other paths, where it does not take a text."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.io import ipin
from pdr.io.tagged_records import GUESS_LINES, MAX_EXTRA_LINES, MAX_OTHER_TAGS, scan_tagged
from tests.pdr.io.test_ipin import EDGES, GOOD, HEADER, _same_recording


def _paths(tmp_path: Path, text: str) -> tuple[Any, Any, Any]:
    """(scan, arrays, exact) readings of ``text`` as an IPIN log."""
    p = tmp_path / "log.txt"
    p.write_bytes(text.encode())
    raw = p.read_bytes()
    return ipin._read_text_fast(p, raw), ipin._read_text_arrays(p, raw, True), ipin._read_text_exact(p, raw)


@pytest.mark.parametrize("text", [GOOD, EDGES, GOOD.rstrip("\n"), EDGES + "\n\n", HEADER + "SOUN;1;2\n" + GOOD,
                                  GOOD + "WIFI;0.01;100.0;net\nACCE;0.09;100.04;1;2;3;3"])
def test_the_scan_reads_what_the_array_path_and_the_exact_path_read(tmp_path, text):
    scan, arrays, exact = _paths(tmp_path, text)
    assert scan is not None and arrays is not None
    _same_recording(scan, arrays)
    _same_recording(scan, exact)
    for kind in scan.streams:
        assert scan.streams[kind].values.flags.c_contiguous


def test_a_tag_that_comes_late_is_counted_and_read_whole(tmp_path):
    """A tag whose records outnumber the first guess (from the first GUESS_LINES lines, where it has none): the exact
    counts, and a second pass."""
    body = "".join(f"ACCE;{i};{i};0;0;9;3\n" for i in range(1, GUESS_LINES + 100))
    body += "".join(f"GYRO;{i};{i};0;0;1;3\n" for i in range(GUESS_LINES + 100, GUESS_LINES + 400))  # > 1 per 128
    scan, arrays, _ = _paths(tmp_path, body)
    assert scan is not None and arrays is not None
    _same_recording(scan, arrays)
    assert len(scan.stream("acc")) == GUESS_LINES + 99 and len(scan.stream("gyro")) == 300


@pytest.mark.parametrize("extra", [
    "WIFI;0.01;100.0;net\x0bname;2412\n",                                  # a vertical tab in a skipped record
    "WIFI;0.01;100.0;net\rname;2412\n",                                    # a lone CR
    "".join(f"T{i:03d};1\n" for i in range(MAX_OTHER_TAGS + 1)),         # more other tags than the table holds
    "AB;1\n" * (MAX_EXTRA_LINES + 1),                                     # more extra lines than the table holds
    "ACCE;0.090;100.030;0.1;0.2;9.8;3;;\n",                              # a field too many
])
def test_the_scan_stops_where_it_does_not_take_the_text(tmp_path, extra):
    raw = (GOOD + extra).encode()
    assert scan_tagged(raw, ipin._TEXT_TAGS, ipin._TEXT_NCOLS) is None
    p = tmp_path / "log.txt"
    p.write_bytes(raw)
    got = ipin._read_text_fast(p, raw)            # the array path, or None for the exact path: as before
    assert (got is None) == (ipin._read_text_arrays(p, raw, True) is None)


def test_the_scan_keeps_tags_lines_and_the_other_records_in_file_order():
    raw = b"% head\nWIFI;1\nACCE;1;2\nBLE4;1\nWIFI;2\nAB;3\n\nACCE;3;4;\n"
    found = scan_tagged(raw, ("ACCE",), (2,))
    assert found is not None
    assert found.values[0].tolist() == [[1.0, 2.0], [3.0, 4.0]] and found.lines[0].tolist() == [3, 8]
    assert found.others == [(1, "WIFI", 2), (3, "BLE4", 1)]
    assert found.extra == [(0, b"% head"), (5, b"AB;3"), (6, b"")]
    assert np.shares_memory(found.values[0], found.values[0].base)


@pytest.mark.parametrize(("text", "name"), [(EDGES, "log.txt"), (GOOD + "ACCE;0.09;100.04;1;2;3", "cut.txt"),
                                             (GOOD.replace("\n", "\r\n"), "crlf.txt"), (GOOD + "SOUN;é\n", "utf8.txt"),
                                             (GOOD + "WIFI;a\x00b\n", "nul.txt")])
def test_a_mapped_plain_file_reads_as_its_bytes_read(tmp_path, monkeypatch, text, name):
    """ipin.read maps a plain file that ends with a line break (pdr.io.text.mapped_text) and scans it in place;
    every other file, and a mapped one the scan stops at, is read as bytes as before."""
    monkeypatch.setattr(ipin, "_use_compiled", lambda size: True)
    p = tmp_path / name
    p.write_bytes(text.encode())
    raw = p.read_bytes()
    if "nul" in name:
        with pytest.raises(InputError, match="binary data"):
            ipin.read(p)
        return
    _same_recording(ipin.read(p), ipin._read_text_exact(p, raw.rpartition(b"\n")[0] + b"\n" if "cut" in name else raw))
    if "cut" in name:
        assert any("cut-off last line" in w for w in ipin.read(p).warnings)


def test_a_gzip_file_is_not_mapped(tmp_path):
    import gzip

    from pdr.io.text import mapped_text
    p = tmp_path / "log.txt"
    p.write_bytes(gzip.compress(GOOD.encode()))              # gzip's bytes without the .gz name
    assert mapped_text(p) is None and mapped_text(tmp_path / "none.txt") is None
    (tmp_path / "empty.txt").write_bytes(b"")
    assert mapped_text(tmp_path / "empty.txt") is None
    q = tmp_path / "plain.txt"
    q.write_bytes(GOOD.encode())
    mapped = mapped_text(q)
    assert mapped is not None and mapped[:] == GOOD.encode()
