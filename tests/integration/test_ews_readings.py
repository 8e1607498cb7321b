"""Each profile's fire readings reach a real EWS: it runs the in-process fire process exactly.

The reset carries the mission's configuration (its profile and settings: the
reading); the advances carry the step number (a new one starts a time-step) and
the ignition clearance as a keep-out. The EWS has no reading of its own: a
reset that carries no configuration runs the default configuration's fire
process, whatever the EWS's environment says (``READINGS_PROFILE`` is the
supervisor's, services/common/mission_env.py).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.model.fire import FireParams
from dualpilot.model.fire_field import FireField
from dualpilot.readings import PROFILES, get_profile
from dualpilot.spec import Stream, stream_rng
from services.common import bus, keys, wire
from services.common.convert import config as config_convert
from services.common.convert import fire as fire_convert
from services.msgs import fire_pb2

pytestmark = pytest.mark.timeout(120)

UAV_POS = np.array([500.0, 500.0])
#: (step, sub-steps) per advance: S2 waits, S1 steps, and a step advanced sub-step by sub-step
#: (as the mission does under the failure rules other than "any")
ADVANCES = [(0, 10), (1, 1), (2, 10), (3, 1), (3, 1), (3, 1), (4, 10), (5, 10), (6, 1), (7, 10)]


@pytest.fixture(scope="module")
def ews(services: Any, liveliness: bus.Liveliness) -> Any:
    services.start("ews")
    assert liveliness.wait_for(["ews"], 60), services.log("ews")[-2000:]
    return services


def _send(session: Any, uav: str, cmd: fire_pb2.FireCommand) -> fire_pb2.FireUpdate:
    wire.Stamper("test", uav).stamp(cmd.header)
    payload, enc = bus.request(session, keys.fire_command(uav), cmd, 30.0)
    return wire.parse(payload, fire_pb2.FireUpdate, enc)


def _replay(session: Any, uav: str, mission: str, seed: int, config: MissionConfig | None,
            clearance: float | None, want: FireParams) -> int:
    """Reset (with ``config`` unless None), advance, compare every sub-step."""
    cmd = fire_pb2.FireCommand(mission_id=mission)
    cmd.reset.seed = seed
    if config is not None:
        config_convert.config_to_msg(config, cmd.reset.config)
    _send(session, uav, cmd)
    field = FireField(params=want)
    rng = stream_rng(seed, Stream.FIRE)
    keep = None if clearance is None else (UAV_POS, clearance)
    compared = 0
    for t, n in ADVANCES:
        cmd = fire_pb2.FireCommand(mission_id=mission)
        cmd.advance.step, cmd.advance.substeps = t, n
        if keep is not None:
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
    assert field.next_id > 0, "the seed should give some fires"
    return compared


@pytest.mark.parametrize("name", list(PROFILES))
def test_each_profile_runs_on_the_ews_sub_step_for_sub_step(ews: Any, session: Any,
                                                            name: str) -> None:
    p = get_profile(name)
    n = _replay(session, ews.uav, f"profile-{name}", 26, MissionConfig(profile=name, seed=26),
                p.mission.ignition_clearance_m, p.fire)
    assert n == sum(k for _, k in ADVANCES)


def test_readings_differ_so_the_comparison_means_something(ews: Any, session: Any) -> None:
    """The fig-r5 EWS process is not today's: the same seed gives other regions."""
    a = FireField(params=get_profile("fig-r5").fire)
    b = FireField(params=get_profile("today").fire)
    ra, rb = stream_rng(26, Stream.FIRE), stream_rng(26, Stream.FIRE)
    for t, n in ADVANCES:
        for _ in range(n):
            a.substep(ra, t)
            b.substep(rb, t)
    assert a.snapshot().regions != b.snapshot().regions


def test_a_reset_without_readings_runs_the_default_not_the_environment(services: Any,
                                                                       session: Any) -> None:
    """An EWS whose environment names the literal profile still runs today's (the default
    configuration's) fire process for a reset without a configuration: the environment's
    mission names are the supervisor's alone."""
    uav = "itestlit"
    services.start("ews-literal", module="services.ews", UAV_ID=uav, READINGS_PROFILE="literal",
                   FIRE_LIFE_BASE="step", FIRE_EXTENT="birth")
    assert bus.Liveliness(session, uav).wait_for(["ews"], 60), services.log("ews-literal")[-2000:]
    assert get_profile("literal").fire != MissionConfig().reading().fire
    _replay(session, uav, "no-readings", 26, None, None, MissionConfig().reading().fire)


def test_bad_readings_get_an_error_reply(ews: Any, session: Any) -> None:
    cmd = fire_pb2.FireCommand(mission_id="bad")
    cmd.reset.seed = 1
    config_convert.config_to_msg(MissionConfig(seed=1), cmd.reset.config)
    cmd.reset.config.settings.add(name="extent", value="42")
    with pytest.raises(bus.QueryError, match="extent takes one of"):
        _send(session, ews.uav, cmd)
