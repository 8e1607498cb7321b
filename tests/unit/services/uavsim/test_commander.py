"""The vehicle's state machine (services/uavsim/commander.py): every transition and every refusal.

Each refusal is checked for the COMMAND_ACK result a ground station gets
(PX4's commander answers TEMPORARILY_REJECTED, ArduPilot FAILED, a mission
start without a mission DENIED) and the STATUSTEXT it shows; no process,
no socket.
"""

from __future__ import annotations

import pytest

from services.common import mav
from services.uavsim.commander import Commander, Conditions, Failsafe
from services.uavsim.flavour import ARDUPILOT, PX4, Flavour, Nav

m = mav.mavlink
ACCEPTED = m.MAV_RESULT_ACCEPTED
#: a vehicle that could do anything: every requirement holds
ALL = Conditions(offboard_signal=True, offboard_resumed=True, manual_control=True,
                 mission_valid=True, mission_takeoff=True, landed=True)
FLAVOURS = [PX4, ARDUPILOT]


def refused(flavour: Flavour) -> int:
    return int(m.MAV_RESULT_TEMPORARILY_REJECTED if flavour is PX4 else m.MAV_RESULT_FAILED)


@pytest.mark.parametrize("flavour", FLAVOURS, ids=lambda f: f.name)
@pytest.mark.parametrize(("nav", "missing", "why"), [
    (Nav.MISSION, {"mission_valid": False}, "no valid mission"),
    (Nav.MISSION, {"own_clock": False}, "lockstep clock: no flight time"),
    (Nav.RETURN, {"home_valid": False}, "no home position"),
    (Nav.RETURN, {"own_clock": False}, "lockstep clock: no flight time"),
    (Nav.POSITION, {"manual_control": False}, "no manual control"),
])
def test_a_state_that_cannot_run_is_refused_with_its_reason(flavour: Flavour, nav: Nav,
                                                            missing: dict[str, bool],
                                                            why: str) -> None:
    c = Commander(flavour)
    out = c.request(nav, Conditions(**{**ALL.__dict__, **missing}))
    assert (out.result, out.text) == (refused(flavour), f"{flavour.names[nav]} refused: {why}")
    assert c.nav is Nav.HOLD and c.changes == []


def test_offboard_needs_a_setpoint_stream_in_px4_not_in_ardupilots_guided() -> None:
    px4, apm = Commander(PX4), Commander(ARDUPILOT)
    out = px4.request(Nav.OFFBOARD, Conditions())
    assert (out.result, out.text) == (m.MAV_RESULT_TEMPORARILY_REJECTED,
                                      "Offboard refused: no setpoint stream")
    assert apm.request(Nav.OFFBOARD, Conditions()).accepted and apm.nav is Nav.OFFBOARD
    assert px4.request(Nav.OFFBOARD, ALL).accepted
    assert px4.changes == [(Nav.HOLD, Nav.OFFBOARD, "commanded")]


@pytest.mark.parametrize("flavour", FLAVOURS, ids=lambda f: f.name)
@pytest.mark.parametrize("nav", list(Nav))
def test_every_state_is_reachable_when_its_requirements_hold(flavour: Flavour, nav: Nav) -> None:
    c = Commander(flavour, armed=True)
    assert c.request(nav, Conditions(**{**ALL.__dict__, "landed": False})).accepted
    assert c.nav is nav and c.intended is nav
    assert flavour.custom_mode(nav) == flavour.modes[nav]


@pytest.mark.parametrize("flavour", FLAVOURS, ids=lambda f: f.name)
@pytest.mark.parametrize(("condition", "text"), [
    ("battery_left", "Arming denied: battery empty"),
    ("home_valid", "Arming denied: no home position"),
    ("inside_fence", "Arming denied: vehicle outside geofence"),
])
def test_the_pre_arm_checks(flavour: Flavour, condition: str, text: str) -> None:
    c = Commander(flavour)
    out = c.arm(Conditions(**{**ALL.__dict__, condition: False}))
    assert (out.result, out.text, c.armed) == (refused(flavour), text, False)
    out = c.arm(ALL)
    assert (out.result, out.text, c.armed) == (ACCEPTED, "Armed by external command", True)
    assert c.arm(ALL).accepted  # armed already: nothing to do


@pytest.mark.parametrize(("flavour", "nav", "text"), [
    (PX4, Nav.LAND, "Arming denied: not in Land"),
    (PX4, Nav.RETURN, "Arming denied: not in Return"),
    (ARDUPILOT, Nav.MISSION, "Arming denied: not in AUTO"),
    (ARDUPILOT, Nav.RETURN, "Arming denied: not in RTL"),
    (PX4, Nav.OFFBOARD, "Arming denied: Offboard: no setpoint stream"),
])
def test_states_that_prevent_arming_and_an_offboard_without_a_stream(flavour: Flavour, nav: Nav,
                                                                     text: str) -> None:
    c = Commander(flavour, intended=nav)
    out = c.arm(Conditions(mission_valid=True))
    assert (out.result, out.text, c.armed) == (refused(flavour), text, False)


@pytest.mark.parametrize("flavour", FLAVOURS, ids=lambda f: f.name)
def test_disarming_in_the_air_needs_the_force_flag(flavour: Flavour) -> None:
    c = Commander(flavour, armed=True)
    flying = Conditions(landed=False)
    out = c.disarm(flying)
    assert (out.result, out.text, c.armed) == (refused(flavour), "Disarming denied: not landed",
                                               True)
    out = c.disarm(flying, forced=True)
    assert (out.result, out.text, c.armed) == (ACCEPTED, "Disarmed by external command", False)
    assert c.disarm(flying).accepted  # disarmed already


def test_disarming_in_a_state_that_prevents_arming_leaves_it_for_hold_in_px4() -> None:
    c = Commander(PX4, armed=True, intended=Nav.LAND)
    assert c.disarm(Conditions(), why="landing").text == "Disarmed by landing"
    assert c.nav is Nav.HOLD and c.changes == [(Nav.LAND, Nav.HOLD, "disarmed")]
    assert c.arm(ALL).accepted
    apm = Commander(ARDUPILOT, armed=True, intended=Nav.LAND)  # ArduCopter stays in LAND
    assert apm.disarm(Conditions()).accepted and apm.nav is Nav.LAND
    assert apm.arm(ALL).text == "Arming denied: not in LAND"


@pytest.mark.parametrize("flavour", FLAVOURS, ids=lambda f: f.name)
def test_takeoff_needs_arming_and_ardupilots_needs_guided(flavour: Flavour) -> None:
    c = Commander(flavour)
    out = c.takeoff(ALL)
    assert (out.result, out.text) == (refused(flavour), "Takeoff denied: not armed")
    c.armed = True
    out = c.takeoff(ALL)
    if flavour is ARDUPILOT:
        assert (out.result, out.text) == (refused(flavour), "Takeoff denied: not in GUIDED")
        assert c.request(Nav.OFFBOARD, ALL).accepted
        out = c.takeoff(ALL)
    assert out.accepted and c.nav is Nav.TAKEOFF
    c.done(Nav.TAKEOFF)  # PX4: Hold after the climb; ArduPilot stays in GUIDED
    assert c.nav is (Nav.HOLD if flavour is PX4 else Nav.OFFBOARD)


def test_the_done_transitions_of_px4_and_ardupilot() -> None:
    for flavour, mission_done in ((PX4, Nav.HOLD), (ARDUPILOT, Nav.MISSION)):
        c = Commander(flavour, armed=True, intended=Nav.MISSION)
        c.done(Nav.MISSION)
        assert c.nav is mission_done
        c.intended = Nav.RETURN
        c.done(Nav.RETURN)
        assert c.nav is Nav.LAND
        c.done(Nav.TAKEOFF)  # not the state flown: nothing
        assert c.nav is Nav.LAND


def test_land_and_return_say_what_they_do() -> None:
    c = Commander(PX4, armed=True)
    out = c.land(ALL)
    assert (out.result, out.text, c.nav) == (ACCEPTED, "Landing at current position", Nav.LAND)
    out = c.rtl(ALL)
    assert (out.result, out.text, c.nav) == (ACCEPTED, "Returning to launch", Nav.RETURN)


def test_mission_start_arms_px4_and_needs_an_armed_ardupilot() -> None:
    c = Commander(PX4)
    out = c.mission_start(Conditions())
    assert (out.result, out.text) == (m.MAV_RESULT_DENIED,
                                      "Mission start denied! No valid mission")
    out = c.mission_start(ALL)
    assert (out.result, out.text, c.armed, c.nav) == (ACCEPTED, "Armed by mission start", True,
                                                      Nav.MISSION)
    apm = Commander(ARDUPILOT)
    out = apm.mission_start(ALL)
    assert (out.result, out.text) == (m.MAV_RESULT_FAILED, "Mission start denied: not armed")
    apm.armed = True
    assert apm.mission_start(ALL).accepted and apm.nav is Nav.MISSION


def test_ardupilot_auto_on_the_ground_needs_a_takeoff_item() -> None:
    c = Commander(ARDUPILOT, armed=True, intended=Nav.OFFBOARD)
    out = c.request(Nav.MISSION, Conditions(**{**ALL.__dict__, "mission_takeoff": False}))
    assert (out.result, out.text) == (m.MAV_RESULT_FAILED, "Auto: Missing Takeoff Cmd")
    assert c.request(Nav.MISSION, ALL).accepted  # it has one
    in_air = Commander(ARDUPILOT, armed=True, intended=Nav.OFFBOARD)
    assert in_air.request(Nav.MISSION, Conditions(
        **{**ALL.__dict__, "mission_takeoff": False, "landed": False})).accepted


@pytest.mark.parametrize(("flavour", "target"), [(PX4, Nav.HOLD), (ARDUPILOT, Nav.OFFBOARD)])
def test_reposition_flies_in_hold_or_guided_only_in_the_air(flavour: Flavour,
                                                            target: Nav) -> None:
    c = Commander(flavour)
    out = c.reposition(ALL, change_mode=True)
    assert (out.result, out.text) == (refused(flavour), "Reposition denied: not flying")
    c.armed = True
    flying = Conditions(**{**ALL.__dict__, "landed": False})
    out = c.reposition(Conditions(**{**flying.__dict__, "own_clock": False}), True)
    assert out.text == "Reposition denied: lockstep clock: no flight time"
    c.intended = Nav.MISSION
    out = c.reposition(flying, change_mode=False)
    assert out.result == m.MAV_RESULT_UNSUPPORTED
    assert c.reposition(flying, change_mode=True).accepted and c.nav is target
    assert c.reposition(flying, change_mode=False).accepted  # in that state already


def test_a_failsafe_flies_its_action_and_a_mode_change_ends_it() -> None:
    c = Commander(PX4, armed=True, intended=Nav.OFFBOARD)
    c.set_failsafe(Failsafe("offboard_lost", Nav.HOLD, "offboard lost", "condition"))
    assert c.nav is Nav.HOLD and c.intended is Nav.OFFBOARD
    assert c.changes == [(Nav.OFFBOARD, Nav.HOLD, "offboard lost")]
    assert c.request(Nav.LAND, ALL).accepted  # the operator takes over with a mode switch
    assert c.failsafe is None and c.nav is Nav.LAND
    c.set_failsafe(Failsafe("battery_empty", Nav.LAND, "battery empty", "disarm"))
    assert c.request(Nav.HOLD, ALL).accepted and c.nav is Nav.LAND  # only disarming ends it
    assert c.disarm(ALL).accepted and c.failsafe is None


def test_a_warning_failsafe_flies_nothing() -> None:
    c = Commander(PX4, armed=True, intended=Nav.MISSION)
    c.set_failsafe(Failsafe("geofence", None, "geofence breached", "mode"))
    assert c.nav is Nav.MISSION and c.changes == []


@pytest.mark.parametrize("flavour", FLAVOURS, ids=lambda f: f.name)
def test_mode_numbers_round_trip(flavour: Flavour) -> None:
    for nav in Nav:
        custom = flavour.custom_mode(nav)
        if nav is not Nav.TAKEOFF or flavour is PX4:  # ArduPilot's take-off is GUIDED's
            assert flavour.nav_of(custom) is nav
    assert PX4.from_command(4.0, float("nan")) == 4 << 16  # NaN sub mode: unset
    assert PX4.nav_of(4 << 16) is Nav.MISSION  # AUTO without a sub mode (Commander.cpp)
    assert PX4.from_command(6.0, 0.0) == 6 << 16 and ARDUPILOT.from_command(4.0, 0.0) == 4
    assert PX4.from_command(float("nan"), 0.0) is None and ARDUPILOT.from_command(4.5, 0) is None
    assert PX4.name_of(PX4.custom_mode(Nav.HOLD)) == "AUTO.LOITER"
    assert ARDUPILOT.name_of(17) == "BRAKE" and ARDUPILOT.nav_of(17) is Nav.HOLD
