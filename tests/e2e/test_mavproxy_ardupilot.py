"""MAVProxy flies ``python -m services.uavsim --autopilot ardupilot`` as it flies ArduPilot SITL.

The vehicle runs on its own clock and serves its ground-station link on TCP,
as ArduPilot SITL's SERIAL0 (a free port here instead of 5760, given with
``--gcs-url``); MAVProxy, headless, is its master over TCP and the commands
are those an ArduCopter user types: ``mode guided``, ``arm throttle``,
``wp load``, ``mode auto`` (refused on the ground without a take-off item,
with ArduCopter's STATUSTEXT), ``takeoff 20``, ``mode auto`` again: the
vehicle flies the waypoints, returns (the route's last item) and lands, and
disarms itself. A pymavlink observer on MAVProxy's ``--out`` checks what
happened.
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from e2e.test_ground_station import MAVPROXY, MavProxy
from services.common import mav
from services.launch import REPO, ProcessGroup, free_port
from services.uavsim import flavour as fl
from tests.support.waits import check, logs_in, wait_for

pytestmark = [pytest.mark.timeout(240)]
m = mav.mavlink
SPEED = 20.0
HOME = (35.1450, 33.4110)  # the ardupilot flavour's origin; it boots 50 m east, 50 m north
START = (50.0, 50.0)
#: the route (m east, north of the origin) at 20 m, then NAV_RETURN_TO_LAUNCH
ROUTE = [(110.0, 50.0), (110.0, 110.0), (50.0, 110.0)]

if not MAVPROXY.exists():  # pragma: no cover - MAVProxy is in the dev extra
    pytest.skip("MAVProxy is not installed (pip install -e '.[dev]')", allow_module_level=True)


def wp_file(path: Path) -> Path:
    """QGC WPL 110, as MAVProxy saves it: the home slot, the waypoints, return to launch."""
    home = mav.to_geodetic(*START, HOME)
    lines = ["QGC WPL 110", f"0\t1\t0\t16\t0\t0\t0\t0\t{home[0]:.7f}\t{home[1]:.7f}\t0.0\t1"]
    for seq, (east, north) in enumerate(ROUTE, start=1):
        lat, lon = mav.to_geodetic(east, north, HOME)
        lines.append(f"{seq}\t0\t3\t16\t0\t0\t0\t0\t{lat:.7f}\t{lon:.7f}\t20.000000\t1")
    lines.append(f"{len(ROUTE) + 1}\t0\t3\t20\t0\t0\t0\t0\t0\t0\t0\t1")
    path.write_text("\n".join(lines) + "\n")
    return path


class Seen:
    """Everything the observer has received so far, read on demand."""

    def __init__(self, port: int):
        self.conn = mav.connect(f"udpin:127.0.0.1:{port}", 254, 191)
        self.msgs: list[Any] = []

    def pump(self) -> list[Any]:
        while (msg := self.conn.recv_match(blocking=False)) is not None:
            if msg.get_srcComponent() == 1:
                self.msgs.append(msg)
        return self.msgs

    def last(self, kind: str) -> Any:
        return next((x for x in reversed(self.pump()) if x.get_type() == kind), None)

    def modes(self) -> list[str]:
        names: list[str] = []
        for hb in (x for x in self.pump() if x.get_type() == "HEARTBEAT"):
            name = fl.ARDUPILOT.name_of(int(hb.custom_mode))
            if not names or names[-1] != name:
                names.append(name)
        return names


@pytest.fixture
def flight(tmp_path: Path) -> Iterator[tuple[MavProxy, Seen, Path]]:
    port, out = free_port("tcp"), free_port("udp")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("ZENOH", "UAV_", "MAVLINK",
                                                                    "GCS_"))}
    env.update(PYTHONPATH=str(REPO), PYTHONUNBUFFERED="1", LOG_FORMAT="text")
    group = ProcessGroup()
    group.start("uavsim", [sys.executable, "-m", "services.uavsim", "--autopilot", "ardupilot",
                           "--speed-factor", str(SPEED), "--gcs-url", f"tcpin:127.0.0.1:{port}",
                           "--mavlink-url", f"tcpin:127.0.0.1:{free_port('tcp')}"],
                env, tmp_path / "uavsim.log")
    seen = Seen(out)
    gcs = MavProxy(f"tcp:127.0.0.1:{port}", out, tmp_path)
    try:
        yield gcs, seen, tmp_path
    finally:
        gcs.stop()
        seen.conn.close()
        codes = group.stop_all()
        check(codes.get("uavsim") == 0, "uavsim to exit with 0", logs_in(tmp_path), codes)


def test_mavproxy_flies_guided_takeoff_and_an_auto_mission(flight: tuple[MavProxy, Seen, Path],
                                                           tmp_path: Path) -> None:
    gcs, seen, logs = flight
    gcs.wait_for(r"Detected vehicle 1:1", 40)
    gcs.wait_for(r"Mode LOITER", 20)  # ArduCopter's number 5
    gcs.wait_for(r"Received \d+ parameters", 20)
    gcs.send("param set RTL_RETURN_ALT 20")  # ArduPilot's RTL_ALT is 15 m; PX4's 60
    wait_for(lambda: any(x.get_type() == "PARAM_VALUE" and x.param_id == "RTL_RETURN_ALT"
                         and x.param_value == 20.0 for x in seen.pump()), 10,
             "the vehicle's PARAM_VALUE RTL_RETURN_ALT = 20", logs_in(logs))
    mark = len(gcs.output())
    gcs.send("mode guided")  # GUIDED needs no setpoint stream (ArduPilot)
    gcs.wait_for(r"Mode GUIDED", 10, after=mark)
    gcs.send("arm throttle")
    gcs.wait_for(r"ARMED", 10, after=mark)
    mark = len(gcs.output())
    gcs.send(f"wp load {wp_file(tmp_path / 'route.txt')}")
    gcs.wait_for(r"MISSION_ACK: TYPE_MISSION: ACCEPTED|Sent all \d+ waypoints", 20, after=mark)
    mark = len(gcs.output())
    gcs.send("mode auto")  # on the ground, and the route has no take-off item
    gcs.wait_for(r"Auto: Missing Takeoff Cmd", 10, after=mark)
    gcs.send("takeoff 20")
    wait_for(lambda: (g := seen.last("GLOBAL_POSITION_INT")) is not None
             and g.relative_alt > 19_500, 20, "the vehicle at 20 m", logs_in(logs))
    gcs.send("mode auto")
    wait_for(lambda: "LAND" in seen.modes() and not seen.last("HEARTBEAT").base_mode
             & m.MAV_MODE_FLAG_SAFETY_ARMED, 60, "the mission flown, returned, landed, disarmed",
             logs_in(logs), last=lambda: seen.modes())
    reached = [x.seq for x in seen.pump() if x.get_type() == "MISSION_ITEM_REACHED"]
    assert reached == [1, 2, 3, 4]
    modes = seen.modes()
    assert modes[modes.index("AUTO"):] == ["AUTO", "RTL", "LAND"]
    gpi = seen.last("GLOBAL_POSITION_INT")
    east, north = mav.to_local(gpi.lat / 1e7, gpi.lon / 1e7, HOME)
    assert math.hypot(east - START[0], north - START[1]) < 1.0 and gpi.relative_alt == 0
    gcs.wait_for(r"DISARMED", 10)
