"""The oracle's witness search over the altitude band: the lattice of :mod:`.search` in 3-D.

docs/three_d.md §9. The A* of :mod:`dualpilot.spacetime.lattice3` over (t, p, v) with
p, v ∈ ℤ³ (the vertical velocity on the sub-lattice {−δ, 0, +δ}), against the cuboids of
the known future (rows x_lo, y_lo, x_hi, y_hi, top: :class:`~dualpilot.oracle.future.FireFuture`
of a 3-D mission), keeping d = max(d_safe, ignition clearance) + a margin from each in 3-D
(the step's distances and its keep-out are 3-D), positions within the band
[floor, ceiling] (what the run-time monitor passes) and the flight's end in the goal box.

The stages (:class:`SearchParams3`), each a budget of node expansions: first the altitudes
between two levels, the start's and d above the tallest cuboid a UAV can fly over (top + d
≤ the ceiling), with the climbs between (few states; most missions), then every altitude
of the band, then the finer lattice. A witness is a trajectory of Eq. (1) whatever the
stage; completeness is claimed only on the lattice of the last stage (the certificate, not
the search, proves impossibility). Lengths m, speeds m/s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dualpilot.arrays import Array
from dualpilot.mission.config import MissionConfig
from dualpilot.oracle.future import Future
from dualpilot.oracle.search import SearchOutcome, Witness, lattice_terms
from dualpilot.spacetime.plan import Stage
from dualpilot.spacetime.plan3 import Levels, Stage3, altitude_indices


@dataclass(frozen=True)
class SearchParams3:
    """The stages of the 3-D witness search, tried in turn until one finds a witness."""

    #: the budgets of docs/three_d.md §9 (200k / 600k / 1M expansions)
    stages: tuple[Stage3, ...] = (Stage3(Stage(5.0, 200_000, weight=1.5), "two"),
                                  Stage3(Stage(5.0, 600_000, weight=3.0), "band"),
                                  Stage3(Stage(2.5, 1_000_000, weight=3.0), "band"))
    #: distance kept beyond d_safe (m), for the round-off of flying the witness
    margin_m: float = 0.05

    def __post_init__(self) -> None:
        if not (self.stages and self.margin_m >= 0):
            raise ValueError(f"invalid search parameters: {self}")


def search3(config: MissionConfig, future: Future,
            params: SearchParams3 = SearchParams3()) -> SearchOutcome:
    """The witness search of ``config``'s 3-D mission on ``future`` (rows with tops)."""
    spent, reason = 0, "exhausted"
    for stage in params.stages:
        path, why, expansions = _run_stage(config, future, stage, params.margin_m)
        spent += expansions
        if path is not None:
            return SearchOutcome(witness_of3(path, stage.stage.delta_mps, config), "found",
                                 spent)
        reason = why
    return SearchOutcome(None, reason, spent)


def altitude_range(config: MissionConfig, tops: Array, levels: Levels, h: float,
                   d: float) -> tuple[int, int]:
    """The lattice's altitude indices (from the start's, spacing ``h`` m) a stage may fly:
    the band's, or those between the start's and the lowest at least ``d`` above the tallest
    of ``tops`` that leaves room under the ceiling (``levels`` "two")."""
    band = config.spec().band
    return altitude_indices(band, band.start_altitude_m, tops, levels, h, d)


def _run_stage(config: MissionConfig, future: Future, stage3: Stage3,
               margin_m: float) -> tuple[Array | None, str, int]:
    """One A* run: (path or None, "found" / "exhausted" / "budget", expansions)."""
    from dualpilot.spacetime.lattice import BUDGET, EXHAUSTED, FOUND
    from dualpilot.spacetime.lattice3 import astar3  # compiled: loaded where it runs

    stage, spec = stage3.stage, config.spec()
    dyn = spec.dynamics
    lt = lattice_terms(config, stage.delta_mps, margin_m, 3)
    steps, n_vel, keep, acc, table, d = lt.steps, lt.n_vel, lt.keep, lt.acc, lt.table, lt.d
    boxes, offsets = future.packed(steps * future.substeps_per_step)
    if boxes.shape[1] != 5:
        raise ValueError("the 3-D search reads regions with their tops (x0, y0, x1, y1, top)")
    iz_lo, iz_hi = altitude_range(config, boxes[:, 4], stage3.levels,
                                  stage.delta_mps * dyn.dt_s, d)
    box = spec.goal_box
    goal = np.concatenate([box.lo + 1e-6, box.hi - 1e-6])
    outcome, path, expansions = astar3(
        np.asarray(spec.start_position, dtype=float), 0, np.zeros((1, 3), dtype=np.int64),
        np.ascontiguousarray(boxes), offsets, future.substeps_per_step, goal, spec.area_size_m,
        iz_lo, iz_hi, d, stage.delta_mps, dyn.dt_s, n_vel, keep, acc, dyn.speed_limit == "norm",
        steps, stage.budget, table, round(16 * stage.weight))
    if outcome == FOUND:
        return path, "found", expansions
    return None, {EXHAUSTED: "exhausted", BUDGET: "budget"}[outcome], expansions


def witness_of3(path: Array, delta: float, config: MissionConfig) -> Witness:
    """The states (T+1, 6) and controls (T, 3) of a lattice path (rows t, i (3), j (3)), from
    the start: u_t = m·(v_{t+1} − (1 − ζ)·v_t)/ΔT, u = 0 on the last step (as in the plane)."""
    spec = config.spec()
    dyn = spec.dynamics
    h = delta * dyn.dt_s
    pos = np.asarray(spec.start_position, dtype=float) + h * path[:, 1:4].astype(float)
    vel = delta * path[:, 4:7].astype(float)
    vel[-1] = (1.0 - dyn.zeta) * vel[-2]  # the last control is zero
    controls = dyn.mass_kg * (vel[1:] - (1.0 - dyn.zeta) * vel[:-1]) / dyn.dt_s
    return Witness(np.hstack([pos, vel]), controls)
