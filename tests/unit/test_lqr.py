"""LQR tracker (dualpilot.system1.lqr): Riccati gain, closed-loop stability, tracking, limits."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from dualpilot.model.dynamics import DynamicsParams, hover_state, rollout, transition_matrices
from dualpilot.system1.lqr import LqrParams, lqr_gain, reference_states, speed_profile, track
from dualpilot.verify import verify_trajectory

DYN = DynamicsParams()


def test_gain_solves_the_riccati_equation() -> None:
    k, p = lqr_gain(DYN, q=2.0, r=0.1)
    phi, gamma = transition_matrices(DYN)
    q, r = 2.0 * np.eye(4), 0.1 * np.eye(2)
    np.testing.assert_allclose(p, solve_discrete_are(phi, gamma, q, r), rtol=1e-12)
    residual = phi.T @ p @ phi - phi.T @ p @ gamma @ np.linalg.solve(
        r + gamma.T @ p @ gamma, gamma.T @ p @ phi) + q - p
    assert np.max(np.abs(residual)) < 1e-9
    np.testing.assert_allclose(k, np.linalg.solve(r + gamma.T @ p @ gamma, gamma.T @ p @ phi))


def test_closed_loop_is_stable() -> None:
    k, _ = lqr_gain(DYN)
    phi, gamma = transition_matrices(DYN)
    assert np.max(np.abs(np.linalg.eigvals(phi - gamma @ k))) < 1.0


def test_axes_decouple_into_the_scalar_double_integrator() -> None:
    # Φ, Γ, Q, R are all block-diagonal in (px, vx), (py, vy): K = [[a, 0, b, 0], [0, a, 0, b]],
    # with (a, b) the gain of the 1-D system p' = p + ΔT v, v' = (1-ζ) v + ΔT/m u.
    k, _ = lqr_gain(DYN)
    assert k[0, 1] == pytest.approx(0.0, abs=1e-12) and k[0, 3] == pytest.approx(0.0, abs=1e-12)
    assert k[1, 0] == pytest.approx(0.0, abs=1e-12) and k[1, 2] == pytest.approx(0.0, abs=1e-12)
    assert k[0, 0] == pytest.approx(k[1, 1]) and k[0, 2] == pytest.approx(k[1, 3])
    a1 = np.array([[1.0, 1.0], [0.0, 0.8]])
    b1 = np.array([[0.0], [1.0 / 1.05]])
    p1 = solve_discrete_are(a1, b1, 2.0 * np.eye(2), 0.1 * np.eye(1))
    k1 = np.linalg.solve(0.1 + b1.T @ p1 @ b1, b1.T @ p1 @ a1)
    np.testing.assert_allclose(k[0, [0, 2]], k1[0], rtol=1e-10)


def test_straight_line_tracking_converges() -> None:
    k, _ = lqr_gain(DYN)
    path = np.array([[100.0, 100.0], [900.0, 100.0]])
    ref = reference_states(path, 60, 10.0, DYN)
    x0 = np.array([100.0, 112.0, 0.0, -3.0])  # 12 m off the line, drifting away
    states, controls = track(x0, ref, k, DYN)
    err = np.linalg.norm(states[:, :2] - ref[:, :2], axis=1)
    assert err[0] == pytest.approx(12.0)
    assert np.all(err[30:] < 1e-3)
    assert np.all(np.abs(controls) <= DYN.u_max_n)
    np.testing.assert_allclose(states, rollout(x0, controls, DYN), atol=1e-9)
    assert verify_trajectory(states, controls, (), DYN, clearance_m=20.0).ok


def test_without_feedforward_the_drag_makes_a_steady_lag() -> None:
    # In steady state at speed v the UAV needs u = ζ·m·v/ΔT to hold v against the drag; with
    # û = -K(x - x̂) alone that force comes from a position lag e = -ζ m v / (ΔT K_pp).
    k, _ = lqr_gain(DYN)
    v = 10.0
    path = np.array([[0.0, 500.0], [10_000.0, 500.0]])
    ref = reference_states(path, 200, v, DYN, v0_mps=v)
    x0 = np.array([0.0, 500.0, v, 0.0])
    states, controls = track(x0, ref, k, DYN, feedforward=False)
    lag = states[-1, 0] - ref[-1, 0]
    assert lag == pytest.approx(-DYN.zeta * DYN.mass_kg * v / (DYN.dt_s * k[0, 0]), rel=1e-6)
    assert controls[-1, 0] == pytest.approx(DYN.zeta * DYN.mass_kg * v / DYN.dt_s, rel=1e-6)
    with_ff, _ = track(x0, ref, k, DYN, feedforward=True)
    assert abs(with_ff[-1, 0] - ref[-1, 0]) < 1e-9


def test_reference_follows_the_path_and_holds_at_its_end() -> None:
    path = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 50.0]])
    ref = reference_states(path, 40, 10.0, DYN)
    assert ref.shape == (41, 4)
    np.testing.assert_array_equal(ref[0], [0.0, 0.0, 0.0, 0.0])
    np.testing.assert_array_equal(ref[1], [0.0, 0.0, 3.0, 0.0])  # from rest, 3 m/s² for one ΔT
    # positions follow p_{k+1} = p_k + ΔT v_k exactly
    np.testing.assert_allclose(ref[1:, :2], ref[:-1, :2] + ref[:-1, 2:], atol=1e-12)
    np.testing.assert_allclose(ref[-1], [100.0, 50.0, 0.0, 0.0])
    on_path = (np.isclose(ref[:, 1], 0.0)) | (np.isclose(ref[:, 0], 100.0))
    assert on_path.all()
    assert np.max(np.linalg.norm(ref[:, 2:], axis=1)) <= 10.0 + 1e-12


def test_speed_profile_is_trapezoidal() -> None:
    s = speed_profile(200.0, 40, 10.0, 1.0, v0_mps=0.0, accel_mps2=3.0, decel_mps2=2.0)
    ds = np.diff(s)
    np.testing.assert_allclose(ds[:5], [0.0, 3.0, 6.0, 9.0, 10.0])  # s_{k+1} = s_k + ΔT v_k
    assert np.all(ds >= 0) and np.all(ds <= 10.0 + 1e-12)
    assert s[-1] == pytest.approx(200.0)


def test_controls_and_velocities_respect_the_limits() -> None:
    k, _ = lqr_gain(DYN)
    path = np.array([[0.0, 0.0], [5000.0, 0.0]])
    ref = reference_states(path, 30, 40.0, DYN, params=LqrParams(accel_mps2=40.0))  # too fast
    x0 = np.array([0.0, 0.0, 14.0, -15.0])
    states, controls = track(x0, ref, k, DYN)
    assert np.max(np.abs(controls)) <= DYN.u_max_n + 1e-12
    assert np.max(np.abs(states[1:, 2:])) <= DYN.v_max_mps + 1e-9
    assert np.max(states[:, 2]) == pytest.approx(DYN.v_max_mps)
    np.testing.assert_allclose(states, rollout(x0, controls, DYN), atol=1e-9)


def test_hover_at_the_goal_stays_put() -> None:
    k, _ = lqr_gain(DYN)
    ref = reference_states(np.array([[900.0, 900.0]]), 10, 12.0, DYN)
    states, controls = track(hover_state(np.array([900.0, 900.0])), ref, k, DYN)
    np.testing.assert_allclose(states[:, :2], 900.0)
    np.testing.assert_allclose(controls, 0.0)


def test_bad_input_raises() -> None:
    with pytest.raises(ValueError, match="positive"):
        lqr_gain(DYN, q=0.0)
    with pytest.raises(ValueError, match="positive"):
        LqrParams(r=-1.0)
    with pytest.raises(ValueError, match="horizon"):
        reference_states(np.array([[0.0, 0.0], [10.0, 0.0]]), 0, 10.0, DYN)
    with pytest.raises(ValueError, match="speed"):
        reference_states(np.array([[0.0, 0.0], [10.0, 0.0]]), 5, 0.0, DYN)
    with pytest.raises(ValueError, match="path"):
        reference_states(np.array([[0.0, np.nan]]), 5, 10.0, DYN)
    k, _ = lqr_gain(DYN)
    with pytest.raises(ValueError, match="finite"):
        track(np.array([np.nan, 0.0, 0.0, 0.0]), np.zeros((3, 4)), k, DYN)
    with pytest.raises(ValueError, match="reference"):
        track(np.zeros(4), np.zeros((1, 4)), k, DYN)
