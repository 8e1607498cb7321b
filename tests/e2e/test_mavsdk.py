"""MAVSDK-Python (``mavsdk<4``, the gRPC API) as a real offboard client of uavsim, per flavour.

For each ``--autopilot`` (px4, ardupilot) a vehicle runs on its own (no
Zenoh router) with the real-time clock, and MAVSDK (its ``mavsdk_server``
ships in the wheel) connects to the offboard port on loopback: discovery,
telemetry with the flavour's flight-mode name, parameters (a refused set
too), ``mission_raw``, the action plugin, offboard ``set_position_ned`` +
``start`` (GUIDED for ArduPilot) flown in the time Eq. (1) needs — counted on
the vehicle's own clock, its ``time_boot_ms`` — and the offboard-loss failsafe
(the mavsdk_server process stopped, then resumed).

Every wait fails with what it waited for and the last lines of uavsim's log
and of mavsdk_server's output (``mavsdk_server.log`` beside it).
"""

from __future__ import annotations

import asyncio
import inspect
import logging
import os
import re
import signal
import sys
import threading
from collections.abc import AsyncIterator, Awaitable, Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import pytest

from services.common import mav
from services.launch import REPO, ProcessGroup, free_port
from services.uavsim import flavour as fl
from services.uavsim.clock import RealtimeClock
from services.uavsim.vehicle import Vehicle
from tests.support.waits import check, explain, logs_in, wait_for

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
#: the offboard flight's leg north (m) and the distance that counts as reached (m): 9 steps
#: of Eq. (1) from a hover, within the vehicle's skip-ahead limit (see the flight's test)
LEG_M, REACHED_M = 70.0, 2.0
#: ticks RealtimeClock.due_steps hands out at once; a longer stall of uavsim skips the rest
DUE_LIMIT = int(inspect.signature(RealtimeClock.due_steps).parameters["limit"].default)


@dataclass
class Rig:
    flavour: str
    loop: asyncio.AbstractEventLoop
    drone: Any
    gcs: Any          # a pymavlink observer on the ground-station port
    group: ProcessGroup
    log: Path         # uavsim's
    logs_dir: Path    # uavsim.log and mavsdk_server.log

    def logs(self) -> list[Path]:
        return logs_in(self.logs_dir)

    def run(self, aw: Awaitable[T], timeout_s: float = 30.0, what: str = "") -> T:
        """Await ``aw`` (a MAVSDK call); past ``timeout_s`` fail, saying what was awaited."""
        try:
            return self.loop.run_until_complete(asyncio.wait_for(aw, timeout_s))
        except TimeoutError:
            name = what or f"MAVSDK {getattr(aw, '__qualname__', aw)!s}"
            pytest.fail(explain(f"timed out after {timeout_s:g} s waiting for {name}",
                                self.logs()), pytrace=False)

    def first(self, gen: AsyncIterator[Any], what: str,
              pred: Callable[[Any], bool] = lambda _x: True, timeout_s: float = 30.0) -> Any:
        """The first item of a MAVSDK telemetry stream with ``pred``; past ``timeout_s`` fail
        with ``what`` and the last item the stream gave."""
        seen: list[Any] = []

        async def scan() -> Any:
            async for item in gen:
                seen[:] = [item]
                if pred(item):
                    return item
            check(False, f"the MAVSDK stream ended while waiting for {what}", self.logs(),
                  f"last seen: {seen[0]!r}" if seen else "")

        try:
            return self.loop.run_until_complete(asyncio.wait_for(scan(), timeout_s))
        except TimeoutError:
            pytest.fail(explain(f"timed out after {timeout_s:g} s waiting for {what}",
                                self.logs(), f"last seen: {seen[0]!r}" if seen
                                else "the stream gave nothing"), pytrace=False)


def heartbeat(conn: Any) -> None:
    conn.mav.heartbeat_send(m.MAV_TYPE_GCS, m.MAV_AUTOPILOT_INVALID, 0, 0, 0)


def observer(port: int, log: Path) -> Any:
    conn = mav.connect(f"udpout:127.0.0.1:{port}", 254, 190)

    def answered() -> bool:  # udpout speaks first; the vehicle answers at once
        heartbeat(conn)
        return conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5) is not None

    wait_for(answered, 20, "the vehicle's HEARTBEAT on the ground-station port", [log],
             period_s=0)
    return conn


def wait_hold(rig: Rig, timeout_s: float) -> Any:
    """The first HEARTBEAT on the ground-station port that reports the flavour's hold mode."""
    hold = fl.FLAVOURS[rig.flavour].custom_mode(fl.Nav.HOLD)
    last: list[Any] = []

    def held() -> Any:
        heartbeat(rig.gcs)
        hb = rig.gcs.recv_match(type="HEARTBEAT", blocking=True, timeout=0.2)
        if hb is not None:
            last[:] = [hb]
        return hb if hb is not None and hb.custom_mode == hold else None

    return wait_for(held, timeout_s, f"a HEARTBEAT in the {rig.flavour} hold mode "
                    f"(custom_mode {hold})", rig.logs(), period_s=0,
                    last=lambda: last[0] if last else "no HEARTBEAT")


class Reports(threading.Thread):
    """Every LOCAL_POSITION_NED the ground-station port receives while it runs (the vehicle's
    own stamps and states), read on a thread of its own so that none waits in the socket."""

    def __init__(self, gcs: Any):
        super().__init__(daemon=True, name="gcs-reports")
        self.gcs, self.stop = gcs, threading.Event()
        self.seen: list[Any] = []

    def run(self) -> None:
        k = 0
        while not self.stop.is_set():
            if k % 10 == 0:
                heartbeat(self.gcs)  # stay the port's client
            k += 1
            msg = self.gcs.recv_match(type="LOCAL_POSITION_NED", blocking=True, timeout=0.1)
            if msg is not None:
                self.seen.append(msg)

    def __enter__(self) -> Reports:
        while self.gcs.recv_msg() is not None:  # what queued up before: not this flight's
            pass
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self.join(5)


@pytest.fixture(scope="module", params=["px4", "ardupilot"])
def rig(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Rig]:
    flavour = str(request.param)
    logs = tmp_path_factory.mktemp(f"mavsdk-{flavour}")
    # mavsdk_server's output (MAVSDK-Python logs it on the "mavsdk_server" logger) into a file
    server_log = logging.FileHandler(logs / "mavsdk_server.log")
    server_log.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(message)s"))
    server_logger = logging.getLogger("mavsdk_server")
    saved = server_logger.level, server_logger.propagate
    server_logger.addHandler(server_log)
    server_logger.setLevel(logging.DEBUG)
    server_logger.propagate = False
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
        gcs = observer(gcs_port, logs / "uavsim.log")
        rig = Rig(flavour, loop, drone, gcs, group, logs / "uavsim.log", logs)
        rig.run(drone.connect(system_address=f"udpout://127.0.0.1:{offboard}"), 30,
                "MAVSDK to connect")
        yield rig
    finally:
        drone._stop_mavsdk_server()
        loop.close()
        if gcs is not None:
            gcs.close()
        codes = group.stop_all()
        server_logger.removeHandler(server_log)
        server_log.close()
        server_logger.setLevel(saved[0])
        server_logger.propagate = saved[1]
        check(codes.get("uavsim") == 0, "uavsim to exit with 0", logs_in(logs), codes)


def test_discovery_telemetry_and_version(rig: Rig) -> None:
    d = rig.drone
    rig.first(d.core.connection_state(), "MAVSDK to discover the vehicle",
              lambda s: s.is_connected)
    assert rig.first(d.telemetry.flight_mode(), "a flight mode") == FlightMode.HOLD
    health = rig.first(d.telemetry.health(), "the vehicle to be armable", lambda h: h.is_armable)
    assert health.is_global_position_ok and health.is_home_position_ok
    assert rig.first(d.telemetry.in_air(), "the in-air state") is False
    pos = rig.first(d.telemetry.position_velocity_ned(), "a position")
    assert (pos.position.north_m, pos.position.east_m) == (START[1], START[0])
    version = rig.run(d.info.get_version())  # REQUEST_MESSAGE AUTOPILOT_VERSION, NaN params
    assert (version.flight_sw_major, version.flight_sw_minor) == (0, 1)
    rig.run(d.telemetry.set_rate_position_velocity_ned(20.0))  # SET_MESSAGE_INTERVAL
    check("not_finite" not in rig.log.read_text(), "uavsim to take MAVSDK's NaN parameters "
          "without a not_finite rejection", rig.logs())


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
        pos = rig.first(d.telemetry.position_velocity_ned(), "a position").position
        rig.run(d.offboard.set_position_ned(PositionNedYaw(pos.north_m, pos.east_m, -50, 0)))
        rig.run(d.offboard.start())
    rig.run(d.action.arm())
    rig.run(d.action.takeoff())
    rig.first(d.telemetry.in_air(), "the vehicle in the air", bool)
    with pytest.raises(ActionError):
        rig.run(d.action.disarm())  # in the air: denied
    rig.run(d.action.hold())
    rig.first(d.telemetry.flight_mode(), "flight mode HOLD", lambda f: f == FlightMode.HOLD)
    if rig.flavour == "ardupilot":
        rig.run(d.offboard.stop())
    rig.run(d.action.land())
    rig.first(d.telemetry.in_air(), "the vehicle on the ground", lambda a: not a)
    rig.run(d.action.disarm())
    rig.first(d.telemetry.armed(), "the vehicle disarmed", lambda a: not a)


def trajectory(start: tuple[float, float], goal: tuple[float, float], steps: int
               ) -> list[np.ndarray]:
    """[east, north, v_e, v_n] from a hover at ``start`` and after each of ``steps`` steps of
    Eq. (1) towards ``goal`` (uavsim's controller: services/uavsim/vehicle.py)."""
    v = Vehicle.at(*start)
    target = np.array([goal[0], goal[1], 0.0, 0.0])
    states = [v.state.copy()]
    for k in range(1, steps + 1):
        v.apply(target, k * 1000)
        states.append(v.state.copy())
    return states


def steps_to_reach(start: tuple[float, float], goal: tuple[float, float], tol_m: float) -> int:
    """Eq. (1) steps the vehicle's controller needs to come within ``tol_m`` of ``goal``."""
    for k, x in enumerate(trajectory(start, goal, 200)):
        if np.hypot(*(x[:2] - np.asarray(goal))) < tol_m:
            return k
    raise AssertionError("never reached")


def test_offboard_flies_to_a_point_in_the_time_the_dynamics_need(rig: Rig) -> None:
    """The vehicle reaches the point after exactly the steps of Eq. (1) it needs, as its own
    clock counts them (no wall time involved).

    On the real-time clock (services/uavsim/clock.py) uavsim flies one step of
    Eq. (1) per tick of ΔT = 1000 ms simulated and stamps the state with that
    tick (``fly_realtime``: ``apply(target, due_ms)``; telemetry right after each
    step carries ``time_boot_ms`` = the tick). A loaded machine only makes the
    ticks come late in wall time: ``due_steps`` then hands out every tick that
    came due, up to :data:`DUE_LIMIT` at once, and each is still one step with
    its own stamp. So between the report of step 1 and that of step k the stamps
    differ by exactly (k − 1)·ΔT, and the tolerance is 0 steps. The one way the
    clock could show more steps than were flown — a stall of uavsim of more than
    DUE_LIMIT ticks, whose extra ticks it skips — cannot fall inside this
    flight: it is shorter than DUE_LIMIT steps, so any stall is caught up within
    one batch of ticks, each flown.
    """
    d = rig.drone
    pos = rig.first(d.telemetry.position_velocity_ned(), "a position").position
    east, north = pos.east_m, pos.north_m
    goal = (east, north + LEG_M)
    need = steps_to_reach((east, north), goal, REACHED_M)
    check(need < DUE_LIMIT, f"the leg to need fewer than {DUE_LIMIT} steps (the test's own "
          f"premise, see its docstring)", None, need)
    ref = trajectory((east, north), goal, need + 5)
    rig.run(d.action.arm())
    rig.run(d.offboard.set_position_ned(PositionNedYaw(goal[1], goal[0], -50.0, 0.0)))
    with Reports(rig.gcs) as reports:
        rig.run(d.offboard.start())  # OFFBOARD (px4) or GUIDED (ardupilot): streamed first
        rig.first(d.telemetry.flight_mode(), "flight mode OFFBOARD",
                  lambda f: f == FlightMode.OFFBOARD)
        rig.first(d.telemetry.position_velocity_ned(), f"the position within {REACHED_M} m of "
                  f"north {goal[1]:.1f} m", lambda p: abs(p.position.north_m - goal[1])
                  < REACHED_M, 60)

        def reached() -> Any:
            return next((r for r in reports.seen
                         if np.hypot(r.y - goal[0], r.x - goal[1]) < REACHED_M), None)

        wait_for(reached, 10, "the ground-station port's report of the goal reached",
                 rig.logs(), last=lambda: reports.seen[-1] if reports.seen else "no report")
    # each report up to the goal: the state of step k of Eq. (1) (k = 0: the hover before it),
    # stamped with the tick of step 1 + (k − 1)·ΔT
    flight = reports.seen[:reports.seen.index(reached()) + 1]
    steps = []
    for r in flight:
        x = np.array([r.y, r.x, r.vy, r.vx])  # NED → [east, north, v_e, v_n]
        k = next((k for k, s in enumerate(ref) if np.allclose(x, s, atol=1e-3)), None)
        check(k is not None, "every reported state to be a state of Eq. (1) on the way to the "
              "goal", rig.logs(), f"{r} is none of {[s.round(3).tolist() for s in ref]}")
        steps.append((k, int(r.time_boot_ms)))
    moving = [(k, t) for k, t in steps if k]
    check(moving and moving[0][0] == 1, "a report of step 1 (the first flown)", rig.logs(),
          steps)
    t1 = moving[0][1]
    dt_ms = 1000
    check(all(t - t1 == (k - 1) * dt_ms for k, t in moving), "the vehicle's clock to advance "
          "one ΔT per step of Eq. (1)", rig.logs(), f"(step, time_boot_ms): {moving}")
    by_clock = (moving[-1][1] - t1) // dt_ms + 1
    check(by_clock == need, f"the vehicle's clock to show the {need} steps of Eq. (1) the "
          f"dynamics need", rig.logs(), f"(step, time_boot_ms): {moving}")


def failsafe_silences(log: str) -> list[float]:
    """The silences (s) uavsim logged when its offboard-loss failsafe fired."""
    return [float(x) for x in re.findall(r"offboard setpoints lost.*? silence_s=([0-9.]+)", log)]


def test_offboard_loss_failsafe_holds_then_the_stream_resumes(rig: Rig) -> None:
    d = rig.drone
    assert rig.first(d.telemetry.flight_mode(), "a flight mode") == FlightMode.OFFBOARD
    loss_t = rig.run(d.param.get_param_float("COM_OF_LOSS_T"))
    before = len(failsafe_silences(rig.log.read_text()))
    pid = d._server_process.pid
    os.kill(pid, signal.SIGSTOP)  # the offboard client freezes: no more setpoints
    try:
        wait_hold(rig, 10)
    finally:
        os.kill(pid, signal.SIGCONT)
    # it did not hold early: the failsafe fired on a silence of COM_OF_LOSS_T or more, as the
    # vehicle measured it (services/uavsim/failsafe.py logs it); how soon after that it held
    # is the reaction time, a figure for the benchmarks, not asserted here
    silences = wait_for(lambda: failsafe_silences(rig.log.read_text())[before:], 10,
                        "uavsim's log line of the offboard-loss failsafe", rig.logs())
    check(len(silences) == 1 and silences[0] >= loss_t, f"one failsafe, after a silence of at "
          f"least COM_OF_LOSS_T = {loss_t:g} s", rig.logs(), f"silences (s): {silences}")
    # the stream is back: after COM_OF_RSM_T the setpoints take control again. MAVSDK stops
    # its stream once a HEARTBEAT shows another mode than offboard (OffboardImpl::
    # process_heartbeat), and the thawed client may read the hold's HEARTBEAT before it sends
    # (seen once in three runs beside two busy processes): it streams as an application must,
    # each set_position_ned restarting the stream, until the vehicle takes the setpoints again
    pos = rig.first(d.telemetry.position_velocity_ned(), "a position").position
    setpoint = PositionNedYaw(pos.north_m, pos.east_m, pos.down_m, 0.0)

    def offboard_again() -> bool:
        rig.run(d.offboard.set_position_ned(setpoint))
        return rig.first(d.telemetry.flight_mode(), "a flight mode") == FlightMode.OFFBOARD

    wait_for(offboard_again, 15, "flight mode OFFBOARD again", rig.logs(), period_s=0.2)
    rig.run(d.offboard.stop())
    rig.run(d.action.land())  # from 50 m: 1.5 m/s, the last 5 m at 0.7 m/s (docs/vehicle.md)
    rig.first(d.telemetry.in_air(), "the vehicle on the ground", lambda a: not a, 30)
    rig.run(d.action.disarm())  # or disarmed already: COM_DISARM_LAND after the touchdown
    rig.first(d.telemetry.armed(), "the vehicle disarmed", lambda a: not a)
