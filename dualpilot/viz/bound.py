"""Figure and ``dualpilot bound`` command: P(S1 in control | d, t) of the paper's supervisor.

The numbers come from :mod:`dualpilot.evaluation.bound` (an exact Markov chain, no sampling).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

from dualpilot.evaluation.bound import (
    attention_marginal,
    best_cc_success,
    p_s1,
    p_s1_path,
    p_s1_table,
)
from dualpilot.supervisor.paper.decision import SupervisorParams

TABLE_STEPS = (0, 15, 30, 45)
CURVE_DISTANCES = (0.0, 40.0, 100.0, 200.0, math.inf)


def plot_p_s1(
    path: Path,
    params: SupervisorParams = SupervisorParams(),
    d_max_m: float = 300.0,
    t_max: int = 80,
) -> Path:
    """Heatmap of P(S_t = 1 | d_s = d for s ≤ t) over d ∈ [0, d_max_m] m, t ∈ [0, t_max], and
    curves over t for a few d with the bound ξ1/Σξ; written to ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = np.linspace(0.0, d_max_m, 121)
    t = np.arange(t_max + 1)
    table = p_s1_table(d, t_max, params)
    fig, (ax_map, ax_curves) = plt.subplots(1, 2, figsize=(12, 4.4))
    im = ax_map.imshow(
        table,
        origin="lower",
        aspect="auto",
        extent=(-0.5, t_max + 0.5, d[0], d[-1]),
        cmap="viridis",
        vmin=0.0,
        vmax=max(0.6, float(table.max())),
    )
    cs = ax_map.contour(t, d, table, levels=[0.1, 0.2, 0.3, 0.4, 0.5], colors="w", linewidths=0.7)
    ax_map.clabel(cs, fmt="%.1f", fontsize=7)
    fig.colorbar(im, ax=ax_map, label="P(S1 in control)")
    ax_map.set_xlabel("time-step t")
    ax_map.set_ylabel("distance to nearest fire d (m), same at every step")
    ax_map.set_title("(a) P(S_t = 1 | d_0 = … = d_t = d)")

    colors = plt.get_cmap("plasma")(np.linspace(0.0, 0.85, len(CURVE_DISTANCES)))
    for dv, col in zip(CURVE_DISTANCES, colors, strict=True):
        label = "no fire" if math.isinf(dv) else f"d = {dv:.0f} m"
        ax_curves.plot(t, p_s1_path(np.full(t_max + 1, dv), params), color=col, label=label)
    bound = [attention_marginal(int(s), 0.0, params)[0] for s in t]
    ax_curves.plot(t, bound, "k--", lw=1, label="ξ1/Σξ at d = 0 (the bound)")
    ax_curves.axvspan(17, 37, color="#1f77b4", alpha=0.1, label="Fig. r1: S1 in control")
    ax_curves.set_xlabel("time-step t")
    ax_curves.set_ylabel("P(S1 in control)")
    ax_curves.set_ylim(0.0, 1.0)
    ax_curves.set_xlim(0, t_max)
    ax_curves.set_title("(b) exact chain of Eq. (Psi) over t")
    ax_curves.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def _cli_bound(args: argparse.Namespace) -> int:
    print("P(S1 in control | d_s = 0 m for s <= t), exact chain of Eq. (Psi):")
    print("   t   P(S1)   xi1/sum(xi)")
    for t in TABLE_STEPS:
        print(f"{t:4d}  {p_s1(0.0, t):.4f}  {attention_marginal(t, 0.0)[0]:.4f}")
    print(
        f"\nbest CC success, fire on the UAV (d = 0) at every step, "
        f"h1 = {args.h1} and h2 = {args.h2} per step:"
    )
    print(f" steps  CC      S1 only  S2 only  E[S1 share]  S1 share for {args.target:.0%}")
    for steps in (int(s) for s in args.steps.split(",")):
        r = best_cc_success(args.h1, args.h2, steps, target=args.target)
        need = "unreachable" if math.isinf(r.share_needed) else f"{r.share_needed:.1%}"
        print(
            f" {steps:5d}  {r.cc_success:6.1%}  {r.s1_success:7.1%}  {r.s2_success:7.1%}"
            f"  {r.s1_share:11.1%}  {need}"
        )
    print(f"\nfigure: {plot_p_s1(Path(args.out))}")
    return 0


def add_bound_parser(subparsers: Any) -> None:
    """``dualpilot bound``: the table, the CC bound and the figure."""
    b = subparsers.add_parser("bound", help="exact P(S1 | d, t) of the supervisor; CC bound")
    b.add_argument("--h1", type=float, default=0.006, help="per-step hazard of S1")
    b.add_argument("--h2", type=float, default=0.05, help="per-step hazard of S2")
    b.add_argument("--steps", default="50,90", help="comma-separated mission lengths")
    b.add_argument("--target", type=float, default=0.9, help="CC success to reach")
    b.add_argument("--out", default="runs/bound/p_s1.png", help="figure path (PNG)")
    b.set_defaults(func=_cli_bound)
