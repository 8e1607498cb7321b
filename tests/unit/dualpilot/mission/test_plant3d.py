"""The multirotor in the 3-D missions (docs/plant.md, "In 3-D"): the model's z is the plant's
altitude, the measured state carries the vertical GPS error, d_safe is judged on the flown
3-D path against the cuboids, and the tube covers the 3-D error."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.flight import PlantVehicle, judge_flight
from dualpilot.mission.local import local_mission
from dualpilot.mission.params import Timing
from dualpilot.mission.result import Ending
from dualpilot.model.dynamics import DynamicsParams, hover_state
from dualpilot.model.geometry import Rect
from dualpilot.model.prism import Cuboid
from dualpilot.plant import MultirotorPlant, PlantParams
from dualpilot.plant.reading import (
    RAYLEIGH_P999,
    PlantReading,
    _norm_p999_factor,
    auto_margin_m,
    gps_norm_p999_m,
    measurement_tol,
)
from dualpilot.plant.sensors import VERTICAL_RATIO, GpsParams

DYN3 = DynamicsParams(dim=3)
CALM = (("plant", "multirotor"), ("gps_sigma_m", 0.0), ("turbulence", "none"),
        ("wind_speed_mps", 0.0))


# -- the tube in 3-D ---------------------------------------------------------------------------
def test_the_3d_errors_quantile_against_its_limits_and_draws() -> None:
    """The 99.9th percentile of ‖e‖, e ~ N(0, diag(σ², σ², (rσ)²)): χ with 3 degrees of
    freedom when r = 1, Rayleigh's 3.717 as r → 0, and 2,000,000 seeded draws at
    Beard & McLain's r = 0.40/0.21 within 0.5 %."""
    assert _norm_p999_factor(1.0) == pytest.approx(chi(3).ppf(0.999), rel=1e-9)
    assert _norm_p999_factor(0.05) == pytest.approx(RAYLEIGH_P999, rel=1e-3)
    draws = np.random.default_rng(7).standard_normal((2_000_000, 3)) * [1.5, 1.5,
                                                                         1.5 * VERTICAL_RATIO]
    sampled = float(np.quantile(np.linalg.norm(draws, axis=1), 0.999))
    assert gps_norm_p999_m(1.5) == pytest.approx(sampled, rel=5e-3)
    assert gps_norm_p999_m(1.5) == pytest.approx(9.6824, abs=1e-4)
    assert gps_norm_p999_m(0.0) == 0.0


def test_the_3d_tube_and_tolerance_leave_the_2d_ones_as_they_were() -> None:
    """"norm" (the default) covers the 3-D error in a 3-D mission; "horizontal" and every
    2-D mission keep the 2-D tube (3.717 σ + 3.0 m); the ideal plant has none."""
    noisy = PlantReading(plant="multirotor", gps_sigma_m=1.5, turbulence="moderate")
    planar = RAYLEIGH_P999 * 1.5 + 3.0
    assert auto_margin_m(noisy) == auto_margin_m(noisy, 2) == pytest.approx(planar)
    assert auto_margin_m(noisy, 3) == pytest.approx(9.682370 + 3.5, abs=1e-6)
    flat = PlantReading(plant="multirotor", gps_sigma_m=1.5, turbulence="moderate",
                        tube_vertical="horizontal")
    assert auto_margin_m(flat, 3) == pytest.approx(planar)
    assert auto_margin_m(PlantReading(gps_sigma_m=1.5), 3) == 0.0
    base = MissionConfig(settings=(("plant", "multirotor"), ("gps_sigma_m", 1.5),
                                   ("turbulence", "moderate")))
    assert base.spec().tracking_margin_m == pytest.approx(planar, abs=1e-6)
    spec3 = base.with_settings({"dim": 3}).spec()
    assert spec3.tracking_margin_m == pytest.approx(13.182370, abs=1e-6)
    assert spec3.flight_d_safe_m == 20.0
    # two measurements a second apart: four σ of the vertical error's one-second difference
    step = math.sqrt(2.0 * (1.0 - math.exp(-1.0 / 1100.0)))
    assert measurement_tol(noisy, 1.0, 3) == pytest.approx(4 * 1.5 * VERTICAL_RATIO * step)
    assert measurement_tol(noisy, 1.0) == pytest.approx(4 * math.sqrt(2.0) * 0.05)
    assert spec3.measurement_tol == pytest.approx(4 * 1.5 * VERTICAL_RATIO * step)


# -- the plant in 3-D ------------------------------------------------------------------------
EXACT = GpsParams()


def _plant(z: float, gps: GpsParams = EXACT, seed: int = 3) -> MultirotorPlant:
    return MultirotorPlant(hover_state(np.array([300.0, 400.0, z]), DYN3),
                           DYN3, np.random.default_rng(seed),
                           PlantParams(kind="multirotor", gps=gps))


def test_the_models_z_is_the_plants_altitude_and_carries_the_vertical_error() -> None:
    """A 3-D vehicle at 37 m (not the 2-D missions' 50 m) hovers at 37 m in calm air; under
    Eq. (1)'s climb it climbs; its measured z is the true z plus the estimate's vertical
    error, to the bit."""
    vehicle = PlantVehicle(_plant(37.0))
    for _ in range(3):
        vehicle.command(np.zeros(6), np.zeros(3), 1.0)
        state = vehicle.observe()
    assert state[2] == pytest.approx(37.0, abs=1e-9) and abs(state[5]) < 1e-9
    up = np.array([0.0, 0.0, 1.05])  # u/m = 1 m/s² upwards: v_z 0 → 1 m/s in one ΔT
    for _ in range(4):
        vehicle.command(np.zeros(6), up, 1.0)
        state = vehicle.observe()
    assert 38.0 < state[2] < 45.0 and state[5] > 0.5  # climbing (PX4 climbs at most 3 m/s)
    assert np.all(np.abs(state[:2] - [300.0, 400.0]) < 1e-6)
    noisy = _plant(50.0, GpsParams(gps_sigma_m=1.5))
    err = noisy.gps.error
    assert abs(err[2]) > 0.0
    assert np.array_equal(noisy.measure()[:3], noisy.state[:3] + err)


def test_the_tracking_error_is_3d_in_3d() -> None:
    """The tracking log of a 3-D vehicle is the 3-D distance between the flown path and the
    planned segment (its vertical part included); a 2-D one's the horizontal."""
    plant = _plant(50.0, GpsParams(gps_sigma_m=1e-9, tau_s=1e12, vel_sigma_mps=0.0))
    vehicle = PlantVehicle(plant)
    plant.gps.error = np.array([0.0, 0.0, 3.0])  # the estimate jumps 3 m up
    vehicle.command(np.zeros(6), np.zeros(3), 1.0)
    vehicle.observe()
    assert vehicle.flight is not None
    f = vehicle.flight
    expected = np.linalg.norm(f.positions[1:] - f.reference[1:], axis=1)
    assert np.array_equal(vehicle.tracking_error_m[0], expected)
    assert float(expected.max()) == pytest.approx(float(np.max(np.abs(
        f.positions[1:, 2] - 50.0))), abs=1e-6)  # hovering: the error is the sink


# -- safety on the flown 3-D path --------------------------------------------------------------
@pytest.mark.parametrize(("jump_m", "top_m", "ending"), [
    (3.0, 29.5, Ending.TRACKING_BREACH),  # the plan keeps 20.5 m, the sink takes it below 20
    (0.0, 29.5, None),  # no jump: the flight holds 50 m, 20.5 m above the top
    (3.0, 30.5, Ending.FIRE_CONTACT),  # the plan itself kept only 19.5 m
])
def test_a_sink_over_a_low_cuboid_is_a_tracking_breach(jump_m: float, top_m: float,
                                                       ending: Ending | None) -> None:
    """A vehicle hovering at 50 m over a front whose cuboid is ``top_m`` tall: the plan (the
    planned segment from the measured start, 50 m) keeps 50 − top from it. When the estimate
    jumps ``jump_m`` up (a GPS glitch) the autopilot sinks towards 50 − jump at PX4's sink
    limit, 1.5 m/s: in one ΔT more than 0.5 m and at most 1.5 m, so the flown path comes
    within d_safe = 20 m of a 29.5 m top, which the plan kept by 0.5 m."""
    plant = _plant(50.0, GpsParams(gps_sigma_m=1e-9, tau_s=1e12, vel_sigma_mps=0.0))
    vehicle = PlantVehicle(plant)
    assert vehicle.measured()[2] == pytest.approx(50.0, abs=1e-6)
    plant.gps.error = np.array([0.0, 0.0, jump_m])
    vehicle.command(np.zeros(6), np.zeros(3), 1.0)
    vehicle.observe()
    path = vehicle.flown_path()
    assert path is not None and path.shape == (101, 3)
    sink = 50.0 - float(path[:, 2].min())
    assert (0.5 < sink <= 1.5) if jump_m else sink < 1e-6
    planned = vehicle.planned_path()
    assert planned.shape == (2, 3) and np.allclose(planned[:, 2], 50.0, atol=1e-6)
    under = Cuboid(Rect(300.0, 400.0, 40.0, 40.0), top_m)  # right below the vehicle
    aside = Cuboid(Rect(300.0, 500.0, 40.0, 40.0), 140.0)  # 80 m to the north: far
    got, left = judge_flight(vehicle, (under, aside), 20.0)
    assert got is ending and left == ()


def test_a_3d_path_against_rectangles_is_refused() -> None:
    vehicle = PlantVehicle(_plant(50.0))
    vehicle.command(np.zeros(6), np.zeros(3), 1.0)
    vehicle.observe()
    with pytest.raises(ValueError, match="cuboids"):
        judge_flight(vehicle, (Rect(300.0, 400.0, 10.0, 10.0),), 20.0)


# -- 3-D missions ------------------------------------------------------------------------------
#: the 3-D lockstep mission's readings (docs/three_d.md, 10): cc on seed 0 climbs over fronts
#: 10–40 m tall
CLIMBING = (("dim", 3), ("fire_height", "uniform"), ("fire_height_min_m", 10.0),
            ("fire_height_max_m", 40.0), ("s1_altitude", "volume"))


def test_a_calm_3d_mission_flies_within_the_measured_tracking_error() -> None:
    """No wind, no turbulence, exact measurements: cc on seed 0 over fronts 10–40 m tall climbs
    (its altitude spans more than 8 m) and every integration step of its flight stays within
    4.5 m (3-D) of the planned segment: the bound measured on this mission (largest 4.43 m,
    p99 3.43 m; docs/plant.md, "In 3-D"), whose tail is PX4's sink limit (1.5 m/s) behind
    Eq. (1)'s descents. No flight left d_safe where its plan kept it."""
    config = MissionConfig.named("cc", seed=0, timing=Timing.PAPER, settings=CLIMBING + CALM)
    result = local_mission(config).run()
    z = [float(r.state[2]) for r in result.records]
    assert max(z) - min(z) > 8.0
    errors = np.concatenate(result.tracking_error_m)
    assert len(errors) == 100 * result.steps
    assert float(errors.max()) <= 4.5
    assert float(np.quantile(errors, 0.99)) <= 3.5  # TRACKING3_P999_M
    assert result.ending is not Ending.TRACKING_BREACH


def test_tall_fronts_in_3d_fly_the_2d_multirotor_mission() -> None:
    """With every front taller than the band and the start and goal at 50 m, the 3-D
    multirotor mission of cc on seed 2 (calm, exact, the same 3.0 m tube) is the 2-D one within
    the tracking error: the same ending, steps and systems, the horizontal states within 1 m
    (0.42 m measured), the altitude within 1.5 m of 50 m (49.01–50.39 m measured). The plant
    holds 50 m only to its tracking error, so the 3-D planners plan from a measured state off
    the band's start altitude and the missions are not bit for bit."""
    flat = MissionConfig.named("cc", seed=2, timing=Timing.PAPER,
                               settings=CALM + (("tracking_margin_m", 3.0),))
    a = local_mission(flat).run()
    b = local_mission(flat.with_settings({"dim": 3})).run()
    assert (a.ending, a.steps) == (b.ending, b.steps)
    assert [r.system for r in a.records] == [r.system for r in b.records]
    for ra, rb in zip(a.records, b.records, strict=True):
        assert float(np.linalg.norm(ra.state[:2] - rb.state[:2])) < 1.0
        assert abs(float(rb.state[2]) - 50.0) < 1.5
