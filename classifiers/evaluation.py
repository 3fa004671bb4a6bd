"""Classification metrics and report plots: confusion matrix, per-class precision/recall/F1, macro-F1,
calibration (reliability table and expected calibration error), as JSON-able dicts and a PNG.

``unknown`` (the reject option) is a prediction like any other in the confusion matrix: a rejected window
counts against the recall of its true class but not against any class's precision. Coverage (fraction
of windows not rejected) is reported alongside.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from classifiers.model import UNKNOWN

N_CALIBRATION_BINS = 10


def classification_metrics(y_true: ArrayLike, y_pred: ArrayLike, confidence: ArrayLike,
                           classes: Sequence[str], target_classes: Sequence[str] | None = None) -> dict[str, Any]:
    """Confusion matrix, per-class precision/recall/F1, macro-F1, accuracy, coverage and calibration.

    Parameters
    ----------
    y_true, y_pred
        (n,) true and predicted labels (``unknown`` allowed in ``y_pred``).
    confidence
        (n,) posterior probability of the predicted (or best) class.
    classes
        Row order of the confusion matrix (true classes); ``unknown`` is added as a last column.
    target_classes
        Optional subset whose macro-F1 is reported as ``macro_f1_target_classes``.
    """
    yt = np.asarray(y_true).astype(str)
    yp = np.asarray(y_pred).astype(str)
    conf = np.asarray(confidence, dtype=np.float64)
    rows = list(classes)
    cols = rows + [UNKNOWN]
    cm = np.zeros((len(rows), len(cols)), dtype=np.int64)
    ri = {c: i for i, c in enumerate(rows)}
    ci = {c: i for i, c in enumerate(cols)}
    for t, p in zip(yt, yp, strict=True):
        if t in ri:
            cm[ri[t], ci.get(p, ci[UNKNOWN])] += 1
    per: dict[str, dict[str, float | int]] = {}
    for c in rows:
        tp = int(np.sum((yt == c) & (yp == c)))
        fp = int(np.sum((yt != c) & (yp == c)))
        fn = int(np.sum((yt == c) & (yp != c)))
        prec = tp / (tp + fp) if tp + fp else 0.0
        rec = tp / (tp + fn) if tp + fn else 0.0
        f1 = 2 * prec * rec / (prec + rec) if prec + rec else 0.0
        per[c] = {"precision": prec, "recall": rec, "f1": f1, "support": int(np.sum(yt == c))}
    present = [c for c in rows if per[c]["support"] > 0]
    out: dict[str, Any] = {
        "classes": rows,
        "confusion_matrix": {"rows_true": rows, "cols_pred": cols, "counts": cm.tolist()},
        "per_class": per,
        "macro_f1": float(np.mean([per[c]["f1"] for c in present])) if present else 0.0,
        "accuracy": float(np.mean(yt == yp)) if yt.size else 0.0,
        "coverage": float(np.mean(yp != UNKNOWN)) if yp.size else 0.0,
        "n_windows": int(yt.size),
    }
    if target_classes:
        tc = [c for c in target_classes if c in per]
        out["target_classes"] = tc
        out["macro_f1_target_classes"] = float(np.mean([per[c]["f1"] for c in tc])) if tc else 0.0
    out["calibration"] = calibration(yt == yp, conf)
    out["ece"] = out["calibration"]["ece"]
    return out


def calibration(correct: ArrayLike, confidence: ArrayLike, n_bins: int = N_CALIBRATION_BINS) -> dict[str, Any]:
    """Reliability table of confidence against accuracy in equal-width bins, and the expected calibration
    error ``ECE = sum_b (n_b / n) |acc_b - conf_b|``.
    """
    ok = np.asarray(correct, dtype=bool)
    c = np.clip(np.asarray(confidence, dtype=np.float64), 0.0, 1.0)
    edges = np.linspace(0.0, 1.0, n_bins + 1)
    b = np.clip(np.digitize(c, edges[1:-1]), 0, n_bins - 1)
    bins = []
    ece = 0.0
    for k in range(n_bins):
        m = b == k
        n = int(m.sum())
        acc = float(ok[m].mean()) if n else float("nan")
        mc = float(c[m].mean()) if n else float("nan")
        if n:
            ece += n / max(1, c.size) * abs(acc - mc)
        bins.append({"lo": float(edges[k]), "hi": float(edges[k + 1]), "n": n,
                     "accuracy": None if not n else acc, "mean_confidence": None if not n else mc})
    return {"bins": bins, "ece": float(ece)}


def plot_report(metrics: dict[str, Any], path: str | Path, title: str = "") -> Path:
    """Confusion matrix (row-normalised) and reliability diagram side by side, as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cm = np.asarray(metrics["confusion_matrix"]["counts"], dtype=np.float64)
    rows = metrics["confusion_matrix"]["rows_true"]
    cols = metrics["confusion_matrix"]["cols_pred"]
    norm = cm / np.maximum(cm.sum(axis=1, keepdims=True), 1)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 5.5), gridspec_kw={"width_ratios": [1.4, 1]})
    ax1.imshow(norm, cmap="Blues", vmin=0, vmax=1)
    ax1.set_xticks(range(len(cols)), cols, rotation=60, ha="right", fontsize=8)
    ax1.set_yticks(range(len(rows)), rows, fontsize=8)
    for i in range(cm.shape[0]):
        for j in range(cm.shape[1]):
            if cm[i, j]:
                ax1.text(j, i, f"{int(cm[i, j])}", ha="center", va="center", fontsize=7,
                         color="white" if norm[i, j] > 0.5 else "black")
    ax1.set_xlabel("predicted")
    ax1.set_ylabel("true")
    ax1.set_title(f"confusion (macro-F1 {metrics['macro_f1']:.3f})")
    bins = metrics["calibration"]["bins"]
    mids = [0.5 * (b["lo"] + b["hi"]) for b in bins if b["n"]]
    accs = [b["accuracy"] for b in bins if b["n"]]
    ax2.plot([0, 1], [0, 1], "k--", lw=1, label="perfect")
    ax2.bar(mids, accs, width=1.0 / len(bins), alpha=0.6, edgecolor="k", label="accuracy")
    ax2.set_xlim(0, 1)
    ax2.set_ylim(0, 1)
    ax2.set_xlabel("confidence (smoothed posterior)")
    ax2.set_ylabel("accuracy")
    ax2.set_title(f"calibration (ECE {metrics['ece']:.3f})")
    ax2.legend(loc="upper left")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return out
