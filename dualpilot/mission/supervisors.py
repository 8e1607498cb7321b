"""The supervisors of the cognitive controller, built by kind: the one registry.

"paper" (:class:`dualpilot.mission.paper.PaperPlanning`): Sec. III-C's supervisor, the
UAV waits for the chosen system's plan; it runs every controller (cc, s1, s2).
"concurrent" (:class:`dualpilot.mission.concurrent.ConcurrentPlanning`): System 2
deliberates while the UAV flies System 1's plans (dualpilot/supervisor/concurrent.py);
the cognitive controller only, with System 1 tracking under the Δu penalty.
"lookahead" (:class:`dualpilot.mission.lookahead.LookaheadPlanning`): the concurrent
supervisor's choice, flown only if it is sound on the known future, else a space-time
plan (dualpilot/supervisor/lookahead.py). Each
implements :class:`dualpilot.mission.supervision.SupervisorPlanning`.
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

from dualpilot.mission.concurrent import ConcurrentPlanning
from dualpilot.mission.lookahead import LookaheadPlanning
from dualpilot.mission.paper import PaperPlanning
from dualpilot.mission.params import Controller
from dualpilot.mission.supervision import SupervisorPlanning
from dualpilot.spec import MissionSpec

if TYPE_CHECKING:
    from dualpilot.mission.config import MissionConfig

__all__ = ["SUPERVISORS", "Supervision", "SupervisorKind", "build_supervisor"]


class SupervisorKind(enum.Enum):
    """Who decides what flies: the paper's supervisor (Sec. III-C: the UAV waits for the
    chosen system's plan) or the concurrent one (System 2 deliberates while System 1's plans
    fly)."""

    PAPER = "paper"
    CONCURRENT = "concurrent"
    LOOKAHEAD = "lookahead"


@dataclass(frozen=True)
class Supervision:
    """One supervisor of the registry: how it is built, the controllers it runs and the System 1
    method it flies by default (dualpilot.planners)."""

    build: Callable[[MissionConfig, MissionSpec], SupervisorPlanning]
    controllers: frozenset[Controller]
    system1_method: str


def _paper(config: MissionConfig, spec: MissionSpec) -> SupervisorPlanning:
    return PaperPlanning()


def _concurrent(config: MissionConfig, spec: MissionSpec) -> SupervisorPlanning:
    reading = config.reading()
    return ConcurrentPlanning(spec, config.timing, reading.mission, reading.fire,
                              reading.supervisor, config.concurrent)


def _lookahead(config: MissionConfig, spec: MissionSpec) -> SupervisorPlanning:
    reading = config.reading()
    return LookaheadPlanning(spec, config.timing, reading.mission, reading.fire,
                             reading.supervisor, config.concurrent)


#: Supervisor kind → its entry; the default first. The concurrent supervisor hands over
#: between the systems every few steps, so its System 1 tracks with the Δu penalty
#: (dualpilot/system1/lqr.py: "rrt+du").
SUPERVISORS: Mapping[SupervisorKind, Supervision] = {
    SupervisorKind.PAPER: Supervision(_paper, frozenset(Controller), "rrt"),
    SupervisorKind.CONCURRENT: Supervision(_concurrent, frozenset({Controller.CC}), "rrt+du"),
    SupervisorKind.LOOKAHEAD: Supervision(_lookahead, frozenset({Controller.CC}), "rrt+du"),
}


def build_supervisor(config: MissionConfig, spec: MissionSpec) -> SupervisorPlanning:
    """The planning phase of ``config``'s supervisor for the mission of ``spec``."""
    return SUPERVISORS[config.supervisor].build(config, spec)
