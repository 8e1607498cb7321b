"""The oracle's witness search: a path to G through the known fire future, under Eq. (1).

A time-expanded A* (:func:`dualpilot.spacetime.lattice.astar`) over a lattice of the
states of Eq. (1) (velocities in steps of δ per axis, positions in steps of δ·ΔT),
with the failure rules at a distance d = max(d_safe, ignition clearance) + a margin
from the regions of the known future (:mod:`~dualpilot.oracle.future`). Keeping the
ignition clearance from every region makes the future exact along the witness: no
birth is ever redrawn for it (the regions contain every drawn birth). The oracle's
steps take one planning sub-step each; hovering in place is how it waits.

The search is complete on its lattice within ``max_steps`` flights and, with an
admissible heuristic, finds the fewest flights on it; a finer lattice could find a
path this one misses (the certificate, not the search, proves impossibility).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dualpilot.arrays import Array
from dualpilot.mission.config import MissionConfig
from dualpilot.oracle.future import Future
from dualpilot.spacetime.field import no_field
from dualpilot.spacetime.lattice import BUDGET, EXHAUSTED, FOUND, astar, reach_table
from dualpilot.spacetime.plan import Stage


@dataclass(frozen=True)
class SearchParams:
    """The stages of the witness search, tried in turn until one finds a witness."""

    #: a coarse lattice first (δ = 5 m/s: few states, most missions), then greedier on it
    #: (weighted A*: faster, longer witnesses), then the finer lattice (δ = 2.5 m/s)
    stages: tuple[Stage, ...] = (Stage(5.0, 200_000, weight=1.5),
                                 Stage(5.0, 600_000, weight=3.0),
                                 Stage(2.5, 1_000_000, weight=3.0))
    #: distance kept beyond d_safe (m), for the round-off of flying the witness
    margin_m: float = 0.05

    def __post_init__(self) -> None:
        if not (self.stages and self.margin_m >= 0):
            raise ValueError(f"invalid search parameters: {self}")


@dataclass(frozen=True)
class Witness:
    """A trajectory through the fires: states x_0..x_T (T+1, 2·dim) and controls u_0..u_{T−1}
    (T, dim); the search's are planar (:func:`dualpilot.oracle.reduction.lift` flies them in
    3-D)."""

    states: Array
    controls: Array

    @property
    def steps(self) -> int:
        return len(self.controls)


@dataclass(frozen=True)
class SearchOutcome:
    """What the search found: a witness, or why not ("exhausted": no lattice path; "budget")."""

    witness: Witness | None
    reason: str
    expansions: int


def search(config: MissionConfig, future: Future,
           params: SearchParams = SearchParams()) -> SearchOutcome:
    """The witness search of ``config``'s mission on ``future``: each stage in turn."""
    spent, reason = 0, "exhausted"
    for stage in params.stages:
        path, why, expansions = _run_stage(config, future, stage, params.margin_m)
        spent += expansions
        if path is not None:
            spec = config.spec()
            return SearchOutcome(witness_of(path, spec.start, stage.delta_mps, config), "found",
                                 spent)
        reason = why
    return SearchOutcome(None, reason, spent)


@dataclass(frozen=True)
class LatticeTerms:
    """What an A* run over a mission's lattice needs of its dynamics (Eq. (1)) and distances."""

    steps: int  # the mission's step limit (flights)
    n_vel: int  # velocities per axis side: v_max / δ
    keep: float  # 1 − ζ: the velocity kept over a step
    acc: float  # ΔT·u_max / m (m/s): the largest change of velocity a step
    table: Array  # reach_table's rows: the heuristic's least steps
    d: float  # the distance kept from every region (m): max(d_safe, the ignition clearance)
    #: plus the search's margin


def lattice_terms(config: MissionConfig, delta_mps: float, margin_m: float,
                  dim: int) -> LatticeTerms:
    """The :class:`LatticeTerms` of ``config``'s ``dim``-D mission on a lattice of velocity
    spacing ``delta_mps`` (ValueError: another dimension, 4096 steps or more, or a v_max that is
    not a multiple of the spacing)."""
    reading, spec = config.reading(), config.spec()
    dyn = spec.dynamics
    steps = reading.mission.max_steps
    if dyn.dim != dim or steps >= 4096:
        raise ValueError(f"the oracle's {dim}-D search takes {dim}-D missions of fewer than "
                         "4096 steps")
    n_vel = round(dyn.v_max_mps / delta_mps)
    if abs(n_vel * delta_mps - dyn.v_max_mps) > 1e-9:
        raise ValueError(f"v_max {dyn.v_max_mps} is not a multiple of δ {delta_mps}")
    keep = 1.0 - dyn.zeta
    acc = dyn.dt_s * dyn.u_max_n / dyn.mass_kg
    table = reach_table(n_vel, delta_mps, keep, acc, dyn.v_max_mps, dyn.dt_s, steps)
    clear = reading.mission.ignition_clearance_m or 0.0
    return LatticeTerms(steps, n_vel, keep, acc, table, max(spec.d_safe_m, clear) + margin_m)


def _run_stage(config: MissionConfig, future: Future, stage: Stage,
               margin_m: float) -> tuple[Array | None, str, int]:
    """One A* run: (path or None, "found" / "exhausted" / "budget", expansions)."""
    spec = config.spec()
    dyn = spec.dynamics
    lt = lattice_terms(config, stage.delta_mps, margin_m, 2)
    steps, n_vel, keep, acc, table, d = lt.steps, lt.n_vel, lt.keep, lt.acc, lt.table, lt.d
    boxes, offsets = future.packed(steps * future.substeps_per_step)
    g = np.array(spec.goal.bounds) + np.array([1, 1, -1, -1]) * 1e-6
    outcome, path, expansions = astar(
        np.array(spec.start, dtype=float), 0, np.zeros((1, 2), dtype=np.int64), boxes, offsets,
        future.substeps_per_step, g,
        spec.area_size_m, d, stage.delta_mps, dyn.dt_s, n_vel, keep, acc, dyn.v_max_mps,
        dyn.speed_limit == "norm", steps, stage.budget, table, round(16 * stage.weight),
        stage.bucket, no_field(), 1.0)
    if outcome == FOUND:
        return path, "found", expansions
    return None, {EXHAUSTED: "exhausted", BUDGET: "budget"}[outcome], expansions


def witness_of(path: Array, start: tuple[float, float], delta: float,
               config: MissionConfig) -> Witness:
    """The states and controls of a lattice path (rows t, i_x, i_y, j_x, j_y; the last row's
    position in G, its velocity the last flight's): u_t = m·(v_{t+1} − (1 − ζ)·v_t)/ΔT, and
    u = 0 on the last step."""
    dyn = config.spec().dynamics
    h = delta * dyn.dt_s
    pos = np.asarray(start, dtype=float) + h * path[:, 1:3].astype(float)
    vel = delta * path[:, 3:5].astype(float)
    vel[-1] = (1.0 - dyn.zeta) * vel[-2]  # the last control is zero
    states = np.hstack([pos, vel])
    controls = dyn.mass_kg * (vel[1:] - (1.0 - dyn.zeta) * vel[:-1]) / dyn.dt_s
    return Witness(states, controls)
