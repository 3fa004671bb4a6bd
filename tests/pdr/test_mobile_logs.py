"""Every sample log in mobile_logs/ reads with format detection, inspects, and is documented."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pdr.cli import main
from pdr.io.native import BATCH_FORMAT
from pdr.io.registry import read_recording
from tests.conftest import REPO_ROOT

MOBILE_LOGS = REPO_ROOT / "mobile_logs"
#: Licences of the datasets whose excerpts may be committed (../shared/data/README.md).
PERMITTED_SOURCES = ("oxford_step_counter", "ms_indoor_location", "foot_stride_gcp", "xio_gait_loop")
MAX_BYTES = 500_000


def _is_log(p: Path) -> bool:
    """Files and native folders that are logs (not documentation or simulator scenario files)."""
    if p.is_dir():
        return (p / "meta.json").is_file()
    if p.name.upper().startswith(("README", "LICENSE")) or p.suffix == ".md":
        return False
    if p.suffix == ".json":  # a pdr-batch/1 document is a log; a scenario description is not
        return BATCH_FORMAT in p.read_text(encoding="utf-8", errors="replace")[:4096]
    return True


def _logs() -> list[Path]:
    if not MOBILE_LOGS.is_dir():
        return []
    out: list[Path] = []
    stack = [MOBILE_LOGS]
    while stack:
        folder = stack.pop()
        for p in sorted(folder.iterdir()):
            if _is_log(p):
                out.append(p)
            elif p.is_dir():
                stack.append(p)
    return sorted(out)


LOGS = _logs()
REAL_LOGS = [p for p in LOGS if p.relative_to(MOBILE_LOGS).parts[0] == "real"]


def test_there_are_real_sample_logs():
    assert len(REAL_LOGS) >= 4


@pytest.mark.parametrize("path", LOGS, ids=lambda p: str(p.relative_to(MOBILE_LOGS)))
def test_log_reads_and_inspects(capsys, path):
    rec = read_recording(path)
    assert rec.duration_s > 1.0
    assert any(len(s) > 10 for s in rec.streams.values())
    assert main(["inspect", str(path), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["format"] == rec.format
    assert all(s["rate_hz"] and s["rate_hz"] > 0 for s in summary["streams"])


@pytest.mark.parametrize("path", REAL_LOGS, ids=lambda p: p.name)
def test_real_log_is_small_documented_and_from_a_permitted_dataset(path):
    size = path.stat().st_size if path.is_file() else sum(f.stat().st_size for f in path.rglob("*") if f.is_file())
    assert size <= MAX_BYTES
    readme = (MOBILE_LOGS / "README.md").read_text(encoding="utf-8")
    assert f"`{path.name}`" in readme
    rec = read_recording(path)
    origin = rec.meta.get("excerpt", {}).get("source", "") if rec.format == "native" else ""
    documented_row = next(line for line in readme.splitlines() if f"`{path.name}`" in line)
    permitted_names = ("Oxford Step Counter", "Microsoft Indoor Location", "foot_stride_gcp", "x-io Gait-Tracking")
    assert any(name in documented_row for name in permitted_names)
    if origin:
        assert origin.split("/")[0] in PERMITTED_SOURCES
