"""``pdr convert LOG --to native OUT``: read any supported log and write it in the native format.

``OUT`` ending in ``.zip`` gives a zip of the native folder, ``.json`` or ``.json.gz`` a ``pdr-batch/1``
JSON document, anything else a native folder (:mod:`pdr.io.native`); a new folder's name may not end in another
file extension (``out.csv`` is refused: the native format has no single CSV file). ``OUT`` is checked before the
log is read. ``--start``/``--end`` keep an
excerpt: streams and ground truth are cut to the window and the time axis restarts at its beginning
(the raw nanosecond timestamps are unchanged). ``--role`` sets the device role written (a file that does not say
which foot carried the IMU, such as PyShoe's, reads as ``right_foot``; a native batch's role decides the session
device it is stored under).
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np

from pdr.cli.outputs import check_writable, in_made_folder, print_warnings
from pdr.cli.progress import Progress
from pdr.errors import InputError
from pdr.io import native, registry
from pdr.recording import DEVICE_ROLES, GroundTruth, Labels, PositionTruth, Recording

TARGETS: tuple[str, ...] = ("native",)


def _cut_labels(lab: Labels | None, start_s: float, end_s: float) -> Labels | None:
    if lab is None:
        return None
    keep = (lab.t_end_s > start_s) & (lab.t_start_s < end_s)
    return Labels(np.maximum(lab.t_start_s[keep], start_s) - start_s,
                  np.minimum(lab.t_end_s[keep], end_s) - start_s,
                  tuple(x for x, k in zip(lab.label, keep, strict=True) if k))


def _is_time_axis(name: str, arr: np.ndarray) -> bool:
    """Extras named ``*_s`` (seconds, per the naming convention) that are 1-D and non-decreasing are times."""
    return (name.endswith("_s") and arr.ndim == 1 and arr.dtype.kind == "f"
            and bool(np.all(np.diff(arr) >= 0)))


def _cut_extra(extra: dict[str, np.ndarray], start_s: float, end_s: float) -> tuple[dict[str, np.ndarray], list[str]]:
    """Cut time-indexed extras.

    Time axes (:func:`_is_time_axis`, e.g. ``zero_velocity_t_s``, ``step_times_chan1_s``) are cut to the
    window and shifted; another array follows the time axis of the same length whose name shares its
    prefix (``zero_velocity`` follows ``zero_velocity_t_s``), else the only time axis of its length.
    Anything else cannot be cut safely (e.g. sample indices) and is dropped, with a note.
    """
    axes = {k: v for k, v in extra.items() if _is_time_axis(k, v)}
    masks = {k: (v >= start_s) & (v < end_s) for k, v in axes.items()}
    out: dict[str, np.ndarray] = {}
    notes: list[str] = []
    for name, arr in extra.items():
        if name in axes:
            out[name] = arr[masks[name]] - start_s
            continue
        same = [k for k in axes if arr.ndim and arr.shape[0] == axes[k].shape[0]]
        prefixed = [k for k in same if name.startswith(k.removesuffix("_s").removesuffix("_t"))]
        candidates = prefixed or (same if len(same) == 1 else [])
        if not candidates:
            notes.append(f"truth extra '{name}' is not time-indexed: dropped from the excerpt")
        else:
            out[name] = arr[masks[candidates[0]]]
    return out, notes


def excerpt(recording: Recording, start_s: float, end_s: float) -> Recording:
    """Streams and ground truth within ``start_s <= t_s < end_s``, on a time axis starting at ``start_s``.

    Parameters
    ----------
    recording
        The full recording.
    start_s, end_s
        Window in seconds on the recording's time axis.

    Returns
    -------
    Recording
        ``t0_ns`` moved to the window start (raw ``t_ns`` unchanged), truth times shifted by
        ``-start_s``, label intervals clipped to the window; ``meta["excerpt"]`` records the source and
        window. A step count without step times, and extra truth arrays that are not indexed by time,
        cannot be cut and are dropped, with a warning.
    """
    if not end_s > start_s:
        raise InputError(f"empty window: end {end_s} s is not after start {start_s} s", field="end")
    part = recording.slice_time(start_s, end_s)
    truth = recording.truth
    notes: list[str] = []
    pos = truth.positions
    if pos is not None:
        keep = (pos.t_s >= start_s) & (pos.t_s < end_s)
        floor = pos.floor[keep] if pos.floor is not None else None
        pos = (PositionTruth(pos.t_s[keep] - start_s, pos.pos_m[keep], floor, pos.kind, pos.frame,
                             pos.origin_lat_lon_deg) if keep.any() else None)
    steps = lengths = None
    count = None
    if truth.step_times_s is not None:
        keep = (truth.step_times_s >= start_s) & (truth.step_times_s < end_s)
        steps = truth.step_times_s[keep] - start_s
        lengths = truth.step_lengths_m[keep] if truth.step_lengths_m is not None else None
        count = int(keep.sum())
    elif truth.step_count is not None:
        notes.append(f"truth step_count ({truth.step_count}) has no step times: dropped from the excerpt")
    extra, extra_notes = _cut_extra(dict(truth.extra), start_s, end_s)
    new_truth = GroundTruth(positions=pos, step_times_s=steps, step_count=count, step_lengths_m=lengths,
                            modes=_cut_labels(truth.modes, start_s, end_s),
                            landmarks=_cut_labels(truth.landmarks, start_s, end_s), extra=extra)
    meta = dict(recording.meta)
    meta["excerpt"] = {"source": recording.source, "format": recording.format,
                       "start_s": float(start_s), "end_s": float(end_s)}
    t0 = recording.origin_ns + int(round(start_s * 1e9))
    return replace(part, t0_ns=t0, truth=new_truth, meta=meta,
                   warnings=part.warnings + tuple(notes) + tuple(extra_notes))


def _output_kind(out: str | Path) -> str:
    """What ``OUT`` names: ``"batch"`` (``.json``, ``.json.gz``), ``"zip"`` (``.zip``) or ``"folder"``."""
    name = Path(out).name.lower()
    if name.endswith(".json") or name.endswith(".json.gz"):
        return "batch"
    return "zip" if name.endswith(".zip") else "folder"


def check_output(out: str | Path) -> None:
    """Refuse an ``OUT`` that cannot be written, before the log is read (:func:`pdr.cli.outputs.check_writable`).

    A folder is refused when a file of that name exists, or when it is new and its name ends in a file
    extension (letters after the last dot, e.g. ``out.csv``): the user meant a file, which the native format
    is not. Raises :class:`InputError` naming ``OUT``, or the :class:`OSError` writing would raise.
    """
    p = Path(out)
    if _output_kind(p) != "folder":
        check_writable(p)
        return
    if p.exists() and not p.is_dir():
        raise InputError("output exists and is not a folder", source=str(p))
    extension = p.suffix[1:]
    if not p.exists() and extension.isalpha():
        raise InputError(f"the native format is a folder, .zip, .json or .json.gz, not a .{extension} file: name "
                         "a folder without an extension, or one of those files", source=str(p), field="OUT")
    in_made_folder(p)


def write_native(recording: Recording, out: str | Path) -> Path:
    """Write as a native folder, zip (``.zip``) or JSON batch (``.json``, ``.json.gz``); see :func:`check_output`."""
    check_output(out)
    if _output_kind(out) == "batch":
        return native.write_batch(recording, Path(out))
    return native.write(recording, Path(out))


def run(args: argparse.Namespace) -> int:
    check_output(args.out)                # before the log is read, not after it
    with Progress(2, "convert") as bar:   # a large log takes a while to read and to write
        bar.set_note(f"reading {Path(args.log).name}")
        recording = registry.read_recording(args.log, args.format)
        if args.role is not None:
            recording = replace(recording, device=replace(recording.device, role=args.role))
        if args.start is not None or args.end is not None:
            start, end = recording.time_span_s()
            recording = excerpt(recording, start if args.start is None else args.start,
                                np.nextafter(end, np.inf) if args.end is None else args.end)
        bar.advance(note=f"writing {Path(args.out).name}")
        out = write_native(recording, args.out)
        bar.advance()
    print_warnings(recording.warnings)  # kept in the output too ('pdr inspect' lists them)
    n = sum(len(s) for s in recording.streams.values())
    print(f"wrote {out} ({len(recording.streams)} streams, {n} samples, {recording.duration_s:.3f} s)")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("convert", help="convert a log to the native format",
                              description=__doc__.split("\n\n", 1)[0] if __doc__ else None)
    p.add_argument("log", metavar="LOG", help="log file or folder in any supported format")
    p.add_argument("--to", choices=TARGETS, required=True, help="output format")
    p.add_argument("out", metavar="OUT", help="output folder, .zip, .json or .json.gz")
    p.add_argument("--format", metavar="F", help="force the input reader (see 'pdr inspect --formats')")
    p.add_argument("--start", type=float, metavar="S", help="keep samples from S seconds (recording time axis)")
    p.add_argument("--end", type=float, metavar="S", help="keep samples before S seconds")
    p.add_argument("--role", choices=DEVICE_ROLES,
                   help="device role to write (default: the log's; e.g. which foot carried a PyShoe IMU)")
    p.set_defaults(func=run)
