"""The oracle's impossibility certificate over the band: D_s as columns of one altitude interval.

docs/three_d.md §9, the planar certificate (:mod:`~dualpilot.oracle.certificate`) with an
altitude interval [lo, hi] in each cell of its grid (empty: lo > hi). Each step of the
argument carries over:

* **growth**: between two sub-steps a controller flies at most one step, ΔT·v_max per axis
  (|v_z| ≤ v_max under both speed limits): a cell's new interval is the hull of the
  intervals of the cells within the planar reach, widened by ΔT·v_max (the hull of a union
  of intervals contains it: an over-approximation). Eq. (1)'s reach box from the start
  bounds every axis, and the altitude stays within the band grown by the monitor's
  allowance and braking's overshoot (:func:`~dualpilot.oracle.reduction.highest_uav_m`:
  every plan the run-time monitor passes keeps the band; braking from the speed limit
  carries 19.86 m past it), never below the ground;
* **removal**: a point fails the check of sub-step s when it lies closer than d_safe to a
  cuboid (bottom 0, top τ): √(d_xy² + d_z²) < d_safe. Over a cell the planar distance is
  at most D, the largest of its corners' (convex), so every point of the cell at an
  altitude z ≥ 0 with z < τ + √(d_safe² − D²) fails: the column loses that lower part and
  stays one interval. A cuboid with τ + d_safe above the column's top removes it whole,
  as in the plane;
* **the goal**: a cell meets G when it touches its rectangle and its interval meets the
  goal box's altitudes.

The ignition keep-out and the rule "become" give up as in the plane, on the planar
distance (never more than the 3-D one: it gives up at least as often). Lengths m.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from dualpilot.arrays import AnyArray, Array
from dualpilot.mission.braking import braking_overshoot_m
from dualpilot.mission.config import MissionConfig
from dualpilot.mission.monitor import MonitorParams
from dualpilot.model.dynamics import hover_state, reach_boxes
from dualpilot.oracle.certificate import (
    Certificate,
    CertificateParams,
    SubstepSweep,
    _Grid,
    scope_of,
    unsupported,
)
from dualpilot.oracle.future import Future


@njit(cache=True)
def drop_failing3(lo: Array, hi: Array, boxes: Array, g0: float, c: float, d: float) -> None:
    """Raise, in place, each column's floor past the altitudes where every point of its cell
    lies closer than ``d`` to a cuboid of ``boxes`` (rows x0, y0, x1, y1, top)."""
    n = lo.shape[0]
    d2 = (d - 1e-6) ** 2  # round-off: a corner counts only when clearly inside
    for k in range(len(boxes)):
        x0, y0, x1, y1, top = boxes[k, 0], boxes[k, 1], boxes[k, 2], boxes[k, 3], boxes[k, 4]
        j0 = max(0, math.floor((x0 - d - g0) / c))
        j1 = min(n, math.floor((x1 + d - g0) / c) + 1)
        i0 = max(0, math.floor((y0 - d - g0) / c))
        i1 = min(n, math.floor((y1 + d - g0) / c) + 1)
        for i in range(i0, i1):
            for j in range(j0, j1):
                if lo[i, j] > hi[i, j]:
                    continue
                far = 0.0
                for cy in (g0 + c * i, g0 + c * (i + 1)):
                    gy = max(0.0, max(y0 - cy, cy - y1))
                    for cx in (g0 + c * j, g0 + c * (j + 1)):
                        gx = max(0.0, max(x0 - cx, cx - x1))
                        far = max(far, gx * gx + gy * gy)
                if far < d2:
                    lo[i, j] = max(lo[i, j], top + math.sqrt(d2 - far))


@njit(cache=True)
def grown3(lo: Array, hi: Array, r: int, mz: float) -> tuple[Array, Array]:
    """Each cell's interval: the hull of those within ``r`` cells (a square), widened by
    ``mz`` m; an empty cell is lo = +∞, hi = −∞."""
    n = lo.shape[0]
    rlo, rhi = np.full((n, n), np.inf), np.full((n, n), -np.inf)
    for i in range(n):  # along each row
        for j in range(n):
            if lo[i, j] <= hi[i, j]:
                for b in range(max(0, j - r), min(n, j + r + 1)):
                    rlo[i, b] = min(rlo[i, b], lo[i, j])
                    rhi[i, b] = max(rhi[i, b], hi[i, j])
    olo, ohi = np.full((n, n), np.inf), np.full((n, n), -np.inf)
    for i in range(n):  # then along each column
        for j in range(n):
            if rlo[i, j] <= rhi[i, j]:
                for a in range(max(0, i - r), min(n, i + r + 1)):
                    olo[a, j] = min(olo[a, j], rlo[i, j] - mz)
                    ohi[a, j] = max(ohi[a, j], rhi[i, j] + mz)
    return olo, ohi


class ReachableColumns(SubstepSweep):
    """D_s of a 3-D mission over a fire future of cuboids (module docstring), advanced
    sub-step by sub-step; from the start at rest, or from ``state`` (6,) after ``substep0``
    sub-steps, as :class:`~dualpilot.oracle.certificate.ReachableSet`."""

    def __init__(self, config: MissionConfig, future: Future,
                 params: CertificateParams = CertificateParams(), state: Array | None = None,
                 substep0: int = 0):
        reading = config.reading()
        self.spec = spec = config.spec()
        dyn = spec.dynamics
        if dyn.dim != 3:
            raise ValueError("columns are the certificate of a 3-D mission")
        self.future, self.substep0 = future, substep0
        self.grid = grid = _Grid(spec.area_size_m, params)
        x0 = hover_state(spec.start_position, dyn) if state is None else np.asarray(state)
        self.lo, self.hi = np.full((grid.n, grid.n), np.inf), np.full((grid.n, grid.n), -np.inf)
        self.lo[grid.cell(*x0[:2])] = self.hi[grid.cell(*x0[:2])] = x0[2]
        self.goal = np.zeros((grid.n, grid.n), dtype=bool)
        self.goal[grid.cells_touching(*spec.goal.bounds)] = True
        self.goal_z = (spec.goal_box.z_lo, spec.goal_box.z_hi)
        self.move = math.ceil(dyn.dt_s * dyn.v_max_mps / grid.c)
        self.move_z = dyn.dt_s * dyn.v_max_mps
        beyond = MonitorParams().area_tol_m + braking_overshoot_m(dyn)
        self.z_range = (max(0.0, spec.band.floor_m - beyond), spec.band.ceiling_m + beyond)
        self.clearance = reading.mission.ignition_clearance_m
        self.riding = reading.mission.failure_rule == "become"
        self.last = scope_of(config, params, future.schedule_free).substeps - substep0
        lo, hi = reach_boxes(x0, reading.mission.max_steps, dyn)
        self.box_lo = np.minimum.accumulate(np.vstack([x0[:3], lo]), axis=0)[1:]
        self.box_hi = np.maximum.accumulate(np.vstack([x0[:3], hi]), axis=0)[1:]
        self.s = 0
        self.unsupported = unsupported(config)

    @property
    def cells(self) -> AnyArray:
        """The cells whose column is not empty."""
        return self.lo <= self.hi

    def _substep(self, s: int) -> Certificate | None:
        grid, spec = self.grid, self.spec
        births = self._births(s, self.future.newborn(self.substep0 + s)[:, :4], self.cells)
        if births is not None:
            return births
        boxes = np.ascontiguousarray(self.future.regions(self.substep0 + s), dtype=float)
        drop_failing3(self.lo, self.hi, boxes, grid.lo, grid.c, spec.d_safe_m)
        if not self.cells.any():
            return Certificate("impossible", f"no position survives sub-step {s}", s)
        self.lo, self.hi = grown3(self.lo, self.hi, self.move, self.move_z)
        z_lo, z_hi = self.z_range
        if s <= len(self.box_lo):  # s flights at most: Eq. (1)'s reach from x0
            b_lo, b_hi = self.box_lo[s - 1] - 1e-6, self.box_hi[s - 1] + 1e-6
            outside = ~grid.box_between(b_lo, b_hi)
            self.lo[outside], self.hi[outside] = np.inf, -np.inf
            z_lo, z_hi = max(z_lo, b_lo[2]), min(z_hi, b_hi[2])
        np.maximum(self.lo, z_lo, out=self.lo)
        np.minimum(self.hi, z_hi, out=self.hi)
        meets = self.goal & (self.lo <= self.goal_z[1]) & (self.hi >= self.goal_z[0])
        if meets.any():
            return Certificate("reachable", f"G within reach after sub-step {s}", s)
        return None


def certify3(config: MissionConfig, future: Future,
             params: CertificateParams = CertificateParams()) -> Certificate:
    """The certificate of ``config``'s 3-D mission over ``future`` (module docstring)."""
    done = ReachableColumns(config, future, params).run()
    assert done is not None
    return done
