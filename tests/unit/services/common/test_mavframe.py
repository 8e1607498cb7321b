"""The stream process's own MAVLink 2 framing, byte for byte against pymavlink's.

pymavlink (the dialect the rest of the stack speaks) frames the same
HEARTBEAT and SET_POSITION_TARGET_LOCAL_NED with the same sequence numbers,
and signs them with the same key, link id and timestamp; the frames must be
identical, and pymavlink must parse ours back (checksum and signature
checked) to the values sent.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from services.common import mavframe

os.environ.setdefault("MAVLINK20", "1")
from pymavlink.dialects.v20 import ardupilotmega as dialect  # noqa: E402

KEY = bytes(range(32))


def pymav(sysid: int, compid: int, key: bytes | None, link_id: int, timestamp: int) -> object:
    mav = dialect.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.sign_outgoing = True
        mav.signing.link_id = link_id
        mav.signing.timestamp = timestamp
    return mav


def test_crc_matches_the_known_check_value() -> None:
    # CRC-16/MCRF4XX of "123456789" is 0x6F91 (the catalogue's check value)
    assert mavframe.x25crc(b"123456789") == 0x6F91


@pytest.mark.parametrize("key", [None, KEY])
def test_frames_are_pymavlinks_byte_for_byte(key: bytes | None) -> None:
    rng = np.random.default_rng(3)
    ts = mavframe.signing_timestamp(1.8e9)
    ours = mavframe.Framer(7, 191, key, link_id=5, timestamp=ts)
    theirs = pymav(7, 191, key, 5, ts)
    for k in range(300):  # the sequence wraps past 255
        if k % 7 == 0:
            a = ours.heartbeat(18, 8, 0, k, 4)
            b = theirs.heartbeat_encode(18, 8, 0, k, 4).pack(theirs)  # type: ignore[attr-defined]
        else:
            ned = tuple(float(v) for v in rng.normal(0, 300, 6))
            if k % 11 == 0:
                ned = (0.0,) * 6  # a payload of trailing zeros
            a = ours.set_position_target_local_ned(1000 * k, 1, 1, 1, 3520, ned)
            b = theirs.set_position_target_local_ned_encode(  # type: ignore[attr-defined]
                1000 * k, 1, 1, 1, 3520, *ned, 0, 0, 0, 0, 0).pack(theirs)
        assert a == bytes(b), k
        theirs.seq = (theirs.seq + 1) % 256  # type: ignore[attr-defined]  # send() does this


def test_pymavlink_parses_our_signed_frames_back() -> None:
    framer = mavframe.Framer(3, 191, KEY, link_id=1)
    rx = dialect.MAVLink(None)
    rx.signing.secret_key = KEY
    rx.signing.allow_unsigned_callback = lambda *_: False
    frames = [framer.heartbeat(18, 8),
              framer.set_position_target_local_ned(4200, 3, 1, 1, 3520,
                                                   (10.5, -3.0, -50.0, 1.0, 2.0, 0.0))]
    msgs = [rx.parse_char(f) for f in frames]
    assert [msg.get_type() for msg in msgs] == ["HEARTBEAT", "SET_POSITION_TARGET_LOCAL_NED"]
    sp = msgs[1]
    assert (sp.time_boot_ms, sp.target_system, sp.type_mask) == (4200, 3, 3520)
    assert (sp.x, sp.y, sp.z, sp.vx, sp.vy) == (10.5, -3.0, -50.0, 1.0, 2.0)
    assert msgs[0].get_srcSystem() == 3 and msgs[0].get_srcComponent() == 191
    tampered = bytearray(framer.heartbeat(18, 8))
    tampered[-1] ^= 1  # the signature
    with pytest.raises(dialect.MAVError, match="signature"):
        rx.parse_char(bytes(tampered))
    corrupt = bytearray(framer.heartbeat(18, 8))
    corrupt[12] ^= 1  # a payload byte: the checksum
    with pytest.raises(dialect.MAVError, match="CRC"):
        rx.parse_char(bytes(corrupt))


def test_bad_ids_and_keys_are_refused() -> None:
    with pytest.raises(ValueError):
        mavframe.Framer(256, 1)
    with pytest.raises(ValueError, match="32 bytes"):
        mavframe.Framer(1, 1, b"short")
