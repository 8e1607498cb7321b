"""The two MAVLink 2 frames the setpoint stream sends, framed and signed with the stdlib alone.

The stream process (services/supervisor/stream/) must stay small and start
fast, so it does not load pymavlink's dialect (about 30 MB): it needs only
HEARTBEAT (id 0) and SET_POSITION_TARGET_LOCAL_NED (id 84). Each frame is
MAVLink 2 (https://mavlink.io/en/guide/serialization.html): magic 0xFD,
payload length, incompat flags (0x01: signed), compat flags, sequence,
system id, component id, the 24-bit message id, the payload with its
trailing zero bytes cut (as MAVLink 2 sends it), CRC-16/MCRF4XX over
everything after the magic plus the message's CRC_EXTRA, and, when signed,
link id, a 48-bit timestamp (10 µs units since 2015-01-01, +1 a frame) and
the first 6 bytes of sha256(key + frame up to the timestamp).
tests/unit/services/common/test_mavframe.py checks every byte against pymavlink.
"""

from __future__ import annotations

import hashlib
import struct
import time
from dataclasses import dataclass, field

MAGIC_V2 = 0xFD
IFLAG_SIGNED = 0x01
MAVLINK_VERSION = 3  # HEARTBEAT.mavlink_version
#: seconds from the unix epoch to 2015-01-01, the signing timestamp's epoch
SIGNING_EPOCH_S = 1420070400

#: id, CRC_EXTRA and wire format (fields by size, as in the dialect) of the frames we send
HEARTBEAT = (0, 50, struct.Struct("<IBBBBB"))
SET_POSITION_TARGET_LOCAL_NED = (84, 143, struct.Struct("<I11fHBBB"))


def _crc_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0x8408 if crc & 1 else crc >> 1
        table.append(crc)
    return tuple(table)


_TABLE = _crc_table()


def x25crc(data: bytes, crc: int = 0xFFFF) -> int:
    """CRC-16/MCRF4XX (MAVLink's "X.25" checksum) of ``data``."""
    for byte in data:
        crc = (crc >> 8) ^ _TABLE[(crc ^ byte) & 0xFF]
    return crc


def signing_timestamp(now_s: float | None = None) -> int:
    """MAVLink's signing timestamp for ``now_s`` (unix s; default now): 10 µs units since 2015."""
    t = time.time() if now_s is None else now_s
    return int(max(t - SIGNING_EPOCH_S, 0.0) * 100_000)


@dataclass
class Framer:
    """Frames messages from one (system, component), optionally signed on ``link_id``."""

    sysid: int
    compid: int
    key: bytes | None = None
    link_id: int = 0
    seq: int = 0
    timestamp: int = field(default_factory=signing_timestamp)

    def __post_init__(self) -> None:
        if not (0 <= self.sysid <= 255 and 0 <= self.compid <= 255 and 0 <= self.link_id <= 255):
            raise ValueError("system, component and link ids are bytes")
        if self.key is not None and len(self.key) != 32:
            raise ValueError(f"a MAVLink signing key has 32 bytes, got {len(self.key)}")

    def frame(self, msg_id: int, crc_extra: int, payload: bytes) -> bytes:
        """One MAVLink 2 frame carrying ``payload``; advances the sequence (and timestamp)."""
        body = payload.rstrip(b"\x00") or payload[:1]  # MAVLink 2 cuts trailing zeros
        signed = self.key is not None
        header = struct.pack("<BBBBBBBHB", MAGIC_V2, len(body), IFLAG_SIGNED if signed else 0,
                             0, self.seq, self.sysid, self.compid, msg_id & 0xFFFF,
                             msg_id >> 16)
        self.seq = (self.seq + 1) & 0xFF
        crc = x25crc(bytes([crc_extra]), x25crc(header[1:] + body))
        out = header + body + struct.pack("<H", crc)
        if not signed:
            return out
        assert self.key is not None
        out += struct.pack("<BQ", self.link_id, self.timestamp)[:7]
        self.timestamp += 1
        return out + hashlib.sha256(self.key + out).digest()[:6]

    def heartbeat(self, mav_type: int, autopilot: int, base_mode: int = 0, custom_mode: int = 0,
                  system_status: int = 0) -> bytes:
        msg_id, extra, fmt = HEARTBEAT
        return self.frame(msg_id, extra, fmt.pack(custom_mode, mav_type, autopilot, base_mode,
                                                  system_status, MAVLINK_VERSION))

    def set_position_target_local_ned(self, time_boot_ms: int, target_system: int,
                                      target_component: int, frame: int, type_mask: int,
                                      ned: tuple[float, ...]) -> bytes:
        """``ned`` = (x, y, z, vx, vy, vz) north-east-down m and m/s; accelerations, yaw 0."""
        msg_id, extra, fmt = SET_POSITION_TARGET_LOCAL_NED
        values = (*ned, 0.0, 0.0, 0.0, 0.0, 0.0)
        return self.frame(msg_id, extra, fmt.pack(int(time_boot_ms) & 0xFFFFFFFF, *values,
                                                  type_mask, target_system, target_component,
                                                  frame))
