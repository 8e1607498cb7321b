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
from collections.abc import Sequence

import numpy as np

from dualpilot.evaluation.missions import Task, mission_spec
from dualpilot.mission.local import LocalFires, local_mission
from dualpilot.mission.ports import KeepOut
from dualpilot.model.fire import Region
from dualpilot.spec import MissionSpec


class ProbedFires(LocalFires):
    """The in-process fires, remembering which front first came within d_safe of the UAV."""

    def __init__(self, spec: MissionSpec):
        super().__init__(spec)
        self.d_safe = spec.d_safe_m
        self.position = np.array(spec.start)
        self.cause: tuple[str, float | None] | None = None

    def advance(self, t: int, n: int,
                keep_out: KeepOut | None) -> Sequence[tuple[Region, ...]]:
        position = self.position
        before = {f.front_id: f.region.polytope().distance(position) for f in self.field.fronts}
        out = super().advance(t, n, keep_out)
        for front in self.field.fronts:
            if self.cause is None and front.region.polytope().distance(position) < self.d_safe:
                kind = "older front" if front.front_id in before else "born during the wait"
                self.cause = (kind, before.get(front.front_id))
        return out


def main(controller: str, n: int) -> None:
    kinds: collections.Counter[str] = collections.Counter()
    distances = []
    for i in range(n):
        spec = mission_spec(0, i)
        mission = local_mission(Task.of(i, 0, controller).mission())
        probe = ProbedFires(spec)
        mission.fires = probe
        while not mission.done:
            probe.position = mission.state[:2].copy()
            mission.step()
        result = mission.result
        if result.failure_cause == "fire_while_planning" and probe.cause is not None:
            kinds[probe.cause[0]] += 1
            if probe.cause[1] is not None:
                distances.append(probe.cause[1])
    print(f"{controller}, {n} missions, caught while planning: {dict(kinds)}")
    if distances:
        print(f"older fronts' distance when the wait began: median {np.median(distances):.1f} m")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "s2", int(sys.argv[2]) if len(sys.argv) > 2 else 40)
