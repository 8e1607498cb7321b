"""What the live view and mission.mcap show of a mission, as plain data.

One step's scene: the area (its boundary, the start, the goal G), the fire
regions and their hulls △(C^i_{1:t}), both systems' plans (the flown plan's
positions x^p_{t..t+T|t}, every asked system's status), the UAV with its
d_safe disc, the flown path, the supervisor's decision (Ξ_t, P_t, A_t, Ψ_t,
S_t), the occupancy forecast and the risk zones the flown plan was made
against. Everything is in the mission's frame: metres east (x) and north (y)
of the area's south-west corner.
:mod:`dualpilot.viz.foxglove` turns these into Foxglove messages; nothing
here knows about Foxglove.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dualpilot.mission.answers import Answer, PlanView, statuses_by_system
from dualpilot.model.altitude import planar_state
from dualpilot.model.dynamics import Array
from dualpilot.model.fire import FireSnapshot
from dualpilot.model.forecast import OccupancyForecast
from dualpilot.model.geometry import Rect
from dualpilot.model.risk import RiskNote
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.paper.decision import Decision

SYSTEMS = (1, 2)
#: the occupancy forecast's slices shown (evenly spread over its horizons, the first and last
#: included): each is one byte a cell of the live view's grid
MAX_FORECAST_SLICES = 5


def rect_outline(r: Rect) -> Array:
    """A rectangle's corners (m), counter-clockwise from the south-west one, shape (4, 2)."""
    return r.corners()


def circle(center: Array, radius_m: float, n: int = 32) -> Array:
    """``n`` points (m) on the circle of ``radius_m`` around ``center``, from due east, CCW."""
    a = 2.0 * math.pi * np.arange(n) / n
    c = np.asarray(center, dtype=float)[:2]
    return np.column_stack([c[0] + radius_m * np.cos(a), c[1] + radius_m * np.sin(a)])


@dataclass(frozen=True)
class AreaView:
    """The mission's area [0, A]², its start and its goal region G (m)."""

    size_m: float
    start: Array  # (2,)
    goal: Array  # (4, 2) corners


def area_view(spec: MissionSpec) -> AreaView:
    return AreaView(float(spec.area_size_m), np.asarray(spec.start, dtype=float),
                    rect_outline(spec.goal))


@dataclass(frozen=True)
class FireView:
    """The active fronts' regions (corners) with their ids and birth steps, and every hull."""

    regions: tuple[Array, ...]  # each (4, 2)
    front_ids: tuple[int, ...]
    born_steps: tuple[int, ...]
    hulls: tuple[Array, ...]  # each (k, 2), counter-clockwise


def fire_view(s: FireSnapshot) -> FireView:
    n = len(s.regions)
    return FireView(
        regions=tuple(rect_outline(r) for r in s.regions),
        front_ids=tuple(s.front_ids) if len(s.front_ids) == n else tuple(range(n)),
        born_steps=tuple(s.born_steps) if len(s.born_steps) == n else (0,) * n,
        hulls=tuple(np.asarray(h.vertices, dtype=float) for h in s.hulls))


def plan_views(answers: tuple[Answer, ...], flown: int, positions: Array
               ) -> tuple[PlanView, ...]:
    """Both systems' :class:`PlanView` at a step (``flown``: the system flown, 0 none)."""
    statuses = statuses_by_system(answers)
    pts = np.asarray(positions, dtype=float)
    pts = pts[:, :2] if pts.ndim == 2 else pts.reshape(-1, 2)  # the ground track in 3-D
    empty = np.empty((0, 2))
    return tuple(PlanView(k, statuses.get(k, ""), pts if k == flown else empty, k == flown)
                 for k in SYSTEMS)


def top_down(state: Array) -> tuple[Array, float | None, float | None]:
    """A 2-D or 3-D state as the scene shows it: [east, north, v_east, v_north] (m, m/s), the
    altitude p_z (m) and the climb v_z (m/s); both None for a 2-D state."""
    x = np.asarray(state, dtype=float).reshape(-1)
    if len(x) == 6:
        return planar_state(x), float(x[2]), float(x[5])
    return x, None, None


def altitude_text(z_m: float | None) -> str:
    """The altitude beside a vehicle's label: `` z=65.4 m`` (m, one decimal); none in 2-D."""
    return "" if z_m is None else f" z={z_m:.1f} m"


def _finite_or_none(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def decision_doc(d: Decision, commanded: int, flown: int, time_s: float) -> dict[str, object]:
    """The decision of one step as a JSON object (d_t: null when no region counts).

    ``system`` is S_t = argmax Ψ_t, ``commanded_system`` the system asked first
    (forced by the s1/s2 controllers), ``flown_system`` the one whose plan was
    flown (0: none, the UAV braked); attention and systems 1-based as in the paper.
    """
    return {
        "t": int(d.t), "time_s": float(time_s), "d_t_m": _finite_or_none(float(d.d_t)),
        "xi": [float(v) for v in d.xi], "p": [float(v) for v in d.p],
        "attention": int(d.attention), "psi": [float(v) for v in d.psi],
        "system": int(d.system), "commanded_system": int(commanded), "flown_system": int(flown),
        "objective": d.objective.value,
    }


def commanded_system(controller: str, d: Decision) -> int:
    """The system a controller asks first at a step: S_t for cc, forced for s1 / s2."""
    return {"s1": 1, "s2": 2}.get(controller, int(d.system))


@dataclass(frozen=True)
class OccupancyView:
    """A few slices of the occupancy forecast, interleaved: one byte a slice a cell.

    Cell (row r, col c) is the square of side ``resolution_m`` whose south-west
    corner is ``origin_m`` + (c, r)·resolution_m; ``data`` runs row by row from
    the south-west cell, each cell's bytes in the order of ``horizons_s``;
    P = byte / 255 (dualpilot/model/forecast.py).
    """

    origin_m: tuple[float, float]
    resolution_m: float
    rows: int
    cols: int
    horizons_s: tuple[float, ...]
    data: bytes


def forecast_slices(n: int, most: int = MAX_FORECAST_SLICES) -> list[int]:
    """Indices of at most ``most`` of ``n`` slices, evenly spread, the first and last kept."""
    if n <= 0:
        return []
    return sorted({int(round(v)) for v in np.linspace(0, n - 1, min(n, most))})


def occupancy_view(fc: OccupancyForecast, most: int = MAX_FORECAST_SLICES) -> OccupancyView:
    idx = forecast_slices(len(fc.horizons), most)
    cells = np.ascontiguousarray(np.moveaxis(fc.levels[idx], 0, -1))  # (rows, cols, slices)
    rows, cols = fc.shape
    return OccupancyView(
        origin_m=(float(fc.origin_m[0]), float(fc.origin_m[1])),
        resolution_m=float(fc.resolution_m), rows=int(rows), cols=int(cols),
        horizons_s=tuple(float(fc.horizons[i] * fc.substep_s) for i in idx),
        data=cells.tobytes())


@dataclass(frozen=True)
class RiskView:
    """The risk zones a flown plan was made against (each (k, 2) vertices, m) at α."""

    zones: tuple[Array, ...]
    alpha: float


def risk_view(note: RiskNote | None) -> RiskView:
    """A record's :class:`~dualpilot.model.risk.RiskNote` as a view (none: no zones)."""
    if note is None:
        return RiskView((), 0.0)
    return RiskView(tuple(np.asarray(z.vertices, dtype=float) for z in note.zones), note.alpha)


def start_text(controller: str, seed: int, detail: str = "") -> str:
    """The event line of a mission's start."""
    return f"mission started: controller {controller}, seed {seed}" + (
        f"; {detail}" if detail else "")


def step_text(t: int, flown: int, plan_status: str, note: str = "") -> str:
    """The event line of one flown step (the stack's MissionEvent STEP, or a record)."""
    what = f"S{flown} flew" if flown else "braked (no OK plan)"
    return f"step {t}: {what}; plans {plan_status or '-'}" + (f"; {note}" if note else "")


def end_text(success: bool, cause: str, steps: int) -> str:
    """The event line of a mission's end."""
    return (f"mission ended after {steps} steps: "
            + ("goal reached" if success else f"failed ({cause or 'unknown'})"))
