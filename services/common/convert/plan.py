"""plan.proto ↔ core types: the mission spec, plan requests (and prepares), plans.

In 3-D (docs/three_d.md) the spec's ``Dynamics.dim`` is 3 (its altitude band and goal
reading are the configuration's, which the prepare carries whole), a request's state is
a 3-D one (``VehicleState.dim`` 3), its previous control has ``up_n`` and each obstacle its
altitudes (``obstacle_altitudes_m``: a :class:`~dualpilot.model.prism.Prism`), and a plan's
states and controls are 6 and 3 packed doubles a row; a 2-D message has none of these
fields, byte for byte as before.

A plan request decodes to the core's :class:`~dualpilot.mission.ports.PlanRequest`
inside a :class:`PlanQuery` (its mission, sequence number, deadline and waypoint
revision), or to a :class:`Prepare` (the mission's spec and configuration). A risk-aware
request's forecast travels whole or by reference (:class:`ForecastRef`: the planner takes it
from the EWS on its own side of the link, checked against the digest). Every
decoder checks counts, finiteness and ranges (services/common/limits.py) and raises
:class:`~services.common.rejections.CodecError` for a bad message.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from typing import Any, cast

import numpy as np

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.ports import PlanRequest
from dualpilot.model.dynamics import DynamicsParams, SpeedLimit
from dualpilot.model.geometry import Polytope
from dualpilot.model.prism import Prism
from dualpilot.model.risk import ForecastView
from dualpilot.plan import Objective, Obstacles, Plan, PlanStatus, certified_gap
from dualpilot.spec import MissionSpec
from services.common.convert.common import (
    force_from_msg,
    packed_from_msg,
    packed_to_msg,
    polygon_from_msg,
    polygon_to_msg,
    rect_from_msg,
    rect_to_msg,
)
from services.common.convert.config import config_from_msg, config_to_msg
from services.common.convert.fire import DIGEST_BYTES, grid_digest, grid_from_msg, wire_grid
from services.common.convert.vehicle import state_from_msg, state_to_msg
from services.common.limits import (
    AREA_MARGIN,
    MAX_ABS_M,
    MAX_FORCE_N,
    MAX_FRONTS,
    MAX_HORIZON,
    MAX_SUBSTEP_S,
    MAX_SUBSTEPS,
    MAX_TEXT,
    check_altitudes,
    check_count,
    check_floats,
    check_in_box,
    check_int,
    check_text,
    finite,
)
from services.common.rejections import Reason, invalid
from services.common.wire import Stamper, check_header
from services.msgs import fire_pb2, plan_pb2

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
    if d.dim != 2:  # a planar spec's bytes are as before
        out.dynamics.dim = d.dim


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
    if d.dim not in (0, 2, 3):
        raise invalid(f"dynamics dim must be 2 or 3, got {d.dim}", Reason.OUT_OF_RANGE)
    start = finite((m.start.east_m, m.start.north_m), "start", MAX_ABS_M)
    try:
        spec = MissionSpec(start=(float(start[0]), float(start[1])),
                           goal=rect_from_msg(m.goal, "goal"), area_size_m=area, d_safe_m=d_safe,
                           clearance_m=clear, seed=int(m.seed),
                           dynamics=DynamicsParams(dt_s=dyn[0], zeta=dyn[1], mass_kg=dyn[2],
                                                   u_max_n=dyn[3], v_max_mps=dyn[4],
                                                   speed_limit=speed_limit,
                                                   dim=int(d.dim) or 2))
    except ValueError as err:
        raise invalid(f"mission spec: {err}", Reason.OUT_OF_RANGE) from err
    return mission_id, spec


@dataclass(frozen=True)
class ForecastRef:
    """A plan request's forecast by reference: the EWS's answer for the request's mission,
    fire revision ``substeps_done`` and step length ``substeps_per_step`` (its grid's
    ``digest``), seen through ``offset_substeps`` as :class:`ForecastView` does."""

    step: int
    substeps_done: int
    substep_s: float
    substeps_per_step: int
    offset_substeps: int
    digest: bytes


#: where a forecast keeps its wire grid's digest (OccupancyForecast.memo)
WIRE_DIGEST = "wire_digest"


@dataclass(frozen=True)
class PlanQuery:
    """A validated plan request: the core's request (step t, system, state, obstacles, …) and
    what it travels with (the mission it is for, its sequence number, the wall time the
    requester waits, the operator-waypoint revision it needs, and a forecast named by
    reference, which the planner resolves into the request's)."""

    request: PlanRequest
    mission_id: str
    seq: int
    deadline_s: float
    waypoints_revision: int = 0
    forecast_ref: ForecastRef | None = None


@dataclass(frozen=True)
class Prepare:
    """A validated prepare request: build this mission's planner of ``system`` from its spec
    (the vehicle's start) and its configuration (methods, risk, reading)."""

    mission_id: str
    system: int
    spec: MissionSpec
    config: MissionConfig
    seq: int = 0
    deadline_s: float = 60.0


def _envelope(m: plan_pb2.PlanRequest, system: int, mission_id: str, deadline_s: float,
              stamper: Stamper, sim_time_s: float) -> None:
    m.system, m.mission_id, m.deadline_s = system, mission_id, deadline_s
    stamper.stamp(m.header, sim_time_s)


def plan_query_msg(query: PlanQuery, stamper: Stamper, sim_time_s: float,
                   by_reference: bool = False) -> plan_pb2.PlanRequest:
    """A plan request on the wire: the core request, its mission, deadline and revision; its
    forecast whole, or with ``by_reference`` named by its revision and digest."""
    req = query.request
    m = plan_pb2.PlanRequest(step=req.t, objective=objective_to_msg(req.objective),
                             waypoints_revision=query.waypoints_revision)
    _envelope(m, req.system, query.mission_id, query.deadline_s, stamper, sim_time_s)
    stamper.stamp(m.state.header, sim_time_s)
    state_to_msg(req.state, req.t, m.state)
    u = [float(v) for v in req.prev_control]
    m.prev_control.east_n, m.prev_control.north_n = u[:2]
    if len(u) == 3:
        m.prev_control.up_n = u[2]
    _obstacles_to_msg(req.obstacles, m)
    if req.forecast is not None:
        forecast_to_msg(req.forecast, req.t, m.forecast, by_reference)
    return m


def _obstacles_to_msg(obstacles: Obstacles, m: plan_pb2.PlanRequest) -> None:
    """Each obstacle's polygon; a prism's altitudes (bottom, top) beside it, in order."""
    for o in obstacles:
        if isinstance(o, Prism):
            polygon_to_msg(o.base, m.obstacles.add())
            m.obstacle_altitudes_m.extend((float(o.z_lo), float(o.z_hi)))
        else:
            polygon_to_msg(o, m.obstacles.add())
    if len(m.obstacle_altitudes_m) not in (0, 2 * len(m.obstacles)):
        raise ValueError("a plan request's obstacles are all prisms (3-D) or all planar")


def _obstacles_from_msg(m: plan_pb2.PlanRequest, dim: int) -> Obstacles:
    """The request's obstacles: polygons (2-D), or prisms over their altitudes (3-D: a pair
    per polygon, each within [0, MAX_ALTITUDE_M] m, bottom below top); CodecError else."""
    check_count(len(m.obstacles), "obstacles", MAX_FRONTS * 2)
    polys = tuple(polygon_from_msg(p, f"obstacle {i}") for i, p in enumerate(m.obstacles))
    alts = list(m.obstacle_altitudes_m)
    if dim == 2:
        if alts:
            raise invalid(f"a planar plan request (state dim 2) carries {len(alts)} obstacle "
                          f"altitudes", Reason.SIZE)
        return polys
    if len(alts) != 2 * len(polys):
        raise invalid(f"a 3-D plan request needs (bottom, top) for each of its {len(polys)} "
                      f"obstacles, got {len(alts)} values", Reason.SIZE)
    check_altitudes(alts, "obstacle altitudes")
    prisms = []
    for i, poly in enumerate(polys):
        lo, hi = alts[2 * i], alts[2 * i + 1]
        if not lo < hi:
            raise invalid(f"obstacle {i}: bottom {lo!r} m is not below its top {hi!r} m",
                          Reason.OUT_OF_RANGE)
        prisms.append(Prism(poly, lo, hi))
    return tuple(prisms)


def forecast_to_msg(view: ForecastView, step: int, out: plan_pb2.PlanForecast,
                    by_reference: bool = False) -> None:
    """The forecast a plan of ``step`` is made on: its grid (slices zlib-compressed), or with
    ``by_reference`` only its grid's digest."""
    fc = view.forecast
    out.step, out.substeps_done, out.substep_s = step, fc.issued_substep, fc.substep_s
    out.substeps_per_step, out.offset_substeps = view.substeps_per_step, view.offset_substeps
    grid = wire_grid(fc)
    if not by_reference:
        out.occupancy.CopyFrom(grid)
        return
    digest = fc.memo.get(WIRE_DIGEST)
    if digest is None:
        digest = fc.memo[WIRE_DIGEST] = grid_digest(grid)
    out.digest = digest


def _forecast_header(m: plan_pb2.PlanForecast, step: int) -> None:
    """The checks a forecast's fields pass whole or by reference (CodecError)."""
    if m.step != step:
        raise invalid(f"the forecast was made for step {m.step}, the request is for step "
                      f"{step}", Reason.STALE)
    check_int(m.substeps_per_step, "substeps_per_step", 1, MAX_SUBSTEPS)
    check_int(m.offset_substeps, "offset_substeps", 0, MAX_SUBSTEPS)


def forecast_from_msg(m: plan_pb2.PlanForecast, step: int) -> ForecastView:
    """A plan request's forecast, whole, as the core's ForecastView; refused (CodecError): one
    made for another step than the request's, a bad grid (:func:`grid_from_msg`), a time-step
    length outside 1..MAX_SUBSTEPS, an offset past MAX_SUBSTEPS (an offset past the
    forecast's horizon is a plan with no zones, as in-process)."""
    _forecast_header(m, step)
    if not m.HasField("occupancy"):
        raise invalid("a plan forecast without its occupancy grid")
    fc = grid_from_msg(m.occupancy, m.substep_s, int(m.substeps_done))
    return ForecastView(fc, int(m.substeps_per_step), int(m.offset_substeps))


def forecast_ref_from_msg(m: plan_pb2.PlanForecast, step: int) -> ForecastRef:
    """A plan request's forecast by reference (no grid, a digest): the checks of
    :func:`forecast_from_msg`, a digest of :data:`DIGEST_BYTES` and a positive, finite T_f."""
    _forecast_header(m, step)
    if len(m.digest) != DIGEST_BYTES:
        raise invalid(f"a plan forecast without its occupancy grid needs a digest of "
                      f"{DIGEST_BYTES} bytes, got {len(m.digest)}", Reason.SIZE)
    check_floats([m.substep_s], "substep_s", MAX_SUBSTEP_S)
    if m.substep_s <= 0:
        raise invalid(f"substep_s must be positive, got {m.substep_s}", Reason.OUT_OF_RANGE)
    return ForecastRef(int(m.step), int(m.substeps_done), float(m.substep_s),
                       int(m.substeps_per_step), int(m.offset_substeps), bytes(m.digest))


def resolved_view(ref: ForecastRef, forecast: fire_pb2.FireForecast) -> ForecastView:
    """The view ``ref`` names, from the EWS's answer ``forecast``; refused (CodecError):
    another revision or T_f, no grid, a grid whose digest is not the reference's."""
    if forecast.substeps_done != ref.substeps_done or not math.isclose(
            forecast.substep_s, ref.substep_s, rel_tol=1e-12, abs_tol=0.0):
        raise invalid(f"the EWS answered revision {forecast.substeps_done} at T_f "
                      f"{forecast.substep_s:g} s for revision {ref.substeps_done} at "
                      f"{ref.substep_s:g} s", Reason.STALE)
    if not forecast.HasField("occupancy"):
        raise invalid("the EWS's forecast carries no occupancy grid")
    if grid_digest(forecast.occupancy) != ref.digest:
        raise invalid("the EWS's forecast is not the one the request names (digest differs)",
                      Reason.STALE)
    fc = grid_from_msg(forecast.occupancy, ref.substep_s, ref.substeps_done)
    fc.memo[WIRE_DIGEST] = ref.digest
    return ForecastView(fc, ref.substeps_per_step, ref.offset_substeps)


def prepare_msg(prep: Prepare, stamper: Stamper, sim_time_s: float) -> plan_pb2.PlanRequest:
    """A prepare request on the wire: the mission's spec and configuration."""
    m = plan_pb2.PlanRequest(prepare=True)
    _envelope(m, prep.system, prep.mission_id, prep.deadline_s, stamper, sim_time_s)
    spec_to_msg(prep.mission_id, prep.spec, m.mission)
    config_to_msg(prep.config, m.config)
    return m


def _deadline(m: plan_pb2.PlanRequest) -> float:
    check_floats([m.deadline_s], "deadline_s", 3600)
    if m.deadline_s <= 0:
        raise invalid(f"deadline_s must be in (0, 3600], got {m.deadline_s}", Reason.OUT_OF_RANGE)
    return float(m.deadline_s)


def _prepare_from_msg(m: plan_pb2.PlanRequest) -> Prepare:
    if not m.HasField("mission") or not m.HasField("config"):
        raise invalid("a prepare request must carry the mission spec and its configuration")
    mission_id, spec = spec_from_msg(m.mission)
    if m.mission_id and m.mission_id != mission_id:
        raise invalid(f"mission_id {m.mission_id!r} differs from the spec's {mission_id!r}")
    config = config_from_msg(m.config)
    if (config.seed, config.goal, config.area_size_m) != (spec.seed, spec.goal,
                                                          spec.area_size_m):
        raise invalid("the mission spec's seed, goal or area differs from its configuration's")
    spec = _with_vertical(spec, config)
    return Prepare(mission_id, int(m.system), spec, config, int(m.header.seq), _deadline(m))


def _with_vertical(spec: MissionSpec, config: MissionConfig) -> MissionSpec:
    """``spec`` with its configuration's altitude band, goal reading and risk zones' heights
    (3-D); CodecError when the two say different dimensions."""
    try:
        own = config.spec()
    except ValueError as err:
        raise invalid(f"mission configuration: {err}", Reason.OUT_OF_RANGE) from err
    if own.dim != spec.dim:
        raise invalid(f"the mission spec's dim {spec.dim} differs from its configuration's "
                      f"{own.dim}", Reason.OUT_OF_RANGE)
    if spec.dim == 2:
        return spec
    try:
        return replace(spec, band=own.band, goal_vertical=own.goal_vertical,
                       zone_heights=own.zone_heights)
    except ValueError as err:
        raise invalid(f"mission spec: {err}", Reason.OUT_OF_RANGE) from err


def plan_request_from_msg(m: plan_pb2.PlanRequest) -> PlanQuery | Prepare:
    """A plan request in core types (a :class:`Prepare` for a prepare request): field checks;
    a planner checks a query against the spec it was prepared with (:func:`check_in_area`)."""
    if m.system not in (1, 2):
        raise invalid(f"system must be 1 or 2, got {m.system}", Reason.OUT_OF_RANGE)
    if m.prepare:
        return _prepare_from_msg(m)
    if not m.HasField("state"):
        raise invalid("plan request without state")
    mission_id = check_text(m.mission_id, "mission_id", 256)
    if not mission_id:
        raise invalid("plan request without a mission_id")
    deadline = _deadline(m)
    check_header(m.state.header)
    objective = objective_from_msg(m.objective)
    assert objective is not None
    state = state_from_msg(m.state)
    dim = 3 if len(state) == 6 else 2
    obstacles = _obstacles_from_msg(m, dim)
    forecast: ForecastView | None = None
    ref: ForecastRef | None = None
    if m.HasField("forecast"):  # whole, or named by reference (no grid: a digest)
        if m.forecast.HasField("occupancy") or not m.forecast.digest:
            forecast = forecast_from_msg(m.forecast, int(m.step))
        else:
            ref = forecast_ref_from_msg(m.forecast, int(m.step))
    request = PlanRequest(t=int(m.step), system=int(m.system), state=state,
                          prev_control=force_from_msg(m.prev_control, "prev_control", dim),
                          obstacles=obstacles, objective=objective, forecast=forecast)
    return PlanQuery(request, mission_id, int(m.header.seq), deadline,
                     int(m.waypoints_revision), ref)


def check_in_area(req: PlanRequest, spec: MissionSpec) -> None:
    """A request is of the mission's dimension (its state's and its obstacles' kind) and
    everything in it lies near the mission's area [0, A]²: the state and the obstacles
    within ``AREA_MARGIN``·A of it (anything farther is not this mission's)."""
    dim = len(req.state) // 2
    if dim != spec.dim:
        raise invalid(f"a plan request of dim {dim} for a mission of dim {spec.dim}",
                      Reason.OUT_OF_RANGE)
    area = spec.area_size_m
    lo, hi = -AREA_MARGIN * area, (1 + AREA_MARGIN) * area
    check_in_box(req.state[None, :2], lo, hi, "the vehicle state")
    for i, o in enumerate(req.obstacles):
        base = o.base if isinstance(o, Prism) else o
        assert isinstance(base, Polytope)
        check_in_box(base.vertices, lo, hi, f"obstacle {i}")


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
        if plan.bound is not None and math.isfinite(plan.bound):
            m.bound = min(float(plan.bound), m.cost)
            gap = certified_gap(m.cost, m.bound)
            if math.isfinite(gap):
                m.certified_gap = gap
    if plan.path is not None:
        packed_to_msg(plan.path, m.path_m)
    try:
        info = json.dumps(plan.info, default=_json_default, allow_nan=True)
    except (TypeError, ValueError, RecursionError):
        info = '{"info_unserializable": true}'
    # cut JSON is no JSON: a too-long info is replaced, never truncated
    m.info_json = info if len(info) <= MAX_TEXT else '{"info_truncated": true}'
    return m


def plan_from_msg(m: plan_pb2.Plan, expected_system: int | None = None, dim: int = 2) -> Plan:
    """A plan in core types, its states and controls (and path) rows of the mission's ``dim``
    (2·dim, dim and dim values); CodecError for a bad one."""
    if m.system not in (1, 2) or (expected_system is not None and m.system != expected_system):
        raise invalid(f"plan from system {m.system}, expected {expected_system}",
                      Reason.OUT_OF_RANGE)
    status = status_from_msg(m.status)
    states = packed_from_msg(m.states, "plan states", 2 * dim, MAX_HORIZON + 1, MAX_ABS_M)
    controls = packed_from_msg(m.controls, "plan controls", dim, MAX_HORIZON, MAX_FORCE_N)
    if dim == 3:
        check_altitudes(states[:, 2].tolist(), "plan states' altitudes")
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
    bound = _bound_from_msg(m)
    path = (packed_from_msg(m.path_m, "plan path", dim, MAX_HORIZON * 10, MAX_ABS_M)
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
        message=check_text(m.message, "plan message"), info=info, bound=bound,
    )


def _bound_from_msg(m: plan_pb2.Plan) -> float | None:
    """A plan's bound, checked: finite, with a cost and at most it; its certified gap, if
    sent, with a bound, finite, ≥ 0 and (cost − bound) / bound (relative 1e-9)."""
    if m.HasField("certified_gap") and not m.HasField("bound"):
        raise invalid("a plan's certified_gap needs its bound")
    if not m.HasField("bound"):
        return None
    if not m.HasField("cost"):
        raise invalid("a plan's bound needs its cost")
    check_floats([m.bound], "plan bound", math.inf)
    if m.bound > m.cost:
        raise invalid(f"plan bound {m.bound!r} exceeds its cost {m.cost!r}",
                      Reason.OUT_OF_RANGE)
    if m.HasField("certified_gap"):
        check_floats([m.certified_gap], "plan certified_gap", math.inf)
        expected = certified_gap(m.cost, m.bound)
        if m.certified_gap < 0 or not math.isclose(m.certified_gap, expected, rel_tol=1e-9,
                                                   abs_tol=1e-12):
            raise invalid(f"plan certified_gap {m.certified_gap!r} is not (cost − bound) / "
                          f"bound = {expected!r}", Reason.OUT_OF_RANGE)
    return float(m.bound)
