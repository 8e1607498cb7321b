"""The supervisor's MAVLink link to the vehicle: the offboard companion's side.

A reader thread keeps the newest LOCAL_POSITION_NED (with its
``time_boot_ms``, the vehicle's simulated clock); a streamer thread re-sends
the current SET_POSITION_TARGET_LOCAL_NED at ``rate_hz`` (≥ 10 Hz; PX4 needs
≥ 2 Hz) and a HEARTBEAT at 1 Hz (5 Hz until the vehicle answers: a ``udpout``
end must speak first). :meth:`VehicleLink.send_setpoint` sends a new setpoint
at once from the caller's thread, so a decision reaches the vehicle without
waiting for the stream.
"""

from __future__ import annotations

import logging
import select
import threading
import time
from typing import Any

import numpy as np

from dualpilot.dynamics import Array
from services.common import codec, mav
from services.common.log import fields

log = logging.getLogger(__name__)
m = mav.mavlink


class VehicleLink:
    """Offboard link to one vehicle (system ``target_system``, component 1)."""

    def __init__(self, url: str, target_system: int = 1, altitude_m: float = 50.0,
                 rate_hz: float = 20.0, passphrase: str = ""):
        if rate_hz < 10:
            raise ValueError(f"setpoints are streamed at >= 10 Hz, got {rate_hz}")
        self.conn = mav.connect(url, target_system, mav.MAV_COMP_ID_ONBOARD_COMPUTER, passphrase)
        self.send = mav.Sender(self.conn)
        self.target_system = target_system
        self.altitude_m = altitude_m
        self.period_s = 1.0 / rate_hz
        self.cond = threading.Condition()
        self.state: Array | None = None
        self.state_time_ms = -1
        self.seen = threading.Event()
        self.setpoint: tuple[Array, int] | None = None
        self.sent = 0
        self._stop = threading.Event()
        self._threads = [
            threading.Thread(target=self._read, name="mav-reader", daemon=True),
            threading.Thread(target=self._stream, name="mav-streamer", daemon=True),
        ]

    def start(self) -> None:
        self._heartbeat()  # speak first so a udpin vehicle learns our address
        for th in self._threads:
            th.start()

    def close(self) -> None:
        self._stop.set()
        for th in self._threads:
            if th.is_alive():
                th.join(1.0)
        self.conn.close()

    # -- outgoing -------------------------------------------------------------------------------
    def _heartbeat(self) -> None:
        self.send("heartbeat", m.MAV_TYPE_ONBOARD_CONTROLLER, m.MAV_AUTOPILOT_INVALID, 0, 0,
                  m.MAV_STATE_ACTIVE)

    def _send_target(self, target: Array, due_ms: int) -> None:
        n, e, d, vn, ve, vd = codec.state_to_ned(target, self.altitude_m)
        self.send("set_position_target_local_ned", int(due_ms), self.target_system,
                  mav.MAV_COMP_ID_AUTOPILOT1, codec.MAV_FRAME_LOCAL_NED, codec.TYPE_MASK_POS_VEL,
                  n, e, d, vn, ve, vd, 0.0, 0.0, 0.0, 0.0, 0.0)
        self.sent += 1

    def send_setpoint(self, target: Array, due_ms: int) -> float:
        """Make ``target`` [p, v] (due at ``due_ms``) the current setpoint and send it now.

        Returns ``time.perf_counter()`` right after the frame left the socket.
        """
        target = np.asarray(target, dtype=float).copy()
        with self.cond:
            self.setpoint = (target, int(due_ms))
        self._send_target(target, due_ms)
        return time.perf_counter()

    def _stream(self) -> None:
        next_hb = 0.0
        while not self._stop.is_set():
            now = time.monotonic()
            if now >= next_hb:
                self._heartbeat()
                next_hb = now + (1.0 if self.seen.is_set() else 0.2)
            with self.cond:
                sp = self.setpoint
            if sp is not None:
                self._send_target(*sp)
            self._stop.wait(self.period_s)

    # -- incoming -------------------------------------------------------------------------------
    def _read(self) -> None:
        fd = self.conn.fd
        while not self._stop.is_set():
            ready, _, _ = select.select([fd], [], [], 0.1)
            if not ready:
                continue
            while (msg := self.conn.recv_msg()) is not None:
                self._on(msg)

    def _on(self, msg: Any) -> None:
        kind = msg.get_type()
        if msg.get_srcSystem() != self.target_system or kind == "BAD_DATA":
            return
        if kind == "HEARTBEAT" and msg.get_srcComponent() == mav.MAV_COMP_ID_AUTOPILOT1:
            if not self.seen.is_set():
                log.info("vehicle heartbeat", extra=fields(sysid=self.target_system,
                                                           mav_type=msg.type))
            self.seen.set()
        elif kind == "LOCAL_POSITION_NED":
            try:
                x = codec.state_from_ned(msg.x, msg.y, msg.vx, msg.vy)
            except codec.CodecError as err:
                codec.rejected("LOCAL_POSITION_NED", err, log)
                return
            with self.cond:
                if msg.time_boot_ms >= self.state_time_ms:
                    self.state, self.state_time_ms = x, int(msg.time_boot_ms)
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
