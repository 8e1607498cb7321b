"""The one place that converts messages (protobuf, MAVLink) to core types and back, and validates.

Every decoder checks what the core would otherwise trust: the schema version,
finite numbers, ranges (positions within ``MAX_ABS_M`` of the origin, speeds,
forces) and sizes (fronts, hull vertices, horizon). A bad message raises
:class:`CodecError` (a ValueError) with a code (MALFORMED: does not parse;
INVALID: parses but fails validation); services call :func:`rejected`, which
logs one line and counts it in :data:`REJECTIONS`, and never crash on input.

Frames: the core's local frame is (east, north) in metres, state
x = [p_east, p_north, v_east, v_north] (Sec. IV, 2-D at fixed altitude).
MAVLink's LOCAL_NED is (north, east, down): :func:`state_to_ned` and
:func:`state_from_ned` are the only conversions between the two.
"""

from __future__ import annotations

import collections
import json
import logging
import math
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar, cast

import numpy as np
from google.protobuf.message import DecodeError, Message

from dualpilot.dynamics import Array
from dualpilot.fire import FireFront, FireSnapshot
from dualpilot.geometry import Polytope, Rect
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.supervisor import Decision
from services.msgs import (
    common_pb2,
    fire_pb2,
    plan_pb2,
    supervisor_pb2,
    vehicle_pb2,
)

from .clock import Anchor, check_speed_factor

log = logging.getLogger(__name__)

SCHEMA_VERSION = 1
MAX_ABS_M = 1.0e5  # positions and fire geometry (m)
MAX_SPEED_MPS = 1.0e3
MAX_FORCE_N = 1.0e4
MAX_FRONTS = 256
MAX_VERTICES = 1024
MAX_HORIZON = 10_000
MAX_WAYPOINTS = 1000
MAX_SUBSTEPS = 10_000
MAX_TEXT = 65_536

#: Rejected messages by kind since the process started (process-wide metric).
REJECTIONS: collections.Counter[str] = collections.Counter()

M = TypeVar("M", bound=Message)


class CodecError(ValueError):
    """A message that cannot be used; ``code`` is an ErrorCode value."""

    def __init__(self, code: common_pb2.ErrorCode, message: str):
        super().__init__(message)
        self.code = code


def invalid(message: str) -> CodecError:
    return CodecError(common_pb2.ERROR_CODE_INVALID, message)


def rejected(what: str, err: Exception, logger: logging.Logger = log) -> None:
    """Count and log a rejected message (never raises)."""
    REJECTIONS[what] += 1
    code = getattr(err, "code", common_pb2.ERROR_CODE_INVALID)
    logger.warning(
        "rejected %s: %s", what, err,
        extra={"fields": {"what": what, "code": common_pb2.ErrorCode.Name(code),
                          "rejections": REJECTIONS[what]}},
    )


# -- bytes ↔ messages -----------------------------------------------------------------------------
def full_name(msg_or_cls: Message | type[Message]) -> str:
    return str(msg_or_cls.DESCRIPTOR.full_name)


def encoding_name(msg_or_cls: Message | type[Message]) -> str:
    """Zenoh encoding string: ``application/protobuf;<full type name>``."""
    return f"application/protobuf;{full_name(msg_or_cls)}"


def parse(payload: bytes, cls: type[M], encoding: str | None = None) -> M:
    """Parse ``payload`` as ``cls`` and check its header; raises CodecError."""
    if encoding and encoding.startswith("application/protobuf;") and encoding != encoding_name(cls):
        raise invalid(f"expected {full_name(cls)}, got encoding {encoding}")
    msg = cls()
    try:
        msg.ParseFromString(bytes(payload))
    except (DecodeError, RuntimeError, ValueError) as err:
        raise CodecError(common_pb2.ERROR_CODE_MALFORMED,
                         f"{full_name(cls)} does not parse: {err}") from err
    if "header" in cls.DESCRIPTOR.fields_by_name:
        check_header(msg.header)  # type: ignore[attr-defined]
    return msg


def check_header(h: common_pb2.Header) -> None:
    if h.schema_version != SCHEMA_VERSION:
        raise invalid(f"schema_version {h.schema_version}, this build speaks {SCHEMA_VERSION}")
    if not (math.isfinite(h.sim_time_s) and h.sim_time_s >= 0):
        raise invalid(f"header sim_time_s must be finite and >= 0, got {h.sim_time_s}")
    _text(h.source, "header.source", 256)
    _text(h.vehicle_id, "header.vehicle_id", 256)


class Stamper:
    """Fills headers for one sender: schema version, source, vehicle id, sequence, stamps."""

    def __init__(self, source: str, vehicle_id: str):
        self.source = source
        self.vehicle_id = vehicle_id
        self.seq = 0

    def stamp(self, header: common_pb2.Header, sim_time_s: float = 0.0) -> int:
        self.seq += 1
        header.schema_version = SCHEMA_VERSION
        header.seq = self.seq
        header.source = self.source
        header.vehicle_id = self.vehicle_id
        header.sim_time_s = float(sim_time_s)
        header.wall_time_ns = time.time_ns()
        return self.seq


def error_msg(stamper: Stamper, code: common_pb2.ErrorCode, message: str) -> common_pb2.Error:
    err = common_pb2.Error(code=code, message=message[:MAX_TEXT])
    stamper.stamp(err.header)
    return err


# -- scalar checks --------------------------------------------------------------------------------
def _check_floats(vals: list[float], what: str, bound: float) -> list[float]:
    # plain Python: for the few numbers of a message this beats numpy's per-call overhead
    for v in vals:
        if not math.isfinite(v):
            raise invalid(f"{what} must be finite, got {vals[:8]}")
        if abs(v) > bound:
            raise invalid(f"{what} must lie within ±{bound:g}, got {vals[:8]}")
    return vals


def _finite(values: Iterable[float], what: str, bound: float) -> Array:
    return np.array(_check_floats([float(v) for v in values], what, bound))


def _count(n: int, what: str, limit: int, minimum: int = 0) -> None:
    if not minimum <= n <= limit:
        raise invalid(f"{what}: {n} items, allowed {minimum}..{limit}")


def _text(s: str, what: str, limit: int = MAX_TEXT) -> str:
    if len(s) > limit:
        raise invalid(f"{what} longer than {limit} characters")
    return s


# -- geometry -------------------------------------------------------------------------------------
def rect_to_msg(r: Rect, out: common_pb2.Rect) -> common_pb2.Rect:
    out.center_east_m, out.center_north_m = r.center_x, r.center_y
    out.width_m, out.height_m = r.width, r.height
    return out


def rect_from_msg(m: common_pb2.Rect, what: str = "rect") -> Rect:
    cx, cy, w, h = _check_floats([m.center_east_m, m.center_north_m, m.width_m, m.height_m],
                                 what, MAX_ABS_M)
    if w <= 0 or h <= 0:
        raise invalid(f"{what} sides must be positive, got {w} x {h}")
    return Rect(float(cx), float(cy), float(w), float(h))


def points_to_msg(points: Array, out: Any) -> None:
    """Append (k, 2) points to a repeated Vec2 field."""
    for e, n in np.asarray(points, dtype=float).reshape(-1, 2):
        out.add(east_m=float(e), north_m=float(n))


def points_from_msg(vs: Sequence[common_pb2.Vec2], what: str, limit: int) -> Array:
    _count(len(vs), what, limit)
    flat = _finite((c for v in vs for c in (v.east_m, v.north_m)), what, MAX_ABS_M)
    return flat.reshape(-1, 2)


def packed_to_msg(points: Array, out: Any) -> None:
    """Append (k, c) values row-major to a packed repeated double field."""
    out.extend(np.asarray(points, dtype=float).ravel().tolist())


def packed_from_msg(values: Sequence[float], what: str, width: int, limit: int,
                    bound: float) -> Array:
    """A packed repeated double field as (k, width) rows; checks count, finiteness and range."""
    n = len(values)
    if n % width:
        raise invalid(f"{what}: {n} values is not a multiple of {width}")
    _count(n // width, what, limit)
    return np.array(_check_floats(list(values), what, bound), dtype=float).reshape(-1, width)


def polygon_to_msg(poly: Polytope, out: common_pb2.Polygon) -> common_pb2.Polygon:
    packed_to_msg(poly.vertices, out.vertices_m)
    return out


def polygon_from_msg(m: common_pb2.Polygon, what: str = "polygon") -> Polytope:
    pts = packed_from_msg(m.vertices_m, what, 2, MAX_VERTICES, MAX_ABS_M)
    if len(pts) < 3:
        raise invalid(f"{what} needs at least 3 vertices, got {len(pts)}")
    fast = _ccw_polytope(pts)
    if fast is not None:
        return fast
    try:
        return Polytope.from_vertices(pts)
    except ValueError as err:
        raise invalid(f"{what}: {err}") from err


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
def check_state_values(x: Array, what: str = "state") -> Array:
    x = np.asarray(x, dtype=float)
    if x.shape != (4,):
        raise invalid(f"{what} must have 4 entries, got shape {x.shape}")
    _finite(x[:2], f"{what} position", MAX_ABS_M)
    _finite(x[2:], f"{what} velocity", MAX_SPEED_MPS)
    return x


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
    return _finite((m.east_n, m.north_n), what, MAX_FORCE_N)


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
    _count(len(m.fronts), "fronts", MAX_FRONTS)
    _count(len(m.extinct_hulls), "extinct hulls", MAX_FRONTS)
    if not (math.isfinite(m.substep_s) and m.substep_s > 0):
        raise invalid(f"substep_s must be positive, got {m.substep_s}")
    regions, hulls, ids, born = [], [], [], []
    for i, f in enumerate(m.fronts):
        regions.append(rect_from_msg(f.region, f"front {i} region"))
        hulls.append(polygon_from_msg(f.hull, f"front {i} hull"))
        _check_floats([f.speed_mps, f.direction_rad], f"front {i} speed/direction",
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
    _count(len(m.fronts), "fronts", MAX_FRONTS)
    return tuple(rect_from_msg(f.region, f"front {i} region") for i, f in enumerate(m.fronts))


# -- fire commands --------------------------------------------------------------------------------
def clock_to_msg(anchor: Anchor, out: common_pb2.Clock) -> common_pb2.Clock:
    out.sim_time_s = anchor.sim_time_s
    out.speed_factor = anchor.speed_factor
    out.anchor_wall_ns = anchor.wall_ns
    return out


def clock_from_msg(m: common_pb2.Clock) -> Anchor:
    if not (math.isfinite(m.sim_time_s) and m.sim_time_s >= 0):
        raise invalid(f"clock sim_time_s must be finite and >= 0, got {m.sim_time_s}")
    try:
        factor = check_speed_factor(m.speed_factor)
    except ValueError as err:
        raise invalid(str(err)) from err
    if m.anchor_wall_ns < 0:
        raise invalid("clock anchor must be >= 0")
    return Anchor(float(m.sim_time_s), int(m.anchor_wall_ns), factor)


@dataclass(frozen=True)
class FireCommand:
    mission_id: str
    kind: str  # "reset" or "advance"
    seed: int = 0
    step: int = 0
    substeps: int = 0
    anchor: Anchor | None = None


def fire_command_from_msg(m: fire_pb2.FireCommand) -> FireCommand:
    mission_id = _text(m.mission_id, "mission_id", 256)
    kind = m.WhichOneof("command")
    if kind == "reset":
        return FireCommand(mission_id, "reset", seed=int(m.reset.seed))
    if kind == "advance":
        a = m.advance
        _count(a.substeps, "substeps", MAX_SUBSTEPS)
        return FireCommand(mission_id, "advance", step=int(a.step), substeps=int(a.substeps),
                           anchor=clock_from_msg(a.clock) if a.HasField("clock") else None)
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


@dataclass(frozen=True)
class MissionSpec:
    mission_id: str
    seed: int
    goal: Rect
    area_size_m: float
    waypoints: Array | None  # (k, 2) or None


@dataclass(frozen=True)
class PlanRequest:
    """A validated plan request in core types."""

    seq: int
    mission: MissionSpec
    step: int
    system: int
    objective: Objective
    state: Array
    prev_control: Array
    fires: FireSnapshot
    deadline_s: float
    prepare: bool = False


def plan_request_msg(
    req: PlanRequest, fires: fire_pb2.FireState, stamper: Stamper, sim_time_s: float,
) -> plan_pb2.PlanRequest:
    """Build a PlanRequest; ``fires`` is the FireState the snapshot came from (sent as is)."""
    m = plan_pb2.PlanRequest(step=req.step, system=req.system,
                             objective=objective_to_msg(req.objective), deadline_s=req.deadline_s,
                             prepare=req.prepare)
    stamper.stamp(m.header, sim_time_s)
    ms = m.mission
    ms.mission_id, ms.seed, ms.area_size_m = req.mission.mission_id, req.mission.seed, \
        req.mission.area_size_m
    rect_to_msg(req.mission.goal, ms.goal)
    if req.mission.waypoints is not None:
        points_to_msg(req.mission.waypoints, ms.operator_waypoints)
    stamper.stamp(m.state.header, sim_time_s)
    state_to_msg(req.state, req.step, m.state)
    m.prev_control.east_n, m.prev_control.north_n = (float(v) for v in req.prev_control)
    m.fires.CopyFrom(fires)
    return m


def plan_request_from_msg(m: plan_pb2.PlanRequest) -> PlanRequest:
    if m.system not in (1, 2):
        raise invalid(f"system must be 1 or 2, got {m.system}")
    for sub in ("mission", "state", "fires"):
        if not m.HasField(sub):
            raise invalid(f"plan request without {sub}")
    ms = m.mission
    area = float(ms.area_size_m)
    if not (math.isfinite(area) and 0 < area <= MAX_ABS_M):
        raise invalid(f"area_size_m must be in (0, {MAX_ABS_M:g}], got {area}")
    goal = rect_from_msg(ms.goal, "goal")
    wps = points_from_msg(ms.operator_waypoints, "operator waypoints", MAX_WAYPOINTS)
    if not (math.isfinite(m.deadline_s) and 0 < m.deadline_s <= 3600):
        raise invalid(f"deadline_s must be in (0, 3600], got {m.deadline_s}")
    check_header(m.state.header)
    check_header(m.fires.header)
    objective = objective_from_msg(m.objective)
    assert objective is not None
    return PlanRequest(
        seq=int(m.header.seq),
        mission=MissionSpec(_text(ms.mission_id, "mission_id", 256), int(ms.seed), goal, area,
                            wps if len(wps) else None),
        step=int(m.step), system=int(m.system), objective=objective,
        state=state_from_msg(m.state), prev_control=force_from_msg(m.prev_control, "prev_control"),
        fires=snapshot_from_msg(m.fires), deadline_s=float(m.deadline_s), prepare=m.prepare,
    )


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
        m.info_json = json.dumps(plan.info, default=_json_default, allow_nan=True)[:MAX_TEXT]
    except (TypeError, ValueError):
        m.info_json = "{}"
    return m


def plan_from_msg(m: plan_pb2.Plan, expected_system: int | None = None) -> Plan:
    if m.system not in (1, 2) or (expected_system is not None and m.system != expected_system):
        raise invalid(f"plan from system {m.system}, expected {expected_system}")
    status = status_from_msg(m.status)
    states = packed_from_msg(m.states, "plan states", 4, MAX_HORIZON + 1, MAX_ABS_M)
    controls = packed_from_msg(m.controls, "plan controls", 2, MAX_HORIZON, MAX_FORCE_N)
    if status is PlanStatus.OK and (len(controls) < 1 or len(states) != len(controls) + 1):
        raise invalid(f"an OK plan needs T >= 1 controls and T+1 states, got "
                      f"{len(controls)} / {len(states)}")
    if not (math.isfinite(m.compute_time_s) and m.compute_time_s >= 0):
        raise invalid(f"compute_time_s must be finite and >= 0, got {m.compute_time_s}")
    path = (packed_from_msg(m.path_m, "plan path", 2, MAX_HORIZON * 10, MAX_ABS_M)
            if len(m.path_m) else None)
    try:
        info = json.loads(m.info_json) if m.info_json else {}
    except json.JSONDecodeError:
        info = {}
    return Plan(
        system=int(m.system), status=status, states=states, controls=controls,
        compute_time_s=float(m.compute_time_s),
        objective=objective_from_msg(m.objective, required=False),
        cost=float(m.cost) if m.HasField("cost") else None, path=path,
        message=_text(m.message, "plan message"), info=info if isinstance(info, dict) else {},
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
        raise invalid("a decision has 3 ξ, 3 p and 2 ψ")
    xi = _finite(m.xi, "xi", 1e6)
    p = _finite(m.p, "p", 1.0)
    psi = _finite(m.psi, "psi", 1e6)
    if math.isnan(m.d_t_m) or m.d_t_m < 0:
        raise invalid(f"d_t must be >= 0 (inf allowed), got {m.d_t_m}")
    if m.attention not in (1, 2, 3) or m.system not in (1, 2):
        raise invalid(f"attention {m.attention} / system {m.system} out of range")
    objective = objective_from_msg(m.objective)
    assert objective is not None
    return Decision(t=int(m.step), d_t=float(m.d_t_m), xi=xi, p=p, attention=int(m.attention),
                    psi=psi, system=int(m.system), objective=objective)


def waypoints_msg(points: Array | None, stamper: Stamper) -> vehicle_pb2.OperatorWaypoints:
    m = vehicle_pb2.OperatorWaypoints()
    stamper.stamp(m.header)
    if points is not None:
        points_to_msg(points, m.waypoints)
    return m


def waypoints_from_msg(m: vehicle_pb2.OperatorWaypoints) -> Array | None:
    pts = points_from_msg(m.waypoints, "operator waypoints", MAX_WAYPOINTS)
    return pts if len(pts) else None


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
    return _finite(pts.ravel(), "waypoints", MAX_ABS_M).reshape(-1, 2)


# -- MAVLink --------------------------------------------------------------------------------------
#: SET_POSITION_TARGET_LOCAL_NED.type_mask: use position and velocity, ignore the rest.
TYPE_MASK_POS_VEL = 3520
#: ... position only.
TYPE_MASK_POS = 3576
MAV_FRAME_LOCAL_NED = 1


def state_to_ned(x: Array, altitude_m: float) -> tuple[float, float, float, float, float, float]:
    """Core state (east, north, v_east, v_north) → NED (x, y, z, vx, vy, vz)."""
    x = check_state_values(x)
    return (float(x[1]), float(x[0]), -float(altitude_m), float(x[3]), float(x[2]), 0.0)


def state_from_ned(n: float, e: float, vn: float, ve: float) -> Array:
    """NED north/east position and velocity → core state; raises CodecError if out of range."""
    return check_state_values(np.array([e, n, ve, vn], dtype=float), "MAVLink state")


def setpoint_from_mavlink(msg: Any) -> Array:
    """A SET_POSITION_TARGET_LOCAL_NED as the core target state [p_e, p_n, v_e, v_n].

    Accepts LOCAL_NED with type_mask 3520 (position + velocity) or 3576
    (position only; velocity target 0).
    """
    if msg.coordinate_frame != MAV_FRAME_LOCAL_NED:
        raise invalid(f"setpoint frame {msg.coordinate_frame}, only LOCAL_NED (1) is supported")
    if msg.type_mask == TYPE_MASK_POS_VEL:
        return state_from_ned(msg.x, msg.y, msg.vx, msg.vy)
    if msg.type_mask == TYPE_MASK_POS:
        return state_from_ned(msg.x, msg.y, 0.0, 0.0)
    raise invalid(f"setpoint type_mask {msg.type_mask}: only 3520 and 3576 are supported")
