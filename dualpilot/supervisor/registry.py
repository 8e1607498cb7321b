"""The supervisors of the cognitive controller, by name: the one registry.

"paper" (:mod:`dualpilot.supervisor.paper`): Sec. III-C's supervisor, the UAV waits for
the chosen system's plan; it runs every controller (cc, s1, s2).
"concurrent" (:mod:`dualpilot.supervisor.concurrent`): System 2 deliberates while the
UAV flies System 1's plans; the cognitive controller only, with System 1 tracking under
the Δu penalty.
"lookahead" (:mod:`dualpilot.supervisor.lookahead`): the concurrent supervisor's choice,
flown only if it is sound on the known future, else a space-time plan.

The registry is the public extension point of entry-point group ``dualpilot.supervisors``
(:mod:`dualpilot.extensions`): each name is a
:class:`~dualpilot.supervisor.interface.SupervisorEntry`; the built-ins are the entry
points of :data:`BUILTIN`, and a separately installed package adds a supervisor by naming
its own (docs/extending.md). A supervisor's name is also its controller's name in
``dualpilot evaluate`` (:func:`dualpilot.mission.config.controller_names`), so it cannot
be one of the paper's controllers (cc, s1, s2) nor the evaluation's oracle.
"""

from __future__ import annotations

from collections.abc import Mapping

from dualpilot.extensions import Registry
from dualpilot.mission.params import Controller
from dualpilot.planners import planner_method
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.interface import Supervisor, SupervisorEntry, SupervisorSettings

__all__ = ["BUILTIN", "PAPER", "REGISTRY", "build_supervisor", "supervisor_entry",
           "supervisor_names"]

#: The paper's supervisor, the default.
PAPER = "paper"
#: The built-in supervisors: entry points of ``dualpilot.supervisors`` (name ->
#: "module:attribute"), the default first.
BUILTIN: Mapping[str, str] = {
    PAPER: "dualpilot.supervisor.paper.planning:ENTRY",
    "concurrent": "dualpilot.supervisor.concurrent.planning:ENTRY",
    "lookahead": "dualpilot.supervisor.lookahead.planning:ENTRY",
}
#: Names a supervisor cannot take: the paper's controllers and the evaluation's oracle.
RESERVED = ("cc", "s1", "s2", "oracle")


def _check(name: str, entry: SupervisorEntry) -> None:
    """A supervisor other than the paper's runs the cognitive controller only (its controller
    is named by the supervisor's name); its System 1 method is a System 1 method."""
    if not entry.controllers or (name != PAPER and entry.controllers != {Controller.CC}):
        raise ValueError("a supervisor other than the paper's runs the cognitive controller "
                         f"only (controllers {{Controller.CC}}), not {set(entry.controllers)}")
    if planner_method(entry.system1_method).system != 1:
        raise ValueError(f"its System 1 method {entry.system1_method!r} is not System 1's")


#: The registry of supervisors (built-in and installed).
REGISTRY: Registry[SupervisorEntry] = Registry(
    "dualpilot.supervisors", SupervisorEntry, BUILTIN, what="supervisor",
    name_pattern=r"[a-z][a-z0-9_-]{0,63}", reserved=RESERVED, check=_check)


def supervisor_names() -> tuple[str, ...]:
    """The installed supervisors' names, the built-ins first (the paper's first)."""
    return REGISTRY.names()


def supervisor_entry(name: str) -> SupervisorEntry:
    """The supervisor registered as ``name`` (ValueError: none is)."""
    return REGISTRY.get(name)


def build_supervisor(config: SupervisorSettings, spec: MissionSpec) -> Supervisor:
    """``config``'s supervisor for the mission of ``spec`` (ValueError: it does not supervise
    missions of the spec's dimension)."""
    entry = supervisor_entry(config.supervisor)
    if spec.dim not in entry.dims:
        raise ValueError(f"the {config.supervisor} supervisor supervises missions in "
                         f"{_dims_text(entry.dims)} only, not dim={spec.dim}"
                         + (f": {spec.dim}-D supervision for it is not built yet "
                            "(docs/three_d.md, Status)" if config.supervisor in BUILTIN else ""))
    return entry.build(config, spec)


def _dims_text(dims: frozenset[int]) -> str:
    return " and ".join(f"{d}-D" for d in sorted(dims))
