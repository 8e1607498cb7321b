"""One mission of an evaluation: configuration i of seed S flown by one controller.

Configuration i (start, goal, fire and supervisor streams) is drawn from the
seed pair (S, i), so every controller and every grid point sees the same
mission. Every task of a run is one base configuration (the flags of
``dualpilot mission``: dualpilot/mission/config_args.py) flown by one controller
name: :func:`flown_by` changes only the controller fields. :func:`run_task` flies
one :class:`Task` and returns its row of ``results.csv`` (:data:`COLUMNS`); it
never raises.
"""

from __future__ import annotations

import sys
import time
import traceback
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from dualpilot.evaluation.columns import flight_columns, oracle_columns
from dualpilot.mission.config import MissionConfig, parse_controller
from dualpilot.mission.config_args import config_to_argv, parse_config
from dualpilot.mission.dimension import flying_text, reason
from dualpilot.mission.params import Timing
from dualpilot.mission.result import Ending
from dualpilot.spec import MissionSpec

CONTROLLERS = ("cc", "s1", "s2")
#: the clairvoyant oracle's row of an evaluation (dualpilot/oracle, evaluation/yardstick.py)
ORACLE = "oracle"
#: evaluate's results.csv (unchanged by the sweep)
COLUMNS = [
    "mission", "seed", "controller", "timing", "success", "failure_cause", "steps",
    "mission_time_s", "energy", "switches", "switch_energy", "fire_substeps", "s1_plans",
    "s2_plans",
    "planning_time_s_median", "planning_time_s_p95", "planning_time_s_total", "start_x",
    "start_y", "goal_x", "goal_y",
    "wall_s", "error",
    # appended (old readers keep their columns): the plant's flight (dualpilot/mission/flight.py)
    "tracking_breach", "tracking_error_p50_m", "tracking_error_p99_m",
]
#: the columns that are measured, not computed: they differ between any two runs
MEASURED_COLUMNS = frozenset({"wall_s", "planning_time_s_median", "planning_time_s_p95",
                              "planning_time_s_total"})

Settings = tuple[tuple[str, Any], ...]
#: the flags a run records by name (run.json) or a task sets itself; :func:`other_flags` the rest
NAMED_FLAGS = ("--controller", "--seed", "--timing", "--profile", "--set", "--s2-method",
               "--goal", "--area-size-m", "--start", "--mission-id")


def flown_by(base: MissionConfig, controller: str) -> MissionConfig:
    """``base`` flown by ``controller`` (a name of controller_names()): only the controller fields
    change (controller, supervisor, risk; the concurrent supervisor's threat rule follows
    risk, a System 1 method left "" the supervisor)."""
    kind, supervisor, risk = parse_controller(controller)
    return replace(base, controller=kind, supervisor=supervisor, risk=risk,
                   concurrent=replace(base.concurrent, threat="current"))


def other_flags(config: MissionConfig) -> list[str]:
    """``config``'s flags that :data:`NAMED_FLAGS` leave out and that differ from the defaults
    (System 1's method, System 2's time limit, the concurrent supervisor's and the forecast's
    parameters)."""
    default = set(config_to_argv(MissionConfig()))
    return [f for f in config_to_argv(config)
            if f.split("=", 1)[0] not in NAMED_FLAGS and f not in default]


def run_config(base: MissionConfig) -> dict[str, Any]:
    """What run.json records of a run's base configuration (a resumed run must match it)."""
    doc: dict[str, Any] = {"seed": base.seed, "profile": base.profile,
                           "s2_method": base.system2_method, "settings": dict(base.settings)}
    if other_flags(base):
        doc["config"] = other_flags(base)
    return doc


def base_of(doc: dict[str, Any], timing: str) -> MissionConfig:
    """The base configuration of a run's run.json (:func:`run_config`) flown with ``timing``."""
    return replace(parse_config(doc.get("config", [])), seed=int(doc["seed"]),
                   profile=doc["profile"], system2_method=doc["s2_method"],
                   settings=tuple(doc.get("settings", {}).items()), timing=Timing(timing))


def mission_seed(seed: int, index: int) -> int:
    """The seed of configuration ``index`` in a run seeded with ``seed``."""
    return int(np.random.SeedSequence([seed, index]).generate_state(1)[0])


def mission_spec(seed: int, index: int) -> MissionSpec:
    """The spec of configuration ``index``: its start, goal and seed."""
    mseed = mission_seed(seed, index)
    return MissionSpec.random(np.random.default_rng(mseed), seed=mseed)


@dataclass(frozen=True)
class Task:
    """One mission: configuration ``index`` of ``seed`` flown with ``config`` (its controller,
    timing, reading and methods; the start, goal and seed are configuration ``index``'s)."""

    index: int
    seed: int
    config: MissionConfig
    point: int = 0
    label: str = ""
    #: the oracle's verdict on the mission instead of a flight (the config's reading; its
    #: controller is System 1, whose pace the oracle flies)
    oracle: bool = False

    @staticmethod
    def of(index: int, seed: int, controller: str, base: MissionConfig | None = None,
           point: int = 0, label: str = "") -> Task:
        """Configuration ``index`` of ``seed`` flown by an evaluation's controller name (or
        :data:`ORACLE`) with the run's ``base`` configuration (default: the defaults)."""
        oracle = controller == ORACLE
        config = flown_by(base or MissionConfig(), "s1" if oracle else controller)
        return Task(index, seed, config, point, label, oracle)

    def mission(self) -> MissionConfig:
        """The configuration flown: the task's, at configuration ``index``'s start and goal."""
        spec = mission_spec(self.seed, self.index)
        return replace(self.config, seed=spec.seed, start=spec.start, goal=spec.goal,
                       area_size_m=spec.area_size_m)

    def identity(self) -> dict[str, object]:
        """The columns that say which mission this is (its row, or its error row)."""
        c = self.config
        return {"point": self.point, "label": self.label, "profile": c.profile,
                "mission": self.index, "seed": mission_seed(self.seed, self.index),
                "controller": ORACLE if self.oracle else c.controller_name,
                "timing": c.timing.value}


def run_task(task: Task) -> dict[str, object]:
    """Fly one mission (or ask the oracle); never raises (an exception becomes an error row)."""
    from dualpilot.mission.local import local_mission

    config = mission_spec(task.seed, task.index)
    row: dict[str, object] = {
        **task.identity(), "start_x": config.start[0], "start_y": config.start[1],
        "goal_x": config.goal.center_x, "goal_y": config.goal.center_y, "error": "",
    }
    t0 = time.perf_counter()
    try:
        reading = task.config.reading()
        row.update(reading.values())
        if task.oracle:
            row.update(oracle_columns(task.mission()))
        else:
            row.update(flight_columns(local_mission(task.mission()).run(), reading))
    except Exception as err:  # noqa: BLE001 - recorded, the run goes on
        row.update(success=0, failure_cause=Ending.ERROR.value,
                   error=f"{type(err).__name__}: {err}")
        traceback.print_exc(file=sys.stderr)
    row["wall_s"] = round(time.perf_counter() - t0, 3)
    return row


def check_dimensions(base: MissionConfig, controllers: Sequence[str]) -> None:
    """Nothing if every controller of ``controllers`` (names, or the oracle) flies ``base``'s
    dimension; else ValueError naming each that does not and why, before any mission."""
    from dualpilot.oracle.oracle import check_dimension as oracle_check

    refused = []
    for name in controllers:
        config = Task.of(0, base.seed, name, base).config
        if name == ORACLE:
            try:
                oracle_check(config)
            except ValueError as err:
                refused.append(f"  {name}: {err}")
        elif why := reason(config):
            refused.append(f"  {name}: {why}")
    if refused:
        raise ValueError(f"dim={base.spec().dim}: these controllers do not fly it\n"
                         + "\n".join(refused) + f"\n{flying_text(base)}")
