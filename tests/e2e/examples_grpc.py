"""MAVSDK-Python's published examples (``mavsdk<4``, the gRPC API), call for call.

Each function is the body of one example of MAVSDK-Python's ``examples/``
(``telemetry.py``, ``telemetry_flight_mode.py``, ``all_params.py``,
``takeoff_and_land.py``, ``offboard_position_ned.py``, ``goto.py``,
``mission.py``, ``geofence.py``) with the same imports and calls in the same
order and the same connection string form. The differences, and only these:
the connection string is a parameter (``udpin://127.0.0.1:14540``: loopback
only in tests), ``System()`` gets a free port for its mavsdk_server,
``print`` appends to the returned record, ``asyncio.sleep(t)`` sleeps ``t``
*simulated* seconds (``sim(t)`` wall seconds: the vehicle flies
``--speed-factor`` times faster than real time), and the loops the examples
run forever end when they have seen what they wait for.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Any

from mavsdk import System
from mavsdk.geofence import Circle, FenceType, GeofenceData, Point, Polygon
from mavsdk.mission import MissionItem, MissionPlan
from mavsdk.offboard import OffboardError, PositionNedYaw

from services.common import mav
from services.launch import free_port
from tests.e2e.examples_common import MISSION, plain  # noqa: F401 (plain: the tests' too)

Sim = Callable[[float], float]


def drone() -> Any:
    return System(port=free_port("tcp"))  # mavsdk_server's gRPC port: a free one


async def connected(d: Any, seen: list[Any]) -> None:
    seen.append("Waiting for drone to connect...")
    async for state in d.core.connection_state():
        if state.is_connected:
            seen.append("-- Connected to drone!")
            break


async def global_position_ok(d: Any, seen: list[Any]) -> None:
    seen.append("Waiting for drone to have a global position estimate...")
    async for health in d.telemetry.health():
        if health.is_global_position_ok and health.is_home_position_ok:
            seen.append("-- Global position estimate OK")
            break


async def telemetry(url: str, sim: Sim) -> dict[str, Any]:
    """examples/telemetry.py: battery, GPS info, in-air and position, printed as they come."""
    d = drone()
    await d.connect(system_address=url)
    out: dict[str, list[Any]] = {"battery": [], "gps_info": [], "in_air": [], "position": []}

    async def each(name: str, gen: Any) -> None:
        async for item in gen:
            out[name].append(item)

    tasks = [asyncio.create_task(each("battery", d.telemetry.battery())),
             asyncio.create_task(each("gps_info", d.telemetry.gps_info())),
             asyncio.create_task(each("in_air", d.telemetry.in_air())),
             asyncio.create_task(each("position", d.telemetry.position()))]
    while not all(len(v) >= 3 for v in out.values()):  # the example runs forever
        await asyncio.sleep(0.05)
    for task in tasks:
        task.cancel()
    d._stop_mavsdk_server()
    return out


async def telemetry_flight_mode(url: str, sim: Sim) -> dict[str, Any]:
    d = drone()
    seen: list[Any] = []
    await d.connect(system_address=url)
    await connected(d, seen)
    async for flight_mode in d.telemetry.flight_mode():
        seen.append(flight_mode)
        break  # the example prints every one, forever
    d._stop_mavsdk_server()
    return {"seen": seen, "flight_mode": seen[-1]}


async def all_params(url: str, sim: Sim) -> dict[str, Any]:
    d = drone()
    await d.connect(system_address=url)
    all_params = await d.param.get_all_params()
    out = {"int": {p.name: p.value for p in all_params.int_params},
           "float": {p.name: p.value for p in all_params.float_params}}
    d._stop_mavsdk_server()
    return out


async def takeoff_and_land(url: str, sim: Sim) -> dict[str, Any]:
    d = drone()
    seen: list[Any] = []
    texts: list[str] = []

    async def print_status_text() -> None:
        try:
            async for status_text in d.telemetry.status_text():
                texts.append(f"Status: {status_text.type}: {status_text.text}")
        except asyncio.CancelledError:
            return

    await d.connect(system_address=url)
    status_text_task = asyncio.ensure_future(print_status_text())
    await connected(d, seen)
    await global_position_ok(d, seen)
    seen.append("-- Arming")
    await d.action.arm()
    seen.append("-- Taking off")
    await d.action.takeoff()
    await asyncio.sleep(sim(10))
    seen.append("-- Landing")
    await d.action.land()
    status_text_task.cancel()
    d._stop_mavsdk_server()
    return {"seen": seen, "texts": texts}


async def offboard_position_ned(url: str, sim: Sim, watch: Any = None) -> dict[str, Any]:
    """examples/offboard_position_ned.py; ``watch()`` notes where the vehicle is at the end of
    each leg (the example only sleeps)."""
    d = drone()
    seen: list[Any] = []
    legs: list[tuple[tuple[float, ...], Any]] = []
    await d.connect(system_address=url)
    await connected(d, seen)
    await global_position_ok(d, seen)
    seen.append("-- Arming")
    await d.action.arm()
    seen.append("-- Setting initial setpoint")
    await d.offboard.set_position_ned(PositionNedYaw(0.0, 0.0, 0.0, 0.0))
    seen.append("-- Starting offboard")
    try:
        await d.offboard.start()
    except OffboardError as error:
        seen.append(f"Starting offboard mode failed with error code: {error._result.result}")
        seen.append("-- Disarming")
        await d.action.disarm()
        d._stop_mavsdk_server()
        return {"seen": seen, "legs": legs}
    for ned, wait_s in (((0.0, 0.0, -5.0, 0.0), 10), ((5.0, 0.0, -5.0, 90.0), 10),
                        ((5.0, 10.0, -5.0, 90.0), 15), ((0.0, 10.0, 0.0, 180.0), 10)):
        seen.append(f"-- Go {ned[0]}m North, {ned[1]}m East, {ned[2]}m Down")
        await d.offboard.set_position_ned(PositionNedYaw(*ned))
        await asyncio.sleep(sim(wait_s))
        legs.append((ned[:3], watch() if watch is not None else None))
    seen.append("-- Stopping offboard")
    try:
        await d.offboard.stop()
    except OffboardError as error:
        seen.append(f"Stopping offboard mode failed with error code: {error._result.result}")
    d._stop_mavsdk_server()
    return {"seen": seen, "legs": legs}


async def goto(url: str, sim: Sim, arrived: Callable[[], bool] = lambda: True
               ) -> dict[str, Any]:
    """examples/goto.py; its last loop ("Staying connected") ends once ``arrived()``."""
    d = drone()
    seen: list[Any] = []
    await d.connect(system_address=url)
    await connected(d, seen)
    await global_position_ok(d, seen)
    seen.append("Fetching amsl altitude at home location....")
    async for terrain_info in d.telemetry.home():
        absolute_altitude = terrain_info.absolute_altitude_m
        break
    seen.append("-- Arming")
    await d.action.arm()
    seen.append("-- Taking off")
    await d.action.takeoff()
    await asyncio.sleep(sim(1))
    # To fly drone 20m above the ground plane
    flying_alt = absolute_altitude + 20.0
    # goto_location() takes Absolute MSL altitude
    await d.action.goto_location(47.397606, 8.543060, flying_alt, 0)
    while not arrived():
        seen.append("Staying connected, press Ctrl-C to exit")
        await asyncio.sleep(sim(1))
    d._stop_mavsdk_server()
    return {"seen": seen, "home_amsl_m": absolute_altitude}


async def mission(url: str, sim: Sim) -> dict[str, Any]:
    d = drone()
    seen: list[Any] = []
    progress: list[tuple[int, int]] = []
    await d.connect(system_address=url)
    await connected(d, seen)

    async def print_mission_progress() -> None:
        async for mission_progress in d.mission.mission_progress():
            progress.append((mission_progress.current, mission_progress.total))

    async def observe_is_in_air(running_tasks: list[Any]) -> None:
        was_in_air = False
        async for is_in_air in d.telemetry.in_air():
            if is_in_air:
                was_in_air = is_in_air
            if was_in_air and not is_in_air:
                for task in running_tasks:
                    task.cancel()
                    try:  # noqa: SIM105 - the example's own code
                        await task
                    except asyncio.CancelledError:
                        pass
                await asyncio.get_event_loop().shutdown_asyncgens()
                return

    print_mission_progress_task = asyncio.ensure_future(print_mission_progress())
    running_tasks = [print_mission_progress_task]
    termination_task = asyncio.ensure_future(observe_is_in_air(running_tasks))
    mission_items = [MissionItem(lat, lon, 25, 10, True, float("nan"), float("nan"),
                                 MissionItem.CameraAction.NONE, float("nan"), float("nan"),
                                 float("nan"), float("nan"), float("nan"),
                                 MissionItem.VehicleAction.NONE) for lat, lon in MISSION]
    mission_plan = MissionPlan(mission_items)
    await d.mission.set_return_to_launch_after_mission(True)
    seen.append("-- Uploading mission")
    await d.mission.upload_mission(mission_plan)
    await global_position_ok(d, seen)
    seen.append("-- Arming")
    await d.action.arm()
    seen.append("-- Starting mission")
    await d.mission.start_mission()
    await termination_task
    d._stop_mavsdk_server()
    return {"seen": seen, "progress": progress}


async def geofence(url: str, sim: Sim) -> dict[str, Any]:
    d = drone()
    seen: list[Any] = []
    await d.connect(system_address=url)
    await connected(d, seen)
    seen.append("Fetching home location coordinates...")
    async for terrain_info in d.telemetry.home():
        latitude = terrain_info.latitude_deg
        longitude = terrain_info.longitude_deg
        break
    await asyncio.sleep(sim(1))
    p1 = Point(latitude - 0.0001, longitude - 0.0001)
    p2 = Point(latitude + 0.0001, longitude - 0.0001)
    p3 = Point(latitude + 0.0001, longitude + 0.0001)
    p4 = Point(latitude - 0.0001, longitude + 0.0001)
    polygon = Polygon([p1, p2, p3, p4], FenceType.INCLUSION)
    circle = Circle(Point(0, 0), 0, FenceType.INCLUSION)
    geofence_data = GeofenceData([polygon], [circle])
    seen.append("Uploading geofence...")
    await d.geofence.upload_geofence(geofence_data)
    seen.append("Geofence uploaded!")
    d._stop_mavsdk_server()
    return {"seen": seen, "home": (latitude, longitude)}


async def fly_out_east(url: str, sim: Sim, east_m: float, out: Callable[[], bool]) -> None:
    """Not an example: take off and go ``east_m`` east of home (through a fence), until
    ``out()`` says the vehicle has done what it does there."""
    d = drone()
    await d.connect(system_address=url)
    async for health in d.telemetry.health():
        if health.is_global_position_ok and health.is_home_position_ok:
            break
    home = await anext(aiter(d.telemetry.home()))
    await d.action.arm()
    await d.action.takeoff()
    await asyncio.sleep(sim(2))
    lat, lon = mav.to_geodetic(east_m, 0.0, (home.latitude_deg, home.longitude_deg))
    await d.action.goto_location(lat, lon, home.absolute_altitude_m + 10.0, 0)
    while not out():
        await asyncio.sleep(sim(1))
    d._stop_mavsdk_server()
