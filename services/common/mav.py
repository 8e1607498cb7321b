"""MAVLink 2 connections for the services (pymavlink), with optional signing.

``MAVLINK20=1`` is set before pymavlink is imported (it picks the dialect at
import time). A ``udpin`` end binds and learns its peer from the first packet;
a ``udpout`` end must send first (a heartbeat) — see ARCHITECTURE §10.
"""

from __future__ import annotations

import hashlib
import os
import threading
from typing import Any

os.environ.setdefault("MAVLINK20", "1")

from pymavlink import mavutil  # noqa: E402

mavlink = mavutil.mavlink

#: MAVLink message ids we use (pymavlink constants, re-exported for readability).
MAV_COMP_ID_AUTOPILOT1 = mavlink.MAV_COMP_ID_AUTOPILOT1
MAV_COMP_ID_ONBOARD_COMPUTER = mavlink.MAV_COMP_ID_ONBOARD_COMPUTER


def signing_key(passphrase: str) -> bytes:
    """The 32-byte key for a passphrase (sha256, as MAVProxy's ``signing key``)."""
    return hashlib.sha256(passphrase.encode()).digest()


def connect(url: str, source_system: int, source_component: int,
            passphrase: str = "") -> Any:
    """Open a pymavlink connection; with a passphrase, sign outgoing and reject unsigned."""
    if not url:
        raise ValueError("empty MAVLink URL")
    conn = mavutil.mavlink_connection(url, source_system=source_system,
                                      source_component=source_component, autoreconnect=True)
    if passphrase:
        conn.setup_signing(signing_key(passphrase), sign_outgoing=True)
    return conn


class Sender:
    """Serialises sends on one connection (pymavlink's sequence counter is not thread-safe)."""

    def __init__(self, conn: Any):
        self.conn = conn
        self.mav = conn.mav
        self.lock = threading.Lock()

    def __call__(self, name: str, *args: Any, **kwargs: Any) -> None:
        with self.lock:
            getattr(self.mav, f"{name}_send")(*args, **kwargs)
