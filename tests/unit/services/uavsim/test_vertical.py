"""The simulated vehicle under a 3-D mission configuration (services/uavsim/missionconfig.py):
in lockstep each setpoint is one step of the 3-D Eq. (1) and LOCAL_POSITION_NED and
GLOBAL_POSITION_INT carry its altitude and climb; on its own clock it keeps the planar Eq. (1)
and its altitude controller."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.model.dynamics import DynamicsParams, step
from services.common import mav, rejections
from services.uavsim import flavour as fl
from services.uavsim.autopilot import VehicleSetup
from services.uavsim.clock import LOCKSTEP, REALTIME
from services.uavsim.endpoint import Endpoint
from services.uavsim.flavour import Nav
from services.uavsim.missionconfig import apply, vertical
from services.uavsim.vehicle import Vehicle
from tests.support.vehicles import COMPANION, HOME, HOME_AMSL_M, Rig, rig, wire

m = mav.mavlink

DYN3 = DynamicsParams(dim=3)


def offboard_3d(start_altitude_m: float = 35.0) -> Rig:
    """A lockstep vehicle at (100, 100) taking a 3-D configuration, then offboard and armed."""
    r = rig(fl.ARDUPILOT, realtime=False, start=(100.0, 100.0))
    ap = r.ap
    vertical(ap.vehicle, DYN3, start_altitude_m)
    assert np.array_equal(ap.vehicle.state, [100.0, 100.0, start_altitude_m, 0.0, 0.0, 0.0])
    assert ap.decide(lambda c: ap.commander.request(Nav.OFFBOARD, c), 0.0).accepted
    assert ap.decide(ap.commander.arm, 0.0).accepted
    return r


def test_a_3d_setpoint_is_one_step_of_the_3d_eq1_and_telemetry_carries_z_down() -> None:
    r = offboard_3d()
    v, dyn = r.ap.vehicle, DYN3
    x0 = v.state.copy()
    u = np.array([2.0, -1.0, 6.0])  # a planned control: the setpoint is Φ x + Γ u
    target = step(x0, u, dyn)
    assert r.ap.setpoint("offboard", target, float(target[2]), 1000, now=0.1)
    assert np.allclose(v.state, target, atol=1e-12) and np.allclose(v.control, u, atol=1e-12)
    # by hand: v_z = (1 − ζ)·0 + ΔT/m · 6 = 5.714285… m/s; p_z = 35 + ΔT·0 = 35 m
    assert v.state[5] == pytest.approx(6.0 / 1.05) and v.state[2] == 35.0
    target2 = step(v.state, np.zeros(3), dyn)
    r.out.clear()
    assert r.ap.setpoint("offboard", target2, float(target2[2]), 2000, now=0.2)
    r.telemetry.position()
    (local,) = r.out.named("local_position_ned")
    _, n, e, d, vn, ve, vd = local
    assert (n, e) == pytest.approx((float(v.state[1]), float(v.state[0])))
    assert d == pytest.approx(-(35.0 + 6.0 / 1.05)) and vd == pytest.approx(-v.state[5])
    glob = r.out.named("global_position_int")[0]
    assert glob[4] == int((35.0 + 6.0 / 1.05) * 1000)  # relative_alt (mm): the climb seen
    assert glob[7] == int(-v.state[5] * 100)  # vz (cm/s, down positive)


def test_a_planar_configuration_after_a_3d_one_flies_the_plane_again() -> None:
    r = offboard_3d()
    v = r.ap.vehicle
    vertical(v, replace(DYN3, dim=2), 50.0)
    assert v.state.shape == (4,) and v.control.shape == (2,)
    assert r.ap.nav.alt == 50.0  # SIM_ALT_M in the air, as before


def endpoint(clock: str) -> Endpoint:
    """A real vehicle endpoint without links (its outbox sends nowhere) at (100, 100)."""
    setup = VehicleSetup(sysid=1, altitude_m=50.0, home=HOME, offboard_loss_s=1.0,
                         clock=clock, home_amsl_m=HOME_AMSL_M)
    return Endpoint(Vehicle.at(100.0, 100.0), {}, setup, boot=0.0)


CONFIG3 = MissionConfig(settings=(("dim", 3), ("start_altitude_m", 35.0)))


def test_the_lockstep_endpoint_flies_checked_3d_setpoints_and_counts_a_bad_one() -> None:
    ep = endpoint(LOCKSTEP)
    apply(ep, CONFIG3)
    v = ep.vehicle
    assert v.dyn.dim == 3 and np.array_equal(v.state, [100.0, 100.0, 35.0, 0.0, 0.0, 0.0])
    ap = ep.ap
    assert ap.decide(lambda c: ap.commander.request(Nav.OFFBOARD, c), 0.0).accepted
    assert ap.decide(ap.commander.arm, 0.0).accepted
    target = step(v.state, np.array([0.0, 1.0, -3.0]), v.dyn)
    # NED: north, east, down = −p_z; velocity north, east, down = −v_z
    msg = wire(m.MAVLink_set_position_target_local_ned_message(
        1000, 1, 1, m.MAV_FRAME_LOCAL_NED, mav.TYPE_MASK_POS_VEL, target[1], target[0],
        -target[2], target[4], target[3], -target[5], 0, 0, 0, 0, 0), COMPANION[1:])
    assert ep.on_setpoint("offboard", COMPANION, msg, 0.1)
    assert np.allclose(v.state, target, atol=1e-4)  # float32 on the wire
    assert v.state[5] == pytest.approx(-3.0 / 1.05, abs=1e-5)  # sinking: ΔT/m · u_z
    before = rejections.REJECTED.snapshot().get("mavlink/offboard", {}).get("out_of_range", 0)
    below = wire(m.MAVLink_set_position_target_local_ned_message(
        2000, 1, 1, m.MAV_FRAME_LOCAL_NED, mav.TYPE_MASK_POS_VEL, 100.0, 100.0, 2.0,
        0, 0, 0, 0, 0, 0, 0, 0), COMPANION[1:])  # z = +2: 2 m below the ground
    x = v.state.copy()
    assert not ep.on_setpoint("offboard", COMPANION, below, 0.2)
    assert np.array_equal(v.state, x)  # refused, not flown
    after = rejections.REJECTED.snapshot()["mavlink/offboard"]["out_of_range"]
    assert after == before + 1


def test_on_its_own_clock_a_3d_configuration_keeps_the_altitude_controller() -> None:
    ep = endpoint(REALTIME)
    apply(ep, CONFIG3)
    assert ep.vehicle.dyn.dim == 2 and ep.vehicle.state.shape == (4,)


def test_the_lockstep_endpoint_keeps_3d_setpoints_in_the_mission_band_grown_by_its_margin(
        ) -> None:
    """CONFIG3's band is the default [20, 120] m; grown by 20 m: [0, 140] m. A setpoint at
    139.5 m is flown, one at 140.5 m is a counted ``out_of_range`` rejection, not flown."""
    ep = endpoint(LOCKSTEP)
    assert ep.setup.band is None  # no mission yet: the 10 km sanity bound
    apply(ep, CONFIG3)
    assert ep.setup.band is not None
    assert (ep.setup.band.floor_m, ep.setup.band.ceiling_m) == (20.0, 120.0)
    ap, v = ep.ap, ep.vehicle
    assert ap.decide(lambda c: ap.commander.request(Nav.OFFBOARD, c), 0.0).accepted
    assert ap.decide(ap.commander.arm, 0.0).accepted

    def at(altitude_m: float, time_ms: int) -> object:
        return wire(m.MAVLink_set_position_target_local_ned_message(
            time_ms, 1, 1, m.MAV_FRAME_LOCAL_NED, mav.TYPE_MASK_POS, 110.0, 105.0,
            -altitude_m, 0, 0, 0, 0, 0, 0, 0, 0), COMPANION[1:])

    def out_of_range() -> int:
        return rejections.REJECTED.snapshot().get("mavlink/offboard", {}).get("out_of_range", 0)

    before = out_of_range()
    assert ep.on_setpoint("offboard", COMPANION, at(139.5, 1000), 0.1)
    # flown: one step towards 104.5 m above, the force up at u_max = 7.5 N: v_z = ΔT/m · 7.5
    assert v.time_ms == 1000 and v.control[2] == 7.5
    assert v.state[5] == pytest.approx(7.5 / 1.05)
    x = v.state.copy()
    assert not ep.on_setpoint("offboard", COMPANION, at(140.5, 2000), 0.2)
    assert np.array_equal(v.state, x)  # refused, not flown
    assert out_of_range() == before + 1
    apply(ep, MissionConfig())  # a planar mission: no band, its setpoints as before
    assert ep.setup.band is None


def test_a_faster_mission_grows_the_band_by_its_braking_overshoot() -> None:
    """v_max 25 m/s: braking from it along z carries the vehicle 25 + 12.857 + 3.143 = 41 m
    (tests/unit/services/common/test_setpoint_band.py): the band grows by 41 m, not 20."""
    ep = endpoint(LOCKSTEP)
    apply(ep, CONFIG3)
    assert ep.setup.band_margin_m == 20.0
    apply(ep, replace(CONFIG3, settings=(*CONFIG3.settings, ("v_max_mps", 25.0))))
    assert ep.setup.band_margin_m == 41.0


def test_on_its_own_clock_no_band_is_kept() -> None:
    ep = endpoint(REALTIME)
    apply(ep, CONFIG3)
    assert ep.setup.band is None
