"""uavsim as a fleet's vehicle host, and what each vehicle saw of its stream (no Zenoh).

One process simulates two vehicles (``--uav-ids``): instance k answers on the
links' ports + k with system id ``--sysid`` + k, flies its own Eq. (1), keeps
its own failsafe and writes its own ``--stream-stats`` file. On the real-time
clock the offboard-loss failsafe brakes to a stop (PX4 SITL); the lockstep
one holds as it is (tests/integration/test_uavsim.py).
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from services.launch import REPO, ProcessGroup, free_port_run

from .test_uavsim import mode, param, position, recv

pytestmark = pytest.mark.timeout(120)
m = __import__("services.common.mav", fromlist=["mavlink"]).mavlink


def connect(port: int, sysid: int) -> Any:
    from services.common import mav

    conn = mav.connect(f"udpout:127.0.0.1:{port}", 250, 191)
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:
        conn.mav.heartbeat_send(m.MAV_TYPE_ONBOARD_CONTROLLER, m.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        hb = conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
        if hb is not None and hb.get_srcComponent() == 1:
            assert hb.get_srcSystem() == sysid
            conn.target_system = sysid
            return conn
    raise TimeoutError("no vehicle heartbeat")


@pytest.fixture
def host(tmp_path: Path) -> Any:
    """A uavsim process hosting vehicles a and b; yields (ports, run dir, group)."""
    base = free_port_run(2)
    group = ProcessGroup()
    env = dict(os.environ, PYTHONPATH=str(REPO), PYTHONUNBUFFERED="1", LOG_FORMAT="text",
               UAV_ZENOH="off")
    argv = [sys.executable, "-m", "services.uavsim", "--uav-ids", "a,b", "--sysid", "7",
            "--mavlink-url", f"udpin:127.0.0.1:{base}", "--gcs-url", "",
            "--start", "100,100", "--clock", "realtime", "--speed-factor", "10",
            "--stream-stats", str(tmp_path / "{uav}" / "stream.json")]
    proc = group.start("uavsim", argv, env, tmp_path / "uavsim.log")
    try:
        yield (base, base + 1), tmp_path, proc
    finally:
        group.stop_all()


def take_off(conn: Any, sysid: int) -> None:
    stream_hold_sys(conn, sysid)
    assert command_sys(conn, sysid, m.MAV_CMD_DO_SET_MODE,
                       m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 4) == m.MAV_RESULT_ACCEPTED
    assert command_sys(conn, sysid, m.MAV_CMD_COMPONENT_ARM_DISARM, 1) == m.MAV_RESULT_ACCEPTED


def stream_hold_sys(conn: Any, sysid: int, n: int = 6) -> tuple[int, np.ndarray]:
    t, x = position(conn)
    for _ in range(n):
        setpoint_sys(conn, sysid, x, t)
        time.sleep(0.05)
    return t, x


def setpoint_sys(conn: Any, sysid: int, target: np.ndarray, due_ms: int) -> None:
    from services.common import mavlink_codec

    n, e, d, vn, ve, vd = mavlink_codec.state_to_ned(target, 50.0)
    conn.mav.set_position_target_local_ned_send(due_ms, sysid, 1, m.MAV_FRAME_LOCAL_NED, 3520,
                                                n, e, d, vn, ve, vd, 0, 0, 0, 0, 0)


def command_sys(conn: Any, sysid: int, cmd: int, *params: float) -> int:
    p = [*params, *([0.0] * (7 - len(params)))]
    conn.mav.command_long_send(sysid, 1, cmd, 0, *p)
    return int(recv(conn, "COMMAND_ACK", 5, lambda a: a.command == cmd).result)


def test_two_vehicles_in_one_process_fly_apart_and_the_realtime_failsafe_brakes(
        host: Any) -> None:
    (port_a, port_b), run_dir, proc = host
    a, b = connect(port_a, 7), connect(port_b, 8)
    take_off(a, 7)
    _, xb0 = position(b)
    # vehicle a streams towards a point 200 m east at 20 Hz; b is left alone
    t_a, x = position(a)
    goal = x.copy()
    goal[0] += 200.0
    t0 = time.monotonic()
    while time.monotonic() - t0 < 2.0:
        setpoint_sys(a, 7, goal, 0)
        time.sleep(0.05)
    _, xa = position(a, t_a + 10_000)  # 10 simulated s later (speed factor 10)
    assert xa[0] > x[0] + 5.0 and abs(xa[2]) > 0.5  # flying east, on its own clock
    _, xb = position(b)
    assert np.allclose(xb, xb0) and mode(b) == (5, False)  # b: untouched, disarmed, LOITER
    # the stream stops: realtime failsafe, LOITER, braked to a stop (the failsafe's timing is
    # tests/unit/services/uavsim/test_failsafe.py's, on injected arrival times: here a wait,
    # not a bound)
    recv(a, "HEARTBEAT", 10, lambda h: h.get_srcComponent() == 1 and h.custom_mode == 5)
    t_hold, _ = position(a)
    _, held = position(a, t_hold + 1)
    assert np.allclose(held[2:], 0.0)
    assert param(a, "SIM_FAILSAFES", 7) == 1.0 and param(b, "SIM_FAILSAFES", 8) == 0.0
    # each vehicle's own statistics: a's gaps (at least 30 of them, none shorter than the
    # sender's 50 ms sleep, as the kernel stamped them; how much longer is the scheduler's),
    # b's none
    deadline = time.monotonic() + 10  # written every 5 s
    stats_a = run_dir / "a" / "stream.json"
    doc: dict[str, Any] = {}
    while time.monotonic() < deadline and doc.get("failsafes") != 1:
        time.sleep(0.2)
        doc = json.loads(stats_a.read_text()) if stats_a.is_file() else {}
    assert doc["sysid"] == 7 and doc["clock"] == "realtime" and doc["failsafes"] == 1
    assert doc["gaps"]["n"] >= 30 and doc["gaps"]["p50_ms"] >= 45.0, doc["gaps"]
    doc_b = json.loads((run_dir / "b" / "stream.json").read_text())
    assert doc_b["sysid"] == 8 and doc_b["setpoints"] == 0 and doc_b["failsafes"] == 0
    a.close()
    b.close()
