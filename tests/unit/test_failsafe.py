"""The offboard-loss failsafe (COM_OF_LOSS_T, COM_OF_RSM_T) on injected arrival times.

The vehicle's endpoint is built without links (no socket, no process); setpoints are
fed in with the arrival time the kernel would have stamped, and the failsafe is
checked at chosen instants, so no assertion depends on the scheduler.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from services.common import mav
from services.uavsim import flavour as fl
from services.uavsim.endpoint import Endpoint, VehicleSetup
from services.uavsim.failsafe import check_offboard
from services.uavsim.vehicle import Vehicle

m = mav.mavlink
LOSS_S = 1.0  # COM_OF_LOSS_T
_SENDER = m.MAVLink(None, srcSystem=255, srcComponent=190)


def setpoint(east: float, north: float, due_ms: int) -> Any:
    """A SET_POSITION_TARGET_LOCAL_NED (position only) as decoded off the wire."""
    msg = m.MAVLink_set_position_target_local_ned_message(
        due_ms, 1, 1, m.MAV_FRAME_LOCAL_NED, 3576, north, east, -50.0, 0, 0, 0, 0, 0, 0, 0, 0)
    return m.MAVLink(None).decode(bytearray(msg.pack(_SENDER)))


def flying(clock: str = "lockstep") -> Endpoint:
    """A vehicle at (100, 100) flying offboard, armed and airborne, its last setpoint at 10 s."""
    setup = VehicleSetup(sysid=1, altitude_m=50.0, home=(35.0, 33.0), offboard_loss_s=LOSS_S,
                         clock=clock, speed_factor=1.0)
    ep = Endpoint(Vehicle.at(100.0, 100.0), {}, setup)
    ep.mode, ep.armed, ep.airborne = fl.OFFBOARD, True, True
    assert ep.on_setpoint("offboard", setpoint(101.0, 100.0, 1000), now=10.0)
    return ep


def test_setpoints_within_com_of_loss_t_keep_the_vehicle_offboard() -> None:
    ep = flying()
    for now in (10.5, 10.99, 11.0):  # silence up to COM_OF_LOSS_T is not a loss
        check_offboard(ep, now)
        assert ep.mode == fl.OFFBOARD and not ep.failsafe
    assert ep.p("SIM_FAILSAFES") == 0.0


def test_silence_past_com_of_loss_t_holds_as_it_is_in_lockstep() -> None:
    ep = flying()
    before = ep.vehicle.state.copy(), ep.vehicle.time_ms
    check_offboard(ep, 11.01)
    assert ep.mode == fl.HOLD and ep.failsafe and ep.failsafe_since == 11.01
    assert ep.p("SIM_FAILSAFES") == 1.0 and ep.stream_stats.failsafes == 1
    # lockstep: the supervisor is the clock, so the held vehicle is exactly as it was
    assert np.array_equal(ep.vehicle.state, before[0]) and ep.vehicle.time_ms == before[1]
    check_offboard(ep, 30.0)  # one episode, counted once
    assert ep.p("SIM_FAILSAFES") == 1.0


def test_the_realtime_failsafe_brakes() -> None:
    ep = flying("realtime")
    ep.vehicle.state[2:] = (5.0, 0.0)  # flying east at 5 m/s
    check_offboard(ep, 11.5)
    assert ep.mode == fl.HOLD and ep.failsafe and ep.target is None


def test_one_setpoint_does_not_take_control_back_a_live_stream_for_com_of_rsm_t_does() -> None:
    ep = flying()
    check_offboard(ep, 12.0)
    assert ep.mode == fl.HOLD
    resume_s = ep.p("COM_OF_RSM_T")
    due = 2000
    t = 20.0  # a new stream starts after the silence
    ep.on_setpoint("offboard", setpoint(101.0, 100.0, due), now=t)
    check_offboard(ep, t)
    assert ep.mode == fl.HOLD  # one setpoint: not yet
    # the stream at 20 Hz: back in offboard once it has been live COM_OF_RSM_T
    for k in range(1, 40):
        now = t + 0.05 * k
        ep.on_setpoint("offboard", setpoint(101.0, 100.0, due), now=now)
        check_offboard(ep, now)
        if ep.mode == fl.OFFBOARD:
            break
    assert ep.mode == fl.OFFBOARD and not ep.failsafe
    assert now - t == pytest.approx(resume_s, abs=0.05 + 1e-9)
    assert ep.stream_stats.failsafe_s == pytest.approx(now - 12.0)


def test_a_gap_in_the_stream_is_the_arrival_times_not_the_read_times() -> None:
    ep = flying()
    for k in range(1, 11):  # ten setpoints 50 ms apart, as the kernel stamped them
        ep.on_setpoint("offboard", setpoint(101.0, 100.0, 1000), now=10.0 + 0.05 * k)
    stats = ep.stream_stats
    assert stats.gaps == 10 and stats.quantile_ms(0.5) == pytest.approx(50.1, abs=0.1)
    assert stats.max_ms() == pytest.approx(50.1, abs=0.1)
