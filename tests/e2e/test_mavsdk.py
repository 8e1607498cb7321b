"""MAVSDK-Python (``mavsdk<4``, the gRPC API) as a real offboard client of uavsim, per flavour.

For each ``--autopilot`` (px4, ardupilot) a vehicle runs on its own (no
Zenoh router) with the real-time clock, and MAVSDK (its ``mavsdk_server``
ships in the wheel) connects to the offboard port on loopback: discovery,
telemetry with the flavour's flight-mode name, parameters (a refused set
too), ``mission_raw``, the action plugin, offboard ``set_position_ned`` +
``start`` (GUIDED for ArduPilot) flown in the time Eq. (1) needs, and the
offboard-loss failsafe (the mavsdk_server process stopped, then resumed).
"""

from __future__ import annotations

import asyncio
import os
import signal
import sys
import time
from collections.abc import Awaitable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import pytest

from services.common import mav
from services.launch import REPO, ProcessGroup, free_port
from services.uavsim import flavour as fl
from services.uavsim.vehicle import Vehicle

mavsdk = pytest.importorskip("mavsdk")
from mavsdk import System  # noqa: E402
from mavsdk.action import ActionError  # noqa: E402
from mavsdk.mission_raw import MissionItem  # noqa: E402
from mavsdk.offboard import PositionNedYaw  # noqa: E402
from mavsdk.param import ParamError  # noqa: E402
from mavsdk.telemetry import FlightMode  # noqa: E402

pytestmark = pytest.mark.timeout(180)
m = mav.mavlink
T = TypeVar("T")
SPEED = 5.0       # simulated s per wall s
START = (50.0, 50.0)
HOME = (35.0, 33.0)


@dataclass
class Rig:
    flavour: str
    loop: asyncio.AbstractEventLoop
    drone: Any
    gcs: Any          # a pymavlink observer on the ground-station port
    group: ProcessGroup
    log: Path

    def run(self, aw: Awaitable[T], timeout_s: float = 30.0) -> T:
        return self.loop.run_until_complete(asyncio.wait_for(aw, timeout_s))


async def first(gen: Any, pred: Any = lambda _x: True) -> Any:
    async for item in gen:
        if pred(item):
            return item
    raise AssertionError("stream ended")


def observer(port: int) -> Any:
    conn = mav.connect(f"udpout:127.0.0.1:{port}", 254, 190)
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:  # udpout speaks first; the vehicle answers at once
        conn.mav.heartbeat_send(m.MAV_TYPE_GCS, m.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        if conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5) is not None:
            return conn
    raise TimeoutError("no vehicle heartbeat on the GCS port")


def wait_hold(gcs: Any, flavour: fl.Flavour, timeout_s: float) -> float:
    """Wall time until a HEARTBEAT reports the flavour's hold mode."""
    t0 = time.monotonic()
    deadline = t0 + timeout_s
    while time.monotonic() < deadline:
        gcs.mav.heartbeat_send(m.MAV_TYPE_GCS, m.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        hb = gcs.recv_match(type="HEARTBEAT", blocking=True, timeout=0.2)
        if hb is not None and hb.custom_mode == flavour.custom_mode(fl.HOLD):
            return time.monotonic() - t0
    raise TimeoutError("no hold heartbeat")


@pytest.fixture(scope="module", params=["px4", "ardupilot"])
def rig(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Rig]:
    flavour = str(request.param)
    logs = tmp_path_factory.mktemp(f"mavsdk-{flavour}")
    offboard, gcs_port = free_port("udp"), free_port("udp")
    env = {k: v for k, v in os.environ.items() if not k.startswith("ZENOH")}
    env.update(PYTHONPATH=str(REPO), PYTHONUNBUFFERED="1", LOG_FORMAT="text", LOG_LEVEL="INFO")
    group = ProcessGroup()
    group.start("uavsim", [sys.executable, "-m", "services.uavsim",
                           "--mavlink-url", f"udpin:127.0.0.1:{offboard}",
                           "--gcs-url", f"udpin:127.0.0.1:{gcs_port}",
                           "--autopilot", flavour, "--clock", "realtime",
                           "--speed-factor", str(SPEED), "--start", f"{START[0]},{START[1]}",
                           "--home", f"{HOME[0]},{HOME[1]}"], env, logs / "uavsim.log")
    loop = asyncio.new_event_loop()
    drone = System(port=free_port("tcp"))
    gcs = None
    try:
        gcs = observer(gcs_port)
        loop.run_until_complete(asyncio.wait_for(
            drone.connect(system_address=f"udpout://127.0.0.1:{offboard}"), 30))
        yield Rig(flavour, loop, drone, gcs, group, logs / "uavsim.log")
    finally:
        drone._stop_mavsdk_server()
        loop.close()
        if gcs is not None:
            gcs.close()
        codes = group.stop_all()
        assert codes.get("uavsim") == 0, (logs / "uavsim.log").read_text()[-3000:]


def test_discovery_telemetry_and_version(rig: Rig) -> None:
    d = rig.drone
    rig.run(first(d.core.connection_state(), lambda s: s.is_connected))
    assert rig.run(first(d.telemetry.flight_mode())) == FlightMode.HOLD
    health = rig.run(first(d.telemetry.health(), lambda h: h.is_armable))
    assert health.is_global_position_ok and health.is_home_position_ok
    assert rig.run(first(d.telemetry.in_air())) is False
    pos = rig.run(first(d.telemetry.position_velocity_ned()))
    assert (pos.position.north_m, pos.position.east_m) == (START[1], START[0])
    version = rig.run(d.info.get_version())  # REQUEST_MESSAGE AUTOPILOT_VERSION, NaN params
    assert (version.flight_sw_major, version.flight_sw_minor) == (0, 1)
    rig.run(d.telemetry.set_rate_position_velocity_ned(20.0))  # SET_MESSAGE_INTERVAL
    assert "not_finite" not in rig.log.read_text()


def test_params_get_set_and_refused(rig: Rig) -> None:
    p = rig.drone.param
    assert rig.run(p.get_param_float("MPC_XY_VEL_MAX")) == 15.0
    rig.run(p.set_param_float("COM_OF_RSM_T", 0.25))
    assert rig.run(p.get_param_float("COM_OF_RSM_T")) == 0.25
    with pytest.raises(ParamError):  # out of range: answered at once with the old value
        rig.run(p.set_param_float("MPC_XY_VEL_MAX", 40.0), 10)
    assert rig.run(p.get_param_float("MPC_XY_VEL_MAX")) == 15.0


def test_mission_raw_round_trip(rig: Rig) -> None:
    mr = rig.drone.mission_raw
    lat, lon = mav.to_geodetic(300.0, 400.0, HOME)
    items = [MissionItem(k, m.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, m.MAV_CMD_NAV_WAYPOINT,
                         int(k == 0), 1, 0.0, 5.0, 0.0, float("nan"),
                         int((lat + k * 1e-3) * 1e7), int(lon * 1e7), 50.0, 0)
             for k in range(2)]
    rig.run(mr.upload_mission(items))
    got = rig.run(mr.download_mission())
    assert [(g.seq, g.frame, g.command, g.x, g.y, g.z) for g in got] == \
        [(i.seq, i.frame, i.command, i.x, i.y, i.z) for i in items]
    rig.run(mr.clear_mission())
    assert rig.run(mr.download_mission()) == []


def test_arm_takeoff_hold_land_disarm(rig: Rig) -> None:
    d = rig.drone
    rig.run(d.action.arm())
    rig.run(d.action.disarm())  # on the ground: accepted
    if rig.flavour == "ardupilot":
        # MAVSDK's ArduPilot take-off switches to GUIDED first, which (as PX4's OFFBOARD)
        # needs a live setpoint stream: the GUIDED equivalent of the sequence
        pos = rig.run(first(d.telemetry.position_velocity_ned())).position
        rig.run(d.offboard.set_position_ned(PositionNedYaw(pos.north_m, pos.east_m, -50, 0)))
        rig.run(d.offboard.start())
    rig.run(d.action.arm())
    rig.run(d.action.takeoff())
    assert rig.run(first(d.telemetry.in_air(), bool)) is True
    with pytest.raises(ActionError):
        rig.run(d.action.disarm())  # in the air: denied
    rig.run(d.action.hold())
    assert rig.run(first(d.telemetry.flight_mode(), lambda f: f == FlightMode.HOLD))
    if rig.flavour == "ardupilot":
        rig.run(d.offboard.stop())
    rig.run(d.action.land())
    assert rig.run(first(d.telemetry.in_air(), lambda a: not a)) is False
    rig.run(d.action.disarm())
    assert rig.run(first(d.telemetry.armed(), lambda a: not a)) is False


def steps_to_reach(start: tuple[float, float], goal: tuple[float, float], tol_m: float) -> int:
    """Eq. (1) steps the vehicle's controller needs to come within ``tol_m`` of ``goal``."""
    v = Vehicle.at(*start)
    target = np.array([goal[0], goal[1], 0.0, 0.0])
    for k in range(1, 200):
        v.apply(target, k * 1000)
        if np.hypot(*(v.state[:2] - target[:2])) < tol_m:
            return k
    raise AssertionError("never reached")


def test_offboard_flies_to_a_point_in_the_time_the_dynamics_need(rig: Rig) -> None:
    d = rig.drone
    pos = rig.run(first(d.telemetry.position_velocity_ned())).position
    east, north = pos.east_m, pos.north_m
    goal = (east, north + 100.0)
    rig.run(d.action.arm())
    rig.run(d.offboard.set_position_ned(PositionNedYaw(goal[1], goal[0], -50.0, 0.0)))
    t0 = time.monotonic()
    rig.run(d.offboard.start())  # OFFBOARD (px4) or GUIDED (ardupilot): streamed first
    assert rig.run(first(d.telemetry.flight_mode(), lambda f: f == FlightMode.OFFBOARD))
    rig.run(first(d.telemetry.position_velocity_ned(),
                  lambda p: abs(p.position.north_m - goal[1]) < 2.0), 60)
    wall = time.monotonic() - t0
    expected = steps_to_reach((east, north), goal, 2.0) / SPEED
    assert 0.6 * expected <= wall <= 1.5 * expected + 1.0, (wall, expected)


def test_offboard_loss_failsafe_holds_then_the_stream_resumes(rig: Rig) -> None:
    d = rig.drone
    flavour = fl.FLAVOURS[rig.flavour]
    assert rig.run(first(d.telemetry.flight_mode())) == FlightMode.OFFBOARD
    pid = d._server_process.pid
    os.kill(pid, signal.SIGSTOP)  # the offboard client freezes: no more setpoints
    try:
        held_after = wait_hold(rig.gcs, flavour, 10)
    finally:
        os.kill(pid, signal.SIGCONT)
    assert held_after <= 1.0 + 1.5  # COM_OF_LOSS_T = 1 s (wall), plus a heartbeat period
    # the stream is back: after COM_OF_RSM_T the setpoints take control again
    assert rig.run(first(d.telemetry.flight_mode(), lambda f: f == FlightMode.OFFBOARD), 15)
    rig.run(d.offboard.stop())
    rig.run(d.action.land())
    rig.run(d.action.disarm())
