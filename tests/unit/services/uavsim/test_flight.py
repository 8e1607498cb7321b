"""The vehicle flying what it is told, in process (services/uavsim/{commands,navigator}.py).

Commands arrive as decoded MAVLink (MAVSDK's NaN "unset" included), the
vehicle flies on its own clock ΔT at a time, and the outcome is checked
against values worked out by hand from the parameters (climb 3 m/s, sink
1.5 m/s and 0.7 m/s below 5 m, cruise 5 m/s, COM_DISARM_LAND 2 s).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from services.common import mav
from services.uavsim import flavour as fl
from services.uavsim.flavour import Nav
from tests.support.vehicles import COMPANION, GCS_PEER, HOME, HOME_AMSL_M, Rig, rig, wire

m = mav.mavlink
NAN = math.nan
ACCEPTED = m.MAV_RESULT_ACCEPTED


def airborne(r: Rig, alt: float = 10.0) -> None:
    """Armed and up at ``alt`` m in Hold (PX4) / GUIDED (ArduPilot)."""
    if r.ap.flavour is fl.ARDUPILOT:
        assert r.command(m.MAV_CMD_DO_SET_MODE, 1, 4) == ACCEPTED
    assert r.command(m.MAV_CMD_COMPONENT_ARM_DISARM, 1) == ACCEPTED
    assert r.command(m.MAV_CMD_NAV_TAKEOFF, *[NAN] * 6, alt if r.ap.flavour is fl.ARDUPILOT
                     else HOME_AMSL_M + alt) == ACCEPTED
    r.fly(math.ceil(alt / 3.0) + 1)
    assert r.ap.vehicle.alt_m == pytest.approx(alt)


def test_takeoff_climbs_at_3_mps_to_mis_takeoff_alt_then_holds() -> None:
    r = rig(fl.PX4)
    assert r.command(m.MAV_CMD_COMPONENT_ARM_DISARM, 1) == ACCEPTED
    assert "Armed by external command" in r.texts()
    assert r.command(m.MAV_CMD_NAV_TAKEOFF) == ACCEPTED  # MAVSDK's: every param NaN
    assert r.nav is Nav.TAKEOFF
    r.fly(1.0)
    assert r.ap.vehicle.alt_m == 2.5  # MIS_TAKEOFF_ALT, within one step of 3 m
    r.fly(1.0)
    assert r.nav is Nav.HOLD


def test_land_sinks_then_slows_then_disarms_after_com_disarm_land() -> None:
    r = rig(fl.PX4)
    airborne(r, 11.0)
    assert r.command(m.MAV_CMD_NAV_LAND) == ACCEPTED
    assert r.texts() == ["Landing at current position", "Land: land"]
    alts = []
    for _ in range(12):
        r.fly(1.0)
        alts.append(r.ap.vehicle.alt_m)
    # 1.5 m/s down to 5 m (11 → 9.5 → 8 → 6.5 → 5), then 0.7 m/s: 4.3, 3.6, … 0.1, 0
    assert alts[:4] == pytest.approx([9.5, 8.0, 6.5, 5.0])
    assert alts[4:11] == pytest.approx([4.3, 3.6, 2.9, 2.2, 1.5, 0.8, 0.1])
    assert alts[11] == 0.0 and r.ap.commander.armed  # touchdown: COM_DISARM_LAND = 2 s
    r.fly(2.0)
    assert not r.ap.commander.armed and "Disarmed by landing" in r.texts()


def test_goto_with_nan_unchanged_fields_flies_there_at_the_cruise_speed() -> None:
    """MAVSDK's goto_location: DO_REPOSITION as COMMAND_INT, param1/param3 NaN (unchanged),
    param2 = change mode, param4 the yaw, altitude AMSL."""
    r = rig(fl.PX4)
    airborne(r)
    lat, lon = mav.to_geodetic(0.0, 200.0, HOME)
    msg = wire(m.MAVLink_command_int_message(1, 1, m.MAV_FRAME_GLOBAL_INT,
                                             m.MAV_CMD_DO_REPOSITION, 0, 0, NAN, 1.0, NAN, 0.0,
                                             round(lat * 1e7), round(lon * 1e7),
                                             HOME_AMSL_M + 20.0))
    r.commands.on_command_int("offboard", COMPANION, msg, 1.0)
    assert r.out.named("command_ack")[-1][:2] == (m.MAV_CMD_DO_REPOSITION, ACCEPTED)
    assert r.nav is Nav.HOLD
    r.fly(30.0)
    x = r.ap.vehicle.state
    assert x[1] == pytest.approx(150.0, abs=6.0)  # 5 m/s for 30 s, less the acceleration
    assert r.ap.vehicle.alt_m == pytest.approx(20.0)  # 10 m up at 3 m/s
    r.fly(30.0)
    assert np.hypot(x[0] - 0.0, r.ap.vehicle.state[1] - 200.0) < 1.0


def test_a_reposition_with_inf_is_refused_as_not_finite() -> None:
    r = rig(fl.PX4)
    rejected = []
    r.commands.reject = lambda link, err, what: rejected.append(err.reason.value)
    msg = wire(m.MAVLink_command_int_message(1, 1, m.MAV_FRAME_GLOBAL_INT,
                                             m.MAV_CMD_DO_REPOSITION, 0, 0, math.inf, 1, 0, 0,
                                             0, 0, 50.0))
    assert not r.commands.on_command_int("gcs", GCS_PEER, msg, 0.0)
    assert r.out.named("command_ack")[-1][1] == m.MAV_RESULT_DENIED
    assert rejected == ["not_finite"]


def test_do_change_speed_sets_the_cruise_speed() -> None:
    r = rig(fl.PX4)
    airborne(r)
    assert r.command(m.MAV_CMD_DO_CHANGE_SPEED, 1, 10.0, -1, 0) == ACCEPTED
    assert r.command(m.MAV_CMD_DO_REPOSITION, -1, 1, 0, NAN, *mav.to_geodetic(0, 500, HOME),
                     NAN) == ACCEPTED
    r.fly(20.0)
    assert np.hypot(*r.ap.vehicle.state[2:]) == pytest.approx(10.0, abs=0.1)


def upload(r: Rig, items: list[mav.MissionItem], mission_type: int = 0) -> int:
    """The mission protocol, the ground station's side: the MISSION_ACK result."""
    r.out.clear()
    r.ap.mission.handle("gcs", wire(m.MAVLink_mission_count_message(
        1, 1, len(items), mission_type)), 0.0)
    for it in items:
        r.ap.mission.handle("gcs", wire(m.MAVLink_mission_item_int_message(
            *it.fields((1, 1)), mission_type)), 0.0)
    return int(r.out.named("mission_ack")[-1][2])


def item(seq: int, command: int, east: float, north: float, alt: float = 25.0,
         p2: float = 3.0, frame: int = m.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT) -> mav.MissionItem:
    lat, lon = mav.to_geodetic(east, north, HOME)
    return mav.MissionItem(seq, frame, command, int(seq == 0), 1, 0.0, p2, 0.0, NAN,
                           round(lat * 1e7), round(lon * 1e7), alt)


def test_a_mission_of_mavsdks_shape_flies_returns_lands_and_disarms() -> None:
    """MAVSDK's mission example: three waypoints, each followed by DO_CHANGE_SPEED 10 m/s,
    and return to launch at the end, started with the Mission mode on the ground."""
    r = rig(fl.PX4)
    speed = mav.MissionItem(0, m.MAV_FRAME_MISSION, 178, 0, 1, 1.0, 10.0, -1.0, 0.0, 0, 0, NAN)
    route = [(0.0, 33.0), (-42.0, 33.0), (-42.0, 9.0)]
    items: list[mav.MissionItem] = []
    for east, north in route:
        items += [item(len(items), 16, east, north),
                  mav.MissionItem(len(items) + 1, *list(speed.__dict__.values())[1:])]
    items.append(mav.MissionItem(len(items), m.MAV_FRAME_MISSION, 20, 0, 1, NAN, NAN, NAN,
                                 NAN, 0, 0, 0.0))
    assert upload(r, items) == m.MAV_MISSION_ACCEPTED
    assert r.command(m.MAV_CMD_COMPONENT_ARM_DISARM, 1) == ACCEPTED
    assert r.command(m.MAV_CMD_DO_SET_MODE, 1, 4, 4) == ACCEPTED  # AUTO.MISSION
    reached: list[int] = []
    for _ in range(120):
        r.out.clear()
        r.fly(1.0)
        reached += [a[0] for a in r.out.named("mission_item_reached")]
        if not r.ap.commander.armed:
            break
    assert reached == list(range(len(items)))
    assert not r.ap.commander.armed and r.ap.vehicle.alt_m == 0.0
    assert np.hypot(*r.ap.vehicle.state[:2]) < 1.0  # back home
    assert r.ap.mission.current == len(items) - 1


def test_a_fence_upload_is_stored_and_a_bad_one_refused() -> None:
    r = rig(fl.PX4)
    lat, lon = HOME
    poly = [mav.MissionItem(k, m.MAV_FRAME_GLOBAL_INT, 5001, 0, 0, 3.0, 0, 0, 0,
                            round((lat + d[0]) * 1e7), round((lon + d[1]) * 1e7), 0.0)
            for k, d in enumerate([(-1e-4, -1e-4), (1e-4, 0.0), (-1e-4, 1e-4)])]
    assert upload(r, poly, m.MAV_MISSION_TYPE_FENCE) == m.MAV_MISSION_ACCEPTED
    assert len(r.ap.fence.zones) == 1 and "geofence: 1 zones" in r.texts()
    assert upload(r, poly[:2], m.MAV_MISSION_TYPE_FENCE) == m.MAV_MISSION_INVALID_PARAM1
    assert len(r.ap.fence.zones) == 1  # the stored fence stays
    lockstep = rig(fl.PX4, realtime=False)  # a planning mission: no fence
    assert upload(lockstep, poly, m.MAV_MISSION_TYPE_FENCE) == m.MAV_MISSION_UNSUPPORTED


def test_a_ground_station_arms_a_lone_vehicle_and_is_refused_beside_a_live_companion() -> None:
    lone = rig(fl.PX4)
    assert lone.command(m.MAV_CMD_COMPONENT_ARM_DISARM, 1, link="gcs") == ACCEPTED
    assert lone.arbiter.link == "gcs"
    r = rig(fl.PX4)
    r.arbiter.heard_on("offboard", 0.0)  # the companion's heartbeat
    assert r.command(m.MAV_CMD_COMPONENT_ARM_DISARM, 1, link="gcs", now=0.5) == \
        m.MAV_RESULT_DENIED
    assert r.texts() == ["Arming refused: the offboard link is in control"]


def test_take_over_and_hand_back() -> None:
    """The companion flies offboard; the ground station takes over with Hold; the companion's
    stream keeps its link live without flying; Offboard from the ground station hands back."""
    r = rig(fl.PX4, realtime=False, start=(100.0, 100.0))
    ap, sp = r.ap, np.array([100.0, 100.0, 0.0, 0.0])
    r.arbiter.heard_on("offboard", 0.0)
    ap.setpoint("offboard", sp, 50.0, 0, now=0.0)
    r.arbiter.commit(r.arbiter.check("offboard", COMPANION, 0.0), 0.0)
    for cmd, params in ((m.MAV_CMD_DO_SET_MODE, (1, 6, 0)), (m.MAV_CMD_COMPONENT_ARM_DISARM,
                                                             (1,))):
        assert r.command(cmd, *params, link="offboard", peer=COMPANION, now=0.1) == ACCEPTED
    assert r.nav is Nav.OFFBOARD
    assert r.command(m.MAV_CMD_DO_SET_MODE, 1, 4, 3, now=1.0) == ACCEPTED  # Hold, from the GCS
    assert r.arbiter.link == "gcs" and r.nav is Nav.HOLD
    for k in range(10):  # the companion keeps streaming while it waits
        ap.setpoint("offboard", sp, 50.0, 0, now=1.0 + 0.05 * k)
    assert ap.signal.live("offboard", 1.5, 1.0)
    assert r.command(m.MAV_CMD_DO_SET_MODE, 1, 6, 0, now=1.5) == ACCEPTED  # hand back
    assert r.arbiter.link == "offboard" and r.nav is Nav.OFFBOARD
    silent = rig(fl.PX4, realtime=False)  # no companion stream: the ground station keeps it
    silent.arbiter.heard_on("offboard", 0.0)
    assert silent.command(m.MAV_CMD_DO_SET_MODE, 1, 6, 0, now=0.5) == \
        m.MAV_RESULT_TEMPORARILY_REJECTED
    assert silent.texts() == ["Offboard refused: no setpoint stream"]


def test_position_mode_flies_the_sticks() -> None:
    r = rig(fl.PX4)
    airborne(r)
    sticks = wire(m.MAVLink_manual_control_message(1, 1000, 0, 500, 0, 0))
    r.ap.manual(sticks, 0.0)
    assert r.command(m.MAV_CMD_DO_SET_MODE, 1, 3, 0, now=0.1) == ACCEPTED  # POSCTL
    r.fly(10.0, now=0.2)
    assert r.ap.vehicle.state[3] == pytest.approx(10.0, abs=0.05)  # full pitch: 10 m/s north
    r.ap.watch(1.3)  # the sticks silent for more than 1 s: hold
    assert r.nav is Nav.HOLD and r.ap.commander.intended is Nav.POSITION
    assert "Failsafe: manual control lost" in r.texts()
    r.ap.manual(sticks, 1.4)
    r.ap.watch(1.4)
    assert r.nav is Nav.POSITION  # back
    assert r.command(m.MAV_CMD_DO_SET_MODE, 1, 4, 3, now=1.5) == ACCEPTED
    assert r.command(m.MAV_CMD_DO_SET_MODE, 1, 3, 0, now=5.0) == \
        m.MAV_RESULT_TEMPORARILY_REJECTED  # no sticks: refused
