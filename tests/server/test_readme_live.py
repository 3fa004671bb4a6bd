"""The README's service section, pasted: its shell commands (pairing shoes, uploading a shoe file, step summaries, a
group) run as written against a real ``pdr serve``, and give what the section says.

Only the server's address, the ``.venv/bin/pdr`` of a checkout and ``../shared/data`` are replaced (by the test
server's, this installation's CLI and the datasets' location).
"""

from __future__ import annotations

import json
import re
import shlex
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest

from server.client import pdr_command, running_server
from tests.conftest import REPO_ROOT, SHARED_DATA, data_path

pytestmark = [pytest.mark.data, pytest.mark.timeout(1200)]

README = REPO_ROOT / "README.md"


def service_commands() -> str:
    """The ``bash`` blocks of the README's service section, up to its token scopes, in order (unindented)."""
    text = README.read_text()
    section = text[text.index("### The service"):text.index("**Tokens and scopes.**")]
    blocks = re.findall(r"^ *```bash\n(.*?)^ *```", section, re.S | re.M)
    return "\n".join(re.sub(r"^  ", "", b, flags=re.M) for b in blocks)


def _json_lines(out: str) -> list[dict[str, Any]]:
    return [json.loads(line) for line in out.splitlines() if line.startswith("{") and line.endswith("}")]


def test_the_readme_service_commands_work_as_written(tmp_path: Path) -> None:
    for tool in ("bash", "curl", "jq"):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} is not installed")
    data_path("pyshoe_vicon", "2017-11-22-11-52-02.mat")
    script = service_commands()
    assert "devices/left_foot/upload" in script and "/steps" in script and "/groups" in script
    pdr = tmp_path / "bin" / "pdr"
    pdr.parent.mkdir()
    pdr.write_text(f"#!/bin/sh\nexec {shlex.join(pdr_command())} \"$@\"\n")
    pdr.chmod(0o755)
    with running_server(tmp_path / "srv") as (url, env, _):
        script = (script.replace("http://127.0.0.1:8000", url).replace(".venv/bin/pdr", str(pdr))
                  .replace("../shared/data", str(SHARED_DATA)))
        run = subprocess.run(["bash", "-c", "set -e -o pipefail\n" + script], env=env, cwd=tmp_path,
                             capture_output=True, text=True, timeout=1100)
    assert run.returncode == 0, run.stderr[-3000:]
    answers = _json_lines(run.stdout)
    uploaded = next(a for a in answers if a.get("format") == "pyshoe")
    assert uploaded["device_role"] == "left_foot"                        # the pairing decides the foot
    summaries = next(a for a in answers if "steps" in a and "batch_id" in a)
    assert summaries["steps"] > 10 and not summaries["duplicate"]
    group_upload = next(a for a in answers if "accepted" in a)
    assert group_upload["accepted"] == 2 and group_upload["stale_ranges"] == 0 and group_upload["applied"] == 2
    tracks = answers[-1]["agents"]
    assert set(tracks) == {"a", "b"} and all(set(feet) == {"left_foot"} for feet in tracks.values())
    # The initial pose and every final step of session S: the payload's last summary closes the stride that the
    # recording's end closed (pdr foot), which the live session keeps in its provisional tail until it ends.
    assert len(tracks["a"]["left_foot"]) == summaries["steps"]
    assert "t_s,east_m,north_m,up_m,floor,heading_deg,step_length_m,mode,device" in run.stdout
