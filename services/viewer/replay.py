"""A run's mission.mcap replayed on the web page: the recording read back into the picture.

``python -m services.viewer --replay runs/latest/mission.mcap`` (several files:
a fleet's ``uav*/mission.mcap``, side by side). Each message is decoded with the
schema the file carries (``mcap``, ``mcap-protobuf-support``) and turned back
into the views dualpilot/viz/foxglove.py drew it from (the inverse of
``VehicleChannels``: regions and hulls from the fires' lines, the UAV's state
from its entity's metadata, …); fed to a :class:`~services.viewer.picture.Picture`
in log-time order, one frame is kept per log time (a step, on the mission's
simulated clock), and the page's slider walks through them.
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dualpilot.mission.answers import PlanView
from dualpilot.model.dynamics import Array
from dualpilot.viz.scene import AreaView, FireView, OccupancyView, RiskView

from .picture import Frame, Picture, VehicleScene

#: between two vehicles' areas when several recordings are replayed side by side (m)
AREA_GAP_M = 100.0


@dataclass(frozen=True)
class Message:
    """One decoded message: its vehicle, its kind (the topic below ``/<uav>/``), its log time."""

    uav: str
    kind: str
    log_time_ns: int
    body: Any  # a protobuf message, or a dict (JSON)


def _decode(schema: Any, encoding: str, data: bytes, cache: dict[int, Any]) -> Any:
    from mcap_protobuf.decoder import DecoderFactory

    if encoding == "json":
        return json.loads(data)
    if schema.id not in cache:
        cache[schema.id] = DecoderFactory().decoder_for(encoding, schema)
    decoder = cache[schema.id]
    if decoder is None:
        raise ValueError(f"cannot decode {encoding} messages of schema {schema.name!r}")
    return decoder(data)


def read_messages(path: Path, rename: str = "") -> list[Message]:
    """Every message of one recording, in log-time order (``rename``: the vehicle's id to
    use instead of the file's)."""
    from mcap.reader import make_reader

    out: list[Message] = []
    cache: dict[int, Any] = {}
    with Path(path).open("rb") as fh:
        for schema, channel, msg in make_reader(fh).iter_messages(log_time_order=True):
            parts = channel.topic.strip("/").split("/", 1)
            if len(parts) != 2 or schema is None:
                continue
            out.append(Message(rename or parts[0], parts[1], int(msg.log_time),
                               _decode(schema, channel.message_encoding, msg.data, cache)))
    return out


# -- the views, back from the Foxglove messages ------------------------------------------------
def _points(line: Any) -> Array:
    return np.array([[p.x, p.y] for p in line.points], dtype=float).reshape(-1, 2)


def _meta(entity: Any) -> dict[str, str]:
    return {kv.key: kv.value for kv in entity.metadata}


def area_of(update: Any) -> AreaView:
    by_id = {e.id: e for e in update.entities}
    start = by_id["start"].spheres[0].pose.position
    return AreaView(float(_meta(by_id["boundary"])["area_size_m"]),
                    np.array([start.x, start.y]), _points(by_id["goal"].lines[0]))


def fires_of(update: Any) -> FireView:
    """Each front's region (its first line) and hull (its second), then the extinct hulls."""
    regions, ids, born, hulls = [], [], [], []
    fronts = [e for e in update.entities if e.id.startswith("front/")]
    for e in fronts:
        m = _meta(e)
        regions.append(_points(e.lines[0]))
        ids.append(int(m["front_id"]))
        born.append(int(m["born_step"]))
        if len(e.lines) > 1:
            hulls.append(_points(e.lines[1]))
    hulls += [_points(e.lines[0]) for e in update.entities if e.id.startswith("hull/")]
    return FireView(tuple(regions), tuple(ids), tuple(born), tuple(hulls))


def vehicle_of(update: Any) -> tuple[Array, int, float]:
    """The UAV's state (east, north, v_east, v_north; a 3-D mission's east, north, altitude,
    v_east, v_north, v_up), its step and d_safe (the disc's radius)."""
    e = update.entities[0]
    m = _meta(e)
    keys = (("east_m", "north_m", "altitude_m", "v_east_mps", "v_north_mps", "v_up_mps")
            if "altitude_m" in m else ("east_m", "north_m", "v_east_mps", "v_north_mps"))
    x = np.array([float(m[k]) for k in keys])
    disc = _points(e.lines[0]) if e.lines else np.empty((0, 2))
    d_safe = float(np.hypot(*(disc[0] - x[:2]))) if len(disc) else 0.0
    return x, int(m["step"]), d_safe


def plan_of(update: Any) -> tuple[PlanView, int]:
    e = update.entities[0]
    m = _meta(e)
    status = "" if m["status"] in ("kept", "not_asked") else m["status"]
    pts = _points(e.lines[0]) if e.lines else np.empty((0, 2))
    return PlanView(int(m["system"]), status, pts, m["flown"] == "true"), int(m["step"])


def forecast_of(grid: Any) -> OccupancyView:
    horizons = tuple(float(f.name.removeprefix("p_").removesuffix("s")) for f in grid.fields)
    rows = len(grid.data) // grid.row_stride if grid.row_stride else 0
    return OccupancyView((grid.pose.position.x, grid.pose.position.y), float(grid.cell_size.x),
                         rows, int(grid.column_count), horizons, bytes(grid.data))


def risk_of(update: Any) -> tuple[RiskView, int]:
    zones = tuple(_points(e.lines[0]) for e in update.entities if e.lines)
    m = _meta(update.entities[0]) if update.entities else {}
    return RiskView(zones, float(m.get("alpha", 0.0))), int(m.get("step", -1))


LEVELS = {2: "info", 3: "warning", 4: "error"}  # foxglove.Log levels


def apply(scene: VehicleScene, msg: Message, plans: dict[int, PlanView]) -> None:
    """Give one recorded message to ``scene`` as the live viewer would have."""
    body, t_ns, kind = msg.body, msg.log_time_ns, msg.kind
    if kind == "area":
        scene.area(area_of(body), t_ns)
    elif kind == "fires":
        scene.fires(fires_of(body), t_ns)
    elif kind == "uav":
        x, step, d_safe = vehicle_of(body)
        scene.vehicle(x, step, d_safe, t_ns)
    elif kind == "path":
        scene.path(_points(body.entities[0].lines[0]) if body.entities[0].lines
                   else np.empty((0, 2)), t_ns)
    elif kind.startswith("plan/system"):
        view, step = plan_of(body)
        plans[view.system] = view
        scene.plans([plans[k] for k in sorted(plans)], step, t_ns)
    elif kind == "decision":
        scene.decision(body, t_ns)
    elif kind == "forecast":
        scene.forecast(forecast_of(body), t_ns)
    elif kind == "risk":
        scene.risk(*risk_of(body), t_ns)
    elif kind == "events":
        scene.event(body.message, t_ns, LEVELS.get(int(body.level), "info"))


# -- the timeline ---------------------------------------------------------------------------------
def _offsets(messages: Sequence[Message]) -> dict[str, tuple[float, float]]:
    """Each vehicle's place in ``world``: its recorded ``tf``, or (recordings that all put their
    area at the origin) side by side, k·(A + 100 m) east of the first."""
    tf: dict[str, tuple[float, float]] = {}
    size: dict[str, float] = {}
    for m in messages:
        if m.kind == "tf" and m.uav not in tf:
            tf[m.uav] = (float(m.body.translation.x), float(m.body.translation.y))
        elif m.kind == "area" and m.uav not in size:
            size[m.uav] = area_of(m.body).size_m
    uavs = list(dict.fromkeys(m.uav for m in messages))
    if len(uavs) > 1 and len({tf.get(u, (0.0, 0.0)) for u in uavs}) == 1:
        east, out = 0.0, {}
        for u in uavs:
            out[u] = (east, 0.0)
            east += size.get(u, 0.0) + AREA_GAP_M
        return out
    return {u: tf.get(u, (0.0, 0.0)) for u in uavs}


def frames_of(messages: Sequence[Message]) -> Iterator[Frame]:
    """One frame a log time, after every message of that time is in the picture."""
    picture = Picture()
    offsets = _offsets(messages)
    plans: dict[str, dict[int, PlanView]] = {u: {} for u in offsets}
    ordered = sorted(messages, key=lambda m: m.log_time_ns)
    for i, m in enumerate(ordered):
        apply(picture.scene(m.uav, offsets[m.uav]), m, plans[m.uav])
        if i + 1 == len(ordered) or ordered[i + 1].log_time_ns != m.log_time_ns:
            yield picture.frame()


@dataclass(frozen=True)
class Timeline:
    """A replay's frames, one a step (log time) of the recordings."""

    frames: tuple[Frame, ...]
    files: tuple[str, ...]

    def at(self, k: int) -> Frame:
        return self.frames[min(max(int(k), 0), len(self.frames) - 1)]


def load(paths: Sequence[Path]) -> Timeline:
    """The timeline of one or more mission.mcap files (a vehicle id seen in two files gets the
    file's number appended); ValueError when they hold no message."""
    messages: list[Message] = []
    seen: set[str] = set()
    for k, path in enumerate(paths):
        got = read_messages(path)
        names = {m.uav for m in got}
        if names & seen:
            got = read_messages(path, rename=f"{sorted(names)[0]}-{k + 1}")
        seen |= {m.uav for m in got}
        messages += got
    if not messages:
        raise ValueError(f"no messages in {', '.join(map(str, paths))}")
    return Timeline(tuple(frames_of(messages)), tuple(str(p) for p in paths))
