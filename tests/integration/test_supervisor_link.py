"""The supervisor's offboard link against a real uavsim (and a scripted vehicle for refusals).

MAVSDK/PX4 order (heartbeat, position, setpoints, offboard, arm) with each
flavour's mode numbers, read from the vehicle's HEARTBEAT (PX4: OFFBOARD
main mode 6, refused without a setpoint stream; ArduPilot: GUIDED 4, which
needs none), refused commands retried then given up cleanly, a vehicle that
disappears for more than 3 s and comes back, and the operator's mission
downloaded and converted to the local frame.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from services.common import bus, mav, mavmodes
from services.launch import free_port
from services.supervisor.link import LinkParams, OffboardError, VehicleLink

pytestmark = pytest.mark.timeout(120)
m = mav.mavlink
HOME = (35.1450, 33.4110)


@pytest.fixture(scope="module", params=["ardupilot", "px4"])
def vehicle(request: pytest.FixtureRequest, services: Any, session: Any) -> Any:
    flavour = str(request.param)
    ports = {"offboard": free_port("udp"), "gcs": free_port("udp")}
    uav = f"itest-link-{flavour}"
    proc = services.start(f"uavsim-{flavour}", module="services.uavsim", UAV_ID=uav,
                          MAVLINK_URL=f"udpin:127.0.0.1:{ports['offboard']}",
                          GCS_URL=f"udpin:127.0.0.1:{ports['gcs']}", UAV_START="80,90",
                          UAV_AUTOPILOT=flavour, UAV_HOME=f"{HOME[0]},{HOME[1]}")
    link_live = bus.Liveliness(session, uav)
    assert link_live.wait_for(["uavsim"], 60), services.log(f"uavsim-{flavour}")[-2000:]
    services.link_ports, services.link_proc, services.flavour = ports, proc, flavour
    yield services
    services.group.stop(proc)
    services.group.procs.remove(proc)


@pytest.fixture()
def link(vehicle: Any) -> Iterator[VehicleLink]:
    lk = VehicleLink(LinkParams(f"udpout:127.0.0.1:{vehicle.link_ports['offboard']}"))
    lk.start()
    try:
        yield lk
    finally:
        lk.close()


def until(pred: Any, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(0.02)
    return bool(pred())


def test_offboard_start_and_a_vehicle_that_disappears(vehicle: Any, link: VehicleLink) -> None:
    stop = threading.Event()
    assert link.status.wait_vehicle(20, stop)
    if vehicle.flavour == "px4":  # PX4's OFFBOARD needs the setpoint stream first
        assert link.status.modes == mavmodes.PX4_MODES
        assert link.commands.command(m.MAV_CMD_DO_SET_MODE, m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                            6, 0) == m.MAV_RESULT_TEMPORARILY_REJECTED
        offboard = "OFFBOARD, armed"
    else:  # ArduPilot's GUIDED holds without one
        assert link.status.modes == mavmodes.ARDUPILOT_MODES
        offboard = "GUIDED, armed"
    link.takeover.start_offboard(stop, timeout_s=20)
    assert link.status.offboard() and link.status.status() == offboard
    assert [(c.mode, c.armed) for c in link.status.mode_changes][-2:] == [
        (offboard.split(",")[0], False), (offboard.split(",")[0], True)]
    t, x = link.position.wait_state(0, 5, stop) or (0, None)
    assert x is not None and np.allclose(x[:2], [80.0, 90.0])
    assert link.position.origin is not None and np.allclose(link.position.origin, HOME)

    pid = vehicle.link_proc.popen.pid
    os.kill(pid, signal.SIGSTOP)  # the vehicle disappears
    try:
        t0 = time.monotonic()
        assert until(lambda: not link.status.alive(), 30), "the link never counted the vehicle lost"
        # not before lost_after_s (3 s) less one heartbeat period (1 s) since the last one heard:
        # a lower bound (the rule itself, on injected times:
        # tests/unit/services/supervisor/link/test_liveness.py)
        assert time.monotonic() - t0 >= 3.0 - 1.0 - 0.05 and not link.status.offboard()
    finally:
        os.kill(pid, signal.SIGCONT)
    # back (a frozen process finds the queued setpoints first, so its failsafe may not trip)
    assert until(link.status.alive, 30), "the vehicle never came back after SIGCONT"
    assert until(link.status.offboard, 30), link.status.status()
    sent: list[int] = []
    command = link.commands.command

    def counted(cmd: int, *params: float, **kw: Any) -> int:
        sent.append(cmd)
        return command(cmd, *params, **kw)

    link.commands.command = counted  # type: ignore[method-assign]
    link.takeover.start_offboard(stop, timeout_s=5)  # nothing left to do: no command sent
    assert sent == [], sent


def test_operator_mission_is_downloaded_in_the_local_frame(vehicle: Any,
                                                           link: VehicleLink) -> None:
    stop = threading.Event()
    assert link.mission.wait_downloaded(10, stop)
    rev0, wps, _ = link.mission.operator_waypoints()
    gcs = mav.connect(f"udpout:127.0.0.1:{vehicle.link_ports['gcs']}", 255, 190)
    gcs.mav.heartbeat_send(m.MAV_TYPE_GCS, m.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    local = [(200.0, 300.0), (650.5, 720.25)]
    items = []
    for seq, (e, n) in enumerate(local):
        lat, lon = mav.to_geodetic(e, n, HOME)
        items.append(m.MAVLink_mission_item_int_message(
            1, 1, seq, m.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, m.MAV_CMD_NAV_WAYPOINT, 0, 1,
            0, 0, 0, 0, round(lat * 1e7), round(lon * 1e7), 50.0, 0))
    gcs.mav.mission_count_send(1, 1, len(items), 0)
    deadline = time.monotonic() + 10
    ack = None
    while ack is None and time.monotonic() < deadline:
        msg = gcs.recv_match(type=["MISSION_REQUEST_INT", "MISSION_ACK"], blocking=True,
                             timeout=0.2)
        if msg is not None and msg.get_type() == "MISSION_REQUEST_INT":
            gcs.mav.send(items[msg.seq])
        elif msg is not None:
            ack = msg
    assert ack is not None and ack.type == m.MAV_MISSION_ACCEPTED
    gcs.close()
    assert until(lambda: link.mission.operator_waypoints()[0] > rev0, 10)
    _, wps, mission_id = link.mission.operator_waypoints()
    assert mission_id and wps is not None
    assert np.allclose(wps, local, atol=0.05)  # degE7 is ≈ 1 cm


class ScriptedVehicle:
    """A pymavlink vehicle that answers DO_SET_MODE DENIED ``deny_mode`` times, then ACCEPTED,
    and the arm command with ``arm_result``."""

    def __init__(self, port: int, deny_mode: int, arm_result: int):
        self.conn = mav.connect(f"udpin:127.0.0.1:{port}", 1, 1)
        self.deny_mode, self.arm_result = deny_mode, arm_result
        self.mode, self.armed = mav.MODE_LOITER, False
        self.commands: list[tuple[int, int]] = []
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self) -> None:
        next_t = 0.0
        while not self.stop.is_set():
            if time.monotonic() >= next_t and self.conn.clients:
                base = m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (
                    m.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0)
                self.conn.mav.heartbeat_send(m.MAV_TYPE_QUADROTOR,
                                             m.MAV_AUTOPILOT_ARDUPILOTMEGA, base, self.mode,
                                             m.MAV_STATE_ACTIVE)
                self.conn.mav.local_position_ned_send(0, 10.0, 20.0, -50.0, 0, 0, 0)
                self.conn.mav.global_position_int_send(0, 351450000, 334110000, 50000, 50000,
                                                       0, 0, 0, 0)
                next_t = time.monotonic() + 0.1
            msg = self.conn.recv_match(blocking=True, timeout=0.05)
            if msg is None or msg.get_type() != "COMMAND_LONG":
                continue
            self.commands.append((int(msg.command), int(msg.confirmation)))
            if msg.command == m.MAV_CMD_DO_SET_MODE:
                result = m.MAV_RESULT_DENIED if self.deny_mode > 0 else m.MAV_RESULT_ACCEPTED
                self.deny_mode -= 1
                if result == m.MAV_RESULT_ACCEPTED:
                    self.mode = int(msg.param2)
            elif msg.command == m.MAV_CMD_COMPONENT_ARM_DISARM:
                result = self.arm_result
                self.armed = result == m.MAV_RESULT_ACCEPTED
            else:
                continue
            self.conn.mav.command_ack_send(msg.command, result, 0, 0, msg.get_srcSystem(),
                                           msg.get_srcComponent())

    def close(self) -> None:
        self.stop.set()
        self.thread.join(2)
        self.conn.close()


@pytest.mark.parametrize(("deny_mode", "arm_result", "error"), [
    (2, m.MAV_RESULT_ACCEPTED, None),                       # refused twice, then accepted
    (0, m.MAV_RESULT_DENIED, "arm refused 3 times"),        # gives up cleanly
    (0, m.MAV_RESULT_UNSUPPORTED, "arm: UNSUPPORTED"),      # no point retrying
])
def test_refused_commands_are_retried_then_given_up(deny_mode: int, arm_result: int,
                                                    error: str | None) -> None:
    port = free_port("udp")
    fake = ScriptedVehicle(port, deny_mode, arm_result)
    lk = VehicleLink(LinkParams(f"udpout:127.0.0.1:{port}", command_timeout_s=0.3))
    lk.start()
    try:
        stop = threading.Event()
        if error is None:
            lk.takeover.start_offboard(stop, timeout_s=10, retry_wait_s=0.05)
            assert lk.status.offboard()
            modes = [c for c in fake.commands if c[0] == m.MAV_CMD_DO_SET_MODE]
            assert len(modes) == 3
        else:
            with pytest.raises(OffboardError, match=error):
                lk.takeover.start_offboard(stop, timeout_s=10, retry_wait_s=0.05)
            assert not lk.status.offboard()
    finally:
        lk.close()
        fake.close()


def test_a_vehicle_that_never_answers_commands(vehicle: Any) -> None:
    """COMMAND_LONG is re-sent with a rising ``confirmation``; no answer gives -1."""
    port = free_port("udp")
    silent = mav.connect(f"udpin:127.0.0.1:{port}", 1, 1)
    lk = VehicleLink(LinkParams(f"udpout:127.0.0.1:{port}", command_timeout_s=0.2))
    lk.start()
    try:
        assert lk.commands.command(m.MAV_CMD_COMPONENT_ARM_DISARM, 1) == -1
        seen = []
        while (msg := silent.recv_match(type="COMMAND_LONG", blocking=True, timeout=0.5)):
            seen.append(int(msg.confirmation))
        assert seen == [0, 1, 2]
    finally:
        lk.close()
        silent.close()
