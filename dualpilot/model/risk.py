"""Forecast risk as planners use it: where P(inside a fire region) exceeds α, step by step.

A plan's step τ (position p_τ) is held while the fires run sub-steps
offset + [τ n, (τ+1) n] (:class:`ForecastView`: n sub-steps a step, the UAV
hovering at p_τ while the next plan is computed). Its *risk zones* are the
convex hulls of the connected groups of cells whose forecast P exceeds α at
some slice of that window (:meth:`RiskMap.zones`); a hull covers every cell
square of its group, so keeping a distance from the zones keeps it from every
risky cell. Past the forecast's horizon a step has no zones. Planners keep
their clearance from the zones of each step as a chance constraint, on top of
(never instead of) the current hulls. Lengths in m.

In 3-D a zone has the height of :class:`~dualpilot.model.zone_heights.ZoneHeights`
(the mission spec's ``zone_heights``, :func:`risk_map`): under the ``"band"`` reading it
is its footprint, as tall as every altitude, and positions are checked in the plane;
otherwise :meth:`RiskMap.zones` are prisms over [0, the zone's top] and every distance is
the exact 3-D one (:class:`~dualpilot.model.segment3.SegmentChecker3`).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import cast

import numpy as np

from dualpilot.arrays import AnyArray, Array
from dualpilot.lazy import lazy_module
from dualpilot.model.forecast import LEVELS, OccupancyForecast
from dualpilot.model.geometry import Polytope, SegmentChecker
from dualpilot.model.prism import Prism
from dualpilot.model.segment3 import SegmentChecker3
from dualpilot.model.zone_heights import BAND, ZoneHeights
from dualpilot.spec import MissionSpec

#: the risk zones' Numba kernels, loaded at their first use
_risk_kernels = lazy_module("dualpilot.model.risk_kernels")

#: A risk zone: its footprint (2-D, and 3-D under "band") or its prism (3-D with heights).
Zone = Polytope | Prism


@dataclass(frozen=True)
class RiskParams:
    """The chance constraint: avoid cells whose forecast occupancy exceeds ``alpha``.

    0.1 is a one-in-ten chance, eight times the births' steady background
    P ≈ p_b E[W]E[H] / (A²(1 − p_s)) = 0.012 of the paper's values (a lower α
    would make the whole area a zone).
    """

    alpha: float = 0.1

    def __post_init__(self) -> None:
        if not 0.0 <= self.alpha < 1.0:
            raise ValueError(f"alpha must be in [0, 1), got {self.alpha}")


@dataclass(frozen=True)
class ForecastView:
    """A forecast as a plan sees it: step τ is held during sub-steps
    ``offset_substeps`` + [τ·n, (τ+1)·n], n = ``substeps_per_step``."""

    forecast: OccupancyForecast
    substeps_per_step: int
    offset_substeps: int = 0

    def __post_init__(self) -> None:
        if self.substeps_per_step < 1 or self.offset_substeps < 0:
            raise ValueError("substeps_per_step >= 1 and offset_substeps >= 0 are required")

    def window(self, tau: int) -> tuple[int, int]:
        """The sub-steps (first, last) during which plan step ``tau`` is held."""
        n = self.substeps_per_step
        return self.offset_substeps + tau * n, self.offset_substeps + (tau + 1) * n

    @property
    def last_step(self) -> int:
        """The last plan step whose window starts within the forecast's horizon."""
        return max(-1, (self.forecast.max_substeps - self.offset_substeps)
                   // self.substeps_per_step)


@dataclass
class RiskMap:
    """The risk zones of a :class:`ForecastView`'s slices and plan steps at one α, as tall as
    ``heights`` says (:data:`~dualpilot.model.zone_heights.BAND`: footprints).

    A slice's zones are kept on its forecast (shared by every planner of the step).
    """

    view: ForecastView
    params: RiskParams = field(default_factory=RiskParams)
    heights: ZoneHeights = BAND
    _checkers: dict[tuple[int, int], SegmentChecker | SegmentChecker3] = field(
        default_factory=dict)

    @property
    def threshold(self) -> int:
        """The largest level that is not risky: P > α ⟺ level > ⌊255 α⌋."""
        return threshold_level(self.params.alpha)

    @property
    def planar(self) -> bool:
        """Whether the zones are footprints (as tall as every altitude)."""
        return self.heights.planar

    def slice_zones(self, i: int) -> tuple[Zone, ...]:
        """The zones of slice i: :meth:`slice_footprints`, or with heights each over
        [0, its top], the top of its highest cell's P (module docstring)."""
        bases = self.slice_footprints(i)
        if self.planar:
            return bases
        fc = self.view.forecast
        key = ("zone prisms", i, self.threshold, self.heights, self.params.alpha)
        got = fc.memo.get(key)
        if got is None:
            levels = group_max_levels(fc.level(i), self.threshold)
            got = tuple(Prism(b, 0.0, self.heights.top_for(int(lv) / LEVELS, self.params.alpha))
                        for b, lv in zip(bases, levels.tolist(), strict=True))
            fc.memo[key] = got
        return cast(tuple[Prism, ...], got)

    def slice_footprints(self, i: int) -> tuple[Polytope, ...]:
        """The footprints of slice i's zones: hulls of its groups of cells above the
        threshold (slices with the same risky cells share them)."""
        fc = self.view.forecast
        key = ("zones", i, self.threshold)
        got = fc.memo.get(key)
        if got is None:
            risky = fc.level(i) > self.threshold
            cells = ("zones of cells", risky.shape, risky.tobytes())
            got = fc.memo.get(cells)
            if got is None:
                got = cell_hulls(risky, fc.resolution_m, fc.origin_m)
                fc.memo[cells] = got
            fc.memo[key] = got
        return cast(tuple[Polytope, ...], got)

    def slices(self, tau: int) -> range:
        """The slices that stand for plan step ``tau``'s window."""
        return self.view.forecast.slices(*self.view.window(tau))

    def zones(self, tau: int) -> tuple[Zone, ...]:
        """The risk zones of plan step ``tau`` (none past the horizon): footprints, or prisms
        with heights."""
        return tuple(z for i in self.slices(tau) for z in self.slice_zones(i))

    def checker(self, tau: int) -> SegmentChecker | SegmentChecker3:
        """A :class:`SegmentChecker` of :meth:`zones` (a :class:`SegmentChecker3` of their
        prisms with heights), kept per slices: windows that stand on the same slices share
        it."""
        idx = self.slices(tau)
        key = (idx.start, idx.stop)
        got = self._checkers.get(key)
        if got is None:
            zones = self.zones(tau)
            got = (SegmentChecker(cast(tuple[Polytope, ...], zones)) if self.planar
                   else SegmentChecker3(cast(tuple[Prism, ...], zones)))
            self._checkers[key] = got
        return got

    def step_masks(self, steps: int, first: int = 1) -> list[tuple[Zone, AnyArray]]:
        """Each zone of the slices of steps first..``steps`` with the plan steps it applies to
        (a bool mask over τ = 0..steps), slice by slice (the windows move forward with τ,
        so that is the order in which the steps meet them)."""
        taus: dict[int, list[int]] = {}  # slice -> the steps whose window it stands for
        for tau in range(first, min(steps, self.view.last_step) + 1):
            for i in self.slices(tau):
                taus.setdefault(i, []).append(tau)
        out: list[tuple[Zone, AnyArray]] = []
        for i in sorted(taus):
            mask = np.zeros(steps + 1, dtype=bool)
            mask[taus[i]] = True
            out.extend((z, mask.copy()) for z in self.slice_zones(i))
        return out


def risk_map(view: ForecastView, params: RiskParams, spec: MissionSpec) -> RiskMap:
    """The :class:`RiskMap` of the mission of ``spec``: its zones as tall as the spec's
    ``zone_heights`` in 3-D, footprints in 2-D (what every consumer of the zones reads)."""
    return RiskMap(view, params, spec.zone_heights if spec.dim == 3 else BAND)


def group_max_levels(level: np.ndarray, threshold: int) -> AnyArray:
    """The largest forecast level of each 8-connected group of cells above ``threshold``, in
    :func:`cell_hulls`' order of the groups."""
    risky = np.ascontiguousarray(np.asarray(level) > threshold, dtype=np.bool_)
    comp, row, first, last = _risk_kernels().groups(risky)
    out = np.zeros(int(comp.max()) + 1 if len(comp) else 0, dtype=np.int64)
    for k, r, a, b in zip(comp.tolist(), row.tolist(), first.tolist(), last.tolist(),
                          strict=True):
        out[k] = max(int(out[k]), int(np.max(level[r, a:b + 1])))
    return out


def threshold_level(alpha: float) -> int:
    """The largest forecast level (1/255) whose probability is not above ``alpha``."""
    return int(np.floor(alpha * LEVELS + 1e-9))


def cell_hulls(risky: np.ndarray, resolution_m: float,
               origin_m: tuple[float, float] = (0.0, 0.0)) -> tuple[Polytope, ...]:
    """The convex hull of the cell squares of each 8-connected group of ``risky`` cells."""
    kernels = _risk_kernels()
    comp, row, first, last = kernels.groups(np.ascontiguousarray(risky, dtype=np.bool_))
    if not len(comp):
        return ()
    verts, normals, offsets, ends = kernels.group_hulls(comp, row, first, last, float(resolution_m),
                                                float(origin_m[0]), float(origin_m[1]))
    starts = np.concatenate([[0], ends[:-1]])
    return tuple(Polytope(vertices=verts[a:b], A=normals[a:b], b=offsets[a:b])
                 for a, b in zip(starts.tolist(), ends.tolist(), strict=True))


def path_risk_clearance(risk: RiskMap, positions: Array, first: int = 1) -> float:
    """The least distance (m) of the segments p_{τ−1}–p_τ from the zones of step τ (τ ≥ first).

    ``positions`` (k, 2) or (k, 3): the ground track is measured against footprints, the
    3-D positions against prisms (zones with heights)."""
    pts = np.asarray(positions, dtype=float)
    pts = pts.reshape(-1, 2) if risk.planar and pts.ndim == 1 else pts
    if pts.ndim != 2 or pts.shape[1] < (2 if risk.planar else 3):
        raise ValueError(f"positions of shape {pts.shape} for zones "
                         f"{'in the plane' if risk.planar else 'with heights'}")
    pts = pts[:, :2] if risk.planar else pts[:, :3]
    worst = float("inf")
    for tau in range(max(first, 1), min(len(pts) - 1, risk.view.last_step) + 1):
        checker = risk.checker(tau)
        if _count(checker):
            worst = min(worst, checker.path_clearance(pts[tau - 1:tau + 1]))
    return worst


def _count(checker: SegmentChecker | SegmentChecker3) -> int:
    """How many zones ``checker`` holds."""
    return checker.n_hulls if isinstance(checker, SegmentChecker) else checker.n_prisms


class ArcRisk:
    """Risk zones along a path flown at ``speed_mps``: the point s metres along it is passed
    in plan step ⌈s / (v ΔT)⌉ (System 1's reading of arrival time, its reference speed).

    The path is planar; with zones that have heights it is flown level at ``altitude_m``
    (the slice of a 3-D System 1) and measured to the prisms."""

    def __init__(self, risk: RiskMap, speed_mps: float, dt_s: float, clearance_m: float,
                 altitude_m: float | None = None):
        if not (speed_mps > 0 and dt_s > 0 and clearance_m >= 0):
            raise ValueError("speed_mps > 0, dt_s > 0 and clearance_m >= 0 are required")
        if not risk.planar and altitude_m is None:
            raise ValueError("zones with heights need the path's altitude")
        self.altitude_m = altitude_m
        self.risk = risk
        self.step_m = speed_mps * dt_s
        self.clearance_m = clearance_m
        self.last_step = risk.view.last_step

    def segment_clear(self, x0: float, y0: float, x1: float, y1: float, s0: float) -> bool:
        """Whether the segment, started ``s0`` m along the path, keeps the clearance from the
        zones of every step it is flown in (pieces split where a step ends)."""
        length = float(np.hypot(x1 - x0, y1 - y0))
        tau = max(1, int(np.ceil(s0 / self.step_m - 1e-12)))
        a = 0.0  # the piece's start, as a fraction of the segment
        while a < 1.0 and tau <= self.last_step:
            end_s = tau * self.step_m  # where step tau's part of the path ends
            b = 1.0 if length <= 0 else min(1.0, max(a, (end_s - s0) / length))
            if not self._piece_clear(tau, x0 + a * (x1 - x0), y0 + a * (y1 - y0),
                                     x0 + b * (x1 - x0), y0 + b * (y1 - y0)):
                return False
            a, tau = b, tau + 1
        return True

    def at(self, altitude_m: float) -> ArcRisk:
        """This timing of the zones for a level path at ``altitude_m`` (itself for
        footprints)."""
        if self.risk.planar or altitude_m == self.altitude_m:
            return self
        out = copy.copy(self)
        out.altitude_m = altitude_m
        return out

    def _piece_clear(self, tau: int, xa: float, ya: float, xb: float, yb: float) -> bool:
        """Whether the piece keeps the clearance from step ``tau``'s zones."""
        checker = self.risk.checker(tau)
        if isinstance(checker, SegmentChecker):
            return not checker.n_hulls or checker.segment_clear(xa, ya, xb, yb, self.clearance_m)
        z = float(cast(float, self.altitude_m))
        return not checker.n_prisms or checker.segment_clear(xa, ya, z, xb, yb, z,
                                                             self.clearance_m)

    def path_clear(self, points: Array, s0: float = 0.0) -> bool:
        """:meth:`segment_clear` of every segment of the polyline ``points``, the first at s0."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        s = s0
        for (x0, y0), (x1, y1) in zip(pts[:-1].tolist(), pts[1:].tolist(), strict=True):
            if not self.segment_clear(x0, y0, x1, y1, s):
                return False
            s += float(np.hypot(x1 - x0, y1 - y0))
        return True


@dataclass(frozen=True)
class RiskNote:
    """What a flown plan was made against, as the records keep it (small: one slice and
    polygons, not the forecast): P at the start of the plan's next step (``heat``, a
    one-slice forecast; None past the horizon) and the distinct risk zones of its steps
    1..T at ``alpha``."""

    heat: OccupancyForecast | None
    zones: tuple[Polytope, ...]
    alpha: float


def risk_note(view: ForecastView, params: RiskParams, steps: int) -> RiskNote:
    """The :class:`RiskNote` of a plan of ``steps`` steps made on ``view`` (the zones come
    from the forecast's memo when a planner or the monitor made them already)."""
    fc = view.forecast
    near = fc.slices(*view.window(1))
    heat = None
    if len(near):
        i = near[0]
        layer = np.array(fc.level(i))  # a copy: the note must not keep the forecast alive
        heat = OccupancyForecast(fc.resolution_m, fc.substep_s, (fc.horizons[i],), [layer],
                                 fc.origin_m, fc.issued_substep, fc.substeps_per_step)
    zones = tuple(cast(Polytope, z) for z, _ in RiskMap(view, params).step_masks(steps, first=1))
    return RiskNote(heat, zones, params.alpha)
