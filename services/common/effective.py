"""What each process runs for each mission: the configuration it was given and what it made of
it, served on its status queryable (services/common/bus/status.py, ``missions``).

A process records a mission when it takes one up: the supervisor when it builds
the configuration, a planner service when it prepares the mission's planner (the
method, the parameters and the dynamics it plans with), the EWS at a reset (the
fire process and the forecast it runs) and uavsim when it takes the mission's
configuration (the Eq. (1) it flies). Anyone can then read each process's
effective configuration back (``tests/e2e/test_config_road.py`` checks that
every field reaches every process).
"""

from __future__ import annotations

import dataclasses
import json
import threading
from collections import OrderedDict
from typing import Any

__all__ = ["EFFECTIVE", "Effective", "plain"]

#: the missions a process keeps on its status (the newest): two for each vehicle of the largest
#: fleet a process serves (services/common/fleet.py, 64)
KEEP_MISSIONS = 128


def plain(value: Any) -> Any:
    """``value`` (a dataclass, tuple, number, …) as JSON data: what a status reply carries."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        value = dataclasses.asdict(value)
    return json.loads(json.dumps(value))


class Effective:
    """The missions a process runs: mission id → its uav, configuration and what was made."""

    def __init__(self, keep: int = KEEP_MISSIONS):
        self.keep = keep
        self._lock = threading.Lock()
        self._missions: OrderedDict[str, dict[str, Any]] = OrderedDict()

    def record(self, mission_id: str, uav: str, config: dict[str, Any],
               **made: Any) -> None:
        """Mission ``mission_id`` of vehicle ``uav`` runs ``config`` (its wire form as JSON,
        services.common.convert.config.config_to_json); ``made``: what the process built from
        it, each value as JSON data."""
        entry = {"uav": uav, "config": config, "made": {k: plain(v) for k, v in made.items()}}
        with self._lock:
            self._missions.pop(mission_id, None)
            self._missions[mission_id] = entry
            while len(self._missions) > self.keep:
                self._missions.popitem(last=False)

    def snapshot(self) -> dict[str, dict[str, Any]]:
        with self._lock:
            return dict(self._missions)


#: this process's missions
EFFECTIVE = Effective()
