"""The altitude band, the 3-D goal and the 2-D flight as the 3-D flight at one altitude."""

import math

import numpy as np
import pytest

from dualpilot.model.altitude import (
    CEILING_M,
    FLOOR_M,
    AltitudeBand,
    GoalBox,
    lift_controls,
    lift_state,
    planar_state,
)
from dualpilot.model.dynamics import DynamicsParams, rollout, step
from dualpilot.model.fire_height import FireHeightParams, cuboid_top_m
from dualpilot.model.geometry import Rect


def test_defaults_are_the_documented_ones():
    band = AltitudeBand()
    assert (band.floor_m, band.ceiling_m) == (FLOOR_M, CEILING_M) == (20.0, 120.0)
    # 400 ft is 121.92 m: the ceiling is the lower of the EU's 120 m and the US limit
    assert CEILING_M <= 400 * 0.3048
    assert band.start_altitude_m == 50.0 and band.goal_z_m == 50.0
    assert band.thickness_m == 100.0


@pytest.mark.parametrize("kwargs, match", [
    ({"floor_m": -1.0}, "floor_m < ceiling_m"),
    ({"floor_m": 130.0}, "floor_m < ceiling_m"),
    ({"start_altitude_m": 10.0}, "start_altitude_m 10.0 lies outside"),
    ({"goal_altitude_m": 121.0}, "goal_altitude_m 121.0 lies outside"),
    ({"ceiling_m": math.inf}, "finite"),
])
def test_a_bad_band_is_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        AltitudeBand(**kwargs)


def test_above_the_ceiling_is_ceiling_plus_the_margin():
    assert AltitudeBand().above_ceiling_m(25.0) == 145.0
    with pytest.raises(ValueError, match="positive"):
        AltitudeBand().above_ceiling_m(0.0)


def test_goal_box_over_the_band_and_as_a_cube():
    rect = Rect(900.0, 900.0, 100.0, 100.0)
    band = AltitudeBand(goal_altitude_m=60.0)
    g = GoalBox.over(rect, band)
    assert (g.z_lo, g.z_hi) == (20.0, 120.0)
    assert g.center == pytest.approx([900.0, 900.0, 60.0])
    assert g.contains([860.0, 940.0, 119.0]) and not g.contains([860.0, 940.0, 121.0])
    cube = GoalBox.over(rect, band, "cube")
    assert (cube.z_lo, cube.z_hi) == (20.0, 110.0)  # 60 ± 50, cut to the floor
    # 3-4-5 by hand: 30 m east of the rectangle and 40 m above the cube
    assert cube.distance([980.0, 900.0, 150.0]) == pytest.approx(50.0)
    assert cube.distance([900.0, 900.0, 60.0]) == 0.0
    with pytest.raises(ValueError, match="vertical must be one of"):
        GoalBox.over(rect, band, "sphere")  # type: ignore[arg-type]


def test_goal_distance_at_a_goal_altitude_is_the_planar_one_bit_for_bit():
    rect = Rect(900.0, 900.0, 100.0, 100.0)
    g = GoalBox.over(rect, AltitudeBand())
    rng = np.random.default_rng(3)
    for p in rng.uniform(0.0, 1000.0, size=(200, 2)):
        assert g.distance([p[0], p[1], 50.0]) == rect.distance(p)


def test_lift_and_drop_a_state():
    x = np.array([1.0, 2.0, 3.0, 4.0])
    x3 = lift_state(x, 50.0)
    assert x3.tolist() == [1.0, 2.0, 50.0, 3.0, 4.0, 0.0]
    assert planar_state(x3).tolist() == x.tolist()
    assert lift_controls([[1.0, 2.0]]).tolist() == [[1.0, 2.0, 0.0]]
    with pytest.raises(ValueError, match="shape"):
        lift_state(x3, 1.0)
    with pytest.raises(ValueError, match="shape"):
        planar_state(x)


@pytest.mark.parametrize("speed_limit", ["axis", "norm"])
def test_the_planar_flight_is_the_3d_flight_at_one_altitude(speed_limit):
    """Eq. (1) with 3×3 blocks flies a lifted 2-D plan exactly as the 2-D Eq. (1) does, its
    altitude constant and its climb 0: the 2-D numbers are the 3-D ones, bit for bit."""
    d2 = DynamicsParams(speed_limit=speed_limit)
    d3 = DynamicsParams(dim=3, speed_limit=speed_limit)
    rng = np.random.default_rng(11)
    for _ in range(300):
        horizon = int(rng.integers(1, 100))
        x = np.concatenate([rng.uniform(0.0, 1000.0, 2), rng.uniform(-15.0, 15.0, 2)])
        u = rng.uniform(-7.5, 7.5, (horizon, 2))
        z = float(rng.uniform(20.0, 120.0))
        flat = rollout(x, u, d2)
        lifted = rollout(lift_state(x, z), lift_controls(u), d3)
        assert np.array_equal(np.array([planar_state(s) for s in lifted]), flat)
        assert np.all(lifted[:, 2] == z) and np.all(lifted[:, 5] == 0.0)
        # the clipped step too (the vehicle's), with a force past the limit
        big = rng.uniform(-20.0, 20.0, 2)
        assert np.array_equal(planar_state(step(lift_state(x, z), lift_controls([big])[0], d3)),
                              step(x, big, d2))


def test_paper_cuboid_heights():
    band = AltitudeBand()
    tall = FireHeightParams()
    assert not tall.draws
    assert cuboid_top_m(tall, band, 25.0) == 145.0  # ceiling + ε: taller than the band
    uniform = FireHeightParams(fire_height="uniform")
    tops = [cuboid_top_m(uniform, band, 25.0, np.random.default_rng(k)) for k in range(500)]
    assert min(tops) >= 100.0 and max(tops) <= 250.0
    # the same draw as numpy's U[100, 250] of that generator
    assert tops[0] == np.random.default_rng(0).uniform(100.0, 250.0)
    with pytest.raises(ValueError, match="needs a generator"):
        cuboid_top_m(uniform, band, 25.0)
    with pytest.raises(ValueError, match="fire_height must be one of"):
        FireHeightParams(fire_height="tall")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="fire_height_min_m <= fire_height_max_m"):
        FireHeightParams(fire_height_min_m=300.0)
