"""LQR tracker (dualpilot.system1.lqr): Riccati gain, closed-loop stability, tracking, limits."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from dualpilot.model.dynamics import DynamicsParams, hover_state, rollout, transition_matrices
from dualpilot.system1.lqr import (
    LqrParams,
    lqr_du_gain,
    lqr_gain,
    reference_states,
    speed_profile,
    track,
)
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


# -- the Δu tracker (System1Params.tracker = "lqr_du") ------------------------------------


def augmented(dyn: DynamicsParams = DYN) -> tuple[np.ndarray, np.ndarray]:
    """A = [[Φ, Γ], [0, I]], B = [[Γ], [I]] of z = [x; u₋], input Δu."""
    phi, gamma = transition_matrices(dyn)
    a = np.block([[phi, gamma], [np.zeros((2, 4)), np.eye(2)]])
    return a, np.vstack([gamma, np.eye(2)])


def test_du_gain_solves_the_augmented_riccati_equation() -> None:
    # cost xᵀQx + uᵀRu + ΔuᵀR_ΔΔu with u = u₋ + Δu: Q_z = diag(Q, R), R_z = R + R_Δ, S = [0; R]
    k, p = lqr_du_gain(DYN, q=2.0, r=0.1, r_delta_u=5.0)
    a, b = augmented()
    qz = np.diag([2.0, 2.0, 2.0, 2.0, 0.1, 0.1])
    rz = 5.1 * np.eye(2)
    s = np.vstack([np.zeros((4, 2)), 0.1 * np.eye(2)])
    g = np.linalg.solve(rz + b.T @ p @ b, b.T @ p @ a + s.T)
    residual = a.T @ p @ a - (a.T @ p @ b + s) @ g + qz - p
    assert np.max(np.abs(residual)) < 1e-9
    np.testing.assert_allclose(k, g, rtol=1e-12)
    kp, kv, ku = k[0, 0], k[0, 2], k[0, 4]
    np.testing.assert_allclose(k, np.hstack([kp * np.eye(2), kv * np.eye(2), ku * np.eye(2)]),
                               atol=1e-12)
    # the finite-horizon Riccati recursion converges to the same gain (value iteration)
    pk = np.zeros((6, 6))
    for _ in range(2000):
        gk = np.linalg.solve(rz + b.T @ pk @ b, b.T @ pk @ a + s.T)
        pk = qz + a.T @ pk @ a - (a.T @ pk @ b + s) @ gk
    np.testing.assert_allclose(gk, k, atol=1e-9)


@pytest.mark.parametrize("r_delta_u", [0.0, 1.0, 100.0, 1e4])
def test_du_closed_loop_is_stable(r_delta_u: float) -> None:
    k, _ = lqr_du_gain(DYN, r_delta_u=r_delta_u)
    a, b = augmented()
    assert np.max(np.abs(np.linalg.eigvals(a - b @ k))) < 1.0


def test_du_gain_tends_to_the_plain_lqr_as_r_delta_u_vanishes() -> None:
    # R_Δ = 0: min over Δu of (u₋ + Δu)ᵀR(u₋ + Δu) + ... is reached at u = −Kx, i.e. K_z = [K, I]
    k, _ = lqr_gain(DYN)
    limit = np.hstack([k, np.eye(2)])
    errors = [np.max(np.abs(lqr_du_gain(DYN, r_delta_u=rd)[0] - limit))
              for rd in (1e-1, 1e-3, 1e-5, 0.0)]
    assert errors[0] > errors[1] > errors[2] and errors[2] < 1e-4 and errors[3] < 1e-8
    # the default weight really changes the gain: softer feedback, u₋ only partly undone
    kp, kv, ku = lqr_du_gain(DYN)[0][0, [0, 2, 4]]
    assert kp < k[0, 0] / 5 and kv < k[0, 2] / 3 and 0.5 < ku < 0.7
    # and with R_Δ → 0 the tracker gives the plain tracker's trajectory from any u₋
    path = np.array([[100.0, 100.0], [900.0, 100.0]])
    ref = reference_states(path, 60, 10.0, DYN)
    x0 = np.array([100.0, 112.0, 0.0, -3.0])
    plain = track(x0, ref, k, DYN)
    du = track(x0, ref, lqr_du_gain(DYN, r_delta_u=0.0)[0], DYN, prev_control=np.array([5.0, -7.0]))
    np.testing.assert_allclose(du[0], plain[0], atol=1e-6)
    np.testing.assert_allclose(du[1], plain[1], atol=1e-6)


def east_to_north() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A UAV flying east at 10 m/s with u_{t|t} = (+3, 0) N, asked to follow a path north."""
    x0 = np.array([500.0, 500.0, 10.0, 0.0])
    ref = reference_states(np.array([[500.0, 500.0], [500.0, 800.0]]), 80, 12.0, DYN, v0_mps=0.0)
    return x0, ref, np.array([3.0, 0.0])


def test_du_first_jump_is_bounded_and_much_smaller_than_the_plain_trackers() -> None:
    """The bound of lqr._track_du on the hand-built handover.

    The reference starts at the UAV at rest along the path: e_p,0 = 0,
    e_v,0 = (10, 0) m/s; it leaves rest northwards at 3 m/s², v̂_1 = (0, 3), so
    u_ff,0 = (m/ΔT)(v̂_1 − (1 − ζ) v̂_0) = (0, 3.15) N and w₋₁ = u₋₁ − u_ff,0 = (3, −3.15) N.
    u₋₁ is feasible (|v_1,x| = 8 + 3/1.05 < 15), so per axis
    |Δu_0,i| ≤ |k_v e_v,i + k_u w₋₁,i|, in norm ≤ k_v·10 + k_u·‖(3, −3.15)‖
    = 0.2917·10 + 0.5942·4.350 = 5.50 N (the per-axis form gives 5.06 N here,
    with equality, no clip being active). The plain tracker applies
    u_0 = clip(u_ff,0 − k_v e_v,0) = (−7.5, 3.15): a jump of ‖(−10.5, 3.15)‖ = 10.96 N.
    """
    x0, ref, u_prev = east_to_north()
    np.testing.assert_allclose(ref[0], [500.0, 500.0, 0.0, 0.0])
    np.testing.assert_allclose(ref[1, 2:], [0.0, 3.0])
    k_du, _ = lqr_du_gain(DYN)
    kv, ku = k_du[0, 2], k_du[0, 4]
    e_v = x0[2:] - ref[0, 2:]
    w_prev = u_prev - DYN.mass_kg / DYN.dt_s * (ref[1, 2:] - (1 - DYN.zeta) * ref[0, 2:])
    np.testing.assert_allclose(w_prev, [3.0, -3.15])
    bound = kv * np.linalg.norm(e_v) + ku * np.linalg.norm(w_prev)
    assert bound == pytest.approx(5.50, abs=0.01)
    states, controls = track(x0, ref, k_du, DYN, prev_control=u_prev)
    jump = float(np.linalg.norm(controls[0] - u_prev))
    assert jump <= bound + 1e-12
    assert jump == pytest.approx(float(np.linalg.norm(kv * e_v + ku * w_prev)), rel=1e-12)
    assert jump == pytest.approx(5.06, abs=0.01)
    k, _ = lqr_gain(DYN)
    _, plain = track(x0, ref, k, DYN)
    np.testing.assert_allclose(plain[0], [-7.5, 3.15])
    plain_jump = float(np.linalg.norm(plain[0] - u_prev))
    assert plain_jump == pytest.approx(10.96, abs=0.01)
    assert jump < 0.5 * plain_jump and jump**2 < 0.25 * plain_jump**2
    # the Δu tracker still brings the UAV onto the path and obeys Eq. (1) and the limits
    assert np.max(np.abs(controls)) <= DYN.u_max_n and np.max(np.abs(states[:, 2:])) <= 15.0
    np.testing.assert_allclose(states, rollout(x0, controls, DYN), atol=1e-9)
    assert abs(states[-1, 0] - 500.0) < 0.1 and states[-1, 1] == pytest.approx(800.0, abs=0.1)
    assert verify_trajectory(states, controls, (), DYN, clearance_m=20.0).ok


def test_du_first_jump_bound_holds_with_the_clips() -> None:
    # |u_0,i − u₋₁,i| ≤ |k_p e_p + k_v e_v + k_u w₋₁| + dist(u₋₁,i, [lo_i, hi_i]) on random cases
    k_du, _ = lqr_du_gain(DYN)
    kp, kv, ku = k_du[0, [0, 2, 4]]
    rng = np.random.default_rng(7)
    m_dt, decay = DYN.mass_kg / DYN.dt_s, 1 - DYN.zeta
    for _ in range(300):
        x0 = np.concatenate([rng.uniform(0, 1000, 2), rng.uniform(-15, 15, 2)])
        path = np.vstack([x0[:2] + rng.normal(0, 5, 2), rng.uniform(0, 1000, (2, 2))])
        ref = reference_states(path, 5, 12.0, DYN, v0_mps=float(rng.uniform(0, 12)))
        u_prev = rng.uniform(-9.0, 9.0, 2)  # sometimes outside U
        _, controls = track(x0, ref, k_du, DYN, prev_control=u_prev)
        w_prev = u_prev - m_dt * (ref[1, 2:] - decay * ref[0, 2:])
        raw = -kp * (x0[:2] - ref[0, :2]) - kv * (x0[2:] - ref[0, 2:]) - ku * w_prev
        lo = np.maximum(-DYN.u_max_n, (-DYN.v_max_mps - decay * x0[2:]) * m_dt)
        hi = np.minimum(DYN.u_max_n, (DYN.v_max_mps - decay * x0[2:]) * m_dt)
        assert np.all(lo <= hi)  # |v_0| ≤ v_max: the clip is one interval
        dist = np.maximum(0.0, np.maximum(lo - u_prev, u_prev - hi))
        assert np.all(np.abs(controls[0] - u_prev) <= np.abs(raw) + dist + 1e-9)


def test_du_steady_flight_along_the_path_has_no_jump() -> None:
    # at cruise on the path with u₋₁ = the drag force ζ·m·v, nothing is left to correct
    v = 10.0
    ref = reference_states(np.array([[0.0, 500.0], [10_000.0, 500.0]]), 50, v, DYN, v0_mps=v)
    x0 = np.array([0.0, 500.0, v, 0.0])
    hold = np.array([DYN.zeta * DYN.mass_kg * v / DYN.dt_s, 0.0])
    states, controls = track(x0, ref, lqr_du_gain(DYN)[0], DYN, prev_control=hold)
    np.testing.assert_allclose(controls, np.tile(hold, (50, 1)), atol=1e-12)
    np.testing.assert_allclose(states[:, :2], ref[:, :2], atol=1e-9)


def test_du_controls_and_velocities_respect_the_limits() -> None:
    path = np.array([[0.0, 0.0], [5000.0, 0.0]])
    ref = reference_states(path, 30, 40.0, DYN, params=LqrParams(accel_mps2=40.0))  # too fast
    x0 = np.array([0.0, 0.0, 14.0, -15.0])
    states, controls = track(x0, ref, lqr_du_gain(DYN)[0], DYN, prev_control=np.array([7.5, -7.5]))
    assert np.max(np.abs(controls)) <= DYN.u_max_n + 1e-12
    assert np.max(np.abs(states[1:, 2:])) <= DYN.v_max_mps + 1e-9
    np.testing.assert_allclose(states, rollout(x0, controls, DYN), atol=1e-9)


def test_du_bad_input_raises() -> None:
    with pytest.raises(ValueError, match="r_delta_u"):
        lqr_du_gain(DYN, r_delta_u=-1.0)
    with pytest.raises(ValueError, match="positive"):
        lqr_du_gain(DYN, q=0.0)
    x0, ref, u_prev = east_to_north()
    k, _ = lqr_gain(DYN)
    with pytest.raises(ValueError, match="prev_control needs"):
        track(x0, ref, k, DYN, prev_control=u_prev)
    k_du, _ = lqr_du_gain(DYN)
    with pytest.raises(ValueError, match="prev_control must"):
        track(x0, ref, k_du, DYN, prev_control=np.array([np.nan, 0.0]))
    with pytest.raises(ValueError, match="prev_control must"):
        track(x0, ref, k_du, DYN, prev_control=np.zeros(3))
    with pytest.raises(ValueError, match="k_u"):
        track(x0, ref, k_du + np.array([[0, 0.1, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0]]), DYN)
    # no prev_control: u₋₁ = 0
    np.testing.assert_array_equal(track(x0, ref, k_du, DYN)[1],
                                  track(x0, ref, k_du, DYN, prev_control=np.zeros(2))[1])


def test_gains_are_solved_once_and_handed_out_as_copies() -> None:
    """The DARE is solved once per (dynamics, weights); each caller gets its own arrays."""
    k1, p1 = lqr_gain(DYN)
    k1[0, 0] = 99.0
    p1[:] = 0.0
    k2, p2 = lqr_gain(DYN)
    assert k2[0, 0] != 99.0 and np.any(p2 != 0.0)
    kz, _ = lqr_du_gain(DYN)
    kz[:] = 0.0
    assert np.any(lqr_du_gain(DYN)[0] != 0.0)
