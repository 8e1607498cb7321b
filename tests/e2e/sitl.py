"""A stand-alone uavsim as a SITL for the client tests, and a ground station that watches it.

MAVSDK's examples connect with a fixed connection string, ``udpin://…:14540``,
and expect the vehicle to send there, as PX4 SITL does. A test that follows
them call for call needs that port, so :func:`api_port` takes it for one
test at a time: an exclusive ``flock`` on :data:`LOCK` (any test run on this
machine that flies on 14540 takes it first, so parallel runs wait instead
of colliding), then a check that nothing else holds the port. If something
outside the project does, the test falls back to a free port, given to the
vehicle with ``--mavlink-url`` (the override stays tested) and to MAVSDK in
the same form of connection string. Everything is on 127.0.0.1.

:class:`Watch` is a pymavlink ground station on a vehicle's ground-station
link (or on MAVProxy's ``--out``): on a thread of its own it records every
HEARTBEAT, STATUSTEXT, MISSION_ITEM_REACHED and the newest of each other
message, so a test checks outcomes independently of the client it drives;
with ``speak`` it heartbeats once a second (a ``udpout`` side speaks first)
and sends commands (:meth:`Watch.command`).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import socket
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from services.common import mav
from services.launch import REPO, ProcessGroup, free_port
from tests.support.waits import logs_in, wait_for

m = mav.mavlink
#: PX4 SITL's API (offboard) port, where MAVSDK's examples listen
PX4_API_PORT = 14540
LOCK = Path(tempfile.gettempdir()) / "dualpilot-udp-14540.lock"


def udp_free(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


@contextlib.contextmanager
def api_port() -> Iterator[tuple[int, bool]]:
    """(port, fixed): 14540 for this test alone, or a free port if something else holds it."""
    with LOCK.open("a") as fh:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX)  # another run's vehicle: wait for it
        if udp_free(PX4_API_PORT):
            yield PX4_API_PORT, True
        else:  # pragma: no cover - a process outside the project holds 14540
            yield free_port("udp"), False


@dataclass
class Watch:
    """What the vehicle told a ground station (module docstring)."""

    conn: Any
    speak: bool = False
    heartbeats: list[Any] = field(default_factory=list)
    texts: list[str] = field(default_factory=list)
    reached: list[int] = field(default_factory=list)
    acks: list[Any] = field(default_factory=list)
    params: dict[str, float] = field(default_factory=dict)  #: the newest PARAM_VALUE of each
    max_alt_m: float = 0.0  #: the highest relative altitude seen
    newest: dict[str, Any] = field(default_factory=dict)
    stop: threading.Event = field(default_factory=threading.Event)
    lock: threading.Lock = field(default_factory=threading.Lock)

    @contextlib.contextmanager
    def running(self) -> Iterator[Watch]:
        thread = threading.Thread(target=self.run, daemon=True, name="watch")
        thread.start()
        try:
            yield self
        finally:
            self.stop.set()
            thread.join(2)
            self.conn.close()

    def send(self, name: str, *args: Any) -> None:
        with self.lock:  # pymavlink's sequence counter is not thread-safe
            getattr(self.conn.mav, f"{name}_send")(*args)

    def command(self, cmd: int, *params: float, timeout_s: float = 10.0) -> int:
        """COMMAND_LONG to system 1 (unset parameters 0): the COMMAND_ACK's result."""
        seen = len(self.acks)
        self.send("command_long", 1, 1, cmd, 0, *params, *([0.0] * (7 - len(params))))
        ack = wait_for(lambda: next((a for a in self.acks[seen:] if a.command == cmd), None),
                       timeout_s, f"the COMMAND_ACK of {cmd}")
        return int(ack.result)

    def run(self) -> None:
        next_hb = 0.0
        while not self.stop.is_set():
            if self.speak and time.monotonic() >= next_hb:
                self.send("heartbeat", m.MAV_TYPE_GCS, m.MAV_AUTOPILOT_INVALID, 0, 0, 0)
                next_hb = time.monotonic() + 1.0
            msg = self.conn.recv_match(blocking=True, timeout=0.1)
            if msg is None or msg.get_srcComponent() != 1:
                continue
            kind = msg.get_type()
            if kind == "HEARTBEAT":
                self.heartbeats.append(msg)
            elif kind == "STATUSTEXT":
                self.texts.append(msg.text)
            elif kind == "MISSION_ITEM_REACHED":
                self.reached.append(int(msg.seq))
            elif kind == "COMMAND_ACK":
                self.acks.append(msg)
            elif kind == "PARAM_VALUE":
                self.params[msg.param_id] = float(msg.param_value)
            elif kind == "GLOBAL_POSITION_INT":
                self.max_alt_m = max(self.max_alt_m, msg.relative_alt / 1000.0)
            self.newest[kind] = msg

    def last(self, kind: str) -> Any:
        return self.newest.get(kind)

    @property
    def armed(self) -> bool:
        return bool(self.heartbeats and self.heartbeats[-1].base_mode
                    & m.MAV_MODE_FLAG_SAFETY_ARMED)

    @property
    def landed(self) -> bool:
        ext = self.last("EXTENDED_SYS_STATE")
        return ext is not None and ext.landed_state == m.MAV_LANDED_STATE_ON_GROUND

    def mode(self) -> tuple[int, bool] | None:
        """The newest HEARTBEAT's custom mode and arming."""
        if not self.heartbeats:
            return None
        hb = self.heartbeats[-1]
        return int(hb.custom_mode), bool(hb.base_mode & m.MAV_MODE_FLAG_SAFETY_ARMED)

    def modes(self, name_of: Any) -> list[str]:
        """The modes the heartbeats showed, each change once, named by ``name_of(custom)``."""
        names: list[str] = []
        for hb in list(self.heartbeats):
            name = name_of(int(hb.custom_mode))
            if not names or names[-1] != name:
                names.append(name)
        return names

    def local(self) -> tuple[float, float, float]:
        """The newest LOCAL_POSITION_NED: (north, east, down) m."""
        p = self.last("LOCAL_POSITION_NED")
        nan = float("nan")
        return (p.x, p.y, p.z) if p is not None else (nan, nan, nan)


@dataclass
class Sitl:
    """A uavsim on its own clock and the ground station watching it."""

    url: str  #: the connection string a client uses (udpin://127.0.0.1:<api port>)
    fixed: bool  #: the api port is 14540 (else a free one, given with --mavlink-url)
    watch: Watch
    group: ProcessGroup
    logs_dir: Path
    speed: float  #: simulated s per wall s

    def logs(self) -> list[Path]:
        return logs_in(self.logs_dir)

    def sim(self, seconds: float) -> float:
        """The wall seconds of ``seconds`` of simulated time (an example's ``sleep``)."""
        return seconds / self.speed

    def until(self, pred: Callable[[], Any], sim_s: float, what: str) -> Any:
        """``pred``'s first truthy value within ``sim_s`` simulated seconds (+ 10 s of slack
        for a loaded machine), else the test fails with the vehicle's log."""
        return wait_for(pred, self.sim(sim_s) + 10.0, what, self.logs(),
                        last=lambda: {k: str(v) for k, v in self.watch.newest.items()
                                      if k in ("HEARTBEAT", "LOCAL_POSITION_NED",
                                               "EXTENDED_SYS_STATE")})


@contextlib.contextmanager
def px4_sitl(logs_dir: Path, speed: float, *flags: str) -> Iterator[Sitl]:
    """``python -m services.uavsim --autopilot px4`` as a user runs it (its offboard link on
    PX4 SITL's 14540 unless taken), its ground-station link to a watching pymavlink."""
    gcs_port = free_port("udp")
    watch = Watch(mav.connect(f"udpin:127.0.0.1:{gcs_port}", 255, 190))
    group = ProcessGroup()
    env = {k: v for k, v in os.environ.items() if not k.startswith(("ZENOH", "UAV_", "MAVLINK",
                                                                    "GCS_"))}
    env.update(PYTHONPATH=str(REPO), PYTHONUNBUFFERED="1", LOG_FORMAT="text", LOG_LEVEL="INFO")
    with watch.running(), api_port() as (port, fixed):
        argv = [sys.executable, "-m", "services.uavsim", "--autopilot", "px4",
                "--speed-factor", str(speed), "--gcs-url", f"udpout:127.0.0.1:{gcs_port}",
                *flags]
        if not fixed:
            argv += ["--mavlink-url", f"udpout:127.0.0.1:{port}"]
        group.start("uavsim", argv, env, logs_dir / "uavsim.log")
        sitl = Sitl(f"udpin://127.0.0.1:{port}", fixed, watch, group, logs_dir, speed)
        try:
            sitl.until(lambda: watch.heartbeats, 5, "the vehicle's HEARTBEAT on the ground-station "
                       "link")
            yield sitl
        finally:
            codes = group.stop_all()
            assert codes.get("uavsim") == 0, (logs_dir / "uavsim.log").read_text()[-3000:]
