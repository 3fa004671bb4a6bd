"""gzip data cut short (pdr.io.gz): read as far as it decompresses, with a warning, only through read_recording."""

import gzip

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.io import ms_indoor, read_recording
from pdr.io.gz import cut_gzip_warnings, decompressed_prefix, gunzip
from tests.conftest import REPO_ROOT

TRACE = REPO_ROOT / "mobile_logs" / "real" / "ms_indoor_site2_F3_5dd51a7650e04e0006f5642c.txt.gz"


def test_gunzip_reads_a_cut_stream_as_far_as_it_goes_only_when_asked():
    text = b"".join(b"%d,%d\n" % (i, i * i) for i in range(5000))
    packed = gzip.compress(text[:20000]) + gzip.compress(text[20000:])       # two members, the second cut
    cut = packed[:-300]
    with pytest.raises(InputError, match="corrupt gzip data") as err:
        gunzip(cut, "/logs/walk.csv.gz")
    assert err.value.source == "/logs/walk.csv.gz"
    with cut_gzip_warnings() as notes:
        got = gunzip(cut, "/logs/walk.csv.gz")
        assert gunzip(packed, "/logs/whole.csv.gz") == text
    assert 20000 < len(got) < len(text) and text.startswith(got)
    assert notes == [f"walk.csv.gz: cut short (the gzip stream ends before its end marker): read the {len(got)} "
                     "bytes that decompress"]
    assert decompressed_prefix(cut, 100) == text[:100]


@pytest.mark.parametrize("raw, message", [
    (b"not gzip at all", r"x.gz: not gzip data, though named .gz: it starts with b'not gzip', gzip with bytes 1f 8b"),
    (gzip.compress(b"x" * 1000, mtime=0)[:11], "corrupt gzip data"),
    (gzip.compress(b"a,b\n" * 100, mtime=0)[:-4] + b"\x00\x00\x00\x01", "corrupt gzip data")],
    ids=["not gzip", "cut in the header", "wrong length"])    # ids the same on every worker
def test_what_is_not_gzip_or_gives_nothing_is_still_refused(raw, message):
    """Not gzip (said so: it was 'corrupt gzip data (Not a gzipped file ...)'), cut before any byte decompresses, or
    damaged (a wrong length in the trailer): refused."""
    with cut_gzip_warnings() as notes, pytest.raises(InputError, match=message):
        gunzip(raw, "x.gz")
    assert notes == []


def test_trailing_bytes_after_a_whole_gzip_are_ignored_with_a_warning_only_when_asked():
    """A whole gzip followed by bytes that are not gzip (a download's trailing junk; `gzip -d` warns "trailing garbage
    ignored") was refused whole as "corrupt gzip data (Not a gzipped file (b'ga'))"; its members are read now, and
    the warning names the file. A damaged member stays refused."""
    text = b"".join(b"%d,%d\n" % (i, i * i) for i in range(5000))
    packed = gzip.compress(text[:20000], mtime=0) + gzip.compress(text[20000:], mtime=0)
    with pytest.raises(InputError, match="corrupt gzip data"):
        gunzip(packed + b"garbage\x01", "/logs/walk.csv.gz")
    with cut_gzip_warnings() as notes:
        assert gunzip(packed + b"garbage\x01", "/logs/walk.csv.gz") == text
    assert notes == ["walk.csv.gz: 8 bytes after the end of the gzip stream that are not gzip data ignored (the "
                     "stream itself is whole)"]
    damaged = bytearray(packed)
    damaged[-30] ^= 0xFF                    # in the second member: its CRC fails
    with cut_gzip_warnings() as notes, pytest.raises(InputError, match="corrupt gzip data"):
        gunzip(bytes(damaged) + b"garbage", "x.gz")
    assert notes == []


def test_a_log_gzip_cut_mid_stream_is_read_with_a_warning_naming_it(tmp_path):
    """A .gz trace cut short (a copy or download stopped) was refused whole ('corrupt gzip data'); read_recording
    now reads the samples that decompress, the cut-off last line dropped, and says so first."""
    whole = ms_indoor.read(TRACE)
    packed = TRACE.read_bytes()
    p = tmp_path / "trace.txt.gz"
    p.write_bytes(packed[:len(packed) * 2 // 3])
    with pytest.raises(InputError, match="corrupt gzip data"):
        ms_indoor.read(p)                               # the reader alone still refuses it
    rec = read_recording(p)
    assert rec.warnings[0].startswith("trace.txt.gz: cut short (the gzip stream ends before its end marker): read ")
    assert any("trace.txt.gz: dropped the cut-off last line" in w for w in rec.warnings)
    n = len(rec.stream("acc"))
    assert 0 < n < len(whole.stream("acc"))
    np.testing.assert_array_equal(rec.values("acc"), whole.values("acc")[:n])
