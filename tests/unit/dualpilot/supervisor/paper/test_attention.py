"""Eq. (KSI), (dir), (categorical), (Psi), (maxPsi) against values worked out by hand."""

import math

import numpy as np
import pytest

from dualpilot.plan import Objective
from dualpilot.supervisor.paper.attention import sample_attention, xi
from dualpilot.supervisor.paper.decision import DecisionDynamics, SupervisorParams, psi_update


@pytest.mark.parametrize(
    ("d", "expected"),
    [
        # 9 - 9 / (1 + 40 e^{0.8}) + 1
        (0.0, 9 - 9 / (1 + 40 * math.exp(0.8)) + 1),
        (40.0, 9 - 9 / 41 + 1),  # exp(0) = 1: 9.78049
        (240.0, 9 - 9 / (1 + 40 * math.exp(-4.0)) + 1),
    ],
)
def test_xi1_against_distance(d, expected):
    assert xi(0, d)[0] == pytest.approx(expected)


def test_xi1_hand_numbers_and_no_fire():
    assert xi(0, 40.0)[0] == pytest.approx(9.780488, abs=1e-6)
    assert xi(0, float("inf"))[0] == 1.0  # lower limit w1d


@pytest.mark.parametrize(
    ("t", "xi2", "xi3"),
    [
        (10, 7 - 7 / 11 + 1, 7 / 11 + 1),  # 7.363636, 1.636364
        (0, 8 - 7 / (1 + 10 * math.exp(0.5)), 7 / (1 + 10 * math.exp(1.5)) + 1),
        (38, 8 - 7 / (1 + 10 * math.exp(-1.4)), 7 / (1 + 10 * math.exp(-4.2)) + 1),
    ],
)
def test_xi2_xi3_against_time(t, xi2, xi3):
    out = xi(t, float("inf"))
    assert out[1] == pytest.approx(xi2) and out[2] == pytest.approx(xi3)


def test_xi_limits_follow_w_c_and_w_d():
    late = xi(1000, 1e6)
    assert late == pytest.approx([1.0, 1.0, 8.0], abs=1e-6)


def test_dirichlet_mean_is_xi_over_sum():
    rng = np.random.default_rng(0)
    xi_t = np.array([1.0, 7.36, 1.64])
    samples = np.array([sample_attention(xi_t, rng)[0] for _ in range(20000)])
    assert samples.mean(axis=0) == pytest.approx(xi_t / xi_t.sum(), abs=0.01)
    assert np.allclose(samples.sum(axis=1), 1.0)


def test_categorical_frequencies_follow_p():
    rng = np.random.default_rng(1)
    xi_t = np.array([2.0, 5.0, 3.0])
    counts = np.bincount([sample_attention(xi_t, rng)[1] for _ in range(20000)], minlength=3)
    assert counts / 20000 == pytest.approx([0.2, 0.5, 0.3], abs=0.015)


def test_psi_updates_by_hand():
    params = SupervisorParams()
    # A = e1: B Q e1 = B [0.8, 0.4] = [0.4, -0.4]
    psi = psi_update(np.zeros(2), 0, params)
    assert psi == pytest.approx([0.4, -0.4])
    # then A = e2: 0.5 [0.4, -0.4] + B [0.5, 0.9] = [0.2 - 0.4, -0.2 + 0.4]
    psi = psi_update(psi, 1, params)
    assert psi == pytest.approx([-0.2, 0.2])
    # A = e3: 0.5 [-0.2, 0.2] + B [0.3, 0.9] = [-0.1 - 0.6, 0.1 + 0.6]
    assert psi_update(psi, 2, params) == pytest.approx([-0.7, 0.7])


def test_supervisor_picks_argmax_and_objective():
    sup = DecisionDynamics(np.random.default_rng(3))
    for t in range(60):
        d = sup.decide(t, 30.0 if 15 <= t < 25 else float("inf"))
        assert d.system == int(np.argmax(d.psi)) + 1
        assert d.attention in (1, 2, 3)
        if d.attention == 2:
            assert d.objective is Objective.MISSION_TIME
        if d.attention == 3:
            assert d.objective is Objective.ENERGY


def test_same_seed_same_decisions():
    runs = []
    for _ in range(2):
        sup = DecisionDynamics(np.random.default_rng(11))
        runs.append([sup.decide(t, 100.0).attention for t in range(40)])
    assert runs[0] == runs[1]


@pytest.mark.parametrize(("t", "d"), [(-1, 10.0), (float("nan"), 10.0), (1, float("nan")), (1, -5)])
def test_bad_attention_input(t, d):
    with pytest.raises(ValueError, match="must be"):
        xi(t, d)


def test_bad_xi_for_sampling():
    with pytest.raises(ValueError, match="positive"):
        sample_attention(np.array([1.0, 0.0, 1.0]), np.random.default_rng(0))


def test_the_categorical_draw_is_generator_choice_on_the_same_stream() -> None:
    # A_t ~ Categorical(P_t) consumes the stream exactly as Generator.choice(3, p=P_t)
    for seed in range(500):
        ours, ref = np.random.default_rng(seed), np.random.default_rng(seed)
        xi_t = ours.uniform(0.05, 10.0, 3)
        ref.uniform(0.05, 10.0, 3)
        p, a = sample_attention(xi_t, ours)
        p_ref = ref.dirichlet(xi_t)
        assert np.array_equal(p, p_ref)
        assert a == int(ref.choice(3, p=p_ref))
        assert ours.random() == ref.random()  # and leaves it at the same place
