"""System 1's tree in ℝ³ (docs/three_d.md, System 1): Alg. 1 over the area and the band.

OMPL's RRT in a 3-D RealVectorStateSpace over [0, A]² × [floor, ceiling], range 15 m
(Sec. IV-A), with the planar tree's habits (:mod:`dualpilot.system1.rrt`): PathFree is
exact (:class:`ExactMotionValidator3`: the whole segment keeps ``clearance_m`` from every
prism, :class:`~dualpilot.model.segment3.SegmentChecker3`); every sample comes from our
``numpy.random.Generator`` — its (x, y) drawn as the planar tree draws them (G's
rectangle with the goal bias, else the area, restricted to and later guided along the
planar grid test's cells), its z uniform over the band; the path is shortcut greedily.
The grid test is planar and sound in 3-D (:func:`dualpilot.system1.reach.band_blockers`).

Before the tree (:func:`_direct3`): a start in G; the straight segment to G_o; and the
climb-over, the pilot's move over a low fire: climb to ``clearance_m`` above the
tallest prism the straight line's ground track passes within ``clearance_m`` of, cruise
to above G_o at that altitude, then (as every path) on to G_o when that is free.

Lengths are metres, times seconds; positions [x, y, z] with z up.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou

from dualpilot.arrays import Array
from dualpilot.model.altitude import AltitudeBand, GoalBox
from dualpilot.model.geometry import SegmentChecker
from dualpilot.model.prism import Prism
from dualpilot.model.segment3 import SegmentChecker3
from dualpilot.system1.reach import BoolArray, band_blockers, start_component
from dualpilot.system1.rrt import (
    ExactMotionValidator,
    RrtParams,
    RrtResult,
    _NumpyDrivenGoal,
    _OmplRrt,
    _Query,
    grow_tree,
    shortcut,
)


@dataclass(frozen=True)
class Query3:
    """One :func:`plan_path3` call: the start ``p`` (3,), G, the band and what every stage
    needs; ``planar`` is the ground-track query of the grid test and the tree's clock."""

    p: Array
    goal: GoalBox
    band: AltitudeBand
    checker: SegmentChecker3
    prisms: Sequence[Prism]
    clearance_m: float
    root_clearance_m: float
    planar: _Query

    @property
    def params(self) -> RrtParams:
        return self.planar.params

    def result(self, status: str, iterations: int) -> RrtResult:
        """No path: ``status`` after ``iterations`` samples."""
        return self.planar.result(status, iterations)


class ExactMotionValidator3(ExactMotionValidator):
    """PathFree in ℝ³: a motion is valid iff its segment keeps the clearance from every prism
    (one leaving the tree's root keeps ``root_clearance_m``)."""

    def __init__(self, si: ob.SpaceInformation, checker: SegmentChecker3, clearance_m: float,
                 root: Array, root_clearance_m: float):
        ob.MotionValidator.__init__(self, si)
        self._checker3 = checker
        self._clearance = clearance_m
        self._root3 = (float(root[0]), float(root[1]), float(root[2]))
        self._root_clearance = root_clearance_m
        self.on_accept = None

    def checkMotion(self, s1: ob.State, s2: ob.State) -> bool:  # noqa: N802 (OMPL API)
        a = (s1[0], s1[1], s1[2])
        need = self._root_clearance if a == self._root3 else self._clearance
        ok = self._checker3.segment_clear(a[0], a[1], a[2], s2[0], s2[1], s2[2], need)
        if ok and self.on_accept is not None:
            self.on_accept(s2[0], s2[1])  # the planar guide follows the tree's ground track
        return ok


class _BandSampler(_NumpyDrivenGoal):
    """The planar sampler's (x, y) with z uniform over the band, from the same generator;
    the goal is the 3-D box G."""

    def __init__(self, si: ob.SpaceInformation, goal: GoalBox, band: AltitudeBand,
                 area_size_m: float, rng: np.random.Generator, bias: float):
        super().__init__(si, goal.rect, area_size_m, rng, bias)
        self._z_lo, self._z_span = float(band.floor_m), float(band.thickness_m)
        self._gz = (float(goal.z_lo), float(goal.z_hi))
        self._zs: list[float] = []

    def sampleGoal(self, st: ob.State) -> None:  # noqa: N802 (OMPL API)
        super().sampleGoal(st)
        if not self._zs:
            self._zs = (self._z_lo + self._z_span * self._rng.random(256)).tolist()
        st[2] = self._zs.pop()

    def distanceGoal(self, st: ob.State) -> float:  # noqa: N802 (OMPL API)
        x, y, z = st[0], st[1], st[2]
        gx = max(0.0, self._lo[0] - x, x - self._hi[0])
        gy = max(0.0, self._lo[1] - y, y - self._hi[1])
        gz = max(0.0, self._gz[0] - z, z - self._gz[1])
        return (gx * gx + gy * gy + gz * gz) ** 0.5


class _OmplRrt3(_OmplRrt):
    """OMPL's RRT over [0, A]² × [floor, ceiling] with :class:`ExactMotionValidator3` and
    :class:`_BandSampler`; :meth:`grow` and the guidance are the planar tree's."""

    def __init__(self, q: Query3, rng: np.random.Generator, component: BoolArray | None):
        params, area = q.params, float(q.planar.area_size_m)
        self._q = q.planar
        self._p3 = q.p
        ou.setLogLevel(ou.LOG_WARN)
        space = ob.RealVectorStateSpace(3)
        bounds = ob.RealVectorBounds(3)
        bounds.setLow(0.0)
        bounds.setHigh(area)
        bounds.setLow(2, float(q.band.floor_m))
        bounds.setHigh(2, float(q.band.ceiling_m))
        space.setBounds(bounds)
        si = ob.SpaceInformation(space)
        si.setStateValidityChecker(lambda s: True)  # states are judged by the motion check
        validator = ExactMotionValidator3(si, q.checker, q.clearance_m, q.p, q.root_clearance_m)
        si.setMotionValidator(validator)
        si.setup()
        start_state = space.allocState()
        start_state[0], start_state[1], start_state[2] = (float(v) for v in q.p)
        sampler = _BandSampler(si, q.goal, q.band, area, rng, params.goal_bias)
        if component is not None and params.sample_reachable:
            sampler.restrict_to(component, params.reach_cell_m)
        pdef = ob.ProblemDefinition(si)
        pdef.addStartState(start_state)
        pdef.setGoal(sampler)
        rrt = og.RRT(si)
        rrt.setRange(params.step_size_m)
        rrt.setGoalBias(1.0)  # every sample goes through sampler.sampleGoal (our rng)
        rrt.setProblemDefinition(pdef)
        rrt.setup()
        self._space, self._si, self._start_state = space, si, start_state
        self.validator, self.sampler, self.pdef, self.rrt = validator, sampler, pdef, rrt

    def path(self) -> Array:
        """The solution path (k, 3) through the tree, starting exactly at the start."""
        sol = self.pdef.getSolutionPath()
        tree = np.array([[sol.getState(i)[0], sol.getState(i)[1], sol.getState(i)[2]]
                         for i in range(sol.getStateCount())])
        tree[0] = self._p3
        return tree


def _clear(q: Query3, a: Array, b: Array, need: float) -> bool:
    return q.checker.segment_clear(float(a[0]), float(a[1]), float(a[2]), float(b[0]),
                                   float(b[1]), float(b[2]), need)


def _finish3(q: Query3, path: Array, status: str, iterations: int,
             tree: Array | None) -> RrtResult:
    """The result for ``path`` (k, 3): extended to G_o when free, then shortcut (as set)."""
    params, center = q.params, q.goal.center
    if params.aim_goal_center and not np.allclose(path[-1], center):
        first = q.root_clearance_m if len(path) == 1 else q.clearance_m
        if _clear(q, path[-1], center, first):
            path = np.vstack([path, center])
    if params.shortcut:
        path = shortcut(path, q.checker, q.clearance_m, q.root_clearance_m)
    return RrtResult(path, status, iterations, time.perf_counter() - q.planar.t0, tree)


def climb_altitude(q: Query3, target: Array) -> float | None:
    """The cruise altitude (m) of the climb-over from the start to ``target``: ``clearance_m``
    above the tallest prism whose base the ground track passes within ``clearance_m`` of,
    and not below the start; None when no prism is in the way or the altitude leaves the
    band."""
    a, b = q.p[:2], target[:2]
    tops = [p.z_hi for p in q.prisms if p.base.segment_distance(a, b) < q.clearance_m]
    if not tops:
        return None
    z = max(max(tops) + q.clearance_m, float(q.p[2]))
    return z if z <= q.band.ceiling_m else None


def _direct3(q: Query3) -> RrtResult | None:
    """A start inside G, a free straight segment into G, or a free climb-over; else None."""
    p, goal, params = q.p, q.goal, q.params
    if goal.contains(p):
        return _finish3(q, p[None].copy(), "direct", 0, None)
    if not params.try_direct:
        return None
    target = goal.center if params.aim_goal_center else np.clip(p, goal.lo, goal.hi)
    if _clear(q, p, target, q.root_clearance_m):
        return _finish3(q, np.vstack([p, target]), "direct", 0, None)
    z = climb_altitude(q, target)
    if z is None:
        return None
    up = np.array([p[0], p[1], z])
    over = np.array([target[0], target[1], z])
    if _clear(q, p, up, q.root_clearance_m) and _clear(q, up, over, q.clearance_m):
        return _finish3(q, np.vstack([p, up, over]), "direct", 0, None)
    return None


def _validate3(start: Array, goal: GoalBox, band: AltitudeBand, area_size_m: float) -> Array:
    p = np.asarray(start, dtype=float).reshape(-1)[:3]
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError(f"start must be a finite 3-D position, got {start}")
    if not (np.isfinite(area_size_m) and area_size_m > 0):
        raise ValueError(f"area_size_m must be positive, got {area_size_m}")
    if not (0.0 <= p[0] <= area_size_m and 0.0 <= p[1] <= area_size_m and band.contains(p[2])):
        raise ValueError(f"start {p} lies outside the {area_size_m} m area and the band "
                         f"[{band.floor_m:g}, {band.ceiling_m:g}] m")
    lo, hi = goal.lo, goal.hi
    if np.any(lo[:2] < 0) or np.any(hi[:2] > area_size_m) or not (
            band.contains(goal.z_lo) and band.contains(goal.z_hi)):
        raise ValueError(f"goal {goal} lies outside the area and the band")
    return p


def _query(start: Array, goal: GoalBox, prisms: Sequence[Prism], band: AltitudeBand,
           clearance_m: float, area_size_m: float, params: RrtParams,
           start_clearance_m: float | None, checker: SegmentChecker3 | None) -> Query3:
    """The validated :class:`Query3` (ValueError as :func:`plan_path3` says)."""
    t0, cpu0 = time.perf_counter(), time.thread_time()
    p = _validate3(start, goal, band, area_size_m)
    checker = SegmentChecker3(prisms) if checker is None else checker
    if clearance_m < 0:
        raise ValueError(f"clearance_m must be >= 0, got {clearance_m}")
    need_start = clearance_m if start_clearance_m is None else start_clearance_m
    d_start = checker.point_distance(p)
    if d_start < need_start:
        raise ValueError(f"start {p} lies {d_start:.1f} m from a fire prism "
                         f"(needs {need_start:.1f} m)")
    root = min(clearance_m, d_start)
    blockers = band_blockers(prisms, band)
    planar = _Query(p[:2].copy(), goal.rect, blockers, SegmentChecker(blockers), clearance_m,
                    root, area_size_m, params, None, t0, cpu0)
    return Query3(p, goal, band, checker, tuple(prisms), clearance_m, root, planar)


def plan_path3(start: Array, goal: GoalBox, prisms: Sequence[Prism], rng: np.random.Generator,
               clearance_m: float, area_size_m: float, band: AltitudeBand,
               params: RrtParams | None = None, start_clearance_m: float | None = None,
               checker: SegmentChecker3 | None = None) -> RrtResult:
    """Alg. 1 in ℝ³: a path (k, 3) from ``start`` into the box ``goal`` keeping
    ``clearance_m`` from every prism, within [0, ``area_size_m``]² × the band.

    ``params`` default to :class:`RrtParams`'s; ``start_clearance_m`` as in
    :func:`dualpilot.system1.rrt.plan_path` (an escape's first edges keep the start's own
    clearance). Raises ValueError for a start outside
    the area or the band, a goal outside them, or a start nearer than
    ``start_clearance_m`` to a prism; no path within the caps is a result.
    """
    params = RrtParams() if params is None else params
    q = _query(start, goal, prisms, band, clearance_m, area_size_m, params,
               start_clearance_m, checker)
    direct = _direct3(q)
    if direct is not None:
        return direct
    component = None
    planar = q.planar
    if params.reach_check and len(planar.hulls):
        component, meets_goal = start_component(
            planar.p, goal.rect, planar.hulls, clearance_m, area_size_m, params.reach_cell_m,
            start_clearance_m=q.root_clearance_m, start_radius_m=params.step_size_m)
        if not meets_goal:
            return q.result("unreachable", 0)
    tree = _OmplRrt3(q, rng, component)
    failed = grow_tree(q, planar, tree, component)
    if failed is not None:
        return failed
    path = tree.path()
    return _finish3(q, path, "exact", tree.sampler.count, path)
