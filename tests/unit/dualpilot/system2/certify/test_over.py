"""The altitude's lower bounds of the certified method's 3-D branches
(dualpilot/system2/certify/over.py, branches.py; docs/three_d.md, 6. System 2, Certified)."""

from __future__ import annotations

import math

import cvxpy as cp
import numpy as np
import pytest

from dualpilot.model.dynamics import DynamicsParams, transition_matrices
from dualpilot.model.geometry import Rect
from dualpilot.model.prism import Prism
from dualpilot.spec import MissionSpec
from dualpilot.system2.certify.branches import Branches
from dualpilot.system2.certify.over import altitude_costs

pytestmark = pytest.mark.unit

SPEC3 = MissionSpec(dynamics=DynamicsParams(dim=3))
BAND, EPS = SPEC3.band, SPEC3.clearance_m  # [20, 120] m, G_o at 50 m; 25 m
TALL = SPEC3.above_ceiling_m


def test_the_climbs_by_hand() -> None:
    """From 50 m at rest, far from an 80 m cuboid reachable at the horizon's end: Z_0 = 0;
    over it z ≥ 105 m at some step, the cheapest at τ = T with the steps before it at
    least 105 − 15 k m (X): 55² + 40² + 25² + 10² = 5350 (κ1 = 1); a cuboid taller than
    the ceiling less ε cannot be passed over (inf); a cuboid low enough to pass at 50 m
    costs nothing; halving κ1 halves the climb."""
    x0 = np.array([100.0, 100.0, 50.0, 0.0, 0.0, 0.0])
    rect = Rect(600.0, 600.0, 100.0, 100.0)
    prisms = (Prism.cuboid(rect, 0.0, 80.0), Prism.cuboid(rect, 0.0, TALL),
              Prism.cuboid(rect, 0.0, 20.0))
    z0, per = altitude_costs(SPEC3, x0, 0.0, prisms, (1.0, 0.0), 80)
    climb = per.min(axis=1)
    assert per[0, -1] == climb[0] and np.all(np.isinf(per[0, :5]))  # 105 m from τ = 6
    assert z0 == 0.0
    assert climb[0] == pytest.approx(5350.0, rel=2e-6) and climb[0] <= 5350.0
    assert math.isinf(climb[1]) and climb[2] == 0.0
    half = altitude_costs(SPEC3, x0, 0.0, prisms, (0.5, 0.0), 80)[1].min(axis=1)
    assert half[0] == pytest.approx(2675.0, rel=2e-6)


def test_a_footprint_out_of_reach_cannot_be_passed_over() -> None:
    """A cuboid 1000 m away at T = 10 (at most 10 × 15 m in each axis a step, nearer than
    the inflated footprint): no step can be over it (inf)."""
    x0 = np.array([100.0, 100.0, 50.0, 0.0, 0.0, 0.0])
    prisms = (Prism.cuboid(Rect(1100.0, 1100.0, 50.0, 50.0), 0.0, 30.8),)
    _, per = altitude_costs(SPEC3, x0, 0.0, prisms, (1.0, 0.001), 10)
    assert np.all(np.isinf(per))


def _z_optimum(x0: np.ndarray, u_prev: float, kappa: tuple[float, float], horizon: int,
               need: float | None, tau: int) -> float:
    """The z part of Eq. (S2) at its least under Eq. (1), U, X and the band, with
    z_τ ≥ ``need`` (none: None), by Clarabel: an independent upper bound's check."""
    dyn = SPEC3.dynamics
    phi, gamma = transition_matrices(dyn)
    i = [2, 5]
    phi_z, gamma_z = phi[np.ix_(i, i)], gamma[i, 2]
    x = cp.Variable((horizon + 1, 2))
    u = cp.Variable(horizon)
    cons = [x[0] == x0[i], cp.abs(u) <= dyn.u_max_n, cp.abs(x[1:, 1]) <= dyn.v_max_mps,
            x[1:, 0] >= BAND.floor_m, x[1:, 0] <= BAND.ceiling_m]
    cons += [x[k + 1] == phi_z @ x[k] + gamma_z * u[k] for k in range(horizon)]
    if need is not None:
        cons.append(x[tau, 0] >= need)
    du = cp.hstack([u[0] - u_prev, u[1:] - u[:-1]])
    prob = cp.Problem(cp.Minimize(kappa[0] * cp.sum_squares(x[1:, 0] - BAND.goal_z_m)
                                  + kappa[1] * cp.sum_squares(du)), cons)
    prob.solve(solver=cp.CLARABEL)
    return float(prob.value) if prob.status == "optimal" else math.inf


@pytest.mark.parametrize("seed", range(4))
def test_the_bounds_are_below_the_altitudes_optimum(seed: int) -> None:
    """At T = 20 from random altitudes and climb rates, over cuboids 10.7-95 m tall whose
    footprint every step can reach: Z_0 is at most the z part's free optimum, and each
    cuboid's bound at each τ at most the z part's optimum with z_τ ≥ top + ε (Clarabel,
    1e-6 relative; inf only where that program is infeasible)."""
    rng = np.random.default_rng(seed)
    kappa = (1.0, 0.001) if seed % 2 else (0.001, 1.0)
    x0 = np.array([300.0, 300.0, rng.uniform(25, 115), 0.0, 0.0, rng.uniform(-10, 10)])
    tops = (10.7, 30.8, 50.0, 80.0, 95.0)
    prisms = tuple(Prism.cuboid(Rect(300.0, 300.0, 200.0, 200.0), 0.0, t) for t in tops)
    u_prev = float(rng.uniform(-2, 2))
    z0, per = altitude_costs(SPEC3, x0, u_prev, prisms, kappa, 20)
    assert z0 <= _z_optimum(x0, u_prev, kappa, 20, None, 1) * (1 + 1e-6) + 1e-9
    for prism, row in zip(prisms, per, strict=True):
        for tau in range(1, 21):
            best = _z_optimum(x0, u_prev, kappa, 20, prism.z_hi + EPS, tau)
            assert row[tau - 1] <= best * (1 + 1e-6) + 1e-9
            if math.isinf(row[tau - 1]):  # called impossible: Clarabel finds it infeasible
                assert math.isinf(best)


def test_the_branches_by_hand() -> None:
    """Three prisms with Z = 5, 5 and inf, Z_0 = 1: branches (all, 1) and ({2}, 5); before a
    search the bound is 1; the smallest set {2} first, then all; then the least branch."""
    br = Branches(1.0, np.array([5.0, 5.0, math.inf]))
    assert br.kept == frozenset({2})
    assert br.branches == [(frozenset({0, 1, 2}), 1.0), (frozenset({2}), 5.0)]
    assert br.bound() == 1.0
    assert br.next_set(1000.0, 0.01) == frozenset({2})
    br.add(frozenset({2}), 100.0)
    assert br.bound() == 101.0  # the all-set's branch takes its subset's 100
    assert br.next_set(1000.0, 0.01) == frozenset({0, 1, 2})
    br.add(frozenset({0, 1, 2}), 120.0)
    assert br.bound() == 105.0 and br.next_set(1000.0, 0.01) is None
    assert br.next_set(105.5, 0.01) is None  # the gap closed
