"""A mission's scene as Foxglove channels: the one definition the live view and mission.mcap share.

:class:`VehicleChannels` declares one vehicle's channels in a foxglove-sdk
``Context`` (topics ``/<uav>/…``, so a fleet's vehicles sit side by side) and
logs :mod:`dualpilot.viz.scene` views on them; whatever sink the context has
(an MCAP writer here, the WebSocket server of services/viewer) gets the same
channels and schemas. :func:`write_mcap` writes a finished mission's records
as ``mission.mcap`` with log times on the mission's simulated clock.

Frames: ``world`` is the root; each vehicle's area is the frame ``<uav>/area``
(the mission frame: x east, y north, m), placed in ``world`` by ``/<uav>/tf``.
foxglove-sdk is a visualization and log-format library, like matplotlib for
the figures; its WebSocket server is started only by services/viewer.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dualpilot.model.dynamics import Array
from dualpilot.spec import MissionSpec
from dualpilot.viz.scene import (
    AreaView,
    FireView,
    OccupancyView,
    PlanView,
    RiskView,
    altitude_text,
    area_view,
    circle,
    commanded_system,
    decision_doc,
    end_text,
    fire_view,
    occupancy_view,
    plan_views,
    risk_view,
    start_text,
    step_text,
    top_down,
)

#: name of the mission's Foxglove recording in a run directory
MCAP_FILE = "mission.mcap"
WORLD_FRAME = "world"
#: heights (m) of the layers, so that lines drawn over one another stay visible
Z_AREA, Z_FIRE, Z_HULL, Z_PATH, Z_PLAN, Z_UAV = 0.0, 0.2, 0.4, 0.6, 0.8, 2.0
Z_RISK = 0.3  # risk zones: above the fires, below the hulls
LINE_PX = 2.0
UAV_SIZE_M = 12.0

#: JSON schema of ``/<uav>/decision`` (dualpilot.viz.scene.decision_doc)
DECISION_SCHEMA: dict[str, Any] = {
    "title": "dualpilot.Decision",
    "type": "object",
    "description": "One supervisor step (Sec. III-C): Xi_t, P_t, A_t, Psi_t, S_t",
    "properties": {
        "t": {"type": "integer", "description": "step"},
        "time_s": {"type": "number", "description": "simulated time when the step began (s)"},
        "d_t_m": {"type": ["number", "null"],
                  "description": "distance to the nearest counted region (m); null: none"},
        "xi": {"type": "array", "items": {"type": "number"}, "description": "Xi_t, Eq. (KSI)"},
        "p": {"type": "array", "items": {"type": "number"}, "description": "P_t ~ Dir(Xi_t)"},
        "attention": {"type": "integer", "description": "A_t, 1-based attribute"},
        "psi": {"type": "array", "items": {"type": "number"}, "description": "Psi_t, Eq. (Psi)"},
        "system": {"type": "integer", "description": "S_t = argmax Psi_t"},
        "commanded_system": {"type": "integer", "description": "the system asked first"},
        "flown_system": {"type": "integer", "description": "the system flown; 0: braked"},
        "objective": {"type": "string", "description": "System 2's objective"},
    },
}


def _fx() -> Any:
    import foxglove

    return foxglove


def _m() -> Any:
    from foxglove import messages

    return messages


def stamp(t_ns: int) -> Any:
    """A Foxglove Timestamp of ``t_ns`` nanoseconds."""
    return _m().Timestamp(int(t_ns) // 1_000_000_000, int(t_ns) % 1_000_000_000)


def ns(seconds: float) -> int:
    return int(round(float(seconds) * 1e9))


def _color(r: float, g: float, b: float, a: float = 1.0) -> Any:
    return _m().Color(r=r, g=g, b=b, a=a)


def _points(pts: Array, z: float) -> list[Any]:
    m = _m()
    return [m.Point3(x=float(x), y=float(y), z=z) for x, y in np.asarray(pts).reshape(-1, 2)]


def _line(pts: Array, z: float, color: Any, closed: bool) -> Any:
    m = _m()
    kind = m.LinePrimitiveLineType.LineLoop if closed else m.LinePrimitiveLineType.LineStrip
    return m.LinePrimitive(type=kind, thickness=LINE_PX, scale_invariant=True,
                           points=_points(pts, z), color=color)


def _fill(pts: Array, z: float, color: Any) -> Any:
    """A convex polygon as a triangle fan."""
    m = _m()
    p = np.asarray(pts).reshape(-1, 2)
    tris = [p[i] for k in range(1, len(p) - 1) for i in (0, k, k + 1)]
    return m.TriangleListPrimitive(points=_points(np.array(tris), z), color=color)


def _pose(x: float, y: float, z: float) -> Any:
    m = _m()
    return m.Pose(position=m.Vector3(x=x, y=y, z=z), orientation=m.Quaternion(w=1.0))


def _meta(**kv: object) -> list[Any]:
    return [_m().KeyValuePair(key=k, value=str(v).lower() if isinstance(v, bool) else str(v))
            for k, v in kv.items()]


FIRE_FILL = (1.0, 0.25, 0.1, 0.55)
HULL_LINE = (1.0, 0.6, 0.0, 1.0)
RISK_LINE = (0.8, 0.3, 1.0, 0.9)  # the forecast's risk zones: violet
PLAN_COLORS = {1: (0.2, 0.6, 1.0, 1.0), 2: (0.9, 0.2, 0.9, 1.0)}


class VehicleChannels:
    """One vehicle's channels in a foxglove-sdk context, and how each view is drawn on them.

    ``offset_m`` places the vehicle's area in ``world`` (east, north m): a
    fleet's areas side by side.
    """

    def __init__(self, uav: str, context: Any = None, offset_m: tuple[float, float] = (0., 0.)):
        fx = _fx()
        from foxglove import channels as ch

        self.uav = uav
        self.frame = f"{uav}/area"
        self.offset_m = offset_m
        kw = {"context": context}
        p = f"/{uav}"
        self.tf = ch.FrameTransformChannel(f"{p}/tf", **kw)
        self.area_ch = ch.SceneUpdateChannel(f"{p}/area", **kw)
        self.fires_ch = ch.SceneUpdateChannel(f"{p}/fires", **kw)
        self.forecast_ch = ch.GridChannel(f"{p}/forecast", **kw)
        self.risk_ch = ch.SceneUpdateChannel(f"{p}/risk", **kw)
        self.plan_ch = {k: ch.SceneUpdateChannel(f"{p}/plan/system{k}", **kw) for k in (1, 2)}
        self.path_ch = ch.SceneUpdateChannel(f"{p}/path", **kw)
        self.uav_ch = ch.SceneUpdateChannel(f"{p}/uav", **kw)
        self.decision_ch = fx.Channel(f"{p}/decision", schema=DECISION_SCHEMA, **kw)
        self.events_ch = ch.LogChannel(f"{p}/events", **kw)

    def _channels(self) -> list[Any]:
        return [self.tf, self.area_ch, self.fires_ch, self.forecast_ch, self.risk_ch,
                *self.plan_ch.values(),
                self.path_ch, self.uav_ch, self.decision_ch, self.events_ch]

    def topics(self) -> list[str]:
        return [c.topic() for c in self._channels()]

    def close(self) -> None:
        """Unadvertise every channel (a viewer's sinks drop them)."""
        for c in self._channels():
            c.close()

    def _entity(self, t_ns: int, eid: str, **kw: Any) -> Any:
        return _m().SceneEntity(timestamp=stamp(t_ns), frame_id=self.frame, id=eid, **kw)

    def _update(self, entities: list[Any]) -> Any:
        """A SceneUpdate that replaces everything the channel showed before."""
        m = _m()
        return m.SceneUpdate(deletions=[m.SceneEntityDeletion(
            type=m.SceneEntityDeletionType.All)], entities=entities)

    # -- the views --------------------------------------------------------------------------------
    def transform(self, t_ns: int) -> None:
        m = _m()
        e, n = self.offset_m
        self.tf.log(m.FrameTransform(
            timestamp=stamp(t_ns), parent_frame_id=WORLD_FRAME, child_frame_id=self.frame,
            translation=m.Vector3(x=float(e), y=float(n), z=0.0),
            rotation=m.Quaternion(w=1.0)), log_time=t_ns)

    def area(self, view: AreaView, t_ns: int) -> None:
        """The area's boundary, the goal G (filled) and the start."""
        m = _m()
        a = view.size_m
        square = np.array([[0.0, 0.0], [a, 0.0], [a, a], [0.0, a]])
        green = _color(0.1, 0.8, 0.3, 0.5)
        sx, sy = (float(v) for v in view.start)
        self.area_ch.log(self._update([
            self._entity(t_ns, "boundary", lines=[_line(square, Z_AREA, _color(.8, .8, .8), True)],
                         metadata=_meta(area_size_m=a)),
            self._entity(t_ns, "goal", triangles=[_fill(view.goal, Z_AREA, green)],
                         lines=[_line(view.goal, Z_AREA, _color(0.1, 0.8, 0.3), True)]),
            self._entity(t_ns, "start", spheres=[m.SpherePrimitive(
                pose=_pose(sx, sy, Z_AREA), size=m.Vector3(x=8.0, y=8.0, z=8.0),
                color=_color(0.9, 0.9, 0.9))], metadata=_meta(east_m=sx, north_m=sy)),
        ]), log_time=t_ns)

    def fires(self, view: FireView, t_ns: int) -> None:
        """Each active front (entity ``front/<id>``: its region filled and outlined, then its
        hull), and the extinct fronts' hulls (``hull/<k>``)."""
        fill, outline = _color(*FIRE_FILL), _color(1.0, 0.2, 0.1)
        hull_c = _color(*HULL_LINE)
        entities = []
        n = len(view.regions)
        for k, (corners, fid, born) in enumerate(zip(view.regions, view.front_ids,
                                                     view.born_steps, strict=True)):
            lines = [_line(corners, Z_FIRE, outline, True)]
            if k < len(view.hulls):
                lines.append(_line(view.hulls[k], Z_HULL, hull_c, True))
            entities.append(self._entity(t_ns, f"front/{fid}", triangles=[
                _fill(corners, Z_FIRE, fill)], lines=lines,
                metadata=_meta(front_id=fid, born_step=born)))
        for k in range(n, len(view.hulls)):
            entities.append(self._entity(t_ns, f"hull/{k}", lines=[
                _line(view.hulls[k], Z_HULL, hull_c, True)], metadata=_meta(extinct=True)))
        self.fires_ch.log(self._update(entities), log_time=t_ns)

    def plans(self, views: Sequence[PlanView], t: int, t_ns: int) -> None:
        """Each system's plan (entity ``plan``: its status, the flown plan's positions)."""
        m = _m()
        for v in views:
            lines, texts = [], []
            if len(v.positions):
                c = _color(*PLAN_COLORS[v.system])
                lines.append(_line(v.positions, Z_PLAN, c, False))
                ex, ey = (float(q) for q in v.positions[-1])
                texts.append(m.TextPrimitive(pose=_pose(ex, ey, Z_PLAN + 5.0), billboard=True,
                                             font_size=14.0, scale_invariant=True, color=c,
                                             text=f"S{v.system} {v.status}"))
            self.plan_ch[v.system].log(self._update([self._entity(
                t_ns, "plan", lines=lines, texts=texts,
                metadata=_meta(system=v.system, step=t,
                               status=v.status or ("kept" if v.flown else "not_asked"),
                               flown=v.flown))]), log_time=t_ns)

    def vehicle(self, state: Array, t: int, d_safe_m: float, t_ns: int) -> None:
        """The UAV (a cube), its d_safe disc and a label, at step ``t``'s state (2-D or 3-D:
        a 3-D one's altitude and climb in the metadata, ``altitude_m`` and ``v_up_mps``, and
        its altitude in the label)."""
        m = _m()
        x, z, vz = top_down(state)
        e, n = float(x[0]), float(x[1])
        yellow = _color(1.0, 0.85, 0.1)
        up = {} if z is None else {"altitude_m": z, "v_up_mps": vz}
        self.uav_ch.log(self._update([self._entity(
            t_ns, "uav", cubes=[m.CubePrimitive(
                pose=_pose(e, n, Z_UAV), size=m.Vector3(x=UAV_SIZE_M, y=UAV_SIZE_M, z=4.0),
                color=yellow)],
            lines=[_line(circle(x[:2], d_safe_m), Z_UAV, _color(1.0, 0.85, 0.1, 0.7), True)],
            texts=[m.TextPrimitive(pose=_pose(e, n, Z_UAV + 10.0), billboard=True,
                                   font_size=14.0, scale_invariant=True, color=yellow,
                                   text=f"{self.uav} t={t}" + altitude_text(z))],
            metadata=_meta(step=t, east_m=e, north_m=n, v_east_mps=float(x[2]),
                           v_north_mps=float(x[3]), **up)),
        ]), log_time=t_ns)

    def path(self, positions: Array, t_ns: int) -> None:
        """The flown path: the UAV's positions so far."""
        pts = np.asarray(positions, dtype=float)
        # a 3-D mission's path in the plane of the scene
        pts = pts[:, :2] if pts.ndim == 2 and pts.shape[1] == 3 else pts.reshape(-1, 2)
        self.path_ch.log(self._update([self._entity(
            t_ns, "path", lines=[_line(pts, Z_PATH, _color(0.95, 0.95, 0.95), False)],
            metadata=_meta(points=len(pts)))]), log_time=t_ns)

    def decision(self, doc: dict[str, object], t_ns: int) -> None:
        self.decision_ch.log(doc, log_time=t_ns)

    def forecast(self, view: OccupancyView, t_ns: int) -> None:
        """The occupancy forecast as a Grid: one uint8 field ``p_<h>s`` a horizon (P·255)."""
        m = _m()
        f = len(view.horizons_s)
        fields = [m.PackedElementField(name=f"p_{h:g}s", offset=i,
                                       type=m.PackedElementFieldNumericType.Uint8)
                  for i, h in enumerate(view.horizons_s)]
        ox, oy = view.origin_m
        self.forecast_ch.log(m.Grid(
            timestamp=stamp(t_ns), frame_id=self.frame, pose=_pose(ox, oy, Z_AREA),
            column_count=view.cols, cell_size=m.Vector2(x=view.resolution_m, y=view.resolution_m),
            row_stride=view.cols * f, cell_stride=f, fields=fields, data=view.data),
            log_time=t_ns)

    def risk(self, view: RiskView, t: int, t_ns: int) -> None:
        """The risk zones the flown plan was made against (entity ``zone/<k>``, outlined;
        none: the channel is cleared)."""
        c = _color(*RISK_LINE)
        self.risk_ch.log(self._update([self._entity(
            t_ns, f"zone/{k}", lines=[_line(z, Z_RISK, c, True)],
            metadata=_meta(step=t, alpha=view.alpha)) for k, z in enumerate(view.zones)]),
            log_time=t_ns)

    def event(self, text: str, t_ns: int, level: str = "info") -> None:
        m = _m()
        lv = {"info": m.LogLevel.Info, "warning": m.LogLevel.Warning,
              "error": m.LogLevel.Error}[level]
        self.events_ch.log(m.Log(timestamp=stamp(t_ns), level=lv, message=text, name=self.uav),
                           log_time=t_ns)


def log_mission(ch: VehicleChannels, result: Any) -> None:
    """Every record of a finished mission (dualpilot.mission.result.MissionResult) on ``ch``,
    at its step's simulated start time; the final state when the mission ended."""
    spec: MissionSpec = result.spec
    area = area_view(spec)
    path: list[Array] = []
    ch.transform(0)
    ch.event(start_text(result.controller, spec.seed, f"timing={result.timing}"), 0)
    last_ns = 0
    risk_aware = any(r.risk is not None for r in result.records)  # else no /risk messages
    for r in result.records:
        t_ns = ns(r.time_s)
        last_ns = max(last_ns, t_ns)
        path.append(np.asarray(r.state[:2], dtype=float))
        ch.area(area, t_ns)
        ch.fires(fire_view(r.snapshot), t_ns)
        ch.vehicle(r.state, r.t, spec.d_safe_m, t_ns)
        ch.path(np.array(path), t_ns)
        ch.decision(decision_doc(r.decision, commanded_system(result.controller, r.decision),
                                 r.system, r.time_s), t_ns)
        ch.plans(plan_views(r.answers, r.system, r.planned_positions), r.t, t_ns)
        if r.risk is not None and r.risk.heat is not None:
            ch.forecast(occupancy_view(r.risk.heat), t_ns)
        if risk_aware:  # an empty update clears the last step's zones
            ch.risk(risk_view(r.risk), r.t, t_ns)
        ch.event(step_text(r.t, r.system, r.plan_status), t_ns,
                 "info" if r.system else "warning")
    if result.final_state is not None and result.records:
        end_ns = max(last_ns, ns(result.sim_time_s)) or last_ns + ns(spec.dynamics.dt_s)
        path.append(np.asarray(result.final_state[:2], dtype=float))
        ch.vehicle(result.final_state, result.steps, spec.d_safe_m, end_ns)
        ch.path(np.array(path), end_ns)
        ch.event(end_text(result.success, result.failure_cause, result.steps), end_ns,
                 "info" if result.success else "error")


def write_mcap(result: Any, out: Path, uav: str = "uav1") -> Path:
    """``out``/mission.mcap: the mission's channels (:class:`VehicleChannels`) from its records,
    log times on its simulated clock; written beside and renamed, so a reader never sees a
    half-written file."""
    fx = _fx()
    path = Path(out) / MCAP_FILE
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    context = fx.Context()
    try:
        with fx.open_mcap(str(tmp), allow_overwrite=True, context=context) as writer:
            writer.write_metadata("mission", {
                "uav": uav, "controller": str(result.controller), "seed": str(result.seed),
                "timing": str(result.timing), "success": str(bool(result.success)).lower(),
                "failure_cause": str(result.failure_cause), "steps": str(result.steps)})
            channels = VehicleChannels(uav, context)
            log_mission(channels, result)
            channels.close()
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path
