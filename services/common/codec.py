"""The one place that converts messages (protobuf, MAVLink) to core types and back, and validates.

Every decoder checks what the core would otherwise trust: the schema version,
finite numbers, ranges (positions within ``MAX_ABS_M`` of the origin, speeds,
forces) and sizes (fronts, hull vertices, horizon). A bad message raises
:class:`CodecError` (a ValueError) with a code (MALFORMED: does not parse;
INVALID: parses but fails validation) and a ``reason`` from the closed set
:class:`Reason` (why, for counters); services call :func:`rejected`, which
counts it per input key and reason in :data:`REJECTED` (served as each
service's status, services/common/bus.py) and logs one line per rejection,
rate-limited so a flood cannot fill the disk. Services never crash on input.

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
import re
import threading
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import Any, TypeVar, cast

import numpy as np
from google.protobuf.message import DecodeError, Message

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
from services.msgs import (
    common_pb2,
    fire_pb2,
    plan_pb2,
    supervisor_pb2,
    vehicle_pb2,
)

from . import mav
from .clock import Anchor, check_speed_factor

log = logging.getLogger(__name__)

SCHEMA_VERSION = 1
MAX_PAYLOAD_BYTES = 8 * 1024 * 1024  # any one message on the bus (a mission's are ≪ 1 MB)
MAX_ABS_M = 1.0e5  # positions and fire geometry (m)
#: A plan request's positions, goal, waypoints and fires lie within the mission's area
#: [0, A]² grown by this many A on every side: "far outside the area" is rejected.
AREA_MARGIN = 1.0
MAX_SPEED_MPS = 1.0e3
MAX_FORCE_N = 1.0e4
MAX_FRONTS = 256
MAX_VERTICES = 1024
MAX_HORIZON = 10_000
MAX_WAYPOINTS = 1000
MAX_SUBSTEPS = 10_000
MAX_SUBSTEP_S = 60.0  # T_f (s)
MAX_FORECAST_CELLS = 1 << 20  # cells of one slice of the occupancy forecast's grid
MAX_FORECAST_SLICES = 4096
MAX_TEXT = 65_536
MIN_SPEED_FACTOR = 1.0e-3  # a paced clock: at least 1 simulated ms per wall s
MAX_CLOCK_SKEW_S = 86_400.0  # a clock anchor within a day of the receiver's wall clock
#: Encodings a payload may carry besides ``application/protobuf;<its type>``
#: (a sender that does not name the type, e.g. a raw ``zenoh/bytes`` query).
NEUTRAL_ENCODINGS = frozenset({"", "zenoh/bytes", "application/octet-stream",
                               "application/protobuf"})

M = TypeVar("M", bound=Message)


class Reason(StrEnum):
    """Why an input was rejected: the closed set the counters use."""

    MALFORMED = "malformed"            # does not parse
    TOO_LARGE = "too_large"            # payload over MAX_PAYLOAD_BYTES
    WRONG_TYPE = "wrong_type"          # encoding names another message type
    SCHEMA_VERSION = "schema_version"  # header from another version of the contract
    NOT_FINITE = "not_finite"          # NaN or ±inf where a number is needed
    OUT_OF_RANGE = "out_of_range"      # a number or coordinate outside its range or the area
    SIZE = "size"                      # too many or too few items, a wrong length
    INVALID = "invalid"                # anything else: missing field, unknown enum, geometry...
    OVERFLOW = "overflow"              # dropped: the service's inbox was full
    # MAVLink links of the vehicle (services/uavsim): frames that are not usable MAVLink 2
    BAD_CRC = "bad_crc"                # a frame whose checksum does not match
    UNKNOWN_MESSAGE = "unknown_message"  # a message id the dialect does not define
    MAVLINK1 = "mavlink1"              # a MAVLink 1 frame (only its HEARTBEAT is accepted)
    WRONG_TARGET = "wrong_target"      # addressed to another system or component
    UNSIGNED = "unsigned"              # unsigned or wrongly signed on a signed link


class CodecError(ValueError):
    """A message that cannot be used; ``code`` is an ErrorCode value, ``reason`` a Reason."""

    def __init__(self, code: common_pb2.ErrorCode, message: str,
                 reason: Reason = Reason.INVALID):
        super().__init__(message)
        self.code = code
        self.reason = reason


def invalid(message: str, reason: Reason = Reason.INVALID) -> CodecError:
    return CodecError(common_pb2.ERROR_CODE_INVALID, message, reason)


class Rejections:
    """Rejected inputs of this process per key and :class:`Reason` (thread-safe).

    ``key`` is the Zenoh key the input came in on; a caller that does not
    know it passes a label (the message kind), which :meth:`alias` can map to
    the key. At most ``max_keys`` keys are kept, the rest count under
    ``"(other)"``. Log lines are a token bucket (``log_burst`` lines, then
    ``log_per_s`` a second); the lines it holds back are counted and reported
    on the next line that is written.
    """

    OTHER = "(other)"

    def __init__(self, max_keys: int = 256, log_burst: float = 20.0, log_per_s: float = 2.0):
        self.max_keys = max_keys
        self.log_burst = log_burst
        self.log_per_s = log_per_s
        self._lock = threading.Lock()
        self._counts: dict[str, collections.Counter[str]] = {}
        self._aliases: dict[str, str] = {}
        #: rejections by the label callers passed (the message kind), as before keys existed
        self.by_label: collections.Counter[str] = collections.Counter()
        self._tokens = log_burst
        self._refilled = time.monotonic()
        self.suppressed = 0  # log lines held back since the last one written
        self.suppressed_total = 0

    def alias(self, label: str, key: str) -> None:
        """Count rejections reported under ``label`` as rejections on ``key``."""
        with self._lock:
            self._aliases[label] = key

    def add(self, key: str, reason: str, label: str | None = None) -> tuple[str, int, int]:
        """Count one rejection; returns (key counted under, its total, lines to log: 0 or
        1 + the number held back before it)."""
        with self._lock:
            self.by_label[label or key] += 1
            key = self._aliases.get(key, key)
            if key not in self._counts and len(self._counts) >= self.max_keys:
                key = self.OTHER
            counts = self._counts.setdefault(key, collections.Counter())
            counts[reason] += 1
            now = time.monotonic()
            self._tokens = min(self.log_burst,
                               self._tokens + (now - self._refilled) * self.log_per_s)
            self._refilled = now
            if self._tokens < 1.0:
                self.suppressed += 1
                self.suppressed_total += 1
                return key, sum(counts.values()), 0
            self._tokens -= 1.0
            held, self.suppressed = self.suppressed, 0
            return key, sum(counts.values()), 1 + held

    def snapshot(self) -> dict[str, dict[str, int]]:
        """{key: {reason: count}} (a copy)."""
        with self._lock:
            return {k: dict(c) for k, c in self._counts.items()}

    def total(self) -> int:
        with self._lock:
            return sum(sum(c.values()) for c in self._counts.values())

    def clear(self) -> None:
        with self._lock:
            self._counts.clear()
            self.by_label.clear()


#: Rejected inputs of this process per key and reason (each service serves it as its status);
#: ``REJECTED.by_label``: by kind (the label passed to :func:`rejected`) since the process started.
REJECTED = Rejections()


def rejected(what: str, err: Exception, logger: logging.Logger = log, key: str | None = None,
             reason: str | None = None) -> None:
    """Count a rejected input under ``key`` (default: ``what``, or its alias) and log it.

    Never raises. The log line is rate-limited (see :class:`Rejections`);
    the counters are exact.
    """
    try:
        why = str(reason or getattr(err, "reason", Reason.INVALID))
        counted, n, lines = REJECTED.add(key or what, why, what)
        if lines:
            code = getattr(err, "code", common_pb2.ERROR_CODE_INVALID)
            logger.warning(
                "rejected %s on %s (%s): %s", what, counted, why, str(err)[:500],
                extra={"fields": {"what": what, "key": counted, "reason": why,
                                  "code": common_pb2.ErrorCode.Name(code),
                                  "rejections": n, "suppressed_before": lines - 1}},
            )
    except Exception:  # counting must never take a service down
        log.exception("could not count a rejection")


# -- bytes ↔ messages -----------------------------------------------------------------------------
def full_name(msg_or_cls: Message | type[Message]) -> str:
    return str(msg_or_cls.DESCRIPTOR.full_name)


def encoding_name(msg_or_cls: Message | type[Message]) -> str:
    """Zenoh encoding string: ``application/protobuf;<full type name>``."""
    return f"application/protobuf;{full_name(msg_or_cls)}"


def parse(payload: bytes, cls: type[M], encoding: str | None = None,
          max_bytes: int = MAX_PAYLOAD_BYTES) -> M:
    """Parse ``payload`` as ``cls`` and check its header; raises CodecError.

    Rejects a payload over ``max_bytes``, an ``encoding`` other than
    ``application/protobuf;<cls>`` or a neutral one (:data:`NEUTRAL_ENCODINGS`),
    bytes that do not parse, and a header of another schema version.
    """
    if len(payload) > max_bytes:
        raise invalid(f"{full_name(cls)} payload of {len(payload)} bytes exceeds {max_bytes}",
                      Reason.TOO_LARGE)
    if encoding and encoding not in NEUTRAL_ENCODINGS and encoding != encoding_name(cls):
        raise invalid(f"expected {full_name(cls)}, got encoding {encoding[:200]}",
                      Reason.WRONG_TYPE)
    msg = cls()
    try:
        msg.ParseFromString(bytes(payload))
    except (DecodeError, RuntimeError, ValueError, RecursionError) as err:
        raise CodecError(common_pb2.ERROR_CODE_MALFORMED,
                         f"{full_name(cls)} does not parse: {err}", Reason.MALFORMED) from err
    if "header" in cls.DESCRIPTOR.fields_by_name:
        check_header(msg.header)  # type: ignore[attr-defined]
    return msg


def check_header(h: common_pb2.Header) -> None:
    if h.schema_version != SCHEMA_VERSION:
        raise invalid(f"schema_version {h.schema_version}, this build speaks {SCHEMA_VERSION}",
                      Reason.SCHEMA_VERSION)
    _check_floats([h.sim_time_s], "header sim_time_s", 1e12)
    if h.sim_time_s < 0:
        raise invalid(f"header sim_time_s must be >= 0, got {h.sim_time_s}", Reason.OUT_OF_RANGE)
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
            raise invalid(f"{what} must be finite, got {vals[:8]}", Reason.NOT_FINITE)
        if abs(v) > bound:
            raise invalid(f"{what} must lie within ±{bound:g}, got {vals[:8]}",
                          Reason.OUT_OF_RANGE)
    return vals


def _finite(values: Iterable[float], what: str, bound: float) -> Array:
    return np.array(_check_floats([float(v) for v in values], what, bound))


def _count(n: int, what: str, limit: int, minimum: int = 0) -> None:
    if not minimum <= n <= limit:
        raise invalid(f"{what}: {n} items, allowed {minimum}..{limit}", Reason.SIZE)


def _text(s: str, what: str, limit: int = MAX_TEXT) -> str:
    if len(s) > limit:
        raise invalid(f"{what} longer than {limit} characters", Reason.SIZE)
    return s


def _in_box(points: Array, lo: float, hi: float, what: str) -> None:
    """Every (east, north) row of ``points`` lies in [lo, hi]² (m)."""
    if len(points) and (points.min() < lo or points.max() > hi):
        raise invalid(f"{what} lies outside [{lo:g}, {hi:g}] m (far outside the area)",
                      Reason.OUT_OF_RANGE)


# -- geometry -------------------------------------------------------------------------------------
def rect_to_msg(r: Rect, out: common_pb2.Rect) -> common_pb2.Rect:
    out.center_east_m, out.center_north_m = r.center_x, r.center_y
    out.width_m, out.height_m = r.width, r.height
    return out


def rect_from_msg(m: common_pb2.Rect, what: str = "rect") -> Rect:
    cx, cy, w, h = _check_floats([m.center_east_m, m.center_north_m, m.width_m, m.height_m],
                                 what, MAX_ABS_M)
    if w <= 0 or h <= 0:
        raise invalid(f"{what} sides must be positive, got {w} x {h}", Reason.OUT_OF_RANGE)
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
        raise invalid(f"{what}: {n} values is not a multiple of {width}", Reason.SIZE)
    _count(n // width, what, limit)
    return np.array(_check_floats(list(values), what, bound), dtype=float).reshape(-1, width)


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
def check_state_values(x: Array, what: str = "state") -> Array:
    x = np.asarray(x, dtype=float)
    if x.shape != (4,):
        raise invalid(f"{what} must have 4 entries, got shape {x.shape}", Reason.SIZE)
    e, n, ve, vn = x.tolist()  # plain floats: checked at 10 Hz per vehicle, both ways
    _check_floats([e, n], f"{what} position", MAX_ABS_M)
    _check_floats([ve, vn], f"{what} velocity", MAX_SPEED_MPS)
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
    _check_floats([m.substep_s], "substep_s", MAX_SUBSTEP_S)
    if m.substep_s <= 0:
        raise invalid(f"substep_s must be positive, got {m.substep_s}", Reason.OUT_OF_RANGE)
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
    _check_floats([m.substep_s], "substep_s", MAX_SUBSTEP_S)
    if m.substep_s <= 0:
        raise invalid(f"substep_s must be positive, got {m.substep_s}", Reason.OUT_OF_RANGE)
    origin = _finite((g.origin.east_m, g.origin.north_m), "grid origin", MAX_ABS_M)
    _check_floats([g.resolution_m], "resolution_m", MAX_ABS_M)
    if g.resolution_m <= 0:
        raise invalid(f"resolution_m must be positive, got {g.resolution_m}",
                      Reason.OUT_OF_RANGE)
    cells = int(g.rows) * int(g.cols)
    if not 0 < cells <= MAX_FORECAST_CELLS:
        raise invalid(f"grid of {g.rows} x {g.cols} cells, allowed 1..{MAX_FORECAST_CELLS}",
                      Reason.SIZE)
    _count(len(g.horizons), "forecast horizons", MAX_FORECAST_SLICES, minimum=1)
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
    _check_floats([g.horizon_s], "horizon_s", MAX_SUBSTEPS * MAX_SUBSTEP_S)
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
    _check_floats([m.sim_time_s], "clock sim_time_s", 1e12)
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
    name = _text(m.scenario, "scenario", 64)
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
    mission_id = _text(m.mission_id, "mission_id", 256)
    kind = m.WhichOneof("command")
    if kind == "reset":
        area = _check_floats([m.reset.area_size_m], "area_size_m", MAX_ABS_M)[0]
        if area < 0:
            raise invalid(f"area_size_m must be >= 0, got {area}", Reason.OUT_OF_RANGE)
        readings = (tuple(fire_readings_from_msg(m.reset.readings).items())
                    if m.reset.HasField("readings") else None)
        return FireCommand(mission_id, "reset", seed=int(m.reset.seed), area_size_m=area,
                           readings=readings, scenario=fire_scenario_from_msg(m.reset))
    if kind == "advance":
        a = m.advance
        _count(a.substeps, "substeps", MAX_SUBSTEPS)
        clear = _check_floats([a.keep_out_m], "keep_out_m", MAX_ABS_M)[0]
        if clear < 0:
            raise invalid(f"keep_out_m must be >= 0, got {clear}", Reason.OUT_OF_RANGE)
        keep_out = None
        if clear > 0:
            keep_out = (_finite((a.keep_out.east_m, a.keep_out.north_m), "keep_out",
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
    mission_id = _text(m.mission_id, "mission_id", 256)
    if not mission_id:
        raise invalid("mission spec without a mission_id")
    for sub in ("goal", "start", "dynamics"):
        if not m.HasField(sub):
            raise invalid(f"mission spec without {sub}")
    area, d_safe, clear = _check_floats([m.area_size_m, m.d_safe_m, m.clearance_m],
                                        "area/d_safe/clearance", MAX_ABS_M)
    d = m.dynamics
    dyn = _check_floats([d.dt_s, d.zeta, d.mass_kg, d.u_max_n, d.v_max_mps], "dynamics",
                        MAX_FORCE_N)
    speed_limit = speed_limit_from_msg(d.speed_limit)
    start = _finite((m.start.east_m, m.start.north_m), "start", MAX_ABS_M)
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
        _text(m.mission_id, "mission_id", 256), None)
    if m.mission_id and m.mission_id != mission_id:
        raise invalid(f"mission_id {m.mission_id!r} differs from the spec's {mission_id!r}")
    if not mission_id:
        raise invalid("plan request without a mission_id")
    _check_floats([m.deadline_s], "deadline_s", 3600)
    if m.deadline_s <= 0:
        raise invalid(f"deadline_s must be in (0, 3600], got {m.deadline_s}", Reason.OUT_OF_RANGE)
    check_header(m.state.header)
    objective = objective_from_msg(m.objective)
    assert objective is not None
    _count(len(m.obstacles), "obstacles", MAX_FRONTS * 2)
    obstacles = tuple(polygon_from_msg(p, f"obstacle {i}") for i, p in enumerate(m.obstacles))
    req = PlanRequest(
        seq=int(m.header.seq), mission_id=mission_id, step=int(m.step), system=int(m.system),
        objective=objective, state=state_from_msg(m.state),
        prev_control=force_from_msg(m.prev_control, "prev_control"), obstacles=obstacles,
        deadline_s=float(m.deadline_s), waypoints_revision=int(m.waypoints_revision),
        prepare=m.prepare, spec=spec, method=_text(m.method, "method", 64),
    )
    if spec is not None:
        check_in_area(req, spec)
    return req


def check_in_area(req: PlanRequest, spec: MissionSpec) -> None:
    """Everything in a request lies near the mission's area [0, A]²: the state and the
    obstacles within ``AREA_MARGIN``·A of it (anything farther is not this mission's)."""
    area = spec.area_size_m
    lo, hi = -AREA_MARGIN * area, (1 + AREA_MARGIN) * area
    _in_box(req.state[None, :2], lo, hi, "the vehicle state")
    for i, h in enumerate(req.obstacles):
        _in_box(h.vertices, lo, hi, f"obstacle {i}")


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
    _check_floats([m.compute_time_s], "compute_time_s", 1e6)
    if m.compute_time_s < 0:
        raise invalid(f"compute_time_s must be >= 0, got {m.compute_time_s}",
                      Reason.OUT_OF_RANGE)
    _check_floats([m.service_time_s], "service_time_s", 1e6)
    if m.service_time_s < 0:
        raise invalid(f"service_time_s must be >= 0, got {m.service_time_s}",
                      Reason.OUT_OF_RANGE)
    if m.HasField("cost"):
        _check_floats([m.cost], "plan cost", math.inf)
    path = (packed_from_msg(m.path_m, "plan path", 2, MAX_HORIZON * 10, MAX_ABS_M)
            if len(m.path_m) else None)
    info_json = _text(m.info_json, "plan info_json")
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
        message=_text(m.message, "plan message"), info=info,
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
    xi = _finite(m.xi, "xi", 1e6)
    p = _finite(m.p, "p", 1.0)
    psi = _finite(m.psi, "psi", 1e6)
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
    return Waypoints(_text(m.mission_id, "mission_id", 256), int(m.revision),
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
    return _finite(pts.ravel(), "waypoints", MAX_ABS_M).reshape(-1, 2)


# -- MAVLink (its constants: services/common/mav.py) ---------------------------------------------
#: A setpoint may lie at most this fraction of the area outside it (a braking target near the
#: edge can overshoot; planners keep their plans inside).
SETPOINT_AREA_MARGIN = 0.1
MAX_SETPOINT_SPEED_MPS = 100.0
MAX_SETPOINT_ALT_M = 10_000.0
#: The longest a setpoint may be stamped ahead of the vehicle's clock (s of simulated time):
#: one step is ΔT plus the planning interval, at most the supervisor's plan deadline.
MAX_SETPOINT_LEAD_S = 600.0
#: The largest UDP datagram a vehicle link parses (one MAVLink 2 frame is at most 280 bytes;
#: a sender may pack a few); larger ones are rejected unread (``too_large``).
MAX_MAVLINK_DATAGRAM = 4096


def state_to_ned(x: Array, altitude_m: float) -> tuple[float, float, float, float, float, float]:
    """Core state (east, north, v_east, v_north) → NED (x, y, z, vx, vy, vz)."""
    x = check_state_values(x)
    return (float(x[1]), float(x[0]), -float(altitude_m), float(x[3]), float(x[2]), 0.0)


def state_from_ned(n: float, e: float, vn: float, ve: float) -> Array:
    """NED north/east position and velocity → core state; raises CodecError if out of range."""
    return check_state_values(np.array([e, n, ve, vn], dtype=float), "MAVLink state")


def setpoint_from_mavlink(msg: Any, area_size_m: float | None = None,
                          lead_ms: int | None = None) -> Array:
    """A SET_POSITION_TARGET_LOCAL_NED as the core target state [p_e, p_n, v_e, v_n].

    Accepts LOCAL_NED with type_mask 3520 (position + velocity) or 3576
    (position only; velocity target 0). With ``area_size_m`` the position must
    lie in the area [0, A]² grown by :data:`SETPOINT_AREA_MARGIN` × A, the
    velocity within :data:`MAX_SETPOINT_SPEED_MPS` per axis and the altitude
    (``-z``) within [0, :data:`MAX_SETPOINT_ALT_M`]; with ``lead_ms`` (the
    setpoint's ``time_boot_ms`` minus the vehicle's clock) it must be due at
    most :data:`MAX_SETPOINT_LEAD_S` ahead. Raises CodecError (reasons
    ``invalid``, ``not_finite``, ``out_of_range``).
    """
    if msg.coordinate_frame != mav.MAV_FRAME_LOCAL_NED:
        raise invalid(f"setpoint frame {msg.coordinate_frame}, only LOCAL_NED "
                      f"({mav.MAV_FRAME_LOCAL_NED}) is supported")
    if msg.type_mask == mav.TYPE_MASK_POS_VEL:
        x = state_from_ned(msg.x, msg.y, msg.vx, msg.vy)
    elif msg.type_mask == mav.TYPE_MASK_POS:
        x = state_from_ned(msg.x, msg.y, 0.0, 0.0)
    else:
        raise invalid(f"setpoint type_mask {msg.type_mask}: only {mav.TYPE_MASK_POS_VEL} and "
                      f"{mav.TYPE_MASK_POS} are supported")
    if area_size_m is not None:
        _finite([msg.z], "setpoint z", MAX_SETPOINT_ALT_M)
        margin = SETPOINT_AREA_MARGIN * area_size_m
        if not (np.all(x[:2] >= -margin) and np.all(x[:2] <= area_size_m + margin)):
            raise invalid(f"setpoint position ({x[0]:.6g}, {x[1]:.6g}) m is outside the area "
                          f"[0, {area_size_m:g}]² grown by {margin:g} m", Reason.OUT_OF_RANGE)
        if np.any(np.abs(x[2:]) > MAX_SETPOINT_SPEED_MPS) or not -msg.z >= 0.0:
            raise invalid(f"setpoint velocity ({x[2]:.6g}, {x[3]:.6g}) m/s or altitude "
                          f"{-msg.z:.6g} m out of range", Reason.OUT_OF_RANGE)
    if lead_ms is not None and lead_ms > MAX_SETPOINT_LEAD_S * 1000:
        raise invalid(f"setpoint due {lead_ms / 1000:.6g} s after the vehicle's clock "
                      f"(at most {MAX_SETPOINT_LEAD_S:g} s)", Reason.OUT_OF_RANGE)
    return x



def mavlink_frame_reason(bad_data_reason: str) -> Reason:
    """The :class:`Reason` for a frame pymavlink could not decode (its BAD_DATA ``reason``)."""
    why = bad_data_reason.lower()
    if "signature" in why or "signed" in why:
        return Reason.UNSIGNED
    if "crc" in why:
        return Reason.BAD_CRC
    return Reason.MALFORMED


def check_finite_fields(msg: Any, names: Iterable[str], what: str) -> None:
    """Raise CodecError (``not_finite``) if any of the float fields ``names`` is NaN or ±inf."""
    for name in names:
        value = getattr(msg, name)
        if not math.isfinite(value):
            raise invalid(f"{what}.{name} is {value}", Reason.NOT_FINITE)


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
    _check_floats([m.step_time_s], "step_time_s", 1e12)
    if m.step_time_s < 0:
        raise invalid(f"step_time_s must be >= 0, got {m.step_time_s}", Reason.OUT_OF_RANGE)
    if m.flown_system not in (0, 1, 2):
        raise invalid(f"flown_system {m.flown_system} out of range", Reason.OUT_OF_RANGE)
    _count(len(m.plans), "plans", 2)
    got: dict[int, PlanView] = {}
    for sp in m.plans:
        if sp.system not in (1, 2) or sp.system in got:
            raise invalid(f"plan of system {sp.system} (once each of 1 and 2)",
                          Reason.OUT_OF_RANGE)
        status = _text(sp.status, "plan status", MAX_TEXT)
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
        _text(getattr(m, name), f"mission event {name}", limit)
    _check_floats([m.position.east_m, m.position.north_m, m.mission_time_s],
                  "mission event position/time", MAX_ABS_M)
    if m.flown_system not in (0, 1, 2):
        raise invalid(f"flown_system {m.flown_system} out of range", Reason.OUT_OF_RANGE)
    return m
