"""What the vehicle tells its links: position, attitude, status, GPS, home (the streamed messages).

LOCAL_POSITION_NED, GLOBAL_POSITION_INT and ATTITUDE at 10 Hz and after every
step; SYS_STATUS, GPS_RAW_INT, EXTENDED_SYS_STATE and MISSION_CURRENT at 1 Hz;
HOME_POSITION and GPS_GLOBAL_ORIGIN every 5 s (services/uavsim/intervals.py,
changed by SET_MESSAGE_INTERVAL).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from services.common import mav, mavlink_codec

if TYPE_CHECKING:
    from .endpoint import Endpoint

m = mav.mavlink


def telemetry(ep: Endpoint, only: int | None = None) -> None:
    """LOCAL_POSITION_NED, GLOBAL_POSITION_INT and ATTITUDE (or ``only`` that one)."""
    x = ep.vehicle.state
    alt = ep.altitude_m
    n, e, d, vn, ve, vd = mavlink_codec.state_to_ned(x, alt)
    lat, lon = mav.to_geodetic(float(x[0]), float(x[1]), ep.origin)
    t_ms = ep.vehicle.time_ms
    hdg = int(math.degrees(math.atan2(ve, vn)) % 360 * 100) if (vn or ve) else 65535
    roll, pitch, yaw = ep.vehicle.attitude()
    if only in (None, m.MAVLINK_MSG_ID_LOCAL_POSITION_NED):
        ep.broadcast("local_position_ned", t_ms, n, e, d, vn, ve, vd)
    if only in (None, m.MAVLINK_MSG_ID_GLOBAL_POSITION_INT):
        ep.broadcast("global_position_int", t_ms, int(lat * 1e7), int(lon * 1e7),
                     int(alt * 1000), int(alt * 1000), int(vn * 100), int(ve * 100),
                     int(vd * 100), hdg)
    if only in (None, m.MAVLINK_MSG_ID_ATTITUDE):
        ep.broadcast("attitude", t_ms, roll, pitch, yaw, 0.0, 0.0, 0.0)


def slow_telemetry(ep: Endpoint, only: int | None = None) -> None:
    """SYS_STATUS, GPS_RAW_INT, EXTENDED_SYS_STATE, MISSION_CURRENT (or ``only`` one)."""
    v = ep.vehicle
    if only in (None, m.MAVLINK_MSG_ID_SYS_STATUS):
        sensors = (m.MAV_SYS_STATUS_SENSOR_3D_GYRO | m.MAV_SYS_STATUS_SENSOR_3D_ACCEL
                   | m.MAV_SYS_STATUS_SENSOR_3D_MAG | m.MAV_SYS_STATUS_SENSOR_GPS
                   | m.MAV_SYS_STATUS_SENSOR_BATTERY | m.MAV_SYS_STATUS_PREARM_CHECK)
        # the pre-arm check passes while there is charge left (arming's only condition)
        healthy = sensors if v.battery_fraction > 0 else (
            sensors & ~m.MAV_SYS_STATUS_PREARM_CHECK)
        ep.broadcast("sys_status", sensors, sensors, healthy, 100,
                     int(v.voltage_v * 1000), -1, int(round(v.battery_fraction * 100)), 0,
                     min(int(ep.p("SIG_REJECTED")), 65535), 0, 0, 0, 0)
    if only in (None, m.MAVLINK_MSG_ID_GPS_RAW_INT):
        x = v.state
        lat, lon = mav.to_geodetic(float(x[0]), float(x[1]), ep.origin)
        speed = math.hypot(float(x[2]), float(x[3]))
        cog = (int(math.degrees(math.atan2(float(x[2]), float(x[3]))) % 360 * 100)
               if speed else 0)
        ep.broadcast("gps_raw_int", v.time_ms * 1000, m.GPS_FIX_TYPE_3D_FIX,
                     int(lat * 1e7), int(lon * 1e7), int(ep.altitude_m * 1000), 80, 120,
                     int(speed * 100), cog, 14)
    if only in (None, m.MAVLINK_MSG_ID_EXTENDED_SYS_STATE):
        landed = (m.MAV_LANDED_STATE_IN_AIR if ep.airborne
                  else m.MAV_LANDED_STATE_ON_GROUND)
        ep.broadcast("extended_sys_state", m.MAV_VTOL_STATE_UNDEFINED, landed)
    if only in (None, m.MAVLINK_MSG_ID_MISSION_CURRENT):
        ep.mission.send_current()


def stream(ep: Endpoint, msg_id: int) -> None:
    """Send one scheduled telemetry message (services/uavsim/intervals.py) on every link."""
    if msg_id == m.MAVLINK_MSG_ID_HEARTBEAT:
        ep.heartbeat()
    elif msg_id in (m.MAVLINK_MSG_ID_HOME_POSITION, m.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN):
        home_position(ep, only=msg_id)
    elif msg_id in (m.MAVLINK_MSG_ID_LOCAL_POSITION_NED, m.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
                    m.MAVLINK_MSG_ID_ATTITUDE):
        telemetry(ep, only=msg_id)
    else:
        slow_telemetry(ep, only=msg_id)


def home_position(ep: Endpoint, link: str | None = None, only: int | None = None) -> None:
    """HOME_POSITION and GPS_GLOBAL_ORIGIN, on every link or on ``link`` (or ``only`` one)."""
    lat, lon = mav.to_geodetic(*ep.home_local, ep.origin)
    args = (int(lat * 1e7), int(lon * 1e7), 0, ep.home_local[1], ep.home_local[0], 0.0,
            [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, ep.vehicle.time_ms * 1000)
    origin = (int(ep.origin[0] * 1e7), int(ep.origin[1] * 1e7), 0,
              ep.vehicle.time_ms * 1000)
    if link is None:
        if only in (None, m.MAVLINK_MSG_ID_HOME_POSITION):
            ep.broadcast("home_position", *args)
        if only in (None, m.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN):
            ep.broadcast("gps_global_origin", *origin)
    else:
        ep.send[link]("home_position", *args)
        ep.send[link]("gps_global_origin", *origin)
