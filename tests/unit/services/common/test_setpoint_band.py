"""A 3-D setpoint's altitude against a planning mission's band (services/common/mavlink_codec.py).

The band [40, 90] m grown by SETPOINT_BAND_MARGIN_M = 20 m is [20, 110] m: 109.5 m and 20.5 m
are flown, 110.5 m and 19.5 m are ``out_of_range`` rejections; with no band known the altitude
may be anywhere in [0, 10 km]; a planar setpoint is checked as before, band or not.
"""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from dualpilot.mission.braking import braking_overshoot_m
from dualpilot.model.altitude import AltitudeBand
from dualpilot.model.dynamics import DynamicsParams
from services.common import mav, mavlink_codec, rejections
from services.common.mavlink_codec import (
    SETPOINT_BAND_MARGIN_M,
    setpoint_band_margin_m,
    setpoint_from_mavlink,
)

BAND = AltitudeBand(floor_m=40.0, ceiling_m=90.0, start_altitude_m=50.0)


def setpoint(altitude_m: float, mask: int = mav.TYPE_MASK_POS_VEL) -> Any:
    """A LOCAL_NED setpoint at (east 120, north 340) m, ``altitude_m`` up (z down), climbing
    at 1.25 m/s."""
    return SimpleNamespace(coordinate_frame=mav.MAV_FRAME_LOCAL_NED, type_mask=mask,
                           x=340.0, y=120.0, z=-altitude_m, vx=-2.0, vy=4.5, vz=-1.25)


def rejected(altitude_m: float, band: AltitudeBand | None = BAND,
             dim: int = 3) -> rejections.CodecError:
    with pytest.raises(rejections.CodecError) as err:
        setpoint_from_mavlink(setpoint(altitude_m), 1000.0, 0, dim=dim, band=band)
    return err.value


def test_the_margin_is_20_m() -> None:
    assert SETPOINT_BAND_MARGIN_M == 20.0  # the hand values below are worked out with it


def test_a_vehicle_grows_the_band_by_the_braking_overshoot_rounded_up() -> None:
    """Braking from v_max along one axis (Eq. (1): v' = 0.8 v + u/1.05, |u| <= 7.5 N, the brake
    u = -1.05·0.8·v clipped): from 15 m/s, 15 m then 0.8·15 - 7.5/1.05 = 4.857 m (19.857 m:
    20 m); from 25 m/s, 25, then 12.857, then 0.8·12.857 - 7.5/1.05 = 3.143 m (41 m)."""
    assert braking_overshoot_m(DynamicsParams(dim=3)) == pytest.approx(15.0 + 12.0 - 7.5 / 1.05)
    assert braking_overshoot_m(DynamicsParams(dim=3, v_max_mps=25.0)) == pytest.approx(41.0)
    assert setpoint_band_margin_m(DynamicsParams(dim=3)) == SETPOINT_BAND_MARGIN_M == 20.0
    assert setpoint_band_margin_m(DynamicsParams(dim=3, v_max_mps=25.0)) == 41.0
    grown = setpoint_from_mavlink(setpoint(130.5), 1000.0, 0, dim=3, band=BAND,
                                  band_margin_m=41.0)  # [40, 90] grown by 41: up to 131 m
    assert grown[2] == pytest.approx(130.5)
    with pytest.raises(rejections.CodecError, match="grown by 41 m"):
        setpoint_from_mavlink(setpoint(131.5), 1000.0, 0, dim=3, band=BAND, band_margin_m=41.0)


@pytest.mark.parametrize("altitude_m", [109.5, 110.0, 90.0, 40.0, 20.0, 20.5])
def test_a_setpoint_in_the_grown_band_is_flown(altitude_m: float) -> None:
    target = setpoint_from_mavlink(setpoint(altitude_m), 1000.0, 0, dim=3, band=BAND)
    assert np.array_equal(target, [120.0, 340.0, altitude_m, 4.5, -2.0, 1.25])


@pytest.mark.parametrize(("altitude_m", "shown"), [(110.5, "110.5 m"), (19.5, "19.5 m"),
                                                   (500.0, "500 m")])
def test_a_setpoint_outside_the_grown_band_is_out_of_range(altitude_m: float,
                                                           shown: str) -> None:
    err = rejected(altitude_m)
    assert err.reason == rejections.Reason.OUT_OF_RANGE
    assert str(err) == (f"setpoint altitude {shown} is outside the band [40, 90] m grown by "
                        f"20 m")


def test_a_position_only_setpoint_is_checked_against_the_band_too() -> None:
    held = setpoint_from_mavlink(setpoint(109.5, mav.TYPE_MASK_POS), 1000.0, 0, dim=3,
                                 band=BAND)
    assert np.array_equal(held, [120.0, 340.0, 109.5, 0.0, 0.0, 0.0])
    with pytest.raises(rejections.CodecError, match="outside the band"):
        setpoint_from_mavlink(setpoint(110.5, mav.TYPE_MASK_POS), 1000.0, 0, dim=3, band=BAND)


def test_without_a_band_the_sanity_bound_holds() -> None:
    for altitude_m in (500.0, 110.5, 19.5, 9_999.0):
        target = setpoint_from_mavlink(setpoint(altitude_m), 1000.0, 0, dim=3)
        assert target[2] == altitude_m
    too_high = rejected(2e4, band=None)
    assert too_high.reason == rejections.Reason.OUT_OF_RANGE and "setpoint z" in str(too_high)
    assert rejected(-0.5, band=None).reason == rejections.Reason.OUT_OF_RANGE  # underground


def test_the_other_checks_come_first() -> None:
    """The planar checks, the ground and the sanity bound before the band: their reasons."""
    underground = str(rejected(-0.5))
    assert "altitude -0.5 m out of range" in underground and "band" not in underground
    assert rejected(math.nan).reason == rejections.Reason.NOT_FINITE
    assert "setpoint z" in str(rejected(2e4))


def test_a_planar_setpoint_is_checked_as_before_band_or_not() -> None:
    for band in (None, BAND):
        target = setpoint_from_mavlink(setpoint(500.0), 1000.0, 0, dim=2, band=band)
        assert np.array_equal(target, [120.0, 340.0, 4.5, -2.0])
        assert rejected(2e4, band=band, dim=2).reason == rejections.Reason.OUT_OF_RANGE
    assert mavlink_codec.MAX_SETPOINT_ALT_M == 10_000.0
