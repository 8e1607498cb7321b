"""Bad input on both MAVLink ports of uavsim: rejected, counted, logged briefly, never flown.

Every datagram of the corpus carries exactly one problem, so the counter it
must land in (``mavlink/offboard`` or ``mavlink/gcs`` × reason, uavsim's
status) is known: random bytes (any framing reason; a datagram that happens
to decode to a real message is not sent), truncated frames, bad CRCs,
oversize datagrams, MAVLink 1 frames, unknown message ids, valid frames of
types the vehicle does not accept, frames for another system, NaN/±inf in
SET_POSITION_TARGET_LOCAL_NED / MISSION_ITEM(_INT) / PARAM_SET, ±inf in
COMMAND_INT (NaN there is DO_REPOSITION's "unchanged") and COMMAND_LONG, or NaN
(MAVLink's "unset") in a parameter the command needs, setpoints far outside the
area or due far in the future, out-of-range parameters and oversized missions. While the fuzzer
sends, a companion streams a hold setpoint: the vehicle must not move, must
not crash, and must still fly a good setpoint afterwards. Only 127.0.0.1.
"""

from __future__ import annotations

import collections
import contextlib
import math
import random
import socket
import threading
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from pymavlink.dialects.v10 import ardupilotmega as v1dialect

from dualpilot.model.dynamics import step
from integration.test_uavsim import connect, position, send_setpoint, take_off
from services.common import bus, mav
from services.launch import free_port

pytestmark = pytest.mark.timeout(300)
m = mav.mavlink
HOME = (35.0, 33.0)
QUICK_INPUTS = 300
SLOW_INPUTS = 10_000
FRAMING = {"malformed", "bad_crc", "unknown_message", "mavlink1"}
#: messages the vehicle sends: a ground station or companion must not send them to it
WRONG_TYPES = ("attitude", "gps_raw_int", "local_position_ned", "vfr_hud", "battery_status")
#: COMMAND_LONG commands of the corpus → the parameters (1-based) each needs (NaN there: refused)
COMMAND_NEEDS: dict[int, tuple[int, ...]] = {
    m.MAV_CMD_COMPONENT_ARM_DISARM: (1,), m.MAV_CMD_DO_SET_MODE: (1, 2),
    m.MAV_CMD_REQUEST_MESSAGE: (1,), m.MAV_CMD_NAV_TAKEOFF: (),
}


class Corpus:
    """Datagrams with exactly one problem each, and the reason the vehicle must count."""

    KINDS = ("random", "truncated", "bad_crc", "oversize", "mavlink1", "unknown_id",
             "wrong_type", "wrong_target", "setpoint_nan", "setpoint_far", "setpoint_late",
             "setpoint_frame", "mission_nan", "mission_far", "mission_count", "param_nan",
             "param_range", "param_unknown", "command_nan", "command_int_nan")

    def __init__(self, seed: int, sysid: int = 1):
        self.rng = random.Random(seed)
        self.enc = m.MAVLink(None, 250, 190)
        self.enc1 = v1dialect.MAVLink(None, 250, 190)
        self.sysid = sysid

    def _pack(self, msg: Any) -> bytes:
        return bytes(msg.pack(self.enc))

    def _bad(self) -> float:
        return self.rng.choice([math.nan, math.inf, -math.inf])

    def _setpoint(self, n: float = 500.0, e: float = 500.0, vn: float = 0.0, ve: float = 0.0,
                  z: float = -50.0, t_ms: int = 0, frame: int = 1, mask: int = 3520) -> bytes:
        return self._pack(self.enc.set_position_target_local_ned_encode(
            t_ms, self.sysid, 1, frame, mask, n, e, z, vn, ve, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))

    def _good_frame(self) -> bytes:
        return self.rng.choice([
            lambda: self._pack(self.enc.heartbeat_encode(6, 8, 0, 0, 0)),
            lambda: self._setpoint(),
            lambda: self._pack(self.enc.param_request_list_encode(self.sysid, 1)),
        ])()

    def _mission_item(self, x: int, y: int, z: float, p1: float = 0.0) -> bytes:
        return self._pack(self.enc.mission_item_int_encode(
            self.sysid, 1, 0, m.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, m.MAV_CMD_NAV_WAYPOINT, 0, 1,
            p1, 0.0, 0.0, 0.0, x, y, z, 0))

    @staticmethod
    def decodes(data: bytes) -> bool:
        """True if a fresh parser gets a real message out of ``data`` (would be acted on)."""
        parser = m.MAVLink(None, 1, 1)
        parser.robust_parsing = True
        for msg in parser.parse_buffer(data) or []:
            kind = msg.get_type()
            if kind != "BAD_DATA" and not kind.startswith("UNKNOWN_"):
                return True
        return False

    def one(self, kind: str) -> tuple[bytes, str | None]:
        r = self.rng
        lat0, lon0 = HOME
        if kind == "random":
            while True:
                data = bytes(r.getrandbits(8) for _ in range(r.randint(1, 300)))
                if r.random() < 0.3:  # start like a frame to reach deeper parser states
                    data = bytes([r.choice([0xFD, 0xFE])]) + data
                if not self.decodes(data):
                    return data, None
        if kind == "truncated":
            frame = self._good_frame()
            return frame[: r.randint(1, len(frame) - 1)], "malformed"
        if kind == "bad_crc":
            flipped = bytearray(self._good_frame())
            flipped[-1 - r.randint(0, 1)] ^= r.randint(1, 255)
            return bytes(flipped), "bad_crc"
        if kind == "oversize":
            return bytes(r.getrandbits(8) for _ in range(r.randint(4097, 9000))), "too_large"
        if kind == "mavlink1":
            msg = r.choice([self.enc1.param_request_list_encode(self.sysid, 1),
                            self.enc1.set_position_target_local_ned_encode(
                                0, self.sysid, 1, 1, 3520, 500, 500, -50, 0, 0, 0, 0, 0, 0, 0,
                                0),
                            self.enc1.command_long_encode(self.sysid, 1, 400, 0, 1, 0, 0, 0, 0,
                                                          0, 0)])
            return bytes(msg.pack(self.enc1)), "mavlink1"
        if kind == "unknown_id":
            while True:
                msgid = r.randint(1, 2**24 - 1)
                if msgid not in m.mavlink_map:
                    break
            payload = bytes(r.getrandbits(8) for _ in range(r.randint(1, 40)))
            head = bytes([0xFD, len(payload), 0, 0, r.randint(0, 255), 250, 190,
                          msgid & 0xFF, (msgid >> 8) & 0xFF, msgid >> 16])
            return head + payload + bytes([r.getrandbits(8), r.getrandbits(8)]), \
                "unknown_message"
        if kind == "wrong_type":
            name = r.choice(WRONG_TYPES)
            fn = getattr(self.enc, f"{name}_encode")
            args = {"attitude": (0, 0.1, 0.1, 0.1, 0, 0, 0),
                    "gps_raw_int": (0, 3, 0, 0, 0, 0, 0, 0, 0, 10),
                    "local_position_ned": (0, 1.0, 2.0, -50.0, 0, 0, 0),
                    "vfr_hud": (0, 0, 0, 0, 50, 0),
                    "battery_status": (0, 0, 0, 0, [0] * 10, 0, 0, 0, 50)}[name]
            return self._pack(fn(*args)), "wrong_type"
        if kind == "wrong_target":
            other = r.choice([s for s in (2, 3, 42, 254, 255) if s != self.sysid])
            msg = r.choice([
                self.enc.param_request_list_encode(other, 1),
                self.enc.command_long_encode(other, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0),
                self.enc.set_position_target_local_ned_encode(0, other, 1, 1, 3520, 1, 1, -50,
                                                              0, 0, 0, 0, 0, 0, 0, 0)])
            return self._pack(msg), "wrong_target"
        if kind == "setpoint_nan":
            vals = [500.0, 500.0, 0.0, 0.0, -50.0]
            vals[r.randrange(5)] = self._bad()
            n, e, vn, ve, z = vals
            return self._setpoint(n, e, vn, ve, z), "not_finite"
        if kind == "setpoint_far":
            far = r.choice([-5000.0, 1300.0, 5e4, 9e4, -9e4])
            n, e = (far, 500.0) if r.random() < 0.5 else (500.0, far)
            return self._setpoint(n, e), "out_of_range"
        if kind == "setpoint_late":
            return self._setpoint(t_ms=r.randint(700_000_000, 2**32 - 1)), "out_of_range"
        if kind == "setpoint_frame":
            return self._setpoint(frame=r.choice([0, 7, 8, 9]), mask=r.choice([3520, 0, 7])), \
                "invalid"
        if kind == "mission_nan":
            x, y = int((lat0 + 0.004) * 1e7), int((lon0 + 0.004) * 1e7)
            if r.random() < 0.5:
                return self._mission_item(x, y, self._bad()), "not_finite"
            return self._mission_item(x, y, 50.0, p1=r.choice([math.inf, -math.inf])), \
                "not_finite"
        if kind == "mission_far":
            x, y = int((lat0 + 0.004) * 1e7), int((lon0 + 0.004) * 1e7)
            if r.random() < 0.5:
                x = int((lat0 + r.choice([-1.0, 0.5, 20.0])) * 1e7)
            else:
                y = int((lon0 + r.choice([-1.0, 0.5, 20.0])) * 1e7)
            return self._mission_item(x, y, 50.0), "out_of_range"
        if kind == "mission_count":
            return self._pack(self.enc.mission_count_encode(
                self.sysid, 1, r.randint(501, 65535), 0)), "size"
        if kind == "param_nan":
            return self._pack(self.enc.param_set_encode(
                self.sysid, 1, b"COM_OF_LOSS_T", self._bad(), 9)), "not_finite"
        if kind == "param_range":
            pname, value = r.choice([(b"COM_OF_LOSS_T", 1e9), (b"SIM_U_MAX_N", 75.0),
                                     (b"MPC_XY_VEL_MAX", -1.0), (b"SIM_ALT_M", 1e6)])
            return self._pack(self.enc.param_set_encode(self.sysid, 1, pname, value, 9)), \
                "out_of_range"
        if kind == "param_unknown":
            pid = r.choice([b"NO_SUCH_PARAM", b"MIS_ID", b"SIG_REJECTED", b"\xff\xfe"])
            return self._pack(self.enc.param_set_encode(self.sysid, 1, pid, 1.0, 9)), "invalid"
        if kind == "command_nan":
            # NaN is "unset" in COMMAND_LONG (MAVSDK sends it): refused only in a parameter the
            # command needs; ±inf is refused anywhere
            params = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
            cmd = r.choice(list(COMMAND_NEEDS))
            if COMMAND_NEEDS[cmd] and r.random() < 0.5:
                params[r.choice(COMMAND_NEEDS[cmd]) - 1] = math.nan
            else:
                params[r.randrange(7)] = r.choice([math.inf, -math.inf])
            return self._pack(self.enc.command_long_encode(self.sysid, 1, cmd, 0, *params)), \
                "not_finite"
        if kind == "command_int_nan":  # ±inf: NaN in DO_REPOSITION is MAVLink's "unchanged"
            return self._pack(self.enc.command_int_encode(
                self.sysid, 1, 0, m.MAV_CMD_DO_REPOSITION, 0, 0,
                self.rng.choice([math.inf, -math.inf]), 0, 0, 0, 0, 0, 50.0)), "not_finite"
        raise ValueError(kind)

    def take(self, n: int) -> Iterator[tuple[bytes, str | None]]:
        for k in range(n):
            yield self.one(self.KINDS[k % len(self.KINDS)])


class Fuzzer:
    """A UDP socket on one vehicle port; sends in small batches, each closed by a barrier
    (a PARAM_REQUEST_READ the vehicle answers), so nothing is lost to a full socket buffer."""

    def __init__(self, port: int, sysid: int = 1):
        self.addr = ("127.0.0.1", port)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.2)
        self.enc = m.MAVLink(None, 250, 190)
        self.parser = m.MAVLink(None, 250, 190)
        self.parser.robust_parsing = True
        self.sysid = sysid

    def barrier(self, timeout_s: float = 10.0) -> None:
        # a fresh index each time, and late answers to the previous barrier drained first,
        # so a stale PARAM_VALUE can never end this one early
        self.index = (getattr(self, "index", -1) + 1) % 5
        index = self.index
        self.sock.setblocking(False)
        with contextlib.suppress(BlockingIOError):
            while self.sock.recv(65536):
                pass
        self.sock.settimeout(0.2)
        req = self.enc.param_request_read_encode(self.sysid, 1, b"", index).pack(self.enc)
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            self.sock.sendto(req, self.addr)
            end = time.monotonic() + 1.0
            while time.monotonic() < end:
                try:
                    data = self.sock.recv(65536)
                except TimeoutError:
                    break
                self.parser.buf, self.parser.buf_index = bytearray(), 0
                for msg in self.parser.parse_buffer(data) or []:
                    if msg.get_type() == "PARAM_VALUE" and msg.param_index == index:
                        return
        raise TimeoutError("the vehicle did not answer the barrier")

    def send(self, inputs: Iterator[tuple[bytes, str | None]]) -> collections.Counter[str]:
        sent: collections.Counter[str] = collections.Counter()
        batch_bytes = batch = 0
        for data, reason in inputs:
            self.sock.sendto(data, self.addr)
            sent[reason or "(framing)"] += 1
            batch += 1
            batch_bytes += len(data) + 1024
            if batch >= 32 or batch_bytes > 96_000:
                self.barrier()
                batch = batch_bytes = 0
        self.barrier()
        return sent

    def close(self) -> None:
        self.sock.close()


@pytest.fixture
def vehicle(services: Any, liveliness: bus.Liveliness) -> Iterator[Any]:
    """A fresh vehicle per test: a fuzzed mode command on the GCS link can take control
    (the ground station's explicit take-over), which a later test must not inherit."""
    ports = {"offboard": free_port("udp"), "gcs": free_port("udp")}
    proc = services.start("uavsim", MAVLINK_URL=f"udpin:127.0.0.1:{ports['offboard']}",
                          GCS_URL=f"udpin:127.0.0.1:{ports['gcs']}", UAV_START="300,400",
                          UAV_HOME=f"{HOME[0]},{HOME[1]}")
    assert liveliness.wait_for(["uavsim"], 60), services.log("uavsim")[-2000:]
    services.ports = ports
    yield services
    services.group.stop(proc)
    services.group.procs.remove(proc)
    assert liveliness.wait_gone("uavsim", 30), "the test's uavsim did not stop"


def rejected(session: Any, link: str) -> collections.Counter[str]:
    st = bus.query_status(session, "itest", "uavsim")
    return collections.Counter(st["rejected"].get(f"mavlink/{link}", {}))


class Hold:
    """The companion: takes off, then streams a hold setpoint at 20 Hz until stopped."""

    def __init__(self, port: int):
        self.conn = connect(port, 1, 191)
        self.t, self.x = take_off(self.conn)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self.stop.is_set():
            send_setpoint(self.conn, self.x, self.t)
            time.sleep(0.05)

    def close(self) -> None:
        self.stop.set()
        self.thread.join(2)


def fuzz_both_ports(vehicle: Any, session: Any, n: int, seed: int) -> dict[str, Any]:
    hold = Hold(vehicle.ports["offboard"])
    try:
        t_before, x_before = position(hold.conn)
        results = {}
        for k, link in enumerate(("offboard", "gcs")):
            before = rejected(session, link)
            fuzzer = Fuzzer(vehicle.ports[link])
            t0 = time.monotonic()
            sent = fuzzer.send(Corpus(seed + k).take(n))
            wall = time.monotonic() - t0
            fuzzer.close()
            delta = rejected(session, link) - before
            results[link] = (sent, delta, wall)
        t_after, x_after = position(hold.conn)
        assert vehicle.group.dead() == [], vehicle.log("uavsim")[-3000:]
        assert np.all(np.isfinite(x_after))
        assert t_after == t_before and np.allclose(x_after, x_before), (x_before, x_after)
        # it still flies a good setpoint: one step of Eq. (1)
        hold.close()
        target = step(x_after, np.array([2.0, -1.0]))
        for _ in range(3):
            send_setpoint(hold.conn, target, t_after + 1000)
        t, got = position(hold.conn, t_after + 1000)
        assert t == t_after + 1000 and np.allclose(got, target, atol=1e-3), (got, target)
    finally:
        hold.close()
        hold.conn.close()
    for link, (sent, delta, _) in results.items():
        framing = sent.pop("(framing)", 0)
        expected = collections.Counter(sent)
        for reason, count in expected.items():
            assert delta[reason] >= count, (link, reason, delta, expected)
        extra = sum(delta.values()) - sum(expected.values())
        assert extra == framing, (link, delta, sent, framing)
        assert sum(delta[r] for r in FRAMING) >= framing
    return results


def test_quick_fuzz_both_ports(vehicle: Any, session: Any) -> None:
    results = fuzz_both_ports(vehicle, session, QUICK_INPUTS, seed=11)
    st = bus.query_status(session, "itest", "uavsim")
    for link in ("offboard", "gcs"):
        counts = st["rejected"][f"mavlink/{link}"]
        assert set(counts) <= set(st["reasons"]), counts
        assert sum(results[link][1].values()) == QUICK_INPUTS
    assert "rejected" in vehicle.log("uavsim")


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_fuzz_10k_inputs_per_port(vehicle: Any, session: Any) -> None:
    log_before = len(vehicle.log("uavsim"))
    results = fuzz_both_ports(vehicle, session, SLOW_INPUTS, seed=1234)
    grown = len(vehicle.log("uavsim")) - log_before
    for link, (_sent, delta, wall) in results.items():
        assert sum(delta.values()) == SLOW_INPUTS, (link, delta)
        print(f"\n{link}: {SLOW_INPUTS} datagrams in {wall:.1f} s; counted {dict(delta)}")
    assert grown < 2_000_000, f"the log grew by {grown} bytes"  # rate-limited lines
