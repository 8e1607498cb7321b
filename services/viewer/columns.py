"""The operations picture as columns: what each of the web page's data sources holds.

Pure functions of a :class:`~services.viewer.picture.Frame`: one dict of
equal-length lists a source (Bokeh's ``ColumnDataSource.data``), positions in
``world`` metres (east, north). The page (services/viewer/page.py) assigns
them; the tests check them without a browser.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from dualpilot.model.dynamics import Array
from dualpilot.viz.scene import OccupancyView, altitude_text, circle

from .picture import Frame, VehicleFrame

Columns = dict[str, list[Any]]

#: the flown system's colour: System 1 blue, System 2 magenta (the Foxglove plans' colours)
SYSTEM_COLORS = {1: "#3399ff", 2: "#e633e6"}
BRAKED_COLOR = "#e03c31"  # no OK plan: the UAV braked
UNKNOWN_COLOR = "#888888"  # no decision yet


#: a flown system's name (flown_name) → its number
FLOWN_NUMBER = {"S1": 1, "S2": 2, "braked": 0}


def flown_name(flown: int | None) -> str:
    """``S1``, ``S2``, ``braked`` (0) or ``-`` (no decision yet)."""
    return "-" if flown is None else ("braked" if flown == 0 else f"S{flown}")


def flown_color(flown: int | None) -> str:
    if flown is None:
        return UNKNOWN_COLOR
    return SYSTEM_COLORS.get(flown, BRAKED_COLOR)


def _shift(v: VehicleFrame, pts: Array) -> tuple[list[float], list[float]]:
    p = np.asarray(pts, dtype=float).reshape(-1, 2)
    return ([float(x) + v.offset_m[0] for x in p[:, 0]],
            [float(y) + v.offset_m[1] for y in p[:, 1]])


def _outlines(frame: Frame, shapes: Any) -> Columns:
    """``xs``/``ys`` of every shape ``shapes(vehicle)`` yields, and each one's vehicle."""
    cols: Columns = {"xs": [], "ys": [], "uav": []}
    for v in frame.vehicles:
        for pts in shapes(v):
            xs, ys = _shift(v, pts)
            cols["xs"].append(xs)
            cols["ys"].append(ys)
            cols["uav"].append(v.uav)
    return cols


def area_columns(frame: Frame) -> dict[str, Columns]:
    """The areas' boundaries, goals G and starts."""
    def square(v: VehicleFrame) -> list[Array]:
        a = v.area.size_m if v.area else 0.0
        return [np.array([[0, 0], [a, 0], [a, a], [0, a], [0, 0]])] if v.area else []

    starts: Columns = {"x": [], "y": [], "uav": []}
    for v in frame.vehicles:
        if v.area is not None:
            starts["x"].append(float(v.area.start[0]) + v.offset_m[0])
            starts["y"].append(float(v.area.start[1]) + v.offset_m[1])
            starts["uav"].append(v.uav)
    return {"area": _outlines(frame, square),
            "goal": _outlines(frame, lambda v: [v.area.goal] if v.area else []),
            "start": starts}


def fire_columns(frame: Frame) -> dict[str, Columns]:
    """The active fronts' regions (with their ids and birth steps) and every hull."""
    fires: Columns = {"xs": [], "ys": [], "uav": [], "front_id": [], "born_step": []}
    for v in frame.vehicles:
        if v.fires is None:
            continue
        for corners, fid, born in zip(v.fires.regions, v.fires.front_ids, v.fires.born_steps,
                                      strict=True):
            xs, ys = _shift(v, corners)
            fires["xs"].append(xs)
            fires["ys"].append(ys)
            fires["uav"].append(v.uav)
            fires["front_id"].append(int(fid))
            fires["born_step"].append(int(born))
    closed = _outlines(frame, lambda v: [np.vstack([h, h[:1]]) for h in v.fires.hulls
                                         if len(h)] if v.fires else [])
    risk = _outlines(frame, lambda v: [np.vstack([z, z[:1]]) for z in v.risk.zones
                                       if len(z)] if v.risk else [])
    return {"fires": fires, "hulls": closed, "risk": risk}


#: the heat map's colour scale: log10 P from HEAT_LOW_P (clear below) to 1, so that the small
#: probabilities of the paper's fire process (about 0.01 everywhere, a few 0.1 beside a front)
#: are told apart; its opacity grows with the square of the position on that scale, to
#: HEAT_ALPHA at P = 1 (the even chance of a birth anywhere stays a faint tint)
HEAT_LOW_P, HEAT_ALPHA = 1e-3, 0.85
#: the heat map's colours from HEAT_LOW_P to 1 (ColorBrewer's YlOrRd, light to dark)
HEAT_COLORS = ("#ffffcc", "#ffeda0", "#fed976", "#feb24c", "#fd8d3c", "#fc4e2a", "#e31a1c",
               "#bd0026", "#800026")


def heat_palette(n: int = 256) -> list[str]:
    """``n`` colours ``#rrggbbaa`` along the heat map's log scale: YlOrRd interpolated, the
    opacity HEAT_ALPHA · s² at the scale's fraction s (0 at HEAT_LOW_P, 1 at P = 1)."""
    rgb = np.array([[int(c[i:i + 2], 16) for i in (1, 3, 5)] for c in HEAT_COLORS], float)
    at = np.linspace(0.0, 1.0, len(HEAT_COLORS))
    out = []
    for s in np.linspace(0.0, 1.0, n):
        r, g, b = (int(round(np.interp(s, at, rgb[:, k]))) for k in range(3))
        out.append(f"#{r:02x}{g:02x}{b:02x}{int(round(255 * HEAT_ALPHA * s * s)):02x}")
    return out


def forecast_image(view: OccupancyView, slice_index: int) -> Array:
    """Horizon ``slice_index`` of the occupancy forecast as P = byte / 255 (rows × cols, row 0
    the southern one), NaN where P = 0 (drawn transparent)."""
    f = len(view.horizons_s)
    cells = np.frombuffer(view.data, dtype=np.uint8).reshape(view.rows, view.cols, f)
    p = cells[:, :, slice_index].astype(float) / 255.0
    p[p <= 0.0] = np.nan
    return p


def forecast_columns(frame: Frame, slice_index: int = -1) -> Columns:
    """Each vehicle's occupancy forecast at one of its horizons (-1: the furthest)."""
    cols: Columns = {"image": [], "x": [], "y": [], "dw": [], "dh": [], "uav": [],
                     "horizon_s": []}
    for v in frame.vehicles:
        fc = v.forecast
        if fc is None or not fc.horizons_s or fc.rows == 0 or fc.cols == 0:
            continue
        k = len(fc.horizons_s) - 1 if slice_index < 0 else min(slice_index,
                                                                len(fc.horizons_s) - 1)
        cols["image"].append(forecast_image(fc, k))
        cols["x"].append(fc.origin_m[0] + v.offset_m[0])
        cols["y"].append(fc.origin_m[1] + v.offset_m[1])
        cols["dw"].append(fc.cols * fc.resolution_m)
        cols["dh"].append(fc.rows * fc.resolution_m)
        cols["uav"].append(v.uav)
        cols["horizon_s"].append(float(fc.horizons_s[k]))
    return cols


def heading_rad(state: Array) -> float:
    """The marker's rotation (rad, counter-clockwise from north) along the velocity;
    0 (north) when the UAV is at rest."""
    ve, vn = float(state[2]), float(state[3])
    return 0.0 if math.hypot(ve, vn) < 1e-6 else math.atan2(vn, ve) - math.pi / 2.0


def vehicle_columns(frame: Frame) -> dict[str, Columns]:
    """Every vehicle (position, heading, who flies, Ψ, altitude: NaN in 2-D, in its label in
    3-D), its d_safe disc, trail and plan."""
    cols: Columns = {k: [] for k in ("x", "y", "angle", "uav", "step", "flies", "color",
                                     "speed", "psi1", "psi2", "altitude", "label")}
    safe: Columns = {"xs": [], "ys": [], "uav": []}
    for v in frame.vehicles:
        if v.state is None:
            continue
        d = v.decision
        flown = None if d is None else int(d["flown_system"])
        psi = [float(p) for p in d["psi"]] if d else [math.nan, math.nan]
        x, y = v.state[0] + v.offset_m[0], v.state[1] + v.offset_m[1]
        for key, value in (("x", float(x)), ("y", float(y)), ("angle", heading_rad(v.state)),
                           ("uav", v.uav), ("step", v.step), ("flies", flown_name(flown)),
                           ("color", flown_color(flown)),
                           ("speed", float(math.hypot(v.state[2], v.state[3]))),
                           ("psi1", psi[0]), ("psi2", psi[1]),
                           ("altitude", math.nan if v.altitude_m is None else v.altitude_m),
                           ("label", f"{v.uav} {flown_name(flown)} t={v.step}"
                                     + altitude_text(v.altitude_m))):
            cols[key].append(value)
        if v.d_safe_m > 0:
            xs, ys = _shift(v, circle(v.state[:2], v.d_safe_m, 48))
            safe["xs"].append(xs + xs[:1])
            safe["ys"].append(ys + ys[:1])
            safe["uav"].append(v.uav)
    trails = _outlines(frame, lambda v: [v.path] if len(v.path) > 1 else [])
    return {"vehicles": cols, "safety": safe, "trails": trails,
            "altitude_trails": altitude_trail_columns(frame), "plans": plan_columns(frame)}


def altitude_trail_columns(frame: Frame) -> Columns:
    """A 3-D mission's trail as segments, each with the mean altitude (m) of its two ends (the
    page colours them by it); nothing for a 2-D mission."""
    cols: Columns = {"xs": [], "ys": [], "uav": [], "altitude": []}
    for v in frame.vehicles:
        z = v.path_altitudes
        if len(z) != len(v.path):
            continue
        for i in range(len(z) - 1):
            xs, ys = _shift(v, v.path[i:i + 2])
            for key, value in (("xs", xs), ("ys", ys), ("uav", v.uav),
                               ("altitude", 0.5 * (z[i] + z[i + 1]))):
                cols[key].append(value)
    return cols


def plan_columns(frame: Frame) -> Columns:
    """The flown plan of each vehicle's newest step, coloured by its system."""
    cols: Columns = {"xs": [], "ys": [], "uav": [], "system": [], "status": [], "color": [],
                     "step": []}
    for v in frame.vehicles:
        for p in v.plans:
            if not p.flown or len(p.positions) < 2:
                continue
            xs, ys = _shift(v, p.positions)
            for key, value in (("xs", xs), ("ys", ys), ("uav", v.uav), ("system", p.system),
                               ("status", p.status or "kept"), ("color", flown_color(p.system)),
                               ("step", v.plan_step)):
                cols[key].append(value)
    return cols


def _plan_status(v: VehicleFrame) -> str:
    return "; ".join(f"S{p.system} {p.status or ('kept' if p.flown else 'not asked')}"
                     for p in v.plans)


def _last_event(v: VehicleFrame) -> str:
    return v.events[-1][2] if v.events else ""


def table_columns(frame: Frame) -> Columns:
    """One row a vehicle: step, who flies, Ψ_t, A_t, d_t, the plans' status, the last event."""
    cols: Columns = {k: [] for k in ("uav", "step", "flies", "psi1", "psi2", "attention",
                                     "d_t_m", "plans", "event")}
    for v in frame.vehicles:
        d = v.decision
        psi = [float(p) for p in d["psi"]] if d else [math.nan, math.nan]
        d_t = d.get("d_t_m") if d else None
        row = (v.uav, v.step, flown_name(None if d is None else int(d["flown_system"])),
               psi[0], psi[1], int(d["attention"]) if d else 0,
               math.nan if d_t is None else float(d_t), _plan_status(v), _last_event(v))
        for key, value in zip(cols, row, strict=True):
            cols[key].append(value)
    return cols


def psi_columns(frame: Frame, uav: str) -> Columns:
    """Ψ_t of ``uav`` over its steps (Eq. Ψ), and which system flew each step (a strip of
    markers at ``flown_y``, a tenth of Ψ's span below its lowest value)."""
    cols: Columns = {"t": [], "psi1": [], "psi2": [], "flown": [], "color": [], "flown_y": []}
    v = next((v for v in frame.vehicles if v.uav == uav), None)
    for d in v.decisions if v is not None else ():
        flown = int(d["flown_system"])
        cols["t"].append(int(d["t"]))
        cols["psi1"].append(float(d["psi"][0]))
        cols["psi2"].append(float(d["psi"][1]))
        cols["flown"].append(flown_name(flown))
        cols["color"].append(flown_color(flown))
    values = cols["psi1"] + cols["psi2"]
    if values:
        low, high = min(values), max(values)
        cols["flown_y"] = [low - 0.1 * max(high - low, 1e-9)] * len(cols["t"])
    return cols


def event_lines(frame: Frame, most: int = 8) -> list[tuple[str, str, str]]:
    """The newest ``most`` events of the whole fleet, newest first: (uav, level, text)."""
    every = [(t, v.uav, level, text) for v in frame.vehicles for t, level, text in v.events]
    every.sort(key=lambda e: e[0], reverse=True)
    return [(uav, level, text) for _, uav, level, text in every[:most]]
