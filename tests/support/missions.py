"""Mission configurations for tests: a spec, a controller and parameter objects as one config.

Tests build fires, mission limits and supervisors from the parameter dataclasses
(``FireParams(p_birth=0.0)``); a :class:`~dualpilot.mission.config.MissionConfig`
takes them as reading overrides, the fields that differ from the profile's.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.params import Controller, MissionParams, Timing
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.model.fire import FireParams
from dualpilot.readings import get_profile
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.paper.decision import SupervisorParams

Part = FireParams | MissionParams | SupervisorParams | DynamicsParams


def overrides(profile: str, *parts: Part | None) -> dict[str, Any]:
    """The scalar fields of ``parts`` that differ from ``profile``'s, by name."""
    base = get_profile(profile).values()
    out: dict[str, Any] = {}
    for part in parts:
        if part is None:
            continue
        for f in dataclasses.fields(part):
            v = getattr(part, f.name)
            if f.name in base and v != base[f.name]:
                out[f.name] = v
    return out


def config_for(spec: MissionSpec, controller: Controller | str = Controller.CC, *,
               fire: FireParams | None = None, mission: MissionParams | None = None,
               supervisor: str = "paper",
               timing: Timing = Timing.PAPER, profile: str = "today",
               **fields: Any) -> MissionConfig:
    """The configuration that flies ``spec`` (start, goal, area, seed) with ``controller``
    (a Controller, or a name such as "concurrent+risk") and the parameter objects given."""
    settings = tuple(overrides(profile, fire, mission, spec.dynamics).items())
    geometry: dict[str, Any] = dict(seed=spec.seed, goal=spec.goal,
                                    area_size_m=spec.area_size_m, start=spec.start,
                                    timing=timing, profile=profile, settings=settings)
    if isinstance(controller, str):
        return MissionConfig.named(controller, **geometry, **fields)
    return MissionConfig(controller=controller, supervisor=supervisor,
                         **geometry, **fields)
