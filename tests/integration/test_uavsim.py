"""uavsim as a MAVLink endpoint: flies Eq. (1) on setpoints, and talks to a ground station.

pymavlink plays both peers (MAVProxy is not installed here): the offboard
companion (component 191) and a GCS (system 255), each on its own UDP port.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pytest

from dualpilot.dynamics import DynamicsParams, hover_state, step
from services.common import bus, codec, mav
from services.launch import free_port

pytestmark = pytest.mark.timeout(90)
m = mav.mavlink


@pytest.fixture(scope="module")
def vehicle(services: Any, liveliness: bus.Liveliness) -> Any:
    ports = {"offboard": free_port("udp"), "gcs": free_port("udp"), "signed": free_port("udp")}
    services.start("uavsim", MAVLINK_URL=f"udpin:127.0.0.1:{ports['offboard']}",
                   GCS_URL=f"udpin:127.0.0.1:{ports['gcs']}", UAV_START="100,200")
    assert liveliness.wait_for(["uavsim"], 60), services.log("uavsim")[-2000:]
    services.ports = ports
    return services


def connect(port: int, sysid: int, compid: int, passphrase: str = "") -> Any:
    conn = mav.connect(f"udpout:127.0.0.1:{port}", sysid, compid, passphrase)
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:  # udpout speaks first; the vehicle answers at once
        conn.mav.heartbeat_send(m.MAV_TYPE_GCS, m.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        hb = conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
        if hb is not None and hb.get_srcComponent() == 1:
            return conn
    raise TimeoutError("no vehicle heartbeat")


def position(conn: Any, min_ms: int = 0, timeout_s: float = 5.0) -> tuple[int, np.ndarray]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        msg = conn.recv_match(type="LOCAL_POSITION_NED", blocking=True, timeout=0.5)
        if msg is not None and msg.time_boot_ms >= min_ms:
            return msg.time_boot_ms, codec.state_from_ned(msg.x, msg.y, msg.vx, msg.vy)
    raise TimeoutError(f"no LOCAL_POSITION_NED at or after {min_ms} ms")


def send_setpoint(conn: Any, target: np.ndarray, due_ms: int, mask: int = 3520) -> None:
    n, e, d, vn, ve, vd = codec.state_to_ned(target, 50.0)
    conn.mav.set_position_target_local_ned_send(due_ms, 1, 1, m.MAV_FRAME_LOCAL_NED, mask,
                                                n, e, d, vn, ve, vd, 0, 0, 0, 0, 0)


def test_heartbeat_and_position_from_component_1(vehicle: Any) -> None:
    conn = connect(vehicle.ports["offboard"], 1, 191)
    hb = conn.recv_match(type="HEARTBEAT", blocking=True, timeout=3)
    assert hb.get_srcSystem() == 1 and hb.get_srcComponent() == 1
    assert hb.type == m.MAV_TYPE_QUADROTOR
    _, x = position(conn)
    assert np.allclose(x, [100.0, 200.0, 0.0, 0.0])
    conn.close()


def test_setpoints_fly_one_step_of_eq1_each(vehicle: Any) -> None:
    """A setpoint is the next planned state: the controller recovers the plan's force."""
    dyn = DynamicsParams()
    conn = connect(vehicle.ports["offboard"], 1, 191)
    t0, x = position(conn)
    assert np.allclose(x[2:], 0.0)
    x = hover_state(x[:2], dyn)
    for k, u in enumerate([np.array([3.0, -2.0]), np.array([-7.5, 7.5]), np.array([0.0, 1.0])]):
        target = step(x, u, dyn)
        due = t0 + 1500 * (k + 1)
        for _ in range(3):  # the ≥ 10 Hz stream repeats it: only the first one moves the vehicle
            send_setpoint(conn, target, due)
        t, got = position(conn, due)
        assert t == due
        assert np.allclose(got, target, atol=1e-3), (got, target)
        x = got
    # a repeat of an old setpoint, a bad frame mask: no motion
    send_setpoint(conn, target, due)
    send_setpoint(conn, target + 10.0, due + 1000, mask=0)
    t, got = position(conn, 0)
    deadline = time.monotonic() + 0.5
    while time.monotonic() < deadline:
        t, got = position(conn, 0)
    assert t == due and np.allclose(got, x, atol=1e-3)
    assert "rejected setpoint" in vehicle.log("uavsim")
    conn.close()


def test_ground_station_link(vehicle: Any) -> None:
    gcs = connect(vehicle.ports["gcs"], 255, 190)
    gcs.mav.param_request_list_send(1, 1)
    names = set()
    deadline = time.monotonic() + 5
    count = None
    while time.monotonic() < deadline and (count is None or len(names) < count):
        pv = gcs.recv_match(type="PARAM_VALUE", blocking=True, timeout=0.5)
        if pv is not None:
            names.add(pv.param_id)
            count = pv.param_count
    assert {"MAV_SYS_ID", "COM_OF_LOSS_T"} <= names and len(names) == count
    gcs.mav.command_long_send(1, 1, m.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 0,
                              1, 0, 0, 0, 0, 0, 0)
    ack = gcs.recv_match(type="COMMAND_ACK", blocking=True, timeout=5)
    assert ack.command == m.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES
    assert ack.result == m.MAV_RESULT_ACCEPTED
    assert gcs.recv_match(type="AUTOPILOT_VERSION", blocking=True, timeout=5) is not None
    gcs.mav.command_long_send(1, 1, m.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 0, 10)
    ack = gcs.recv_match(type="COMMAND_ACK", blocking=True, timeout=5)
    assert ack.result == m.MAV_RESULT_UNSUPPORTED
    gcs.mav.mission_request_list_send(1, 1)
    count_msg = gcs.recv_match(type="MISSION_COUNT", blocking=True, timeout=5)
    assert count_msg.count == 0
    gpi = gcs.recv_match(type="GLOBAL_POSITION_INT", blocking=True, timeout=5)
    assert gpi.lat != 0 and gpi.lon != 0 and gpi.relative_alt == 50_000
    gcs.close()


def test_signed_offboard_link_rejects_unsigned_setpoints(vehicle: Any, wait_until: Any) -> None:
    port = vehicle.ports["signed"]
    vehicle.start("uavsim-signed", module="services.uavsim", MAVLINK_URL=f"udpin:127.0.0.1:{port}",
                  GCS_URL="", UAV_START="10,10", UAV_ID="itest-signed",
                  MAVLINK_SIGNING_PASSPHRASE="fire-and-ice")
    signed = connect(port, 1, 191, passphrase="fire-and-ice")
    t0, x = position(signed)
    unsigned = mav.connect(f"udpout:127.0.0.1:{port}", 1, 191)
    target = step(hover_state(x[:2]), np.array([1.0, 1.0]))
    send_setpoint(unsigned, target, t0 + 1000)
    assert wait_until(lambda: "rejected mavlink" in vehicle.log("uavsim-signed"), 5)
    send_setpoint(signed, target, t0 + 1000)
    t, got = position(signed, t0 + 1000)
    assert np.allclose(got, target, atol=1e-3)
    signed.close()
    unsigned.close()
