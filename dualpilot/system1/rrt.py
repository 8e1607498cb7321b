"""System 1's path planner, Alg. 1: an RRT from the UAV's position to the goal region G.

OMPL's RRT (``ompl`` 2.x) in a 2-D RealVectorStateSpace over the area, range
15 m (Sec. IV-A). PathFree (Alg. 1, line 8) is exact
(:class:`ExactMotionValidator`: the whole segment keeps ``clearance_m`` from
every hull △(C^i_{1:t})); every sample comes from our
``numpy.random.Generator``, so a seed gives the same path; a grid test
(:mod:`dualpilot.system1.reach`) proves G unreachable or narrows the samples;
the path is shortcut greedily. The readings of the paper's loose points are
the fields of :class:`RrtParams`.

Lengths are metres, times seconds.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou

from dualpilot.arrays import Array
from dualpilot.model.geometry import Polytope, Rect, SegmentChecker
from dualpilot.model.risk import ArcRisk
from dualpilot.model.segment3 import SegmentChecker3
from dualpilot.system1.reach import BoolArray, coarsen, corridor, start_component


@dataclass(frozen=True)
class RrtParams:
    """Alg. 1 settings. ``step_size_m`` is the paper's 15 m; see the module docstring.

    ``max_iterations`` defaults to 2000 rather than the paper's 500: on
    random fire fields of Sec. IV-A with a path to G, 500 samples failed on
    19 % of instances and 2000 on 0.6 % (median 311, p95 ≈ 1130 iterations;
    README, "System 1's iteration cap"). ``max_cpu_s`` is a safety cap on the planning
    thread's CPU time (s, ``time.thread_time``), not wall time: a search ends where it
    would on an idle machine however loaded the machine is, so a mission is the same
    mission under load (the in-process loop, the stack and the tests).
    ``reach_check`` runs the grid test of :mod:`dualpilot.system1.reach` on cells of
    ``reach_cell_m`` before the tree is grown; ``sample_reachable`` then
    draws area samples from the start's possibly-free component only.
    """

    step_size_m: float = 15.0
    max_iterations: int = 2000
    goal_bias: float = 0.05
    max_cpu_s: float = 2.0
    shortcut: bool = True
    aim_goal_center: bool = True
    try_direct: bool = True
    reach_check: bool = True
    reach_cell_m: float = 10.0
    sample_reachable: bool = True
    guide_after: int = 500
    guide_share: float = 0.5
    guide_window: int = 5

    def __post_init__(self) -> None:
        if not (self.step_size_m > 0 and self.max_iterations >= 1 and self.max_cpu_s > 0
                and self.reach_cell_m > 0 and self.guide_after >= 1 and self.guide_window >= 1):
            raise ValueError("step_size_m, max_iterations, max_cpu_s, reach_cell_m, "
                             "guide_after and guide_window must be > 0")
        if not (0.0 <= self.goal_bias <= 1.0 and 0.0 <= self.guide_share <= 1.0):
            raise ValueError("goal_bias and guide_share in [0, 1] are required")


@dataclass(frozen=True)
class RrtResult:
    """Outcome of :func:`plan_path`.

    ``path`` (k, 2) runs from the start to a point inside G, or is None when
    no path was found; ``status`` is "direct" (straight segment free),
    "exact" (RRT reached G), "unreachable" (proved that no path exists,
    :mod:`dualpilot.system1.reach`), "iteration_cap" or "time_cap".
    """

    path: Array | None
    status: str
    iterations: int
    time_s: float
    tree_path: Array | None = None  # the RRT's path before shortcutting

    @property
    def found(self) -> bool:
        return self.path is not None


def shortcut(path: Array, checker: SegmentChecker | SegmentChecker3, clearance_m: float,
             first_clearance_m: float | None = None, risk: ArcRisk | None = None) -> Array:
    """Greedy shortcut: from each kept vertex jump to the farthest vertex in free line of sight.

    Segments leaving ``path[0]`` need only ``first_clearance_m`` (defaults to
    ``clearance_m``; see :func:`plan_path` on starts near a hull). With ``risk``
    a jump must also keep clear of the risk zones of the steps it is flown in (planar
    paths only). A 3-D path (k, 3) takes a :class:`SegmentChecker3`.
    """
    dim = 3 if isinstance(checker, SegmentChecker3) else 2
    if dim == 3 and risk is not None:
        raise ValueError("the risk zones' shortcut is planar")
    pts = np.asarray(path, dtype=float).reshape(-1, dim)
    if len(pts) <= 2:
        return pts.copy()
    first = clearance_m if first_clearance_m is None else first_clearance_m
    keep = [0]
    i = 0
    s_i = 0.0  # arc length of the kept path to vertex i
    while i < len(pts) - 1:
        cand = np.arange(i + 1, len(pts))
        need = first if i == 0 else clearance_m
        ok = checker.clear(np.repeat(pts[i][None], len(cand), axis=0), pts[cand], need)
        ok[0] = True  # consecutive tree vertices were checked when the edge was added
        if risk is None:
            j = int(cand[np.nonzero(ok)[0][-1]])
        else:  # the farthest jump that is also clear of the risk zones (the next vertex was)
            x0, y0 = pts[i].tolist()
            j = i + 1
            for c, good in zip(cand[::-1].tolist(), ok[::-1].tolist(), strict=True):
                if good and (c == i + 1 or risk.segment_clear(
                        x0, y0, float(pts[c, 0]), float(pts[c, 1]), s_i)):
                    j = int(c)
                    break
            s_i += float(np.hypot(*(pts[j] - pts[i])))
        i = j
        keep.append(i)
    return pts[keep]


class ExactMotionValidator(ob.MotionValidator):
    """OMPL motion validator: a motion is valid iff its segment keeps the clearance exactly.

    A motion leaving the tree's root may instead keep ``root_clearance_m``
    (the start's own clearance when the start is nearer than ``clearance_m``).
    """

    def __init__(self, si: ob.SpaceInformation, checker: SegmentChecker, clearance_m: float,
                 root: Array, root_clearance_m: float, risk: ArcRisk | None = None):
        super().__init__(si)
        self._checker = checker
        self._clearance = clearance_m
        self._root = (float(root[0]), float(root[1]))
        self._root_clearance = root_clearance_m
        self.on_accept: Callable[[float, float], None] | None = None
        self._risk = risk
        #: with ``risk``: each tree vertex's path length from the root (its arrival time)
        self._arc: dict[tuple[float, float], float] = {self._root: 0.0}

    def checkMotion(self, s1: ob.State, s2: ob.State) -> bool:  # noqa: N802 (OMPL API)
        a = (s1[0], s1[1])
        need = self._root_clearance if a == self._root else self._clearance
        ok = self._checker.segment_clear(a[0], a[1], s2[0], s2[1], need)
        if ok and self._risk is not None:  # RRT grows the tree from s1, a tree vertex
            s0 = self._arc.get(a, float(np.hypot(a[0] - self._root[0], a[1] - self._root[1])))
            ok = self._risk.segment_clear(a[0], a[1], s2[0], s2[1], s0)
            if ok:
                self._arc[(s2[0], s2[1])] = s0 + float(np.hypot(s2[0] - a[0], s2[1] - a[1]))
        if ok and self.on_accept is not None:
            self.on_accept(s2[0], s2[1])  # RRT adds s2 to the tree when its motion is valid
        return ok


class _NumpyDrivenGoal(ob.GoalSampleableRegion):
    """Goal G for OMPL that also draws every RRT sample x̃ from our numpy Generator.

    RRT runs with goal bias 1, so it calls ``sampleGoal`` once per iteration:
    we return a uniform state of the area, or with probability ``bias`` a
    uniform state of G, or (once :meth:`guide_along` is set) with
    probability ``share`` a state just ahead of the tree along the chain.
    ``count`` is the number of iterations so far.
    """

    def __init__(self, si: ob.SpaceInformation, goal: Rect, area_size_m: float,
                 rng: np.random.Generator, bias: float):
        super().__init__(si)
        self._lo = (float(goal.lo[0]), float(goal.lo[1]))
        self._hi = (float(goal.hi[0]), float(goal.hi[1]))
        self._area = float(area_size_m)
        self._rng = rng
        self._bias = bias
        self._block: list[list[float]] = []  # samples drawn ahead (unguided)
        self._uniforms: list[list[float]] = []  # uniforms drawn ahead (guided)
        self.count = 0
        self._cap = 1 << 62
        self._ptc: ob.PlannerTerminationCondition | None = None
        self._cells: BoolArray | None = None
        self._cell_m = 1.0
        self._along: NDArray[np.int64] | None = None
        self._chain: list[list[float]] = []
        self._guide_cell_m = 1.0
        self._share = 0.0
        self._window = 1
        self._frontier = 0

    def stop_after(self, samples: int, ptc: ob.PlannerTerminationCondition) -> None:
        """End the solve run by ``ptc`` once ``samples`` samples have been drawn."""
        self._cap = samples
        self._ptc = ptc

    def restrict_to(self, cells: BoolArray, cell_m: float) -> None:
        """Draw area samples only from the cells where ``cells`` (rows y, columns x) is True."""
        self._cells = cells
        self._cell_m = cell_m
        self._block = []  # samples drawn under the old rule are not used

    def guide_along(self, chain: NDArray[np.int64], cell_m: float, share: float,
                    window: int) -> None:
        """Draw a share of the samples just ahead of the tree along a chain of cells.

        ``chain`` (k, 2) holds (column, row) cells of side ``cell_m`` from the
        start to G. The frontier is the farthest chain cell a tree node lies
        in or next to (:meth:`reached`); a guided sample is uniform in the
        3×3 block around a chain cell drawn from the ``window`` cells from
        the frontier on.
        """
        if not len(chain):
            return
        n = int(np.ceil(self._area / cell_m))
        along = np.full((n, n), -1, dtype=np.int64)
        for k, (i, j) in enumerate(chain.tolist()):
            along[max(j - 1, 0):j + 2, max(i - 1, 0):i + 2] = k
        self._along = along
        self._chain = ((chain - 1) * cell_m).tolist()  # corners of the 3×3 blocks
        self._guide_cell_m = cell_m
        self._share = share
        self._window = window
        self._frontier = 0

    def reached(self, x: float, y: float) -> None:
        """A tree node was added at (x, y): move the frontier if it lies farther along the chain."""
        if self._along is None:
            return
        k = int(self._along[_cell_index(y, self._guide_cell_m, len(self._along)),
                            _cell_index(x, self._guide_cell_m, len(self._along))])
        if k > self._frontier:
            self._frontier = k

    def _guided_sample(self) -> tuple[float, float]:
        """One sample of the guided mixture (goal, chain window, area), drawn from our rng."""
        while True:
            if not self._uniforms:
                self._uniforms = self._rng.random((256, 4)).tolist()
            u0, u1, u2, u3 = self._uniforms.pop()
            if u0 < self._bias:
                return (self._lo[0] + u1 * (self._hi[0] - self._lo[0]),
                        self._lo[1] + u2 * (self._hi[1] - self._lo[1]))
            if u3 < self._share:
                k = min(self._frontier + int(u3 / self._share * self._window), len(self._chain) - 1)
                x = self._chain[k][0] + 3.0 * u1 * self._guide_cell_m
                y = self._chain[k][1] + 3.0 * u2 * self._guide_cell_m
                if not (0.0 <= x < self._area and 0.0 <= y < self._area):
                    continue
            else:
                x, y = u1 * self._area, u2 * self._area
            n = 0 if self._cells is None else len(self._cells)
            if self._cells is None or self._cells[_cell_index(y, self._cell_m, n),
                                                  _cell_index(x, self._cell_m, n)]:
                return x, y

    def _refill(self, n: int = 256) -> None:
        # Drawn in blocks for speed; the sequence of samples depends only on the rng.
        u = self._rng.random((n, 3))
        to_goal = u[:, 0] < self._bias
        lo = np.where(to_goal[:, None], np.array(self._lo), 0.0)
        span = np.where(to_goal[:, None], np.array(self._hi) - np.array(self._lo), self._area)
        pts = lo + u[:, 1:] * span
        if self._cells is not None:
            idx = np.minimum((pts // self._cell_m).astype(int), self._cells.shape[0] - 1)
            pts = pts[to_goal | self._cells[idx[:, 1], idx[:, 0]]]
        self._block = pts[::-1].tolist()

    def sampleGoal(self, st: ob.State) -> None:  # noqa: N802 (OMPL API)
        self.count += 1
        if self.count >= self._cap and self._ptc is not None:
            self._ptc.terminate()  # this sample is the last one RRT uses
        if self._along is not None:
            st[0], st[1] = self._guided_sample()
            return
        if not self._block:
            self._refill()
        st[0], st[1] = self._block.pop()

    def maxSampleCount(self) -> int:  # noqa: N802 (OMPL API)
        return 1 << 30

    def distanceGoal(self, st: ob.State) -> float:  # noqa: N802 (OMPL API)
        x, y = st[0], st[1]
        gx = max(0.0, self._lo[0] - x, x - self._hi[0])
        gy = max(0.0, self._lo[1] - y, y - self._hi[1])
        return (gx * gx + gy * gy) ** 0.5


def _cell_index(v: float, cell_m: float, n: int) -> int:
    """Row or column of coordinate ``v`` (m) on a grid of ``n`` cells of side ``cell_m``."""
    return min(int(v / cell_m), n - 1)


def _length(path: Array) -> float:
    """Length (m) of the polyline ``path``."""
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())


def _validate(start: Array, goal: Rect, area_size_m: float) -> Array:
    p = np.asarray(start, dtype=float).reshape(-1)[:2]
    if p.shape != (2,) or not np.all(np.isfinite(p)):
        raise ValueError(f"start must be a finite 2-D position, got {start}")
    if not (np.isfinite(area_size_m) and area_size_m > 0):
        raise ValueError(f"area_size_m must be positive, got {area_size_m}")
    area = Rect(area_size_m / 2, area_size_m / 2, area_size_m, area_size_m)
    if not goal.inside(area):
        raise ValueError(f"goal {goal} lies outside the {area_size_m} m area")
    if not area.contains(p):
        raise ValueError(f"start {p} lies outside the {area_size_m} m area")
    return p


@dataclass(frozen=True)
class _Query:
    """One :func:`plan_path` call: the validated start ``p`` and what every stage needs.

    ``root_clearance_m`` is what edges leaving the start keep (m); ``t0`` the
    call's start (``time.perf_counter``), ``cpu0`` its thread's CPU time then
    (``time.thread_time``, s), from which ``params.max_cpu_s`` counts.
    """

    p: Array
    goal: Rect
    hulls: Sequence[Polytope]
    checker: SegmentChecker
    clearance_m: float
    root_clearance_m: float
    area_size_m: float
    params: RrtParams
    risk: ArcRisk | None
    t0: float
    cpu0: float

    def result(self, status: str, iterations: int) -> RrtResult:
        """No path: ``status`` after ``iterations`` samples."""
        return RrtResult(None, status, iterations, time.perf_counter() - self.t0, None)


class _OmplRrt:
    """OMPL's RRT over the area (Alg. 1) with the exact motion check, sampled from our rng.

    ``sampler`` draws every sample x̃ (:class:`_NumpyDrivenGoal`), ``validator``
    is PathFree (:class:`ExactMotionValidator`); :meth:`grow` runs the tree on.
    """

    def __init__(self, q: _Query, rng: np.random.Generator, component: BoolArray | None):
        params = q.params
        self._q = q
        ou.setLogLevel(ou.LOG_WARN)
        space = ob.RealVectorStateSpace(2)
        bounds = ob.RealVectorBounds(2)
        bounds.setLow(0.0)
        bounds.setHigh(float(q.area_size_m))
        space.setBounds(bounds)
        si = ob.SpaceInformation(space)
        si.setStateValidityChecker(lambda s: True)  # states are judged by the exact motion check
        validator = ExactMotionValidator(si, q.checker, q.clearance_m, q.p, q.root_clearance_m,
                                         q.risk)
        si.setMotionValidator(validator)
        si.setup()
        start_state = space.allocState()
        start_state[0], start_state[1] = float(q.p[0]), float(q.p[1])
        sampler = _NumpyDrivenGoal(si, q.goal, q.area_size_m, rng, params.goal_bias)
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

    def grow(self, samples: int) -> bool:
        """Run RRT on the same tree until G is reached, ``samples`` samples or the CPU cap.

        OMPL asks the termination condition once per iteration, on this thread: it
        compares the thread's CPU time with the query's ``max_cpu_s``. The sampler
        ends the solve itself once it has drawn ``samples`` samples.
        """
        cpu_end = self._q.cpu0 + self._q.params.max_cpu_s
        ptc = ob.PlannerTerminationCondition(lambda: time.thread_time() > cpu_end)
        self.sampler.stop_after(samples, ptc)
        status = self.rrt.solve(ptc)
        return bool(status.getStatus() == ob.PlannerStatus.EXACT_SOLUTION)

    def path(self) -> Array:
        """The solution path (k, 2) through the tree, starting exactly at the start."""
        sol = self.pdef.getSolutionPath()
        tree = np.array([[sol.getState(i)[0], sol.getState(i)[1]]
                         for i in range(sol.getStateCount())])
        tree[0] = self._q.p  # exactly the start
        return tree


def _root_clearance(p: Array, checker: SegmentChecker, clearance_m: float,
                    start_clearance_m: float | None) -> float:
    """The clearance (m) edges leaving the start keep: ``clearance_m``, or less for an escape.

    Raises ValueError for a negative ``clearance_m`` or a start nearer than
    ``start_clearance_m`` (default ``clearance_m``) to a hull.
    """
    if clearance_m < 0:
        raise ValueError(f"clearance_m must be >= 0, got {clearance_m}")
    need_start = clearance_m if start_clearance_m is None else start_clearance_m
    d_start = checker.point_distance(p)
    if d_start < need_start:
        raise ValueError(
            f"start {p} lies {d_start:.1f} m from a fire hull (needs {need_start:.1f} m)"
        )
    return min(clearance_m, d_start)


def _finish(q: _Query, path: Array, status: str, iterations: int,
            tree: Array | None) -> RrtResult:
    """The result for ``path``: extended to G's centre when free, then shortcut (as set)."""
    params, checker, risk = q.params, q.checker, q.risk
    center = q.goal.center
    if params.aim_goal_center and not np.allclose(path[-1], center):
        first = q.root_clearance_m if len(path) == 1 else q.clearance_m
        (x0, y0), (x1, y1) = path[-1].tolist(), center.tolist()
        if checker.segment_clear(x0, y0, x1, y1, first) and (
                risk is None or risk.segment_clear(x0, y0, x1, y1, _length(path))):
            path = np.vstack([path, center])
    if params.shortcut:
        path = shortcut(path, checker, q.clearance_m, q.root_clearance_m, risk)
    return RrtResult(path, status, iterations, time.perf_counter() - q.t0, tree)


def _direct(q: _Query) -> RrtResult | None:
    """A start inside G, or a free straight segment into G (``try_direct``); else None."""
    p, goal, params = q.p, q.goal, q.params
    if goal.contains(p):
        return _finish(q, p[None].copy(), "direct", 0, None)
    if params.try_direct:
        target = goal.center if params.aim_goal_center else np.clip(p, goal.lo, goal.hi)
        (x0, y0), (x1, y1) = p.tolist(), target.tolist()
        if q.checker.segment_clear(x0, y0, x1, y1, q.root_clearance_m) and (
                q.risk is None or q.risk.segment_clear(x0, y0, x1, y1, 0.0)):
            return _finish(q, np.vstack([p, target]), "direct", 0, None)
    return None


def _grow_guided(q: _Query, tree: _OmplRrt, coarse: BoolArray) -> bool | None:
    """Grow on after ``guide_after`` samples, guided along a corridor of a finer grid.

    The grid has cells of ``reach_cell_m / 2`` within ``coarse``; a share of the
    samples is drawn ahead of the tree along the corridor to G
    (:meth:`_NumpyDrivenGoal.guide_along`). Returns whether G was reached, or
    None when the finer grid proves G unreachable.
    """
    params = q.params
    fine_m = params.reach_cell_m / 2
    fine, meets_goal = start_component(
        q.p, q.goal, q.hulls, q.clearance_m, q.area_size_m, fine_m,
        start_clearance_m=q.root_clearance_m, start_radius_m=params.step_size_m,
        coarse=coarse)
    if not meets_goal:
        return None
    chain = corridor(coarsen(fine), q.p, q.goal, params.reach_cell_m)
    if params.sample_reachable:
        tree.sampler.restrict_to(fine, fine_m)
    tree.sampler.guide_along(chain, params.reach_cell_m, params.guide_share,
                             params.guide_window)
    tree.validator.on_accept = tree.sampler.reached
    tree.pdef.clearSolutionPaths()  # RRT's approximate answer from the first run
    try:
        return tree.grow(params.max_iterations)
    finally:
        tree.validator.on_accept = None  # a cycle through OMPL's objects would never be freed


def plan_path(
    start: Array,
    goal: Rect,
    hulls: Sequence[Polytope],
    rng: np.random.Generator,
    clearance_m: float,
    area_size_m: float,
    params: RrtParams = RrtParams(),
    start_clearance_m: float | None = None,
    checker: SegmentChecker | None = None,
    risk: ArcRisk | None = None,
) -> RrtResult:
    """Alg. 1: a path (k, 2) from ``start`` into ``goal`` keeping ``clearance_m`` from hulls.

    The area is [0, ``area_size_m``]² (m).
    ``start_clearance_m`` (default ``clearance_m``) is the least
    clearance the start itself must have. A start between it and
    ``clearance_m`` is an escape: edges leaving the start need only keep the
    start's own clearance (they may not move closer to a hull), every later
    edge the full ``clearance_m``. With ``risk`` every edge (and shortcut) also
    keeps clear of the forecast's risk zones of the steps in which it is flown,
    timed by its path length from the start (:class:`dualpilot.model.risk.ArcRisk`).

    Raises ValueError for a non-finite start or one outside the area, a goal
    outside the area, or a start nearer than ``start_clearance_m`` to a hull.
    No path within the caps is a result (``path is None``), not an error.
    """
    t0, cpu0 = time.perf_counter(), time.thread_time()
    p = _validate(start, goal, area_size_m)
    checker = SegmentChecker(hulls) if checker is None else checker
    root_clearance = _root_clearance(p, checker, clearance_m, start_clearance_m)
    q = _Query(p, goal, hulls, checker, clearance_m, root_clearance, area_size_m, params,
               risk, t0, cpu0)
    direct = _direct(q)
    if direct is not None:
        return direct

    component = None
    if params.reach_check and len(hulls):
        component, meets_goal = start_component(
            p, goal, hulls, clearance_m, area_size_m, params.reach_cell_m,
            start_clearance_m=root_clearance, start_radius_m=params.step_size_m)
        if not meets_goal:
            return q.result("unreachable", 0)

    tree = _OmplRrt(q, rng, component)
    failed = grow_tree(q, q, tree, component)
    if failed is not None:
        return failed
    path = tree.path()
    return _finish(q, path, "exact", tree.sampler.count, path)


def grow_tree(q: Any, planar: _Query, tree: _OmplRrt, component: BoolArray | None
              ) -> RrtResult | None:
    """Grow ``tree`` (unguided up to ``guide_after`` samples, then guided by the grid's
    ``component``): None once it holds a path to G, else ``q``'s result of why not
    (``planar``: the query whose plane guides the samples)."""
    params = planar.params
    guide = component is not None and params.guide_after < params.max_iterations
    solved: bool | None = tree.grow(params.guide_after if guide else params.max_iterations)
    if (not solved and guide and component is not None
            and tree.sampler.count >= params.guide_after):
        solved = _grow_guided(planar, tree, component)
        if solved is None:
            return q.result("unreachable", tree.sampler.count)
    iterations = tree.sampler.count
    if not solved:
        cause = "iteration_cap" if iterations >= params.max_iterations else "time_cap"
        return q.result(cause, iterations)
    return None
