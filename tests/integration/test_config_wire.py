"""The mission configuration's wire form: every field on it, and back unchanged.

The configuration travels whole with a prepare request and with the EWS's
reset (services/common/convert/config.py); a field the wire did not carry would
be dropped silently on the way to a process, so a test fails when one has none.
"""

from __future__ import annotations

import dataclasses

import pytest
from hypothesis import given, settings

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.config_args import config_to_argv, parse_config
from dualpilot.model.forecast import ForecastParams
from dualpilot.model.risk import RiskParams
from dualpilot.supervisor.concurrent.rule import ConcurrentParams
from services.common import rejections, wire
from services.common.convert import config as config_convert
from services.msgs import config_pb2
from tests.support.configs import configs


def _wire_names(msg: type) -> set[str]:
    return {f.name for f in msg.DESCRIPTOR.fields}  # type: ignore[attr-defined]


@pytest.mark.parametrize(("cls", "msg", "derived"), [
    (MissionConfig, config_pb2.MissionConfig, set()),
    (ConcurrentParams, config_pb2.ConcurrentParams, {"threat"}),  # follows MissionConfig.risk
    (RiskParams, config_pb2.RiskParams, set()),
    (ForecastParams, config_pb2.ForecastParams, set()),
])
def test_every_field_has_a_wire_field(cls: type, msg: type, derived: set[str]) -> None:
    fields = {f.name for f in dataclasses.fields(cls)}
    assert fields - derived - _wire_names(msg) == set(), "fields the wire would drop"
    assert _wire_names(msg) - fields == set(), "wire fields no dataclass field fills"


def _through_the_wire(config: MissionConfig) -> MissionConfig:
    msg = config_convert.config_to_msg(config, config_pb2.MissionConfig())
    return config_convert.config_from_msg(wire.parse(msg.SerializeToString(),
                                                     config_pb2.MissionConfig))


@settings(max_examples=200, derandomize=True)
@given(configs())
def test_flags_config_wire_config_is_unchanged(config: MissionConfig) -> None:
    from_flags = parse_config(config_to_argv(config))
    assert from_flags == config
    assert _through_the_wire(from_flags) == config


def test_a_bad_config_is_refused_with_its_reason() -> None:
    msg = config_convert.config_to_msg(MissionConfig.named("concurrent"),
                                       config_pb2.MissionConfig())
    for change, match in ((lambda m: setattr(m, "controller", 2), "does not run s1"),
                          (lambda m: setattr(m, "supervisor", "warp"),
                           r"supervisor 'warp' is not installed here \(installed: paper, "
                           r"concurrent, lookahead"),
                          (lambda m: setattr(m, "supervisor", ""), "supervisor '' is not"),
                          (lambda m: setattr(m, "supervisor", "x" * 65), "longer than 64"),
                          (lambda m: setattr(m, "timing", 7), "timing 7 is not one of"),
                          (lambda m: m.settings.add(name="p_birth", value="2"), "p_birth"),
                          (lambda m: setattr(m.concurrent, "q_rate", 0.0), "q_rate"),
                          (lambda m: setattr(m.concurrent, "s2_unavailable", "ground"),
                           "s2_unavailable must be 'keep' or 'system1', not 'ground'"),
                          (lambda m: setattr(m.concurrent, "s2_unavailable", "k" * 17),
                           "longer than 16"),
                          (lambda m: setattr(m.concurrent, "reanchor_tol", "wide"),
                           "reanchor_tol must be 'fixed' or 'tube', not 'wide'"),
                          (lambda m: setattr(m.concurrent, "reanchor_tol", "t" * 17),
                           "longer than 16"),
                          (lambda m: setattr(m.concurrent, "reanchor_tol_m", float("nan")),
                           "finite"),
                          (lambda m: m.ClearField("goal"), "without a goal"),
                          (lambda m: setattr(m.forecast, "members", 0), "members must be"),
                          (lambda m: setattr(m.forecast, "members", 10**6), "at most"),
                          (lambda m: setattr(m.forecast, "resolution_m", -1.0), "resolution"),
                          (lambda m: setattr(m.forecast, "horizon_s", float("inf")),
                           "finite"),
                          (lambda m: setattr(m, "system2_time_limit_s", 0.0), "must be > 0"),
                          (lambda m: setattr(m, "system2_time_limit_s", float("nan")),
                           "finite"),
                          (lambda m: setattr(m, "system2_time_limit_s", 1e9), "within")):
        bad = config_pb2.MissionConfig()
        bad.CopyFrom(msg)
        change(bad)
        with pytest.raises(rejections.CodecError, match=match):
            config_convert.config_from_msg(bad)


def test_what_flies_without_system2_crosses_the_wire_and_empty_is_the_default() -> None:
    """``s2_unavailable`` on the wire as its word; a sender that leaves it empty (one built
    before the field) means the default, "keep"."""
    onboard = MissionConfig.named("concurrent", concurrent=ConcurrentParams(
        s2_unavailable="system1"))
    msg = config_convert.config_to_msg(onboard, config_pb2.MissionConfig())
    assert msg.concurrent.s2_unavailable == "system1"
    assert config_convert.config_from_msg(msg).concurrent.s2_unavailable == "system1"
    msg.concurrent.s2_unavailable = ""
    assert config_convert.config_from_msg(msg).concurrent == ConcurrentParams()


def test_the_reanchoring_reading_crosses_the_wire_and_empty_is_the_default() -> None:
    """``reanchor_tol`` on the wire as its word; a sender that leaves it empty (one built
    before the field) means the default, "fixed"."""
    tube = MissionConfig.named("lookahead+risk", concurrent=ConcurrentParams(
        reanchor_tol="tube"))
    msg = config_convert.config_to_msg(tube, config_pb2.MissionConfig())
    assert msg.concurrent.reanchor_tol == "tube"
    assert config_convert.config_from_msg(msg) == tube
    assert _through_the_wire(tube) == tube
    msg.concurrent.reanchor_tol = ""
    assert config_convert.config_from_msg(msg).concurrent.reanchor_tol == "fixed"
    default = config_convert.config_to_msg(MissionConfig(), config_pb2.MissionConfig())
    assert default.concurrent.reanchor_tol == "fixed"
