"""MAVSDK's published examples, as written, against ``python -m services.uavsim --autopilot px4``.

Each test starts the vehicle as a user would (its offboard link sends to
PX4 SITL's 14540, its home PX4 SITL's: tests/e2e/sitl.py) and runs one
example, call for call, with ``mavsdk<4`` (the gRPC API:
tests/e2e/examples_grpc.py, in this process) and with the native 4.x
binding (tests/e2e/examples_native.py, a program of its own: the two
install the same module name), then checks the outcome on a ground station
of its own: altitudes and positions within tolerance, the mission's items
reached, the fence accepted and acted on, landed and disarmed at the end.
The vehicle flies :data:`SPEED` times real time; an example's ``sleep(t)``
is ``t`` simulated seconds.
"""

from __future__ import annotations

import asyncio
import json
import math
import os
import subprocess
import sys
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from services.common import mav
from services.launch import REPO
from services.uavsim import flavour as fl
from services.uavsim.params import PARAMS
from tests.e2e.examples_common import plain
from tests.e2e.sitl import Sitl, px4_sitl, udp_free
from tests.support.waits import check, wait_for

grpc = pytest.importorskip("tests.e2e.examples_grpc")  # needs mavsdk<4

pytestmark = [pytest.mark.slow, pytest.mark.timeout(240)]
m = mav.mavlink
SPEED = 10.0  # simulated s per wall s
HOME = fl.PX4_SITL.home  # PX4 SITL's: 47.397742, 8.545594, 488 m
#: where ``make setup`` installs the native 4.x binding (Makefile, pyproject's extra mavsdk4)
MAVSDK4 = Path(sys.prefix) / "mavsdk4"


@pytest.fixture(params=["grpc", "native"])
def api(request: pytest.FixtureRequest) -> str:
    if request.param == "native" and not (MAVSDK4 / "mavsdk").is_dir():
        pytest.fail(f"the native MAVSDK 4.x binding is not in {MAVSDK4}: run make setup")
    return str(request.param)


@pytest.fixture
def sitl(tmp_path: Path) -> Iterator[Sitl]:
    with px4_sitl(tmp_path, SPEED) as s:
        yield s


def run(sitl: Sitl, api: str, name: str, *args: Any, timeout_s: float = 90.0) -> Any:
    """Example ``name`` to its end with ``api``; what it saw, as plain data."""
    if api == "native":
        return run_native(sitl, name, timeout_s)
    example: Callable[..., Any] = getattr(grpc, name)
    # the previous example's mavsdk_server is killed, not waited for: its socket on the api
    # port may outlive it by a moment, and a new server cannot bind it ("Address in use")
    port = int(sitl.url.rsplit(":", 1)[1])
    wait_for(lambda: udp_free(port), 10.0, f"the api port {port} released by the last example")

    async def bounded() -> Any:
        return await asyncio.wait_for(example(sitl.url, sitl.sim, *args), timeout_s)

    try:
        return plain(asyncio.run(bounded()))
    except TimeoutError:
        check(False, f"examples_grpc.{name} to end within {timeout_s:g} s", sitl.logs())


def run_native(sitl: Sitl, name: str, timeout_s: float) -> Any:
    env = dict(os.environ, PYTHONPATH=f"{MAVSDK4}{os.pathsep}{REPO}")
    try:
        out = subprocess.run([sys.executable, "-m", "tests.e2e.examples_native", name, sitl.url,
                              str(sitl.speed)], capture_output=True, text=True, env=env,
                             timeout=timeout_s, cwd=REPO)
    except subprocess.TimeoutExpired:
        check(False, f"examples_native {name} to end within {timeout_s:g} s", sitl.logs())
    check(out.returncode == 0, f"examples_native {name} to exit with 0", sitl.logs(),
          out.stderr[-3000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def landed_and_disarmed(sitl: Sitl, sim_s: float = 60.0) -> None:
    sitl.until(lambda: sitl.watch.landed and not sitl.watch.armed, sim_s,
               "the vehicle landed and disarmed")


def from_home(lat: float, lon: float) -> tuple[float, float]:
    """(east, north) m of a point from PX4 SITL's home (the px4 vehicle's local origin)."""
    return mav.to_local(lat, lon, HOME[:2])


def test_telemetry(api: str, sitl: Sitl) -> None:
    out = run(sitl, api, "telemetry")
    if not sitl.fixed:  # pragma: no cover - another program holds 14540
        warnings.warn("14540 is held by another program: the examples ran on a free port "
                      "given with --mavlink-url", stacklevel=1)
    assert all(b["remaining_percent"] == pytest.approx(100.0) for b in out["battery"])
    assert all(g["num_satellites"] == 14 and g["fix_type"] == "FIX_3D"
               for g in out["gps_info"])
    assert out["in_air"][-1] is False
    p = out["position"][-1]  # at PX4 SITL's home, on the ground
    assert (p["latitude_deg"], p["longitude_deg"]) == pytest.approx(HOME[:2], abs=1e-7)
    assert p["absolute_altitude_m"] == pytest.approx(HOME[2]) and p["relative_altitude_m"] == 0


def test_telemetry_flight_mode(api: str, sitl: Sitl) -> None:
    out = run(sitl, api, "telemetry_flight_mode")
    assert "-- Connected to drone!" in out["seen"]
    assert out["flight_mode"] == "HOLD"  # PX4 boots in AUTO.LOITER


def test_all_params(api: str, sitl: Sitl) -> None:
    out = run(sitl, api, "all_params")
    assert out["int"] == {}  # every parameter is a REAL32
    assert set(out["float"]) == set(PARAMS)
    assert out["float"]["MIS_TAKEOFF_ALT"] == 2.5 and out["float"]["COM_OF_LOSS_T"] == 1.0
    assert out["float"]["MPC_XY_CRUISE"] == 5.0 and out["float"]["GF_ACTION"] == 2.0


def test_takeoff_and_land(api: str, sitl: Sitl) -> None:
    out = run(sitl, api, "takeoff_and_land")
    assert out["seen"][-3:] == ["-- Arming", "-- Taking off", "-- Landing"]
    # up to MIS_TAKEOFF_ALT = 2.5 m during the 10 s the example waits, then down and disarmed
    assert sitl.watch.max_alt_m == pytest.approx(2.5, abs=0.01)
    landed_and_disarmed(sitl, 20)
    assert "Landing at current position" in sitl.watch.texts
    assert sitl.watch.modes(fl.PX4.name_of)[:4] == ["AUTO.LOITER", "AUTO.TAKEOFF", "AUTO.LOITER",
                                            "AUTO.LAND"]


def test_offboard_position_ned(api: str, sitl: Sitl) -> None:
    out = run(sitl, api, "offboard_position_ned", *([sitl.watch.local] if api == "grpc" else []))
    assert "-- Stopping offboard" in out["seen"]
    assert [tuple(ned) for ned, _ in out["legs"]] == [(0.0, 0.0, -5.0), (5.0, 0.0, -5.0),
                                                      (5.0, 10.0, -5.0), (0.0, 10.0, 0.0)]
    for ned, at in out["legs"][:3]:  # each leg's end: there within 0.5 m
        assert np.allclose(at, ned, atol=0.5), (ned, at)
    # The last leg goes down and sideways at once: the descent reaches the ground before the
    # 5 m back north are flown, and a landed vehicle does not slide, so it stops short; 2 m
    # covers that (the first three legs, in the air, are held to 0.5 m).
    end = out["legs"][3][1]
    assert np.allclose(end[:2], (0.0, 10.0), atol=2.0) and end[2] == pytest.approx(0.0)
    landed_and_disarmed(sitl, 10)  # z = 0: it landed, and disarmed after COM_DISARM_LAND
    n, e, d = sitl.watch.local()
    assert math.hypot(n - 0.0, e - 10.0) < 2.0 and d == 0.0
    assert "OFFBOARD" in sitl.watch.modes(fl.PX4.name_of)


def test_goto(api: str, sitl: Sitl) -> None:
    target = from_home(47.397606, 8.543060)  # ≈ 193 m west, 15 m south of home

    def arrived() -> bool:
        n, e, d = sitl.watch.local()
        return math.hypot(e - target[0], n - target[1]) < 1.0 and abs(-d - 20.0) < 0.5

    out = run(sitl, api, "goto", *([arrived] if api == "grpc" else []))
    assert out["home_amsl_m"] == pytest.approx(HOME[2])
    sitl.until(arrived, 10, "the vehicle at the goto's point")
    gpi = sitl.watch.last("GLOBAL_POSITION_INT")
    assert (gpi.lat / 1e7, gpi.lon / 1e7) == pytest.approx((47.397606, 8.543060), abs=1e-5)
    assert gpi.relative_alt / 1000 == pytest.approx(20.0, abs=0.5)
    assert gpi.alt / 1000 == pytest.approx(HOME[2] + 20.0, abs=0.5)  # AMSL, as goto asked
    assert sitl.watch.modes(fl.PX4.name_of)[-1] == "AUTO.LOITER"  # PX4 flies a goto in Hold


def test_mission(api: str, sitl: Sitl) -> None:
    out = run(sitl, api, "mission", timeout_s=150)
    # MAVSDK uploads each item as NAV_WAYPOINT + DO_CHANGE_SPEED, then NAV_RETURN_TO_LAUNCH
    assert sitl.watch.reached == list(range(7))
    assert out["progress"] and out["progress"][-1][1] == 3
    landed_and_disarmed(sitl, 20)
    n, e, _ = sitl.watch.local()
    assert math.hypot(n, e) < 1.0  # back at home
    modes = sitl.watch.modes(fl.PX4.name_of)
    assert modes[modes.index("AUTO.MISSION"):][:3] == ["AUTO.MISSION", "AUTO.RTL", "AUTO.LAND"]


def test_geofence(api: str, sitl: Sitl) -> None:
    out = run(sitl, api, "geofence")
    assert out["seen"][-1] == "Geofence uploaded!"
    assert out["home"] == pytest.approx(HOME[:2], abs=1e-7)
    uploads = [line for line in (sitl.logs_dir / "uavsim.log").read_text().splitlines()
               if "mission upload" in line]
    # the vehicle's STATUSTEXT reaches the test's own link in its own time (the example's
    # upload ended with the vehicle's ack, on the example's link): wait for it
    zones = 2 if api == "grpc" else 1
    wait_for(lambda: f"geofence: {zones} zones" in sitl.watch.texts, 10.0,
             f"the vehicle's 'geofence: {zones} zones'", last=lambda: sitl.watch.texts)
    if api == "grpc":  # mavsdk<4 sends the polygon and the placeholder circle (radius 0)
        assert len(uploads) == 1
    else:  # MAVSDK 4.x refuses the placeholder itself: nothing sent, then the polygon alone
        assert "upload refused by MAVSDK: INVALID_ARGUMENT" in out["seen"]
        assert len(uploads) == 1
        assert "count=4" in uploads[0]
        return
    # the breach action (GF_ACTION 2, Hold): a goto 30 m east stops at the fence's edge
    half_east = from_home(HOME[0], HOME[1] + 1e-4)[0]  # ≈ 7.5 m

    def held_outside() -> bool:
        lpn = sitl.watch.last("LOCAL_POSITION_NED")
        return "Failsafe: geofence breached" in sitl.watch.texts and abs(lpn.vy) < 0.05

    run(sitl, api, "fly_out_east", 30.0, held_outside)
    east = sitl.watch.local()[1]
    assert half_east < east < half_east + 6.0  # out by at most a step at 5 m/s
