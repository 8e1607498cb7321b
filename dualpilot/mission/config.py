"""The one mission configuration: every setting of a mission, built once and passed whole.

A :class:`MissionConfig` is what a user chooses for one mission: which
controller flies (the paper's three, or the cognitive controller under another
supervisor, each with or without the fire forecast), the reading of the paper (a profile and its
overrides, the fire scenario among them), the planners' methods, the timing,
the seed and the ids. It is built once (``dualpilot mission``, ``evaluate`` and
``sweep`` from their flags, dualpilot/mission/config_args.py; the stack's
supervisor from the same flags or the environment, services/common/mission_env.py),
and the in-process mission, the stack's supervisor, the planner services, the
EWS and uavsim all read their settings from it: none re-lists them. Its wire
form is written once, in ``services/common/convert/config.py``.

The controller names of ``dualpilot evaluate`` (:func:`controller_names`: ``cc``,
``s1``, ``s2``, the name of every other installed supervisor, ``concurrent`` and
``lookahead`` among them, and each with ``+risk``) are spellings of three typed fields
(:func:`parse_controller`): the controller, the supervisor (by its registry name,
:mod:`dualpilot.supervisor.registry`) and ``risk``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, Literal

from dualpilot.mission.params import Controller, Timing
from dualpilot.model.forecast import ForecastParams
from dualpilot.model.geometry import Rect
from dualpilot.readings import Profile, get_profile, parse_value, part_of
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.concurrent.rule import ConcurrentParams
from dualpilot.supervisor.registry import PAPER, supervisor_entry, supervisor_names
from dualpilot.system2.problem import System2Params

if TYPE_CHECKING:
    from dualpilot.system1.planner import System1Params

__all__ = ["DEFAULT_MISSION", "MissionConfig", "controller_name", "controller_names",
           "parse_controller"]


#: The spelling of ``risk`` in a controller name.
RISK_SPELLING = "+risk"
#: The order in which tables list the built-in controllers (the order they were added);
#: the installed supervisors' follow, by name.
LISTED = ("cc", "s1", "s2", "concurrent", "cc+risk", "s1+risk", "s2+risk",
          "concurrent+risk", "lookahead", "lookahead+risk")

#: one reading override: (field name of the profile's parameters, its value)
Setting = tuple[str, Any]


def controller_names() -> tuple[str, ...]:
    """The controllers an evaluation compares, by name: the paper's supervisor's three
    (cc, s1, s2), the cognitive controller of every other installed supervisor by the
    supervisor's name, and each flown with the fire forecast (``+risk``)."""
    bases = [c.value for c in Controller] + [s for s in supervisor_names() if s != PAPER]
    names = [base + suffix for base in bases for suffix in ("", RISK_SPELLING)]
    order = {name: k for k, name in enumerate(LISTED)}
    return tuple(sorted(names, key=lambda n: order.get(n, len(order))))


def parse_controller(name: str) -> tuple[Controller, str, bool]:
    """(controller, supervisor, risk) of a controller name of :func:`controller_names`."""
    base = name.removesuffix(RISK_SPELLING)
    risk = base != name
    if base in {c.value for c in Controller}:
        return Controller(base), PAPER, risk
    if base != PAPER and base in supervisor_names():
        return Controller.CC, base, risk
    raise ValueError(f"unknown controller {name!r}; choose from {', '.join(controller_names())}")


def controller_name(controller: Controller, supervisor: str, risk: bool) -> str:
    """The name of :func:`controller_names` that spells the three fields."""
    base = controller.value if supervisor == PAPER else supervisor
    return base + (RISK_SPELLING if risk else "")


def _canonical_settings(settings: Any) -> tuple[Setting, ...]:
    """Settings as a tuple sorted by name, each value typed (text is parsed by its field)."""
    items = settings.items() if hasattr(settings, "items") else settings
    out: dict[str, Any] = {}
    for name, value in items:
        part_of(name)  # ValueError for a name no parameter class has
        out[name] = parse_value(name, value) if isinstance(value, str) else value
    return tuple(sorted(out.items()))


@dataclass(frozen=True)
class MissionConfig:
    """Everything chosen for one mission (lengths m, times s).

    ``profile`` and ``settings`` are the reading of the paper
    (:mod:`dualpilot.readings`; the fire scenario is the setting ``scenario``,
    the step limit ``max_steps``, the ignition clearance ``ignition_clearance_m``);
    :meth:`reading` resolves them. ``supervisor`` is a name of the supervisors' registry
    (:mod:`dualpilot.supervisor.registry`). ``system1_method`` "" is the supervisor's
    (:meth:`methods` resolves it, so a configuration flown by another controller keeps its
    choice). ``system2_time_limit_s``
    is System 2's solver time limit per plan (:class:`~dualpilot.system2.problem.System2Params`:
    the exact method's; fast+exact and certified keep budgets of their own). With ``risk``
    both planners take the fire forecast (their risk-aware variants) and the
    concurrent supervisor judges threats on it (``concurrent.threat`` is then "forecast");
    ``forecast`` is that forecast's grid and ensemble (the in-process fire port's and the
    EWS's alike). ``start`` is where an in-process mission starts (None: the spec's default);
    in the stack the mission starts where the vehicle is.
    """

    controller: Controller = Controller.CC
    supervisor: str = PAPER
    risk: bool = False
    timing: Timing = Timing.PAPER
    seed: int = 0
    profile: str = "today"
    settings: tuple[Setting, ...] = ()
    system1_method: str = ""
    system2_method: str = "fast"
    system2_time_limit_s: float = System2Params().time_limit_s
    concurrent: ConcurrentParams = field(default_factory=ConcurrentParams)
    forecast: ForecastParams = field(default_factory=ForecastParams)
    goal: Rect = MissionSpec().goal
    area_size_m: float = MissionSpec().area_size_m
    start: tuple[float, float] | None = None
    mission_id: str = ""
    uav_id: str = ""

    def __post_init__(self) -> None:
        entry = supervisor_entry(self.supervisor)  # ValueError: not installed here
        if self.controller not in entry.controllers:
            raise ValueError(f"the {self.supervisor} supervisor does not run "
                             f"{self.controller.value} (it runs "
                             f"{', '.join(sorted(c.value for c in entry.controllers))})")
        if self.mission_id.startswith("-"):  # "--" would read as the end of the flags
            raise ValueError(f"mission_id must not start with '-', got {self.mission_id!r}")
        if not 0 <= self.seed < 2**64:
            raise ValueError(f"seed must be in [0, 2^64), got {self.seed}")
        object.__setattr__(self, "settings", _canonical_settings(self.settings))
        if not 0 < self.system2_time_limit_s < math.inf:
            raise ValueError(f"system2_time_limit_s must be a positive number of seconds, got "
                             f"{self.system2_time_limit_s}")
        object.__setattr__(self, "system2_time_limit_s", float(self.system2_time_limit_s))
        threat: Literal["current", "forecast"] = "forecast" if self.risk else "current"
        if self.concurrent.threat == "forecast" and not self.risk:
            raise ValueError("forecast threats are the risk-aware controller's: set risk")
        if self.concurrent.threat != threat:
            object.__setattr__(self, "concurrent", replace(self.concurrent, threat=threat))
        if self.start is not None:
            object.__setattr__(self, "start", (float(self.start[0]), float(self.start[1])))
        self.reading()  # the profile exists and the settings apply
        self.spec()  # the geometry is consistent

    # -- the controller by name --------------------------------------------------------------
    @classmethod
    def named(cls, name: str, **fields: Any) -> MissionConfig:
        """The configuration of controller ``name`` (:func:`controller_names`) with
        ``fields``."""
        controller, supervisor, risk = parse_controller(name)
        return cls(controller=controller, supervisor=supervisor, risk=risk, **fields)

    @property
    def controller_name(self) -> str:
        """This configuration's controller as a name of :func:`controller_names`."""
        return controller_name(self.controller, self.supervisor, self.risk)

    # -- what the parts read -----------------------------------------------------------------
    def reading(self) -> Profile:
        """The reading of the paper: the profile with the settings applied."""
        return get_profile(self.profile).with_settings(dict(self.settings))

    def spec(self, start: tuple[float, float] | None = None) -> MissionSpec:
        """The frozen spec: the geometry, the seed and the reading's dynamics (Eq. 1); the
        start is ``start`` (the vehicle's position), else :attr:`start`, else the default."""
        at = start if start is not None else self.start
        base = MissionSpec(goal=self.goal, area_size_m=self.area_size_m, seed=self.seed)
        if at is not None:
            base = replace(base, start=(float(at[0]), float(at[1])))
        return self.reading().spec(base)

    def methods(self) -> dict[int, str]:
        """The planners' registry names by system (:mod:`dualpilot.planners`); System 1's
        "" is the supervisor's."""
        system1 = self.system1_method or supervisor_entry(self.supervisor).system1_method
        return {1: system1, 2: self.system2_method}

    def system1_params(self) -> System1Params:
        """System 1's parameters: the paper's, with this reading's ``s1_altitude`` (where a 3-D
        System 1 plans, dualpilot/system1/altitude.py)."""
        from dualpilot.system1.planner import System1Params

        return System1Params(altitude=self.reading().altitude.s1_altitude)

    def system2_params(self) -> System2Params:
        """System 2's parameters: the paper's, with this configuration's time limit."""
        return System2Params(time_limit_s=self.system2_time_limit_s)

    def systems(self) -> list[int]:
        """The planners this controller may ask."""
        return {Controller.CC: [1, 2], Controller.S1: [1], Controller.S2: [2]}[self.controller]

    def with_settings(self, settings: Any) -> MissionConfig:
        """This configuration with more reading overrides (name → value or its text)."""
        merged = dict(self.settings)
        merged.update(_canonical_settings(settings))
        return replace(self, settings=tuple(merged.items()))


#: The default mission: what ``make run``, ``docker compose up`` and ``dualpilot mission`` fly
#: when nothing says otherwise (the mission flags' defaults, dualpilot.mission.config_args;
#: the Makefile passes none, docker-compose.yml leaves their environment names empty, and
#: tests/integration/test_compose.py fails when they fly different missions). The lookahead
#: supervisor with the forecast is never significantly below the best other controller
#: (docs/yardstick.md; 69.0 % of today's held-out missions, 71.1 % of the achievable); seed 7
#: is one it flies to G (65 steps, in-process and through the stack), not every seed is.
DEFAULT_MISSION = MissionConfig.named("lookahead+risk", seed=7, timing=Timing.PAPER,
                                      profile="today")
