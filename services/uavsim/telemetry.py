"""What the vehicle tells its links: position, attitude, status, GPS, home (the streamed messages).

LOCAL_POSITION_NED, GLOBAL_POSITION_INT and ATTITUDE at 10 Hz and after every
step; SYS_STATUS, GPS_RAW_INT, EXTENDED_SYS_STATE and MISSION_CURRENT at 1 Hz;
HOME_POSITION and GPS_GLOBAL_ORIGIN every 5 s, the plant's wind (WIND_COV or WIND,
services/uavsim/wind.py) at 1 Hz (services/uavsim/intervals.py,
changed by SET_MESSAGE_INTERVAL); a message on request (REQUEST_MESSAGE).
Altitudes: LOCAL_POSITION_NED ``z`` is −(height above home), GLOBAL_POSITION_INT
``alt`` is above mean sea level (home's AMSL altitude + the height),
``relative_alt`` above home; ``vz`` (down positive) the altitude controller's on the
vehicle's own clock, the 3-D Eq. (1)'s −v_z in lockstep under ``dim=3``, else 0.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from services.common import mav, mavlink_codec

from .autopilot import Autopilot
from .flavour import Nav
from .outbox import Outbox
from .wind import WIND_IDS, has_wind, send_wind

m = mav.mavlink
#: AUTOPILOT_VERSION.flight_sw_version: 0.1.0, release (major<<24 | minor<<16 | patch<<8 | type)
FLIGHT_SW_VERSION = (0 << 24) | (1 << 16) | (0 << 8) | 255
#: what the vehicle really does: MAVLink 2 and signing on the offboard link, MISSION_ITEM_INT
#: and MISSION_ITEM uploads (mission and, on its own clock, fence), float parameters,
#: SET_POSITION_TARGET_LOCAL_NED, COMMAND_INT (DO_REPOSITION). Not claimed: FTP, terrain,
#: SET_ATTITUDE_TARGET, rally points.
CAPABILITIES = (m.MAV_PROTOCOL_CAPABILITY_MAVLINK2 | m.MAV_PROTOCOL_CAPABILITY_MISSION_INT
                | m.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT | m.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
                | m.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
                | m.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
                | m.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE)
FAST = (m.MAVLINK_MSG_ID_LOCAL_POSITION_NED, m.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
        m.MAVLINK_MSG_ID_ATTITUDE)
SLOW = (m.MAVLINK_MSG_ID_SYS_STATUS, m.MAVLINK_MSG_ID_GPS_RAW_INT,
        m.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, m.MAVLINK_MSG_ID_MISSION_CURRENT)
HOME = (m.MAVLINK_MSG_ID_HOME_POSITION, m.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN)


class Telemetry:
    """The streamed messages of one vehicle, built from its :class:`Autopilot` and sent on
    ``outbox``; ``origin`` is the local frame's (deg lat, lon), ``home`` where it booted (m
    east, north) at ``home_amsl_m`` (m above mean sea level)."""

    def __init__(self, ap: Autopilot, outbox: Outbox, origin: tuple[float, float],
                 home: tuple[float, float], home_amsl_m: float):
        self.ap = ap
        self.outbox = outbox
        self.origin = origin
        self.home = home
        self.home_amsl_m = home_amsl_m

    def position(self, only: int | None = None, link: str | None = None) -> None:
        """LOCAL_POSITION_NED, GLOBAL_POSITION_INT and ATTITUDE (or ``only`` that one)."""
        v = self.ap.vehicle
        alt = self.ap.nav.alt
        n, e, _, vn, ve, vd = mavlink_codec.state_to_ned(v.state, alt)
        d = -alt  # 3-D in lockstep: the state's p_z in the air (Navigator.alt)
        if self.ap.own_clock:
            vd = -v.vz_mps
        elif self.ap.nav.landed:
            vd = 0.0
        t_ms = v.time_ms
        if only in (None, m.MAVLINK_MSG_ID_LOCAL_POSITION_NED):
            self.outbox.send(link, "local_position_ned", t_ms, n, e, d, vn, ve, vd)
        if only in (None, m.MAVLINK_MSG_ID_GLOBAL_POSITION_INT):
            lat, lon = mav.to_geodetic(float(v.state[0]), float(v.state[1]), self.origin)
            hdg = int(math.degrees(math.atan2(ve, vn)) % 360 * 100) if (vn or ve) else 65535
            self.outbox.send(link, "global_position_int", t_ms, int(lat * 1e7), int(lon * 1e7),
                             int((self.home_amsl_m + alt) * 1000), int(alt * 1000),
                             int(vn * 100), int(ve * 100), int(vd * 100), hdg)
        if only in (None, m.MAVLINK_MSG_ID_ATTITUDE):
            roll, pitch, yaw = v.attitude()
            self.outbox.send(link, "attitude", t_ms, roll, pitch, yaw, 0.0, 0.0, 0.0)

    def status(self, only: int | None = None, link: str | None = None) -> None:
        """SYS_STATUS, GPS_RAW_INT, EXTENDED_SYS_STATE, MISSION_CURRENT (or ``only`` one)."""
        v = self.ap.vehicle
        if only in (None, m.MAVLINK_MSG_ID_SYS_STATUS):
            sensors = (m.MAV_SYS_STATUS_SENSOR_3D_GYRO | m.MAV_SYS_STATUS_SENSOR_3D_ACCEL
                       | m.MAV_SYS_STATUS_SENSOR_3D_MAG | m.MAV_SYS_STATUS_SENSOR_GPS
                       | m.MAV_SYS_STATUS_SENSOR_BATTERY | m.MAV_SYS_STATUS_PREARM_CHECK)
            # the pre-arm check bit while there is charge left (MAVSDK's is_armable)
            healthy = sensors if v.battery_fraction > 0 else (
                sensors & ~m.MAV_SYS_STATUS_PREARM_CHECK)
            self.outbox.send(link, "sys_status", sensors, sensors, healthy, 100,
                             int(v.voltage_v * 1000), -1, int(round(v.battery_fraction * 100)),
                             0, min(int(self.ap.params["SIG_REJECTED"]), 65535), 0, 0, 0, 0)
        if only in (None, m.MAVLINK_MSG_ID_GPS_RAW_INT):
            lat, lon = mav.to_geodetic(float(v.state[0]), float(v.state[1]), self.origin)
            k = v.dyn.dim  # the velocity's first entry
            ve, vn = float(v.state[k]), float(v.state[k + 1])
            speed = math.hypot(ve, vn)
            cog = int(math.degrees(math.atan2(ve, vn)) % 360 * 100) if speed else 0
            self.outbox.send(link, "gps_raw_int", v.time_ms * 1000, m.GPS_FIX_TYPE_3D_FIX,
                             int(lat * 1e7), int(lon * 1e7),
                             int((self.home_amsl_m + self.ap.nav.alt) * 1000), 80, 120,
                             int(speed * 100), cog, 14)
        if only in (None, m.MAVLINK_MSG_ID_EXTENDED_SYS_STATE):
            self.outbox.send(link, "extended_sys_state", m.MAV_VTOL_STATE_UNDEFINED,
                             self.landed_state())
        if only in (None, m.MAVLINK_MSG_ID_MISSION_CURRENT):
            self.ap.mission.send_current(link)

    def landed_state(self) -> int:
        nav, ap = self.ap.commander.nav, self.ap
        if ap.nav.landed:
            return int(m.MAV_LANDED_STATE_ON_GROUND)
        if nav is Nav.TAKEOFF and ap.vehicle.vz_mps > 0:
            return int(m.MAV_LANDED_STATE_TAKEOFF)
        if nav is Nav.LAND and ap.vehicle.vz_mps < 0:
            return int(m.MAV_LANDED_STATE_LANDING)
        return int(m.MAV_LANDED_STATE_IN_AIR)

    def home_position(self, only: int | None = None, link: str | None = None) -> None:
        """HOME_POSITION and GPS_GLOBAL_ORIGIN (or ``only`` one)."""
        lat, lon = mav.to_geodetic(*self.home, self.origin)
        t_us = self.ap.vehicle.time_ms * 1000
        amsl_mm = int(self.home_amsl_m * 1000)
        if only in (None, m.MAVLINK_MSG_ID_HOME_POSITION):
            self.outbox.send(link, "home_position", int(lat * 1e7), int(lon * 1e7), amsl_mm,
                             self.home[1], self.home[0], 0.0, [1.0, 0.0, 0.0, 0.0],
                             0.0, 0.0, 0.0, t_us)
        if only in (None, m.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN):
            self.outbox.send(link, "gps_global_origin", int(self.origin[0] * 1e7),
                             int(self.origin[1] * 1e7), amsl_mm, t_us)

    def stream(self, msg_id: int, link: str | None = None) -> None:
        """Send one scheduled (or requested) message."""
        if msg_id == m.MAVLINK_MSG_ID_HEARTBEAT:
            self.ap.heartbeat()
        elif msg_id in HOME:
            self.home_position(only=msg_id, link=link)
        elif msg_id in FAST:
            self.position(only=msg_id, link=link)
        elif msg_id in WIND_IDS:  # the plant's air (services/uavsim/wind.py)
            send_wind(self.ap, self.outbox, msg_id, self.home_amsl_m + self.ap.nav.alt, link)
        else:
            self.status(only=msg_id, link=link)

    def sender(self, link: str, msg_id: int) -> Callable[[], None] | None:
        """The function that answers REQUEST_MESSAGE of ``msg_id`` on ``link`` (None: not one
        the vehicle has)."""
        if msg_id == m.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
            return lambda: self.outbox.send(link, "autopilot_version", CAPABILITIES,
                                            FLIGHT_SW_VERSION, 0, 0, 0, [0] * 8, [0] * 8,
                                            [0] * 8, 0, 0, self.ap.sysid)
        if msg_id == m.MAVLINK_MSG_ID_HOME_POSITION:  # and the origin with it
            return lambda: self.home_position(link=link)
        if msg_id in WIND_IDS and not has_wind(self.ap, msg_id):
            return None
        if msg_id in (*FAST, *SLOW, *HOME, *WIND_IDS, m.MAVLINK_MSG_ID_HEARTBEAT):
            return lambda: self.stream(msg_id, link)
        return None
