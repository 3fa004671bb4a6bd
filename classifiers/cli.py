"""Command line: ``pdr train``, ``pdr classify`` and the ``pdr eval classifier`` target.

``pdr train TASK --data PATH... --out models/NAME [--estimator bayes|xgboost|landmark_tree] [--cv] [--without G...]``
    Fit a model on every log under the paths; with ``--cv`` also run leave-one-group-out evaluation and
    put the figures, with the command line, into the model card.
``pdr classify LOG [--model NAME] --out MODES.csv [--online]``
    One row per window ``t_start_s,t_end_s,mode,confidence`` on the log's own clock; smoothed offline
    (forward-backward) or, with ``--online``, as the streaming classifier would emit them (a model with
    context features decides the last windows when the log ends).
``pdr eval classifier MODEL --data PATH... [--cv] [--json] [--out-dir DIR] [--target-classes ...]``
    Confusion matrix, per-class precision/recall/F1, macro-F1 and calibration (JSON and PNG) of a saved
    model on held-out data, or (``--cv``) of its configuration retrained leave-one-group-out; prints the
    inference speed in windows per second on one core. With ``--timeline``: the modes timeline's figures per
    recording instead (:mod:`classifiers.timeline_eval`); with ``--floors``: the step-mode timeline's stairs
    steps and elevator rides on multi-floor walks with landmarks (:mod:`classifiers.floor_eval`); with
    ``--targets``: both, as issue 30's targets beside their figures (:mod:`classifiers.mode_targets`).
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from classifiers.artifacts import library_versions, load_model, model_card, save_model
from classifiers.datasets import LabelledWindows, labelled_windows, load_recordings
from classifiers.evaluation import classification_metrics, plot_report
from classifiers.features import extract_features
from classifiers.model import ContextModel
from classifiers.simdata import simulated_recordings
from classifiers.tasks import TASKS, get_task
from classifiers.training import ESTIMATOR_KINDS, available_groups, cross_validate, fit_model, predict_sequences
from classifiers.windows import WindowConfig, Windows, make_windows
from pdr.cli.progress import Progress
from pdr.errors import InputError
from pdr.recording import Recording

#: The classes the MobiFall target is stated over (issue: stand, walk, jog, stairs up, stairs down).
DEFAULT_TARGETS = {"motion_mode": ["stationary", "walking", "running", "stairs_up", "stairs_down"],
                   "landmark": ["stairs", "elevator"]}


def _command_line() -> str:
    return "pdr " + " ".join(shlex.quote(a) for a in sys.argv[1:])


def _training_summary(data: LabelledWindows, recs: list[Recording]) -> dict[str, Any]:
    used = sorted(set(data.recording.tolist()))
    placements: dict[str, int] = {}
    for i in used:
        key = recs[i].device.placement or "unknown"
        placements[key] = placements.get(key, 0) + 1
    return {"recordings": len(used), "windows": len(data), "placements": placements,
            "groups": sorted(set(data.groups.astype(str).tolist())), "class_windows": data.class_counts()}


#: How the cross-validation figures are made (stated in every model card evaluation it makes).
CV_PROTOCOL = ("leave-one-group-out: each group (a subject where the source names one, else a recording) is held "
               "out in turn, the model is refitted on the others and applied to the held-out recordings in time "
               "order (Markov smoothing over each recording); windows are never shuffled across groups")


def _per_placement(data: LabelledWindows, recs: list[Recording], label: np.ndarray, confidence: np.ndarray,
                   classes: list[str], targets: list[str] | None) -> dict[str, Any]:
    """Classification figures of each placement group (device placement of the window's recording)."""
    place = np.array([recs[i].device.placement or "unknown" for i in data.recording.tolist()], dtype=object)
    out: dict[str, Any] = {}
    for p in sorted(set(place.tolist())):
        m = place == p
        present = [t for t in (targets or []) if t in set(data.y[m].astype(str).tolist())]
        sub = classification_metrics(data.y[m], label[m], confidence[m], classes, present or None)
        out[p] = {k: sub[k] for k in ("macro_f1", "macro_f1_target_classes", "accuracy", "n_windows") if k in sub}
        out[p]["per_class"] = {c: v for c, v in sub["per_class"].items() if v["support"] > 0}
    return out


def _recordings(args: argparse.Namespace) -> list[Recording]:
    recs = load_recordings(args.data) if args.data else []
    if args.sim:
        recs += simulated_recordings(args.sim, args.sim_seed)
    if not recs:
        raise InputError("no data: give --data PATH... and/or --sim N")
    return recs


# ---------------------------------------------------------------- train
def register_train(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("train", help="train a motion-mode, placement or landmark classifier",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("task", choices=sorted(TASKS), help="classification task")
    p.add_argument("--data", nargs="*", default=[], help="logs or folders of logs (any supported format)")
    p.add_argument("--sim", type=int, default=0, metavar="N",
                   help="add N simulated logs with stairs, elevator and escalator rides (pdr.sim)")
    p.add_argument("--sim-seed", type=int, default=0, help="seed of the simulated logs")
    p.add_argument("--out", required=True, help="model folder to write (e.g. models/NAME)")
    p.add_argument("--estimator", choices=ESTIMATOR_KINDS, default=None,
                   help="bayes (default; landmark_tree for the landmark task) or xgboost")
    p.add_argument("--window-s", type=float, default=2.56, help="window length (s)")
    p.add_argument("--hop-s", type=float, default=1.28, help="window hop (s)")
    p.add_argument("--rate-hz", type=float, default=50.0, help="resampling rate (Hz)")
    p.add_argument("--dwell-s", type=float, default=None, help="mean dwell time of the Markov smoothing (s)")
    p.add_argument("--reject", type=float, default=0.5, help="posterior below which the label is 'unknown'")
    p.add_argument("--cv", action="store_true", help="also run leave-one-group-out evaluation into the card")
    p.add_argument("--without", nargs="*", default=[], metavar="GROUP",
                   help="feature groups to leave out (ablation: how much a group helps)")
    p.add_argument("--note", default=None, help="free text for the model card's Notes section")
    p.set_defaults(func=run_train)


def run_train(args: argparse.Namespace) -> int:
    task = get_task(args.task)
    cfg = WindowConfig(length_s=args.window_s, hop_s=args.hop_s, rate_hz=args.rate_hz)
    kind = args.estimator or ("landmark_tree" if task.name == "landmark" else "bayes")
    unknown = sorted(set(args.without) - set(task.feature_groups))
    if unknown:
        raise InputError(f"--without: {', '.join(unknown)} not among the task's feature groups "
                         f"{', '.join(task.feature_groups)}", field="without")
    with Progress(4 if args.cv else 3, f"train {task.name}") as bar:
        bar.set_note("reading the logs" + (f", simulating {args.sim}" if args.sim else ""))
        recs = _recordings(args)
        groups = tuple(g for g in available_groups(recs, task) if g not in args.without)
        bar.advance(note=f"windows and features of {len(recs)} recordings")
        data = labelled_windows(recs, task, cfg, groups)
        bar.advance(note=f"fitting on {len(data)} windows")
        model = fit_model(data, task, cfg, groups, kind, reject_threshold=args.reject, mean_dwell_s=args.dwell_s)
        bar.advance(note="leave-one-group-out cross-validation" if args.cv else None)
        if args.cv:
            metrics = _cv_metrics(data, model, task.name, recs=recs)
            bar.advance()
    model.info = {"train_command": _command_line(), "training_data": {
        "paths": [str(p) for p in args.data], "simulated_logs": args.sim, "simulation_seed": args.sim_seed,
        **_training_summary(data, recs)},
        "estimator_params": {k: (v if isinstance(v, int | float | str | type(None)) else str(v))
                             for k, v in model.estimator.get_params().items() if k != "columns"},
        "evaluations": []}
    if args.note:
        model.info["notes"] = args.note
    if args.cv:
        model.info["evaluations"].append({"title": "leave-one-group-out cross-validation on the training data",
                                          "protocol": CV_PROTOCOL,
                                          "command": _command_line(), "metrics": _card_metrics(metrics)})
    out = save_model(model, args.out)
    print(f"wrote {out} ({kind}, {len(model.classes)} classes, {len(data)} windows, "
          f"{len(model.feature_names)} features, streams {', '.join(model.required_streams)})")
    if args.cv:
        m = model.info["evaluations"][-1]["metrics"]
        line = f"leave-one-group-out macro-F1 {m['macro_f1']:.4f}"
        if "target_classes" in m:
            line += f", over {', '.join(m['target_classes'])}: {m['macro_f1_target_classes']:.4f}"
        print(line)
    return 0


def _cv_metrics(data: LabelledWindows, model: ContextModel, task_name: str,
                targets: list[str] | None = None, recs: list[Recording] | None = None) -> dict[str, Any]:
    """Leave-one-group-out figures (:data:`CV_PROTOCOL`); per placement too when ``recs`` has several."""
    task = get_task(task_name)
    params = {k: v for k, v in model.estimator.get_params().items() if k != "columns"}
    res, classes = cross_validate(data, task, model.window, model.feature_groups, model.estimator_kind, params,
                                  model.reject_threshold, model.mean_dwell_s)
    targets = targets if targets is not None else DEFAULT_TARGETS.get(task_name)
    metrics = classification_metrics(data.y, res.label, res.confidence, classes, targets)
    metrics["n_groups"] = len(set(data.groups.astype(str).tolist()))
    if recs is not None and task.label_source != "placement":
        metrics["per_placement"] = _per_placement(data, recs, np.asarray(res.label, dtype=object),
                                                  np.asarray(res.confidence, dtype=np.float64), classes, targets)
    return metrics


def _card_metrics(metrics: dict[str, Any]) -> dict[str, Any]:
    keep = ("macro_f1", "macro_f1_target_classes", "target_classes", "accuracy", "coverage", "ece", "n_windows",
            "n_groups", "per_class", "confusion_matrix", "windows_per_s", "classifier_windows_per_s",
            "features_and_classifier_windows_per_s", "end_to_end_windows_per_s", "per_placement")
    return {k: metrics[k] for k in keep if k in metrics}


# ---------------------------------------------------------------- eval
def register_eval(targets: argparse._SubParsersAction) -> None:
    p = targets.add_parser("classifier", help="evaluate a classifier model (grouped, with calibration)")
    p.add_argument("model", help="model folder or shipped model name")
    p.add_argument("--data", nargs="*", default=[], help="labelled logs or folders")
    p.add_argument("--sim", type=int, default=0, metavar="N", help="add N simulated logs (pdr.sim)")
    p.add_argument("--sim-seed", type=int, default=1, help="seed of the simulated logs (training used 0)")
    p.add_argument("--cv", action="store_true",
                   help="retrain the model's configuration leave-one-group-out on the data instead of "
                        "applying the saved model (use when the data was used for training)")
    p.add_argument("--json", action="store_true", help="print the metrics as JSON")
    p.add_argument("--no-barometer", action="store_true",
                   help="leave out the barometric second stage (classifiers.baro_stage): how much it helps")
    p.add_argument("--out-dir", default=None, help="write metrics.json and report.png here")
    p.add_argument("--target-classes", nargs="*", default=None, help="classes of the headline macro-F1")
    p.add_argument("--update-card", action="store_true", help="append the figures to the model card")
    p.add_argument("--timeline", action="store_true",
                   help="instead: figures of the modes timeline per recording (car/vehicle labels in walks, "
                        "vehicle fraction of car trips, IPIN stops found; classifiers.timeline_eval)")
    p.add_argument("--floors", action="store_true",
                   help="instead: figures of the step-mode timeline on multi-floor walks with landmarks (stairs "
                        "steps, elevator rides and their floor count; classifiers.floor_eval)")
    p.add_argument("--targets", action="store_true",
                   help="instead: issue 30's modes-timeline targets, each figure beside its target (the --timeline "
                        "and --floors figures; classifiers.mode_targets)")
    p.add_argument("--site", default=None, metavar="SITE.json",
                   help="with --floors or --targets: the building's site description (floor height or floor "
                        "altitudes)")
    p.set_defaults(func=run_eval)


#: Fewest windows the speed benchmark runs on (the longest logs are added until there are this many).
BENCHMARK_MIN_WINDOWS = 2000


def benchmark(model: ContextModel, X: np.ndarray, recs: list[Recording] | None = None,
              repeats: int = 3) -> dict[str, float]:
    """Inference speed on one core, in windows per second.

    ``classifier``: the estimator on ready features ``X``; ``features_and_classifier``: feature extraction
    and estimator on the windows of the longest of ``recs`` (log by log, until ``BENCHMARK_MIN_WINDOWS``);
    ``end_to_end``: also cutting the logs into windows (resampling). Each figure is the best of ``repeats``
    runs, by the process's CPU time with every thread pool limited to one thread (a shared machine's load
    does not count against it), and also by wall-clock time (``_wall``).
    """
    from threadpoolctl import threadpool_limits

    def best(fn: Any) -> tuple[float, float]:
        cpu, wall = float("inf"), float("inf")
        for _ in range(repeats):
            c, t = time.process_time(), time.perf_counter()
            fn()
            cpu, wall = min(cpu, time.process_time() - c), min(wall, time.perf_counter() - t)
        return max(cpu, 1e-9), max(wall, 1e-9)

    out: dict[str, float] = {}
    with threadpool_limits(limits=1):
        cpu, wall = best(lambda: model.window_proba(X))
        out["classifier_windows_per_s"] = X.shape[0] / cpu
        out["classifier_windows_per_s_wall"] = X.shape[0] / wall
        chosen: list[Recording] = []
        wins: list[Windows] = []
        for rec in sorted(recs or [], key=lambda r: -r.duration_s):
            if sum(len(w) for w in wins) >= BENCHMARK_MIN_WINDOWS:
                break
            w = make_windows(rec, model.window, margin_s=model.margin_s)
            if len(w):
                chosen.append(rec)
                wins.append(w)
        n = sum(len(w) for w in wins)
        if n:
            model.window_proba(extract_features(wins[0], model.feature_groups))  # compile the kernels first
            cpu, wall = best(lambda: [model.window_proba(extract_features(w, model.feature_groups)) for w in wins])
            out["features_and_classifier_windows_per_s"] = n / cpu
            out["features_and_classifier_windows_per_s_wall"] = n / wall

            def whole() -> None:
                for rec in chosen:
                    w = make_windows(rec, model.window, margin_s=model.margin_s)
                    model.window_proba(extract_features(w, model.feature_groups))

            cpu, wall = best(whole)
            out["end_to_end_windows_per_s"] = n / cpu
            out["end_to_end_windows_per_s_wall"] = n / wall
            out["benchmark_windows"] = float(n)
            out["benchmark_logs"] = float(len(chosen))
    return out


def _report_figures(args: argparse.Namespace, fig: dict[str, Any], name: str,
                    print_text: Callable[[dict[str, Any]], None]) -> None:
    """Figures with the command line that made them: into ``--out-dir``/``name`` if given, then as JSON
    (``--json``) or text.
    """
    fig["command"] = _command_line()
    if args.out_dir:
        out = Path(args.out_dir)
        out.mkdir(parents=True, exist_ok=True)
        (out / name).write_text(json.dumps(fig, indent=1) + "\n", encoding="utf-8")
    if args.json:
        print(json.dumps(fig, indent=1))
    else:
        print_text(fig)


def run_eval(args: argparse.Namespace) -> int:
    model = load_model(args.model)
    model.barometer = not args.no_barometer
    task = get_task(model.task)
    # Stages on a terminal's stderr (reading the logs takes minutes over several datasets); the figures are printed
    # once the bar is closed, so the two never share a line.
    with Progress(2 if args.floors or args.targets or args.timeline else 4, f"eval classifier {args.model}") as bar:
        bar.set_note("reading the logs" + (f", simulating {args.sim}" if args.sim else ""))
        recs = _recordings(args)
        bar.advance(note=f"{len(recs)} recordings")
        if args.floors:
            from classifiers.floor_eval import floor_figures, print_floor_figures
            from pdr.phone.landmarks import Site

            report = ("floors.json", floor_figures(recs, Site.load(args.site) if args.site else None),
                      print_floor_figures)
        elif args.targets:
            from classifiers.mode_targets import print_targets, target_figures
            from pdr.phone.landmarks import Site

            report = ("targets.json", target_figures(model, recs, Site.load(args.site) if args.site else None),
                      print_targets)
        elif args.timeline:
            from classifiers.timeline_eval import print_timeline, timeline_figures

            report = ("timeline.json", timeline_figures(model, recs), print_timeline)
        if args.floors or args.targets or args.timeline:
            bar.advance()
        else:
            missing = [s for s in model.required_streams if not all(r.has(s) for r in recs)]
            if missing:
                raise InputError(f"the model needs the {', '.join(missing)} stream(s), which some of the data lacks")
            data = labelled_windows(recs, task, model.window, model.feature_groups)
            if args.no_barometer:
                data = replace(data, baro=None)
            bar.advance(note=("leave-one-group-out cross-validation" if args.cv else "predicting")
                        + f" on {len(data)} windows")
            targets = args.target_classes if args.target_classes is not None else DEFAULT_TARGETS.get(task.name)
            if args.cv:
                metrics = _cv_metrics(data, model, task.name, targets, recs)
                title = "leave-one-group-out cross-validation"
            else:
                res = predict_sequences(model, data)
                classes = sorted(set(data.y.astype(str)) | set(model.classes))
                metrics = classification_metrics(data.y, res.label, res.confidence, classes, targets)
                if task.label_source != "placement":
                    metrics["per_placement"] = _per_placement(data, recs, np.asarray(res.label, dtype=object),
                                                              np.asarray(res.confidence, dtype=np.float64),
                                                              classes, targets)
                title = "saved model on the given data"
            bar.advance(note="inference speed")
            metrics["n_groups"] = len(set(data.groups.astype(str).tolist()))
            X = np.tile(data.X, (max(1, 10000 // max(1, len(data))), 1))
            metrics.update(benchmark(model, X, recs))
            bar.advance()
    if args.floors or args.targets or args.timeline:
        _report_figures(args, report[1], report[0], report[2])
        return 0
    metrics["windows_per_s"] = metrics.get("features_and_classifier_windows_per_s", float("nan"))
    metrics["command"] = _command_line()
    metrics["versions"] = library_versions()
    if args.out_dir:
        out = Path(args.out_dir)
        out.mkdir(parents=True, exist_ok=True)
        (out / "metrics.json").write_text(json.dumps(metrics, indent=1) + "\n", encoding="utf-8")
        plot_report(metrics, out / "report.png", f"{model.info.get('name', '')}: {title}")
    if args.update_card:
        _append_card(args.model, title, metrics)
    if args.json:
        print(json.dumps(metrics, indent=1))
    else:
        print(f"{title}: {metrics['n_windows']} windows, {metrics['n_groups']} groups")
        print(f"macro-F1 {metrics['macro_f1']:.4f}  accuracy {metrics['accuracy']:.4f}  "
              f"coverage {metrics['coverage']:.4f}  ECE {metrics['ece']:.4f}")
        if "macro_f1_target_classes" in metrics:
            print(f"macro-F1 over {', '.join(metrics['target_classes'])}: {metrics['macro_f1_target_classes']:.4f}")
        for c, m in metrics["per_class"].items():
            print(f"  {c:22s} P {m['precision']:.3f}  R {m['recall']:.3f}  F1 {m['f1']:.3f}  n {m['support']}")
        print(f"inference on one core (CPU time; wall clock in brackets), {metrics['benchmark_windows']:.0f} "
              f"windows of the {metrics['benchmark_logs']:.0f} longest logs: classifier "
              f"{metrics['classifier_windows_per_s']:.0f} "
              f"({metrics['classifier_windows_per_s_wall']:.0f}) windows/s, features + classifier "
              f"{metrics['features_and_classifier_windows_per_s']:.0f} "
              f"({metrics['features_and_classifier_windows_per_s_wall']:.0f}) windows/s, with windowing "
              f"{metrics['end_to_end_windows_per_s']:.0f} ({metrics['end_to_end_windows_per_s_wall']:.0f}) windows/s")
    return 0


def _append_card(model_name: str, title: str, metrics: dict[str, Any]) -> None:
    from classifiers.installed import resolve_model_dir

    d = resolve_model_dir(model_name)
    doc = json.loads((d / "model.json").read_text(encoding="utf-8"))
    evals = doc.setdefault("info", {}).setdefault("evaluations", [])
    entry = {"title": title, "command": metrics["command"], "metrics": _card_metrics(metrics)}
    if title.startswith("leave-one-group-out"):
        entry["protocol"] = CV_PROTOCOL
    evals.append(entry)
    (d / "model.json").write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    (d / "MODEL_CARD.md").write_text(model_card(doc), encoding="utf-8")
