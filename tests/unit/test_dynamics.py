"""Eq. (1) against matrices and steps worked out by hand (ΔT = 1 s, ζ = 0.2, m = 1.05 kg)."""

import numpy as np
import pytest

from dualpilot.model.dynamics import DynamicsParams, rollout, step, transition_matrices


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
