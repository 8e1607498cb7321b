"""Eq. (1) against matrices and steps worked out by hand (ΔT = 1 s, ζ = 0.2, m = 1.05 kg)."""

import numpy as np
import pytest

from dualpilot.model.dynamics import (
    DynamicsParams,
    reach_boxes,
    rollout,
    step,
    transition_matrices,
)


def test_phi_gamma_2d_match_hand_values():
    phi, gamma = transition_matrices(DynamicsParams())
    assert phi == pytest.approx(
        np.array([[1, 0, 1, 0], [0, 1, 0, 1], [0, 0, 0.8, 0], [0, 0, 0, 0.8]])
    )
    g = 1 / 1.05
    assert gamma == pytest.approx(np.array([[0, 0], [0, 0], [g, 0], [0, g]]))


def test_phi_gamma_3d_shapes_and_blocks():
    phi, gamma = transition_matrices(DynamicsParams(dim=3, dt_s=0.5, zeta=0.1, mass_kg=2.0))
    assert phi.shape == (6, 6) and gamma.shape == (6, 3)
    assert phi[:3, 3:] == pytest.approx(0.5 * np.eye(3))
    assert phi[3:, 3:] == pytest.approx(0.9 * np.eye(3))
    assert gamma[3:] == pytest.approx(0.25 * np.eye(3))


def test_step_by_hand_and_speed_limit():
    # p' = p + v = 10; v' = 0.8*10 + 7.5/1.05 = 15.142857 -> clipped to 15 m/s
    nxt = step(np.array([0.0, 0.0, 10.0, 0.0]), np.array([7.5, 0.0]))
    assert nxt == pytest.approx([10.0, 0.0, 15.0, 0.0])
    # force beyond the 7.5 N limit is clipped: v' = 0 + 7.5/1.05
    nxt = step(np.zeros(4), np.array([0.0, -100.0]))
    assert nxt == pytest.approx([0.0, 0.0, 0.0, -7.5 / 1.05])


def test_rollout_matches_repeated_step_without_saturation():
    u = np.array([[1.0, -1.0], [0.5, 0.5], [0.0, 2.0]])
    states = rollout(np.array([5.0, 5.0, 1.0, 0.0]), u)
    x = np.array([5.0, 5.0, 1.0, 0.0])
    for k in range(3):
        x = step(x, u[k])
        assert states[k + 1] == pytest.approx(x)


@pytest.mark.parametrize(
    ("state", "match"),
    [(np.array([np.nan, 0, 0, 0]), "finite"), (np.zeros(3), "shape")],
)
def test_bad_state_is_rejected(state, match):
    with pytest.raises(ValueError, match=match):
        step(state, np.zeros(2))


def test_bad_parameters_are_rejected():
    with pytest.raises(ValueError, match="dim"):
        DynamicsParams(dim=4)
    with pytest.raises(ValueError, match="invalid"):
        DynamicsParams(zeta=1.5)


def _extreme_rollout(x0: np.ndarray, horizon: int, dyn: DynamicsParams,
                     sign: float) -> np.ndarray:
    """Positions p_1..p_T under the force ``sign``·u_max on every axis, through :func:`step`
    (Eq. (1) with the per-axis speed clip)."""
    x, out = x0.copy(), []
    for _ in range(horizon):
        x = step(x, np.full(dyn.dim, sign * dyn.u_max_n), dyn)
        out.append(x[: dyn.dim])
    return np.array(out)


@pytest.mark.parametrize("dim", [2, 3])
def test_reach_boxes_are_the_extreme_forces_rolled_out(dim: int) -> None:
    dyn = DynamicsParams(dim=dim)
    rng = np.random.default_rng(11)
    for _ in range(50):
        x0 = np.concatenate([rng.uniform(0.0, 1000.0, dim), rng.uniform(-15.0, 15.0, dim)])
        lo, hi = reach_boxes(x0, 40, dyn)
        assert lo.shape == hi.shape == (40, dim)
        np.testing.assert_allclose(hi, _extreme_rollout(x0, 40, dyn, 1.0), rtol=0, atol=1e-9)
        np.testing.assert_allclose(lo, _extreme_rollout(x0, 40, dyn, -1.0), rtol=0, atol=1e-9)


def test_reach_boxes_3d_axes_are_the_planar_ones_bit_for_bit() -> None:
    dyn2, dyn3 = DynamicsParams(), DynamicsParams(dim=3)
    rng = np.random.default_rng(12)
    for _ in range(100):
        p, v = rng.uniform(0.0, 1000.0, 3), rng.uniform(-15.0, 15.0, 3)
        lo3, hi3 = reach_boxes(np.concatenate([p, v]), 80, dyn3)
        lo2, hi2 = reach_boxes(np.array([p[0], p[1], v[0], v[1]]), 80, dyn2)
        assert np.array_equal(lo3[:, :2], lo2) and np.array_equal(hi3[:, :2], hi2)
        # the vertical axis is the planar x axis of a state with the altitude's numbers
        loz, hiz = reach_boxes(np.array([p[2], p[0], v[2], v[0]]), 80, dyn2)
        assert np.array_equal(lo3[:, 2], loz[:, 0]) and np.array_equal(hi3[:, 2], hiz[:, 0])


def test_reach_boxes_refuse_a_state_of_the_other_dimension() -> None:
    with pytest.raises(ValueError, match=r"shape \(6,\)"):
        reach_boxes(np.zeros(4), 5, DynamicsParams(dim=3))
