"""Build the two planners of a mission from a seed (kept apart from the loop for the services)."""

from __future__ import annotations

import numpy as np

from dualpilot.mission.step import MissionConfig
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.plan import Planner
from dualpilot.system2.problem import System2Params

#: Seed-sequence key of System 1's RNG, apart from the fire and supervisor streams.
SYSTEM1_STREAM = 7


def make_system1(
    config: MissionConfig, seed: int, dynamics: DynamicsParams = DynamicsParams()
) -> Planner:
    from dualpilot.system1.planner import System1

    rng = np.random.default_rng(np.random.SeedSequence([seed, SYSTEM1_STREAM]))
    return System1(config.goal, rng=rng, dynamics=dynamics, area_size_m=config.area_size_m)


def make_system2_planner(
    config: MissionConfig,
    method: str = "fast",
    params: System2Params = System2Params(),
    dynamics: DynamicsParams = DynamicsParams(),
) -> Planner:
    from dualpilot.system2.fast.planner import make_system2

    return make_system2(method, config.goal, params, dynamics)


def make_planners(
    config: MissionConfig,
    seed: int,
    system2_method: str = "fast",
    system2_params: System2Params = System2Params(),
    dynamics: DynamicsParams = DynamicsParams(),
) -> dict[int, Planner]:
    return {
        1: make_system1(config, seed, dynamics),
        2: make_system2_planner(config, system2_method, system2_params, dynamics),
    }
