"""Fig. r5: success rate, mission completion time and energy of CC, S1 and S2, with 95 % CIs."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

LABELS = {"cc": "CC", "s1": "S1", "s2": "S2", "concurrent": "CC\n(concurrent)",
          "cc+risk": "CC\n+risk", "s1+risk": "S1\n+risk", "s2+risk": "S2\n+risk",
          "concurrent+risk": "conc.\n+risk", "lookahead": "look-\nahead",
          "lookahead+risk": "lookahead\n+risk", "oracle": "oracle"}
COLORS = {"cc": "#2ca02c", "s1": "#1f77b4", "s2": "#d62ca8", "concurrent": "#ff7f0e",
          "cc+risk": "#98df8a", "s1+risk": "#aec7e8", "s2+risk": "#f7b6d2",
          "concurrent+risk": "#ffbb78", "lookahead": "#9467bd", "lookahead+risk": "#c5b0d5",
          "oracle": "#7f7f7f"}


def plot_fig_r5(summary: dict[str, Any], path: Path) -> Path:
    ctrl = summary["controllers"]
    names = [c for c in LABELS if c in ctrl]
    panels = [
        ("(a) Success rate", "success rate (%)", "success_rate", "success_rate_ci95", 100.0),
        (
            "(b) Mission completion time",
            "time (s)",
            "mission_time_s_mean",
            "mission_time_s_ci95",
            1.0,
        ),
        ("(c) Energy  Σ‖u_t − u_{t−1}‖²", "energy (N²)", "energy_mean", "energy_ci95", 1.0),
    ]
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.8))
    for ax, (title, ylabel, key, ci_key, scale) in zip(axes, panels, strict=True):
        vals = np.array([ctrl[c][key] for c in names], dtype=float) * scale
        ci = np.array([ctrl[c][ci_key] for c in names], dtype=float) * scale
        err = np.abs(np.vstack([vals - ci[:, 0], ci[:, 1] - vals]))
        err = np.nan_to_num(err)
        x = np.arange(len(names))
        ax.bar(
            x,
            np.nan_to_num(vals),
            yerr=err,
            capsize=6,
            color=[COLORS[c] for c in names],
            alpha=0.85,
        )
        ax.set_xticks(x, [LABELS[c] for c in names])
        ax.set_title(title)
        ax.set_ylabel(ylabel)
        for xi, v, top in zip(x, vals, ci[:, 1], strict=True):
            if np.isfinite(v):
                y = top if np.isfinite(top) else v
                ax.annotate(f"{v:.3g}", (xi, y), textcoords="offset points", xytext=(0, 4),
                            ha="center", va="bottom", fontsize=9)
        ax.margins(y=0.12)
        ax.grid(axis="y", alpha=0.3)
    axes[0].set_ylim(0, 105)
    fig.suptitle(
        f"{summary['missions']} missions, timing = {summary['timing']} "
        "(time and energy over successful missions; bars: 95 % CI)",
        fontsize=10,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
