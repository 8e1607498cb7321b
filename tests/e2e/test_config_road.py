"""Every field of the mission configuration reaches every process of the stack.

Two missions set every field of :class:`~dualpilot.mission.config.MissionConfig`
to a value other than its default between them (a test below fails when a
field is added that neither sets): the first flies the lookahead supervisor
with the forecast, the second System 2 alone. Each is handed to its supervisor
as the launcher does (its command-line flags) and flown through the stack
(shared router, EWS and planners; a uavsim and a supervisor per vehicle,
unpaced). Each process is then asked for its status (``<ns>/status/<service>``:
``missions``, services/common/effective.py): the configuration it holds must
decode to the one the supervisor built, and what it made of it must be what
the in-process mission makes of that configuration: the EWS's fire process and
forecast grid, each planner's method, System 2's time limit and the planners'
Eq. (1), uavsim's Eq. (1) and area. A process that ignored a field (kept a
default, or read a variable of its own) fails here.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.params import Timing
from dualpilot.model.forecast import ForecastParams
from dualpilot.model.geometry import Rect
from dualpilot.model.risk import RiskParams
from dualpilot.supervisor.concurrent.rule import ConcurrentParams
from services import launch
from services.common import bus
from services.common.convert.config import config_from_json
from services.common.effective import plain
from tests.support.waits import check, logs_in

pytestmark = [pytest.mark.slow, pytest.mark.timeout(600)]

#: where compose's uavsim boots (UAV_START): the stack's missions start there
START = (50.0, 50.0)
#: between them, every field of MissionConfig other than its default (mission and vehicle ids
#: are the launcher's and the supervisor's)
LOOKAHEAD = MissionConfig.named(
    "lookahead+risk", timing=Timing.MEASURED, seed=11, profile="fig-r5",
    settings=(("max_steps", 3), ("speed_limit", "norm"), ("zeta", 0.3), ("u_max_n", 6.5)),
    system1_method="rrt+du", system2_time_limit_s=7.0,
    concurrent=ConcurrentParams(check_steps=6, q_rate=0.3, risk=RiskParams(alpha=0.2)),
    forecast=ForecastParams(members=8, resolution_m=20.0, horizon_s=20.0, interval_s=2.0),
    goal=Rect(700.0, 650.0, 120.0, 120.0), area_size_m=900.0, start=START)
SYSTEM2 = MissionConfig.named(
    "s2", seed=12, profile="literal",
    settings=(("max_steps", 3), ("mass_kg", 1.2), ("life_base", "substep")),
    system2_method="thorough", system2_time_limit_s=9.5,
    forecast=ForecastParams(members=4), goal=Rect(600.0, 700.0, 100.0, 100.0),
    area_size_m=950.0, start=START)
CONFIGS = (LOOKAHEAD, SYSTEM2)


def test_between_them_the_missions_set_every_field_to_another_value() -> None:
    default = MissionConfig()
    fields = {f.name for f in dataclasses.fields(MissionConfig)} - {"mission_id", "uav_id"}
    unset = [f for f in sorted(fields)
             if all(getattr(c, f) == getattr(default, f) for c in CONFIGS)]
    assert unset == []


@dataclasses.dataclass
class Flown:
    uav: str
    config: MissionConfig  # what the supervisor builds: the vehicle's seed, ids
    logs: list[Path]


@pytest.fixture(scope="module")
def flown(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[launch.Fleet,
                                                                      list[Flown]]]:
    out = tmp_path_factory.mktemp("config-road")
    uavs = [f"cr{k}" for k in range(len(CONFIGS))]
    cfg = launch.StackConfig(run_dir=out / "shared", speed_factor=0.0, free_ports=True,
                             log_format="text")
    with launch.Fleet(cfg, uavs) as fleet:
        runs, ids = [], {}
        for uav, config in zip(uavs, CONFIGS, strict=True):
            v = fleet.start_vehicle(uav, config.seed, out / uav, config=config,
                                    env={"SPEED_FACTOR": "0",
                                         "UAV_START": f"{START[0]},{START[1]}"})
            ids[uav] = v.mission_id
            runs.append(Flown(uav, dataclasses.replace(config, mission_id=v.mission_id,
                                                       uav_id=uav),
                              [*logs_in(out / uav / "logs"), *logs_in(fleet.stack.logs)]))
        outcomes = fleet.wait_end(ids, 300.0)
        for run in runs:
            check(outcomes[run.uav].ended, f"{run.uav}'s mission to end", run.logs,
                  outcomes[run.uav])
        yield fleet, runs


def held(session: Any, uav: str, service: str, run: Flown) -> dict[str, Any]:
    """What ``service`` (its status on ``uav``'s keys) runs for ``run``'s mission."""
    missions = bus.query_status(session, uav, service, 10.0)["missions"]
    check(run.config.mission_id in missions, f"{service} to hold {run.config.mission_id}",
          run.logs, sorted(missions))
    entry: dict[str, Any] = missions[run.config.mission_id]
    assert entry["uav"] == run.uav, (service, entry["uav"])
    assert config_from_json(entry["config"]) == run.config, service
    return dict(entry["made"])


def test_every_process_runs_the_configuration_the_supervisor_built(flown: Any) -> None:
    fleet, runs = flown
    shared = runs[0].uav  # the shared services answer on their first vehicle's keys
    with launch.client_session(fleet.endpoint) as session:
        for run in runs:
            c = run.config
            dynamics = plain(c.spec().dynamics)
            assert held(session, run.uav, "supervisor", run) == {}
            sim = held(session, run.uav, "uavsim", run)
            assert sim == {"dynamics": dynamics, "area_size_m": c.area_size_m}
            ews = held(session, shared, "ews", run)
            assert ews == {"fire": plain(c.reading().fire), "forecast": plain(c.forecast)}
            for system in c.systems():
                made = held(session, shared, f"system{system}", run)
                method = c.methods()[system] + ("+risk" if c.risk else "")
                assert (made["method"], made["dynamics"]) == (method, dynamics), system
                if system == 2:
                    assert made["params"] == plain(c.system2_params())
    # the readings differ from the defaults where it shows: a process on its own defaults
    # would have answered otherwise above
    assert plain(LOOKAHEAD.spec().dynamics) != plain(MissionConfig().spec().dynamics)
    assert plain(SYSTEM2.reading().fire) != plain(MissionConfig().reading().fire)
