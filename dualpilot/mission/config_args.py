"""A :class:`~dualpilot.mission.config.MissionConfig` from command-line flags, and back.

One grammar for every entry point: ``dualpilot mission`` and the stack's
supervisor (``python -m services.supervisor``, whose flags take their defaults
from the environment: ``CONTROLLER``, ``MISSION_SEED``, …, so docker compose and
the local launcher set a mission by environment) add the same flags
(:func:`add_config_arguments`) and read them with :func:`config_from_args`.
:func:`config_to_argv` writes a configuration as flags: reading them back gives
the same configuration (a property test checks it).

The reading's named flags (``--d-t-reading``, ``--fire-scenario``, …) are
shorthands for ``--set NAME=VALUE``; the concurrent supervisor's parameters are
``--concurrent NAME=VALUE`` (``risk.alpha`` for the forecast's α); the fire forecast's
grid and ensemble are ``--forecast NAME=VALUE``.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable, Iterable, Sequence
from typing import Any

from dualpilot.mission.config import CONTROLLER_NAMES, MissionConfig, parse_controller
from dualpilot.mission.params import Timing
from dualpilot.mission.supervisors import SupervisorKind
from dualpilot.model.forecast import ForecastParams
from dualpilot.model.geometry import Rect
from dualpilot.model.risk import RiskParams
from dualpilot.readings import PROFILES, parse_settings, settable, value_text
from dualpilot.supervisor.concurrent import ConcurrentParams

__all__ = ["add_config_arguments", "config_from_args", "config_to_argv"]

#: A default's source: (environment variable, default text) -> text. The core CLI's
#: returns the default; the services' reads the environment first.
Env = Callable[[str, str], str]

#: The reading's named flags: (flag, setting name, environment variable).
READING_FLAGS = (
    ("--d-t-reading", "d_t_reading", "D_T_READING"),
    ("--failure-rule", "failure_rule", "FAILURE_RULE"),
    ("--fire-substeps-per-motion", "fire_substeps_per_motion", "FIRE_SUBSTEPS_PER_MOTION"),
    ("--fire-life-base", "life_base", "FIRE_LIFE_BASE"),
    ("--fire-extent", "extent", "FIRE_EXTENT"),
    ("--redraw-clearance", "redraw_clearance", "FIRE_REDRAW_CLEARANCE"),
    ("--attention-draw", "attention_draw", "ATTENTION_DRAW"),
    ("--speed-limit", "speed_limit", "SPEED_LIMIT"),
    ("--scenario", "scenario", "FIRE_SCENARIO"),
    ("--ignition-clearance", "ignition_clearance_m", "IGNITION_CLEARANCE_M"),
    ("--max-steps", "max_steps", "MAX_STEPS"),
)


def _defaults(name: str, default: str) -> str:
    return default


def _items(text: str) -> list[str]:
    """``"a=1;b=2"`` (an environment variable's list of settings) as ``["a=1", "b=2"]``."""
    return [t.strip() for t in text.split(";") if t.strip()]


def add_config_arguments(p: argparse.ArgumentParser, env: Env = _defaults,
                         seed: int = 7) -> None:
    """The mission configuration's flags on ``p`` (defaults through ``env``)."""
    g = p.add_argument_group("mission configuration (dualpilot.mission.config)")
    g.add_argument("--controller", default=env("CONTROLLER", "cc"), choices=CONTROLLER_NAMES,
                   help="who flies: the paper's cc, s1, s2, the concurrent supervisor, each with "
                        "+risk: with the fire forecast [CONTROLLER]")
    g.add_argument("--supervisor", default=env("SUPERVISOR", ""),
                   choices=["", *(k.value for k in SupervisorKind)],
                   help="the cognitive controller's supervisor (concurrent: as --controller "
                        "concurrent) [SUPERVISOR]")
    g.add_argument("--seed", type=int, default=env("MISSION_SEED", str(seed)),
                   help="[MISSION_SEED]")
    g.add_argument("--timing", default=env("TIMING", "paper"), choices=[t.value for t in Timing],
                   help="planning time T_s: the paper's 155 ms / 5 s or measured [TIMING]")
    g.add_argument("--profile", default=env("READINGS_PROFILE", "today"), choices=list(PROFILES),
                   help="named reading of the paper (dualpilot profiles) [READINGS_PROFILE]")
    g.add_argument("--set", action="append", default=_items(env("READINGS", "")),
                   metavar="NAME=VALUE", help="set one parameter of the reading (repeatable; "
                   f"names: {', '.join(settable())}) [READINGS: 'a=1;b=2']")
    for flag, name, var in READING_FLAGS:
        g.add_argument(flag, dest=f"reading_{name}", default=env(var, ""),
                       help=f"--set {name}=VALUE [{var}]")
    g.add_argument("--s1-method", default=env("S1_METHOD", ""),
                   help="System 1's method (dualpilot.planners; default: the supervisor's) "
                        "[S1_METHOD]")
    g.add_argument("--s2-method", default=env("S2_METHOD", "fast"),
                   help="System 2's method (dualpilot.planners) [S2_METHOD]")
    g.add_argument("--concurrent", action="append",
                   default=_items(env("CONCURRENT_PARAMS", "")), metavar="NAME=VALUE",
                   help="a parameter of the concurrent supervisor (repeatable; names: "
                        f"{', '.join(concurrent_names())}) [CONCURRENT_PARAMS: 'a=1;b=2']")
    g.add_argument("--forecast", action="append",
                   default=_items(env("FORECAST_PARAMS", "")), metavar="NAME=VALUE",
                   help="the risk-aware controllers' fire forecast (repeatable; names: "
                        f"{', '.join(FORECAST_NAMES)}) [FORECAST_PARAMS: 'a=1;b=2']")
    g.add_argument("--goal", default=env("GOAL", "900,900,100,100"),
                   help="goal rectangle 'east,north,width,height' in m [GOAL]")
    g.add_argument("--area-size-m", type=float, default=env("AREA_SIZE_M", "1000"),
                   help="[AREA_SIZE_M]")
    g.add_argument("--start", default=env("MISSION_START", ""),
                   help="'east,north' (m) where an in-process mission starts (the stack's: where "
                        "the vehicle is) [MISSION_START]")
    g.add_argument("--mission-id", default=env("MISSION_ID", ""), help="[MISSION_ID]")


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


def _concurrent_items(params: ConcurrentParams) -> list[str]:
    """The parameters that differ from the defaults, as ``name=value`` (exact: repr)."""
    base = ConcurrentParams()
    out = [f"{f.name}={getattr(params, f.name)!r}" for f in dataclasses.fields(params)
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


def _settings(args: argparse.Namespace) -> dict[str, str]:
    """``--set`` and the named reading flags as one dict (a name given twice must agree)."""
    settings = parse_settings(args.set)
    for _, name, _ in READING_FLAGS:
        value = getattr(args, f"reading_{name}")
        if value == "":
            continue
        if name in settings and settings[name] != value:
            raise ValueError(f"{name} is set twice: {settings[name]!r} and {value!r}")
        settings[name] = value
    return settings


def config_from_args(args: argparse.Namespace) -> MissionConfig:
    """The configuration the flags of :func:`add_config_arguments` say (ValueError if bad)."""
    controller, supervisor, risk = parse_controller(args.controller)
    if args.supervisor:
        chosen = SupervisorKind(args.supervisor)
        if chosen is not supervisor and supervisor is not SupervisorKind.PAPER:
            raise ValueError(f"--supervisor {chosen.value} contradicts --controller "
                             f"{args.controller}")
        supervisor = chosen
    return MissionConfig(
        controller=controller, supervisor=supervisor, risk=risk, timing=Timing(args.timing),
        seed=int(args.seed), profile=args.profile, settings=tuple(_settings(args).items()),
        system1_method=args.s1_method, system2_method=args.s2_method,
        concurrent=concurrent_params(args.concurrent), forecast=forecast_params(args.forecast),
        goal=parse_goal(args.goal),
        area_size_m=float(args.area_size_m),
        start=_pair(args.start, "--start") if args.start else None,
        mission_id=args.mission_id)


# -- config -> flags -----------------------------------------------------------------------------

def config_to_argv(config: MissionConfig) -> list[str]:
    """Flags that :func:`config_from_args` reads back as ``config`` (the ``uav_id`` is the
    process's own: ``--uav-id`` of the services). Each is ``--flag=value``, so a value that
    starts with "-" is still a value."""
    c = config
    g = c.goal
    pairs = [("controller", c.controller_name), ("timing", c.timing.value),
             ("seed", str(c.seed)), ("profile", c.profile), ("s1-method", c.system1_method),
             ("s2-method", c.system2_method), ("area-size-m", repr(c.area_size_m)),
             ("goal", ",".join(repr(v) for v in (g.center_x, g.center_y, g.width, g.height))),
             ("mission-id", c.mission_id)]
    pairs += [("set", f"{name}={value_text(value)}") for name, value in c.settings]
    pairs += [("concurrent", item) for item in _concurrent_items(c.concurrent)]
    pairs += [("forecast", item) for item in _forecast_items(c.forecast)]
    if c.start is not None:
        pairs.append(("start", f"{c.start[0]!r},{c.start[1]!r}"))
    return [f"--{flag}={value}" for flag, value in pairs]


def parse_config(argv: Sequence[str], env: Env = _defaults) -> MissionConfig:
    """The configuration of ``argv`` (the flags of :func:`add_config_arguments` only)."""
    p = argparse.ArgumentParser(add_help=False)
    add_config_arguments(p, env)
    return config_from_args(p.parse_args(list(argv)))


def config_env(config: MissionConfig) -> dict[str, str]:
    """The environment that makes the flags of :func:`add_config_arguments` (defaults read
    from the environment, as the services do) say ``config``: how a launcher or a compose
    file hands a process its mission. Every variable is set, the unused ones empty, so none
    is inherited from the launcher's own environment."""
    c = config
    g = c.goal
    env = {var: "" for _, _, var in READING_FLAGS}
    env.update({
        "CONTROLLER": c.controller_name, "SUPERVISOR": "", "TIMING": c.timing.value,
        "MISSION_SEED": str(c.seed), "READINGS_PROFILE": c.profile,
        "READINGS": ";".join(f"{n}={value_text(v)}" for n, v in c.settings),
        "S1_METHOD": c.system1_method, "S2_METHOD": c.system2_method,
        "CONCURRENT_PARAMS": ";".join(_concurrent_items(c.concurrent)),
        "FORECAST_PARAMS": ";".join(_forecast_items(c.forecast)),
        "GOAL": ",".join(repr(v) for v in (g.center_x, g.center_y, g.width, g.height)),
        "AREA_SIZE_M": repr(c.area_size_m), "MISSION_ID": c.mission_id,
        "MISSION_START": "" if c.start is None else f"{c.start[0]!r},{c.start[1]!r}",
    })
    return env
