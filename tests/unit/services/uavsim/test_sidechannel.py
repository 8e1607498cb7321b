"""uavsim's side channels (services/uavsim/sidechannel.py) on a real Zenoh session of their own.

One peer session with no endpoints and no scouting queries its own queryables: a query waits
in the inbox until the vehicle's loop polls; then it gets its answer, or the error reply of
what was refused (a bad request counted per key and reason, an unavailable one not).
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import numpy as np
import pytest
import zenoh

from dualpilot.mission.config import MissionConfig
from dualpilot.model.dynamics import DynamicsParams, step
from services.common import bus, keys, rejections, wire
from services.common.convert import config as config_convert
from services.common.convert import plant as plant_convert
from services.msgs import common_pb2, config_pb2, plant_pb2
from services.uavsim.autopilot import VehicleSetup
from services.uavsim.clock import LOCKSTEP
from services.uavsim.endpoint import Endpoint
from services.uavsim.missionconfig import MissionConfigs, fly_plant, mission_configs
from services.uavsim.sidechannel import SideChannel
from services.uavsim.truth import flight_truths
from services.uavsim.vehicle import Vehicle
from tests.support.vehicles import HOME, HOME_AMSL_M

UAV = "side1"
STAMPER = wire.Stamper("test", UAV)
PLANT = (("plant", "multirotor"), ("wind_speed_mps", 5.0))


@pytest.fixture
def session() -> Iterator[zenoh.Session]:
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", "[]")
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("scouting/gossip/enabled", "false")
    with zenoh.open(conf) as s:
        yield s


def ask(session: zenoh.Session, channel: SideChannel, payload: bytes,
        encoding: zenoh.Encoding) -> zenoh.Reply:
    """Send one query, wait (at most 5 s) until it is in the channel's inbox, poll, and
    return its reply."""
    replies = session.get(channel.key, payload=payload, encoding=encoding, timeout=5.0,
                          attachment=str(session.info.zid()).encode())
    deadline = time.monotonic() + 5.0
    while channel.inbox.q.qsize() == 0:
        assert time.monotonic() < deadline, "the query never reached the inbox"
        time.sleep(0.001)
    assert replies.try_recv() is None  # nothing answers before the vehicle's loop polls
    channel.poll()
    reply: zenoh.Reply = replies.recv()
    return reply


def error_of(reply: zenoh.Reply) -> common_pb2.Error:
    assert reply.ok is None and reply.err is not None
    return wire.parse(reply.err.payload.to_bytes(), common_pb2.Error)


def counted(key: str) -> dict[str, int]:
    return rejections.REJECTED.snapshot().get(key, {})


def test_the_truth_channel_answers_from_the_loop_and_counts_only_bad_requests(
        session: zenoh.Session) -> None:
    v = Vehicle.at(50.0, 50.0)
    channel = flight_truths(session, UAV, v)
    key = keys.sim_flight(UAV)
    req = plant_convert.request_msg(1000, STAMPER)
    enc = bus.encoding(req)
    try:
        before = counted(key)
        ideal = error_of(ask(session, channel, req.SerializeToString(), enc))
        assert ideal.code == common_pb2.ERROR_CODE_UNAVAILABLE and "ideal plant" in ideal.message
        bad = error_of(ask(session, channel, b"\xff\x00garbage", enc))
        assert bad.code == common_pb2.ERROR_CODE_MALFORMED
        after = counted(key)
        assert sum(after.values()) == sum(before.values()) + 1  # the bad request only
        assert after.get("malformed", 0) == before.get("malformed", 0) + 1
        assert after.get("unavailable", 0) == before.get("unavailable", 0)
        fly_plant(v, MissionConfig.named("cc", seed=3, settings=PLANT), own_clock=False)
        v.apply(step(v.state, np.array([5.0, -5.0]), DynamicsParams()), 1000)
        reply = ask(session, channel, req.SerializeToString(), enc)
        assert reply.ok is not None
        got = plant_convert.flight_from_msg(wire.parse(reply.ok.payload.to_bytes(),
                                                       plant_pb2.PlantFlight))
        assert v.plant is not None
        assert got.time_ms == 1000 and got.flights == 1
        assert np.array_equal(got.path, v.plant.truth().path)
    finally:
        channel.close()


def test_the_mission_channel_takes_a_configuration_from_the_supervisor_only(
        session: zenoh.Session) -> None:
    setup = VehicleSetup(sysid=1, altitude_m=50.0, home=HOME, offboard_loss_s=1.0,
                         clock=LOCKSTEP, home_amsl_m=HOME_AMSL_M)
    ep = Endpoint(Vehicle.at(100.0, 100.0), {}, setup, boot=0.0)
    configs = MissionConfigs(UAV, ep, bus.Liveliness(session, UAV))
    channel = mission_configs(session, configs)
    key = keys.sim_mission(UAV)
    msg = MissionConfig(settings=(("dim", 3),))
    try:
        before = counted(key).get("invalid", 0)
        wire_msg = config_convert.config_to_msg(msg, config_pb2.MissionConfig())
        err = error_of(ask(session, channel, wire_msg.SerializeToString(),
                           bus.encoding(wire_msg)))
        assert err.code == common_pb2.ERROR_CODE_INVALID
        assert "not from this vehicle's supervisor (none)" in err.message
        assert counted(key).get("invalid", 0) == before + 1
        assert ep.vehicle.dyn.dim == 2  # not taken
        zid = str(session.info.zid())
        token = session.liveliness().declare_token(keys.holder(UAV, "supervisor", zid))
        deadline = time.monotonic() + 5.0
        while configs.live.holder("supervisor") != zid:
            assert time.monotonic() < deadline, "the supervisor's token was never seen"
            time.sleep(0.001)
        reply = ask(session, channel, wire_msg.SerializeToString(), bus.encoding(wire_msg))
        assert reply.ok is not None
        took = config_convert.config_from_msg(wire.parse(reply.ok.payload.to_bytes(),
                                                         config_pb2.MissionConfig))
        assert took == msg
        assert ep.vehicle.dyn.dim == 3 and ep.vehicle.state.shape == (6,)
        assert counted(key).get("invalid", 0) == before + 1
        token.undeclare()
    finally:
        channel.close()
