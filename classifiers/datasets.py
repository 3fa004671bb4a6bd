"""Labelled windows from recordings: dataset loading, label derivation and grouping for evaluation.

Recordings are read with :func:`pdr.io.read_recording` (any supported format; a folder is searched for
logs). Labels per window come from the task's source:

* ``modes``: ``truth.modes`` intervals (MobiFall activities, driving trips, simulated logs). IPIN logs have
  no activity labels; :func:`ipin_mode_labels` derives them from the surveyed landmarks (POSI) and the
  barometer: between two landmarks on different floors the windows where the barometric altitude changes
  faster than ``VERTICAL_SPEED_MPS`` are ``stairs_up/down`` or, when both landmarks are at the same place
  (horizontal distance under ``ELEVATOR_MAX_DISTANCE_M``) and the person does not step while the pressure
  changes (standard deviation of the specific-force norm over the interval under ``STEPPING_ACC_STD``; a
  switchback staircase also ends above where it started), ``elevator_up/down``; between two landmarks on
  the same floor passed at a walking pace the windows are ``walking``; the stops of
  :func:`classifiers.stops.stop_intervals` (no step and a still device for 2 s or more) outside the floor
  changes are ``standing`` (:func:`ipin_standing`). Everything else stays unlabelled.
* ``placement``: ``device.placement`` for every window.

A window gets a label when one label covers at least ``MIN_LABEL_COVERAGE`` of it; other windows are
dropped from training and evaluation. Windows are grouped by subject (``meta['subject']``) when the source
names one, otherwise by recording, so cross-validation leaves whole people or recordings out.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from classifiers.baro_stage import vertical_speed
from classifiers.features import context_margin_s, extract_features
from classifiers.stops import step_intervals, stop_intervals, subtract
from classifiers.tasks import Task
from classifiers.windows import WindowConfig, make_windows
from pdr.errors import InputError, UnknownFormatError
from pdr.frames import pressure_to_altitude_m
from pdr.io import detect_format, read_recording
from pdr.recording import Labels, Recording

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

MIN_LABEL_COVERAGE = 0.8
#: Barometric vertical speed (m/s) above which a floor-change interval counts as moving vertically.
VERTICAL_SPEED_MPS = 0.12
#: Landmarks closer than this (m) horizontally but on different floors are an elevator ride.
ELEVATOR_MAX_DISTANCE_M = 3.0
#: Standard deviation of the specific-force norm (m/s^2) above which a vertical interval has steps (hand-held
#: walking shows ~1-2.5 m/s^2, standing in a cabin ~0.1-0.3 m/s^2).
STEPPING_ACC_STD = 0.7
#: Longest pause (s) of the pressure change inside one flight of stairs or elevator ride.
MAX_LANDING_S = 2.0
#: Mean speed (m/s) between two same-floor landmarks above which the interval is labelled walking.
WALKING_MIN_SPEED_MPS = 0.5


@dataclass(frozen=True)
class LabelledWindows:
    """Feature rows with labels and grouping.

    Attributes
    ----------
    X
        (W, F) features.
    y
        (W,) task classes (object strings).
    groups
        (W,) group name (subject or recording) for grouped cross-validation.
    recording
        (W,) index of the source recording (windows of one recording are consecutive and in time order).
    t_start_s, t_end_s
        (W,) window bounds on the recording's axis (s).
    sources
        Source path of each recording index.
    baro
        (W, 2) barometric vertical speed (m/s) and its standard error per window
        (:func:`classifiers.baro_stage.vertical_speed`), NaN where the recording has no pressure data.
    """

    X: FloatArray
    y: NDArray[np.object_]
    groups: NDArray[np.object_]
    recording: NDArray[np.int64]
    t_start_s: FloatArray
    t_end_s: FloatArray
    sources: tuple[str, ...]
    baro: FloatArray | None = None

    def __len__(self) -> int:
        return int(self.y.size)

    def select(self, mask: NDArray[np.bool_]) -> LabelledWindows:
        return LabelledWindows(self.X[mask], self.y[mask], self.groups[mask], self.recording[mask],
                               self.t_start_s[mask], self.t_end_s[mask], self.sources,
                               None if self.baro is None else self.baro[mask])

    def class_counts(self) -> dict[str, int]:
        names, counts = np.unique(self.y.astype(str), return_counts=True)
        return {str(n): int(c) for n, c in zip(names, counts, strict=True)}


def iter_log_paths(path: str | Path) -> Iterator[Path]:
    """Every readable log under ``path`` (itself if it is one; otherwise its children, recursively)."""
    p = Path(path)
    if not p.exists():
        raise InputError("no such file or folder", source=str(p))
    try:
        detect_format(p)
        yield p
        return
    except UnknownFormatError:
        if not p.is_dir():
            return
    for child in sorted(p.iterdir()):
        if child.name.startswith("."):
            continue
        yield from iter_log_paths(child)


def _dedupe_key(rec: Recording, path: Path) -> tuple[str, ...]:
    files = rec.meta.get("files")
    if isinstance(files, list | tuple) and files:
        return (rec.format, *sorted(str(f).split(".")[0] for f in files))
    return (rec.format, path.name.split(".")[0])


def load_recordings(paths: Iterable[str | Path]) -> list[Recording]:
    """Read every log under ``paths``; one recording per trial (a trial split over files is read once)."""
    out: list[Recording] = []
    seen: set[tuple[str, ...]] = set()
    for root in paths:
        for p in iter_log_paths(root):
            rec = read_recording(p)
            key = _dedupe_key(rec, p)
            if key in seen:
                continue
            seen.add(key)
            out.append(rec)
    if not out:
        raise InputError("no readable logs found", source=", ".join(str(p) for p in paths))
    return out


def group_of(rec: Recording) -> str:
    """Cross-validation group: ``<format>:subject<id>`` when the source names the subject, else the recording."""
    subject = rec.meta.get("subject")
    if subject is not None:
        return f"{rec.format}:subject{subject}"
    return f"{rec.format}:{Path(rec.source).name.split('.')[0]}"


def ipin_mode_labels(rec: Recording) -> Labels | None:
    """Motion-mode intervals derived from POSI landmarks and the barometer (module docstring); None if absent."""
    pos = rec.truth.positions
    if pos is None or len(pos) < 2 or pos.floor is None or not np.isfinite(pos.floor).any():
        return None
    starts: list[float] = []
    ends: list[float] = []
    labels: list[str] = []
    altitude_t = altitude = None
    if rec.has("baro") and len(rec.stream("baro")) > 4:
        t_b = rec.t_s("baro")
        h = pressure_to_altitude_m(rec.values("baro")[:, 0])
        # 2 s moving average before differentiating: pressure sensors are quantised to ~0.01 hPa (8 cm).
        k = max(1, int(round(2.0 * (len(t_b) - 1) / max(t_b[-1] - t_b[0], 1e-9))))
        c = np.cumsum(np.r_[0.0, h])
        hs = (c[k:] - c[:-k]) / k
        ts = (np.cumsum(np.r_[0.0, t_b])[k:] - np.cumsum(np.r_[0.0, t_b])[:-k]) / k
        altitude_t, altitude = ts, hs
    for i in range(len(pos) - 1):
        t0, t1 = float(pos.t_s[i]), float(pos.t_s[i + 1])
        if t1 <= t0:
            continue
        f0, f1 = pos.floor[i], pos.floor[i + 1]
        dist = float(np.linalg.norm(pos.pos_m[i + 1, :2] - pos.pos_m[i, :2]))
        if np.isfinite(f0) and np.isfinite(f1) and f0 != f1:
            if altitude_t is None or altitude is None:
                continue
            kind = "elevator" if dist < ELEVATOR_MAX_DISTANCE_M else "stairs"
            direction = "up" if f1 > f0 else "down"
            sel = (altitude_t >= t0) & (altitude_t <= t1)
            if sel.sum() < 3:
                continue
            ts, hs = altitude_t[sel], altitude[sel]
            v = np.gradient(hs, ts)
            moving = np.abs(v) > VERTICAL_SPEED_MPS
            # Intervals of consecutive moving samples.
            edges = np.flatnonzero(np.diff(np.r_[0, moving.astype(int), 0]))
            for a, b in zip(edges[::2], edges[1::2], strict=True):
                if ts[b - 1] - ts[a] >= 1.0:
                    starts.append(float(ts[a]))
                    ends.append(float(ts[b - 1]))
                    stepping = _acc_norm_std(rec, float(ts[a]), float(ts[b - 1])) > STEPPING_ACC_STD
                    labels.append(f"{'stairs' if stepping else kind}_{direction}")
        elif dist / (t1 - t0) > WALKING_MIN_SPEED_MPS:
            starts.append(t0)
            ends.append(t1)
            labels.append("walking")
    if not labels:
        return None
    # Vertical intervals of one kind interrupted by a short pause of the pressure change (a landing) are one.
    merged: list[tuple[float, float, str]] = []
    for a, b, name in sorted(zip(starts, ends, labels, strict=True)):
        if merged and merged[-1][2] == name != "walking" and a - merged[-1][1] <= MAX_LANDING_S:
            merged[-1] = (merged[-1][0], b, name)
        else:
            merged.append((a, b, name))
    # A stop wins over the walking leg around it.
    standing = ipin_standing(rec)
    pieces: list[tuple[float, float, str]] = [(a, b, "standing") for a, b in standing]
    for a, b, name in merged:
        rest = [(a, b)]
        for cut in standing:
            rest = subtract(rest, cut)
        pieces += [(x, y, name) for x, y in rest]
    merged = sorted(pieces)
    return Labels(np.asarray([m[0] for m in merged], dtype=np.float64),
                  np.asarray([m[1] for m in merged], dtype=np.float64), tuple(m[2] for m in merged))


def ipin_standing(rec: Recording) -> list[tuple[float, float]]:
    """Standing intervals ``(t0_s, t1_s)`` of a landmark walk: the stops of :func:`classifiers.stops.stop_intervals`
    (no step and a still device for ``MIN_STOP_S`` or more; its docstring states the rule) that overlap no
    interval between two landmarks on different floors (a still rider in an elevator cabin is not standing).
    """
    pos = rec.truth.positions
    if pos is None or pos.floor is None or not rec.has("acc"):
        return []
    legs = [(float(pos.t_s[i]), float(pos.t_s[i + 1])) for i in range(len(pos) - 1)
            if np.isfinite(pos.floor[i]) and np.isfinite(pos.floor[i + 1]) and pos.floor[i] != pos.floor[i + 1]]
    return [(s.t_start_s, s.t_end_s) for s in stop_intervals(rec, step_intervals(rec))
            if not any(s.t_end_s > a and s.t_start_s < b for a, b in legs)]


def _acc_norm_std(rec: Recording, t0: float, t1: float) -> float:
    """Standard deviation of the specific-force norm (m/s^2) over ``[t0, t1]`` (s); 0 without data."""
    if not rec.has("acc"):
        return 0.0
    t = rec.t_s("acc")
    sel = (t >= t0) & (t <= t1)
    if sel.sum() < 2:
        return 0.0
    return float(np.std(np.linalg.norm(rec.values("acc")[sel], axis=1)))


def mode_labels(rec: Recording) -> Labels | None:
    """The recording's motion-mode intervals: ``truth.modes``, or derived from IPIN landmarks."""
    if rec.truth.modes is not None:
        return rec.truth.modes
    return ipin_mode_labels(rec)


def window_labels(labels: Labels, t_start_s: FloatArray, t_end_s: FloatArray, n_points: int = 16) -> list[str | None]:
    """Majority label of each window when it covers at least ``MIN_LABEL_COVERAGE`` of it, else None."""
    if t_start_s.size == 0:
        return []
    frac = (np.arange(n_points) + 0.5) / n_points
    t = t_start_s[:, None] + frac[None, :] * (t_end_s - t_start_s)[:, None]
    at = labels.at(t.ravel()).reshape(t.shape)
    out: list[str | None] = []
    for row in at:
        names, counts = np.unique(row.astype(str), return_counts=True)
        j = int(np.argmax(counts))
        ok = names[j] != "" and counts[j] >= MIN_LABEL_COVERAGE * n_points
        out.append(str(names[j]) if ok else None)
    return out


def labelled_windows(recordings: list[Recording], task: Task, cfg: WindowConfig,
                     groups: tuple[str, ...]) -> LabelledWindows:
    """Windows, features and task labels of every recording (unlabelled windows dropped)."""
    xs, ys, gs, rs, t0s, t1s, bs = [], [], [], [], [], [], []
    sources = []
    for i, rec in enumerate(recordings):
        sources.append(rec.source)
        win = make_windows(rec, cfg, margin_s=context_margin_s(groups, cfg.length_s))
        if len(win) == 0:
            continue
        if task.label_source == "placement":
            raw: list[str | None] = [rec.device.placement] * len(win)
        else:
            lab = mode_labels(rec)
            if lab is None:
                log.info("%s: no motion-mode labels, skipped", rec.source)
                continue
            # Window times are on the recording's axis, like the labels.
            raw = window_labels(lab, win.t_start_s, win.t_end_s)
        y = np.array([task.map_label(v) for v in raw], dtype=object)
        keep = np.array([v is not None for v in y]) & win.valid
        if not keep.any():
            continue
        kept = win.select(keep)
        xs.append(extract_features(kept, groups))
        speed = vertical_speed(kept)
        bs.append(np.full((int(keep.sum()), 2), np.nan) if speed is None else np.column_stack(speed))
        ys.append(y[keep])
        gs.append(np.full(int(keep.sum()), group_of(rec), dtype=object))
        rs.append(np.full(int(keep.sum()), i, dtype=np.int64))
        t0s.append(win.t_start_s[keep])
        t1s.append(win.t_end_s[keep])
    if not xs:
        raise InputError(f"no labelled windows for task '{task.name}' in the given data")
    return LabelledWindows(np.vstack(xs), np.concatenate(ys), np.concatenate(gs), np.concatenate(rs),
                           np.concatenate(t0s), np.concatenate(t1s), tuple(sources), np.vstack(bs))
