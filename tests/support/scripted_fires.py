"""Fires written out by hand: each front a box as a function of the sub-step, for the oracle's
tests.

A :class:`ScriptedFire` is both what the oracle reads of a fire future (regions per
sub-step, the fronts new at each) and, through :meth:`ScriptedFire.port`, a fire port
the mission step flies against (:class:`dualpilot.mission.ports.FirePort`, with the
fires' exact forecast): the same boxes at the same sub-steps, so a witness is checked
against the very fires it was planned on. The fires do not depend on the UAV or on the
step length. A front may have a height (``top_m``, m): the port then reports the cuboids of
a 3-D fire (every front of a fire with a top, or none).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from dualpilot.arrays import AnyArray, Array
from dualpilot.mission.ports import KeepOut
from dualpilot.model.fire import FireSnapshot, Region
from dualpilot.model.forecast import OccupancyForecast
from dualpilot.model.geometry import Rect
from dualpilot.model.prism import Cuboid

Box = Callable[[int], Rect]


@dataclass(frozen=True)
class ScriptedFront:
    """A front that exists after sub-steps ``born``..``dies - 1`` with the region ``box(s)``."""

    front_id: int
    box: Box
    born: int = 0
    dies: int | None = None
    top_m: float | None = None

    def active(self, s: int) -> bool:
        return self.born <= s and (self.dies is None or s < self.dies)


def moving_box(x0: float, y0: float, x1: float, y1: float, vx: float = 0.0,
               vy: float = 0.0) -> Box:
    """The box [x0, x1] × [y0, y1] moved by (vx, vy) m every sub-step."""
    return lambda s: Rect((x0 + x1) / 2 + vx * s, (y0 + y1) / 2 + vy * s, x1 - x0, y1 - y0)


class ScriptedFire:
    """Fronts by hand (:class:`ScriptedFront`), one step = ``substeps_per_step`` sub-steps."""

    schedule_free = True

    def __init__(self, fronts: Sequence[ScriptedFront], substeps_per_step: int = 1):
        self.fronts = tuple(fronts)
        self.substeps_per_step = substeps_per_step
        tall = {f.top_m is None for f in self.fronts}
        if len(tall) > 1:
            raise ValueError("every front of a scripted fire has a top, or none")

    def active(self, s: int) -> list[tuple[ScriptedFront, Rect]]:
        return [(f, f.box(s)) for f in self.fronts if f.active(s)]

    def regions(self, s: int) -> Array:
        return np.array([r.bounds for _, r in self.active(s)], dtype=float).reshape(-1, 4)

    def newborn(self, s: int) -> Array:
        return np.array([r.bounds for f, r in self.active(s) if f.born == s],
                        dtype=float).reshape(-1, 4)

    def packed(self, substeps: int) -> tuple[Array, AnyArray]:
        parts = [self.regions(s) for s in range(substeps + 1)]
        offsets = np.zeros(len(parts) + 1, dtype=np.int64)
        offsets[1:] = np.cumsum([len(p) for p in parts])
        return np.vstack(parts), offsets

    def port(self) -> ScriptedFirePort:
        """A fire port at sub-step 0 of these fires."""
        return ScriptedFirePort(self)

    def cuboids(self) -> ScriptedCuboids:
        """These fires as the oracle's 3-D future reads them: rows with the tops."""
        return ScriptedCuboids(self)


class ScriptedCuboids:
    """A :class:`ScriptedFire` of fronts with tops whose regions are rows (x_lo, y_lo, x_hi,
    y_hi, top) (m): the oracle's future of a 3-D mission (dualpilot/oracle/future.py)."""

    schedule_free = True
    width = 5

    def __init__(self, fire: ScriptedFire):
        if any(f.top_m is None for f in fire.fronts):
            raise ValueError("every front needs a top")
        self.fire = fire
        self.substeps_per_step = fire.substeps_per_step

    def _rows(self, s: int, newborn: bool) -> Array:
        return np.array([(*r.bounds, f.top_m) for f, r in self.fire.active(s)
                         if not newborn or f.born == s], dtype=float).reshape(-1, 5)

    def regions(self, s: int) -> Array:
        return self._rows(s, False)

    def newborn(self, s: int) -> Array:
        return self._rows(s, True)

    def packed(self, substeps: int) -> tuple[Array, AnyArray]:
        parts = [self.regions(s) for s in range(substeps + 1)]
        offsets = np.zeros(len(parts) + 1, dtype=np.int64)
        offsets[1:] = np.cumsum([len(p) for p in parts])
        return np.vstack(parts), offsets


class ScriptedFirePort:
    """The fire port of a :class:`ScriptedFire` (dualpilot.mission.ports.FirePort)."""

    def __init__(self, fire: ScriptedFire):
        self.fire = fire
        self.s = 0

    def snapshot(self) -> FireSnapshot:
        active = self.fire.active(self.s)
        tops = tuple(float(f.top_m) for f, _ in active if f.top_m is not None)
        return FireSnapshot(regions=tuple(r for _, r in active),
                            hulls=tuple(r.polytope() for _, r in active),
                            front_ids=tuple(f.front_id for f, _ in active),
                            born_steps=tuple(f.born for f, _ in active),
                            tops_m=tops, hull_tops_m=tops)

    def margin_m(self) -> float:
        return 0.0

    def forecast(self, substeps_per_step: int) -> OccupancyForecast:
        """The exact forecast of these fires from now, 40 s ahead in slices of 1 s."""
        return rasterised(self.fire, self.s, tuple(range(0, 81, 2)))

    def advance(self, t: int, n: int, keep_out: KeepOut | None) -> list[tuple[Region, ...]]:
        out = []
        for _ in range(n):
            self.s += 1
            out.append(tuple(r if f.top_m is None else Cuboid(r, f.top_m)
                             for f, r in self.fire.active(self.s)))
        return out


def rasterised(fire: ScriptedFire, issued: int, horizons: tuple[int, ...],
               resolution_m: float = 10.0, area_m: float = 1000.0,
               substep_s: float = 0.5) -> OccupancyForecast:
    """The scripted fires' exact forecast: P = 1 in the cells whose centre lies in a region
    ``h`` sub-steps after ``issued``, 0 elsewhere, for each horizon h."""
    n = round(area_m / resolution_m)
    centres = (np.arange(n) + 0.5) * resolution_m
    xs, ys = np.meshgrid(centres, centres)
    levels = []
    for h in horizons:
        lv = np.zeros((n, n), dtype=np.uint8)
        for _, r in fire.active(issued + h):
            x0, y0, x1, y1 = r.bounds
            lv[(xs >= x0) & (xs <= x1) & (ys >= y0) & (ys <= y1)] = 255
        levels.append(lv)
    return OccupancyForecast(resolution_m, substep_s, horizons, levels, issued_substep=issued)
