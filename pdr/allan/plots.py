"""Log-log Allan-deviation plots (PNG, matplotlib Agg backend; no display needed).

One figure per sensor: the overlapping ADEV of each axis with its confidence interval as error
bars, the fitted noise model (dashed), the asymptote lines of the resolved terms (dotted: -1/2 line of
N, flat 0.664 B, +1/2 line of K, ...), and markers where the classic readings are taken: the -1/2 line
at tau = 1 s (N), the minimum (tau_min, 0.664 B) and the +1/2 line at tau = 3 s (K).
"""

from __future__ import annotations

import io
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from pdr.allan.characterise import SensorResult  # noqa: E402
from pdr.allan.noise_model import FLICKER_FACTOR, model_columns  # noqa: E402

_COLORS = {"x": "tab:red", "y": "tab:green", "z": "tab:blue"}
_TITLES = {"gyro": "Gyroscope", "acc": "Accelerometer"}


def plot_sensor(result: SensorResult, title_suffix: str = "") -> bytes:
    """PNG bytes of the Allan-deviation plot of one sensor."""
    tau = result.curve.tau_s
    fig, ax = plt.subplots(figsize=(8.0, 6.0), dpi=110)
    dense = np.logspace(np.log10(tau[0]), np.log10(tau[-1]), 300)
    cols = model_columns(dense)
    for name, a in result.axes.items():
        c = _COLORS.get(name, "black")
        yerr = np.vstack([a.adev - a.adev_lo, a.adev_hi - a.adev])
        ax.errorbar(tau, a.adev, yerr=yerr, fmt="o-", ms=3, lw=1.2, color=c, capsize=2, elinewidth=0.8,
                    label=f"{name} overlapping ADEV")
        theta = np.array([(a.fit.estimate[k]) ** 2 for k in ("Q", "N", "B", "K", "R")])
        ax.plot(dense, np.sqrt(cols @ theta), "--", color=c, lw=1.0, alpha=0.9, label=f"{name} model fit")
        for i, k in enumerate(("Q", "N", "B", "K", "R")):
            if a.fit.value[k] is not None:
                ax.plot(dense, np.sqrt(cols[:, i] * theta[i]), ":", color=c, lw=0.9, alpha=0.7)
        sl = a.slopes
        if sl.N is not None:
            ax.plot([1.0], [sl.N], marker="s", mfc="none", color=c, ms=8)
        ax.plot([sl.tau_min_s], [sl.adev_min], marker="v", mfc="none", color=c, ms=8)
        if sl.K is not None:
            ax.plot([3.0], [sl.K], marker="^", mfc="none", color=c, ms=8)
        for k, v in (("N", a.fit.value["N"]), ("K", a.fit.value["K"])):
            if v is not None:
                ax.plot([1.0 if k == "N" else 3.0], [v], marker="x", color=c, ms=7)
        if a.fit.value["B"] is not None:
            ax.plot([sl.tau_min_s], [FLICKER_FACTOR * a.fit.value["B"]], marker="x", color=c, ms=7)
    lows = np.concatenate([a.adev_lo for a in result.axes.values()])
    highs = np.concatenate([a.adev_hi for a in result.axes.values()])
    lows = lows[np.isfinite(lows) & (lows > 0)]
    highs = highs[np.isfinite(highs) & (highs > 0)]
    if lows.size and highs.size:
        ax.set_ylim(lows.min() / 3.0, highs.max() * 2.0)  # asymptotes must not squash the curves
    for xv in (1.0, 3.0):
        if tau[0] <= xv <= tau[-1]:
            ax.axvline(xv, color="0.8", lw=0.8, zorder=0)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("averaging time tau [s]")
    ax.set_ylabel(f"Allan deviation [{result.unit}]")
    ax.set_title(f"{_TITLES.get(result.sensor, result.sensor)}{title_suffix}")
    ax.grid(True, which="both", lw=0.4, alpha=0.5)
    handles, labels = ax.get_legend_handles_labels()
    from matplotlib.lines import Line2D

    handles += [Line2D([], [], ls=":", color="0.3"), Line2D([], [], marker="s", mfc="none", ls="", color="0.3"),
                Line2D([], [], marker="v", mfc="none", ls="", color="0.3"),
                Line2D([], [], marker="^", mfc="none", ls="", color="0.3"),
                Line2D([], [], marker="x", ls="", color="0.3")]
    labels += ["asymptotes of resolved terms", "slope reading N (-1/2 line at 1 s)", "minimum (tau_min)",
               "slope reading K (+1/2 line at 3 s)", "fitted N / 0.664 B / K at the same taus"]
    ax.legend(handles, labels, fontsize=7, loc="best")
    fig.tight_layout()
    out = io.BytesIO()
    fig.savefig(out, format="png")
    plt.close(fig)
    return out.getvalue()


def write_plot(result: SensorResult, path: str | Path, title_suffix: str = "") -> bytes:
    """Write the PNG to ``path`` and return its bytes."""
    png = plot_sensor(result, title_suffix)
    Path(path).write_bytes(png)
    return png
