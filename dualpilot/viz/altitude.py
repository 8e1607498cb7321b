"""A 3-D mission's altitude: its side view and its ground track coloured by altitude.

``fig_altitude.png`` (drawn by :func:`dualpilot.viz.mission.make_figures` for a run whose
trace.json carries ``altitude``, i.e. a 3-D mission, docs/three_d.md) has two panels:

* (a) top-down: the flown ground track coloured by the altitude flown (colour bar, m), the
  front of (b) at the first step of each passage over or near fronts, with its top, the
  start and G;
* (b) side view: altitude (m) against the time-step t (ΔT = 1 s): the band's floor and
  ceiling, the flown altitude p_z at each step (and at the end), each flown plan's altitudes
  z^p_{t..t+T|t} in the colour of the system that made it, and the top of the tallest front
  whose region lies within ``near_m`` of the UAV's ground position at t (the fronts its
  ground track passes over or near).

Everything here reads the plain trace.json document (no :class:`RunData`), so the module
does not depend on :mod:`dualpilot.viz.mission`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Rectangle

from dualpilot.model.dynamics import Array

FIG_ALTITUDE = "fig_altitude.png"
#: the fronts counted under the UAV: those whose region is within this planar distance (m) of
#: its ground position, the paper's d_safe ("a predefined safety threshold (denoted as
#: d_safe = 20 m)")
NEAR_M = 20.0
ALTITUDE_CMAP = "viridis"
PLAN_COLORS = {1: "#1f5fbf", 2: "#d6278c"}
FIRE_FACE, FIRE_EDGE = "#f05a28", "#a51d1d"
GOAL_FACE, GOAL_EDGE = "#9be29b", "#1f7a1f"
BAND_COLOR = "0.35"


@dataclass(frozen=True)
class SideView:
    """What the side view draws (m, time in steps).

    ``t``/``flown_m``: the flown altitude at each step's start, then at the end (the final
    position, one step after the last); ``plans``: for each step that flew a plan, its system
    and the plan's times t..t+T and altitudes; ``fire_top_m``: at each step, the top of the
    tallest front within ``near_m`` of the ground position (NaN: none near, or no tops) and
    ``fire_region`` its region [cx, cy, w, h] ([] for none).
    """

    t: Array
    flown_m: Array
    plans: tuple[tuple[int, Array, Array], ...]
    step_t: Array
    fire_top_m: Array
    fire_region: tuple[list[float], ...]
    floor_m: float
    ceiling_m: float


def rect_distance(px: float, py: float, region: Any) -> float:
    """Planar distance (m) from (px, py) to the rectangle [cx, cy, w, h] (0 inside it)."""
    cx, cy, w, h = (float(v) for v in region)
    return math.hypot(max(abs(px - cx) - w / 2.0, 0.0), max(abs(py - cy) - h / 2.0, 0.0))


def front_near(step: dict[str, Any], near_m: float = NEAR_M) -> tuple[float, list[float]]:
    """The top (m) and region [cx, cy, w, h] of the tallest of ``step``'s fronts within
    ``near_m`` of its ground position ((NaN, []) when none is, or the step has no tops)."""
    px, py = (float(v) for v in step["position"][:2])
    near = [(float(top), [float(v) for v in region])
            for region, top in zip(step.get("regions", []), step.get("tops", []), strict=False)
            if rect_distance(px, py, region) <= near_m]
    return max(near, key=lambda n: n[0]) if near else (math.nan, [])


def side_view(trace: dict[str, Any], near_m: float = NEAR_M) -> SideView:
    """The side view's data of a 3-D trace.json document (ValueError for a 2-D one)."""
    band = trace.get("altitude")
    if band is None:
        raise ValueError("a 2-D run has no altitude: trace.json has no 'altitude'")
    steps = trace["steps"]
    step_t = np.array([float(s["t"]) for s in steps])
    flown = [float(s["position"][2]) for s in steps]
    t = list(step_t)
    final = trace.get("final_position", [])
    if len(final) == 3 and math.isfinite(float(final[2])):
        t.append(step_t[-1] + 1.0)
        flown.append(float(final[2]))
    plans = []
    for s, ts in zip(steps, step_t, strict=True):
        plan = np.asarray(s.get("plan", []), dtype=float).reshape(-1, 3)
        if int(s["system"]) and len(plan):
            plans.append((int(s["system"]), ts + np.arange(len(plan), dtype=float), plan[:, 2]))
    near = [front_near(s, near_m) for s in steps]
    return SideView(np.array(t), np.array(flown), tuple(plans), step_t,
                    np.array([top for top, _ in near]), tuple(region for _, region in near),
                    float(band["floor_m"]), float(band["ceiling_m"]))


def _draw_side(ax: Axes, sv: SideView) -> list[Any]:
    """Panel (b); returns its legend's handles."""
    seen = np.isfinite(sv.fire_top_m)
    if np.any(seen):  # one bar a step, as tall as the front
        ax.bar(sv.step_t[seen], sv.fire_top_m[seen], width=1.0, color=FIRE_FACE,
               edgecolor=FIRE_EDGE, alpha=0.6, lw=0.8, zorder=1)
    for system, ts, zs in sv.plans:
        ax.plot(ts, zs, ":", color=PLAN_COLORS.get(system, "0.3"), lw=1.0, alpha=0.55, zorder=2)
    ax.plot(sv.t, sv.flown_m, "-", color="k", lw=2.0, marker="." if len(sv.t) <= 30 else None,
            zorder=4)
    for z, name in ((sv.floor_m, "floor"), (sv.ceiling_m, "ceiling")):
        ax.axhline(z, color=BAND_COLOR, ls="--", lw=1.2, zorder=3)
        ax.text(1.0, z, f" {name} {z:g} m", transform=ax.get_yaxis_transform(), va="center",
                ha="left", fontsize=8, color=BAND_COLOR, clip_on=False)
    ax.set_xlim(sv.t[0] - 0.5, sv.t[-1] + 0.5)
    tallest = float(np.max(sv.fire_top_m[seen])) if np.any(seen) else 0.0
    ax.set_ylim(0.0, max(sv.ceiling_m, tallest) * 1.08)  # a front above the band: all of it
    ax.set_xlabel("time-step t (ΔT = 1 s)")
    ax.set_ylabel("altitude (m)")
    ax.set_title("(b) side view: altitude against time")
    return [Line2D([], [], color="k", lw=2.0, label="flown altitude"),
            Line2D([], [], color=PLAN_COLORS[1], ls=":", lw=1.2, label="planned, System 1"),
            Line2D([], [], color=PLAN_COLORS[2], ls=":", lw=1.2, label="planned, System 2"),
            Line2D([], [], color=BAND_COLOR, ls="--", lw=1.2, label="band's floor, ceiling"),
            Patch(fc=FIRE_FACE, ec=FIRE_EDGE, alpha=0.55,
                  label=f"top of the tallest front within {NEAR_M:g} m of the track")]


def _draw_top_down(fig: Figure, ax: Axes, trace: dict[str, Any], sv: SideView) -> None:
    """Panel (a): the ground track coloured by altitude, with its colour bar."""
    area = float(trace.get("area_size_m", 1000.0))
    gx, gy, gw, gh = trace["goal"]
    ax.add_patch(Rectangle((gx - gw / 2, gy - gh / 2), gw, gh, fc=GOAL_FACE, ec=GOAL_EDGE,
                           lw=1.2, alpha=0.8, zorder=1))
    for k, region in enumerate(sv.fire_region):  # each passage over fronts: its first step's
        if not region or (k > 0 and sv.fire_region[k - 1]):
            continue
        cx, cy, w, h = region
        ax.add_patch(Rectangle((cx - w / 2, cy - h / 2), w, h, fc=FIRE_FACE, ec=FIRE_EDGE,
                               alpha=0.35, lw=0.8, zorder=2))
        ax.text(cx + w / 2, cy + h / 2, f" t={sv.step_t[k]:g}: {sv.fire_top_m[k]:.0f} m",
                ha="left", va="bottom", fontsize=8, color=FIRE_EDGE, zorder=3)
    xy = [s["position"][:2] for s in trace["steps"]]
    if len(sv.t) > len(xy):
        xy.append(trace["final_position"][:2])
    pts = np.asarray(xy, dtype=float)
    norm = Normalize(float(np.min(sv.flown_m)), max(float(np.max(sv.flown_m)),
                                                   float(np.min(sv.flown_m)) + 1.0))
    track = LineCollection(list(np.stack([pts[:-1], pts[1:]], axis=1)), cmap=ALTITUDE_CMAP,
                           norm=norm, lw=3.0, zorder=5, capstyle="round")
    track.set_array(0.5 * (sv.flown_m[:-1] + sv.flown_m[1:]))  # each segment: its mean altitude
    ax.add_collection(track)
    over = np.isfinite(sv.fire_top_m)  # the steps of (b)'s bars, as a halo under the track
    ax.plot(pts[: len(over)][over, 0], pts[: len(over)][over, 1], "o", color=FIRE_FACE, ms=9,
            alpha=0.6, ls="", zorder=4, label=f"over or within {NEAR_M:g} m of a front (b)")
    ax.plot(*pts[0], "o", color="k", ms=5, zorder=6)
    if np.any(over):
        ax.legend(loc="lower right", fontsize=8, framealpha=0.9)
    fig.colorbar(track, ax=ax, label="flown altitude (m)", shrink=0.85)
    ax.set_xlim(0, area)
    ax.set_ylim(0, area)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"(a) ground track, coloured by altitude;\nthe front within {NEAR_M:g} m of it "
                 "as each passage began (t: its top)")


def draw_altitude(fig: Figure, trace: dict[str, Any]) -> None:
    """Both panels of ``fig_altitude.png`` of a 3-D trace.json document into ``fig``."""
    sv = side_view(trace)
    ax_top, ax_side = fig.subplots(1, 2, width_ratios=[1.0, 1.5])
    _draw_top_down(fig, ax_top, trace, sv)
    handles = _draw_side(ax_side, sv)
    ax_side.legend(handles=handles, loc="upper left", fontsize=8, framealpha=0.9)
