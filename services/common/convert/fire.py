"""fire.proto ↔ core types: the fire state, its occupancy forecast and the EWS's commands.

Decoders check counts, finiteness and ranges (services/common/limits.py) and raise
:class:`~services.common.rejections.CodecError` for a bad message; a reset's
mission configuration is decoded by services/common/convert/config.py. In 3-D each front
carries its cuboid's top and its hull's (``top_m``, ``hull_top_m``) and each extinct hull
its top (``extinct_hull_tops_m``): every front has both or none, each top lies within
[0, MAX_ALTITUDE_M] m, positive, the hull's at least the cuboid's; a 2-D state has none.
"""

from __future__ import annotations

import hashlib
import math
import zlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.ports import KeepOut
from dualpilot.model.fire import FireFront, FireSnapshot, Region
from dualpilot.model.forecast import OccupancyForecast
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.model.prism import Cuboid
from services.common.clock import Anchor, SimClock
from services.common.convert.common import (
    clock_from_msg,
    polygon_from_msg,
    polygon_to_msg,
    rect_from_msg,
    rect_to_msg,
    sim_clock_to_msg,
)
from services.common.convert.config import config_from_msg, config_to_msg
from services.common.limits import (
    MAX_ABS_M,
    MAX_FORECAST_CELLS,
    MAX_FORECAST_SLICES,
    MAX_FRONTS,
    MAX_SPEED_MPS,
    MAX_SUBSTEP_S,
    MAX_SUBSTEPS,
    check_altitudes,
    check_count,
    check_floats,
    check_int,
    check_text,
    finite,
)
from services.common.rejections import Reason, invalid
from services.common.wire import Stamper, check_header
from services.msgs import fire_pb2


def fire_state_msg(
    fronts: Sequence[FireFront], extinct_hulls: Sequence[Polytope], step: int, substeps_done: int,
    substep_s: float, stamper: Stamper, sim_time_s: float,
    extinct_tops: Sequence[float] = (),
) -> fire_pb2.FireState:
    """The EWS's FireField as a FireState message (in 3-D with the fronts' tops and
    ``extinct_tops``, one per extinct hull)."""
    msg = fire_pb2.FireState(step=step, substeps_done=substeps_done, substep_s=substep_s)
    stamper.stamp(msg.header, sim_time_s)
    for f in fronts:
        fm = msg.fronts.add(front_id=f.front_id, born_step=f.born_step, speed_mps=f.speed_mps,
                            direction_rad=f.direction_rad)
        rect_to_msg(f.region, fm.region)
        polygon_to_msg(f.hull, fm.hull)
        if f.top_m is not None:
            fm.top_m = float(f.top_m)
        if f.hull_top_m is not None:
            fm.hull_top_m = float(f.hull_top_m)
    for h in extinct_hulls:
        polygon_to_msg(h, msg.extinct_hulls.add())
    msg.extinct_hull_tops_m.extend(float(t) for t in extinct_tops)
    return msg


def _front_tops(m: fire_pb2.FireState) -> tuple[tuple[float, ...], tuple[float, ...]] | None:
    """(each front's top, each front's hull top then each extinct hull's) of a 3-D state,
    None for a planar one; CodecError for a top out of range, or when only some carry them."""
    tops = [f.top_m for f in m.fronts if f.HasField("top_m")]
    hull_tops = [f.hull_top_m for f in m.fronts if f.HasField("hull_top_m")]
    extinct = list(m.extinct_hull_tops_m)
    given = [*tops, *hull_tops, *extinct]
    if not given:
        return None
    check_altitudes(given, "fire tops")
    if any(t <= 0.0 for t in given):
        raise invalid("a fire's top must lie above the ground (> 0 m)", Reason.OUT_OF_RANGE)
    if len(tops) != len(m.fronts) or len(hull_tops) != len(m.fronts):
        raise invalid("a fire state's fronts carry top_m and hull_top_m all, or none",
                      Reason.SIZE)
    if len(extinct) != len(m.extinct_hulls):
        raise invalid(f"{len(extinct)} extinct hull tops for {len(m.extinct_hulls)} extinct "
                      f"hulls", Reason.SIZE)
    if any(h < t for t, h in zip(tops, hull_tops, strict=True)):
        raise invalid("a front's hull top lies below its cuboid's top", Reason.OUT_OF_RANGE)
    return tuple(tops), tuple(hull_tops) + tuple(extinct)


def snapshot_from_msg(m: fire_pb2.FireState) -> FireSnapshot:
    """A FireState as the core's FireSnapshot (front hulls first, then extinct hulls; in 3-D
    with their tops)."""
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
    tops = _front_tops(m)
    return FireSnapshot(regions=tuple(regions), hulls=tuple(hulls), front_ids=tuple(ids),
                        born_steps=tuple(born), tops_m=() if tops is None else tops[0],
                        hull_tops_m=() if tops is None else tops[1])


def regions_from_msg(m: fire_pb2.FireState) -> tuple[Rect, ...]:
    """Only the current regions of a FireState (validated, their tops too), as rectangles."""
    check_count(len(m.fronts), "fronts", MAX_FRONTS)
    rects = tuple(rect_from_msg(f.region, f"front {i} region") for i, f in enumerate(m.fronts))
    _front_tops(m)
    return rects


def current_from_msg(m: fire_pb2.FireState) -> tuple[Region, ...]:
    """The current regions of a FireState as the step measures them (validated): rectangles,
    or in 3-D the cuboids C_t over them (:meth:`FireSnapshot.current`)."""
    rects = regions_from_msg(m)
    tops = _front_tops(m)
    if tops is None:
        return rects
    return tuple(Cuboid(r, t) for r, t in zip(rects, tops[0], strict=True))


def occupancy_to_msg(fc: OccupancyForecast, out: fire_pb2.OccupancyGrid,
                     compress: bool = True) -> fire_pb2.OccupancyGrid:
    """The core's occupancy forecast as an OccupancyGrid (its levels, byte for byte; each
    slice zlib-compressed unless ``compress`` is False)."""
    out.origin.east_m, out.origin.north_m = fc.origin_m
    out.resolution_m = fc.resolution_m
    out.rows, out.cols = fc.shape
    out.horizons.extend(fc.horizons)
    raw = [np.ascontiguousarray(lv).tobytes() for lv in fc.layers]
    out.probabilities.extend([zlib.compress(b, 1) for b in raw] if compress else raw)
    out.encoding = fire_pb2.SLICE_ENCODING_ZLIB if compress else fire_pb2.SLICE_ENCODING_RAW
    out.horizon_s = fc.max_substeps * fc.substep_s
    out.substeps_per_step = fc.substeps_per_step
    return out


#: a forecast grid's digest (bytes: BLAKE2b-128 of its deterministic serialized form)
DIGEST_BYTES = 16


def grid_digest(grid: fire_pb2.OccupancyGrid) -> bytes:
    """BLAKE2b-128 of ``grid``'s deterministic serialized form: the same grid, the same
    digest, whoever decoded it (a plan request names a forecast by it)."""
    return hashlib.blake2b(grid.SerializeToString(deterministic=True),
                           digest_size=DIGEST_BYTES).digest()


#: where a forecast keeps its wire form (OccupancyForecast.memo): encoded once a forecast,
#: however many plan requests carry it (the stack keeps the EWS's own message there)
WIRE_GRID = "wire_grid"


def wire_grid(fc: OccupancyForecast) -> fire_pb2.OccupancyGrid:
    """``fc`` as an OccupancyGrid, encoded on first use and kept in its memo."""
    grid = fc.memo.get(WIRE_GRID)
    if grid is None:
        grid = occupancy_to_msg(fc, fire_pb2.OccupancyGrid())
        fc.memo[WIRE_GRID] = grid
    return grid


def occupancy_from_msg(m: fire_pb2.FireForecast) -> OccupancyForecast | None:
    """A FireForecast's grid as the core's OccupancyForecast (None when it carries none);
    :func:`grid_from_msg` says what is rejected."""
    check_header(m.header)
    if not m.HasField("occupancy"):
        return None
    return grid_from_msg(m.occupancy, m.substep_s, int(m.substeps_done))


def _slice_bytes(data: bytes, encoding: int, cells: int, i: int) -> bytes:
    """Slice ``i``'s rows × cols bytes; a zlib slice is inflated to at most ``cells`` bytes."""
    if encoding == fire_pb2.SLICE_ENCODING_RAW:
        out = data
    elif encoding == fire_pb2.SLICE_ENCODING_ZLIB:
        inflate = zlib.decompressobj()
        try:
            out = inflate.decompress(data, cells)
        except zlib.error as err:
            raise invalid(f"slice {i} is not zlib data: {err}") from err
        if inflate.unconsumed_tail:
            raise invalid(f"slice {i} inflates to more than the grid's {cells} bytes",
                          Reason.SIZE)
        if not inflate.eof:
            raise invalid(f"slice {i}'s zlib stream is cut short after {len(out)} of "
                          f"{cells} bytes", Reason.SIZE)
        if inflate.unused_data:
            raise invalid(f"slice {i} has {len(inflate.unused_data)} bytes after its zlib "
                          "stream", Reason.SIZE)
    else:
        raise invalid(f"slice encoding {encoding} is not one of RAW, ZLIB", Reason.OUT_OF_RANGE)
    if len(out) != cells:
        raise invalid(f"slice {i} has {len(out)} bytes, the grid {cells}", Reason.SIZE)
    return out


def grid_from_msg(g: fire_pb2.OccupancyGrid, substep_s: float,
                  issued_substep: int) -> OccupancyForecast:
    """An OccupancyGrid as the core's OccupancyForecast, issued after ``issued_substep``
    sub-steps of T_f = ``substep_s``.

    Rejected: a grid without cells or with more than MAX_FORECAST_CELLS, a slice that is not
    rows × cols bytes (once inflated: a zlib slice may not inflate past it), horizons that
    are not increasing (or past MAX_SUBSTEPS) or not one per slice, a horizon_s that is not
    horizons[-1]·T_f, a bad origin, resolution, encoding or T_f. Every byte is a probability
    (P = byte / 255 lies in [0, 1] by construction).
    """
    check_floats([substep_s], "substep_s", MAX_SUBSTEP_S)
    if substep_s <= 0:
        raise invalid(f"substep_s must be positive, got {substep_s}", Reason.OUT_OF_RANGE)
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
    check_floats([g.horizon_s], "horizon_s", MAX_SUBSTEPS * MAX_SUBSTEP_S)
    if not math.isclose(g.horizon_s, horizons[-1] * substep_s, rel_tol=1e-9, abs_tol=1e-9):
        raise invalid(f"horizon_s {g.horizon_s} is not the last horizon {horizons[-1]} x "
                      f"T_f {substep_s}", Reason.INVALID)
    slices = [_slice_bytes(b, g.encoding, cells, i) for i, b in enumerate(g.probabilities)]
    levels = np.frombuffer(b"".join(slices), dtype=np.uint8).reshape(
        len(horizons), int(g.rows), int(g.cols))
    return OccupancyForecast(resolution_m=float(g.resolution_m), substep_s=float(substep_s),
                             horizons=tuple(horizons), levels=levels.copy(),
                             origin_m=(float(origin[0]), float(origin[1])),
                             issued_substep=issued_substep,
                             substeps_per_step=max(1, int(g.substeps_per_step)))


@dataclass(frozen=True)
class FireCommand:
    """A validated FireCommand in core types: a reset (seed, area, the mission's config), an
    advance (step, sub-steps, the pacing clock, the keep-out) or a forecast query (step, the
    fire state's revision ``substeps_done``, the time-step length ``substeps``)."""

    mission_id: str
    kind: str  # "reset", "advance" or "forecast"
    seed: int = 0
    area_size_m: float = 0.0  # reset: the mission's area (0: the EWS's default)
    step: int = 0
    substeps: int = 0
    anchor: Anchor | None = None
    keep_out: KeepOut | None = None  # advance: (position, ignition clearance m)
    #: reset: the mission's configuration, whose reading the EWS runs (None: the EWS's own)
    config: MissionConfig | None = None
    substeps_done: int = 0  # forecast: the fire state (revision) it must start from
    #: a planner's forecast by reference (``ews/forecasts``): the digest of the grid asked for
    digest: bytes = b""


def fire_reset_msg(mission_id: str, seed: int, area_size_m: float, config: MissionConfig | None,
                   stamper: Stamper, sim_time_s: float) -> fire_pb2.FireCommand:
    """The supervisor's reset: a new fire process of ``config``'s reading from ``seed``."""
    m = fire_pb2.FireCommand(mission_id=mission_id)
    m.reset.seed, m.reset.area_size_m = seed, area_size_m
    if config is not None:
        config_to_msg(config, m.reset.config)
    stamper.stamp(m.header, sim_time_s)
    return m


def fire_advance_msg(mission_id: str, step: int, substeps: int, keep_out: KeepOut | None,
                     clock: SimClock | None, stamper: Stamper) -> fire_pb2.FireCommand:
    """The supervisor's advance of ``substeps`` sub-steps during ``step``; with ``clock``, its
    anchor paces the publications (sub-step k due at τ_t + k·T_f)."""
    m = fire_pb2.FireCommand(mission_id=mission_id)
    m.advance.step, m.advance.substeps = step, substeps
    if keep_out is not None:
        # the wire's keep-out is planar (a 3-D mission's altitude is not on it yet)
        m.advance.keep_out.east_m, m.advance.keep_out.north_m = (float(v)
                                                                  for v in keep_out[0][:2])
        m.advance.keep_out_m = float(keep_out[1])
    if clock is not None:
        sim_clock_to_msg(clock, m.advance.clock)
    stamper.stamp(m.header, clock.now_s if clock is not None else 0.0)
    return m


def fire_forecast_query_msg(mission_id: str, step: int, substeps_done: int,
                            substeps_per_step: int, stamper: Stamper,
                            sim_time_s: float, digest: bytes = b"") -> fire_pb2.FireCommand:
    """The supervisor's question: the occupancy forecast from the fire state after
    ``substeps_done`` sub-steps, for time-steps of ``substeps_per_step`` sub-steps; with
    ``digest``, a planner's: the answer already given whose grid has that digest."""
    m = fire_pb2.FireCommand(mission_id=mission_id)
    q = m.forecast
    q.step, q.substeps_done, q.substeps_per_step = step, substeps_done, substeps_per_step
    q.digest = digest
    stamper.stamp(m.header, sim_time_s)
    return m


def forecast_reply_msg(fc: OccupancyForecast, step: int, compute_s: float,
                       out: fire_pb2.FireForecast) -> fire_pb2.FireForecast:
    """The EWS's answer to a forecast query: ``fc`` (made for ``step`` in ``compute_s``)."""
    out.step, out.substeps_done, out.substep_s = step, fc.issued_substep, fc.substep_s
    out.compute_s = compute_s
    occupancy_to_msg(fc, out.occupancy)
    return out


def fire_command_from_msg(m: fire_pb2.FireCommand) -> FireCommand:
    mission_id = check_text(m.mission_id, "mission_id", 256)
    kind = m.WhichOneof("command")
    if kind == "reset":
        area = check_floats([m.reset.area_size_m], "area_size_m", MAX_ABS_M)[0]
        if area < 0:
            raise invalid(f"area_size_m must be >= 0, got {area}", Reason.OUT_OF_RANGE)
        config = config_from_msg(m.reset.config) if m.reset.HasField("config") else None
        return FireCommand(mission_id, "reset", seed=int(m.reset.seed), area_size_m=area,
                           config=config)
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
    if kind == "forecast":
        q = m.forecast
        check_int(q.substeps_per_step, "substeps_per_step", 1, MAX_SUBSTEPS)
        if len(q.digest) not in (0, DIGEST_BYTES):
            raise invalid(f"a forecast digest has {DIGEST_BYTES} bytes, got {len(q.digest)}",
                          Reason.SIZE)
        return FireCommand(mission_id, "forecast", step=int(q.step),
                           substeps=int(q.substeps_per_step), substeps_done=int(q.substeps_done),
                           digest=bytes(q.digest))
    raise invalid("FireCommand carries no reset, advance or forecast")
