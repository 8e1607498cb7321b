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

import pytest

from e2e.test_ground_station import MAVPROXY, MavProxy
from services.common import mav
from services.launch import REPO, ProcessGroup, free_port
from services.uavsim import flavour as fl
from tests.e2e.sitl import Watch
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


@pytest.fixture
def flight(tmp_path: Path) -> Iterator[tuple[MavProxy, Watch, Path]]:
    port, out = free_port("tcp"), free_port("udp")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("ZENOH", "UAV_", "MAVLINK",
                                                                    "GCS_"))}
    env.update(PYTHONPATH=str(REPO), PYTHONUNBUFFERED="1", LOG_FORMAT="text")
    group = ProcessGroup()
    group.start("uavsim", [sys.executable, "-m", "services.uavsim", "--autopilot", "ardupilot",
                           "--speed-factor", str(SPEED), "--gcs-url", f"tcpin:127.0.0.1:{port}",
                           "--mavlink-url", f"tcpin:127.0.0.1:{free_port('tcp')}"],
                env, tmp_path / "uavsim.log")
    seen = Watch(mav.connect(f"udpin:127.0.0.1:{out}", 254, 191))
    gcs = MavProxy(f"tcp:127.0.0.1:{port}", out, tmp_path)
    try:
        with seen.running():
            yield gcs, seen, tmp_path
    finally:
        gcs.stop()
        codes = group.stop_all()
        check(codes.get("uavsim") == 0, "uavsim to exit with 0", logs_in(tmp_path), codes)


def test_mavproxy_flies_guided_takeoff_and_an_auto_mission(flight: tuple[MavProxy, Watch, Path],
                                                           tmp_path: Path) -> None:
    gcs, seen, logs = flight
    gcs.wait_for(r"Detected vehicle 1:1", 40)
    gcs.wait_for(r"Mode LOITER", 20)  # ArduCopter's number 5
    gcs.wait_for(r"Received \d+ parameters", 20)
    gcs.send("param set RTL_RETURN_ALT 20")  # ArduPilot's RTL_ALT is 15 m; PX4's 60
    wait_for(lambda: seen.params.get("RTL_RETURN_ALT") == 20.0, 10,
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
    name = fl.ARDUPILOT.name_of
    wait_for(lambda: "LAND" in seen.modes(name) and not seen.armed, 60,
             "the mission flown, returned, landed, disarmed", logs_in(logs),
             last=lambda: seen.modes(name))
    assert seen.reached == [1, 2, 3, 4]
    modes = seen.modes(name)
    assert modes[modes.index("AUTO"):] == ["AUTO", "RTL", "LAND"]
    gpi = seen.last("GLOBAL_POSITION_INT")
    east, north = mav.to_local(gpi.lat / 1e7, gpi.lon / 1e7, HOME)
    assert math.hypot(east - START[0], north - START[1]) < 1.0 and gpi.relative_alt == 0
    gcs.wait_for(r"DISARMED", 10)
