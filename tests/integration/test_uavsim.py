"""uavsim as a MAVLink autopilot: the offboard sequence, Eq. (1) on setpoints, the failsafe,
parameters, commands, the mission protocol, signing and the flight log.

pymavlink plays the peers: the offboard companion (component 191) and a GCS
(system 255), each on its own UDP port (MAVProxy drives it in tests/e2e).
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dualpilot.model.dynamics import DynamicsParams, hover_state, step
from services.common import bus, mav, mavlink_codec
from services.launch import free_port

pytestmark = pytest.mark.timeout(120)
m = mav.mavlink
HOME = (35.0, 33.0)  # the local frame's origin


@pytest.fixture(scope="module")
def vehicle(services: Any, liveliness: bus.Liveliness, tmp_path_factory: Any) -> Any:
    ports = {"offboard": free_port("udp"), "gcs": free_port("udp"), "signed": free_port("udp")}
    services.tlog = tmp_path_factory.mktemp("tlog") / "vehicle.tlog"
    services.start("uavsim", MAVLINK_URL=f"udpin:127.0.0.1:{ports['offboard']}",
                   GCS_URL=f"udpin:127.0.0.1:{ports['gcs']}", UAV_START="100,200",
                   UAV_HOME=f"{HOME[0]},{HOME[1]}", TLOG_PATH=str(services.tlog))
    assert liveliness.wait_for(["uavsim"], 60), services.log("uavsim")[-2000:]
    services.ports = ports
    return services


def connect(port: int, sysid: int, compid: int, key: bytes | None = None) -> Any:
    conn = mav.connect(f"udpout:127.0.0.1:{port}", sysid, compid, key=key)
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:  # udpout speaks first; the vehicle answers at once
        conn.mav.heartbeat_send(m.MAV_TYPE_GCS, m.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        hb = conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
        if hb is not None and hb.get_srcComponent() == 1:
            return conn
    raise TimeoutError("no vehicle heartbeat")


def recv(conn: Any, kind: str | list[str], timeout_s: float = 5.0,
         cond: Any = lambda msg: True) -> Any:
    deadline = time.monotonic() + timeout_s
    seen = None
    while time.monotonic() < deadline:
        msg = conn.recv_match(type=kind, blocking=True, timeout=0.2)
        if msg is not None and cond(msg):
            return msg
        seen = msg if msg is not None else seen
    raise TimeoutError(f"no {kind} that meets the condition within {timeout_s:g} s "
                       f"(last seen: {seen})")


def position(conn: Any, min_ms: int = 0, timeout_s: float = 5.0) -> tuple[int, np.ndarray]:
    msg = recv(conn, "LOCAL_POSITION_NED", timeout_s, lambda s: s.time_boot_ms >= min_ms)
    return msg.time_boot_ms, mavlink_codec.state_from_ned(msg.x, msg.y, msg.vx, msg.vy)


def send_setpoint(conn: Any, target: np.ndarray, due_ms: int, mask: int = 3520) -> None:
    n, e, d, vn, ve, vd = mavlink_codec.state_to_ned(target, 50.0)
    conn.mav.set_position_target_local_ned_send(due_ms, 1, 1, m.MAV_FRAME_LOCAL_NED, mask,
                                                n, e, d, vn, ve, vd, 0, 0, 0, 0, 0)


def command(conn: Any, cmd: int, *params: float) -> int:
    p = [*params, *([0.0] * (7 - len(params)))]
    conn.mav.command_long_send(1, 1, cmd, 0, *p)
    return int(recv(conn, "COMMAND_ACK", 5, lambda a: a.command == cmd).result)


def command_said(conn: Any, cmd: int, *params: float) -> tuple[int, list[str]]:
    """The COMMAND_ACK result and the STATUSTEXTs the vehicle sent with it (before the ACK
    or within 0.3 s after it)."""
    p = [*params, *([0.0] * (7 - len(params)))]
    conn.mav.command_long_send(1, 1, cmd, 0, *p)
    texts: list[str] = []
    result, deadline = None, time.monotonic() + 5
    while time.monotonic() < deadline:
        msg = conn.recv_match(type=["COMMAND_ACK", "STATUSTEXT"], blocking=True, timeout=0.1)
        if msg is not None and msg.get_type() == "STATUSTEXT":
            texts.append(msg.text)
        elif msg is not None and msg.command == cmd and result is None:
            result, deadline = int(msg.result), time.monotonic() + 0.3
    assert result is not None, f"no COMMAND_ACK of {cmd}"
    return result, texts


def mode(conn: Any, timeout_s: float = 3.0) -> tuple[int, bool]:
    hb = recv(conn, "HEARTBEAT", timeout_s, lambda h: h.get_srcComponent() == 1)
    return int(hb.custom_mode), bool(hb.base_mode & m.MAV_MODE_FLAG_SAFETY_ARMED)


def stream_hold(conn: Any, n: int = 6) -> tuple[int, np.ndarray]:
    """A few setpoints holding the current state (due now: no motion)."""
    t, x = position(conn)
    for _ in range(n):
        send_setpoint(conn, x, t)
        time.sleep(0.05)
    return t, x


def take_off(conn: Any) -> tuple[int, np.ndarray]:
    """The offboard sequence: stream, GUIDED, arm. A new peer streams until the vehicle takes
    it: the previous peer on the link keeps control until silent for COM_OF_LOSS_T."""
    deadline = time.monotonic() + 5
    while True:
        stream_hold(conn)
        result = command(conn, m.MAV_CMD_DO_SET_MODE, m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                         mav.MODE_GUIDED)
        if result != m.MAV_RESULT_DENIED or time.monotonic() > deadline:
            break
    assert result == m.MAV_RESULT_ACCEPTED
    assert command(conn, m.MAV_CMD_COMPONENT_ARM_DISARM, 1) == m.MAV_RESULT_ACCEPTED
    return stream_hold(conn, 2)


def test_boots_disarmed_holding_guided_needs_no_stream_takeoff_needs_arming(vehicle: Any
                                                                             ) -> None:
    conn = connect(vehicle.ports["offboard"], 1, 191)
    hb = recv(conn, "HEARTBEAT", 3, lambda h: h.get_srcComponent() == 1)
    assert hb.get_srcSystem() == 1 and hb.type == m.MAV_TYPE_QUADROTOR
    assert mode(conn) == (mav.MODE_LOITER, False)
    _, x = position(conn)
    assert np.allclose(x, [100.0, 200.0, 0.0, 0.0])
    # ArduPilot's GUIDED holds until a setpoint comes: no stream needed (PX4's OFFBOARD: the
    # px4 flavour refuses it, tests/unit/services/uavsim/test_commander.py)
    assert command(conn, m.MAV_CMD_DO_SET_MODE, m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                   mav.MODE_GUIDED) == m.MAV_RESULT_ACCEPTED
    assert command_said(conn, m.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10) == (
        m.MAV_RESULT_FAILED, ["Takeoff denied: not armed"])
    t, x = position(conn)
    send_setpoint(conn, step(x, np.array([5.0, 5.0])), t + 1000)  # ignored: disarmed
    _, again = position(conn)
    assert np.allclose(again, x)
    conn.close()


def test_offboard_sequence_then_setpoints_fly_one_step_of_eq1_each(vehicle: Any) -> None:
    """A setpoint is the next planned state: the controller recovers the plan's force."""
    dyn = DynamicsParams()
    conn = connect(vehicle.ports["offboard"], 1, 191)
    t0, x = take_off(conn)
    assert mode(conn) == (mav.MODE_GUIDED, True)
    gpi = recv(conn, "GLOBAL_POSITION_INT")
    assert gpi.relative_alt == 50_000  # airborne at SIM_ALT_M
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
    deadline = time.monotonic() + 0.5
    while time.monotonic() < deadline:
        t, got = position(conn, 0)
    assert t == due and np.allclose(got, x, atol=1e-3)
    assert "rejected setpoint" in vehicle.log("uavsim")
    att = recv(conn, "ATTITUDE")  # 10 Hz: before the failsafe brakes (1 s without setpoints)
    assert math.isclose(att.roll, math.atan2(0.0, 1.05 * 9.81), abs_tol=1e-6)
    assert math.isclose(att.pitch, -math.atan2(1.0, 1.05 * 9.81), rel_tol=1e-5)
    status = recv(conn, "SYS_STATUS")
    assert 0 < status.battery_remaining < 100  # Σ‖u‖ΔT ≈ 24 N·s of 1000
    assert status.onboard_control_sensors_health & m.MAV_SYS_STATUS_PREARM_CHECK  # armable

    # the failsafe: no setpoint for COM_OF_LOSS_T = 1 s → LOITER (hold; its timing is
    # tests/unit/services/uavsim/test_failsafe.py's, on injected arrival times: here a wait,
    # not a bound);
    # lockstep: no simulated time passes without a new stamp, so it holds as it is (x: the
    # state after the last step, still moving), its clock where it was
    recv(conn, "HEARTBEAT", 10, lambda h: h.get_srcComponent() == 1
         and h.custom_mode == mav.MODE_LOITER)
    t_held, held = position(conn)
    assert t_held == due and np.allclose(held, x, atol=1e-3) and np.any(np.abs(x[2:]) > 0.1)
    assert param(conn, "SIM_FAILSAFES") == 1.0
    # one new setpoint does not take control back; a live stream does (COM_OF_RSM_T). The
    # stream is live from that first setpoint (the next follow within COM_OF_LOSS_T), so the
    # lower bound below is measured from it
    t_stream = time.monotonic()
    send_setpoint(conn, step(held, np.array([1.0, 0.0])), due + 1000)
    _, same = position(conn)
    assert np.allclose(same, held)
    while time.monotonic() - t_stream < 3.0:
        send_setpoint(conn, step(held, np.array([1.0, 0.0])), due + 1000)
        t, got = position(conn)
        if t == due + 1000:
            break
    # control came back, and not before the stream was live for COM_OF_RSM_T = 0.5 s (a lower
    # bound: a loaded machine only makes it later)
    assert t == due + 1000 and time.monotonic() - t_stream >= 0.5 - 0.01
    assert mode(conn)[0] == mav.MODE_GUIDED
    # disarming in the air needs the force flag (ArduPilot answers a refusal FAILED)
    assert command(conn, m.MAV_CMD_COMPONENT_ARM_DISARM, 0) == m.MAV_RESULT_FAILED
    assert command(conn, m.MAV_CMD_COMPONENT_ARM_DISARM, 0, 21196) == m.MAV_RESULT_ACCEPTED
    assert mode(conn)[1] is False
    conn.close()


def test_ground_station_link_params_and_commands(vehicle: Any) -> None:
    gcs = connect(vehicle.ports["gcs"], 255, 190)
    gcs.mav.param_request_list_send(1, 1)
    values: dict[str, float] = {}
    count = None
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline and (count is None or len(values) < count):
        pv = gcs.recv_match(type="PARAM_VALUE", blocking=True, timeout=0.5)
        if pv is not None:
            values[pv.param_id] = pv.param_value
            count = pv.param_count
    assert len(values) == count
    assert values["COM_OF_LOSS_T"] == 1.0 and values["MPC_XY_VEL_MAX"] == 15.0
    # a value out of range is refused (the unchanged value comes back); a valid one is taken
    gcs.mav.param_set_send(1, 1, b"MPC_XY_VEL_MAX", 40.0, m.MAV_PARAM_TYPE_REAL32)
    pv = recv(gcs, "PARAM_VALUE", 5, lambda p: p.param_id == "MPC_XY_VEL_MAX")
    assert pv.param_value == 15.0
    gcs.mav.param_set_send(1, 1, b"COM_OF_LOSS_T", 1.2, m.MAV_PARAM_TYPE_REAL32)
    pv = recv(gcs, "PARAM_VALUE", 5, lambda p: p.param_id == "COM_OF_LOSS_T")
    assert math.isclose(pv.param_value, 1.2, rel_tol=1e-6)
    gcs.mav.param_set_send(1, 1, b"COM_OF_LOSS_T", 1.0, m.MAV_PARAM_TYPE_REAL32)
    recv(gcs, "PARAM_VALUE", 5, lambda p: p.param_id == "COM_OF_LOSS_T" and p.param_value == 1)

    assert command(gcs, m.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 1) == m.MAV_RESULT_ACCEPTED
    caps = recv(gcs, "AUTOPILOT_VERSION").capabilities
    assert caps & m.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    assert command(gcs, m.MAV_CMD_REQUEST_MESSAGE,
                   m.MAVLINK_MSG_ID_HOME_POSITION) == m.MAV_RESULT_ACCEPTED
    home = recv(gcs, "HOME_POSITION")
    assert (home.x, home.y) == (200.0, 100.0)  # NED of the start (100 east, 200 north)
    lat, lon = mav.to_geodetic(100.0, 200.0, HOME)
    assert (home.latitude, home.longitude) == (int(lat * 1e7), int(lon * 1e7))
    assert command(gcs, m.MAV_CMD_REQUEST_MESSAGE, 12345) == m.MAV_RESULT_UNSUPPORTED
    # AUTO in lockstep: no mission, and no flight time (operator missions fly through System 1)
    assert command_said(gcs, m.MAV_CMD_DO_SET_MODE, m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                        3) == (m.MAV_RESULT_FAILED, ["AUTO refused: no valid mission"])
    assert command(gcs, m.MAV_CMD_MISSION_START) == m.MAV_RESULT_DENIED
    assert command(gcs, m.MAV_CMD_PREFLIGHT_CALIBRATION) == m.MAV_RESULT_UNSUPPORTED
    gps = recv(gcs, "GPS_RAW_INT")
    assert gps.fix_type == m.GPS_FIX_TYPE_3D_FIX and gps.lat != 0
    assert recv(gcs, "EXTENDED_SYS_STATE") is not None
    gcs.close()


def param(conn: Any, name: str, sysid: int = 1) -> float:
    conn.mav.param_request_read_send(sysid, 1, name.encode(), -1)
    return float(recv(conn, "PARAM_VALUE", 5, lambda p: p.param_id == name).param_value)


def _item(seq: int, east: float, north: float, frame: int = 6, command_id: int = 16,
          z: float = 50.0) -> Any:
    lat, lon = mav.to_geodetic(east, north, HOME)
    return m.MAVLink_mission_item_int_message(1, 1, seq, frame, command_id, 0, 1, 0.0, 5.0, 0.0,
                                              math.nan, int(lat * 1e7), int(lon * 1e7), z, 0)


def upload(gcs: Any, items: list[Any], skip_answer: bool = False) -> tuple[int, list[int]]:
    """MISSION_COUNT, answer each MISSION_REQUEST_INT; returns the ACK result and requests."""
    gcs.mav.mission_count_send(1, 1, len(items), 0)
    asked: list[int] = []
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        msg = gcs.recv_match(type=["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"],
                             blocking=True, timeout=0.2)
        if msg is None:
            continue
        if msg.get_type() == "MISSION_ACK":
            return int(msg.type), asked
        asked.append(int(msg.seq))
        if not skip_answer:
            gcs.mav.send(items[msg.seq])
    raise TimeoutError("no MISSION_ACK")


def download(gcs: Any, use_int: bool = True) -> list[mav.MissionItem]:
    gcs.mav.mission_request_list_send(1, 1, 0)
    count = recv(gcs, "MISSION_COUNT").count
    out = []
    for seq in range(count):
        if use_int:
            gcs.mav.mission_request_int_send(1, 1, seq, 0)
        else:
            gcs.mav.mission_request_send(1, 1, seq, 0)
        kind = "MISSION_ITEM_INT" if use_int else "MISSION_ITEM"
        out.append(mav.MissionItem.from_msg(recv(gcs, kind, 5, lambda i, s=seq: i.seq == s)))
    gcs.mav.mission_ack_send(1, 1, m.MAV_MISSION_ACCEPTED, 0)
    return out


def test_mission_upload_download_clear_and_rejections(vehicle: Any) -> None:
    gcs = connect(vehicle.ports["gcs"], 255, 190)
    assert download(gcs) == []
    # ArduPilot-style home slot (frame GLOBAL at seq 0), then waypoints; one sent as MISSION_ITEM
    items = [_item(0, 0.0, 0.0, frame=0), _item(1, 300.0, 250.0), _item(2, 600.0, 700.0)]
    lat, lon = mav.to_geodetic(850.0, 880.0, HOME)
    items.append(m.MAVLink_mission_item_message(1, 1, 3, 3, 16, 0, 1, 0, 0, 0, 0, lat, lon,
                                                50.0, 0))
    result, asked = upload(gcs, items)
    assert result == m.MAV_MISSION_ACCEPTED and asked == [0, 1, 2, 3]
    got = download(gcs)
    wire = m.MAVLink(None, 255, 190)  # as the vehicle decoded them (MISSION_ITEM: float32)
    sent = [mav.MissionItem.from_msg(wire.decode(bytearray(i.pack(wire)))) for i in items]
    assert len(got) == 4 and all(a.same(b) for a, b in zip(got, sent, strict=True))
    assert [round(v) for v in mav.waypoints_local(got, HOME)[0]] == [300, 250]
    assert len(mav.waypoints_local(got, HOME)) == 3  # the home slot is not flown
    assert len(download(gcs, use_int=False)) == 4
    version = param(gcs, "MIS_ID")
    assert version >= 1
    cur = recv(gcs, "MISSION_CURRENT")
    assert cur.total == 4 and cur.seq == 1

    # rejected uploads keep the stored mission
    for bad, expected in (
        ([_item(0, 100, 1200)], m.MAV_MISSION_INVALID_PARAM5_X),   # north of the area
        ([_item(0, -50, 100)], m.MAV_MISSION_INVALID_PARAM6_Y),    # west of it
        ([_item(0, 100, 100, command_id=m.MAV_CMD_NAV_LOITER_UNLIM)], m.MAV_MISSION_UNSUPPORTED),
        ([_item(0, 100, 100, frame=m.MAV_FRAME_LOCAL_NED)], m.MAV_MISSION_UNSUPPORTED_FRAME),
        ([_item(0, 100, 100, z=math.inf)], m.MAV_MISSION_INVALID_PARAM7),
        ([m.MAVLink_mission_item_message(1, 1, 0, 3, 16, 0, 1, 0, 0, 0, 0, math.nan, 33.0, 50,
                                         0)], m.MAV_MISSION_INVALID_PARAM5_X),
    ):
        assert upload(gcs, bad)[0] == expected
    gcs.mav.mission_count_send(1, 1, 60_000, 0)
    assert recv(gcs, "MISSION_ACK").type == m.MAV_MISSION_NO_SPACE
    gcs.mav.mission_count_send(1, 1, 2, m.MAV_MISSION_TYPE_FENCE)
    assert recv(gcs, "MISSION_ACK").type == m.MAV_MISSION_UNSUPPORTED
    assert len(download(gcs)) == 4
    # an unanswered transfer is re-requested, then cancelled
    result, asked = upload(gcs, [_item(0, 1, 1)], skip_answer=True)
    assert result == m.MAV_MISSION_OPERATION_CANCELLED and asked == [0] * 6
    gcs.mav.mission_clear_all_send(1, 1, 0)
    assert recv(gcs, "MISSION_ACK").type == m.MAV_MISSION_ACCEPTED
    assert download(gcs) == []
    assert param(gcs, "MIS_ID") == version + 1
    gcs.close()


def test_tlog_records_the_links(vehicle: Any) -> None:
    path: Path = vehicle.tlog
    assert path.is_file() and path.stat().st_size > 0
    log = mav.mavutil.mavlink_connection(str(path))
    kinds: set[str] = set()
    while (msg := log.recv_match()) is not None:
        kinds.add(msg.get_type())
    assert {"HEARTBEAT", "LOCAL_POSITION_NED", "SET_POSITION_TARGET_LOCAL_NED",
            "MISSION_ITEM_INT", "COMMAND_ACK", "SYS_STATUS"} <= kinds


def test_signed_offboard_link_rejects_unsigned_setpoints(vehicle: Any, wait_until: Any,
                                                         tmp_path: Path) -> None:
    port = vehicle.ports["signed"]
    key_file = tmp_path / "key.bin"
    key = bytes(range(32))
    key_file.write_bytes(key)
    vehicle.start("uavsim-signed", module="services.uavsim", MAVLINK_URL=f"udpin:127.0.0.1:{port}",
                  GCS_URL="", UAV_START="10,10", UAV_ID="itest-signed",
                  MAVLINK_SIGNING_KEY_FILE=str(key_file))
    signed = connect(port, 1, 191, key=key)
    t0, x = take_off(signed)
    unsigned = mav.connect(f"udpout:127.0.0.1:{port}", 1, 191)
    wrong = mav.connect(f"udpout:127.0.0.1:{port}", 1, 191, passphrase="not the key")
    target = step(hover_state(x[:2]), np.array([1.0, 1.0]))
    send_setpoint(unsigned, target, t0 + 1000)
    send_setpoint(wrong, target, t0 + 1000)
    assert wait_until(lambda: "rejected mavlink" in vehicle.log("uavsim-signed"), 5)
    assert param(signed, "SIG_REJECTED") >= 2
    _, still = position(signed)
    assert np.allclose(still, x)
    send_setpoint(signed, target, t0 + 1000)
    t, got = position(signed, t0 + 1000)
    assert np.allclose(got, target, atol=1e-3)
    for conn in (signed, unsigned, wrong):
        conn.close()


def test_signing_key_file_reading(tmp_path: Path) -> None:
    raw = tmp_path / "raw"
    raw.write_bytes(b"k" * 32)
    assert mav.read_signing_key(raw) == b"k" * 32
    phrase = tmp_path / "phrase"
    phrase.write_text("fire-and-ice\n")
    assert mav.read_signing_key(phrase) == mav.signing_key("fire-and-ice")
    empty = tmp_path / "empty"
    empty.write_text("\n")
    with pytest.raises(ValueError, match="empty"):
        mav.read_signing_key(empty)
    east, north = mav.to_local(*mav.to_geodetic(321.5, 876.25, HOME), HOME)
    assert math.isclose(east, 321.5, abs_tol=1e-6) and math.isclose(north, 876.25, abs_tol=1e-6)


@pytest.mark.parametrize(("speed_limit", "speed"), [("axis", 15.0 * math.sqrt(2.0)),
                                                    ("norm", 15.0)])
def test_the_vehicle_clips_the_speed_as_its_reading_says(speed_limit: str, speed: float) -> None:
    """A setpoint asking for 30 m/s per axis on the diagonal, held for 20 steps: full force,
    the speed settles at the limit (|v_i| = 15 per axis, |v| = 15 as a norm)."""
    from services.uavsim.vehicle import Vehicle

    v = Vehicle.at(0.0, 0.0, DynamicsParams(speed_limit=speed_limit))  # type: ignore[arg-type]
    for k in range(20):
        v.apply(np.array([1000.0, 1000.0, 30.0, 30.0]), 1000 * (k + 1))
    assert float(np.hypot(*v.state[2:])) == pytest.approx(speed, abs=1e-9)
    v.set_limits(v_max_mps=10.0)  # MPC_XY_VEL_MAX keeps the reading
    assert v.dyn.speed_limit == speed_limit
