"""The oracle's impossibility certificate: the reachable positions, over-approximated, miss G.

On a grid of square cells, D_s is a set of cells that contains every position any
controller can hold during sub-step s of the fires (the idle UAV is checked after
each sub-step, dualpilot/mission/step.py). It over-approximates because

* between two sub-steps a controller flies at most one step (every step takes at
  least one sub-step), and a step moves the UAV by ΔT·v_t, at most ΔT·v_max per axis
  (|v_i| ≤ v_max; ‖v‖ ≤ v_max is inside that square): D_{s+1} is D_s grown by that
  square, in cells, rounded up; Eq. (1)'s inertia and the force limit are used only
  from the start: after k flights the UAV lies in the box that the force and speed
  limits allow from its initial state (:func:`~dualpilot.model.dynamics.reach_boxes`),
  or one of the earlier flights' boxes (it may have flown fewer);
* a cell leaves D_s only when every point of it fails the check of sub-step s: its
  four corners lie closer than d_safe to one region (the distance to a box is convex,
  so the whole cell does); the flown segments are not checked at all.

If D_s empties, or grown D_s never meets G up to the last sub-step any covered
flight can reach, no covered flight reaches G: **impossible**. Which flights are
covered (:class:`Scope`):

* fires that do not depend on the step length (:func:`~dualpilot.oracle.future.schedule_free`):
  every flight whose fires run at most ``max_steps`` × ``max_step_substeps`` sub-steps
  (steps of any length up to that many sub-steps);
* otherwise the future is that of steps of one planning sub-step
  (:mod:`~dualpilot.oracle.future`): every flight at that pace.

Two things would let a flight leave the future the certificate reads, and make it
give up (**unknown**) the moment a cell of D_s could see them:

* the ignition clearance: a birth drawn within it of the UAV is redrawn elsewhere
  and the fire stream moves (the physics scenarios' births are not handled: unknown);
* the failure rule "become": a front born within d_safe of the UAV does not fail it
  until the UAV has once been clear of it; the rule "newborn" is not handled.

Lengths m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from dualpilot.arrays import AnyArray, Array
from dualpilot.mission.config import MissionConfig
from dualpilot.model.dynamics import hover_state, reach_boxes
from dualpilot.model.scenarios import PAPER
from dualpilot.oracle.future import Future, schedule_free
from dualpilot.spec import MissionSpec


@dataclass(frozen=True)
class CertificateParams:
    """The certificate's grid and the flights it covers."""

    #: side of a grid cell (m); ΔT·v_max / cell_m not a whole number, so a step's reach in
    #: cells, rounded up, keeps a margin against round-off (15 m: 3.75 cells → 4)
    cell_m: float = 4.0
    #: a step of a covered flight takes at most this many planning sub-steps (fires that do not
    #: depend on the step length): 11 is the longest step of the paper's timing, System 2's 5 s
    #: and then System 1's 155 ms (⌈5.155 / 0.5⌉)
    max_step_substeps: int = 11
    #: room outside the area (m): a braking UAV drifts at most v·ΔT·(1 + (1 − ζ) + …) past its
    #: last planned position, which the run-time monitor keeps in the area
    border_m: float = 50.0

    def __post_init__(self) -> None:
        if not (self.cell_m > 0 and self.max_step_substeps >= 1 and self.border_m >= 0):
            raise ValueError(f"invalid certificate parameters: {self}")


@dataclass(frozen=True)
class Scope:
    """The flights a certificate speaks for: those whose fires ran at most ``substeps``
    sub-steps, and, when ``one_substep_steps``, only those whose every step took one planning
    sub-step."""

    substeps: int
    one_substep_steps: bool

    def covers(self, fire_substeps: int, steps: int, substeps_per_step: int) -> bool:
        """Whether a flight of ``steps`` steps that saw ``fire_substeps`` sub-steps is covered
        (``substeps_per_step``: 1 + the reading's sub-steps in flight)."""
        if self.one_substep_steps and fire_substeps != steps * substeps_per_step:
            return False
        return fire_substeps <= self.substeps


@dataclass(frozen=True)
class Certificate:
    """The certificate's answer: "impossible", "reachable" (grown D_s met G) or "gave up" (a
    flight could leave the known future, or the reading is not handled), with why."""

    verdict: str
    reason: str
    substeps: int


def scope_of(config: MissionConfig, params: CertificateParams = CertificateParams(),
             free: bool | None = None) -> Scope:
    """The flights a certificate of ``config``'s mission speaks for (``free``: whether its
    fires are free of the step length; None: as its reading's are)."""
    reading = config.reading()
    k = 1 + reading.mission.fire_substeps_per_motion
    steps = reading.mission.max_steps
    if schedule_free(reading.fire) if free is None else free:
        return Scope(steps * (params.max_step_substeps + k - 1), False)
    return Scope(steps * k, True)


def unsupported(config: MissionConfig) -> str:
    """Why the certificate cannot speak for ``config``'s reading ("" when it can)."""
    reading = config.reading()
    if reading.mission.failure_rule == "newborn":
        return "failure rule newborn"
    if reading.mission.ignition_clearance_m is not None and reading.fire.scenario != PAPER:
        return "ignition clearance on a physics scenario"
    if reading.mission.ignition_clearance_m is not None and reading.fire.redraw_clearance:
        return "redraws kept clear of the UAV"
    return ""


@njit(cache=True)
def grown(cells: AnyArray, r: int) -> AnyArray:
    """``cells`` grown by the square of half-side ``r`` cells (a sliding window per axis)."""
    n, m = cells.shape
    rows = np.zeros((n, m), dtype=np.bool_)
    for i in range(n):  # along each row: is a cell within r columns set?
        last = -(1 << 30)
        for j in range(m + r):
            if j < m and cells[i, j]:
                last = j
            if j - r >= 0 and j - last <= 2 * r:
                rows[i, j - r] = True
    out = np.zeros((n, m), dtype=np.bool_)
    for j in range(m):  # then along each column
        last = -(1 << 30)
        for i in range(n + r):
            if i < n and rows[i, j]:
                last = i
            if i - r >= 0 and i - last <= 2 * r:
                out[i - r, j] = True
    return out


@njit(cache=True)
def _drop_failing(cells: AnyArray, boxes: Array, lo: float, c: float, d: float) -> None:
    n = cells.shape[0]
    d2 = (d - 1e-6) ** 2  # round-off: a corner counts only when clearly inside
    for k in range(len(boxes)):
        x0, y0, x1, y1 = boxes[k, 0], boxes[k, 1], boxes[k, 2], boxes[k, 3]
        j0 = max(0, math.floor((x0 - d - lo) / c))
        j1 = min(n, math.floor((x1 + d - lo) / c) + 1)
        i0 = max(0, math.floor((y0 - d - lo) / c))
        i1 = min(n, math.floor((y1 + d - lo) / c) + 1)
        for i in range(i0, i1):
            for j in range(j0, j1):
                if not cells[i, j]:
                    continue
                inside = True
                for cy in (lo + c * i, lo + c * (i + 1)):
                    gy = max(0.0, max(y0 - cy, cy - y1))
                    for cx in (lo + c * j, lo + c * (j + 1)):
                        gx = max(0.0, max(x0 - cx, cx - x1))
                        if gx * gx + gy * gy >= d2:
                            inside = False
                if inside:
                    cells[i, j] = False


class _Grid:
    """Square cells over [−border, A + border]²: cell (i, j) is row i (y), column j (x)."""

    def __init__(self, area_m: float, params: CertificateParams):
        self.c = params.cell_m
        self.lo = -params.border_m
        self.n = math.ceil((area_m + 2 * params.border_m) / self.c)
        self.corners = self.lo + self.c * np.arange(self.n + 1)

    def cell(self, x: float, y: float) -> tuple[int, int]:
        return int((y - self.lo) // self.c), int((x - self.lo) // self.c)

    def cells_touching(self, x0: float, y0: float, x1: float, y1: float) -> tuple[slice, slice]:
        """Rows and columns of the cells that meet the box (clipped to the grid)."""
        j0, j1 = (max(0, min(self.n, math.floor((v - self.lo) / self.c) + e))
                  for v, e in ((x0, 0), (x1, 1)))
        i0, i1 = (max(0, min(self.n, math.floor((v - self.lo) / self.c) + e))
                  for v, e in ((y0, 0), (y1, 1)))
        return slice(i0, i1), slice(j0, j1)

    def drop_failing(self, cells: AnyArray, boxes: Array, d: float) -> None:
        """Clear, in place, the cells whose four corners lie closer than ``d`` to one box."""
        _drop_failing(cells, np.ascontiguousarray(boxes, dtype=float), self.lo, self.c, d)

    def box_between(self, lo: Array, hi: Array) -> AnyArray:
        """The cells that meet the box [lo, hi] (m)."""
        out = np.zeros((self.n, self.n), dtype=bool)
        out[self.cells_touching(float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))] = True
        return out

    def near(self, cells: AnyArray, boxes: Array, d: float) -> bool:
        """Whether a point of one of ``cells`` could lie closer than ``d`` to a box."""
        for x0, y0, x1, y1 in boxes:
            rows, cols = self.cells_touching(x0 - d, y0 - d, x1 + d, y1 + d)
            if cells[rows, cols].any():
                return True
        return False


class SubstepSweep:
    """The certificate's sweep: a reachable set advanced sub-step by sub-step until one sub-step
    answers (:class:`ReachableSet` in the plane, ``ReachableColumns`` over the band).

    A subclass sets :attr:`spec`, :attr:`grid`, :attr:`clearance`, :attr:`riding`,
    :attr:`last`, :attr:`unsupported` and ``s`` = 0, and writes :meth:`_substep`.
    """

    spec: MissionSpec
    grid: _Grid
    clearance: float | None
    riding: bool
    last: int
    unsupported: str
    s: int

    def run(self, until: int | None = None) -> Certificate | None:
        """Advance to sub-step ``until`` (None: the scope's last); the answer once there is
        one, None when ``until`` came first."""
        if self.unsupported:
            return Certificate("gave up", self.unsupported, 0)
        end = self.last if until is None else min(until, self.last)
        while self.s < end:
            self.s += 1
            done = self._substep(self.s)
            if done is not None:
                return done
        if self.s >= self.last:
            return Certificate("impossible", f"G out of reach for {self.last} sub-steps",
                               self.last)
        return None

    def _substep(self, s: int) -> Certificate | None:
        raise NotImplementedError

    def _births(self, s: int, born: Array, cells: AnyArray) -> Certificate | None:
        """Give up at sub-step ``s`` when a front ``born`` (rows x0, y0, x1, y1) could be
        redrawn off the UAV (the ignition clearance) or be born on it (rule "become"): a point
        of ``cells`` near it."""
        if len(born) and self.clearance is not None and self.grid.near(cells, born,
                                                                       self.clearance):
            return Certificate("gave up", f"a birth could be redrawn off the UAV at sub-step {s}",
                               s)
        if len(born) and self.riding and self.grid.near(cells, born, self.spec.d_safe_m):
            return Certificate("gave up", f"a front born on the UAV at sub-step {s} "
                               "(rule become)", s)
        return None


class ReachableSet(SubstepSweep):
    """D_s of a mission over a fire future, advanced sub-step by sub-step (module docstring).

    By default from the start at rest at sub-step 0; with ``state`` from that state (m, m/s)
    after ``substep0`` sub-steps of the future (the fires an in-flight UAV still faces).
    """

    def __init__(self, config: MissionConfig, future: Future,
                 params: CertificateParams = CertificateParams(), state: Array | None = None,
                 substep0: int = 0):
        reading = config.reading()
        self.spec = spec = config.spec()
        dyn = spec.dynamics
        self.future, self.substep0 = future, substep0
        self.grid = grid = _Grid(spec.area_size_m, params)
        x0 = hover_state(np.array(spec.start), dyn) if state is None else np.asarray(state)
        self.reach = np.zeros((grid.n, grid.n), dtype=bool)
        self.reach[grid.cell(*x0[:2])] = True
        self.goal = np.zeros_like(self.reach)
        self.goal[grid.cells_touching(*spec.goal.bounds)] = True
        self.move = math.ceil(dyn.dt_s * dyn.v_max_mps / grid.c)
        self.clearance = reading.mission.ignition_clearance_m
        self.riding = reading.mission.failure_rule == "become"
        self.last = scope_of(config, params, future.schedule_free).substeps - substep0
        #: row j: where the UAV can be after at most j + 1 flights from x0, per axis (m)
        lo, hi = reach_boxes(x0, reading.mission.max_steps, dyn)
        self.lo = np.minimum.accumulate(np.vstack([x0[:2], lo]), axis=0)[1:]
        self.hi = np.maximum.accumulate(np.vstack([x0[:2], hi]), axis=0)[1:]
        self.s = 0  # sub-steps done
        self.unsupported = unsupported(config)

    def _substep(self, s: int) -> Certificate | None:
        grid, spec = self.grid, self.spec
        births = self._births(s, self.future.newborn(self.substep0 + s), self.reach)
        if births is not None:
            return births
        grid.drop_failing(self.reach, self.future.regions(self.substep0 + s), spec.d_safe_m)
        if not self.reach.any():
            return Certificate("impossible", f"no position survives sub-step {s}", s)
        self.reach = grown(self.reach, self.move)
        if s <= len(self.lo):  # s flights at most: Eq. (1)'s reach from x0
            self.reach &= grid.box_between(self.lo[s - 1] - 1e-6, self.hi[s - 1] + 1e-6)
        if (self.reach & self.goal).any():
            return Certificate("reachable", f"G within reach after sub-step {s}", s)
        return None


def certify(config: MissionConfig, future: Future,
            params: CertificateParams = CertificateParams()) -> Certificate:
    """The certificate of ``config``'s mission over ``future`` (module docstring)."""
    done = ReachableSet(config, future, params).run()
    assert done is not None
    return done
