"""Plans through a known future of boxes: the lattice search from a moving state, and checks.

A :class:`FutureBoxes` is the compiled form :func:`dualpilot.spacetime.lattice.astar` reads:
the boxes (x_lo, y_lo, x_hi, y_hi) after each sub-step s = 0, 1, … counted from now,
``boxes[offsets[s]:offsets[s + 1]]``, with ``per_step`` sub-steps a step. A plan's step
τ (the flight x_τ → x_{τ+1}) meets the fires of sub-steps τ·k + 1..(τ + 1)·k: the
failure rules of :func:`~dualpilot.spacetime.lattice.move_clear`. Lengths m, speeds m/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dualpilot.arrays import AnyArray, Array
from dualpilot.model.dynamics import rollout
from dualpilot.plan import Plan, PlanStatus
from dualpilot.spec import MissionSpec

#: the cells of the static distance field (m)
FIELD_CELL_M = 10.0


@dataclass(frozen=True)
class Stage:
    """One A* run: its lattice, priority weight, pruning and budget."""

    #: lattice velocity step δ (m/s); v_max must be a multiple of it
    delta_mps: float
    #: node expansions before this stage gives up
    budget: int
    #: weighted A*: priority t + weight·h (1: A*, the fewest flights on the lattice)
    weight: float = 1.0
    #: one queued node per step, velocity and square of this many lattice positions a side
    bucket: int = 1

    def __post_init__(self) -> None:
        if not (self.delta_mps > 0 and self.budget > 0 and self.weight >= 1.0
                and self.bucket >= 1):
            raise ValueError(f"invalid search stage: {self}")


@dataclass(frozen=True)
class FutureBoxes:
    """Boxes after each sub-step from now (module docstring); ``per_step`` sub-steps a step."""

    boxes: Array
    offsets: AnyArray
    per_step: int = 1

    @property
    def steps(self) -> int:
        """Steps whose every sub-step has boxes."""
        return (len(self.offsets) - 2) // self.per_step

    @staticmethod
    def of(parts: list[Array], per_step: int = 1) -> FutureBoxes:
        """The future whose boxes after sub-step s are ``parts[s]`` (each (k, 4), or (k, 5) with
        the cuboids' tops)."""
        offsets = np.zeros(len(parts) + 1, dtype=np.int64)
        offsets[1:] = np.cumsum([len(p) for p in parts])
        width = parts[0].shape[1] if parts else 4
        boxes = np.vstack(parts) if offsets[-1] else np.empty((0, width))
        return FutureBoxes(np.ascontiguousarray(boxes, dtype=float), offsets, per_step)


def arrival(plan: Plan, spec: MissionSpec) -> int | None:
    """The first step τ ≥ 1 whose position x_τ lies in G (None: the plan never gets there)."""
    pos = plan.states[:, :2]
    for tau in range(1, len(pos)):
        if spec.goal.contains(pos[tau]):
            return tau
    return None


def plan_clear(plan: Plan, future: FutureBoxes, d: float, steps: int | None = None) -> bool:
    """Whether the plan's first ``steps`` flights (all: None) keep ``d`` from the boxes of their
    sub-steps (flights past the future's last step meet its last boxes)."""
    from dualpilot.spacetime.lattice import move_clear  # compiled: loaded where a plan is checked

    pos = plan.states[:, :2]
    last = len(pos) - 1 if steps is None else min(steps, len(pos) - 1)
    k = future.per_step
    for tau in range(last):
        t = min(tau, future.steps - 1)
        if not move_clear(pos[tau, 0], pos[tau, 1], pos[tau + 1, 0], pos[tau + 1, 1], t, k,
                          future.boxes, future.offsets, d):
            return False
    return True


def lattice_plan(state: Array, future: FutureBoxes, spec: MissionSpec, stage: Stage, steps: int,
                 d: float, static: Array | None = None,
                 survive: int = 0) -> tuple[Plan | None, int]:
    """A plan from ``state`` into G within ``steps`` flights that keeps ``d`` from the boxes of
    ``future`` (the A* of :mod:`~dualpilot.spacetime.lattice`), and the expansions spent.

    The first flight is fixed by the state (x_1 = x_0 + ΔT·v_0 in position); the search starts
    at x_1 with every lattice velocity one control can reach from v_0. None when the first
    flight fails, lands in G already (nothing to plan), or no path is found. ``static``:
    boxes present at every sub-step of ``future``, whose distance field
    (:mod:`~dualpilot.spacetime.field`) sharpens the search's heuristic. With ``survive``
    > 0 the plan need not reach G: it keeps ``d`` for ``survive`` flights (an escape).
    """
    from dualpilot.spacetime.field import no_field, static_field  # compiled: loaded here
    from dualpilot.spacetime.lattice import FOUND, astar, move_clear, reach_table

    dyn = spec.dynamics
    n_vel = round(dyn.v_max_mps / stage.delta_mps)
    keep, acc = 1.0 - dyn.zeta, dyn.dt_s * dyn.u_max_n / dyn.mass_kg
    p0, v0 = np.asarray(state[:2], dtype=float), np.asarray(state[2:], dtype=float)
    p1 = p0 + dyn.dt_s * v0
    steps = min(steps, future.steps)
    if survive:
        steps = min(steps, survive)
    if steps < 2 or spec.goal.contains(p1) or not move_clear(
            p0[0], p0[1], p1[0], p1[1], 0, future.per_step, future.boxes, future.offsets, d):
        return None, 0
    first = _reachable(v0, stage.delta_mps, n_vel, keep, acc, dyn.v_max_mps,
                       dyn.speed_limit == "norm")
    if len(first) == 0:
        return None, 0
    table = reach_table(n_vel, stage.delta_mps, keep, acc, dyn.v_max_mps, dyn.dt_s, steps)
    goal = np.array(spec.goal.bounds) + np.array([1, 1, -1, -1]) * 1e-6
    if survive:  # anywhere in the area will do
        goal = np.array([0.0, 0.0, spec.area_size_m, spec.area_size_m])
    field = no_field() if survive or static is None or not len(static) else static_field(
        np.ascontiguousarray(static, dtype=float), goal, spec.area_size_m, d, FIELD_CELL_M)
    outcome, path, expansions = astar(
        p1, 1, first, future.boxes, future.offsets, future.per_step, goal, spec.area_size_m, d,
        stage.delta_mps, dyn.dt_s, n_vel, keep, acc, dyn.v_max_mps, dyn.speed_limit == "norm",
        steps, stage.budget, table, round(16 * stage.weight), stage.bucket, field, FIELD_CELL_M,
        survive)
    if outcome != FOUND:
        return None, expansions
    h = stage.delta_mps * dyn.dt_s
    vel = stage.delta_mps * path[:, 3:5].astype(float)
    vel[-1] = keep * (vel[-2] if len(vel) > 1 else v0)  # the last control is zero
    velocities = np.vstack([v0, vel])
    controls = dyn.mass_kg * (velocities[1:] - keep * velocities[:-1]) / dyn.dt_s
    states = rollout(np.asarray(state, dtype=float), controls, dyn)
    assert np.allclose(states[1:, :2], p1 + h * path[:, 1:3], atol=1e-6)
    return Plan(1, PlanStatus.OK, states, controls, 0.0, info={"planner": "space-time"}), \
        expansions


def _reachable(v0: Array, delta: float, n_vel: int, keep: float, acc: float, v_max: float,
               norm: bool) -> AnyArray:
    """Rows (j_x, j_y) of the lattice velocities one control reaches from the velocity v0."""
    lo = [max(-n_vel, math.ceil((keep * v0[a] - acc) / delta - 1e-9)) for a in (0, 1)]
    hi = [min(n_vel, math.floor((keep * v0[a] + acc) / delta + 1e-9)) for a in (0, 1)]
    rows = [(jx, jy) for jx in range(lo[0], hi[0] + 1) for jy in range(lo[1], hi[1] + 1)
            if not norm or (jx * jx + jy * jy) * delta * delta <= v_max * v_max + 1e-9]
    return np.array(rows, dtype=np.int64).reshape(-1, 2)
