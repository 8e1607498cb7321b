"""The vehicle's setpoint: the current SET_POSITION_TARGET_LOCAL_NED and its stream.

The stream — the current setpoint at ``rate_hz`` (≥ 10 Hz; PX4 needs ≥ 2 Hz)
and a HEARTBEAT at 1 Hz (5 Hz until the vehicle answers: a ``udpout`` end
must speak first) — is sent by the supervisor's stream process
(services/supervisor/stream/) on the link's own UDP socket, signed on link id
1. Only a link that is not UDP (tcp, serial) streams from a thread of this
process instead (:meth:`Setpoints.repeat`). :meth:`Setpoints.send` sends a
new setpoint at once from the caller's thread, so a decision reaches the
vehicle without waiting for the stream.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

import numpy as np

from dualpilot.model.dynamics import Array
from services.common import mav, mavlink_codec
from services.common.log import fields

from ..stream.client import StreamLink, stream_process
from .connection import Channel
from .params import LinkParams

log = logging.getLogger("services.supervisor.link")
m = mav.mavlink


class Setpoints:
    """The current setpoint of one vehicle and who streams it."""

    def __init__(self, connection: Channel, params: LinkParams,
                 alive: Callable[[], bool], current: Callable[[], tuple[Array, int] | None]):
        """``alive()``: the vehicle is heard (the heartbeat's period); ``current()``: its newest
        state and ``time_boot_ms`` (what :meth:`hold` streams)."""
        self.connection = connection
        self.altitude_m = params.altitude_m
        self.alive = alive
        self.current = current
        self.lock = threading.Lock()
        self.setpoint: tuple[Array, int] | None = None
        self._sent = 0  # setpoints sent by this process (a link that is not UDP)
        self._dests: list[tuple[str, int]] = []
        self._hb_period = 0.0
        self.stream: StreamLink | None = None
        if params.stream == "process" and connection.udp:  # the stream process
            key = params.key
            if key is None and params.passphrase:
                key = mav.signing_key(params.passphrase)
            self.stream = stream_process().add(
                connection.conn.port, [], params.target_system, mav.MAV_COMP_ID_ONBOARD_COMPUTER,
                connection.target, mav.MAV_FRAME_LOCAL_NED, params.rate_hz, key, link_id=1)

    @property
    def sent(self) -> int:
        """Setpoint frames sent on this link (stream repeats included)."""
        return self.stream.frames if self.stream is not None else self._sent

    def stats(self) -> dict[str, object]:
        """What the stream process kept: frames, the longest gap between them, its scheduling."""
        if self.stream is None:
            return {"process": False, "frames": self._sent}
        return {"process": True, "scheduling": self.stream.owner.priority,
                "restarts": self.stream.owner.restarts, **self.stream.stats()}

    def _send_target(self, target: Array, due_ms: int, wait: bool = True) -> float:
        """Send a setpoint now (through the stream process, which then repeats it)."""
        n, e, d, vn, ve, vd = mavlink_codec.state_to_ned(target, self.altitude_m)
        if self.stream is not None:
            return self.stream.setpoint(int(due_ms), (n, e, d, vn, ve, vd),
                                        mav.TYPE_MASK_POS_VEL, wait)
        self.connection.send("set_position_target_local_ned", int(due_ms),
                             *self.connection.target, mav.MAV_FRAME_LOCAL_NED,
                             mav.TYPE_MASK_POS_VEL, n, e, d, vn, ve, vd,
                             0.0, 0.0, 0.0, 0.0, 0.0)
        self._sent += 1
        return time.perf_counter()

    def send(self, target: Array, due_ms: int) -> float:
        """Make ``target`` [p, v] (due at ``due_ms``) the current setpoint and send it now.

        Returns ``time.perf_counter()`` right after the frame left the socket.
        """
        target = np.asarray(target, dtype=float).copy()
        with self.lock:
            self.setpoint = (target, int(due_ms))
        return self._send_target(target, due_ms)

    def hold(self) -> None:
        """Stream the vehicle's current state, due now: keeps the stream alive, moves nothing."""
        now = self.current()
        with self.lock:
            if now is None or self.setpoint is not None:
                return
            self.setpoint = now
        self._send_target(*now, wait=False)

    def repeat(self) -> None:
        """Send the current setpoint again (the stream of a link that is not UDP)."""
        with self.lock:
            sp = self.setpoint
        if sp is not None:
            self._send_target(*sp)

    def update_stream(self) -> None:
        """Tell the stream process where the vehicle is and how often to heartbeat."""
        if self.stream is None:
            return
        period = 1.0 if self.alive() else 0.2
        if period != self._hb_period:
            self._hb_period = period
            self.stream.heartbeat(period, m.MAV_TYPE_ONBOARD_CONTROLLER, m.MAV_AUTOPILOT_INVALID,
                                  m.MAV_STATE_ACTIVE)
        if self._dests and not getattr(self.connection.conn, "udp_server", True):
            return  # a fixed destination, resolved once
        dests = self.connection.destinations()
        if dests != self._dests:
            self._dests = dests
            self.stream.dests(dests)

    def close(self) -> dict[str, object]:
        """End the stream; its statistics ({} without the stream process)."""
        if self.stream is None:
            return {}
        stats = dict(self.stream.close())
        log.info("setpoint stream closed", extra=fields(**stats))
        return stats
