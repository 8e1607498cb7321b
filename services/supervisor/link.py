"""The supervisor's MAVLink link to the vehicle: an offboard companion, in MAVSDK/PX4 order.

Threads: a reader keeps the newest LOCAL_POSITION_NED (with its
``time_boot_ms``, the vehicle's simulated clock), the vehicle's autopilot,
mode and arming from its HEARTBEAT (the mode numbers are the autopilot's:
PX4's OFFBOARD is main mode 6, ArduPilot's GUIDED 4, services/common/mavmodes.py;
every change of mode is kept with the STATUSTEXT before it, and each time it
leaves offboard mode is counted: services/supervisor/faults.py), COMMAND_ACKs,
the geodetic origin (GPS_GLOBAL_ORIGIN) and the mission id (parameter
``MIS_ID``); a poller asks for ``MIS_ID`` and the origin at 1 Hz; a mission
watcher downloads the vehicle's mission (MISSION_REQUEST_LIST →
MISSION_COUNT → MISSION_REQUEST_INT for each item → MISSION_ACK, with
retries) whenever ``MIS_ID`` changes.

The stream — the current SET_POSITION_TARGET_LOCAL_NED at ``rate_hz`` (≥ 10
Hz; PX4 needs ≥ 2 Hz) and a HEARTBEAT at 1 Hz (5 Hz until the vehicle
answers: a ``udpout`` end must speak first) — is sent by the supervisor's
stream process (services/supervisor/stream/) on this link's own UDP socket,
signed on link id 1 (the link's own frames use link id 0). Only a link that
is not UDP (tcp, serial) streams from a thread of this process instead.

:meth:`VehicleLink.start_offboard` is the MAVSDK/PX4 start: wait for a
heartbeat and a valid position, stream setpoints that hold the current state,
switch to offboard (PX4 OFFBOARD, ArduPilot GUIDED), arm; a refused command is logged and retried
(``command_attempts``), then the start fails with :class:`OffboardError`.
The vehicle counts as lost after ``lost_after_s`` (3 s) without a heartbeat.
:meth:`VehicleLink.send_setpoint` sends a new setpoint at once from the
caller's thread, so a decision reaches the vehicle without waiting for the stream.
"""

from __future__ import annotations

import logging
import math
import queue
import select
import socket
import threading
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from dualpilot.model.dynamics import Array
from services.common import mav, mavlink_codec, mavmodes, rejections
from services.common.log import fields, vehicle_thread
from services.supervisor.stream.client import StreamLink, stream_process

log = logging.getLogger(__name__)
m = mav.mavlink

MISSION = m.MAV_MISSION_TYPE_MISSION
#: who sends the stream: the stream process (UDP links), or a thread of this process (a link
#: that is not UDP, and the comparison of benchmarks/stream_gaps.py)
STREAMS = ("process", "thread")
#: the reader wakes at least this often (s)
READER_PERIOD_S = 0.1
#: the poller's period with a stream process (s): the stream's destination and heartbeat rate
POLL_PERIOD_S = 0.25


class OffboardError(RuntimeError):
    """The vehicle could not be put under offboard control."""


@dataclass(frozen=True)
class ModeChange:
    """The vehicle's mode or arming changed (as its HEARTBEAT said)."""

    at_s: float  #: monotonic s the heartbeat was read
    mode: str  #: the autopilot's name (OFFBOARD, AUTO.LOITER, GUIDED, LOITER, …)
    armed: bool
    text: str  #: the last STATUSTEXT before it (the vehicle's reason)


def _destinations(conn: Any) -> list[tuple[str, int]]:
    """Where a UDP link sends: its fixed destination (udpout), else the peers heard (udpin)."""
    if not getattr(conn, "udp_server", True):
        host, port = conn.destination_addr
        try:
            return [(socket.gethostbyname(host), int(port))]
        except OSError:  # not resolvable yet (a container still starting): asked again
            return []
    return sorted((str(a), int(p)) for a, p in getattr(conn, "clients", ()))


def result_name(result: int) -> str:
    if result < 0:
        return "NO_ANSWER"
    entry = m.enums["MAV_RESULT"].get(result)
    return entry.name if entry is not None else str(result)


def heard_within(now_s: float, heartbeat_s: float, listened_s: float, lost_after_s: float,
                 reader_period_s: float = READER_PERIOD_S) -> bool:
    """Whether a vehicle last heard at ``heartbeat_s`` still counts as alive at ``now_s``
    (monotonic s): within ``lost_after_s``, less the time the reader was kept from listening
    beyond its period since ``listened_s`` (heartbeats wait in the socket meanwhile)."""
    deaf_s = max(0.0, now_s - listened_s - reader_period_s)
    return now_s - heartbeat_s - deaf_s <= lost_after_s


class VehicleLink:
    """Offboard link to one vehicle (system ``target_system``, component 1)."""

    def __init__(self, url: str, target_system: int = 1, altitude_m: float = 50.0,
                 rate_hz: float = 20.0, passphrase: str = "", key: bytes | None = None,
                 lost_after_s: float = 3.0, command_attempts: int = 3,
                 command_timeout_s: float = 1.0, stream: str = "process"):
        if rate_hz < 10:
            raise ValueError(f"setpoints are streamed at >= 10 Hz, got {rate_hz}")
        if stream not in STREAMS:
            raise ValueError(f"stream must be one of {STREAMS}, got {stream!r}")
        self.conn = mav.connect(url, target_system, mav.MAV_COMP_ID_ONBOARD_COMPUTER, passphrase,
                                key=key, link_id=0)
        self.send = mav.Sender(self.conn)
        if key is None and passphrase:
            key = mav.signing_key(passphrase)
        self.stream: StreamLink | None = None
        udp = isinstance(getattr(self.conn, "port", None), socket.socket)
        if stream == "process" and udp:  # the stream process
            self.stream = stream_process().add(
                self.conn.port, [], target_system, mav.MAV_COMP_ID_ONBOARD_COMPUTER,
                (target_system, mav.MAV_COMP_ID_AUTOPILOT1), mav.MAV_FRAME_LOCAL_NED, rate_hz,
                key, link_id=1)
        self._dests: list[tuple[str, int]] = []
        self._hb_period = 0.0
        self.target_system = target_system
        self.target = (target_system, mav.MAV_COMP_ID_AUTOPILOT1)
        self.altitude_m = altitude_m
        self.period_s = 1.0 / rate_hz
        self.lost_after_s = lost_after_s
        self.command_attempts = command_attempts
        self.command_timeout_s = command_timeout_s
        self._init_vehicle_view()
        self._stop = threading.Event()
        self._threads = [
            threading.Thread(target=vehicle_thread(self._read), name="mav-reader", daemon=True),
            threading.Thread(target=vehicle_thread(self._poll), name="mav-poller", daemon=True),
            threading.Thread(target=vehicle_thread(self._watch_mission), name="mav-mission",
                             daemon=True),
        ]

    def _init_vehicle_view(self) -> None:
        """What the link knows of the vehicle before it has heard it: nothing yet."""
        self.cond = threading.Condition()
        self.state: Array | None = None
        self.state_time_ms = -1
        self.global_ok = False
        self.seen = threading.Event()
        self.last_heartbeat = 0.0
        self._listened = time.monotonic()  # when the reader last waited for the vehicle
        self.mode = -1
        self.armed = False
        #: the vehicle's mode numbers, from its HEARTBEAT's autopilot field (None: not heard)
        self.modes: mavmodes.ModeMap | None = None
        #: every change of mode or arming: (monotonic s, mode name, armed, last STATUSTEXT)
        self.mode_changes: list[ModeChange] = []
        self.origin: tuple[float, float] | None = None
        self.setpoint: tuple[Array, int] | None = None
        self._sent = 0  # setpoints sent by this process (a link that is not UDP)
        self.acks: dict[int, int] = {}
        #: times the vehicle left offboard mode while armed, and the last STATUSTEXT before it
        self.holds = 0
        self.hold_reasons: list[str] = []
        self.last_text = ""
        #: LOCAL_POSITION_NED that changed the state without a new time_boot_ms (no step)
        self.moved_without_step = 0
        self.mission_id_seen: float | None = None
        self.mission_id_loaded: float | None = None
        self.mission_items: list[mav.MissionItem] | None = None
        self.mission_rev = 0
        self._mission_q: queue.Queue[Any] = queue.Queue()
        self._mission_changed = threading.Event()

    def start(self) -> None:
        self._update_stream()  # speak first so a udpin vehicle learns our address
        if self.stream is None:
            self._heartbeat()
        for th in self._threads:
            th.start()

    def close(self) -> dict[str, object]:
        """Stop the stream and the threads, close the link; the stream's statistics."""
        stats: dict[str, object] = {}
        if self.stream is not None:
            stats = dict(self.stream.close())
            log.info("setpoint stream closed", extra=fields(**stats))
        self._stop.set()
        self._mission_changed.set()
        for th in self._threads:
            if th.is_alive():
                th.join(1.0)
        self.conn.close()
        return stats

    @property
    def sent(self) -> int:
        """Setpoint frames sent on this link (stream repeats included)."""
        return self.stream.frames if self.stream is not None else self._sent

    def stream_stats(self) -> dict[str, object]:
        """What the stream process kept: frames, the longest gap between them, its scheduling."""
        if self.stream is None:
            return {"process": False, "frames": self._sent}
        return {"process": True, "scheduling": self.stream.owner.priority,
                "restarts": self.stream.owner.restarts, **self.stream.stats()}

    # -- vehicle status -------------------------------------------------------------------------
    def alive(self) -> bool:
        """A heartbeat from the vehicle within ``lost_after_s`` — counted from when the reader
        last listened: a reader kept off the CPU has not heard the vehicle, but has not missed
        it either (its heartbeats wait in the socket)."""
        if not self.seen.is_set():
            return False
        return heard_within(time.monotonic(), self.last_heartbeat, self._listened,
                            self.lost_after_s)

    def offboard(self) -> bool:
        """Alive, armed and in offboard mode (PX4 OFFBOARD, ArduPilot GUIDED): the setpoints
        fly it."""
        return (self.alive() and self.armed and self.modes is not None
                and self.mode == self.modes.offboard)

    def mode_name(self, mode: int | None = None) -> str:
        mode = self.mode if mode is None else mode
        return self.modes.name(mode) if self.modes is not None else str(mode)

    def status(self) -> str:
        if not self.alive():
            return "lost"
        armed = "armed" if self.armed else "disarmed"
        return f"{self.mode_name()}, {armed}"

    # -- outgoing -------------------------------------------------------------------------------
    def _heartbeat(self) -> None:
        self.send("heartbeat", m.MAV_TYPE_ONBOARD_CONTROLLER, m.MAV_AUTOPILOT_INVALID, 0, 0,
                  m.MAV_STATE_ACTIVE)

    def _send_target(self, target: Array, due_ms: int, wait: bool = True) -> float:
        """Send a setpoint now (through the stream process, which then repeats it)."""
        n, e, d, vn, ve, vd = mavlink_codec.state_to_ned(target, self.altitude_m)
        if self.stream is not None:
            return self.stream.setpoint(int(due_ms), (n, e, d, vn, ve, vd),
                                        mav.TYPE_MASK_POS_VEL, wait)
        self.send("set_position_target_local_ned", int(due_ms), *self.target,
                  mav.MAV_FRAME_LOCAL_NED, mav.TYPE_MASK_POS_VEL,
                  n, e, d, vn, ve, vd, 0.0, 0.0, 0.0, 0.0, 0.0)
        self._sent += 1
        return time.perf_counter()

    def send_setpoint(self, target: Array, due_ms: int) -> float:
        """Make ``target`` [p, v] (due at ``due_ms``) the current setpoint and send it now.

        Returns ``time.perf_counter()`` right after the frame left the socket.
        """
        target = np.asarray(target, dtype=float).copy()
        with self.cond:
            self.setpoint = (target, int(due_ms))
        return self._send_target(target, due_ms)

    def hold(self) -> None:
        """Stream the vehicle's current state, due now: keeps the stream alive, moves nothing."""
        with self.cond:
            if self.state is None or self.setpoint is not None:
                return
            self.setpoint = (self.state.copy(), self.state_time_ms)
            sp = self.setpoint
        self._send_target(*sp, wait=False)

    def _update_stream(self) -> None:
        """Tell the stream process where the vehicle is and how often to heartbeat."""
        if self.stream is None:
            return
        period = 1.0 if self.alive() else 0.2
        if period != self._hb_period:
            self._hb_period = period
            self.stream.heartbeat(period, m.MAV_TYPE_ONBOARD_CONTROLLER, m.MAV_AUTOPILOT_INVALID,
                                  m.MAV_STATE_ACTIVE)
        if self._dests and not getattr(self.conn, "udp_server", True):
            return  # a fixed destination, resolved once
        dests = _destinations(self.conn)
        if dests != self._dests:
            self._dests = dests
            self.stream.dests(dests)

    def _poll(self) -> None:
        """Parameter and origin polls at 1 Hz; the stream's destination and heartbeat period
        (or, on a link that is not UDP, the stream itself)."""
        next_hb = next_poll = 0.0
        while not self._stop.is_set():
            now = time.monotonic()
            self._update_stream()
            if self.stream is None and now >= next_hb:
                self._heartbeat()
                next_hb = now + (1.0 if self.alive() else 0.2)
            if now >= next_poll and self.seen.is_set():
                self.send("param_request_read", *self.target, b"MIS_ID", -1)
                if self.origin is None:
                    self.send("command_long", *self.target, m.MAV_CMD_REQUEST_MESSAGE, 0,
                              m.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN, 0, 0, 0, 0, 0, 0)
                next_poll = now + 1.0
            if self.stream is None:
                with self.cond:
                    sp = self.setpoint
                if sp is not None:
                    self._send_target(*sp)
            self._stop.wait(self.period_s if self.stream is None else POLL_PERIOD_S)

    def command(self, cmd: int, *params: float, stop: threading.Event | None = None) -> int:
        """COMMAND_LONG, re-sent (``confirmation`` + 1) until a COMMAND_ACK arrives; the result,
        or -1 if none came after ``command_attempts`` tries."""
        p = [float(v) for v in params] + [0.0] * (7 - len(params))
        for confirmation in range(self.command_attempts):
            with self.cond:
                self.acks.pop(cmd, None)
            self.send("command_long", *self.target, cmd, confirmation, *p)
            deadline = time.monotonic() + self.command_timeout_s
            with self.cond:
                while True:
                    result = self.acks.get(cmd)
                    if result is not None and result != m.MAV_RESULT_IN_PROGRESS:
                        return int(result)
                    remaining = deadline - time.monotonic()
                    if remaining <= 0 or (stop is not None and stop.is_set()):
                        break
                    self.cond.wait(min(remaining, 0.1))
            if stop is not None and stop.is_set():
                break
        return -1

    def start_offboard(self, stop: threading.Event, timeout_s: float = 30.0,
                       retry_wait_s: float = 0.5) -> None:
        """Heartbeat, a valid position, setpoints, offboard mode, arm (MAVSDK/PX4 order).

        Steps already satisfied are skipped, so it also re-takes a vehicle that
        came back. Raises OffboardError when the vehicle refuses (after
        ``command_attempts`` tries with ``retry_wait_s`` between them) or
        ``timeout_s`` passes; returns early when ``stop`` is set.
        """
        deadline = time.monotonic() + timeout_s
        if not self.wait_vehicle(timeout_s, stop):
            raise OffboardError("no heartbeat from the vehicle")
        while not (self.global_ok and self.state is not None):
            if stop.wait(0.05) or time.monotonic() > deadline:
                raise OffboardError("no valid position from the vehicle")
        self.hold()
        stop.wait(5 * self.period_s)  # PX4 accepts offboard only with the stream already live
        modes = self.modes
        assert modes is not None  # set with the first heartbeat
        log.info("taking the vehicle", extra=fields(autopilot=modes.family,
                                                    offboard=modes.name(modes.offboard)))
        steps = (
            ("offboard mode", lambda: self.mode == modes.offboard, m.MAV_CMD_DO_SET_MODE,
             (float(m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), *modes.offboard_request)),
            ("arm", lambda: self.armed, m.MAV_CMD_COMPONENT_ARM_DISARM, (1.0,)),
        )
        for what, done, cmd, params in steps:
            for attempt in range(1, self.command_attempts + 1):
                if done() or stop.is_set():
                    break
                result = self.command(cmd, *params, stop=stop)
                if result == m.MAV_RESULT_ACCEPTED:
                    log.info("vehicle accepted", extra=fields(command=what))
                    break
                log.warning("vehicle refused a command", extra=fields(
                    command=what, result=result_name(result), attempt=attempt,
                    of=self.command_attempts))
                if result == m.MAV_RESULT_UNSUPPORTED:
                    raise OffboardError(f"{what}: UNSUPPORTED")
                stop.wait(retry_wait_s)
            else:
                raise OffboardError(f"{what} refused {self.command_attempts} times")
        while not (self.offboard() or stop.is_set()):  # the heartbeat confirms it
            if time.monotonic() > deadline:
                raise OffboardError(f"vehicle not under offboard control ({self.status()})")
            stop.wait(0.05)

    # -- incoming -------------------------------------------------------------------------------
    def _read(self) -> None:
        fd = self.conn.fd
        while not self._stop.is_set():
            self._listened = time.monotonic()
            ready, _, _ = select.select([fd], [], [], READER_PERIOD_S)
            if not ready:
                continue
            while (msg := self.conn.recv_msg()) is not None:
                self._on(msg)

    def _on(self, msg: Any) -> None:
        kind = msg.get_type()
        if kind == "BAD_DATA" or msg.get_srcSystem() != self.target_system:
            return
        if msg.get_srcComponent() != mav.MAV_COMP_ID_AUTOPILOT1:
            return
        if kind == "HEARTBEAT":
            self._on_heartbeat(msg)
        elif kind == "LOCAL_POSITION_NED":
            try:
                x = mavlink_codec.state_from_ned(msg.x, msg.y, msg.vx, msg.vy)
            except rejections.CodecError as err:
                rejections.rejected("LOCAL_POSITION_NED", err, log)
                return
            with self.cond:
                if msg.time_boot_ms >= self.state_time_ms:
                    if (msg.time_boot_ms == self.state_time_ms and self.state is not None
                            and not np.array_equal(x, self.state)):
                        self.moved_without_step += 1  # lockstep: only a step moves it
                    self.state, self.state_time_ms = x, int(msg.time_boot_ms)
                    self.cond.notify_all()
        elif kind == "GLOBAL_POSITION_INT":
            self.global_ok = msg.lat != 0 or msg.lon != 0
        elif kind == "GPS_GLOBAL_ORIGIN":
            lat, lon = msg.latitude / 1e7, msg.longitude / 1e7
            if math.isfinite(lat) and abs(lat) < 85 and abs(lon) <= 180:
                self.origin = (lat, lon)
        elif kind == "COMMAND_ACK":
            with self.cond:
                self.acks[int(msg.command)] = int(msg.result)
                self.cond.notify_all()
        elif kind == "STATUSTEXT":
            self.last_text = str(msg.text)[:50]
        elif kind == "PARAM_VALUE" and msg.param_id == "MIS_ID":
            self.mission_id_seen = float(msg.param_value)
            if self.mission_id_seen != self.mission_id_loaded:
                self._mission_changed.set()
        elif kind in ("MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ACK"):
            self._mission_q.put(msg)

    def _on_heartbeat(self, msg: Any) -> None:
        """The vehicle's autopilot (its mode numbers), mode and arming; a change is kept, and
        leaving offboard control while armed is counted (a fault of the mission)."""
        with self.cond:
            modes = mavmodes.for_autopilot(int(msg.autopilot))
            if not self.seen.is_set() or not self.alive() or modes != self.modes:
                log.info("vehicle heartbeat", extra=fields(
                    sysid=self.target_system, mav_type=msg.type, autopilot=modes.family))
            self.modes = modes
            self.last_heartbeat = time.monotonic()
            mode, armed = int(msg.custom_mode), bool(
                msg.base_mode & m.MAV_MODE_FLAG_SAFETY_ARMED)
            if (mode, armed) != (self.mode, self.armed):
                self.mode_changes.append(ModeChange(self.last_heartbeat, modes.name(mode), armed,
                                                    self.last_text))
                if self.seen.is_set():
                    log.info("vehicle mode", extra=fields(mode=modes.name(mode), armed=armed))
                if self.mode == modes.offboard and self.armed and mode != modes.offboard:
                    self.holds += 1  # it left offboard control: a fault of the mission
                    self.hold_reasons.append(self.last_text)
            self.mode, self.armed = mode, armed
            self.seen.set()
            self.cond.notify_all()

    def wait_vehicle(self, timeout_s: float, stop: threading.Event) -> bool:
        deadline = time.monotonic() + timeout_s
        while not self.seen.wait(0.1):
            if stop.is_set() or time.monotonic() > deadline:
                return False
        return True

    def wait_state(self, min_time_ms: int, timeout_s: float,
                   stop: threading.Event) -> tuple[int, Array] | None:
        """The newest state stamped at or after ``min_time_ms`` (None on timeout or stop)."""
        deadline = time.monotonic() + timeout_s
        with self.cond:
            while self.state is None or self.state_time_ms < min_time_ms:
                remaining = deadline - time.monotonic()
                if remaining <= 0 or stop.is_set():
                    return None
                self.cond.wait(min(remaining, 0.1))
            return self.state_time_ms, self.state.copy()

    # -- the operator's mission -------------------------------------------------------------------
    def _expect(self, kind: str, timeout_s: float, seq: int | None = None) -> Any:
        deadline = time.monotonic() + timeout_s
        while (remaining := deadline - time.monotonic()) > 0 and not self._stop.is_set():
            try:
                msg = self._mission_q.get(timeout=min(remaining, 0.1))
            except queue.Empty:
                continue
            if msg.get_type() == kind and (seq is None or msg.seq == seq) and int(
                    getattr(msg, "mission_type", MISSION)) == MISSION:
                return msg
        return None

    def download_mission(self, timeout_s: float = 0.5, retries: int = 5) -> list[mav.MissionItem]:
        """The vehicle's mission, item by item (mission protocol, re-requesting lost ones)."""
        while not self._mission_q.empty():
            self._mission_q.get_nowait()
        count_msg = None
        for _ in range(retries):
            self.send("mission_request_list", *self.target, MISSION)
            if (count_msg := self._expect("MISSION_COUNT", timeout_s)) is not None:
                break
        if count_msg is None:
            raise TimeoutError("no MISSION_COUNT from the vehicle")
        items: list[mav.MissionItem] = []
        for seq in range(int(count_msg.count)):
            for _ in range(retries):
                self.send("mission_request_int", *self.target, seq, MISSION)
                if (item := self._expect("MISSION_ITEM_INT", timeout_s, seq)) is not None:
                    items.append(mav.MissionItem.from_msg(item))
                    break
            else:
                raise TimeoutError(f"no MISSION_ITEM_INT {seq} from the vehicle")
        self.send("mission_ack", *self.target, m.MAV_MISSION_ACCEPTED, MISSION)
        return items

    def _watch_mission(self) -> None:
        while not self._stop.is_set():
            self._mission_changed.wait(1.0)  # set by the reader when MIS_ID is heard
            self._mission_changed.clear()
            seen = self.mission_id_seen
            if seen is None or seen == self.mission_id_loaded:
                continue
            try:
                items = self.download_mission()
            except TimeoutError as err:
                log.warning("mission download failed", extra=fields(error=str(err)))
                continue
            with self.cond:
                self.mission_items, self.mission_id_loaded = items, seen
                self.mission_rev += 1
                self.cond.notify_all()
            log.info("mission downloaded", extra=fields(mission_id=seen, items=len(items),
                                                        waypoints=sum(i.is_waypoint()
                                                                      for i in items)))

    def wait_mission(self, timeout_s: float, stop: threading.Event) -> bool:
        """Wait until the vehicle's current mission (its MIS_ID) has been downloaded."""
        deadline = time.monotonic() + timeout_s
        with self.cond:
            while self.mission_id_seen is None or self.mission_id_loaded != self.mission_id_seen:
                remaining = deadline - time.monotonic()
                if remaining <= 0 or stop.is_set():
                    return False
                self.cond.wait(min(remaining, 0.1))
            return True

    def operator_waypoints(self) -> tuple[int, Array | None, float | None]:
        """(revision, local waypoints (k, 2) east/north m or None, mission id) of the newest
        downloaded mission; revision 0 means none downloaded yet."""
        with self.cond:
            rev, items, mid = self.mission_rev, self.mission_items, self.mission_id_loaded
        if not rev or items is None:
            return rev, None, mid
        if self.origin is None:
            return 0, None, None  # not convertible yet: the next step tries again
        wps = mav.waypoints_local(items, self.origin)
        return rev, (np.array(wps, dtype=float) if wps else None), mid
