"""A :class:`~dualpilot.mission.config.MissionConfig` from command-line flags, and back.

One grammar for every entry point: ``dualpilot mission``, ``evaluate`` and
``sweep``, the stack's launcher and its supervisor (``python -m
services.supervisor``) add the same flags (:func:`add_config_arguments`) and
read them with :func:`config_from_args`. The core knows flags only: the
environment names docker compose sets (``CONTROLLER``, ``MISSION_SEED``, …) are
the services' (services/common/mission_env.py), which turns them into these
flags. :func:`config_to_argv` writes a configuration as flags: reading them back
gives the same configuration (a property test checks it).

The reading's named flags (``--d-t-reading``, ``--scenario``, …) are
shorthands for ``--set NAME=VALUE``; the concurrent supervisor's parameters are
``--concurrent NAME=VALUE`` (``risk.alpha`` for the forecast's α); the fire forecast's
grid and ensemble are ``--forecast NAME=VALUE``. An evaluation leaves out the
fields it sets per task (``per_mission=False``: the controller, from its
``--controllers``; the start, goal, area and id, drawn per mission); a sweep's
``--set`` is a grid axis (``grid=True``).
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from dualpilot.mission.config import (
    DEFAULT_MISSION,
    MissionConfig,
    controller_names,
    parse_controller,
)
from dualpilot.mission.params import Timing
from dualpilot.model.forecast import ForecastParams
from dualpilot.model.geometry import Rect
from dualpilot.model.risk import RiskParams
from dualpilot.readings import PROFILES, parse_settings, settable, value_text
from dualpilot.supervisor.concurrent.rule import ConcurrentParams
from dualpilot.supervisor.registry import PAPER, supervisor_names

__all__ = ["READING_FLAGS", "add_config_arguments", "config_from_args", "config_to_argv",
           "parse_config", "reading_settings"]

#: The reading's named flags: (flag, setting name).
READING_FLAGS = (
    ("--d-t-reading", "d_t_reading"),
    ("--failure-rule", "failure_rule"),
    ("--fire-substeps-per-motion", "fire_substeps_per_motion"),
    ("--fire-life-base", "life_base"),
    ("--fire-extent", "extent"),
    ("--redraw-clearance", "redraw_clearance"),
    ("--attention-draw", "attention_draw"),
    ("--speed-limit", "speed_limit"),
    ("--scenario", "scenario"),
    ("--ignition-clearance", "ignition_clearance_m"),
    ("--max-steps", "max_steps"),
)
#: The defaults the flags start from.
_DEFAULT = MissionConfig()


def _goal_text(goal: Rect) -> str:
    return ",".join(repr(v) for v in (goal.center_x, goal.center_y, goal.width, goal.height))


def add_config_arguments(p: argparse.ArgumentParser, seed: int | None = None, *,
                         per_mission: bool = True, grid: bool = False) -> None:
    """The mission configuration's flags on ``p``, ``seed`` the default of ``--seed``.

    A mission's flags default to the default mission
    (:data:`~dualpilot.mission.config.DEFAULT_MISSION`: its controller, seed, timing and
    reading), so ``dualpilot mission``, the launcher (``make run``) and the supervisor
    (``docker compose up``) fly it when nothing is given. ``per_mission=False`` (an
    evaluation) leaves out the controller (its ``--controllers`` name each task's) and the
    start, goal, area and id (drawn per mission: ``--seed`` is then the run's seed S,
    configuration i drawn from (S, i)); ``grid=True`` (a sweep) makes ``--set`` and the
    reading's named flags grid axes.
    """
    d = DEFAULT_MISSION if per_mission else _DEFAULT
    g = p.add_argument_group("mission configuration (dualpilot.mission.config)")
    if per_mission:
        _add_who_flies(g, d)
    g.add_argument("--seed", type=int, default=d.seed if seed is None else seed,
                   help="every random stream of the mission is drawn from it (default "
                        "%(default)s)" if per_mission
                   else "the run's seed S: configuration i (start, goal, streams) is drawn "
                        "from (S, i)")
    g.add_argument("--timing", default=d.timing.value, choices=[t.value for t in Timing],
                   help="planning time T_s: the paper's 155 ms / 5 s or measured")
    g.add_argument("--profile", default=d.profile, choices=list(PROFILES),
                   help="named reading of the paper (dualpilot profiles)")
    g.add_argument("--set", action="append", default=[],
                   metavar="NAME=V1,V2" if grid else "NAME=VALUE",
                   help=("a grid axis: parameter NAME takes each value (repeat for more axes)"
                         if grid else "set one parameter of the reading (repeatable)")
                   + f"; names: {', '.join(settable())}")
    for flag, name in READING_FLAGS:
        g.add_argument(flag, dest=f"reading_{name}", default="",
                       help=f"--set {name}=VALUE" + (" (a grid axis of one value)" if grid
                                                     else ""))
    g.add_argument("--s1-method", default="",
                   help="System 1's method (dualpilot.planners; default: the supervisor's)")
    g.add_argument("--s2-method", default="fast", help="System 2's method (dualpilot.planners)")
    g.add_argument("--s2-time-limit-s", type=float, default=_DEFAULT.system2_time_limit_s,
                   help="System 2's solver time limit per plan (s; the exact method's: "
                        "System2Params.time_limit_s)")
    g.add_argument("--concurrent", action="append", default=[], metavar="NAME=VALUE",
                   help="a parameter of the concurrent supervisor (repeatable; names: "
                        f"{', '.join(concurrent_names())})")
    g.add_argument("--forecast", action="append", default=[], metavar="NAME=VALUE",
                   help="the risk-aware controllers' fire forecast (repeatable; names: "
                        f"{', '.join(FORECAST_NAMES)})")
    if per_mission:
        _add_where(g)


def _add_who_flies(g: argparse._ArgumentGroup, d: MissionConfig) -> None:
    """A mission's ``--controller`` and ``--supervisor`` (``d``: their defaults)."""
    g.add_argument("--controller", default=d.controller_name, choices=controller_names(),
                   help="who flies: the paper's cc, s1, s2, or another supervisor by its "
                        "name (concurrent, lookahead, an installed one), each with +risk: "
                        "with the fire forecast (default %(default)s)")
    g.add_argument("--supervisor", default="", choices=["", *supervisor_names()],
                   help="the cognitive controller's supervisor (concurrent: as "
                        "--controller concurrent)")


def _add_where(g: argparse._ArgumentGroup) -> None:
    """A mission's goal, area, start and id (an evaluation draws them per mission)."""
    g.add_argument("--goal", default=_goal_text(_DEFAULT.goal),
                   help="goal rectangle 'east,north,width,height' in m")
    g.add_argument("--area-size-m", type=float, default=_DEFAULT.area_size_m,
                   help="the square area [0, A]² (m)")
    g.add_argument("--start", default="",
                   help="'east,north' (m) where an in-process mission starts (the stack's: "
                        "where the vehicle is)")
    g.add_argument("--mission-id", default="")


# -- the concurrent supervisor's parameters by name ----------------------------------------------
def concurrent_names() -> list[str]:
    """The settable names of :class:`ConcurrentParams` (its RiskParams as ``risk.<name>``);
    ``threat`` follows the controller's ``+risk``."""
    top = [f.name for f in dataclasses.fields(ConcurrentParams) if f.name not in ("risk", "threat")]
    return top + [f"risk.{f.name}" for f in dataclasses.fields(RiskParams)]


def _typed(cls: type, name: str, text: str) -> Any:
    field = next(f for f in dataclasses.fields(cls) if f.name == name)
    kind = str(field.type)
    if text.strip().lower() in ("none", "") and "None" in kind:
        return None
    if kind.startswith("Literal"):  # a word (its values are the dataclass's to check)
        return text.strip()
    return int(text) if kind.startswith("int") else float(text)


def concurrent_params(items: Iterable[str]) -> ConcurrentParams:
    """``["name=value", ...]`` as ConcurrentParams (ValueError for an unknown name)."""
    top: dict[str, Any] = {}
    risk: dict[str, Any] = {}
    known = concurrent_names()
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or name not in known:
            raise ValueError(f"--concurrent takes NAME=VALUE with NAME one of "
                             f"{', '.join(known)}; got {item!r}")
        if name.startswith("risk."):
            risk[name[5:]] = _typed(RiskParams, name[5:], value)
        else:
            top[name] = _typed(ConcurrentParams, name, value)
    return ConcurrentParams(**top, risk=RiskParams(**risk))


def _text(value: object) -> str:
    """A parameter's value as ``--concurrent`` reads it back: a word as it is, a number
    exact (its repr)."""
    return value if isinstance(value, str) else repr(value)


def _concurrent_items(params: ConcurrentParams) -> list[str]:
    """The parameters that differ from the defaults, as ``name=value`` (exact: repr)."""
    base = ConcurrentParams()
    out = [f"{f.name}={_text(getattr(params, f.name))}" for f in dataclasses.fields(params)
           if f.name not in ("risk", "threat") and getattr(params, f.name) != getattr(base, f.name)]
    out += [f"risk.{f.name}={getattr(params.risk, f.name)!r}"
            for f in dataclasses.fields(params.risk)
            if getattr(params.risk, f.name) != getattr(base.risk, f.name)]
    return out


# -- the fire forecast's parameters by name ------------------------------------------------------
FORECAST_NAMES = tuple(f.name for f in dataclasses.fields(ForecastParams))


def forecast_params(items: Iterable[str]) -> ForecastParams:
    """``["name=value", ...]`` as ForecastParams (ValueError for an unknown name)."""
    values: dict[str, Any] = {}
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or name not in FORECAST_NAMES:
            raise ValueError(f"--forecast takes NAME=VALUE with NAME one of "
                             f"{', '.join(FORECAST_NAMES)}; got {item!r}")
        values[name] = _typed(ForecastParams, name, value)
    return ForecastParams(**values)


def _forecast_items(params: ForecastParams) -> list[str]:
    """The forecast parameters that differ from the defaults, as ``name=value`` (repr)."""
    base = ForecastParams()
    return [f"{n}={getattr(params, n)!r}" for n in FORECAST_NAMES
            if getattr(params, n) != getattr(base, n)]


# -- flags -> config -----------------------------------------------------------------------------
def _pair(text: str, what: str) -> tuple[float, float]:
    try:
        east, north = (float(v) for v in text.split(","))
    except ValueError as err:
        raise ValueError(f"{what} must be 'east,north', got {text!r}") from err
    return east, north


def parse_goal(text: str) -> Rect:
    """A goal rectangle written 'east,north,width,height' (m)."""
    try:
        cx, cy, w, h = (float(v) for v in text.split(","))
    except ValueError as err:
        raise ValueError(f"--goal must be 'east,north,width,height', got {text!r}") from err
    return Rect(cx, cy, w, h)


def reading_settings(args: argparse.Namespace) -> dict[str, str]:
    """``--set`` and the named reading flags as one dict (a name given twice must agree)."""
    settings = parse_settings(args.set)
    for _, name in READING_FLAGS:
        value = getattr(args, f"reading_{name}")
        if value == "":
            continue
        if name in settings and settings[name] != value:
            raise ValueError(f"{name} is set twice: {settings[name]!r} and {value!r}")
        settings[name] = value
    return settings


def _controller(args: argparse.Namespace) -> tuple[Any, str, bool]:
    """(controller, supervisor, risk) of ``--controller`` and ``--supervisor``."""
    name = getattr(args, "controller", _DEFAULT.controller_name)
    controller, supervisor, risk = parse_controller(name)
    if getattr(args, "supervisor", ""):
        chosen = args.supervisor
        if chosen != supervisor and supervisor != PAPER:
            raise ValueError(f"--supervisor {chosen} contradicts --controller {name}")
        supervisor = chosen
    return controller, supervisor, risk


def config_from_args(args: argparse.Namespace,
                     settings: Mapping[str, Any] | None = None) -> MissionConfig:
    """The configuration the flags of :func:`add_config_arguments` say (ValueError if bad);
    ``settings`` instead of the reading's flags (a sweep's grid point gives them)."""
    controller, supervisor, risk = _controller(args)
    start = getattr(args, "start", "")
    return MissionConfig(
        controller=controller, supervisor=supervisor, risk=risk, timing=Timing(args.timing),
        seed=int(args.seed), profile=args.profile,
        settings=tuple((reading_settings(args) if settings is None else settings).items()),
        system1_method=args.s1_method, system2_method=args.s2_method,
        system2_time_limit_s=float(args.s2_time_limit_s),
        concurrent=concurrent_params(args.concurrent), forecast=forecast_params(args.forecast),
        goal=parse_goal(getattr(args, "goal", _goal_text(_DEFAULT.goal))),
        area_size_m=float(getattr(args, "area_size_m", _DEFAULT.area_size_m)),
        start=_pair(start, "--start") if start else None,
        mission_id=getattr(args, "mission_id", ""))


# -- config -> flags -----------------------------------------------------------------------------

def config_to_argv(config: MissionConfig) -> list[str]:
    """Flags that :func:`config_from_args` reads back as ``config`` (the ``uav_id`` is the
    process's own: ``--uav-id`` of the services). Each is ``--flag=value``, so a value that
    starts with "-" is still a value."""
    c = config
    pairs = [("controller", c.controller_name), ("timing", c.timing.value),
             ("seed", str(c.seed)), ("profile", c.profile), ("s1-method", c.system1_method),
             ("s2-method", c.system2_method),
             ("s2-time-limit-s", repr(c.system2_time_limit_s)),
             ("area-size-m", repr(c.area_size_m)), ("goal", _goal_text(c.goal)),
             ("mission-id", c.mission_id)]
    pairs += [("set", f"{name}={value_text(value)}") for name, value in c.settings]
    pairs += [("concurrent", item) for item in _concurrent_items(c.concurrent)]
    pairs += [("forecast", item) for item in _forecast_items(c.forecast)]
    if c.start is not None:
        pairs.append(("start", f"{c.start[0]!r},{c.start[1]!r}"))
    return [f"--{flag}={value}" for flag, value in pairs]


def parse_config(argv: Sequence[str]) -> MissionConfig:
    """The configuration of ``argv`` (the flags of :func:`add_config_arguments` only)."""
    p = argparse.ArgumentParser(add_help=False)
    add_config_arguments(p)
    return config_from_args(p.parse_args(list(argv)))
