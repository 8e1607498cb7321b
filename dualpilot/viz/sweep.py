"""The sweep's figure: success (95 % Wilson intervals, the paper's Fig. r5 marked), time, energy.

One column group per grid point; the paper's S1 ≈ 95 %, S2 ≈ 40 %, CC ≈ 90 %
(Fig. r5a) are dashed lines in each controller's colour.
"""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from dualpilot.viz.evaluation import COLORS, LABELS  # noqa: E402

#: Fig. r5(a) of the paper: success rate (%) per controller.
PAPER_SUCCESS = {"cc": 90.0, "s1": 95.0, "s2": 40.0}


def _short(label: str) -> str:
    return "\n".join(textwrap.wrap(label.replace("profile=", ""), 22))


def plot_sweep(summary: dict[str, Any], path: Path) -> Path:
    """Three stacked panels over the grid points; returns ``path``."""
    points = summary["points"]
    names = [c for c in LABELS if c in summary["controllers"]]
    panels = [
        ("success rate (%)", "success_rate", "success_rate_ci95", 100.0),
        ("mission time (s)", "mission_time_s_mean", "mission_time_s_ci95", 1.0),
        ("energy Σ‖u_t − u_{t−1}‖² (N²)", "energy_mean", "energy_ci95", 1.0),
    ]
    n = len(points)
    fig, axes = plt.subplots(3, 1, figsize=(max(7.0, 0.75 * n + 2.0), 10), sharex=True)
    x = np.arange(n)
    width = 0.8 / max(len(names), 1)
    for ax, (ylabel, key, ci_key, scale) in zip(axes, panels, strict=True):
        for j, c in enumerate(names):
            stats = [p["controllers"].get(c) for p in points]
            vals = np.array([s[key] if s else np.nan for s in stats], dtype=float) * scale
            ci = np.array([s[ci_key] if s else [np.nan, np.nan] for s in stats],
                          dtype=float) * scale
            err = np.nan_to_num(np.abs(np.vstack([vals - ci[:, 0], ci[:, 1] - vals])))
            ax.errorbar(x + (j - (len(names) - 1) / 2) * width, vals, yerr=err, fmt="o",
                        capsize=4, color=COLORS[c], label=LABELS[c])
            if key == "success_rate" and c in PAPER_SUCCESS:  # the paper's Fig. r5
                ax.axhline(PAPER_SUCCESS[c], color=COLORS[c], ls="--", lw=1, alpha=0.7)
        ax.set_ylabel(ylabel)
        ax.grid(axis="y", alpha=0.3)
    axes[0].set_ylim(-2, 102)
    axes[0].legend(title="dashed: paper (Fig. r5a)", fontsize=8, ncols=3, loc="lower right")
    axes[-1].set_xticks(x, [f"[{p['point']}]\n{_short(p['label'])}" for p in points],
                        fontsize=6 if n > 8 else 7, rotation=90 if n > 8 else 0)
    axes[0].set_title(
        f"{summary['missions']} missions per point, timing = {summary['timing']}, seed "
        f"{summary['seed']}\n(Wilson 95 % intervals; time and energy over successful "
        "missions, 95 % CI)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
