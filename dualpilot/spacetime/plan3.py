"""Plans through a known future of cuboids over the band: the 3-D lattice from a moving state.

docs/three_d.md §8–9. A :class:`~dualpilot.spacetime.plan.FutureBoxes` whose rows are
cuboids (x_lo, y_lo, x_hi, y_hi, top) over the ground, read by the A* of
:mod:`dualpilot.spacetime.lattice3` (states (t, p, v), p, v ∈ ℤ³, the vertical velocity on
the sub-lattice {−δ, 0, +δ}; the exact 3-D segment-to-cuboid distance). Its stages
(:class:`Stage3`): the altitudes between two levels (the origin's and the lowest at least d
above the tallest cuboid a UAV can fly over), or the whole band. The oracle
(:mod:`dualpilot.oracle.search3`) runs them from rest at the start; the lookahead supervisor
(:mod:`dualpilot.supervisor.lookahead`) from the UAV's state, its first flight fixed by it.
Lengths m, speeds m/s.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from dualpilot.arrays import AnyArray, Array
from dualpilot.model.altitude import AltitudeBand
from dualpilot.model.dynamics import rollout
from dualpilot.plan import Plan, PlanStatus
from dualpilot.spacetime.plan import FutureBoxes, Stage
from dualpilot.spec import MissionSpec

#: the altitudes a stage searches: between the two levels, or the whole band
Levels = Literal["two", "band"]


@dataclass(frozen=True)
class Stage3:
    """A stage of the 3-D search: its lattice and budget, and the altitudes it may fly."""

    stage: Stage
    levels: Levels


def altitude_indices(band: AltitudeBand, z0: float, tops: Array, levels: Levels, h: float,
                     d: float) -> tuple[int, int]:
    """The lattice's altitude indices (from ``z0`` m, spacing ``h`` m) a stage may fly: the
    band's, or those between ``z0`` and the lowest at least ``d`` above the tallest of
    ``tops`` that leaves room under the ceiling (``levels`` "two")."""
    lo = math.ceil((band.floor_m - z0) / h - 1e-9)
    hi = math.floor((band.ceiling_m - z0) / h + 1e-9)
    if levels == "band":
        return lo, hi
    over = [t + d for t in tops if t + d <= band.ceiling_m]
    level = math.ceil((max(over) - z0) / h - 1e-9) if over else 0
    return max(lo, min(0, level)), min(hi, max(0, level))


def plan_clear3(plan: Plan, future: FutureBoxes, d: float, steps: int | None = None) -> bool:
    """Whether the 3-D plan's first ``steps`` flights (all: None) keep ``d`` from the cuboids
    of their sub-steps, by the exact 3-D distance (flights past the future's last step meet
    its last cuboids)."""
    from dualpilot.spacetime.lattice3 import move_clear3  # compiled: loaded where it runs

    pos = np.ascontiguousarray(plan.states[:, :3], dtype=float)
    last = len(pos) - 1 if steps is None else min(steps, len(pos) - 1)
    for tau in range(last):
        t = min(tau, future.steps - 1)
        if not move_clear3(pos[tau], pos[tau + 1], t, future.per_step, future.boxes,
                           future.offsets, d):
            return False
    return True


def lattice_plan3(state: Array, future: FutureBoxes, spec: MissionSpec,
                  stages: Sequence[Stage3], steps: int, d: float) -> tuple[Plan | None, int]:
    """A 3-D plan from ``state`` (6,) into the goal box within ``steps`` flights that keeps
    ``d`` from the cuboids of ``future`` and stays in the band: the first stage that finds one
    (:func:`~dualpilot.spacetime.lattice3.astar3`), and the expansions spent.

    The first flight is fixed by the state (x_1 = x_0 + ΔT·v_0); the search starts at x_1,
    step 1, with every lattice velocity one control reaches from v_0 (j_z on the
    sub-lattice). None when the first flight fails or leaves the band, lands in G already,
    or no stage finds a path.
    """
    from dualpilot.spacetime.lattice import FOUND, reach_table
    from dualpilot.spacetime.lattice3 import astar3, move_clear3  # compiled: loaded here

    dyn = spec.dynamics
    x0 = np.asarray(state, dtype=float)
    p1 = x0[:3] + dyn.dt_s * x0[3:]
    steps = min(steps, future.steps)
    band = spec.band
    if steps < 2 or spec.in_goal(p1) or not band.floor_m <= p1[2] <= band.ceiling_m or \
            not move_clear3(x0[:3], p1, 0, future.per_step, future.boxes, future.offsets, d):
        return None, 0
    keep, acc = 1.0 - dyn.zeta, dyn.dt_s * dyn.u_max_n / dyn.mass_kg
    box = spec.goal_box
    goal = np.concatenate([box.lo + 1e-6, box.hi - 1e-6])
    spent = 0
    for stage3 in stages:
        stage = stage3.stage
        n_vel = round(dyn.v_max_mps / stage.delta_mps)
        first = _reachable3(x0[3:], stage.delta_mps, n_vel, keep, acc,
                            dyn.speed_limit == "norm")
        if len(first) == 0:
            continue
        h = stage.delta_mps * dyn.dt_s
        iz_lo, iz_hi = altitude_indices(band, float(p1[2]), future.boxes[:, 4], stage3.levels,
                                        h, d)
        table = reach_table(n_vel, stage.delta_mps, keep, acc, dyn.v_max_mps, dyn.dt_s, steps)
        outcome, path, expansions = astar3(
            p1, 1, first, future.boxes, future.offsets, future.per_step, goal,
            spec.area_size_m, iz_lo, iz_hi, d, stage.delta_mps, dyn.dt_s, n_vel, keep, acc,
            dyn.speed_limit == "norm", steps, stage.budget, table, round(16 * stage.weight))
        spent += expansions
        if outcome == FOUND:
            return _plan_of(path, x0, p1, stage.delta_mps, spec), spent
    return None, spent


def _plan_of(path: AnyArray, x0: Array, p1: Array, delta: float, spec: MissionSpec) -> Plan:
    """The plan of a lattice path (rows t, i (3), j (3), from x_1): its controls
    u_t = m·(v_{t+1} − (1 − ζ)·v_t)/ΔT from v_0, u = 0 on the last step, rolled out by
    Eq. (1) from ``x0``."""
    dyn = spec.dynamics
    keep = 1.0 - dyn.zeta
    vel = delta * path[:, 4:7].astype(float)
    vel[-1] = keep * (vel[-2] if len(vel) > 1 else x0[3:])  # the last control is zero
    velocities = np.vstack([x0[3:], vel])
    controls = dyn.mass_kg * (velocities[1:] - keep * velocities[:-1]) / dyn.dt_s
    states = rollout(x0, controls, dyn)
    h = delta * dyn.dt_s
    assert np.allclose(states[1:, :3], p1 + h * path[:, 1:4], atol=1e-6)
    return Plan(1, PlanStatus.OK, states, controls, 0.0, info={"planner": "space-time"})


def _reachable3(v0: Array, delta: float, n_vel: int, keep: float, acc: float,
                norm: bool) -> AnyArray:
    """Rows (j_x, j_y, j_z) of the lattice velocities one control reaches from ``v0`` (j_z in
    {−1, 0, 1})."""
    lo = [max(-n_vel, math.ceil((keep * v0[a] - acc) / delta - 1e-9)) for a in range(3)]
    hi = [min(n_vel, math.floor((keep * v0[a] + acc) / delta + 1e-9)) for a in range(3)]
    lo[2], hi[2] = max(lo[2], -1), min(hi[2], 1)
    rows = [(jx, jy, jz) for jx in range(lo[0], hi[0] + 1) for jy in range(lo[1], hi[1] + 1)
            for jz in range(lo[2], hi[2] + 1)
            if not norm or jx * jx + jy * jy + jz * jz <= n_vel * n_vel]
    return np.array(rows, dtype=np.int64).reshape(-1, 3)
