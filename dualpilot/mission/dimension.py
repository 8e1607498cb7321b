"""Whether a controller flies missions of its spec's dimension (docs/three_d.md).

A controller flies a mission of ``dim`` = 3 when its supervisor and the planning method
of every system it asks say they plan in 3-D (:attr:`SupervisorEntry.dims
<dualpilot.supervisor.interface.SupervisorEntry.dims>`, :attr:`PlannerMethod.dims
<dualpilot.planners.PlannerMethod.dims>`). A method that plans some 3-D missions only says which
(:attr:`PlannerMethod.scope3 <dualpilot.planners.PlannerMethod.scope3>`, read from the
reading before the mission). A controller that does not fly its mission is refused before
it starts, by name, with every part that does not plan it.
"""

from __future__ import annotations

from dataclasses import replace

from dualpilot.mission.config import MissionConfig, controller_names, parse_controller
from dualpilot.planners import BUILTIN as BUILTIN_METHODS
from dualpilot.planners import planner_method
from dualpilot.supervisor.registry import BUILTIN as BUILTIN_SUPERVISORS
from dualpilot.supervisor.registry import supervisor_entry

__all__ = ["check_dimension", "flying_controllers", "flying_text", "reason", "refusals"]


def _only(dims: frozenset[int]) -> str:
    return " and ".join(f"{d}-D" for d in sorted(dims)) + " only"


def _parts(config: MissionConfig) -> list[tuple[str, bool]]:
    """(sentence, built in) for each part of ``config``'s controller that does not plan in
    its spec's dimension (a method that is not installed, or does not load, is left to
    :func:`~dualpilot.planners.build_planner`, which names it as before)."""
    spec = config.spec()
    dim = spec.dim
    out = []
    entry = supervisor_entry(config.supervisor)
    if dim not in entry.dims:
        out.append((f"the {config.supervisor} supervisor supervises missions in "
                    f"{_only(entry.dims)}", config.supervisor in BUILTIN_SUPERVISORS))
    methods = config.methods()
    for system in config.systems():
        try:
            method = planner_method(methods[system])
        except ValueError:  # unknown, or does not load: the mission's planner says so
            continue
        name = f"System {system} method {methods[system]!r}"
        if dim not in method.dims:
            out.append((f"{name} plans in {_only(method.dims)}",
                        methods[system] in BUILTIN_METHODS))
        elif dim == 3 and method.scope3 is not None:
            reading = config.reading()
            why = method.scope3(spec, reading.altitude.heights, reading.fire.scenario)
            if why:
                out.append((f"{name} {why}", methods[system] in BUILTIN_METHODS))
    return out


def refusals(config: MissionConfig) -> tuple[str, ...]:
    """The parts of ``config``'s controller that do not plan in its spec's dimension, each
    as a sentence (empty: the controller flies it)."""
    return tuple(sentence for sentence, _ in _parts(config))


def flying_controllers(config: MissionConfig) -> tuple[str, ...]:
    """The names of :func:`controller_names` that fly ``config``'s mission (its reading,
    dimension and methods) under their own supervisor and risk."""
    names = []
    for name in controller_names():
        controller, supervisor, risk = parse_controller(name)
        flown = replace(config, controller=controller, supervisor=supervisor, risk=risk,
                        concurrent=replace(config.concurrent, threat="current"))  # risk's
        if not refusals(flown):
            names.append(name)
    return tuple(names)


def reason(config: MissionConfig) -> str:
    """Why ``config``'s controller does not fly its spec's dimension ("": it does): every
    part that plans in fewer dimensions, and for a built-in part that its planning in that
    dimension is not built yet, for an installed one that it does not declare it."""
    parts = _parts(config)
    dim = config.spec().dim
    built_in = [s for s, b in parts if b]
    installed = [s for s, b in parts if not b]
    why = []
    if built_in:
        why.append(f"{'; '.join(built_in)}: {dim}-D planning for "
                   f"{'it' if len(built_in) == 1 else 'these'} is not built yet "
                   f"(docs/three_d.md, Status)")
    if installed:
        why.append(f"{'; '.join(installed)}: installed as a plug-in, "
                   f"{'it does' if len(installed) == 1 else 'they do'} not declare dim {dim} "
                   f"(dims)")
    return "; ".join(why)


def flying_text(config: MissionConfig) -> str:
    """"Controllers that fly dim=N: ..." for ``config``'s reading and methods."""
    flying = flying_controllers(config)
    return (f"Controllers that fly dim={config.spec().dim}: "
            f"{', '.join(flying) if flying else 'none yet'}")


def check_dimension(config: MissionConfig) -> None:
    """Nothing if ``config``'s controller flies its spec's dimension; else ValueError naming
    the controller, :func:`reason` and the controllers that do fly it."""
    why = reason(config)
    if why:
        raise ValueError(f"controller {config.controller_name!r} does not fly "
                         f"dim={config.spec().dim}: {why}. {flying_text(config)}")
