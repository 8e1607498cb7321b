"""The supervisors of the cognitive controller, built by name, like the planners' registry.

"paper" (:class:`dualpilot.mission.paper.PaperPlanning`): Sec. III-C's supervisor, the
UAV waits for the chosen system's plan; it runs every controller (cc, s1, s2).
"concurrent" (:class:`dualpilot.mission.concurrent.ConcurrentPlanning`): System 2
deliberates while the UAV flies System 1's plans (dualpilot/supervisor/concurrent.py);
the cognitive controller only. Each implements
:class:`dualpilot.mission.supervision.SupervisorPlanning`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

from dualpilot.mission.concurrent import ConcurrentPlanning
from dualpilot.mission.paper import PaperPlanning
from dualpilot.mission.params import Controller, MissionParams, Timing
from dualpilot.mission.supervision import SupervisorPlanning
from dualpilot.model.fire import FireParams
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.concurrent import ConcurrentParams
from dualpilot.supervisor.decision import SupervisorParams

__all__ = ["SUPERVISORS", "SupervisorSetup", "build_supervisor"]


@dataclass(frozen=True)
class SupervisorSetup:
    """What a supervisor is built from: the mission's controller, spec, timing and parameters."""

    controller: Controller
    spec: MissionSpec
    timing: Timing
    params: MissionParams
    fire: FireParams
    supervisor: SupervisorParams
    concurrent: ConcurrentParams


def _paper(setup: SupervisorSetup) -> SupervisorPlanning:
    return PaperPlanning()


def _concurrent(setup: SupervisorSetup) -> SupervisorPlanning:
    if setup.controller is not Controller.CC:
        raise ValueError("the concurrent supervisor runs the cognitive controller (cc)")
    return ConcurrentPlanning(setup.spec, setup.timing, setup.params, setup.fire,
                              setup.supervisor, setup.concurrent)


#: Supervisor name → constructor; the default first.
SUPERVISORS: Mapping[str, Callable[[SupervisorSetup], SupervisorPlanning]] = {
    "paper": _paper, "concurrent": _concurrent,
}


def build_supervisor(name: str, setup: SupervisorSetup) -> SupervisorPlanning:
    """The supervisor ``name`` (a key of :data:`SUPERVISORS`); ValueError for another name."""
    if name not in SUPERVISORS:
        choices = " or ".join(repr(k) for k in SUPERVISORS)
        raise ValueError(f"supervisor must be {choices}, not {name!r}")
    return SUPERVISORS[name](setup)
