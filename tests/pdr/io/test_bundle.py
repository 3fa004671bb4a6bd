"""Multi-file logs (pdr.io.bundle): a folder, a zip of it and a zip of its files read alike."""

from __future__ import annotations

import gzip
import zipfile
from pathlib import Path

import pytest

from pdr.errors import InputError
from pdr.io.bundle import Bundle, is_zip

FILES = {"meta.json": b'{"device": "x"}', "Accelerometer.csv": b"t,x\n1,2\n", "sub/Gyroscope.csv": b"t,x\n3,4\n"}


def folder(root: Path) -> Path:
    d = root / "log"
    for name, data in FILES.items():
        (d / name).parent.mkdir(parents=True, exist_ok=True)
        if name == "Accelerometer.csv":
            (d / (name + ".gz")).write_bytes(gzip.compress(data))       # stored gzipped
        else:
            (d / name).write_bytes(data)
    return d


def zipped(root: Path, name: str, members: dict[str, bytes]) -> Path:
    path = root / name
    with zipfile.ZipFile(path, "w") as zf:
        for n, data in members.items():
            zf.writestr(n, data)
    return path


def layouts(tmp_path: Path) -> list[Bundle]:
    """The same log as a folder, a zip of the folder, a zip of its files, and a zip with macOS debris."""
    gz = {("Accelerometer.csv.gz" if n == "Accelerometer.csv" else n): (gzip.compress(d) if n == "Accelerometer.csv"
                                                                       else d) for n, d in FILES.items()}
    return [
        Bundle(folder(tmp_path)),
        Bundle(zipped(tmp_path, "a.zip", {f"log/{n}": d for n, d in gz.items()})),
        Bundle(zipped(tmp_path, "b.zip", gz)),
        Bundle(zipped(tmp_path, "c.zip", {**{f"walk 1/{n}": d for n, d in gz.items()},
                                           "__MACOSX/walk 1/._meta.json": b"junk"}), anchor="meta.json"),
    ]


def test_every_layout_gives_the_same_members_and_contents(tmp_path: Path) -> None:
    for b in layouts(tmp_path):
        assert b.members() == sorted(FILES), b.path
        for name, data in FILES.items():
            assert b.get(name) == data, (b.path, name)
            assert b.need(name) == data
        assert b.text("meta.json") == '{"device": "x"}'
        assert b.get("Magnetometer.csv") is None


def test_anchor_picks_the_root_inside_a_deeper_zip(tmp_path: Path) -> None:
    """The shallowest ``anchor`` marks the root; without it a zip with two top folders has its root at the top."""
    members = {"export/phone/meta.json": b"{}", "export/phone/data.csv": b"1", "export/phone/old/meta.json": b"[]",
               "readme.txt": b"r"}
    b = Bundle(zipped(tmp_path, "d.zip", members), anchor="meta.json")
    assert b.members() == ["data.csv", "meta.json", "old/meta.json"]
    assert b.need("meta.json") == b"{}"
    assert b.name("data.csv").endswith("d.zip:export/phone/data.csv")
    assert Bundle(zipped(tmp_path, "e.zip", members)).members() == sorted(members)


def test_errors_name_the_file_or_member(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such file or folder"):
        Bundle(tmp_path / "missing")
    not_zip = tmp_path / "log.zip"
    not_zip.write_bytes(b"plain text")
    assert not is_zip(not_zip) and not is_zip(tmp_path / "absent.zip")
    with pytest.raises(InputError, match="not a readable zip archive"):
        Bundle(not_zip)
    b = Bundle(zipped(tmp_path, "f.zip", {"x.csv.gz": b"not gzip", "bin.csv": b"a\x00b"}))
    assert is_zip(b.path)
    with pytest.raises(InputError, match="not gzip data, though named .gz") as err:
        b.get("x.csv")
    assert "f.zip:x.csv" in str(err.value)
    with pytest.raises(InputError, match="missing member 'y.csv'"):
        b.need("y.csv")
    with pytest.raises(InputError, match="binary data"):
        b.text("bin.csv")


def _make_no_file(path: Path, kind: str) -> str:
    """Put a ``kind`` at ``path`` (a folder, a named pipe, a symbolic link to itself); the notice expected of it."""
    import os

    if kind == "folder":
        path.mkdir()
        return f"{path.name}: not read: a folder, not a file"
    if kind == "fifo":
        os.mkfifo(path)
        return f"{path.name}: not read: a named pipe (FIFO), not a file"
    path.symlink_to(path.name)
    return f"{path.name}: not read: a symbolic link that leads nowhere (a loop, or its target is missing)"


@pytest.mark.parametrize("kind", ["folder", "fifo", "symlink loop"])
def test_a_member_that_is_no_file_is_not_read_and_said(tmp_path, kind):
    """A folder member that is a folder, a named pipe or a link that loops was skipped as if absent, unsaid; it is
    still not read (a pipe is never opened), and said within pdr.io.notices.collecting (read_recording's)."""
    from pdr.io import notices
    from pdr.io.text import find_member

    d = folder(tmp_path)
    expected = _make_no_file(d / "Gyroscope.csv", kind)
    with notices.collecting() as notes:
        assert Bundle(d).get("Gyroscope.csv") is None and find_member(d, "Gyroscope.csv") is None
        assert Bundle(d).get("Accelerometer.csv") == FILES["Accelerometer.csv"]
    assert notes == [expected, expected]
    assert Bundle(d).get("Gyroscope.csv") is None   # outside: as before, nothing said
