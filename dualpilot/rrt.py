"""System 1's path planner, Alg. 1: an RRT from the UAV's position to the goal region G.

The tree is grown by OMPL's RRT (``ompl`` 2.x) in a 2-D RealVectorStateSpace
over the area with step size (range) 15 m (Sec. IV-A). Our reading of the
paper's loose points, each a parameter of :class:`RrtParams`:

* **PathFree** (Alg. 1, line 8) is exact: an edge is accepted only if the
  whole segment keeps ``clearance_m`` from every hull △(C^i_{1:t}).
  OMPL's own motion check samples the segment and can clip a corner, so we
  install :class:`ExactMotionValidator` instead.
* **Iterations** count samples x̃ (one per pass of Alg. 1's loop). The paper
  caps them at 500; with exact checks that cap fails on many random fire
  fields (see ``max_iterations``), so our default is larger. A wall-clock cap
  bounds the answer time as well.
* **Determinism**: every sample comes from our ``numpy.random.Generator``.
  The bindings do not expose ``setStateSamplerAllocator``, so we set OMPL's
  goal bias to 1 and hand RRT a goal whose ``sampleGoal`` draws a uniform
  state of the area (or, with probability ``goal_bias``, a state of G). RRT's
  internal RNG then decides nothing, and the same seed gives the same path.
* The raw tree path is shortcut greedily (exact checks), as an operator would
  not zig-zag, and it ends at G's centre when that is reachable in a straight
  free segment (else at the first tree state inside G).

Lengths are metres, times seconds.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou

from .dynamics import Array
from .geometry import Polytope, Rect


@dataclass(frozen=True)
class RrtParams:
    """Alg. 1 settings. ``step_size_m`` is the paper's 15 m; see the module docstring.

    ``max_iterations`` defaults to 2000 rather than the paper's 500: on
    random fire fields of Sec. IV-A with a path to G, 500 samples failed on
    30 % of instances and 2000 on 2 % (median 370, p95 ≈ 1100 iterations;
    README, "System 1 iteration cap"). ``max_wall_s`` is a safety cap.
    """

    step_size_m: float = 15.0
    max_iterations: int = 2000
    clearance_m: float = 25.0
    goal_bias: float = 0.05
    max_wall_s: float = 2.0
    shortcut: bool = True
    aim_goal_center: bool = True
    try_direct: bool = True

    def __post_init__(self) -> None:
        if not (self.step_size_m > 0 and self.max_iterations >= 1 and self.max_wall_s > 0):
            raise ValueError("step_size_m > 0, max_iterations >= 1 and max_wall_s > 0 are required")
        if self.clearance_m < 0 or not 0.0 <= self.goal_bias <= 1.0:
            raise ValueError("clearance_m >= 0 and goal_bias in [0, 1] are required")


@dataclass(frozen=True)
class RrtResult:
    """Outcome of :func:`plan_path`.

    ``path`` (k, 2) runs from the start to a point inside G, or is None when
    no path was found; ``status`` is "direct" (straight segment free),
    "exact" (RRT reached G), "iteration_cap" or "time_cap".
    """

    path: Array | None
    status: str
    iterations: int
    time_s: float
    tree_path: Array | None = None  # the RRT's path before shortcutting

    @property
    def found(self) -> bool:
        return self.path is not None


class SegmentChecker:
    """Exact segment-to-hulls distances, vectorised over segments and hull edges.

    For a segment that neither crosses an edge nor starts inside a hull, the
    distance to a convex polygon is the smallest of its endpoints' distances
    to the polygon's edges and the polygon's vertices' distances to the
    segment; otherwise it is 0. This equals ``Polytope.segment_distance``
    (the unit tests check that) at a fraction of the cost.
    """

    def __init__(self, hulls: Sequence[Polytope]):
        self.n_hulls = len(hulls)
        self._parts = [_HullEdges([h]) for h in hulls]
        self._all = _HullEdges(hulls) if hulls else None
        lo = [h.vertices.min(axis=0) for h in hulls]
        hi = [h.vertices.max(axis=0) for h in hulls]
        self._boxes = [(float(a[0]), float(a[1]), float(b[0]), float(b[1]))
                       for a, b in zip(lo, hi, strict=True)]
        self._box_lo = np.array(lo).reshape(-1, 2)
        self._box_hi = np.array(hi).reshape(-1, 2)

    def segment_clear(self, x0: float, y0: float, x1: float, y1: float, need_m: float) -> bool:
        """Whether the single segment (x0, y0)–(x1, y1) keeps ``need_m`` from every hull.

        Bounding boxes settle most segments in plain Python; only the hulls
        whose box is nearer than ``need_m`` get the exact distance.
        """
        lox, hix = (x0, x1) if x0 <= x1 else (x1, x0)
        loy, hiy = (y0, y1) if y0 <= y1 else (y1, y0)
        need2 = need_m * need_m
        p0 = p1 = np.empty((0, 2))
        for i, (bx0, by0, bx1, by1) in enumerate(self._boxes):
            gx = max(0.0, bx0 - hix, lox - bx1)
            gy = max(0.0, by0 - hiy, loy - by1)
            if gx * gx + gy * gy >= need2:
                continue
            if not len(p0):
                p0, p1 = np.array([[x0, y0]]), np.array([[x1, y1]])
            if self._parts[i].distances(p0, p1)[0] < need_m:
                return False
        return True

    def clear(self, p0: Array, p1: Array, need_m: float) -> Array:
        """Whether each segment p0[i]–p1[i] keeps ``need_m`` from every hull (bool (n,))."""
        p0 = np.atleast_2d(np.asarray(p0, dtype=float))
        p1 = np.atleast_2d(np.asarray(p1, dtype=float))
        if self.n_hulls == 0:
            return np.ones(len(p0), dtype=bool)
        seg_lo = np.minimum(p0, p1)[:, None]
        seg_hi = np.maximum(p0, p1)[:, None]
        gap = np.maximum(0.0, np.maximum(self._box_lo[None] - seg_hi, seg_lo - self._box_hi[None]))
        lower = np.sqrt(np.min(np.sum(gap * gap, axis=-1), axis=1))
        ok = lower >= need_m
        todo = np.nonzero(~ok)[0]
        if len(todo):
            ok[todo] = self.distances(p0[todo], p1[todo]) >= need_m
        return ok

    def distances(self, p0: Array, p1: Array) -> Array:
        """Distance from each segment p0[i]–p1[i] (arrays (n, 2)) to the nearest hull (or inf)."""
        p0 = np.atleast_2d(np.asarray(p0, dtype=float))
        p1 = np.atleast_2d(np.asarray(p1, dtype=float))
        if self._all is None:
            return np.full(len(p0), np.inf)
        return self._all.distances(p0, p1)

    def point_distance(self, p: Array) -> float:
        """Distance from point p to the nearest hull (inf if none)."""
        q = np.asarray(p, dtype=float)[:2]
        return float(self.distances(q[None], q[None])[0])

    def path_clearance(self, points: Array) -> float:
        """Smallest distance from the polyline through ``points`` (k, 2) to any hull."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        if len(pts) == 1:
            return self.point_distance(pts[0])
        return float(np.min(self.distances(pts[:-1], pts[1:])))


class _HullEdges:
    """Edges and faces of one or more hulls as flat arrays (components split for speed)."""

    def __init__(self, hulls: Sequence[Polytope]):
        a = np.vstack([h.vertices for h in hulls])
        c = np.vstack([np.roll(h.vertices, -1, axis=0) for h in hulls])
        self.ax, self.ay = a[:, 0].copy(), a[:, 1].copy()
        self.dx, self.dy = c[:, 0] - a[:, 0], c[:, 1] - a[:, 1]
        len2 = self.dx**2 + self.dy**2
        self.inv_len2 = 1.0 / np.where(len2 > 0, len2, 1.0)
        normals = np.vstack([h.A for h in hulls])
        self.nx, self.ny = normals[:, 0].copy(), normals[:, 1].copy()
        self.offsets = np.concatenate([h.b for h in hulls])
        self.starts = np.cumsum([0] + [h.n_faces for h in hulls[:-1]])

    def distances(self, p0: Array, p1: Array) -> Array:
        x0, y0 = p0[:, :1], p0[:, 1:2]  # (n, 1)
        x1, y1 = p1[:, :1], p1[:, 1:2]
        ax, ay, dx, dy = self.ax, self.ay, self.dx, self.dy  # (m,)
        d2 = np.minimum(_pt_seg2(x0, y0, ax, ay, dx, dy, self.inv_len2),
                        _pt_seg2(x1, y1, ax, ay, dx, dy, self.inv_len2))
        sx, sy = x1 - x0, y1 - y0
        slen2 = sx * sx + sy * sy
        inv = 1.0 / np.where(slen2 > 0, slen2, 1.0)
        d2 = np.minimum(d2, _pt_seg2(ax, ay, x0, y0, sx, sy, inv))
        d = np.sqrt(d2.min(axis=1))
        # proper crossings of the segment with a hull edge (orientation tests)
        o1 = sx * (ay - y0) - sy * (ax - x0)
        o2 = sx * (ay + dy - y0) - sy * (ax + dx - x0)
        o3 = dx * (y0 - ay) - dy * (x0 - ax)
        o4 = dx * (y1 - ay) - dy * (x1 - ax)
        crossing = ((o1 * o2) < 0) & ((o3 * o4) < 0)
        # a segment wholly inside a hull crosses nothing: test one endpoint
        slack = x0 * self.nx + y0 * self.ny - self.offsets  # (n, faces)
        inside = np.maximum.reduceat(slack, self.starts, axis=1) <= 0.0
        hit = crossing.any(axis=1) | inside.any(axis=1)
        return np.where(hit, 0.0, d)


def _pt_seg2(px: Array, py: Array, ax: Array, ay: Array, dx: Array, dy: Array,
             inv_len2: Array) -> Array:
    """Broadcast squared distance from points (px, py) to segments a → a + d."""
    t = np.minimum(np.maximum(((px - ax) * dx + (py - ay) * dy) * inv_len2, 0.0), 1.0)
    ex = px - ax - t * dx
    ey = py - ay - t * dy
    return np.asarray(ex * ex + ey * ey)


def shortcut(path: Array, checker: SegmentChecker, clearance_m: float,
             first_clearance_m: float | None = None) -> Array:
    """Greedy shortcut: from each kept vertex jump to the farthest vertex in free line of sight.

    Segments leaving ``path[0]`` need only ``first_clearance_m`` (defaults to
    ``clearance_m``; see :func:`plan_path` on starts near a hull).
    """
    pts = np.asarray(path, dtype=float).reshape(-1, 2)
    if len(pts) <= 2:
        return pts.copy()
    first = clearance_m if first_clearance_m is None else first_clearance_m
    keep = [0]
    i = 0
    while i < len(pts) - 1:
        cand = np.arange(i + 1, len(pts))
        need = first if i == 0 else clearance_m
        ok = checker.clear(np.repeat(pts[i][None], len(cand), axis=0), pts[cand], need)
        ok[0] = True  # consecutive tree vertices were checked when the edge was added
        i = int(cand[np.nonzero(ok)[0][-1]])
        keep.append(i)
    return pts[keep]


class ExactMotionValidator(ob.MotionValidator):
    """OMPL motion validator: a motion is valid iff its segment keeps the clearance exactly.

    A motion leaving the tree's root may instead keep ``root_clearance_m``
    (the start's own clearance when the start is nearer than ``clearance_m``).
    """

    def __init__(self, si: ob.SpaceInformation, checker: SegmentChecker, clearance_m: float,
                 root: Array, root_clearance_m: float):
        super().__init__(si)
        self._checker = checker
        self._clearance = clearance_m
        self._root = (float(root[0]), float(root[1]))
        self._root_clearance = root_clearance_m

    def checkMotion(self, s1: ob.State, s2: ob.State) -> bool:  # noqa: N802 (OMPL API)
        a = (s1[0], s1[1])
        need = self._root_clearance if a == self._root else self._clearance
        return self._checker.segment_clear(a[0], a[1], s2[0], s2[1], need)


class _NumpyDrivenGoal(ob.GoalSampleableRegion):
    """Goal G for OMPL that also draws every RRT sample x̃ from our numpy Generator.

    RRT runs with goal bias 1, so it calls ``sampleGoal`` once per iteration:
    we return a uniform state of the area, or with probability ``bias`` a
    uniform state of G. ``count`` is the number of iterations so far.
    """

    def __init__(self, si: ob.SpaceInformation, goal: Rect, area_size_m: float,
                 rng: np.random.Generator, bias: float):
        super().__init__(si)
        self._lo = (float(goal.lo[0]), float(goal.lo[1]))
        self._hi = (float(goal.hi[0]), float(goal.hi[1]))
        self._area = float(area_size_m)
        self._rng = rng
        self._bias = bias
        self._block: list[tuple[float, float]] = []
        self.count = 0

    def _refill(self, n: int = 256) -> None:
        # Drawn in blocks for speed; the sequence of samples depends only on the rng.
        u = self._rng.random((n, 3))
        to_goal = u[:, 0] < self._bias
        lo = np.where(to_goal[:, None], np.array(self._lo), 0.0)
        span = np.where(to_goal[:, None], np.array(self._hi) - np.array(self._lo), self._area)
        pts = lo + u[:, 1:] * span
        self._block = [(float(x), float(y)) for x, y in pts[::-1]]

    def sampleGoal(self, st: ob.State) -> None:  # noqa: N802 (OMPL API)
        self.count += 1
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


def plan_path(
    start: Array,
    goal: Rect,
    hulls: Sequence[Polytope],
    rng: np.random.Generator,
    params: RrtParams = RrtParams(),
    area_size_m: float = 1000.0,
    start_clearance_m: float | None = None,
    checker: SegmentChecker | None = None,
) -> RrtResult:
    """Alg. 1: a path (k, 2) from ``start`` into ``goal`` keeping ``params.clearance_m`` from hulls.

    ``start_clearance_m`` (default ``params.clearance_m``) is the least
    clearance the start itself must have. A start between it and
    ``clearance_m`` is an escape: edges leaving the start need only keep the
    start's own clearance (they may not move closer to a hull), every later
    edge the full ``clearance_m``.

    Raises ValueError for a non-finite start or one outside the area, a goal
    outside the area, or a start nearer than ``start_clearance_m`` to a hull.
    No path within the caps is a result (``path is None``), not an error.
    """
    t0 = time.perf_counter()
    p = _validate(start, goal, area_size_m)
    checker = SegmentChecker(hulls) if checker is None else checker
    need_start = params.clearance_m if start_clearance_m is None else start_clearance_m
    d_start = checker.point_distance(p)
    if d_start < need_start:
        raise ValueError(
            f"start {p} lies {d_start:.1f} m from a fire hull (needs {need_start:.1f} m)"
        )
    root_clearance = min(params.clearance_m, d_start)
    center = goal.center

    def finish(path: Array, status: str, iterations: int, tree: Array | None) -> RrtResult:
        if params.aim_goal_center and not np.allclose(path[-1], center):
            first = root_clearance if len(path) == 1 else params.clearance_m
            if checker.clear(path[-1][None], center[None], first)[0]:
                path = np.vstack([path, center])
        if params.shortcut:
            path = shortcut(path, checker, params.clearance_m, root_clearance)
        return RrtResult(path, status, iterations, time.perf_counter() - t0, tree)

    if goal.contains(p):
        return finish(p[None].copy(), "direct", 0, None)
    if params.try_direct:
        target = center if params.aim_goal_center else np.clip(p, goal.lo, goal.hi)
        if checker.clear(p[None], target[None], root_clearance)[0]:
            return finish(np.vstack([p, target]), "direct", 0, None)

    ou.setLogLevel(ou.LOG_WARN)
    space = ob.RealVectorStateSpace(2)
    bounds = ob.RealVectorBounds(2)
    bounds.setLow(0.0)
    bounds.setHigh(float(area_size_m))
    space.setBounds(bounds)
    si = ob.SpaceInformation(space)
    si.setStateValidityChecker(lambda s: True)  # states are judged by the exact motion check
    validator = ExactMotionValidator(si, checker, params.clearance_m, p, root_clearance)
    si.setMotionValidator(validator)
    si.setup()
    start_state = space.allocState()
    start_state[0], start_state[1] = float(p[0]), float(p[1])
    goal_obj = _NumpyDrivenGoal(si, goal, area_size_m, rng, params.goal_bias)
    pdef = ob.ProblemDefinition(si)
    pdef.addStartState(start_state)
    pdef.setGoal(goal_obj)
    rrt = og.RRT(si)
    rrt.setRange(params.step_size_m)
    rrt.setGoalBias(1.0)  # every sample goes through goal_obj.sampleGoal (our rng)
    rrt.setProblemDefinition(pdef)
    rrt.setup()
    deadline = t0 + params.max_wall_s
    timed_out = [False]

    def stop() -> bool:
        if goal_obj.count >= params.max_iterations:
            return True
        if time.perf_counter() > deadline:
            timed_out[0] = True
            return True
        return False

    status = rrt.solve(ob.PlannerTerminationCondition(stop))
    iterations = goal_obj.count
    if status.getStatus() != ob.PlannerStatus.EXACT_SOLUTION:
        cause = "time_cap" if timed_out[0] else "iteration_cap"
        return RrtResult(None, cause, iterations, time.perf_counter() - t0, None)
    sol = pdef.getSolutionPath()
    tree = np.array([[sol.getState(i)[0], sol.getState(i)[1]] for i in range(sol.getStateCount())])
    tree[0] = p  # exactly the start
    return finish(tree, "exact", iterations, tree)
