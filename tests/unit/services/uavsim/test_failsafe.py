"""The failsafes (services/uavsim/failsafe.py) on injected arrival times: offboard loss, geofence
breach, empty battery.

The vehicle is built without links (tests/support/vehicles.py); setpoints
are fed in with the arrival time the kernel would have stamped, and the
failsafe is chosen at chosen instants, so no assertion depends on the scheduler.
"""

from __future__ import annotations

import numpy as np
import pytest

from services.common import mav
from services.uavsim import flavour as fl
from services.uavsim.flavour import Nav
from services.uavsim.geofence import Geofence, Zone
from tests.support.vehicles import Rig, rig

m = mav.mavlink
LOSS_S = 1.0  # COM_OF_LOSS_T


def target(east: float, north: float) -> np.ndarray:
    return np.array([east, north, 0.0, 0.0])


def flying(realtime: bool = False, flavour: fl.Flavour = fl.ARDUPILOT) -> Rig:
    """A vehicle at (100, 100) flying offboard, armed and airborne, its last setpoint at 10 s."""
    r = rig(flavour, realtime=realtime, start=(100.0, 100.0))
    ap = r.ap
    ap.setpoint("offboard", target(101.0, 100.0), 50.0, 1000, now=9.9)
    assert ap.decide(lambda c: ap.commander.request(Nav.OFFBOARD, c), 9.95).accepted
    assert ap.decide(ap.commander.arm, 9.95).accepted
    assert ap.setpoint("offboard", target(101.0, 100.0), 50.0, 2000, now=10.0) != realtime
    if realtime:
        r.fly(2.0, now=10.0)
    assert ap.nav.flown_offboard and not ap.nav.landed
    return r


def test_setpoints_within_com_of_loss_t_keep_the_vehicle_offboard() -> None:
    r = flying()
    for now in (10.5, 10.99, 11.0):  # silence up to COM_OF_LOSS_T is not a loss
        r.ap.watch(now)
        assert r.nav is Nav.OFFBOARD and r.ap.commander.failsafe is None
    assert r.params["SIM_FAILSAFES"] == 0.0


def test_silence_past_com_of_loss_t_holds_as_it_is_in_lockstep() -> None:
    r = flying()
    v = r.ap.vehicle
    before = v.state.copy(), v.time_ms
    assert np.any(v.state[2:] != 0)  # still moving after its step
    r.ap.watch(11.01)
    assert r.nav is Nav.HOLD and r.ap.in_offboard_failsafe and r.ap.failsafe_since == 11.01
    assert r.params["SIM_FAILSAFES"] == 1.0 and r.ap.stream_stats.failsafes == 1
    assert "LOITER: offboard lost" in r.texts()
    # lockstep: the supervisor is the clock, so the held vehicle is exactly as it was
    assert np.array_equal(v.state, before[0]) and v.time_ms == before[1]
    r.ap.watch(30.0)  # one episode, counted once
    assert r.params["SIM_FAILSAFES"] == 1.0


def test_the_realtime_failsafe_brakes() -> None:
    r = flying(realtime=True)
    r.ap.vehicle.state[2:] = (5.0, 0.0)  # flying east at 5 m/s
    r.ap.watch(11.5)
    assert r.nav is Nav.HOLD and np.array_equal(r.ap.vehicle.state[2:], [0.0, 0.0])


def test_one_setpoint_does_not_take_control_back_a_live_stream_for_com_of_rsm_t_does() -> None:
    r = flying()
    ap = r.ap
    ap.watch(12.0)
    assert r.nav is Nav.HOLD
    resume_s = r.params["COM_OF_RSM_T"]
    t = 20.0  # a new stream starts after the silence
    ap.setpoint("offboard", target(101.0, 100.0), 50.0, 2000, now=t)
    ap.watch(t)
    assert r.nav is Nav.HOLD  # one setpoint: not yet
    for k in range(1, 40):  # the stream at 20 Hz: offboard again once live COM_OF_RSM_T
        now = t + 0.05 * k
        ap.setpoint("offboard", target(101.0, 100.0), 50.0, 2000, now=now)
        ap.watch(now)
        if r.nav is Nav.OFFBOARD:
            break
    assert r.nav is Nav.OFFBOARD and ap.commander.failsafe is None
    assert now - t == pytest.approx(resume_s, abs=0.05 + 1e-9)
    assert ap.stream_stats.failsafe_s == pytest.approx(now - 12.0)


def test_a_commanded_mode_ends_the_offboard_failsafe() -> None:
    r = flying()
    r.ap.watch(12.0)
    assert r.ap.decide(lambda c: r.ap.commander.request(Nav.LAND, c), 12.5).accepted
    assert r.ap.commander.failsafe is None and r.nav is Nav.LAND
    assert r.ap.stream_stats.failsafe_s == pytest.approx(0.5)


def test_ardupilots_guided_without_a_stream_has_no_offboard_failsafe() -> None:
    r = rig(fl.ARDUPILOT, realtime=True)
    ap = r.ap
    assert ap.decide(lambda c: ap.commander.request(Nav.OFFBOARD, c), 0.0).accepted
    assert ap.decide(ap.commander.arm, 0.0).accepted
    ap.watch(30.0)  # GUIDED, holding, no stream ever: nothing to lose
    assert r.nav is Nav.OFFBOARD and ap.commander.failsafe is None


def test_a_gap_in_the_stream_is_the_arrival_times_not_the_read_times() -> None:
    r = flying()
    for k in range(1, 11):  # ten setpoints 50 ms apart, as the kernel stamped them
        r.ap.setpoint("offboard", target(101.0, 100.0), 50.0, 2000, now=10.0 + 0.05 * k)
    stats = r.ap.stream_stats
    assert stats.gaps == 11 and stats.quantile_ms(0.5) == pytest.approx(50.1, abs=0.1)


def fenced(r: Rig, action: int) -> None:
    """A 20 m inclusion square around (0, 0), GF_ACTION ``action``, the vehicle in the air at
    (0, 0) in Hold."""
    r.params.set("GF_ACTION", action)
    r.ap.fence = Geofence((Zone(True, np.array([[-10.0, -10], [10, -10], [10, 10], [-10, 10]])),))
    ap = r.ap
    assert ap.decide(ap.commander.arm, 0.0).accepted
    r.ap.nav.takeoff_alt = 10.0
    assert ap.decide(ap.commander.takeoff, 0.0).accepted
    r.fly(6.0)
    assert r.nav is Nav.HOLD and ap.vehicle.alt_m == pytest.approx(10.0)


@pytest.mark.parametrize(("action", "nav"), [(2, Nav.HOLD), (3, Nav.RETURN), (5, Nav.LAND)])
def test_leaving_the_fence_does_gf_action(action: int, nav: Nav) -> None:
    r = rig(fl.PX4)
    fenced(r, action)
    ap = r.ap
    ap.vehicle.state[:2] = (15.0, 0.0)  # out of the square (an operator's sticks, a gust)
    r.out.clear()
    ap.watch(1.0)
    assert ap.commander.failsafe is not None and ap.commander.failsafe.cause == "geofence"
    assert r.nav is nav and "Failsafe: geofence breached" in r.texts()
    # the operator takes over with a mode change, and flies back in: no second breach
    assert ap.decide(lambda c: ap.commander.request(Nav.HOLD, c), 2.0).accepted
    assert ap.commander.failsafe is None
    ap.watch(3.0)
    assert ap.commander.failsafe is None and r.nav is Nav.HOLD


def test_gf_action_warn_only_says_so() -> None:
    r = rig(fl.PX4)
    fenced(r, 1)
    r.ap.vehicle.state[:2] = (0.0, 15.0)
    r.out.clear()
    r.ap.watch(1.0)
    assert r.ap.commander.failsafe is None and r.nav is Nav.HOLD
    assert r.texts() == ["Geofence breached"]


def test_an_empty_battery_lands() -> None:
    r = rig(fl.PX4)
    fenced(r, 0)
    r.ap.vehicle.impulse_ns = r.ap.vehicle.capacity_ns  # all used
    r.ap.watch(1.0)
    assert r.nav is Nav.LAND and r.ap.commander.failsafe is not None
    assert r.ap.decide(lambda c: r.ap.commander.request(Nav.HOLD, c), 2.0).accepted
    assert r.nav is Nav.LAND  # only disarming ends it


def test_a_fence_hold_stops_a_goto_that_flies_out() -> None:
    """A goto in Hold (PX4) towards a point outside the fence: the breach's Hold (GF_ACTION 2)
    is the state already flown, and it stops the vehicle where it broke out."""
    r = rig(fl.PX4)
    fenced(r, 2)
    assert r.command(m.MAV_CMD_DO_REPOSITION, -1, 1, 0, float("nan"),
                     *mav.to_geodetic(100.0, 0.0, (47.397742, 8.545594)), float("nan")) == 0
    for _ in range(30):
        r.fly(1.0)
        if r.ap.commander.failsafe is not None:
            break
    assert r.ap.commander.failsafe is not None and r.nav is Nav.HOLD
    east = float(r.ap.vehicle.state[0])
    assert 10.0 < east < 16.0  # out by at most one step at the cruise speed
    r.fly(10.0)
    assert float(r.ap.vehicle.state[0]) == pytest.approx(east, abs=5.0)  # it stopped there
