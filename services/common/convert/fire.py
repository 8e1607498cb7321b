"""fire.proto ↔ core types: the fire state, its occupancy forecast and the EWS's commands.

Decoders check counts, finiteness and ranges (services/common/limits.py) and raise
:class:`~services.common.rejections.CodecError` for a bad message; a reset's
mission configuration is decoded by services/common/convert/config.py.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.ports import KeepOut
from dualpilot.model.fire import FireFront, FireSnapshot
from dualpilot.model.forecast import OccupancyForecast
from dualpilot.model.geometry import Polytope, Rect
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
    check_count,
    check_floats,
    check_text,
    finite,
)
from services.common.rejections import Reason, invalid
from services.common.wire import Stamper, check_header
from services.msgs import fire_pb2


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


@dataclass(frozen=True)
class FireCommand:
    """A validated FireCommand in core types: a reset (seed, area, the mission's config) or
    an advance (step, sub-steps, the pacing clock, the keep-out)."""

    mission_id: str
    kind: str  # "reset" or "advance"
    seed: int = 0
    area_size_m: float = 0.0  # reset: the mission's area (0: the EWS's default)
    step: int = 0
    substeps: int = 0
    anchor: Anchor | None = None
    keep_out: KeepOut | None = None  # advance: (position, ignition clearance m)
    #: reset: the mission's configuration, whose reading the EWS runs (None: the EWS's own)
    config: MissionConfig | None = None


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
        m.advance.keep_out.east_m, m.advance.keep_out.north_m = (float(v) for v in keep_out[0])
        m.advance.keep_out_m = float(keep_out[1])
    if clock is not None:
        sim_clock_to_msg(clock, m.advance.clock)
    stamper.stamp(m.header, clock.now_s if clock is not None else 0.0)
    return m


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
    raise invalid("FireCommand carries neither reset nor advance")
