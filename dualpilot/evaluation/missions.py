"""One mission of an evaluation: configuration i of seed S flown by one controller.

Configuration i (start, goal, fire and supervisor streams) is drawn from the
seed pair (S, i), so every controller and every grid point sees the same
mission. :func:`run_task` flies one :class:`Task` and returns its row of
``results.csv`` (:data:`COLUMNS`); it never raises.
"""

from __future__ import annotations

import sys
import time
import traceback
from dataclasses import dataclass
from typing import Any

import numpy as np

from dualpilot.mission.params import Timing, controller_of, uses_risk
from dualpilot.readings import Profile, get_profile
from dualpilot.spec import MissionSpec

CONTROLLERS = ("cc", "s1", "s2")
#: evaluate's results.csv (unchanged by the sweep)
COLUMNS = [
    "mission", "seed", "controller", "timing", "success", "failure_cause", "steps",
    "mission_time_s", "energy", "switches", "switch_energy", "fire_substeps", "s1_plans",
    "s2_plans",
    "planning_time_s_median", "planning_time_s_p95", "planning_time_s_total", "start_x",
    "start_y", "goal_x", "goal_y",
    "wall_s", "error",
]
#: the columns that are measured, not computed: they differ between any two runs
MEASURED_COLUMNS = frozenset({"wall_s", "planning_time_s_median", "planning_time_s_p95",
                              "planning_time_s_total"})

Settings = tuple[tuple[str, Any], ...]


def mission_seed(seed: int, index: int) -> int:
    """The seed of configuration ``index`` in a run seeded with ``seed``."""
    return int(np.random.SeedSequence([seed, index]).generate_state(1)[0])


def mission_spec(seed: int, index: int) -> MissionSpec:
    """The spec of configuration ``index``: its start, goal and seed."""
    mseed = mission_seed(seed, index)
    return MissionSpec.random(np.random.default_rng(mseed), seed=mseed)


@dataclass(frozen=True)
class Task:
    """One mission: configuration ``index`` of ``seed``, one controller, one reading."""

    index: int
    seed: int
    controller: str
    timing: str
    s2_method: str
    ignition_clearance_m: float | None = None  # set (not None): overrides the profile's
    profile: str = "today"
    settings: Settings = ()
    point: int = 0
    label: str = ""

    def reading(self) -> Profile:
        extra = dict(self.settings)
        if self.ignition_clearance_m is not None:
            extra["ignition_clearance_m"] = self.ignition_clearance_m
        return get_profile(self.profile).with_settings(extra)


def run_task(task: Task) -> dict[str, object]:
    """Fly one mission; never raises (an exception becomes an error row)."""
    from dualpilot.mission.local import local_mission

    config = mission_spec(task.seed, task.index)
    row: dict[str, object] = {
        "point": task.point, "label": task.label, "profile": task.profile,
        "mission": task.index, "seed": config.seed, "controller": task.controller,
        "timing": task.timing, "start_x": config.start[0], "start_y": config.start[1],
        "goal_x": config.goal.center_x, "goal_y": config.goal.center_y, "error": "",
    }
    t0 = time.perf_counter()
    try:
        reading = task.reading()
        row.update(reading.values())
        controller, supervisor = controller_of(task.controller)
        result = local_mission(
            controller, reading.spec(config), timing=Timing(task.timing),
            params=reading.mission, fire_params=reading.fire,
            supervisor_params=reading.supervisor, system2_method=task.s2_method,
            supervisor=supervisor, risk=uses_risk(task.controller),
        ).run()
        times = result.planning_time_s["s1"] + result.planning_time_s["s2"]
        row.update(
            success=int(result.success), failure_cause=result.failure_cause,
            steps=result.steps, mission_time_s=result.mission_time_s,
            energy=round(result.energy, 6), switches=result.switches,
            switch_energy=round(result.switch_energy, 6),
            fire_substeps=sum(r.fire_substeps for r in result.records)
            + reading.mission.fire_substeps_per_motion * result.steps,
            s1_plans=len(result.planning_time_s["s1"]),
            s2_plans=len(result.planning_time_s["s2"]),
            planning_time_s_median=float(np.median(times)) if times else "",
            planning_time_s_p95=float(np.percentile(times, 95)) if times else "",
            planning_time_s_total=float(np.sum(times)),
        )
    except Exception as err:  # noqa: BLE001 - recorded, the run goes on
        row.update(success=0, failure_cause="error", error=f"{type(err).__name__}: {err}")
        traceback.print_exc(file=sys.stderr)
    row["wall_s"] = round(time.perf_counter() - t0, 3)
    return row
