"""config.proto ↔ :class:`~dualpilot.mission.config.MissionConfig`: the one wire form of it.

The configuration travels whole, with the plan request that prepares a mission,
with the EWS's reset and to the simulated vehicle (uavsim's ``uavsim/mission``).
Decoding checks every field (known enums, short texts, a supervisor installed in
this process, the reading's names and values, the concurrent supervisor's ranges, a
goal inside the area) and raises :class:`~services.common.rejections.CodecError` for a
bad one: a configuration that decodes is one the core accepts.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from google.protobuf import json_format

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.params import Controller, Timing
from dualpilot.model.forecast import ForecastParams
from dualpilot.model.risk import RiskParams
from dualpilot.readings import parse_value, value_text
from dualpilot.supervisor.concurrent.rule import ConcurrentParams
from dualpilot.supervisor.registry import supervisor_names
from services.common.convert.common import rect_from_msg, rect_to_msg
from services.common.limits import MAX_ABS_M, check_count, check_floats, check_text, finite
from services.common.rejections import CodecError, Reason, invalid
from services.msgs import config_pb2

#: the most reading overrides a configuration carries (every settable field once is fewer)
MAX_SETTINGS = 64

_CONTROLLERS = {Controller.CC: config_pb2.CONTROLLER_KIND_CC,
                Controller.S1: config_pb2.CONTROLLER_KIND_S1,
                Controller.S2: config_pb2.CONTROLLER_KIND_S2}
_TIMINGS = {Timing.PAPER: config_pb2.TIMING_PAPER, Timing.MEASURED: config_pb2.TIMING_MEASURED}
#: ConcurrentParams' fields on the wire (its ``threat`` follows ``MissionConfig.risk``)
CONCURRENT_WIRE = tuple(f.name for f in dataclasses.fields(ConcurrentParams)
                        if f.name not in ("threat", "risk"))
#: those that are words (``s2_unavailable``, ``reanchor_tol``: empty on the wire is the default)
_WORDS = ("s2_unavailable", "reanchor_tol")
#: those that are always numbers (``threat_margin_m`` may be absent: the spec's clearance)
_NUMBERS = tuple(n for n in CONCURRENT_WIRE if n not in ("threat_margin_m", *_WORDS))



def config_to_msg(config: MissionConfig, out: config_pb2.MissionConfig
                  ) -> config_pb2.MissionConfig:
    """``config`` into ``out``, every field."""
    c = config
    out.mission_id, out.uav_id, out.seed = c.mission_id, c.uav_id, c.seed
    out.controller = _CONTROLLERS[c.controller]
    out.supervisor = c.supervisor
    out.timing = _TIMINGS[c.timing]
    out.risk, out.profile = c.risk, c.profile
    for name, value in c.settings:
        out.settings.add(name=name, value=value_text(value))
    out.system1_method, out.system2_method = c.system1_method, c.system2_method
    out.system2_time_limit_s = c.system2_time_limit_s
    p = c.concurrent
    if p.threat_margin_m is not None:
        out.concurrent.threat_margin_m = p.threat_margin_m
    for name in _NUMBERS:
        setattr(out.concurrent, name, getattr(p, name))
    out.concurrent.risk.alpha = p.risk.alpha
    for name in _WORDS:
        setattr(out.concurrent, name, getattr(p, name))
    f = c.forecast
    out.forecast.members, out.forecast.resolution_m = f.members, f.resolution_m
    out.forecast.horizon_s, out.forecast.interval_s = f.horizon_s, f.interval_s
    rect_to_msg(c.goal, out.goal)
    out.area_size_m = c.area_size_m
    if c.start is not None:
        out.start.east_m, out.start.north_m = c.start
    return out


def config_to_json(config: MissionConfig) -> dict[str, Any]:
    """``config``'s wire form as JSON data (protobuf's JSON mapping, the field names of
    config.proto): what a status reply says a process runs."""
    msg = config_to_msg(config, config_pb2.MissionConfig())
    doc: dict[str, Any] = json_format.MessageToDict(msg, preserving_proto_field_name=True)
    return doc


def config_from_json(doc: dict[str, Any]) -> MissionConfig:
    """The configuration of :func:`config_to_json`'s data, checked as off the wire."""
    try:
        msg = json_format.ParseDict(doc, config_pb2.MissionConfig())
    except json_format.ParseError as err:
        raise invalid(f"mission config: {err}") from err
    return config_from_msg(msg)


def _enum(value: int, table: Mapping[Any, Any], what: str) -> Any:
    back = {v: k for k, v in table.items()}
    if value not in back:
        raise invalid(f"{what} {value} is not one of {sorted(back)}", Reason.OUT_OF_RANGE)
    return back[value]


def _supervisor_from_msg(m: config_pb2.MissionConfig) -> str:
    """The supervisor's name, if a supervisor of that name is installed in this process."""
    name = check_text(m.supervisor, "supervisor", 64)
    installed = supervisor_names()
    if name not in installed:
        raise invalid(f"supervisor {name!r} is not installed here (installed: "
                      f"{', '.join(installed)})", Reason.OUT_OF_RANGE)
    return name


def _concurrent_from_msg(m: config_pb2.ConcurrentParams, risk: bool) -> ConcurrentParams:
    names = _NUMBERS
    values = check_floats([getattr(m, n) for n in names] + [m.risk.alpha],
                          "concurrent parameters", MAX_ABS_M)
    margin = (check_floats([m.threat_margin_m], "threat_margin_m", MAX_ABS_M)[0]
              if m.HasField("threat_margin_m") else None)
    typed: dict[str, Any] = {n: (int(v) if n == "check_steps" else float(v))
             for n, v in zip(names, values, strict=False)}
    words: dict[str, Any] = {n: check_text(getattr(m, n), n, 16)
                             or getattr(ConcurrentParams, n) for n in _WORDS}
    try:
        return ConcurrentParams(threat_margin_m=margin, **typed, **words,
                                threat="forecast" if risk else "current",
                                risk=RiskParams(alpha=float(values[-1])))
    except ValueError as err:
        raise invalid(f"concurrent parameters: {err}", Reason.OUT_OF_RANGE) from err


#: the most ensemble members and the longest forecast horizon (s) a configuration may ask for
MAX_FORECAST_MEMBERS = 4096
MAX_FORECAST_HORIZON_S = 3600.0
#: the longest System 2 time limit a configuration may ask for (s)
MAX_TIME_LIMIT_S = 3600.0


def _forecast_from_msg(m: config_pb2.ForecastParams) -> ForecastParams:
    resolution, horizon, interval = check_floats(
        [m.resolution_m, m.horizon_s, m.interval_s], "forecast parameters", MAX_ABS_M)
    if m.members > MAX_FORECAST_MEMBERS or horizon > MAX_FORECAST_HORIZON_S:
        raise invalid(f"forecast of {m.members} members over {horizon:g} s: at most "
                      f"{MAX_FORECAST_MEMBERS} members and {MAX_FORECAST_HORIZON_S:g} s",
                      Reason.OUT_OF_RANGE)
    try:
        return ForecastParams(members=int(m.members), resolution_m=float(resolution),
                              horizon_s=float(horizon), interval_s=float(interval))
    except ValueError as err:
        raise invalid(f"forecast parameters: {err}", Reason.OUT_OF_RANGE) from err


def _settings_from_msg(m: config_pb2.MissionConfig) -> tuple[tuple[str, Any], ...]:
    check_count(len(m.settings), "settings", MAX_SETTINGS)
    out = []
    for s in m.settings:
        name = check_text(s.name, "setting name", 64)
        text = check_text(s.value, f"setting {name}", 256)
        try:
            out.append((name, parse_value(name, text)))
        except ValueError as err:
            raise invalid(f"setting {name}={text!r}: {err}", Reason.OUT_OF_RANGE) from err
    if len({n for n, _ in out}) != len(out):
        raise invalid("a setting is named twice")
    return tuple(out)


def _time_limit_from_msg(m: config_pb2.MissionConfig) -> float:
    limit = check_floats([m.system2_time_limit_s], "system2_time_limit_s", MAX_TIME_LIMIT_S)[0]
    if not limit > 0:
        raise invalid(f"system2_time_limit_s must be > 0, got {limit:g}", Reason.OUT_OF_RANGE)
    return float(limit)


def config_from_msg(m: config_pb2.MissionConfig) -> MissionConfig:
    """The configuration of ``m``; every field checked (CodecError for a bad one)."""
    start = None
    if m.HasField("start"):
        e, n = finite((m.start.east_m, m.start.north_m), "start", MAX_ABS_M)
        start = (float(e), float(n))
    if not m.HasField("goal"):
        raise invalid("mission config without a goal")
    area = check_floats([m.area_size_m], "area_size_m", MAX_ABS_M)[0]
    try:
        return MissionConfig(
            controller=_enum(m.controller, _CONTROLLERS, "controller"),
            supervisor=_supervisor_from_msg(m),
            risk=bool(m.risk), timing=_enum(m.timing, _TIMINGS, "timing"), seed=int(m.seed),
            profile=check_text(m.profile, "profile", 64), settings=_settings_from_msg(m),
            system1_method=check_text(m.system1_method, "system1_method", 64),
            system2_method=check_text(m.system2_method, "system2_method", 64),
            system2_time_limit_s=_time_limit_from_msg(m),
            concurrent=_concurrent_from_msg(m.concurrent, bool(m.risk)),
            forecast=_forecast_from_msg(m.forecast) if m.HasField("forecast")
            else ForecastParams(),
            goal=rect_from_msg(m.goal, "goal"), area_size_m=float(area), start=start,
            mission_id=check_text(m.mission_id, "mission_id", 256),
            uav_id=check_text(m.uav_id, "uav_id", 64))
    except CodecError:
        raise
    except ValueError as err:  # the core's own checks: profile, settings, geometry, pairing
        raise invalid(f"mission config: {err}", Reason.OUT_OF_RANGE) from err
