"""The vehicle's components on their own: control arbiter, parameters, geofence, mission run,
telemetry outbox (services/uavsim/{control,params,geofence,missionrun,telemetry}.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from services.common import mav, rejections
from services.uavsim import flavour as fl
from services.uavsim.control import GCS, OFFBOARD, ControlArbiter
from services.uavsim.geofence import Geofence, zones
from services.uavsim.missionrun import Frame, Goal, MissionRun
from services.uavsim.outbox import RecordingOutbox
from services.uavsim.params import Parameters, ParamProtocol
from tests.support.vehicles import HOME, HOME_AMSL_M, rig, wire

m = mav.mavlink
A = (("127.0.0.1", 1000), 1, 191)
B = (("127.0.0.1", 1001), 1, 191)
G = (("127.0.0.1", 2000), 255, 190)


def arbiter() -> ControlArbiter:
    return ControlArbiter(lambda: 1.0, lambda: 10.0)


# -- who may steer -----------------------------------------------------------------------------
def test_a_ground_station_flies_a_lone_vehicle_and_keeps_it() -> None:
    c = arbiter()  # nothing ever heard on the offboard link: it counts as lost
    d = c.check(GCS, G, 5.0)
    assert not d.refused and d.link == GCS
    c.commit(d, 5.0)
    c.heard_on(GCS, 5.0)
    assert c.check(OFFBOARD, A, 6.0).refused == "the gcs link is in control"
    assert not c.check(OFFBOARD, A, 16.0).refused  # the ground station silent: COM_DL_LOSS_T


def test_a_live_companion_keeps_control_until_the_ground_station_takes_over() -> None:
    c = arbiter()
    c.heard_on(OFFBOARD, 0.0)
    c.commit(c.check(OFFBOARD, A, 0.0), 0.0)
    assert c.check(GCS, G, 0.5).refused == "the offboard link is in control"  # an arm, say
    d = c.check(GCS, G, 0.5, takeover=True)  # a mode change: the operator's take-over
    assert not d.refused and c.link == OFFBOARD  # not before the command was accepted
    c.commit(d, 0.5)
    assert c.link == GCS and c.waiting(OFFBOARD)  # the companion's stream now waits
    back = c.check(GCS, G, 1.0, takeover=True, hands_back=True)
    c.commit(back, 1.0)
    assert (c.link, c.controller) == (OFFBOARD, None) and not c.waiting(OFFBOARD)
    c.commit(c.check(OFFBOARD, B, 1.1), 1.1)  # the next to stream on it takes it
    assert c.controller == B


def test_one_peer_at_a_time_on_the_link() -> None:
    c = arbiter()
    c.heard_on(OFFBOARD, 0.0)
    c.commit(c.check(OFFBOARD, A, 0.0), 0.0)
    assert c.check(OFFBOARD, B, 0.9).refused.startswith("a second peer 1:191")
    assert not c.check(OFFBOARD, B, 1.01).refused  # A silent for COM_OF_LOSS_T
    c.commit(c.check(OFFBOARD, B, 1.01), 1.01)
    assert c.controller == B


def test_a_refused_decision_changes_nothing() -> None:
    c = arbiter()
    c.heard_on(OFFBOARD, 0.0)
    d = c.check(GCS, G, 0.1)
    c.commit(d, 0.1)
    assert d.refused and c.link == OFFBOARD


# -- parameters --------------------------------------------------------------------------------
def test_parameters_check_set_and_announce() -> None:
    p = Parameters(COM_OF_LOSS_T=1.5)
    out = RecordingOutbox()
    rejected: list[tuple[str, rejections.CodecError, str]] = []
    proto = ParamProtocol(p, out, lambda link, err, what: rejected.append((link, err, what)))
    assert p["COM_OF_LOSS_T"] == 1.5 and p["MPC_XY_CRUISE"] == 5.0
    seen: list[tuple[str, float]] = []
    p.on_change(lambda name, value: seen.append((name, value)))
    msg = wire(m.MAVLink_param_set_message(1, 1, b"MPC_XY_CRUISE", 8.0, 9))
    assert proto.param_set("gcs", msg)
    assert p["MPC_XY_CRUISE"] == 8.0 and seen == [("MPC_XY_CRUISE", 8.0)]
    values = out.named("param_value")
    assert values[-1][:2] == (b"MPC_XY_CRUISE", 8.0) and values[-1][3] == len(p.names())
    for name, value, reason in ((b"MPC_XY_CRUISE", 99.0, "out_of_range"),
                                (b"MIS_ID", 3.0, "invalid"), (b"NOPE", 1.0, "invalid"),
                                (b"SIM_KP", math.inf, "not_finite")):
        out.clear()
        assert not proto.param_set("gcs", wire(m.MAVLink_param_set_message(1, 1, name, value,
                                                                           9)))
        assert rejected[-1][1].reason.value == reason
        known = name != b"NOPE"
        assert bool(out.named("param_value")) == known  # the unchanged value answers it
        assert out.texts() == ([f"{name.decode()}: refused {value:g}"] if known else [])
    assert p["MPC_XY_CRUISE"] == 8.0


# -- geofence ----------------------------------------------------------------------------------
def fence_item(seq: int, command: int, lat: float, lon: float, param1: float) -> mav.MissionItem:
    return mav.MissionItem(seq, m.MAV_FRAME_GLOBAL_INT, command, 0, 0, param1, 0, 0, 0,
                           round(lat * 1e7), round(lon * 1e7), 0.0)


def test_the_fence_of_mavsdks_geofence_example() -> None:
    """Four vertices ±0.0001° around home (inclusion) and MAVSDK's placeholder circle: radius 0
    at (0, 0). Inside: at least one inclusion zone contains the point, no exclusion zone."""
    lat, lon = HOME
    corners = [(lat - 1e-4, lon - 1e-4), (lat + 1e-4, lon - 1e-4), (lat + 1e-4, lon + 1e-4),
               (lat - 1e-4, lon + 1e-4)]
    items = [fence_item(k, 5001, a, b, 4) for k, (a, b) in enumerate(corners)]
    items.append(fence_item(4, 5003, 0.0, 0.0, 0.0))
    fence = Geofence(tuple(zones(items, HOME)))
    half_east = math.radians(1e-4) * mav.EARTH_RADIUS_M * math.cos(math.radians(lat))
    assert fence.inside(0.0, 0.0) and fence.inside(half_east - 0.1, 0.0)
    assert not fence.inside(half_east + 0.1, 0.0) and not fence.inside(0.0, 11.2)
    exclusion = Geofence((*fence.zones, *zones([fence_item(0, 5004, lat, lon, 3.0)], HOME)))
    assert not exclusion.inside(0.0, 0.0) and exclusion.inside(4.0, 0.0)
    assert Geofence().inside(1e6, 1e6)  # no fence


@pytest.mark.parametrize(("items", "match"), [
    ([fence_item(0, 5001, 47.0, 8.0, 3), fence_item(1, 5001, 47.1, 8.0, 3)], "polygon of 3"),
    ([fence_item(0, 5001, 47.0, 8.0, 2), fence_item(1, 5001, 47.1, 8.0, 2)], "polygon of 2"),
    ([fence_item(0, 5003, 47.0, 8.0, -1.0)], "circle radius -1"),
    ([fence_item(0, 16, 47.0, 8.0, 0.0)], "not a fence item"),
])
def test_a_fence_that_is_no_fence_is_refused(items: list[mav.MissionItem], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        zones(items, HOME)


# -- mission run -------------------------------------------------------------------------------
def item(seq: int, command: int, east: float = 0.0, north: float = 0.0, alt: float = 25.0,
         p1: float = 0.0, p2: float = 0.0, frame: int = 6) -> mav.MissionItem:
    lat, lon = mav.to_geodetic(east, north, HOME) if (east or north) else (0.0, 0.0)
    return mav.MissionItem(seq, frame, command, 0, 1, p1, p2, 0, 0, round(lat * 1e7),
                           round(lon * 1e7), alt)


def test_a_mission_run_item_by_item() -> None:
    items = [item(0, 16, 40, 0, p2=3.0), item(1, 178, alt=math.nan, p1=1.0, p2=10.0),
             item(2, 2000, alt=math.nan), item(3, 16, 40, 30, alt=488.0 + 30, frame=5),
             item(4, 20, alt=math.nan)]
    run = MissionRun(items, Frame(HOME, HOME_AMSL_M), acc_rad_m=15.0, takeoff_alt_m=2.5)
    run.start(0, Goal(0, 0, 0), landed=True)
    step = run.step(Goal(0, 0, 0), 1.0)  # on the ground: first up to the first altitude
    assert step.goal == Goal(0, 0, 25.0) and run.climb_first == 25.0
    step = run.step(Goal(0, 0, 25.0), 1.0)
    assert (step.goal.east, step.goal.north, step.goal.alt) == pytest.approx((40, 0, 25),
                                                                             abs=0.02)  # degE7
    step = run.step(Goal(37.5, 0, 24.5), 1.0)  # within param2 = 3 m and 1 m of its altitude
    assert step.reached == [0] and run.current_seq == 1
    step = run.step(Goal(37.5, 0, 24.5), 1.0)  # the speed item and the camera item pass by
    assert step.speed == 10.0 and step.reached == [1, 2] and run.current_seq == 3
    assert step.goal.alt == pytest.approx(30.0)  # GLOBAL frame: AMSL less home's
    step = run.step(Goal(40, 30, 30), 1.0)
    assert step.reached == [3]
    step = run.step(Goal(40, 30, 30), 1.0)
    assert step.rtl and step.reached == [4]


def test_waypoint_hold_time_and_the_end_of_a_mission() -> None:
    run = MissionRun([item(0, 16, 10, 0, p1=2.0)], Frame(HOME, HOME_AMSL_M), 15.0, 2.5)
    run.start(0, Goal(10, 0, 25), landed=False)
    assert run.step(Goal(10, 0, 25), 1.0).reached == [0]  # reached on arrival, then it waits
    assert not run.step(Goal(10, 0, 25), 1.0).done
    assert run.step(Goal(10, 0, 25), 1.0).reached == []
    assert run.step(Goal(10, 0, 25), 1.0).done


# -- telemetry ---------------------------------------------------------------------------------
def test_telemetry_altitudes_and_landed_state() -> None:
    r = rig(fl.PX4)
    r.ap.vehicle.alt_m, r.ap.vehicle.vz_mps = 12.5, 1.5
    r.telemetry.position()
    r.telemetry.status()
    r.telemetry.home_position()
    (lpn,) = r.out.named("local_position_ned")
    assert lpn[3] == -12.5 and lpn[6] == -1.5  # z down, vz down
    (gpi,) = r.out.named("global_position_int")
    assert gpi[1:3] == (round(HOME[0] * 1e7), round(HOME[1] * 1e7))
    assert (gpi[3], gpi[4]) == (500_500, 12_500)  # AMSL mm, relative mm
    (home,) = r.out.named("home_position")
    assert home[:3] == (int(HOME[0] * 1e7), int(HOME[1] * 1e7), 488_000)
    (ext,) = r.out.named("extended_sys_state")
    assert ext[1] == m.MAV_LANDED_STATE_IN_AIR
    r.ap.vehicle.alt_m, r.ap.vehicle.vz_mps = 0.0, 0.0
    assert r.telemetry.landed_state() == m.MAV_LANDED_STATE_ON_GROUND
    assert r.telemetry.sender("gcs", 12345) is None
    assert np.isclose(r.ap.nav.alt, 0.0)
