"""The supervisor's bound: exact P(S1 | d, t) of Eq. (Psi), checked by hand and by Monte-Carlo."""

import math

import numpy as np
import pytest

from dualpilot.cli import main
from dualpilot.evaluation.bound import (
    BoundParams,
    DiscretisationWarning,
    attention_marginal,
    best_cc_success,
    chain_method,
    p_s1,
    p_s1_path,
    p_s1_table,
    s1_share_needed,
)
from dualpilot.supervisor.paper.attention import xi
from dualpilot.supervisor.paper.decision import DecisionDynamics, SupervisorParams

Z99 = 2.5758  # two-sided 99 % normal quantile


def _xi_hand(t: float, d: float) -> tuple[float, float, float]:
    """Eq. (KSI) with the published w values, written out."""
    xi1 = 9 - 9 / (1 + 40 * math.exp(-0.02 * (d - 40))) + 1
    xi2 = 7 - 7 / (1 + 10 * math.exp(-0.05 * (t - 10))) + 1
    xi3 = 7 / (1 + 10 * math.exp(-0.15 * (t - 10))) + 1
    return xi1, xi2, xi3


def test_t0_by_hand():
    # Ψ_{−1} = (0, 0) (DecisionDynamics.__init__), so Ψ_0 = B Q A_0:
    # B Q = [[0.8 − 0.4, 0.5 − 0.9, 0.3 − 0.9], [−0.4, 0.4, 0.6]] = [[0.4, −0.4, −0.6], ...]
    # A_0 = e1 → Ψ_0 = (0.4, −0.4): S1;  e2 → (−0.4, 0.4), e3 → (−0.6, 0.6): S2.
    # So P(S_0 = 1) = P(A_0 = 1) = ξ1/Σξ, with at d = 0, t = 0:
    # ξ1 = 10 − 9/(1 + 40 e^0.8) = 9.90002, ξ2 = 8 − 7/(1 + 10 e^0.5) = 7.59971,
    # ξ3 = 1 + 7/(1 + 10 e^1.5) = 1.15278, Σξ = 18.65251 → 0.530761.
    xi1, xi2, xi3 = _xi_hand(0, 0)
    assert xi1 / (xi1 + xi2 + xi3) == pytest.approx(0.530761, abs=1e-6)
    assert p_s1(0.0, 0) == pytest.approx(xi1 / (xi1 + xi2 + xi3), abs=1e-12)
    xi1, xi2, xi3 = _xi_hand(0, 120)
    assert p_s1(120.0, 0) == pytest.approx(xi1 / (xi1 + xi2 + xi3), abs=1e-12)


def test_t1_and_t2_by_hand_with_the_tie():
    # x = Ψ(1) − Ψ(2) = 2 Ψ(1); x_t = x_{t−1}/2 + c_a, c = (0.8, −0.8, −1.2); S1 ⇔ x ≥ 0.
    # t = 1: x_0 ∈ {0.8, −0.8, −1.2}; a = 1 gives x_1 ∈ {1.2, 0.4, 0.2} ≥ 0, a = 2, 3 < 0.
    p = [attention_marginal(t, 0.0) for t in range(3)]
    assert p_s1(0.0, 1) == pytest.approx(p[1][0], abs=1e-12)
    # t = 2: S1 ⇔ A_2 = 1 and x_1 ≥ −1.6. x_1 < −1.6 only for (A_0, A_1) = (3, 3): −1.8;
    # (2, 3) gives x_1 = −0.4 − 1.2 = −1.6 and x_2 = 0: a tie, which goes to System 1.
    assert p_s1(0.0, 2) == pytest.approx(p[2][0] * (1 - p[0][2] * p[1][2]), abs=1e-12)


class _FixedAttention:
    """An rng stand-in whose Dirichlet and categorical draws always pick attention ``a``."""

    def __init__(self, a: int):
        self.a = a

    def dirichlet(self, alpha):
        return np.eye(3)[self.a]

    def random(self):  # the uniform of the categorical draw: P_t = e_a picks a for any u < 1
        return 0.5


def test_real_supervisor_breaks_that_tie_to_system_1():
    sup = DecisionDynamics(np.random.default_rng(0))
    sup.psi = np.array([-0.8, 0.8])  # x_1 = −1.6
    sup.rng = _FixedAttention(0)  # type: ignore[assignment]
    assert sup.decide(2, 0.0).system == 1


def test_finite_state_reduction_equals_enumeration():
    assert chain_method() == "lattice"
    d = [math.inf, math.inf, 300.0, 80.0, 10.0, 0.0, 0.0, 5.0, 60.0, 250.0, math.inf, 0.0, 0.0]
    exact = p_s1_path(d)
    enumerated = p_s1_path(d, BoundParams(method="enumerate", max_states=10**6))
    assert np.abs(exact - enumerated).max() < 1e-12


def test_s1_flies_only_when_attention_is_on_response_time():
    # x_{t−1} < 1.6 = 0.8/(1 − 1/2) always, so A_t = 2 (−0.8) or 3 (−1.2) make x_t < 0
    table = p_s1_table([0.0, 50.0, 200.0, math.inf], 80)
    bound = np.array(
        [[attention_marginal(t, d)[0] for t in range(81)] for d in (0.0, 50.0, 200.0, math.inf)]
    )
    assert np.all(table <= bound + 1e-12)
    assert np.all(table[:, 2:] < bound[:, 2:])  # x_{t−1} < −1.6 is reachable from t = 2
    assert table.max() == pytest.approx(0.530761, abs=1e-6)  # at d = 0, t = 0


def _mc_supervisor(d_path, runs, seed, params=SupervisorParams()):
    """Fraction of runs of the real DecisionDynamics with S_t = 1, per step."""
    rng = np.random.default_rng(seed)
    s1 = np.zeros(len(d_path))
    for _ in range(runs):
        sup = DecisionDynamics(rng, params)
        for t, d in enumerate(d_path):
            s1[t] += sup.decide(t, d).system == 1
    return s1 / runs


def _within_ci99(p_hat, p, runs):
    half = Z99 * np.sqrt(np.maximum(p * (1 - p), 1e-12) / runs)
    return np.abs(p_hat - p) <= half, half


@pytest.mark.parametrize(("d_m", "runs", "seed"), [(0.0, 1500, 11), (150.0, 600, 12)])
def test_monte_carlo_of_the_supervisor_agrees(d_m, runs, seed):
    steps = [0, 1, 2, 5, 15, 30, 45]
    d_path = [d_m] * (max(steps) + 1)
    p_hat = _mc_supervisor(d_path, runs, seed)[steps]
    exact = p_s1_path(d_path)[steps]
    ok, half = _within_ci99(p_hat, exact, runs)
    assert ok.all(), (p_hat, exact, half)
    if d_m == 0.0:  # the test can tell the chain from the naive bound ξ1/Σξ at t = 30, 45
        naive = np.array([attention_marginal(t, d_m)[0] for t in steps])
        assert np.all(np.abs(p_hat - naive)[-2:] > half[-2:])


def test_monte_carlo_on_a_mission_path_agrees():
    # no fire for 8 steps, a front at 20 m for 10 steps, then it moves away
    d_path = [math.inf] * 8 + [20.0] * 10 + [90.0, 160.0, 240.0, math.inf, math.inf]
    runs = 800
    p_hat = _mc_supervisor(d_path, runs, seed=13)
    ok, half = _within_ci99(p_hat, p_s1_path(d_path), runs)
    assert ok.all(), (p_hat, half)


def test_general_h_falls_back_to_a_grid_and_agrees_with_the_supervisor():
    params = SupervisorParams(h=0.45, q=((0.7, 0.5, 0.3), (0.4, 0.9, 0.8)))
    assert chain_method(params) == "enumerate"
    steps = 20
    with pytest.warns(DiscretisationWarning, match="discretising"):
        p = p_s1_path([0.0] * steps, BoundParams(supervisor=params, max_states=2000))
    runs = 800
    p_hat = _mc_supervisor([0.0] * steps, runs, seed=14, params=params)
    ok, half = _within_ci99(p_hat[[3, 10, 19]], p[[3, 10, 19]], runs)
    assert ok.all(), (p_hat, p, half)
    with pytest.raises(ValueError, match="max_states"):
        p_s1_path([0.0] * steps, BoundParams(supervisor=params, method="enumerate", max_states=50))


def test_non_scalar_h_and_b_run_on_the_full_psi_state():
    h = ((0.5, 0.2), (0.1, 0.4))
    b = ((1.0, -0.5), (-1.0, 1.0))
    bp = BoundParams(h_matrix=h, b_matrix=b, max_states=3000, grid_points=401)
    steps = 12
    with pytest.warns(DiscretisationWarning):
        p = p_s1_path([10.0] * steps, bp)
    # vectorised Monte-Carlo of Eqs. (dir), (categorical), (Psi), (maxPsi)
    rng = np.random.default_rng(15)
    runs = 20000
    hm, bq = np.array(h), np.array(b) @ SupervisorParams().q_matrix
    psi = np.zeros((runs, 2))
    p_hat = np.empty(steps)
    for t in range(steps):
        pt = rng.dirichlet(xi(t, 10.0), size=runs)
        a = (rng.random(runs)[:, None] > np.cumsum(pt, axis=1)).sum(axis=1).clip(0, 2)
        psi = psi @ hm.T + bq.T[a]
        p_hat[t] = np.mean(psi[:, 0] >= psi[:, 1])
    ok, half = _within_ci99(p_hat, p, runs)
    assert ok.all(), (p_hat, p, half)


def test_cc_bound_is_monotone_in_h2_and_between_s2_and_s1():
    values = [best_cc_success(0.006, h2, 50).cc_success for h2 in (0.006, 0.02, 0.05, 0.1, 0.3)]
    assert all(a >= b for a, b in zip(values, values[1:], strict=False))
    assert values[0] == pytest.approx(0.994**50)  # equal hazards: the supervisor cannot matter
    r = best_cc_success(0.006, 0.05, 50)
    assert r.s2_success < r.cc_success < r.s1_success
    assert r.s2_success == pytest.approx(0.95**50) and r.s1_success == pytest.approx(0.994**50)


def test_cc_bound_is_s2_success_when_s1_never_flies():
    # Q where System 2 wins every attribute: (1,−1) B Q < 0, x_t < 0 at every step
    never = SupervisorParams(q=((0.1, 0.1, 0.1), (0.9, 0.9, 0.9)))
    r = best_cc_success(0.006, 0.05, 40, never)
    assert np.all(r.p_s1 == 0.0)
    assert r.cc_success == pytest.approx(0.95**40, rel=1e-12)


def test_cc_bound_with_hazards_per_step():
    h2 = np.r_[np.zeros(10), np.full(20, 0.05)]  # hazards only once a front is near
    r = best_cc_success(0.0, h2, target=0.9)
    assert r.steps == 30 and r.s1_success == 1.0
    assert r.cc_success == pytest.approx(best_cc_success(0.0, h2, d_m=[0.0] * 30).cc_success)
    # the CC bound at the paper's hazards: far below 90 %, and 90 % is out of S1's own reach
    r50 = best_cc_success(0.006, 0.05, 50)
    assert r50.cc_success < 0.25 and math.isinf(r50.share_needed)


def test_share_needed():
    # constant hazards: (ln 0.9 − T ln(1 − h2)) / (T (ln(1 − h1) − ln(1 − h2)))
    h1, h2, n = 0.002, 0.05, 18
    closed = (math.log(0.9) - n * math.log(1 - h2)) / (n * (math.log(1 - h1) - math.log(1 - h2)))
    assert s1_share_needed(0.9, h1, h2, n) == pytest.approx(closed)
    assert s1_share_needed(0.9, 0.0, 0.05, 18) == pytest.approx(
        1 - math.log(0.9) / (18 * math.log(0.95))
    )
    assert s1_share_needed(0.3, 0.006, 0.05, 18) == 0.0  # S2 alone reaches 40 %
    assert math.isinf(s1_share_needed(0.9, 0.006, 0.05, 50))


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: p_s1(-1.0, 3), "distance to the nearest fire must be >= 0 m"),
        (lambda: p_s1(float("nan"), 3), "distance to the nearest fire must be >= 0 m"),
        (lambda: p_s1_path([0.0, -5.0]), "distance to the nearest fire must be >= 0 m"),
        (lambda: p_s1(0.0, -1), "step t must be an integer >= 0"),
        (lambda: p_s1(0.0, 2.5), "step t must be an integer >= 0"),  # type: ignore[arg-type]
        (lambda: best_cc_success(1.2, 0.05, 50), r"hazard h1 must be a probability per step"),
        (lambda: best_cc_success(0.006, -0.1, 50), r"hazard h2 must be a probability per step"),
        (lambda: best_cc_success(0.006, [0.05, 2.0]), r"hazard h2 must be a probability"),
        (lambda: best_cc_success(0.006, 0.05), "give the mission length"),
        (lambda: best_cc_success(0.006, 0.05, 50, d_m=-3.0), "must be >= 0 m"),
        (lambda: s1_share_needed(1.5, 0.006, 0.05, 50), r"target success must be in \(0, 1\]"),
        (lambda: p_s1(0.0, 3, BoundParams(method="exact")), "method must be one of"),
    ],
)
def test_bad_input_raises(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_cli_bound_prints_the_table_and_writes_the_figure(tmp_path, capsys):
    out = tmp_path / "p_s1.png"
    assert main(["bound", "--out", str(out), "--steps", "50,90"]) == 0
    text = capsys.readouterr().out
    assert "0.5308" in text and "unreachable" in text
    assert out.stat().st_size > 10_000
