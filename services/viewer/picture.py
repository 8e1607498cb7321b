"""The operations picture: every vehicle's latest scene, as plain data the web page draws.

A :class:`VehicleScene` takes the same calls as a vehicle's Foxglove channels
(dualpilot/viz/foxglove.py ``VehicleChannels``: area, fires, forecast, risk,
plans, vehicle, path, decision, event) and keeps the newest of each, with the
history of decisions (Ψ_t over the steps) and the last events. A
:class:`Picture` holds the fleet's scenes behind one lock: the viewer's loop
writes, the web page's sessions read a :class:`Frame` (an immutable copy) a few
times a second. Positions are in ``world`` (m): a vehicle's mission frame
shifted by its offset, the k-th area k·(A + 100 m) east of the first, as in
the Foxglove view.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from dualpilot.mission.answers import PlanView
from dualpilot.model.dynamics import Array
from dualpilot.viz.scene import AreaView, FireView, OccupancyView, RiskView, top_down

#: decisions kept per vehicle (the Ψ plot's history); a mission has a few hundred steps
MAX_DECISIONS = 2000
#: events kept per vehicle (the page shows the newest)
MAX_EVENTS = 50
#: layers a page redraws only when they changed
LAYERS = ("area", "fires", "forecast", "risk", "plans", "vehicle", "path", "decision", "event")


@dataclass(frozen=True)
class VehicleFrame:
    """One vehicle's scene at one moment (what a page draws), ``world`` offset included."""

    uav: str
    offset_m: tuple[float, float]
    area: AreaView | None = None
    fires: FireView | None = None
    forecast: OccupancyView | None = None
    risk: RiskView | None = None
    plans: tuple[PlanView, ...] = ()
    plan_step: int = -1
    state: Array | None = None  # (4,): east, north (m), v_east, v_north (m/s)
    altitude_m: float | None = None  # a 3-D mission's p_z (m); None in 2-D
    step: int = -1
    d_safe_m: float = 0.0
    path: Array = field(default_factory=lambda: np.empty((0, 2)))
    path_altitudes: tuple[float, ...] = ()  # a 3-D mission's p_z (m) at each point of path
    decisions: tuple[dict[str, Any], ...] = ()  # decision_doc of each step, oldest first
    events: tuple[tuple[int, str, str], ...] = ()  # (log time ns, level, text), oldest first
    versions: tuple[int, ...] = (0,) * len(LAYERS)  # one counter a layer (LAYERS)
    updated_ns: int = 0  # log time of the newest message

    def version(self, layer: str) -> int:
        return self.versions[LAYERS.index(layer)]

    @property
    def decision(self) -> dict[str, Any] | None:
        """The newest step's decision (Ξ, P, A, Ψ, S_t, the flown system), None before one."""
        return self.decisions[-1] if self.decisions else None


@dataclass(frozen=True)
class Frame:
    """The whole picture at one moment: every vehicle in the order first seen."""

    vehicles: tuple[VehicleFrame, ...] = ()
    version: int = 0  # grows with every change

    def layer_key(self, layer: str) -> tuple[tuple[str, int], ...]:
        """What a page compares to know whether ``layer`` changed since it last drew it."""
        return tuple((v.uav, v.version(layer)) for v in self.vehicles)


class VehicleScene:
    """One vehicle's newest scene; the methods are those of ``VehicleChannels`` (the same
    views, the same arguments), so the live viewer and a replay feed both alike."""

    def __init__(self, picture: Picture, uav: str, offset_m: tuple[float, float]):
        self._picture = picture
        self._frame = VehicleFrame(uav, (float(offset_m[0]), float(offset_m[1])))
        self._decisions: deque[dict[str, Any]] = deque(maxlen=MAX_DECISIONS)
        self._events: deque[tuple[int, str, str]] = deque(maxlen=MAX_EVENTS)

    @property
    def frame(self) -> VehicleFrame:
        return self._frame

    def _set(self, layer: str, t_ns: int, **changes: Any) -> None:
        with self._picture.lock:
            f = self._frame
            v = list(f.versions)
            v[LAYERS.index(layer)] += 1
            self._frame = replace(f, versions=tuple(v), updated_ns=max(f.updated_ns, t_ns),
                                  **changes)
            self._picture.changed()

    # -- the calls of VehicleChannels --------------------------------------------------------------
    def transform(self, t_ns: int) -> None:
        """The area's place in ``world`` is fixed when the scene is made: nothing to do."""

    def area(self, view: AreaView, t_ns: int) -> None:
        self._set("area", t_ns, area=view)

    def fires(self, view: FireView, t_ns: int) -> None:
        self._set("fires", t_ns, fires=view)

    def forecast(self, view: OccupancyView, t_ns: int) -> None:
        self._set("forecast", t_ns, forecast=view)

    def risk(self, view: RiskView, t: int, t_ns: int) -> None:
        self._set("risk", t_ns, risk=view)

    def plans(self, views: Sequence[PlanView], t: int, t_ns: int) -> None:
        self._set("plans", t_ns, plans=tuple(views), plan_step=int(t))

    def vehicle(self, state: Array, t: int, d_safe_m: float, t_ns: int) -> None:
        """The vehicle's state (2-D, or 3-D: kept from above, with its altitude)."""
        planar, z, _ = top_down(state)
        self._set("vehicle", t_ns, state=np.array(planar, dtype=float), altitude_m=z,
                  step=int(t), d_safe_m=float(d_safe_m))

    def path(self, positions: Array, t_ns: int) -> None:
        """The flown path: (n, 2) positions, or a 3-D mission's (n, 3) with its altitudes."""
        p = np.array(positions, dtype=float)
        if p.ndim == 2 and p.shape[1] == 3:
            self._set("path", t_ns, path=p[:, :2].copy(),
                      path_altitudes=tuple(float(z) for z in p[:, 2]))
        else:
            self._set("path", t_ns, path=p.reshape(-1, 2), path_altitudes=())

    def decision(self, doc: dict[str, object], t_ns: int) -> None:
        with self._picture.lock:
            self._decisions.append(dict(doc))
            self._set("decision", t_ns, decisions=tuple(self._decisions))

    def event(self, text: str, t_ns: int, level: str = "info") -> None:
        with self._picture.lock:
            self._events.append((int(t_ns), level, text))
            self._set("event", t_ns, events=tuple(self._events))

    def new_mission(self) -> None:
        """A new mission on this vehicle: forget the last one's decisions."""
        with self._picture.lock:
            self._decisions.clear()
            self._set("decision", 0, decisions=())


class Picture:
    """Every vehicle's scene, behind one lock (written by the viewer, read by the page)."""

    def __init__(self) -> None:
        self.lock = threading.RLock()
        self._scenes: dict[str, VehicleScene] = {}
        self._version = 0

    def changed(self) -> None:
        with self.lock:
            self._version += 1

    def scene(self, uav: str, offset_m: tuple[float, float] = (0.0, 0.0)) -> VehicleScene:
        """``uav``'s scene, made (at ``offset_m`` in ``world``) when first asked for."""
        with self.lock:
            got = self._scenes.get(uav)
            if got is None:
                got = self._scenes[uav] = VehicleScene(self, uav, offset_m)
                self._version += 1
            return got

    def frame(self) -> Frame:
        with self.lock:
            return Frame(tuple(s.frame for s in self._scenes.values()), self._version)
