"""What the MAVSDK example modules share, without importing either MAVSDK (they differ)."""

from __future__ import annotations

from enum import Enum
from typing import Any

#: the mission example's waypoints (around PX4 SITL's home), in its own digits
MISSION = [(47.398039859999997, 8.5455725400000002), (47.398036222362471, 8.5450146439425509),
           (47.397825620791885, 8.5450092830163271)]


def plain(x: Any) -> Any:
    """What an example saw as plain data: enums by name, MAVSDK's objects as dicts."""
    if isinstance(x, Enum):
        return x.name
    if isinstance(x, dict):
        return {str(k): plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [plain(v) for v in x]
    if hasattr(x, "__dict__"):
        return {k: plain(v) for k, v in vars(x).items() if not k.startswith("_")}
    return x
#: PX4 SITL's home (MAVSDK's mission example flies around it)
MISSION = [(47.398039859999997, 8.5455725400000002), (47.398036222362471, 8.5450146439425509),
           (47.397825620791885, 8.5450092830163271)]
