"""The paper's per-mission figures: Fig. r1 (a)–(h), Fig. r2, Fig. r3 and Fig. 3.

``make_figures(run_dir)`` reads a run directory written by :mod:`dualpilot.mission.records`
(``summary.json``, ``steps.csv``, ``trace.json``) and writes PNGs next to them:

* ``fig_r1_trajectory.png`` – (a)–(f) executed trajectory (solid, coloured by the
  system that flew it), the plan at t (dotted), ``*`` the position at t, ``×`` the
  plan's final predicted position, fire regions and their hulls △(C^i_{1:t}), goal G;
* ``fig_r1_attention.png`` – (g) Ξ_t of Eq. (KSI) and (h) the attention A_t of
  Eq. (categorical), over bands showing the system that flew each step;
* ``fig_r2_dirichlet.png`` – 200 samples of P_t ~ Dirichlet(Ξ_t), Eq. (dir), on the simplex;
* ``fig_r3_psi.png`` – Ψ_t of Eq. (Psi) and S_t = argmax Ψ_t, Eq. (maxPsi);
* ``fig3_attention_profiles.png`` – Fig. 3: ξ1 against d and ξ2, ξ3 against t;
* ``fig_altitude.png`` – a 3-D mission's only: its side view and its ground track coloured
  by altitude (:mod:`dualpilot.viz.altitude`).

Figures are built on :class:`matplotlib.figure.Figure` with the Agg canvas: no
pyplot state, no display. Time is in steps (ΔT = 1 s), distances in metres.
"""

from __future__ import annotations

import json
import string
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib as mpl
import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Polygon, Rectangle
from matplotlib.ticker import MaxNLocator

from dualpilot.mission.records import read_steps_csv
from dualpilot.mission.result import Ending
from dualpilot.model.dynamics import Array
from dualpilot.supervisor.paper.attention import AttentionParams, xi
from dualpilot.viz.altitude import FIG_ALTITUDE, draw_altitude

DPI = 120
#: Seed of the Dirichlet samples of Fig. r2 (combined with t, so each panel is reproducible).
DIRICHLET_SEED = 2024
DIRICHLET_SAMPLES = 200

SYSTEM_COLORS = {0: "0.45", 1: "#1f5fbf", 2: "#d6278c"}
BAND_COLORS = {0: "0.85", 1: "#c6dbf5", 2: "#f9cfe5"}
SYSTEM_NAMES = {0: "braked (no plan)", 1: "System 1", 2: "System 2"}
ATTRIBUTES = ("response time", "mission time", "energy")
XI_COLORS = ("#d62728", "#2ca02c", "#8c564b")
FIRE_FACE, FIRE_EDGE = "#f05a28", "#a51d1d"
HULL_FACE, HULL_EDGE = "#ffc58a", "#f29a4a"
GOAL_FACE, GOAL_EDGE = "#9be29b", "#1f7a1f"

FIG_TRAJECTORY = "fig_r1_trajectory.png"
FIG_ATTENTION = "fig_r1_attention.png"
FIG_DIRICHLET = "fig_r2_dirichlet.png"
FIG_PSI = "fig_r3_psi.png"
FIG_PROFILES = "fig3_attention_profiles.png"

_TRIANGLE = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, np.sqrt(3.0) / 2.0]])


# -- reading a run ---------------------------------------------------------------------------
@dataclass(frozen=True)
class RunData:
    """One run directory in memory: steps.csv columns, trace.json, summary.json."""

    run_dir: Path
    columns: dict[str, np.ndarray]
    trace: dict[str, Any]
    summary: dict[str, Any]

    @property
    def n_steps(self) -> int:
        return len(self.trace["steps"])

    @property
    def t(self) -> Array:
        return np.asarray(self.columns["t"], dtype=float)

    @property
    def systems(self) -> list[int]:
        """System flown at each step: 1, 2, or 0 when no plan was flown (braked)."""
        return [int(s) for s in np.asarray(self.columns["system"], dtype=float)]

    @property
    def positions(self) -> Array:
        """Positions (m) before each step's control, shape (n_steps, 2)."""
        return _ground_track([s["position"] for s in self.trace["steps"]])

    @property
    def area_m(self) -> float:
        return float(self.trace.get("area_size_m", 1000.0))

    @property
    def ending(self) -> Ending | None:
        """How the mission ended (summary.json, else trace.json; either record form:
        :meth:`Ending.read`); None if it did not end."""
        said = self.summary if {"ending", "success"} & self.summary.keys() else self.trace
        return Ending.read(said) if {"ending", "success"} & said.keys() else None

    def title(self) -> str:
        info = {**self.trace, **self.summary}
        head = f"{str(info.get('controller', '?')).upper()} mission, seed {info.get('seed', '?')}"
        steps = int(info.get("steps", self.n_steps))  # steps flown (a caught last step is not)
        n = f"{steps} step{'s' if steps != 1 else ''}"
        ending = self.ending
        if ending is Ending.GOAL:
            return f"{head}: reached G after {n}"
        cause = ("not finished" if ending is None else ending.value).replace("_", " ")
        return f"{head}: {cause} after {n}"


def load_run(run_dir: Path) -> RunData:
    """Read ``steps.csv``, ``trace.json`` and (if present) ``summary.json`` of a run."""
    run_dir = Path(run_dir)
    steps_path, trace_path = run_dir / "steps.csv", run_dir / "trace.json"
    for p in (steps_path, trace_path):
        if not p.is_file():
            raise FileNotFoundError(f"{p} is missing: not a mission run directory")
    columns = read_steps_csv(steps_path)
    trace = json.loads(trace_path.read_text())
    summary_path = run_dir / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.is_file() else {}
    n = len(trace.get("steps", []))
    if n == 0:
        raise ValueError(f"{run_dir} holds a run with no steps")
    if len(columns["t"]) != n:
        raise ValueError(f"steps.csv has {len(columns['t'])} rows but trace.json {n} steps")
    return RunData(run_dir=run_dir, columns=columns, trace=trace, summary=summary)


# -- choosing steps ----------------------------------------------------------------------------
def switch_steps(systems: Sequence[int]) -> list[int]:
    """Indices where System 1 or 2 flies and the other one flew last (braked steps skipped)."""
    out, last = [], 0
    for k, s in enumerate(systems):
        if s in (1, 2):
            if last and s != last:
                out.append(k)
            last = s
    return out


def choose_panel_steps(systems: Sequence[int], n_panels: int = 6) -> list[int]:
    """Step indices for Fig. r1 (a)–(f): an early step, the last one, and system switches.

    Switches (the first step of the new system: the panel shows the old
    trajectory and the new system's plan) are taken farthest-first so the
    panels spread over the mission; remaining slots are filled evenly.
    """
    n = len(systems)
    if n <= n_panels:
        return list(range(n))
    last = n - 1
    chosen = [min(10, last // 5), last]
    min_gap = max(2, n // (2 * n_panels))

    def gap(k: int) -> int:
        return min(abs(k - c) for c in chosen)

    switches = switch_steps(systems)
    while len(chosen) < n_panels:
        pool = [k for k in switches if gap(k) >= min_gap]
        if not pool:
            break
        chosen.append(max(pool, key=gap))
    while len(chosen) < n_panels:  # fill evenly, not before the early step
        chosen.append(max((k for k in range(chosen[0], n) if k not in chosen), key=gap))
    return sorted(chosen)


def choose_dirichlet_steps(xi1: Sequence[float] | Array) -> list[int]:
    """Step indices for Fig. r2: t = 0, t = 10, the peak of ξ1 and the last step."""
    n = len(xi1)
    last = n - 1
    vals = np.asarray(xi1, dtype=float)
    peak = int(np.nanargmax(vals)) if np.any(np.isfinite(vals)) else last
    picks = sorted({0, min(10, last), peak, last})
    while len(picks) < min(4, n):  # short mission: spread the rest evenly
        free = [k for k in range(n) if k not in picks]
        picks = sorted([*picks, max(free, key=lambda k: min(abs(k - c) for c in picks))])
    return picks


# -- shared drawing helpers -----------------------------------------------------------------
@contextmanager
def _style() -> Iterator[None]:
    with mpl.rc_context():  # readable at the paper's column width
        mpl.rc("font", size=10)
        mpl.rc("axes", titlesize=11, labelsize=10)
        mpl.rc("legend", fontsize=9)
        mpl.rc("xtick", labelsize=9)
        mpl.rc("ytick", labelsize=9)
        mpl.rc("figure", titlesize=12)
        yield


def _new_figure(w: float, h: float) -> Figure:
    fig = Figure(figsize=(w, h), dpi=DPI, layout="constrained")
    fig.get_layout_engine().set(h_pad=0.08, w_pad=0.06)  # type: ignore[union-attr, call-arg]
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Figure, path: Path) -> Path:
    fig.savefig(path, dpi=DPI, facecolor="white")
    return path


def _runs(values: Sequence[int]) -> list[tuple[int, int, int]]:
    """Maximal runs of equal values as (value, first index, last index)."""
    out: list[tuple[int, int, int]] = []
    for k, v in enumerate(values):
        if out and out[-1][0] == v:
            out[-1] = (v, out[-1][1], k)
        else:
            out.append((int(v), k, k))
    return out


def _system_bands(ax: Axes, t: Array, systems: Sequence[int]) -> None:
    """Shade each step's slot [t − ½, t + ½] with the colour of the system in control."""
    for s, i, j in _runs(systems):
        ax.axvspan(t[i] - 0.5, t[j] + 0.5, color=BAND_COLORS.get(s, "0.9"), lw=0, zorder=0)


def _band_handles(systems: Sequence[int], what: str) -> list[Patch]:
    present = sorted({int(s) for s in systems}, key=lambda s: (s == 0, s))
    return [
        Patch(color=BAND_COLORS[s], label=f"{SYSTEM_NAMES[s]} {what}" if s else SYSTEM_NAMES[0])
        for s in present
        if s in BAND_COLORS
    ]


def _time_axis(ax: Axes, t: Array) -> None:
    ax.set_xlim(t[0] - 0.5, t[-1] + 0.5)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("time-step t (ΔT = 1 s)")


def _ground_track(rows: Any) -> Array:
    """Positions (n, 2) m of rows of 2 or 3 coordinates (a 3-D mission's altitude dropped)."""
    a = np.asarray(rows, dtype=float)
    return a[:, :2] if a.ndim == 2 else a.reshape(-1, 2)


def _plan_array(step: dict[str, Any]) -> Array:
    """The step's planned positions, (T+1, 2) m ((0, 2) when no plan was flown)."""
    return _ground_track(step.get("plan", []))


# -- Fig. r1 (a)-(f) ---------------------------------------------------------------------------
def _draw_trajectory_panel(ax: Axes, run: RunData, k: int, label: str) -> None:
    area = run.area_m
    step = run.trace["steps"][k]
    systems = run.systems
    pos = run.positions
    gx, gy, gw, gh = run.trace["goal"]
    ax.add_patch(Rectangle((gx - gw / 2, gy - gh / 2), gw, gh, fc=GOAL_FACE, ec=GOAL_EDGE,
                           lw=1.2, alpha=0.8, zorder=1))
    # outline and label again above the fires, so G stays visible under a fire
    ax.add_patch(Rectangle((gx - gw / 2, gy - gh / 2), gw, gh, fc="none", ec=GOAL_EDGE,
                           lw=1.2, zorder=4))
    ax.text(gx, gy, "G", ha="center", va="center", fontsize=11, fontweight="bold",
            color=GOAL_EDGE, zorder=4)
    for hull in step.get("hulls", []):
        verts = np.asarray(hull, dtype=float).reshape(-1, 2)
        if len(verts) >= 3:
            ax.add_patch(Polygon(verts, closed=True, fc=HULL_FACE, ec=HULL_EDGE, alpha=0.45,
                                 lw=1.0, ls="--", zorder=2))
    for cx, cy, w, h in step.get("regions", []):
        ax.add_patch(Rectangle((cx - w / 2, cy - h / 2), w, h, fc=FIRE_FACE, ec=FIRE_EDGE,
                               alpha=0.7, lw=1.0, zorder=3))
    start = np.asarray(run.trace.get("start", pos[0]), dtype=float)
    ax.plot(*start, "o", color="k", ms=5, zorder=5)
    # segment j (pos[j] -> pos[j+1]) was flown with the system of step j
    for s, i, j in _runs(systems[:k]):
        seg = pos[i : j + 2]
        ax.plot(seg[:, 0], seg[:, 1], "-", color=SYSTEM_COLORS.get(s, "k"), lw=2.2, zorder=6,
                solid_capstyle="round")
    s_now = int(systems[k])
    color = SYSTEM_COLORS.get(s_now, "k")
    plan = _plan_array(step)
    if len(plan):
        ax.plot(plan[:, 0], plan[:, 1], ":", color=color, lw=2.0, zorder=7)
        ax.plot(*plan[-1], "x", color=color, ms=9, mew=2.2, zorder=8)
    ax.plot(*pos[k], "*", color=color, mec="k", mew=0.6, ms=15, zorder=9)
    ax.set_xlim(0, area)
    ax.set_ylim(0, area)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    t = int(run.t[k])
    who = {1: "S1", 2: "S2"}.get(s_now, "braked")
    ax.set_title(f"({label}) t = {t}  [{who}]")


def _trajectory_legend(systems: Sequence[int]) -> list[Any]:
    handles: list[Any] = [
        Line2D([], [], color=SYSTEM_COLORS[1], lw=2.2, label="executed, System 1"),
        Line2D([], [], color=SYSTEM_COLORS[2], lw=2.2, label="executed, System 2"),
        Line2D([], [], color="0.2", lw=2.0, ls=":", label="plan at t (system's colour)"),
        Line2D([], [], color="0.2", marker="*", ls="", ms=13, label="position at t"),
        Line2D([], [], color="0.2", marker="x", ls="", ms=9, mew=2,
               label="final predicted position"),
        Patch(fc=FIRE_FACE, ec=FIRE_EDGE, alpha=0.7, label="active fire region"),
        Patch(fc=HULL_FACE, ec=HULL_EDGE, alpha=0.45, ls="--",
              label=r"fire path hull $\triangle(C^i_{1:t})$"),
        Patch(fc=GOAL_FACE, ec=GOAL_EDGE, alpha=0.8, label="goal region G"),
        Line2D([], [], color="k", marker="o", ls="", ms=5, label="start"),
    ]
    if 0 in set(int(s) for s in systems):
        handles.insert(2, Line2D([], [], color=SYSTEM_COLORS[0], lw=2.2, label="braked (no plan)"))
    return handles


def figure_trajectory(run: RunData, steps: Sequence[int] | None = None) -> Figure:
    """Fig. r1 (a)–(f): trajectory panels at step indices ``steps`` (default: chosen)."""
    picks = list(steps) if steps is not None else choose_panel_steps(run.systems)
    if not picks:
        raise ValueError("need at least one step for the trajectory panels")
    for k in picks:
        if not 0 <= int(k) < run.n_steps:
            raise ValueError(f"step {k} is outside the run's 0..{run.n_steps - 1}")
    n = len(picks)
    ncols = n if n <= 3 else 2 if n == 4 else 3
    nrows = -(-n // ncols)
    wide = ncols == 3  # legend below a full row of panels, else on the right
    fig = _new_figure(4.0 * ncols + (0.0 if wide else 3.2), 3.9 * nrows + (1.1 if wide else 0.6))
    axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
    labels = string.ascii_lowercase
    for i, (ax, k) in enumerate(zip(axes, picks, strict=False)):
        _draw_trajectory_panel(ax, run, int(k), labels[i % 26])
    for ax in axes[n:]:
        ax.set_axis_off()
    fig.suptitle(run.title())
    fig.legend(handles=_trajectory_legend(run.systems),
               loc="outside lower center" if wide else "outside right center",
               ncol=5 if wide else 1, frameon=False)
    return fig


# -- Fig. r1 (g)-(h) ---------------------------------------------------------------------------
def figure_attention(run: RunData) -> Figure:
    """Fig. r1 (g) Ξ_t over time, (h) the attention A_t, on bands of the system flown."""
    t, systems = run.t, run.systems
    fig = _new_figure(10.0, 6.0)
    ax_g, ax_h = fig.subplots(2, 1, sharex=True, height_ratios=[1.6, 1.0])
    _system_bands(ax_g, t, systems)
    marker = "o" if len(t) <= 20 else None
    for a in range(3):
        ax_g.plot(t, run.columns[f"xi{a + 1}"], color=XI_COLORS[a], lw=2.0, marker=marker, ms=4,
                  label=rf"$\xi_{a + 1}$: {ATTRIBUTES[a]}", zorder=3)
    ax_g.set_ylabel(r"attention parameter $\xi_a(t)$")
    ax_g.set_title(r"(g) attention parameters $\Xi_t$, Eq. (KSI)")
    handles, _ = ax_g.get_legend_handles_labels()
    d = np.asarray(run.columns["d_t"], dtype=float)
    finite = np.isfinite(d)
    if np.any(finite):
        ax_d = ax_g.twinx()
        ax_d.plot(t[finite], d[finite], ".", color="0.35", ms=4, zorder=2)
        ax_d.set_ylabel(r"$d_t$: distance to fire (m)", color="0.35")
        ax_d.tick_params(axis="y", colors="0.35")
        ax_d.set_ylim(0, max(float(np.max(d[finite])) * 1.05, 100.0))
        handles.append(Line2D([], [], color="0.35", marker=".", ls="", ms=6,
                              label=r"$d_t$ (right axis; no dot: no fire)"))
    else:
        handles.append(Line2D([], [], ls="", label=r"no fire in this run: $d_t = \infty$"))
    handles.extend(_band_handles(systems, "flew"))
    fig.legend(handles=handles, loc="outside right center", frameon=False)

    _system_bands(ax_h, t, systems)
    att = np.asarray(run.columns["attention"], dtype=float)
    for a in range(3):
        sel = att == a + 1
        ax_h.plot(t[sel], np.full(int(sel.sum()), a + 1), "|", color=XI_COLORS[a], ms=14, mew=2.5)
    ax_h.set_yticks([1, 2, 3], [f"{i + 1}: {name}" for i, name in enumerate(ATTRIBUTES)])
    ax_h.set_ylim(0.4, 3.6)
    ax_h.set_ylabel("attended attribute")
    ax_h.set_title(r"(h) attention activation $A_t$, Eq. (categorical)")
    _time_axis(ax_h, t)
    fig.suptitle(run.title())
    return fig


# -- Fig. r2 -----------------------------------------------------------------------------------
def to_simplex_xy(p: Array) -> Array:
    """Barycentric (p1, p2, p3) → the plane: p1 at (0, 0), p2 at (1, 0), p3 at the top."""
    p = np.asarray(p, dtype=float).reshape(-1, 3)
    return np.asarray((p / p.sum(axis=1, keepdims=True)) @ _TRIANGLE)


def dirichlet_samples(xi_t: Array, t: int, n: int = DIRICHLET_SAMPLES) -> Array:
    """``n`` draws of P_t ~ Dirichlet(Ξ_t), Eq. (dir), from a generator seeded by (seed, t)."""
    rng = np.random.default_rng([DIRICHLET_SEED, int(t)])
    return np.asarray(rng.dirichlet(np.asarray(xi_t, dtype=float), size=n))


def _draw_simplex(ax: Axes) -> None:
    tri = np.vstack([_TRIANGLE, _TRIANGLE[:1]])
    for level in (0.2, 0.4, 0.6, 0.8):  # lines p_i = level
        for i in range(3):
            j, k = (i + 1) % 3, (i + 2) % 3
            a = level * _TRIANGLE[i] + (1 - level) * _TRIANGLE[j]
            b = level * _TRIANGLE[i] + (1 - level) * _TRIANGLE[k]
            ax.plot([a[0], b[0]], [a[1], b[1]], color="0.88", lw=0.7, zorder=0)
    ax.plot(tri[:, 0], tri[:, 1], color="0.3", lw=1.2, zorder=1)
    offsets = [(-0.02, -0.05, "right", "top"), (1.02, -0.05, "left", "top"),
               (0.5, np.sqrt(3) / 2 + 0.04, "center", "bottom")]
    for i, (x, y, ha, va) in enumerate(offsets):
        ax.text(x, y, f"p{i + 1}\n{ATTRIBUTES[i]}" if i < 2 else f"p3: {ATTRIBUTES[2]}",
                ha=ha if i == 2 else "center", va=va, fontsize=9, color=XI_COLORS[i])
    ax.set_xlim(-0.12, 1.12)
    ax.set_ylim(-0.2, np.sqrt(3) / 2 + 0.14)
    ax.set_aspect("equal")
    ax.set_axis_off()


def figure_dirichlet(run: RunData, steps: Sequence[int] | None = None) -> Figure:
    """Fig. r2: 200 samples of P_t ~ Dirichlet(Ξ_t) on the 2-simplex at a few steps."""
    xis = np.column_stack([np.asarray(run.columns[f"xi{a}"], dtype=float) for a in (1, 2, 3)])
    picks = list(steps) if steps is not None else choose_dirichlet_steps(xis[:, 0])
    n = len(picks)
    fig = _new_figure(max(3.3 * n + 0.4, 6.0), 4.1 if n >= 3 else 4.6)
    axes = np.atleast_1d(fig.subplots(1, n, squeeze=False).ravel())
    for ax, k in zip(axes, picks, strict=True):
        _draw_simplex(ax)
        t = int(run.t[k])
        xi_t = xis[k]
        if np.all(np.isfinite(xi_t)) and np.all(xi_t > 0):
            xy = to_simplex_xy(dirichlet_samples(xi_t, t))
            ax.scatter(xy[:, 0], xy[:, 1], s=9, color="#4a4a9c", alpha=0.55, lw=0, zorder=2)
            mean = to_simplex_xy(xi_t)[0]
            ax.plot(*mean, "P", color="k", ms=9, mec="w", zorder=4)
            title = rf"t = {t}:  $\Xi_t$ = ({xi_t[0]:.1f}, {xi_t[1]:.1f}, {xi_t[2]:.1f})"
        else:
            title = rf"t = {t}:  $\Xi_t$ unavailable"
        p_t = np.array([run.columns[f"p{a}"][k] for a in (1, 2, 3)], dtype=float)
        if np.all(np.isfinite(p_t)) and p_t.sum() > 0:
            ax.plot(*to_simplex_xy(p_t)[0], "*", color="#e08a00", mec="k", mew=0.6, ms=14, zorder=5)
        ax.set_title(title)
    handles = [
        Line2D([], [], color="#4a4a9c", marker="o", ls="", ms=4, alpha=0.6,
               label=rf"{DIRICHLET_SAMPLES} samples of $P_t \sim \mathrm{{Dir}}(\Xi_t)$"),
        Line2D([], [], color="k", marker="P", ls="", ms=9, mec="w",
               label=r"mean $\Xi_t\,/\,(\xi_1 + \xi_2 + \xi_3)$"),
        Line2D([], [], color="#e08a00", marker="*", ls="", ms=12, mec="k",
               label=r"$P_t$ drawn in the mission"),
    ]
    fig.legend(handles=handles, loc="outside lower center", ncol=3 if n >= 3 else 1, frameon=False)
    fig.suptitle(r"Attention probabilities $P_t = (p_1, p_2, p_3)$, Eq. (dir)")
    return fig


# -- Fig. r3 -----------------------------------------------------------------------------------
def figure_psi(run: RunData) -> Figure:
    """Fig. r3: Ψ_t(1), Ψ_t(2) with bands of S_t = argmax Ψ_t (ties → System 1)."""
    t = run.t
    psi = np.column_stack([np.asarray(run.columns[f"psi{i}"], dtype=float) for i in (1, 2)])
    chosen = np.where(psi[:, 1] > psi[:, 0], 2, 1)
    fig = _new_figure(10.0, 4.2)
    ax = fig.subplots()
    _system_bands(ax, t, [int(c) for c in chosen])
    ax.axhline(0.0, color="0.5", lw=0.8, zorder=1)
    for i in range(2):
        ax.plot(t, psi[:, i], "-", marker="o", ms=3.5, lw=1.8, color=SYSTEM_COLORS[i + 1],
                label=rf"$\Psi_t({i + 1})$: System {i + 1}", zorder=3)
    handles, _ = ax.get_legend_handles_labels()
    selected = r"selected: $S_t = \arg\max_i \Psi_t(i)$"
    handles.extend(_band_handles([int(c) for c in chosen], selected))
    flown = np.asarray(run.systems)
    top = float(np.nanmax(np.abs(psi))) if np.any(np.isfinite(psi)) else 1.0
    top = max(top, 0.1)
    other = (flown != 0) & (flown != chosen)
    if np.any(other):
        ax.plot(t[other], np.full(int(other.sum()), 1.12 * top), "v", color="k", ms=6, zorder=4)
        handles.append(Line2D([], [], color="k", marker="v", ls="",
                              label="fallback: other system flew"))
    braked = flown == 0
    if np.any(braked):
        ax.plot(t[braked], np.full(int(braked.sum()), 1.12 * top), "s", color=SYSTEM_COLORS[0],
                ms=5, zorder=4)
        handles.append(Line2D([], [], color=SYSTEM_COLORS[0], marker="s", ls="",
                              label="braked (no plan)"))
    ax.set_ylim(-1.25 * top, 1.25 * top)
    ax.set_ylabel(r"decision score $\Psi_t(i)$")
    ax.set_title(r"Decision dynamics $\Psi_t = H\Psi_{t-1} + BQA_t$, Eq. (Psi)")
    _time_axis(ax, t)
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    return fig


# -- Fig. 3 ------------------------------------------------------------------------------------
def attention_profiles(
    params: AttentionParams = AttentionParams(),
    d_max_m: float = 400.0,
    t_max: float = 80.0,
    n: int = 401,
) -> dict[str, Array]:
    """Eq. (KSI) curves of Fig. 3: ξ1 over d ∈ [0, d_max] m, ξ2, ξ3 over t ∈ [0, t_max] steps."""
    d = np.linspace(0.0, d_max_m, n)
    t = np.linspace(0.0, t_max, n)
    xi1 = np.array([xi(0.0, float(v), params)[0] for v in d])
    xi23 = np.array([xi(float(v), float("inf"), params)[1:] for v in t])
    return {"d": d, "xi1": xi1, "t": t, "xi2": xi23[:, 0], "xi3": xi23[:, 1]}


def figure_attention_profiles(params: AttentionParams = AttentionParams()) -> Figure:
    """Fig. 3: ξ1 against the distance d_t (m), ξ2 and ξ3 against the time-step t."""
    prof = attention_profiles(params)
    fig = _new_figure(10.0, 3.9)
    ax_d, ax_t = fig.subplots(1, 2)
    r, m, e = params.response, params.mission_time, params.energy
    ax_d.plot(prof["d"], prof["xi1"], color=XI_COLORS[0], lw=2.2, label=r"$\xi_1$: response time")
    ax_d.set_xlabel(r"distance to the new fire $d_t$ (m)")
    ax_d.set_ylabel("attention parameter")
    ax_d.set_title(rf"(a) $\xi_1(d_t)$, $w_1$ = ({r.a:g}, {r.b:g}, {r.c:g}, {r.d:g})")
    ax_d.set_xlim(prof["d"][0], prof["d"][-1])
    ax_t.plot(prof["t"], prof["xi2"], color=XI_COLORS[1], lw=2.2, label=r"$\xi_2$: mission time")
    ax_t.plot(prof["t"], prof["xi3"], color=XI_COLORS[2], lw=2.2, label=r"$\xi_3$: energy")
    ax_t.set_xlabel("time-step t (ΔT = 1 s)")
    ax_t.set_ylabel("attention parameter")
    ax_t.set_title(rf"(b) $\xi_2(t)$, $\xi_3(t)$, $w_2$ = ({m.a:g}, {m.b:g}, {m.c:g}, {m.d:g}), "
                   rf"$w_3$ = ({e.a:g}, {e.b:g}, {e.c:g}, {e.d:g})")
    ax_t.set_xlim(prof["t"][0], prof["t"][-1])
    top = max(float(np.max(prof[k])) for k in ("xi1", "xi2", "xi3"))
    for ax, loc in ((ax_d, "upper right"), (ax_t, "lower right")):  # corners the curves leave free
        ax.set_ylim(0.0, top * 1.08)
        ax.grid(True, color="0.9")
        ax.legend(loc=loc, frameon=True)
    return fig


def plot_attention_profiles(path: Path, params: AttentionParams = AttentionParams()) -> Path:
    """Write Fig. 3 (a pure function of the attention parameters) to ``path``."""
    with _style():
        return _save(figure_attention_profiles(params), Path(path))


# -- a 3-D mission's altitude ------------------------------------------------------------------
def figure_altitude(run: RunData) -> Figure:
    """A 3-D mission's side view and altitude-coloured ground track (ValueError in 2-D)."""
    fig = _new_figure(13.0, 5.4)
    draw_altitude(fig, run.trace)
    fig.suptitle(run.title())
    return fig


# -- all figures of a run ------------------------------------------------------------------------
def make_figures(run_dir: Path, steps: Sequence[int] | None = None) -> list[Path]:
    """Write the five PNGs of a mission run into ``run_dir`` (a 3-D mission's six: its
    altitude too); returns their paths.

    ``steps`` overrides the step indices of the trajectory panels of Fig. r1.
    """
    run = load_run(Path(run_dir))
    out = run.run_dir
    with _style():
        paths = [
            _save(figure_trajectory(run, steps), out / FIG_TRAJECTORY),
            _save(figure_attention(run), out / FIG_ATTENTION),
            _save(figure_dirichlet(run), out / FIG_DIRICHLET),
            _save(figure_psi(run), out / FIG_PSI),
        ]
        if "altitude" in run.trace:
            paths.append(_save(figure_altitude(run), out / FIG_ALTITUDE))
    paths.append(plot_attention_profiles(out / FIG_PROFILES))
    return paths
