"""How often each telemetry message is streamed: defaults, SET_MESSAGE_INTERVAL, what is due.

MAV_CMD_SET_MESSAGE_INTERVAL (param1 message id, param2 interval in µs; −1
stops the stream, 0 restores the default) changes the rate for every link (a
simulated vehicle has one telemetry schedule; PX4 keeps one per link). Rates
above :data:`MAX_RATE_HZ` are capped; a message the vehicle does not stream is
UNSUPPORTED. The stream after each Eq. (1) step is not affected.
"""

from __future__ import annotations

import math

from services.common import mav

m = mav.mavlink

MAX_RATE_HZ = 50.0
#: message id → default period (s)
DEFAULT_PERIOD_S: dict[int, float] = {
    m.MAVLINK_MSG_ID_HEARTBEAT: 1.0,
    m.MAVLINK_MSG_ID_LOCAL_POSITION_NED: 0.1,
    m.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 0.1,
    m.MAVLINK_MSG_ID_ATTITUDE: 0.1,
    m.MAVLINK_MSG_ID_SYS_STATUS: 1.0,
    m.MAVLINK_MSG_ID_GPS_RAW_INT: 1.0,
    m.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 1.0,
    m.MAVLINK_MSG_ID_MISSION_CURRENT: 1.0,
    m.MAVLINK_MSG_ID_HOME_POSITION: 5.0,
    m.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN: 5.0,
    # the plant's air, the flavour's own message while a plant flies (services/uavsim/wind.py)
    m.MAVLINK_MSG_ID_WIND_COV: 1.0,
    m.MAVLINK_MSG_ID_WIND: 1.0,
}


class Schedule:
    """The period of each streamed message (None: stopped) and when it is next due."""

    def __init__(self, now: float) -> None:
        self.period: dict[int, float | None] = dict(DEFAULT_PERIOD_S)
        self.next_due: dict[int, float] = {msg_id: now for msg_id in self.period}

    def set_interval(self, msg_id: int, interval_us: float, now: float) -> int:
        """Apply SET_MESSAGE_INTERVAL; returns the MAV_RESULT."""
        if msg_id not in self.period:
            return int(m.MAV_RESULT_UNSUPPORTED)
        if interval_us == -1:
            self.period[msg_id] = None
        elif interval_us == 0:
            self.period[msg_id] = DEFAULT_PERIOD_S[msg_id]
        elif interval_us > 0:
            self.period[msg_id] = max(interval_us / 1e6, 1.0 / MAX_RATE_HZ)
        else:
            return int(m.MAV_RESULT_DENIED)
        self.next_due[msg_id] = now
        return int(m.MAV_RESULT_ACCEPTED)

    def interval_us(self, msg_id: int) -> int:
        """The MESSAGE_INTERVAL answer: µs, −1 stopped, 0 not streamed."""
        if msg_id not in self.period:
            return 0
        period = self.period[msg_id]
        return -1 if period is None else int(period * 1e6)

    def due(self, now: float) -> list[int]:
        """The message ids due now (their next time is moved on)."""
        out = []
        for msg_id, period in self.period.items():
            if period is not None and now >= self.next_due[msg_id]:
                out.append(msg_id)
                nxt = self.next_due[msg_id] + period
                if nxt <= now:  # a stall: the missed periods are skipped (no burst), on the
                    # same grid (the vehicles of a host booted together keep sending together)
                    nxt += period * math.floor((now - nxt) / period + 1.0)
                self.next_due[msg_id] = nxt
        return out

    def wait_s(self, now: float) -> float:
        """Seconds until the next message is due."""
        times = [t for k, t in self.next_due.items() if self.period[k] is not None]
        return max(0.0, min(times, default=now + 1.0) - now)
