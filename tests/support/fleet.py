"""Missions flown at once through a shared stack, one vehicle each (the lockstep tests).

:func:`fly_fleet` starts every run on its own vehicle of a :class:`services.launch.Fleet`,
waits for all of them to end, stops each vehicle and checks that its processes exited with 0;
a mission that does not end or a process that fails is a test failure with the logs of the
vehicle and of the shared services.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from dualpilot.mission.config import MissionConfig
from services import launch
from tests.support.waits import check, logs_in

#: how long (s) a fleet's unpaced missions may take together
FLEET_TIMEOUT_S = 300.0


@dataclass(frozen=True)
class FleetRun:
    """One mission of a fleet: what a failure calls it, its seed and run directory, the
    services' environment beyond the fleet's and its configuration (None: the fleet's)."""

    name: str
    seed: int
    run_dir: Path
    env: Mapping[str, str] = field(default_factory=dict)
    config: MissionConfig | None = None


def fly_fleet(fleet: launch.Fleet, runs: Sequence[FleetRun],
              timeout_s: float = FLEET_TIMEOUT_S,
              on_start: Callable[[int], None] | None = None,
              on_end: Callable[[int], None] | None = None) -> list[Path]:
    """Fly ``runs`` at once, the k-th on the fleet's k-th vehicle; their run directories in
    order, once every mission has ended and every vehicle's processes exited with 0.

    ``on_start(k)`` is called once run k's vehicle is started, ``on_end(k)`` as soon as its
    mission has ended (its records are written by then), while the others still fly.
    """
    if len(runs) > len(fleet.uav_ids):
        raise ValueError(f"{len(runs)} runs for a fleet of {len(fleet.uav_ids)} vehicles")
    pairs = list(zip(fleet.uav_ids, runs, strict=False))
    index = {uav: k for k, (uav, _) in enumerate(pairs)}
    mission_ids = {}
    for k, (uav, run) in enumerate(pairs):
        mission_ids[uav] = fleet.start_vehicle(uav, run.seed, run.run_dir, env=run.env,
                                               config=run.config).mission_id
        if on_start is not None:
            on_start(k)

    def ended(uav: str, outcome: launch.Outcome) -> None:
        if on_end is not None and outcome.ended:
            on_end(index[uav])

    outcomes = fleet.wait_end(mission_ids, timeout_s, on_end=ended)
    dirs = []
    for uav, run in pairs:
        run_dir = fleet.vehicles[uav].run_dir
        logs = [*logs_in(run_dir), *logs_in(fleet.stack.logs)]
        check(outcomes[uav].ended, f"{run.name} to end", logs, outcomes[uav])
        codes = fleet.stop_vehicle(uav)
        check(all(code == 0 for code in codes.values()),
              f"the processes of {run.name} to exit with 0", logs, codes)
        dirs.append(run_dir)
    return dirs
