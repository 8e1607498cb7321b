"""Protobuf messages ↔ core dataclasses, validated: the one place the two meet (ARCHITECTURE §5).

Every decoder checks what the core would otherwise trust: finite numbers, ranges
and sizes (services/common/limits.py); a bad message raises
:class:`~services.common.rejections.CodecError`. Geometry, vehicle state, fires
and their forecast, fire commands, plans and their requests, decisions,
waypoints and the live view's step plans. Bytes ↔ messages: services/common/wire.py.
"""

from __future__ import annotations

import json
import math
import re
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from dualpilot.mission.result import StepRecord
from dualpilot.model.dynamics import Array, DynamicsParams, SpeedLimit
from dualpilot.model.fire import FireFront, FireParams, FireSnapshot
from dualpilot.model.forecast import OccupancyForecast
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.model.scenarios import scenario_names
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.decision import Decision
from dualpilot.viz.scene import PlanView, plan_statuses
from services.common.clock import Anchor, check_speed_factor
from services.common.limits import (
    AREA_MARGIN,
    MAX_ABS_M,
    MAX_CLOCK_SKEW_S,
    MAX_FORCE_N,
    MAX_FORECAST_CELLS,
    MAX_FORECAST_SLICES,
    MAX_FRONTS,
    MAX_HORIZON,
    MAX_SPEED_MPS,
    MAX_SUBSTEP_S,
    MAX_SUBSTEPS,
    MAX_TEXT,
    MAX_VERTICES,
    MAX_WAYPOINTS,
    MIN_SPEED_FACTOR,
    check_count,
    check_floats,
    check_in_box,
    check_state_values,
    check_text,
    finite,
)
from services.common.rejections import Reason, invalid
from services.common.wire import Stamper, check_header
from services.msgs import (
    common_pb2,
    fire_pb2,
    plan_pb2,
    supervisor_pb2,
    vehicle_pb2,
)


# -- geometry -------------------------------------------------------------------------------------
def rect_to_msg(r: Rect, out: common_pb2.Rect) -> common_pb2.Rect:
    out.center_east_m, out.center_north_m = r.center_x, r.center_y
    out.width_m, out.height_m = r.width, r.height
    return out


def rect_from_msg(m: common_pb2.Rect, what: str = "rect") -> Rect:
    cx, cy, w, h = check_floats([m.center_east_m, m.center_north_m, m.width_m, m.height_m],
                                 what, MAX_ABS_M)
    if w <= 0 or h <= 0:
        raise invalid(f"{what} sides must be positive, got {w} x {h}", Reason.OUT_OF_RANGE)
    return Rect(float(cx), float(cy), float(w), float(h))


def points_to_msg(points: Array, out: Any) -> None:
    """Append (k, 2) points to a repeated Vec2 field."""
    for e, n in np.asarray(points, dtype=float).reshape(-1, 2):
        out.add(east_m=float(e), north_m=float(n))


def points_from_msg(vs: Sequence[common_pb2.Vec2], what: str, limit: int) -> Array:
    check_count(len(vs), what, limit)
    flat = finite((c for v in vs for c in (v.east_m, v.north_m)), what, MAX_ABS_M)
    return flat.reshape(-1, 2)


def packed_to_msg(points: Array, out: Any) -> None:
    """Append (k, c) values row-major to a packed repeated double field."""
    out.extend(np.asarray(points, dtype=float).ravel().tolist())


def packed_from_msg(values: Sequence[float], what: str, width: int, limit: int,
                    bound: float) -> Array:
    """A packed repeated double field as (k, width) rows; checks count, finiteness and range."""
    n = len(values)
    if n % width:
        raise invalid(f"{what}: {n} values is not a multiple of {width}", Reason.SIZE)
    check_count(n // width, what, limit)
    return np.array(check_floats(list(values), what, bound), dtype=float).reshape(-1, width)


def polygon_to_msg(poly: Polytope, out: common_pb2.Polygon) -> common_pb2.Polygon:
    packed_to_msg(poly.vertices, out.vertices_m)
    return out


def polygon_from_msg(m: common_pb2.Polygon, what: str = "polygon") -> Polytope:
    pts = packed_from_msg(m.vertices_m, what, 2, MAX_VERTICES, MAX_ABS_M)
    if len(pts) < 3:
        raise invalid(f"{what} needs at least 3 vertices, got {len(pts)}", Reason.SIZE)
    try:
        poly = _ccw_polytope(pts) or Polytope.from_vertices(pts)
    except (ValueError, ArithmeticError) as err:
        raise invalid(f"{what}: {err}") from err
    if not (np.all(np.isfinite(poly.A)) and np.all(np.isfinite(poly.b))):
        raise invalid(f"{what}: degenerate polygon (no finite face normals)")
    return poly


def _ccw_polytope(v: Array) -> Polytope | None:
    """The polytope of vertices that already form a strictly convex CCW polygon, else None.

    The sender's hulls come from :meth:`Polytope.from_vertices`, so their
    vertices are canonical (counter-clockwise from the lowest (x, y)) and
    recomputing the hull would return them unchanged, at ≈ 0.5 ms a hull.
    The checks run in plain Python (faster than numpy for a few vertices);
    A and b use from_vertices' own formula, so the result is identical.
    """
    pts = v.tolist()
    n = len(pts)
    if min(pts) != pts[0]:
        return None
    falling = False
    for i in range(n):
        (x0, y0), (x1, y1), (x2, y2) = pts[i], pts[(i + 1) % n], pts[(i + 2) % n]
        ex, ey, fx, fy = x1 - x0, y1 - y0, x2 - x1, y2 - y1
        if ex * fy - ey * fx <= 1e-9:  # strict left turns...
            return None
        if ex < 0:
            falling = True
        elif ex > 0 and falling:  # ...winding once: x rises, then falls (no star polygons)
            return None
    edges = np.concatenate((v[1:], v[:1])) - v
    normals = np.column_stack([edges[:, 1], -edges[:, 0]])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    b = np.einsum("ij,ij->i", normals, v)
    return Polytope(vertices=v, A=normals, b=b)


# -- vehicle state --------------------------------------------------------------------------------
def state_to_msg(x: Array, step: int, out: vehicle_pb2.VehicleState,
                 altitude_m: float = 0.0) -> vehicle_pb2.VehicleState:
    x = check_state_values(x)
    out.step = step
    out.east_m, out.north_m, out.velocity_east_mps, out.velocity_north_mps = (float(v) for v in x)
    out.altitude_m = float(altitude_m)
    return out


def state_from_msg(m: vehicle_pb2.VehicleState) -> Array:
    x = np.array([m.east_m, m.north_m, m.velocity_east_mps, m.velocity_north_mps])
    return check_state_values(x)


def force_from_msg(m: common_pb2.Force2, what: str = "force") -> Array:
    return finite((m.east_n, m.north_n), what, MAX_FORCE_N)


# -- fires ----------------------------------------------------------------------------------------
def fire_state_msg(
    fronts: Sequence[FireFront], extinct_hulls: Sequence[Polytope], step: int, substeps_done: int,
    substep_s: float, stamper: Stamper, sim_time_s: float,
) -> fire_pb2.FireState:
    """The EWS's FireField as a FireState message."""
    msg = fire_pb2.FireState(step=step, substeps_done=substeps_done, substep_s=substep_s)
    stamper.stamp(msg.header, sim_time_s)
    for f in fronts:
        fm = msg.fronts.add(front_id=f.front_id, born_step=f.born_step, speed_mps=f.speed_mps,
                            direction_rad=f.direction_rad)
        rect_to_msg(f.region, fm.region)
        polygon_to_msg(f.hull, fm.hull)
    for h in extinct_hulls:
        polygon_to_msg(h, msg.extinct_hulls.add())
    return msg


def snapshot_from_msg(m: fire_pb2.FireState) -> FireSnapshot:
    """A FireState as the core's FireSnapshot (front hulls first, then extinct hulls)."""
    check_count(len(m.fronts), "fronts", MAX_FRONTS)
    check_count(len(m.extinct_hulls), "extinct hulls", MAX_FRONTS)
    check_floats([m.substep_s], "substep_s", MAX_SUBSTEP_S)
    if m.substep_s <= 0:
        raise invalid(f"substep_s must be positive, got {m.substep_s}", Reason.OUT_OF_RANGE)
    regions, hulls, ids, born = [], [], [], []
    for i, f in enumerate(m.fronts):
        regions.append(rect_from_msg(f.region, f"front {i} region"))
        hulls.append(polygon_from_msg(f.hull, f"front {i} hull"))
        check_floats([f.speed_mps, f.direction_rad], f"front {i} speed/direction",
                      MAX_SPEED_MPS)
        ids.append(int(f.front_id))
        born.append(int(f.born_step))
    if len(set(ids)) != len(ids):
        raise invalid("front ids must be unique")
    hulls += [polygon_from_msg(h, f"extinct hull {i}") for i, h in enumerate(m.extinct_hulls)]
    return FireSnapshot(regions=tuple(regions), hulls=tuple(hulls), front_ids=tuple(ids),
                        born_steps=tuple(born))


def regions_from_msg(m: fire_pb2.FireState) -> tuple[Rect, ...]:
    """Only the current regions of a FireState (validated)."""
    check_count(len(m.fronts), "fronts", MAX_FRONTS)
    return tuple(rect_from_msg(f.region, f"front {i} region") for i, f in enumerate(m.fronts))


def occupancy_to_msg(fc: OccupancyForecast, out: fire_pb2.OccupancyGrid) -> fire_pb2.OccupancyGrid:
    """The core's occupancy forecast as an OccupancyGrid (its levels, byte for byte)."""
    out.origin.east_m, out.origin.north_m = fc.origin_m
    out.resolution_m = fc.resolution_m
    out.rows, out.cols = fc.shape
    out.horizons.extend(fc.horizons)
    out.probabilities.extend(np.ascontiguousarray(lv).tobytes() for lv in fc.layers)
    out.horizon_s = fc.max_substeps * fc.substep_s
    out.substeps_per_step = fc.substeps_per_step
    return out


def occupancy_from_msg(m: fire_pb2.FireForecast) -> OccupancyForecast | None:
    """A FireForecast's grid as the core's OccupancyForecast (None when it carries none).

    Rejected: a grid without cells or with more than MAX_FORECAST_CELLS, a slice whose
    length is not rows × cols, horizons that are not increasing (or past MAX_SUBSTEPS) or not
    one per slice, a horizon_s that is not horizons[-1]·T_f, a bad origin, resolution or T_f.
    """
    check_header(m.header)
    if not m.HasField("occupancy"):
        return None
    g = m.occupancy
    check_floats([m.substep_s], "substep_s", MAX_SUBSTEP_S)
    if m.substep_s <= 0:
        raise invalid(f"substep_s must be positive, got {m.substep_s}", Reason.OUT_OF_RANGE)
    origin = finite((g.origin.east_m, g.origin.north_m), "grid origin", MAX_ABS_M)
    check_floats([g.resolution_m], "resolution_m", MAX_ABS_M)
    if g.resolution_m <= 0:
        raise invalid(f"resolution_m must be positive, got {g.resolution_m}",
                      Reason.OUT_OF_RANGE)
    cells = int(g.rows) * int(g.cols)
    if not 0 < cells <= MAX_FORECAST_CELLS:
        raise invalid(f"grid of {g.rows} x {g.cols} cells, allowed 1..{MAX_FORECAST_CELLS}",
                      Reason.SIZE)
    check_count(len(g.horizons), "forecast horizons", MAX_FORECAST_SLICES, minimum=1)
    if len(g.probabilities) != len(g.horizons):
        raise invalid(f"{len(g.probabilities)} probability slices for {len(g.horizons)} "
                      "horizons", Reason.SIZE)
    horizons = [int(h) for h in g.horizons]
    if any(b <= a for a, b in zip(horizons, horizons[1:], strict=False)) or (
            horizons[-1] > MAX_SUBSTEPS):
        raise invalid(f"horizons must increase, at most {MAX_SUBSTEPS}: {horizons[:8]}",
                      Reason.OUT_OF_RANGE)
    bad = [i for i, b in enumerate(g.probabilities) if len(b) != cells]
    if bad:
        raise invalid(f"slice {bad[0]} has {len(g.probabilities[bad[0]])} bytes, the grid "
                      f"{g.rows} x {g.cols}", Reason.SIZE)
    check_floats([g.horizon_s], "horizon_s", MAX_SUBSTEPS * MAX_SUBSTEP_S)
    if not math.isclose(g.horizon_s, horizons[-1] * m.substep_s, rel_tol=1e-9, abs_tol=1e-9):
        raise invalid(f"horizon_s {g.horizon_s} is not the last horizon {horizons[-1]} x "
                      f"T_f {m.substep_s}", Reason.INVALID)
    levels = np.frombuffer(b"".join(g.probabilities), dtype=np.uint8).reshape(
        len(horizons), int(g.rows), int(g.cols))
    return OccupancyForecast(resolution_m=float(g.resolution_m), substep_s=float(m.substep_s),
                             horizons=tuple(horizons), levels=levels.copy(),
                             origin_m=(float(origin[0]), float(origin[1])),
                             issued_substep=int(m.substeps_done),
                             substeps_per_step=max(1, int(g.substeps_per_step)))


# -- fire commands --------------------------------------------------------------------------------
def clock_to_msg(anchor: Anchor, out: common_pb2.Clock) -> common_pb2.Clock:
    out.sim_time_s = anchor.sim_time_s
    out.speed_factor = anchor.speed_factor
    out.anchor_wall_ns = anchor.wall_ns
    return out


def clock_from_msg(m: common_pb2.Clock, now_ns: int | None = None) -> Anchor:
    """A Clock as an Anchor; a paced clock's anchor must lie within
    :data:`MAX_CLOCK_SKEW_S` of ``now_ns`` (default: this machine's wall clock)."""
    check_floats([m.sim_time_s], "clock sim_time_s", 1e12)
    if m.sim_time_s < 0:
        raise invalid(f"clock sim_time_s must be >= 0, got {m.sim_time_s}", Reason.OUT_OF_RANGE)
    if math.isnan(m.speed_factor):
        raise invalid("clock speed_factor is NaN", Reason.NOT_FINITE)
    try:
        factor = check_speed_factor(m.speed_factor)
    except ValueError as err:
        raise invalid(str(err), Reason.OUT_OF_RANGE) from err
    if factor and not MIN_SPEED_FACTOR <= factor <= 1e9:
        raise invalid(f"clock speed_factor must be 0 (unpaced) or in [{MIN_SPEED_FACTOR:g}, 1e9],"
                      f" got {factor}", Reason.OUT_OF_RANGE)
    if m.anchor_wall_ns < 0:
        raise invalid("clock anchor must be >= 0", Reason.OUT_OF_RANGE)
    now_ns = time.time_ns() if now_ns is None else now_ns
    if factor and abs(m.anchor_wall_ns - now_ns) > MAX_CLOCK_SKEW_S * 1e9:
        raise invalid(f"clock anchor {m.anchor_wall_ns} ns is more than {MAX_CLOCK_SKEW_S:g} s "
                      "from this machine's clock", Reason.OUT_OF_RANGE)
    return Anchor(float(m.sim_time_s), int(m.anchor_wall_ns), factor)


_LIFE_BASES = {"substep": fire_pb2.FIRE_LIFE_BASE_SUBSTEP, "step": fire_pb2.FIRE_LIFE_BASE_STEP}
_EXTENTS = {"substep": fire_pb2.FIRE_EXTENT_SUBSTEP, "step": fire_pb2.FIRE_EXTENT_STEP,
            "birth": fire_pb2.FIRE_EXTENT_BIRTH}


def fire_readings_to_msg(params: FireParams, out: fire_pb2.FireReset) -> fire_pb2.FireReset:
    """The readings of ``params`` (FireParams) into a FireReset, for the EWS to run them."""
    r = out.readings
    r.life_base = _LIFE_BASES[params.life_base]
    r.extent = _EXTENTS[params.extent]
    r.redraw_clearance = params.redraw_clearance
    r.keep_extinct_hulls = params.keep_extinct_hulls
    out.scenario = params.scenario
    return out


def fire_scenario_from_msg(m: fire_pb2.FireReset) -> str:
    """FireReset.scenario checked against the known fire processes ("": the EWS's own)."""
    name = check_text(m.scenario, "scenario", 64)
    if name and name not in scenario_names():
        raise invalid(f"unknown fire scenario {name!r} (known: {', '.join(scenario_names())})",
                      Reason.OUT_OF_RANGE)
    return name


def fire_readings_from_msg(m: fire_pb2.FireReadings) -> dict[str, object]:
    """A FireReadings as FireParams fields (an unspecified enum: left to the EWS)."""
    out: dict[str, object] = {"redraw_clearance": bool(m.redraw_clearance),
                              "keep_extinct_hulls": bool(m.keep_extinct_hulls)}
    for name, value, table in (("life_base", m.life_base, _LIFE_BASES),
                               ("extent", m.extent, _EXTENTS)):
        if value == 0:
            continue
        back = {v: k for k, v in table.items()}
        if value not in back:
            raise invalid(f"unknown {name} {value}", Reason.OUT_OF_RANGE)
        out[name] = back[value]
    return out


@dataclass(frozen=True)
class FireCommand:
    mission_id: str
    kind: str  # "reset" or "advance"
    seed: int = 0
    area_size_m: float = 0.0  # reset: the mission's area (0: the EWS's default)
    step: int = 0
    substeps: int = 0
    anchor: Anchor | None = None
    keep_out: tuple[Array, float] | None = None  # advance: (position, ignition clearance m)
    #: reset: FireParams fields to run (None: the EWS's own readings)
    readings: tuple[tuple[str, object], ...] | None = None
    #: reset: the fire process, FireParams.scenario ("": the EWS's own)
    scenario: str = ""


def fire_command_from_msg(m: fire_pb2.FireCommand) -> FireCommand:
    mission_id = check_text(m.mission_id, "mission_id", 256)
    kind = m.WhichOneof("command")
    if kind == "reset":
        area = check_floats([m.reset.area_size_m], "area_size_m", MAX_ABS_M)[0]
        if area < 0:
            raise invalid(f"area_size_m must be >= 0, got {area}", Reason.OUT_OF_RANGE)
        readings = (tuple(fire_readings_from_msg(m.reset.readings).items())
                    if m.reset.HasField("readings") else None)
        return FireCommand(mission_id, "reset", seed=int(m.reset.seed), area_size_m=area,
                           readings=readings, scenario=fire_scenario_from_msg(m.reset))
    if kind == "advance":
        a = m.advance
        check_count(a.substeps, "substeps", MAX_SUBSTEPS)
        clear = check_floats([a.keep_out_m], "keep_out_m", MAX_ABS_M)[0]
        if clear < 0:
            raise invalid(f"keep_out_m must be >= 0, got {clear}", Reason.OUT_OF_RANGE)
        keep_out = None
        if clear > 0:
            keep_out = (finite((a.keep_out.east_m, a.keep_out.north_m), "keep_out",
                                MAX_ABS_M), clear)
        return FireCommand(mission_id, "advance", step=int(a.step), substeps=int(a.substeps),
                           anchor=clock_from_msg(a.clock) if a.HasField("clock") else None,
                           keep_out=keep_out)
    raise invalid("FireCommand carries neither reset nor advance")


# -- plans ----------------------------------------------------------------------------------------
_OBJECTIVES = {
    Objective.MISSION_TIME: plan_pb2.OBJECTIVE_MISSION_TIME,
    Objective.ENERGY: plan_pb2.OBJECTIVE_ENERGY,
}
_OBJECTIVES_BACK = {v: k for k, v in _OBJECTIVES.items()}


def objective_to_msg(o: Objective | None) -> plan_pb2.Objective:
    return plan_pb2.OBJECTIVE_UNSPECIFIED if o is None else _OBJECTIVES[o]


def objective_from_msg(v: plan_pb2.Objective, required: bool = True) -> Objective | None:
    if v in _OBJECTIVES_BACK:
        return _OBJECTIVES_BACK[v]
    if v == plan_pb2.OBJECTIVE_UNSPECIFIED and not required:
        return None
    raise invalid(f"unknown objective {v}")


def status_to_msg(s: PlanStatus) -> plan_pb2.PlanStatus:
    return cast(plan_pb2.PlanStatus, plan_pb2.PlanStatus.Value("PLAN_STATUS_" + s.name))


def status_from_msg(v: plan_pb2.PlanStatus) -> PlanStatus:
    try:
        name = plan_pb2.PlanStatus.Name(v)
    except ValueError as err:
        raise invalid(f"unknown plan status {v}") from err
    if name == "PLAN_STATUS_UNSPECIFIED":
        raise invalid("plan status is unspecified")
    return PlanStatus[name.removeprefix("PLAN_STATUS_")]


_SPEED_LIMITS: dict[SpeedLimit, plan_pb2.SpeedLimit] = {
    "axis": plan_pb2.SPEED_LIMIT_AXIS, "norm": plan_pb2.SPEED_LIMIT_NORM}


def speed_limit_from_msg(value: int) -> SpeedLimit:
    """DynamicsParams.speed_limit of a SpeedLimit value (unspecified: "axis")."""
    if value == plan_pb2.SPEED_LIMIT_UNSPECIFIED:
        return "axis"
    for name, number in _SPEED_LIMITS.items():
        if value == number:
            return name
    raise invalid(f"unknown speed_limit {value}", Reason.OUT_OF_RANGE)


def spec_to_msg(mission_id: str, spec: MissionSpec, out: plan_pb2.MissionSpec) -> None:
    """The core's frozen mission spec as a message (sent once, when a mission is prepared)."""
    out.mission_id, out.seed, out.area_size_m = mission_id, spec.seed, spec.area_size_m
    rect_to_msg(spec.goal, out.goal)
    out.start.east_m, out.start.north_m = spec.start
    out.d_safe_m, out.clearance_m = spec.d_safe_m, spec.clearance_m
    d = spec.dynamics
    out.dynamics.dt_s, out.dynamics.zeta, out.dynamics.mass_kg = d.dt_s, d.zeta, d.mass_kg
    out.dynamics.u_max_n, out.dynamics.v_max_mps = d.u_max_n, d.v_max_mps
    out.dynamics.speed_limit = _SPEED_LIMITS[d.speed_limit]


def spec_from_msg(m: plan_pb2.MissionSpec) -> tuple[str, MissionSpec]:
    """(mission id, spec) of a MissionSpec message; every field checked."""
    mission_id = check_text(m.mission_id, "mission_id", 256)
    if not mission_id:
        raise invalid("mission spec without a mission_id")
    for sub in ("goal", "start", "dynamics"):
        if not m.HasField(sub):
            raise invalid(f"mission spec without {sub}")
    area, d_safe, clear = check_floats([m.area_size_m, m.d_safe_m, m.clearance_m],
                                        "area/d_safe/clearance", MAX_ABS_M)
    d = m.dynamics
    dyn = check_floats([d.dt_s, d.zeta, d.mass_kg, d.u_max_n, d.v_max_mps], "dynamics",
                        MAX_FORCE_N)
    speed_limit = speed_limit_from_msg(d.speed_limit)
    start = finite((m.start.east_m, m.start.north_m), "start", MAX_ABS_M)
    try:
        spec = MissionSpec(start=(float(start[0]), float(start[1])),
                           goal=rect_from_msg(m.goal, "goal"), area_size_m=area, d_safe_m=d_safe,
                           clearance_m=clear, seed=int(m.seed),
                           dynamics=DynamicsParams(dt_s=dyn[0], zeta=dyn[1], mass_kg=dyn[2],
                                                   u_max_n=dyn[3], v_max_mps=dyn[4],
                                                   speed_limit=speed_limit))
    except ValueError as err:
        raise invalid(f"mission spec: {err}", Reason.OUT_OF_RANGE) from err
    return mission_id, spec


@dataclass(frozen=True)
class PlanRequest:
    """A validated plan request in core types; ``spec`` only with ``prepare``."""

    seq: int
    mission_id: str
    step: int
    system: int
    objective: Objective
    state: Array
    prev_control: Array
    obstacles: tuple[Polytope, ...]
    deadline_s: float
    waypoints_revision: int = 0
    prepare: bool = False
    spec: MissionSpec | None = None
    method: str = ""  # with prepare: the planner method ("" the service's default)


def plan_request_msg(req: PlanRequest, stamper: Stamper, sim_time_s: float,
                     ) -> plan_pb2.PlanRequest:
    """Build a PlanRequest message (the spec goes only with ``prepare``)."""
    m = plan_pb2.PlanRequest(step=req.step, system=req.system, mission_id=req.mission_id,
                             objective=objective_to_msg(req.objective), deadline_s=req.deadline_s,
                             prepare=req.prepare, waypoints_revision=req.waypoints_revision,
                             method=req.method)
    stamper.stamp(m.header, sim_time_s)
    if req.spec is not None:
        spec_to_msg(req.mission_id, req.spec, m.mission)
    stamper.stamp(m.state.header, sim_time_s)
    state_to_msg(req.state, req.step, m.state)
    m.prev_control.east_n, m.prev_control.north_n = (float(v) for v in req.prev_control)
    for poly in req.obstacles:
        polygon_to_msg(poly, m.obstacles.add())
    return m


def plan_request_from_msg(m: plan_pb2.PlanRequest) -> PlanRequest:
    """A PlanRequest in core types: field checks, and :func:`check_in_area` when it carries
    the spec (a planner checks later requests against the spec it was prepared with)."""
    if m.system not in (1, 2):
        raise invalid(f"system must be 1 or 2, got {m.system}", Reason.OUT_OF_RANGE)
    if not m.HasField("state"):
        raise invalid("plan request without state")
    if m.prepare and not m.HasField("mission"):
        raise invalid("a prepare request must carry the mission spec")
    mission_id, spec = spec_from_msg(m.mission) if m.HasField("mission") else (
        check_text(m.mission_id, "mission_id", 256), None)
    if m.mission_id and m.mission_id != mission_id:
        raise invalid(f"mission_id {m.mission_id!r} differs from the spec's {mission_id!r}")
    if not mission_id:
        raise invalid("plan request without a mission_id")
    check_floats([m.deadline_s], "deadline_s", 3600)
    if m.deadline_s <= 0:
        raise invalid(f"deadline_s must be in (0, 3600], got {m.deadline_s}", Reason.OUT_OF_RANGE)
    check_header(m.state.header)
    objective = objective_from_msg(m.objective)
    assert objective is not None
    check_count(len(m.obstacles), "obstacles", MAX_FRONTS * 2)
    obstacles = tuple(polygon_from_msg(p, f"obstacle {i}") for i, p in enumerate(m.obstacles))
    req = PlanRequest(
        seq=int(m.header.seq), mission_id=mission_id, step=int(m.step), system=int(m.system),
        objective=objective, state=state_from_msg(m.state),
        prev_control=force_from_msg(m.prev_control, "prev_control"), obstacles=obstacles,
        deadline_s=float(m.deadline_s), waypoints_revision=int(m.waypoints_revision),
        prepare=m.prepare, spec=spec, method=check_text(m.method, "method", 64),
    )
    if spec is not None:
        check_in_area(req, spec)
    return req


def check_in_area(req: PlanRequest, spec: MissionSpec) -> None:
    """Everything in a request lies near the mission's area [0, A]²: the state and the
    obstacles within ``AREA_MARGIN``·A of it (anything farther is not this mission's)."""
    area = spec.area_size_m
    lo, hi = -AREA_MARGIN * area, (1 + AREA_MARGIN) * area
    check_in_box(req.state[None, :2], lo, hi, "the vehicle state")
    for i, h in enumerate(req.obstacles):
        check_in_box(h.vertices, lo, hi, f"obstacle {i}")


def _json_default(v: Any) -> Any:
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (np.floating, np.integer, np.bool_)):
        return v.item()
    return str(v)


def plan_to_msg(plan: Plan, step: int, request_seq: int, stamper: Stamper,
                sim_time_s: float = 0.0) -> plan_pb2.Plan:
    m = plan_pb2.Plan(step=step, system=plan.system, status=status_to_msg(plan.status),
                      compute_time_s=float(plan.compute_time_s),
                      objective=objective_to_msg(plan.objective), message=plan.message[:MAX_TEXT],
                      request_seq=request_seq)
    stamper.stamp(m.header, sim_time_s)
    packed_to_msg(plan.states, m.states)
    packed_to_msg(plan.controls, m.controls)
    if plan.cost is not None and math.isfinite(plan.cost):
        m.cost = float(plan.cost)
    if plan.path is not None:
        packed_to_msg(plan.path, m.path_m)
    try:
        info = json.dumps(plan.info, default=_json_default, allow_nan=True)
    except (TypeError, ValueError, RecursionError):
        info = '{"info_unserializable": true}'
    # cut JSON is no JSON: a too-long info is replaced, never truncated
    m.info_json = info if len(info) <= MAX_TEXT else '{"info_truncated": true}'
    return m


def plan_from_msg(m: plan_pb2.Plan, expected_system: int | None = None) -> Plan:
    if m.system not in (1, 2) or (expected_system is not None and m.system != expected_system):
        raise invalid(f"plan from system {m.system}, expected {expected_system}",
                      Reason.OUT_OF_RANGE)
    status = status_from_msg(m.status)
    states = packed_from_msg(m.states, "plan states", 4, MAX_HORIZON + 1, MAX_ABS_M)
    controls = packed_from_msg(m.controls, "plan controls", 2, MAX_HORIZON, MAX_FORCE_N)
    if status is PlanStatus.OK and (len(controls) < 1 or len(states) != len(controls) + 1):
        raise invalid(f"an OK plan needs T >= 1 controls and T+1 states, got "
                      f"{len(controls)} / {len(states)}", Reason.SIZE)
    check_floats([m.compute_time_s], "compute_time_s", 1e6)
    if m.compute_time_s < 0:
        raise invalid(f"compute_time_s must be >= 0, got {m.compute_time_s}",
                      Reason.OUT_OF_RANGE)
    check_floats([m.service_time_s], "service_time_s", 1e6)
    if m.service_time_s < 0:
        raise invalid(f"service_time_s must be >= 0, got {m.service_time_s}",
                      Reason.OUT_OF_RANGE)
    if m.HasField("cost"):
        check_floats([m.cost], "plan cost", math.inf)
    path = (packed_from_msg(m.path_m, "plan path", 2, MAX_HORIZON * 10, MAX_ABS_M)
            if len(m.path_m) else None)
    info_json = check_text(m.info_json, "plan info_json")
    try:
        info = json.loads(info_json) if info_json else {}
    except (ValueError, RecursionError) as err:
        raise invalid(f"plan info_json is not JSON: {str(err)[:200]}") from err
    if not isinstance(info, dict):
        raise invalid(f"plan info_json must be a JSON object, got {type(info).__name__}")
    return Plan(
        system=int(m.system), status=status, states=states, controls=controls,
        compute_time_s=float(m.compute_time_s),
        objective=objective_from_msg(m.objective, required=False),
        cost=float(m.cost) if m.HasField("cost") else None, path=path,
        message=check_text(m.message, "plan message"), info=info,
    )


# -- decisions and events -------------------------------------------------------------------------
def decision_to_msg(d: Decision, commanded_system: int, stamper: Stamper,
                    sim_time_s: float) -> supervisor_pb2.Decision:
    m = supervisor_pb2.Decision(step=d.t, d_t_m=float(d.d_t), attention=d.attention,
                                system=d.system, objective=objective_to_msg(d.objective),
                                commanded_system=commanded_system)
    stamper.stamp(m.header, sim_time_s)
    m.xi.extend(float(v) for v in d.xi)
    m.p.extend(float(v) for v in d.p)
    m.psi.extend(float(v) for v in d.psi)
    return m


def decision_from_msg(m: supervisor_pb2.Decision) -> Decision:
    if len(m.xi) != 3 or len(m.p) != 3 or len(m.psi) != 2:
        raise invalid("a decision has 3 ξ, 3 p and 2 ψ", Reason.SIZE)
    xi = finite(m.xi, "xi", 1e6)
    p = finite(m.p, "p", 1.0)
    psi = finite(m.psi, "psi", 1e6)
    if np.any(xi <= 0):
        raise invalid(f"ξ (Dirichlet concentrations) must be > 0, got {xi}", Reason.OUT_OF_RANGE)
    if np.any(p < 0) or abs(float(p.sum()) - 1.0) > 1e-6:
        raise invalid(f"p must be a probability vector, got {p}", Reason.OUT_OF_RANGE)
    if math.isnan(m.d_t_m):
        raise invalid("d_t is NaN", Reason.NOT_FINITE)
    if m.d_t_m < 0:
        raise invalid(f"d_t must be >= 0 (inf allowed), got {m.d_t_m}", Reason.OUT_OF_RANGE)
    if m.attention not in (1, 2, 3) or m.system not in (1, 2):
        raise invalid(f"attention {m.attention} / system {m.system} out of range",
                      Reason.OUT_OF_RANGE)
    objective = objective_from_msg(m.objective)
    assert objective is not None
    return Decision(t=int(m.step), d_t=float(m.d_t_m), xi=xi, p=p, attention=int(m.attention),
                    psi=psi, system=int(m.system), objective=objective)


@dataclass(frozen=True)
class Waypoints:
    """Operator waypoints of one mission, at a revision (1, 2, …; 0: none sent)."""

    mission_id: str
    revision: int
    points: Array | None  # (k, 2) or None (cleared)


def waypoints_msg(w: Waypoints, stamper: Stamper) -> vehicle_pb2.OperatorWaypoints:
    m = vehicle_pb2.OperatorWaypoints(mission_id=w.mission_id, revision=w.revision)
    stamper.stamp(m.header)
    if w.points is not None:
        points_to_msg(w.points, m.waypoints)
    return m


def waypoints_from_msg(m: vehicle_pb2.OperatorWaypoints) -> Waypoints:
    pts = points_from_msg(m.waypoints, "operator waypoints", MAX_WAYPOINTS)
    return Waypoints(check_text(m.mission_id, "mission_id", 256), int(m.revision),
                     pts if len(pts) else None)


def parse_waypoints(text: str) -> Array | None:
    """``"e1,n1;e2,n2"`` (m) → (k, 2) waypoints; empty text → None. For CLI flags."""
    text = text.strip()
    if not text:
        return None
    try:
        pts = np.array([[float(c) for c in p.split(",")] for p in text.split(";")])
    except ValueError as err:
        raise ValueError(f"waypoints must look like 'e1,n1;e2,n2', got {text!r}") from err
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"waypoints must look like 'e1,n1;e2,n2', got {text!r}")
    return finite(pts.ravel(), "waypoints", MAX_ABS_M).reshape(-1, 2)


# -- the live view's step plans (services/viewer) ------------------------------------------------
#: one status of a system at a step: a word (a plan status, "unavailable", the concurrent
#: supervisor's "adopted", ...) and the run-time monitor's optional note
_PLAN_STATUS = re.compile(r"^[a-z_]{1,32}(\[[^\]]{0,1000}\])?$")


@dataclass(frozen=True)
class StepPlans:
    """A validated StepPlans message in core types: both systems' plans at a step."""

    mission_id: str
    step: int
    time_s: float  # τ_t (s)
    flown: int  # 0: none
    plans: tuple[PlanView, ...]  # systems 1 and 2; status "" for a system not asked
    spec: MissionSpec


def step_plans_msg(record: StepRecord, mission_id: str, spec: MissionSpec, stamper: Stamper,
                   sim_time_s: float) -> supervisor_pb2.StepPlans:
    """A recorded step's plans: each asked system's status, the flown plan's positions."""
    m = supervisor_pb2.StepPlans(mission_id=mission_id, step=record.t,
                                 step_time_s=float(record.time_s), flown_system=record.system)
    stamper.stamp(m.header, sim_time_s)
    spec_to_msg(mission_id, spec, m.mission)
    statuses = plan_statuses(record.plan_status)
    if record.system and record.system not in statuses:
        statuses[record.system] = ""  # flown, not asked at this step (a kept plan)
    for system, status in statuses.items():
        sp = m.plans.add(system=system, status=status[:MAX_TEXT])
        if system == record.system:
            packed_to_msg(np.asarray(record.planned_positions)[:, :2], sp.positions_m)
    return m


def step_plans_from_msg(m: supervisor_pb2.StepPlans) -> StepPlans:
    """Rejected: a system other than 1 or 2 (or twice), a status that is not one, positions for
    a plan that was not flown, a flown system without its plan, a bad spec or time."""
    if not m.HasField("mission"):
        raise invalid("step plans without the mission spec")
    mission_id, spec = spec_from_msg(m.mission)
    check_floats([m.step_time_s], "step_time_s", 1e12)
    if m.step_time_s < 0:
        raise invalid(f"step_time_s must be >= 0, got {m.step_time_s}", Reason.OUT_OF_RANGE)
    if m.flown_system not in (0, 1, 2):
        raise invalid(f"flown_system {m.flown_system} out of range", Reason.OUT_OF_RANGE)
    check_count(len(m.plans), "plans", 2)
    got: dict[int, PlanView] = {}
    for sp in m.plans:
        if sp.system not in (1, 2) or sp.system in got:
            raise invalid(f"plan of system {sp.system} (once each of 1 and 2)",
                          Reason.OUT_OF_RANGE)
        status = check_text(sp.status, "plan status", MAX_TEXT)
        parts = status.split(";") if status else []
        if any(not _PLAN_STATUS.match(p) for p in parts) or (
                not parts and sp.system != m.flown_system):
            raise invalid(f"plan status {status[:80]!r} is not a status")
        pts = packed_from_msg(sp.positions_m, "plan positions", 2, MAX_HORIZON + 1, MAX_ABS_M)
        if len(pts) and sp.system != m.flown_system:
            raise invalid(f"positions for system {sp.system}'s plan, which was not flown")
        got[sp.system] = PlanView(int(sp.system), status, pts, sp.system == m.flown_system)
    if m.flown_system and (m.flown_system not in got or not len(got[m.flown_system].positions)):
        raise invalid(f"system {m.flown_system} flew but its plan's positions are missing")
    empty = np.empty((0, 2))
    plans = tuple(got.get(k, PlanView(k, "", empty, False)) for k in (1, 2))
    return StepPlans(mission_id, int(m.step), float(m.step_time_s), int(m.flown_system), plans,
                     spec)


def check_mission_event(m: supervisor_pb2.MissionEvent) -> supervisor_pb2.MissionEvent:
    """A MissionEvent a viewer may show: a known kind, short texts, a finite position."""
    if m.kind not in supervisor_pb2.MissionEventKind.values() or (
            m.kind == supervisor_pb2.MISSION_EVENT_KIND_UNSPECIFIED):
        raise invalid(f"unknown mission event kind {m.kind}", Reason.OUT_OF_RANGE)
    for name, limit in (("mission_id", 256), ("controller", 16), ("failure_cause", 256),
                        ("plan_status", MAX_TEXT), ("message", MAX_TEXT)):
        check_text(getattr(m, name), f"mission event {name}", limit)
    check_floats([m.position.east_m, m.position.north_m, m.mission_time_s],
                  "mission event position/time", MAX_ABS_M)
    if m.flown_system not in (0, 1, 2):
        raise invalid(f"flown_system {m.flown_system} out of range", Reason.OUT_OF_RANGE)
    return m
