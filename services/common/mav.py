"""MAVLink 2 for the services (pymavlink): connections, signing keys, flight logs, geodesy, modes.

``MAVLINK20=1`` is set before pymavlink is imported (it picks the dialect at
import time). A ``udpin`` end binds and learns its peer from the first packet;
a ``udpout`` end must send first (a heartbeat) — see ARCHITECTURE §10.

Flight modes (HEARTBEAT ``custom_mode``) are read by the vehicle's
``autopilot`` field (services/common/mavmodes.py); ArduCopter's GUIDED (4,
offboard control) and LOITER (5, hold) are named here because the stack's
default vehicle claims ArduPilot.
"""

from __future__ import annotations

import hashlib
import math
import os
import struct
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

os.environ.setdefault("MAVLINK20", "1")

from pymavlink import mavutil  # noqa: E402

mavlink = mavutil.mavlink

#: MAVLink ids we use (pymavlink constants, re-exported for readability).
MAV_COMP_ID_AUTOPILOT1 = mavlink.MAV_COMP_ID_AUTOPILOT1
MAV_COMP_ID_ONBOARD_COMPUTER = mavlink.MAV_COMP_ID_ONBOARD_COMPUTER

#: ArduCopter's custom_mode of offboard control and hold (services/common/mavmodes.py)
MODE_GUIDED = 4
MODE_LOITER = 5

EARTH_RADIUS_M = 6_378_137.0
SIGNING_KEY_LEN = 32

# -- SET_POSITION_TARGET_LOCAL_NED ----------------------------------------------------------------
#: The setpoints' frame: LOCAL_NED (1), x north, y east, z down (m); altitude is ``-z``.
MAV_FRAME_LOCAL_NED = mavlink.MAV_FRAME_LOCAL_NED
#: POSITION_TARGET_TYPEMASK bit groups; a set bit means *ignore*.
TYPE_MASK_POSITION_BITS = (mavlink.POSITION_TARGET_TYPEMASK_X_IGNORE
                           | mavlink.POSITION_TARGET_TYPEMASK_Y_IGNORE
                           | mavlink.POSITION_TARGET_TYPEMASK_Z_IGNORE)  # bits 0-2
TYPE_MASK_VELOCITY_BITS = (mavlink.POSITION_TARGET_TYPEMASK_VX_IGNORE
                           | mavlink.POSITION_TARGET_TYPEMASK_VY_IGNORE
                           | mavlink.POSITION_TARGET_TYPEMASK_VZ_IGNORE)  # bits 3-5
TYPE_MASK_ACCEL_BITS = (mavlink.POSITION_TARGET_TYPEMASK_AX_IGNORE
                        | mavlink.POSITION_TARGET_TYPEMASK_AY_IGNORE
                        | mavlink.POSITION_TARGET_TYPEMASK_AZ_IGNORE)  # bits 6-8
TYPE_MASK_FORCE_BIT = mavlink.POSITION_TARGET_TYPEMASK_FORCE_SET  # bit 9
TYPE_MASK_YAW_BITS = (mavlink.POSITION_TARGET_TYPEMASK_YAW_IGNORE
                      | mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE)  # bits 10-11
#: type_mask: use position and velocity, ignore the rest (3520).
TYPE_MASK_POS_VEL = TYPE_MASK_ACCEL_BITS | TYPE_MASK_YAW_BITS
#: type_mask: position only (3576).
TYPE_MASK_POS = TYPE_MASK_POS_VEL | TYPE_MASK_VELOCITY_BITS


# -- signing --------------------------------------------------------------------------------------
def signing_key(passphrase: str) -> bytes:
    """The 32-byte key for a passphrase (sha256, as MAVProxy's ``signing key PASSPHRASE``)."""
    return hashlib.sha256(passphrase.encode()).digest()


def read_signing_key(path: str | Path) -> bytes:
    """The signing key in a file: exactly 32 bytes are the raw key; anything else is a
    passphrase (surrounding whitespace and the trailing newline stripped) hashed with sha256,
    as MAVProxy's signing module does. Raises ValueError for an empty file."""
    raw = Path(path).read_bytes()
    if len(raw) == SIGNING_KEY_LEN:
        return raw
    text = raw.decode("utf-8", errors="strict").strip()
    if not text:
        raise ValueError(f"signing key file {path} is empty")
    return signing_key(text)


def resolve_key(passphrase: str = "", key_file: str = "") -> bytes | None:
    """The key from ``key_file`` (preferred) or ``passphrase``; None when neither is set."""
    if key_file:
        return read_signing_key(key_file)
    if passphrase:
        return signing_key(passphrase)
    return None


def connect(url: str, source_system: int, source_component: int,
            passphrase: str = "", key: bytes | None = None, link_id: int | None = None) -> Any:
    """Open a pymavlink connection; with a key (or passphrase), sign outgoing and reject unsigned.

    A keyed connection accepts only frames signed with the same key; the others
    arrive as BAD_DATA and are counted in ``conn.mav.signing`` (badsig/unsigned/reject).
    ``link_id`` is the signing link id (default: pymavlink numbers links 0, 1, … a process).
    """
    if not url:
        raise ValueError("empty MAVLink URL")
    conn = mavutil.mavlink_connection(url, source_system=source_system,
                                      source_component=source_component, autoreconnect=True)
    if key is None and passphrase:
        key = signing_key(passphrase)
    if key is not None:
        if len(key) != SIGNING_KEY_LEN:
            raise ValueError(f"a MAVLink signing key has {SIGNING_KEY_LEN} bytes, got {len(key)}")
        # a callback that refuses everything makes pymavlink count the refusals (reject_count)
        conn.setup_signing(key, sign_outgoing=True,
                           allow_unsigned_callback=lambda _mav, _msg_id: False, link_id=link_id)
    return conn


def rejected_frames(conn: Any) -> int:
    """Frames a keyed connection refused (unsigned or wrongly signed); 0 without signing."""
    signing = getattr(conn.mav, "signing", None)
    if signing is None or signing.secret_key is None:
        return 0
    return int(signing.reject_count)


# -- telemetry log --------------------------------------------------------------------------------
class Tlog:
    """A ``.tlog`` as MAVProxy writes it: per frame an 8-byte big-endian µs timestamp, then the
    raw frame (``mavutil.mavfile.setup_logfile``). Flushed after every frame; thread-safe."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fh: IO[bytes] | None = self.path.open("wb")
        self._lock = threading.Lock()
        self.frames = 0

    def write(self, frame: bytes, t_s: float | None = None) -> None:
        usec = int((time.time() if t_s is None else t_s) * 1e6)
        with self._lock:
            if self._fh is None:
                return
            self._fh.write(struct.pack(">Q", usec) + bytes(frame))
            self._fh.flush()
            self.frames += 1

    def message(self, msg: Any) -> None:
        """Log a received or sent pymavlink message (BAD_DATA is skipped)."""
        if msg is not None and msg.get_type() != "BAD_DATA":
            self.write(msg.get_msgbuf())

    def close(self) -> None:
        with self._lock:
            if self._fh is not None:
                self._fh.close()
                self._fh = None


class Sender:
    """Serialises sends on one connection (pymavlink's sequence counter is not thread-safe);
    with a :class:`Tlog`, every frame sent is logged."""

    def __init__(self, conn: Any, tlog: Tlog | None = None):
        self.conn = conn
        self.mav = conn.mav
        self.lock = threading.Lock()
        self.tlog = tlog

    def __call__(self, name: str, *args: Any, **kwargs: Any) -> Any:
        """Send message ``name`` (``heartbeat``, ``command_long``, ...); returns the message."""
        msg = getattr(self.mav, f"{name}_encode")(*args, **kwargs)
        return self.message(msg)

    def message(self, msg: Any, log: bool = True) -> Any:
        with self.lock:
            self.mav.send(msg)
        if log and self.tlog is not None:
            self.tlog.message(msg)
        return msg


# -- the local frame on the map --------------------------------------------------------------------
def to_geodetic(east_m: float, north_m: float, origin: tuple[float, float]) -> tuple[float, float]:
    """Local metres east/north of ``origin`` (lat, lon degrees) → (lat, lon) degrees.

    Flat-earth (equirectangular) around the origin: over the 1 km area the
    error against WGS-84 is well below a metre.
    """
    lat0, lon0 = origin
    lat = lat0 + math.degrees(north_m / EARTH_RADIUS_M)
    lon = lon0 + math.degrees(east_m / (EARTH_RADIUS_M * math.cos(math.radians(lat0))))
    return lat, lon


def to_local(lat: float, lon: float, origin: tuple[float, float]) -> tuple[float, float]:
    """(lat, lon) degrees → local (east, north) metres of ``origin`` (inverse of to_geodetic)."""
    lat0, lon0 = origin
    north = math.radians(lat - lat0) * EARTH_RADIUS_M
    east = math.radians(lon - lon0) * EARTH_RADIUS_M * math.cos(math.radians(lat0))
    return east, north


# -- mission items --------------------------------------------------------------------------------
#: frames of waypoint items we accept: global, lat/lon as degrees or degE7, any altitude reference
GLOBAL_FRAMES = frozenset({
    mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_FRAME_GLOBAL_INT,
    mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
})
#: MAV_FRAME_GLOBAL(_INT) at seq 0 is ArduPilot's home slot (MAVProxy ``wp`` files start with it)
HOME_FRAMES = frozenset({mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_FRAME_GLOBAL_INT})


@dataclass(frozen=True)
class MissionItem:
    """One mission item as MISSION_ITEM_INT carries it (lat/lon in degE7, z in m)."""

    seq: int
    frame: int
    command: int
    current: int
    autocontinue: int
    param1: float
    param2: float
    param3: float
    param4: float
    x: int
    y: int
    z: float

    @staticmethod
    def from_msg(msg: Any) -> MissionItem:
        """From MISSION_ITEM_INT, or MISSION_ITEM (float degrees, rounded to degE7).

        Raises ValueError for a non-finite or out-of-range latitude/longitude
        (``"x"``/``"y"`` in the message, to pick the MAV_MISSION_* result).
        """
        if msg.get_type() == "MISSION_ITEM":
            for name, val, lim in (("x", msg.x, 90.0), ("y", msg.y, 180.0)):
                if not (math.isfinite(val) and abs(val) <= lim):
                    raise ValueError(name)
            x, y = round(msg.x * 1e7), round(msg.y * 1e7)
        else:
            x, y = int(msg.x), int(msg.y)
        return MissionItem(int(msg.seq), int(msg.frame), int(msg.command), int(msg.current),
                           int(msg.autocontinue), float(msg.param1), float(msg.param2),
                           float(msg.param3), float(msg.param4), x, y, float(msg.z))

    @property
    def lat(self) -> float:
        return self.x / 1e7

    @property
    def lon(self) -> float:
        return self.y / 1e7

    def is_home(self) -> bool:
        """ArduPilot's home slot: item 0 in an absolute-altitude global frame; not flown."""
        return self.seq == 0 and self.frame in HOME_FRAMES

    def is_waypoint(self) -> bool:
        return self.command == mavlink.MAV_CMD_NAV_WAYPOINT and not self.is_home()

    def fields(self, target: tuple[int, int], float_latlon: bool = False) -> tuple[Any, ...]:
        """MISSION_ITEM_INT's fields (MISSION_ITEM's with ``float_latlon``: degrees), up to
        but without ``mission_type``."""
        x, y = (self.lat, self.lon) if float_latlon else (self.x, self.y)
        return (target[0], target[1], self.seq, self.frame, self.command, self.current,
                self.autocontinue, self.param1, self.param2, self.param3, self.param4, x, y,
                self.z)

    def same(self, other: MissionItem) -> bool:
        """Field-wise equality where NaN equals NaN (an unset param of MISSION_ITEM_INT)."""
        for a, b in zip(self.__dict__.values(), other.__dict__.values(), strict=True):
            if a != b and not (isinstance(a, float) and isinstance(b, float)
                               and math.isnan(a) and math.isnan(b)):
                return False
        return True


def waypoints_local(items: list[MissionItem], origin: tuple[float, float]) -> list[tuple[float,
                                                                                          float]]:
    """The NAV_WAYPOINT items of a mission, in flying order, as local (east, north) metres."""
    return [to_local(it.lat, it.lon, origin) for it in items if it.is_waypoint()]
