"""``pdr classify LOG``: motion modes of a log, as the service lists them (module :func:`run_classify`).

Registering the command imports nothing heavy (``pdr classify`` on a hand-held log needs neither scikit-learn nor
XGBoost); the model path imports them when it runs.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from classifiers.installed import DEFAULT_MODEL, placement_model
from pdr.cli.one_shot import one_shot_process
from pdr.cli.outputs import in_made_folder, print_warnings
from pdr.errors import InputError
from pdr.io.registry import read_recording
from pdr.recording import Recording


def register_classify(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("classify", help="motion mode (or other context) per window of a log")
    p.add_argument("log", help="log file or folder (any supported format)")
    p.add_argument("--model", default=None,
                   help="model name or folder (default: the motion-mode model installed for the phone's placement, "
                        f"{DEFAULT_MODEL} for a trouser pocket; for a placement without one, the modes the service "
                        "lists: the phone pipeline's step modes with its stops and elevator rides)")
    p.add_argument("--placement", default="auto", choices=("auto", "pocket", "hand", "torso", "swinging"),
                   help="where the phone is carried (auto: from the log's metadata, else detected from its motion)")
    p.add_argument("--out", required=True, help="CSV to write: t_start_s,t_end_s,mode,confidence")
    p.add_argument("--online", action="store_true",
                   help="forward filtering as in streaming use (a model's windows; the step-mode timeline of a "
                        "placement without a model is built online already)")
    p.set_defaults(func=run_classify)


def _placement_modes(rec: Recording, placement: str) -> tuple[str | None, list[dict[str, Any]] | None,
                                                              Callable[[str], list[dict[str, Any]]]]:
    """As the service: the motion-mode model installed for the phone's placement (``placement``; ``auto``: the
    log's metadata, else the pipeline's detection) as ``(name, None, step_modes)``; for a placement without one,
    ``(None, rows, step_modes)``: the phone pipeline's step modes with its stops and rides
    (:mod:`classifiers.step_timeline`), a notice on stderr. ``step_modes(why)`` gives those rows and notice when the
    installed model cannot use the log.
    """
    from classifiers.step_timeline import step_timeline
    from pdr.phone.configure import placement_group

    group: str | None = placement if placement != "auto" else placement_group(rec.device.placement)
    timeline = step_timeline(rec) if group == "auto" else None      # the pipeline detects the placement
    if timeline is not None:
        group = timeline.placement

    def step_modes(why: str) -> list[dict[str, Any]]:
        tl = timeline or step_timeline(rec, placement=group)
        print(f"motion modes from step patterns: {why}; the modes are the phone pipeline's step modes with its stops "
              f"and elevator rides, as the service lists them (no confidence)", file=sys.stderr)
        end = rec.origin_ns / 1e9 + rec.time_span_s()[1]
        return [{"t_start_s": a, "t_end_s": b, "mode": label, "confidence": math.nan} for a, b, label in tl.spans(end)]

    name = placement_model(group)
    if name is not None:
        return name, None, step_modes
    named = rec.device.placement if rec.device.placement not in (None, "", "unknown") else None
    how = (f"carried in the {group}" if group is not None else
           "whose placement is unknown (" + (f"the log's '{named}' is not one the pipeline tracks" if named else
                                             "the log names none") + " and no walking was detected to find it)")
    return None, step_modes(f"no mode classifier is installed for a phone {how}"), step_modes


def run_classify(args: argparse.Namespace) -> int:
    with one_shot_process():    # pdr.cli.one_shot
        return _classify(args)


def _classify(args: argparse.Namespace) -> int:
    """``pdr classify``: read, classify, write (:func:`run_classify`)."""
    rec = read_recording(args.log)
    print_warnings(rec.warnings)        # what the reader dropped (a cut-off last line, repeated samples, ...)
    if not rec.has("acc"):              # as `pdr track`: no windows and no steps, so the CSV would be empty
        why = "; ".join(w for w in rec.warnings if "acc" in w)
        raise InputError("no accelerometer stream with gravity ('acc'): cannot classify" + (f" ({why})" if why else ""),
                         source=str(args.log))
    t0 = rec.origin_ns / 1e9
    name, rows, step_modes = (args.model, None, None) if args.model else _placement_modes(rec, args.placement)
    if rows is None:
        from classifiers.artifacts import load_model

        assert name is not None         # a model was named or is installed for the placement
        model = load_model(name)
        try:
            if args.online:
                from classifiers.streaming import StreamingClassifier

                clf = StreamingClassifier(model)
                rows = [r.to_dict() for r in clf.update(rec) + clf.finish()]
            else:
                rows = model.classify(rec).rows(t0)
        except InputError as exc:
            if step_modes is None:      # the model was asked for
                raise
            # As the service (server.phone_processor): the installed model cannot use the log (an accelerometer-only
            # pocket log for a model that needs the gyro): the step modes, saying why.
            rows = step_modes(f"the installed '{name}' model cannot use this log ({exc.message})")
            name = None
    if not rows:     # an empty CSV says why (a log shorter than one window, or no step, stop or ride in it)
        span = rec.time_span_s()
        why = (f"the log's {span[1] - span[0]:.1f} s hold no full {model.window.length_s:g} s window of the streams "
               f"the '{name}' model needs" if name is not None else
               "the phone pipeline found no step, stop or elevator ride in the log")
        print(f"note: no motion modes: {why}; the CSV has its header only", file=sys.stderr)
    out = Path(args.out)
    write_modes_csv(rows, out)
    tally: dict[str, int] = {}
    for r in rows:
        tally[r["mode"]] = tally.get(r["mode"], 0) + 1
    what = "timeline entries" if name is None else "windows"
    counts = " (" + ", ".join(f"{m} {c}" for m, c in sorted(tally.items())) + ")" if tally else ""
    print(f"wrote {out}: {len(rows)} {what}{counts}")
    return 0


def write_modes_csv(rows: list[dict[str, Any]], out: Path) -> None:
    """The CSV of ``pdr classify``: ``t_start_s,t_end_s,mode,confidence`` (s on the log's clock; confidence empty
    where there is none), its folder made.
    """
    with in_made_folder(out).open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["t_start_s", "t_end_s", "mode", "confidence"])
        for r in rows:
            conf = "" if math.isnan(r["confidence"]) else f"{r['confidence']:.4f}"
            w.writerow([f"{r['t_start_s']:.3f}", f"{r['t_end_s']:.3f}", r["mode"], conf])
