"""A zip that no reader takes as it is is read from its content: a zipped folder of a folders-only reader (folder at
the top or files flat) or a zip of one log file, named by the zip, never by the temporary folder it was unpacked to."""

from __future__ import annotations

import gzip
import zipfile
from pathlib import Path

import numpy as np
import pytest

from pdr.io import detect_format, read_recording
from tests.conftest import REPO_ROOT, data_path

MS = REPO_ROOT / "mobile_logs" / "real" / "ms_indoor_site2_F3_5dd51a7650e04e0006f5642c.txt.gz"


def _zip(path: Path, files: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(path, "w") as z:
        for name, content in files.items():
            z.writestr(name, content)
    return path


def _same_streams(a, b) -> None:  # noqa: ANN001
    assert set(a.streams) == set(b.streams)
    for k in a.streams:
        assert np.array_equal(a.streams[k].t_ns, b.streams[k].t_ns) and np.array_equal(a.values(k), b.values(k))


def test_a_zip_of_one_log_file(tmp_path):
    z = _zip(tmp_path / "trace.zip", {"trace.txt": gzip.decompress(MS.read_bytes())})
    assert detect_format(z) == "ms_indoor"
    rec, ref = read_recording(z), read_recording(MS)
    _same_streams(rec, ref)
    assert rec.source == str(z) and "pdr-unzip-" not in repr(rec.meta) + repr(rec.warnings)


@pytest.mark.data
@pytest.mark.parametrize("layout", ["folder at the top", "flat"])
def test_zipped_folders_of_folder_readers(tmp_path, layout):
    trial = data_path("mobifall_v2_pocket", "sub2", "ADL", "WAL")
    files = {f.name: f.read_bytes() for f in sorted(trial.glob("WAL_*_2_1.txt*")) if "_ori_" not in f.name}
    assert len(files) == 2
    folder = tmp_path / "WAL_2_1"
    folder.mkdir()
    for name, content in files.items():
        (folder / name).write_bytes(content)
    top = "WAL_2_1/" if layout == "folder at the top" else ""
    z = _zip(tmp_path / "walk.zip", {top + n: c for n, c in files.items()})
    assert detect_format(z) == "mobifall"
    rec, ref = read_recording(z), read_recording(folder)
    _same_streams(rec, ref)
    assert rec.truth.modes is not None and rec.meta["activity_code"] == "WAL"
    assert rec.source == str(z) and "pdr-unzip-" not in repr(dict(rec.meta))


def test_a_gzip_saved_without_its_gz_suffix_is_read_as_one_with_it(tmp_path):
    """A gzipped trace saved as 'trace.txt' (a browser or a copy that dropped the '.gz') was 'not a supported log
    format': the readers gunzip by the magic bytes, the sniffers only by the name. Both now do."""
    plain = tmp_path / "trace.txt"
    plain.write_bytes(MS.read_bytes())
    assert detect_format(plain) == "ms_indoor"
    _same_streams(read_recording(plain), read_recording(MS))
