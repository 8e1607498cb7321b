"""Which front catches a hovering UAV: one born during the same wait, or an older one?

Flies the evaluation's configurations (seed pair (0, i), as `dualpilot evaluate
--seed 0`) under the paper's timing and, for every mission that ends with
``fire_while_planning``, records whether the front that came within d_safe
existed before the wait began. Usage::

    .venv/bin/python benchmarks/failure_causes.py s2 40
"""

from __future__ import annotations

import collections
import sys

import numpy as np

from dualpilot.evaluate import mission_config, mission_seed
from dualpilot.mission.step import Controller, Mission, Timing
from dualpilot.planners import make_planners


class ProbedMission(Mission):
    """A mission that remembers which front caught the UAV while it hovered."""

    cause: tuple[str, float | None] | None = None

    def _propagate(self, n: int, t: int) -> bool:
        position = self.state[:2]
        before = {f.front_id: f.region.polytope().distance(position) for f in self.fires.fronts}
        for _ in range(n):
            self.fires.substep(self.fire_rng, t)
            for front in self.fires.fronts:
                if front.region.polytope().distance(position) < self.params.d_safe_m:
                    kind = "older front" if front.front_id in before else "born during the wait"
                    self.cause = (kind, before.get(front.front_id))
                    return False
        return True


def main(controller: str, n: int) -> None:
    kinds: collections.Counter[str] = collections.Counter()
    distances = []
    for i in range(n):
        seed, config = mission_seed(0, i), mission_config(0, i)
        mission = ProbedMission(
            Controller(controller),
            make_planners(config, seed),
            seed=seed,
            timing=Timing.PAPER,
            config=config,
        )
        result = mission.run()
        if result.failure_cause == "fire_while_planning" and mission.cause is not None:
            kinds[mission.cause[0]] += 1
            if mission.cause[1] is not None:
                distances.append(mission.cause[1])
    print(f"{controller}, {n} missions, caught while planning: {dict(kinds)}")
    if distances:
        print(f"older fronts' distance when the wait began: median {np.median(distances):.1f} m")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "s2", int(sys.argv[2]) if len(sys.argv) > 2 else 40)
