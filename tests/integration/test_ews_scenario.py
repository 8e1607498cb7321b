"""A fire-behaviour scenario reaches a real EWS: it runs the in-process physics fires exactly.

The reset carries the mission's configuration, whose reading names the fire
process (the setting ``scenario``); a reset without a configuration runs the
paper's process even on an EWS started with ``FIRE_SCENARIO`` (a name of the
supervisor's); an unknown name gets an error reply; the occupancy forecast it
publishes is the in-process one; the EWS warms the fire process of a mission that
asks for forecasts at its reset, before its first forecast.
"""

from __future__ import annotations

import queue
import re
import time
from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import LocalFires
from dualpilot.model.fire import FireParams
from dualpilot.model.fire_field import FireField
from dualpilot.model.forecast import LEVELS, ForecastParams
from dualpilot.model.scenarios import PAPER, SCENARIOS
from dualpilot.spec import MissionSpec, Stream, stream_rng
from services.common import bus, keys, rejections, wire
from services.common.convert import config as config_convert
from services.common.convert import fire as fire_convert
from services.ews.warm import Warmer, warm_process
from services.msgs import fire_pb2
from tests.support.missions import config_for

pytestmark = pytest.mark.timeout(180)

UAV_POS = np.array([500.0, 500.0])
#: (step, sub-steps) per advance, as a mission of S1 and S2 plans asks them
ADVANCES = [(0, 10), (1, 1), (2, 10), (3, 1), (4, 10), (5, 10), (6, 1), (7, 10)]


@pytest.fixture(scope="module")
def ews(services: Any, liveliness: bus.Liveliness) -> Any:
    services.start("ews")
    assert liveliness.wait_for(["ews"], 60), services.log("ews")[-2000:]
    return services


def _send(session: Any, uav: str, cmd: fire_pb2.FireCommand) -> fire_pb2.FireUpdate:
    wire.Stamper("test", uav).stamp(cmd.header)
    payload, enc = bus.request(session, keys.fire_command(uav), cmd, 60.0)
    return wire.parse(payload, fire_pb2.FireUpdate, enc)


def _replay(session: Any, uav: str, mission: str, seed: int, sent: FireParams | None,
            want: FireParams) -> int:
    """Reset (naming ``sent``'s process unless None), advance with a keep-out, compare."""
    cmd = fire_pb2.FireCommand(mission_id=mission)
    cmd.reset.seed = seed
    if sent is not None:
        config_convert.config_to_msg(config_for(MissionSpec(seed=seed), fire=sent),
                                     cmd.reset.config)
    _send(session, uav, cmd)
    field = FireField(params=want)
    rng = stream_rng(seed, Stream.FIRE)
    keep = (UAV_POS, 20.0)
    compared = 0
    for t, n in ADVANCES:
        cmd = fire_pb2.FireCommand(mission_id=mission)
        cmd.advance.step, cmd.advance.substeps = t, n
        cmd.advance.keep_out.east_m, cmd.advance.keep_out.north_m = UAV_POS
        cmd.advance.keep_out_m = keep[1]
        update = _send(session, uav, cmd)
        assert len(update.states) == n
        for state in update.states:
            field.substep(rng, t, keep_out=keep)
            got, exp = fire_convert.snapshot_from_msg(state), field.snapshot()
            assert got.regions == exp.regions
            assert got.front_ids == exp.front_ids and got.born_steps == exp.born_steps
            assert all(np.array_equal(a.vertices, b.vertices)
                       for a, b in zip(got.hulls, exp.hulls, strict=True))
            compared += 1
    assert (field.physics is not None) == (want.scenario != PAPER), "the fire process"
    assert field.next_id > 0, "the seed should give some fires"
    return compared


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_each_scenario_runs_on_the_ews_sub_step_for_sub_step(ews: Any, session: Any,
                                                             name: str) -> None:
    fire = FireParams(scenario=name)
    assert _replay(session, ews.uav, f"scenario-{name}", 26, fire, fire) == sum(
        n for _, n in ADVANCES)


def test_a_scenario_forecast_is_the_in_process_fire_ports_byte_for_byte(
        ews: Any, session: Any) -> None:
    """After every command the EWS publishes the scenario's occupancy forecast (its level set
    run ahead, dualpilot/model/physics_forecast.py): the grid the in-process fire port gives
    from the same fire state, serialised byte for byte."""
    got: queue.Queue[fire_pb2.FireForecast] = queue.Queue()
    sub = session.declare_subscriber(keys.forecast(ews.uav), lambda s: got.put(
        fire_pb2.FireForecast.FromString(s.payload.to_bytes())))
    fire = FireParams(scenario="grass-15")
    seed = 26
    _replay(session, ews.uav, "scenario-forecast", seed, fire, fire)
    local = LocalFires(MissionSpec(seed=seed), fire)
    keep = (UAV_POS, 20.0)
    want: list[bytes] = [_grid(local, 1)]  # after the reset
    for t, n in ADVANCES:
        local.advance(t, n, keep)
        want.append(_grid(local, n))
    seen: list[fire_pb2.FireForecast] = []
    deadline = time.monotonic() + 30
    while len(seen) < len(want) and time.monotonic() < deadline:
        try:
            seen.append(got.get(timeout=0.5))
        except queue.Empty:
            continue
    sub.undeclare()
    assert [m.substeps_done for m in seen] == [0, *np.cumsum([n for _, n in ADVANCES])]
    assert [m.occupancy.SerializeToString() for m in seen] == want
    last = fire_convert.occupancy_from_msg(seen[-1])
    assert last is not None and last.horizons[-1] == 80 and seen[-1].occupancy.horizon_s == 40.0
    burning = (last.level(0) == LEVELS).sum()
    assert 0 < burning < (last.level(len(last.horizons) - 1) == LEVELS).sum(), (
        "the fires should burn and grow over the horizon")


def _grid(local: LocalFires, n: int) -> bytes:
    fc = local.forecast(n)
    assert fc is not None
    return fire_convert.occupancy_to_msg(fc, fire_pb2.OccupancyGrid()).SerializeToString()


def test_a_reset_naming_no_scenario_runs_the_paper_process_not_the_environment(
        services: Any, session: Any) -> None:
    """FIRE_SCENARIO is the supervisor's (services/common/mission_env.py): an EWS started with it
    still runs the default configuration's paper process for a reset without a configuration."""
    uav = "itestgrass"
    services.start("ews-grass", module="services.ews", UAV_ID=uav, FIRE_SCENARIO="grass-5")
    assert bus.Liveliness(session, uav).wait_for(["ews"], 60), services.log("ews-grass")[-2000:]
    _replay(session, uav, "no-scenario", 26, None, FireParams())


def _scenario_reset(name: str) -> fire_pb2.FireCommand:
    """A reset whose configuration names the fire process ``name`` (any text, on the wire)."""
    cmd = fire_pb2.FireCommand(mission_id="bad-scenario")
    cmd.reset.seed = 1
    config_convert.config_to_msg(MissionConfig(seed=1), cmd.reset.config)
    cmd.reset.config.settings.add(name="scenario", value=name)
    return cmd


def test_an_unknown_scenario_gets_an_error_reply(ews: Any, session: Any) -> None:
    with pytest.raises(bus.QueryError, match="scenario must be one of .* not 'tundra'"):
        _send(session, ews.uav, _scenario_reset("tundra"))


def test_the_reset_carries_the_scenario_and_the_codec_checks_it() -> None:
    def sent(fire: FireParams) -> str:
        cmd = fire_pb2.FireCommand(mission_id="m")
        config_convert.config_to_msg(config_for(MissionSpec(), fire=fire), cmd.reset.config)
        config = fire_convert.fire_command_from_msg(cmd).config
        assert config is not None
        return config.reading().fire.scenario

    assert sent(FireParams(scenario="shrub")) == "shrub"
    assert sent(FireParams()) == "paper"
    cmd = fire_pb2.FireCommand(mission_id="m")
    cmd.reset.seed = 1
    assert fire_convert.fire_command_from_msg(cmd).config is None  # the default
    for bad, match in (("tundra", "scenario must be one of"), ("x" * 257, "longer than 256")):
        with pytest.raises(rejections.CodecError, match=match):
            fire_convert.fire_command_from_msg(_scenario_reset(bad))


def test_every_fire_process_can_be_warmed() -> None:
    """warm_process makes one forecast of the paper's process and of each named scenario (from
    its first front)."""
    for name in ["paper", *SCENARIOS]:
        assert warm_process(FireParams(scenario=name), ForecastParams(members=4)) > 0, name


def test_a_warmer_warms_each_fire_process_once() -> None:
    warmer = Warmer()
    grass, shrub = FireParams(scenario="grass-15"), FireParams(scenario="shrub", substep_s=0.25)
    grid = ForecastParams(members=4)
    assert warmer.start(grass, grid) and warmer.start(shrub, grid)
    assert not warmer.start(replace(grass, substep_s=0.25), grid)  # the same process
    warmer.wait(FireParams())  # never started: returns at once
    warmer.wait(grass)
    warmer.wait(shrub)
    assert warmer.started() == ["grass-15", "shrub"]
    assert set(warmer.took) == {"grass-15", "shrub"} and all(s > 0 for s in warmer.took.values())


def _forecast(session: Any, uav: str, mission: str, substeps_done: int) -> fire_pb2.FireForecast:
    cmd = fire_convert.fire_forecast_query_msg(mission, 0, substeps_done, 10,
                                               wire.Stamper("test", uav), 0.0)
    return _send(session, uav, cmd).forecast


def _reset_and_forecast(session: Any, uav: str, mission: str, controller: str,
                        scenario: str) -> None:
    cmd = fire_pb2.FireCommand(mission_id=mission)
    cmd.reset.seed = 26
    config_convert.config_to_msg(config_for(MissionSpec(seed=26), controller,
                                            fire=FireParams(scenario=scenario)),
                                 cmd.reset.config)
    _send(session, uav, cmd)
    assert _forecast(session, uav, mission, 0).occupancy.horizon_s > 0


def test_the_ews_warms_the_fire_process_of_a_mission_that_asks_for_forecasts(
        services: Any, session: Any) -> None:
    """The EWS announces itself without warming any forecast; a reset of a risk-aware mission
    warms that mission's fire process (and no other), once a process, and its first forecast
    is answered only once the warm-up is done: the mission's first forecast is not the
    process's first. A mission that asks for none (and nobody listening) warms nothing."""
    uav, name = "itestwarm", "ews-warm"
    services.start(name, module="services.ews", UAV_ID=uav)
    assert bus.Liveliness(session, uav).wait_for(["ews"], 60), services.log(name)[-2000:]

    def warmed() -> list[str]:
        return re.findall(r"forecast warmed .*scenario=(\S+)", services.log(name))

    assert warmed() == []
    _reset_and_forecast(session, uav, "warm-cc", "cc", "grass-5")  # asks none: no warm-up
    assert warmed() == []
    _reset_and_forecast(session, uav, "warm-risk", "s1+risk", "grass-15")
    assert warmed() == ["grass-15"]  # logged before the forecast was answered
    _reset_and_forecast(session, uav, "warm-again", "s2+risk", "grass-15")
    assert warmed() == ["grass-15"]
