"""The plants: the ideal one is Eq. (1) bit for bit; the multirotor hovers, steps like its
linearised cascade, saturates where PX4's limits say and repeats itself with a seed."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from dualpilot.mission.local import LocalVehicle
from dualpilot.model.dynamics import DynamicsParams, step
from dualpilot.plant import (
    GpsParams,
    IdealPlant,
    MultirotorParams,
    MultirotorPlant,
    PlantParams,
    WindParams,
    make_plant,
)
from dualpilot.plant.multirotor import B3, T, fly, hover_vector
from dualpilot.plant.params import GRAVITY_MPS2
from dualpilot.plant.setpoints import hermite_stream, segment_path

ALT = 50.0
MR = MultirotorParams()


def _hold(target: list[float], seconds: float, params: MultirotorParams = MR) -> np.ndarray:
    sp = np.zeros((1, 9))
    sp[0, :3] = target
    return np.repeat(sp, int(seconds * params.setpoint_hz), axis=0)


def _calm(n: int) -> np.ndarray:
    return np.zeros((n, 3))


@pytest.mark.parametrize("dim", [2, 3])
def test_ideal_plant_is_eq1_bit_for_bit(dim: int) -> None:
    dyn = DynamicsParams(dim=dim)
    rng = np.random.default_rng(3)
    x0 = np.concatenate([rng.uniform(0, 1000, dim), rng.uniform(-15, 15, dim)])
    plant, vehicle, x = IdealPlant(x0, dyn), LocalVehicle(x0, dyn), x0.copy()
    for _ in range(40):
        u = rng.uniform(-9.0, 9.0, dim)  # beyond the limit too: both clip alike
        flight = plant.fly(plant.measure(), u)
        vehicle.command(np.zeros(2 * dim), u, 1.0)
        x = step(x, u, dyn)
        assert np.array_equal(flight.state, vehicle.observe())
        assert np.array_equal(flight.state, x) and np.array_equal(plant.measure(), x)
    assert flight.positions.shape == (101, 3)


def test_ideal_path_is_the_straight_eq1_segment() -> None:
    dyn = DynamicsParams()
    x0 = np.array([10.0, 20.0, 3.0, -4.0])
    flight = IdealPlant(x0, dyn).fly(x0, np.array([7.5, 7.5]))
    # p_t + s·v_t at s = 0.25 s, by hand: (10.75, 19.0), at the fixed altitude
    assert flight.positions[25] == pytest.approx([10.75, 19.0, ALT])
    assert flight.tracking_error_m().max() == pytest.approx(0.0, abs=1e-12)


def test_hover_holds_exactly_in_calm_air() -> None:
    x = hover_vector(np.array([5.0, -3.0, ALT]), np.zeros(3), MR)
    path = fly(x, _hold([5.0, -3.0, ALT], 10.0), 0.05, _calm(1000), _calm(1000), MR)
    assert np.abs(path[:, :3] - [5.0, -3.0, ALT]).max() < 1e-9
    assert np.abs(path[:, 3:]).max() < 1e-9


def _linear_step(r: float, seconds: float, params: MultirotorParams) -> tuple[np.ndarray,
                                                                              np.ndarray]:
    """The small-signal cascade along x, written apart from the kernel as one ODE: tilt θ
    (rad) with rate ω, a_x = g·θ − (k_l/m)·v; PX4's P → PID (D on the velocity derivative
    low-passed at MPC_VELD_LP); attitude P with the rate lag τ_ω."""
    a, c = params.airframe, params.controller
    g, tau_w = GRAVITY_MPS2, a.rate_tau_s
    wc = 2 * math.pi * c.veld_lp_hz

    def rhs(_t: float, s: np.ndarray) -> list[float]:
        x, v, th, om, integ, vd = s
        acc = g * math.tan(th) - a.linear_drag_nspm / a.mass_kg * v
        vel_sp = c.xy_p * (r - x)
        a_sp = c.xy_vel_p * (vel_sp - v) + integ - c.xy_vel_d * vd
        th_d = math.atan(a_sp / g)
        return [v, acc, om, (c.att_p * (th_d - th) - om) / tau_w, c.xy_vel_i * (vel_sp - v),
                wc * (acc - vd)]

    t = np.arange(int(seconds * 100) + 1) / 100.0
    sol = solve_ivp(rhs, (0.0, seconds), [0.0] * 6, t_eval=t, max_step=0.002, rtol=1e-9)
    return t, sol.y[0]


def test_small_step_follows_the_linearised_cascade() -> None:
    x = hover_vector(np.array([0.0, 0.0, ALT]), np.zeros(3), MR)
    path = fly(x, _hold([0.5, 0.0, ALT], 10.0), 0.05, _calm(1000), _calm(1000), MR)
    _, ref = _linear_step(0.5, 10.0, MR)
    assert np.abs(path[:, 0] - ref).max() < 0.01  # 2 % of the step
    assert abs(path[-1, 1]) < 1e-9


def test_ten_metre_step_settles_within_documented_bounds() -> None:
    x = hover_vector(np.array([0.0, 0.0, ALT]), np.zeros(3), MR)
    path = fly(x, _hold([10.0, 0.0, ALT], 15.0), 0.05, _calm(1500), _calm(1500), MR)
    t = np.arange(len(path)) / 100.0
    outside = np.nonzero(np.abs(path[:, 0] - 10.0) > 0.5)[0]
    # docs/plant.md: overshoot under 10 %, inside ±0.5 m after 5 s, altitude within 0.3 m
    assert path[:, 0].max() < 11.0
    assert t[outside[-1] + 1] < 5.0
    assert np.abs(path[:, 2] - ALT).max() < 0.3


def test_tilt_and_thrust_saturate_at_px4_limits() -> None:
    x = hover_vector(np.array([0.0, 0.0, ALT]), np.zeros(3), MR)
    sp = _hold([0.0, 0.0, ALT], 1.0)
    sp[:, 6] = 30.0  # 30 m/s² east: three times g·tan(45°)
    sp[:, 8] = 30.0  # and 30 m/s² up: beyond full thrust
    tilt, thrust = [], []
    for _ in range(200):
        fly(x, sp[:1], 1.0, _calm(1), _calm(1), MR)
        tilt.append(math.degrees(math.acos(x[B3 + 2])))
        thrust.append(x[T])
    assert max(tilt) <= 45.0 + 1e-9
    assert max(thrust) <= MR.airframe.max_thrust_n + 1e-9
    assert max(thrust) > 0.95 * MR.airframe.max_thrust_n  # it does reach the limit


def test_far_target_speed_stays_at_the_velocity_limit() -> None:
    x = hover_vector(np.array([0.0, 0.0, ALT]), np.zeros(3), MR)
    path = fly(x, _hold([2000.0, 2000.0, ALT], 40.0), 0.05, _calm(4000), _calm(4000), MR)
    speed = np.linalg.norm(path[:, 3:5], axis=1)
    assert speed.max() <= MR.controller.xy_vel_max_mps * 1.02
    assert speed[-1] == pytest.approx(MR.controller.xy_vel_max_mps, rel=0.02)


def test_hermite_stream_meets_eq1_at_both_ends() -> None:
    dyn = DynamicsParams()
    x0 = np.array([0.0, 0.0, 10.0, -5.0])
    x1 = step(x0, np.array([-7.5, 3.0]), dyn)
    sp = hermite_stream(x0, x1, 1.0, 20.0, 2, ALT)
    assert sp.shape == (20, 9)
    assert sp[0, :6] == pytest.approx([0.0, 0.0, ALT, 10.0, -5.0, 0.0])
    # one more sample at τ = 1 would be x1: the stream's curve at 19/20 is close to it
    fine = hermite_stream(x0, x1, 1.0, 1000.0, 2, ALT)
    assert fine[-1, :2] == pytest.approx(x1[:2], abs=0.02)
    # the largest departure from Eq. (1)'s straight segment is 4/27 ΔT ‖Δv‖ at τ = 2/3
    straight = segment_path(x0, np.arange(1000) / 1000.0, 2, ALT)
    dev = np.linalg.norm(fine[:, :3] - straight, axis=1)
    assert dev.max() == pytest.approx(4 / 27 * np.linalg.norm(x1[2:] - x0[2:]), rel=1e-3)


def test_two_d_missions_hold_the_altitude() -> None:
    dyn = DynamicsParams()
    x = np.array([50.0, 50.0, 0.0, 0.0])
    plant = MultirotorPlant(x, dyn, np.random.default_rng(0))
    for u in [np.array([7.5, 7.5])] * 5 + [np.array([-7.5, 0.0])] * 5:
        flight = plant.fly(x, u)
        x = step(x, u, dyn)
        assert np.abs(flight.positions[:, 2] - ALT).max() < 0.5
    assert plant.state.shape == (4,)


def _gusty() -> PlantParams:
    return PlantParams(kind="multirotor",
                       wind=WindParams(wind_speed_mps=10.0, wind_dir_rad=1.0,
                                       turbulence="moderate"),
                       gps=GpsParams(gps_sigma_m=1.5))


def _mission(seed: int) -> list[np.ndarray]:
    dyn = DynamicsParams()
    x = np.array([50.0, 50.0, 0.0, 0.0])
    plant = make_plant(_gusty(), x, dyn, np.random.default_rng(seed))
    out = []
    for k in range(8):
        u = np.array([7.5, 5.0]) if k < 4 else np.array([-3.0, 0.0])
        flight = plant.fly(plant.measure(), u)
        out += [flight.positions, flight.wind, flight.measured]
    return out


def test_seed_reproduces_a_windy_noisy_flight() -> None:
    a, b, c = _mission(7), _mission(7), _mission(8)
    assert all(np.array_equal(p, q) for p, q in zip(a, b, strict=True))
    assert not all(np.array_equal(p, q) for p, q in zip(a, c, strict=True))


def test_measured_state_carries_the_gps_error() -> None:
    dyn = DynamicsParams()
    x = np.array([50.0, 50.0, 0.0, 0.0])
    plant = MultirotorPlant(x, dyn, np.random.default_rng(1), _gusty())
    err = plant.measure() - plant.state
    assert 0.0 < np.linalg.norm(err[:2]) < 10 * 1.5
    exact = MultirotorPlant(x, dyn, np.random.default_rng(1))
    assert np.array_equal(exact.measure(), exact.state)


def test_plant_params_reject_unknown_kind() -> None:
    with pytest.raises(ValueError, match="plant must be one of"):
        PlantParams(kind="rocket")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="rate_hz >= 100"):
        MultirotorParams(rate_hz=50.0)


def test_three_d_state_maps_z_to_altitude_and_climbs() -> None:
    dyn = DynamicsParams(dim=3)
    x = np.array([50.0, 50.0, 60.0, 0.0, 0.0, 0.0])
    plant = MultirotorPlant(x, dyn, np.random.default_rng(0))
    assert np.array_equal(plant.state, x)  # no altitude offset in 3-D
    worst = 0.0
    for u in [np.array([2.0, 0.0, 2.0])] * 4:  # climbs at ≤ 2.9 m/s, under MPC_Z_VEL_MAX_UP
        flight = plant.fly(plant.measure(), u)
        worst = max(worst, float(flight.tracking_error_m().max()))
        assert flight.reference[0, 2] == pytest.approx(flight.positions[0, 2], abs=1e-9)
    assert plant.state[2] > 65.0 and worst < 1.0
