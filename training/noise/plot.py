"""Allan deviation plot of one triad: each axis's pooled curve with its 68 % CI band, the fitted
model, and the three IEEE 952 reading lines (−1/2 slope through N at τ = 1 s, the floor 0.664 B,
+1/2 slope through K at τ = 3 s), supported ones solid, unsupported ones dotted."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from training.noise.allan import FLOOR_FACTOR
from training.noise.characterise import UNITS, AxisNoise

AXIS_COLOURS = ("tab:red", "tab:green", "tab:blue")


def plot_triad(triad: str, axes: list[AxisNoise], path: str | Path, title: str = "") -> Path | None:
    """PNG of the triad's Allan deviations at `path`; None when no axis has a curve."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    if all(a.curve is None for a in axes):
        return None
    fig, ax = plt.subplots(figsize=(6.4, 4.4), dpi=90)
    u = UNITS[triad]
    for i, a in enumerate(axes):
        if a.curve is None or a.fit is None:
            continue
        c, colour, taus = a.curve, AXIS_COLOURS[i], a.curve.taus
        ci = c.ci(a.fit.dominant_alpha(taus))
        ax.fill_between(taus, ci[:, 0], ci[:, 1], color=colour, alpha=0.2, linewidth=0)
        ax.loglog(taus, c.adev, color=colour, linewidth=1.2, label=f"{'xyz'[i]}: data (68 % CI band)")
        ax.loglog(taus, np.sqrt(a.fit.avar(taus)), color=colour, linewidth=0.8, linestyle="--")
        f = a.figures
        style = {True: "-", False: ":"}
        n, b, k = (f[name] for name in ("noise_density", "bias_instability", "random_walk"))
        if n["value"] > 0:
            ax.loglog(taus, n["value"] / np.sqrt(taus), color=colour, linewidth=0.5, linestyle=style[n["supported"]])
        if b["value"] > 0:
            ax.loglog(taus, np.full(taus.shape, FLOOR_FACTOR * b["value"]), color=colour, linewidth=0.5,
                      linestyle=style[b["supported"]])
        if k["value"] > 0:
            ax.loglog(taus, k["value"] * np.sqrt(taus / 3.0), color=colour, linewidth=0.5,
                      linestyle=style[k["supported"]])
    ax.plot([], [], color="grey", linestyle="--", linewidth=0.8, label="fitted model")
    ax.plot([], [], color="grey", linestyle="-", linewidth=0.5, label="N, 0.664 B, K lines (dotted: unsupported)")
    lows = [a.curve.adev.min() for a in axes if a.curve is not None]
    highs = [a.curve.adev.max() for a in axes if a.curve is not None]
    ax.set_ylim(min(lows) / 3.0, max(highs) * 3.0)
    ax.set_xlabel("averaging time τ [s]")
    ax.set_ylabel(f"Allan deviation σ(τ) [{u}]")
    ax.set_title(title or f"{triad}: overlapping Allan deviation", fontsize=10)
    from matplotlib.ticker import NullFormatter
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.yaxis.set_minor_formatter(NullFormatter())
    ax.grid(True, which="both", linewidth=0.3)
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path)
    plt.close(fig)
    return path
