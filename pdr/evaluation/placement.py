"""How well the pipeline's online placement detector (:mod:`pdr.phone.placement_detect`) names the carriage of
real phones, across walkers and datasets (issue 25, item 3): per step, the placement the pipeline used against the
recording's own label, as a confusion matrix per dataset and overall.

The label of a recording is its carriage as the dataset states it, grouped as the pipeline groups placements
(:data:`pdr.phone.pipeline.PLACEMENT_GROUPS`): a trouser pocket, front or back, is ``pocket``; a hand (Oxford's
"hand", IPIN's and MS's hand-held walks, the benchmark's texting) and an armband are ``hand``; a bag or the neck is
``torso``; the benchmark's swinging hand is ``swinging``. The Sensor Logger walks carry theirs in the folder name
(``inhand-``, ``texting-``: hand; ``inpocket-``: pocket). The detector is run as ``pdr track`` runs it on a log that
names no placement: the label is taken off the recording first. It knows three carriages (hand, pocket, swinging):
a torso-worn phone is steady, so it reads as held, and the pipeline's heading for both is the device heading.
Without a gyroscope nothing is detected (the pipeline takes the phone as hand-held and says so): such recordings
(Oxford's, accelerometer only) are counted apart, not in the matrices.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from pdr.errors import InputError
from pdr.evaluation.walking_recordings import recordings
from pdr.io import read_recording
from pdr.phone.pipeline import PLACEMENT_GROUPS, PdrPipeline, PipelineConfig, track_rows
from pdr.recording import Recording

#: Sensor Logger walk folders' name prefixes and the carriage they name (the dataset's SOURCE.md).
SENSOR_LOGGER_PREFIXES = {"inhand": "hand", "texting": "hand", "inpocket": "pocket"}
#: Columns of the confusion matrices: what the detector can say, and steps with no placement.
DETECTED = ("hand", "pocket", "swinging", "none")


def true_placement(rec: Recording, path: Path) -> str | None:
    """The recording's labelled carriage as a pipeline placement group (module doc), None where it has none."""
    if rec.meta.get("carriage") == "Swinging":
        return "swinging"
    label = rec.meta.get("placement_label") or rec.device.placement
    if label:
        return label if label in ("pocket", "hand", "torso", "swinging") else PLACEMENT_GROUPS.get(str(label))
    prefix = path.name.split("-", 1)[0]
    return SENSOR_LOGGER_PREFIXES.get(prefix)


def detected_placements(rec: Recording, config: PipelineConfig | None = None) -> list[str]:
    """The placement of each step of ``rec`` as the pipeline detects it when the log names none."""
    unlabelled = replace(rec, device=replace(rec.device, placement=None))
    rows = track_rows(PdrPipeline(config or PipelineConfig()).run(unlabelled))
    return [str(r.get("placement") or "none") for r in rows]


@dataclass
class RecordingPlacement:
    """One recording's label, the per-step detected placements counted, and how often the placement changed."""

    dataset: str
    name: str
    label: str
    counts: Counter[str]
    changes: int
    has_gyro: bool = True

    @property
    def right(self) -> float:
        """Share of the steps whose detected placement is the label's (a torso-worn phone read as held counts)."""
        n = sum(self.counts.values())
        want = "hand" if self.label == "torso" else self.label
        return self.counts[want] / n if n else float("nan")


def evaluate_recording(dataset: str, path: Path, config: PipelineConfig | None = None) -> RecordingPlacement | None:
    """Detect the placement of one labelled recording's steps; None when it has no label."""
    rec = read_recording(path)
    label = true_placement(rec, path)
    if label is None:
        return None
    steps = detected_placements(rec, config)
    changes = sum(1 for a, b in zip(steps, steps[1:], strict=False) if a != b)
    return RecordingPlacement(dataset, path.name, label, Counter(steps), changes, rec.has("gyro"))


def confusion(results: Iterable[RecordingPlacement]) -> dict[str, dict[str, int]]:
    """Steps per label (rows) and detected placement (columns, :data:`DETECTED`)."""
    out: dict[str, dict[str, int]] = {}
    for r in results:
        row = out.setdefault(r.label, dict.fromkeys(DETECTED, 0))
        for k, v in r.counts.items():
            row[k if k in row else "none"] += v
    return out


def summary(results: list[RecordingPlacement]) -> dict[str, Any]:
    """Confusion matrices per dataset and overall, the share of steps right, and the recordings whose placement
    changed or was mostly wrong.
    """
    no_gyro = [r for r in results if not r.has_gyro]
    results = [r for r in results if r.has_gyro]
    by_dataset: dict[str, list[RecordingPlacement]] = {}
    for r in results:
        by_dataset.setdefault(r.dataset.split()[0], []).append(r)

    def block(rs: list[RecordingPlacement]) -> dict[str, Any]:
        m = confusion(rs)
        steps = sum(sum(row.values()) for row in m.values())
        right = sum(row["hand" if lab == "torso" else lab] for lab, row in m.items())
        return {"recordings": len(rs), "steps": steps, "right": right / steps if steps else float("nan"),
                "confusion": m}

    return {"all": block(results), "by_dataset": {k: block(v) for k, v in sorted(by_dataset.items())},
            "mostly_wrong": [{"dataset": r.dataset, "recording": r.name, "label": r.label,
                              "detected": dict(r.counts)} for r in results if r.right < 0.5],
            "changes": sum(r.changes for r in results),
            "without_gyroscope": {"recordings": len(no_gyro), "steps": sum(sum(r.counts.values()) for r in no_gyro),
                                  "datasets": sorted({r.dataset for r in no_gyro})}}


def evaluate(data: Path, config: PipelineConfig | None = None,
             progress: Callable[[str], None] | None = None) -> list[RecordingPlacement]:
    """Every walking recording with a placement label under ``data`` (a folder holding the shared datasets)."""
    found = [(d, p) for d, p, walking in recordings(data) if walking]
    if not found:
        raise InputError("no recording of the shared datasets here (sensor_logger_walks, oxford_step_counter, "
                         "mobifall_v2_pocket, ms_indoor_location, ipin2023_t3, attitude_smartphones)",
                         source=str(data))
    out = []
    for dataset, path in found:
        r = evaluate_recording(dataset, path, config)
        if r is not None:
            out.append(r)
        if progress is not None:
            progress(path.name)
    return out


def report_lines(s: dict[str, Any]) -> list[str]:
    """The summary as text: one confusion matrix per dataset and the overall one."""
    lines = []
    for title, b in [("ALL", s["all"]), *s["by_dataset"].items()]:
        lines.append(f"{title}: {b['recordings']} recordings, {b['steps']} steps, {100 * b['right']:.1f} % of steps "
                     "as labelled (a torso-worn phone read as held counts)")
        lines.append("    label \\ detected " + "".join(f"{c:>10}" for c in DETECTED))
        for label, row in sorted(b["confusion"].items()):
            lines.append(f"    {label:18s} " + "".join(f"{row[c]:>10}" for c in DETECTED))
    lines.append(f"placement changes within a recording: {s['changes']}")
    ng = s["without_gyroscope"]
    if ng["recordings"]:
        lines.append(f"without a gyroscope (not detected, taken as hand-held; not in the matrices): {ng['recordings']} "
                     f"recordings, {ng['steps']} steps ({', '.join(ng['datasets'])})")
    for w in s["mostly_wrong"]:
        lines.append(f"mostly wrong: {w['dataset']} {w['recording']} (label {w['label']}): {w['detected']}")
    return lines
