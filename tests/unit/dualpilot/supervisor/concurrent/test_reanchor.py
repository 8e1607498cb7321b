"""The re-anchoring tolerances: "fixed" (2 m, 1 m/s) and "tube" (the flying plant's tube).

Hand-worked values: the multirotor at ``gps_sigma_m`` = 1.5 in moderate turbulence has the
tube 3.71692·1.5 + 3.0 = 8.5754 m (kept in steps of 2⁻²⁰ m) and the velocity tube
3.71692·0.05 + 3.5 = 3.68585 m/s (σ√(2 ln 1000), √(2 ln 1000) = 3.716922).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.model.dynamics import hover_state, rollout
from dualpilot.plan import Plan, PlanStatus
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.concurrent.rule import ConcurrentParams, reanchor
from tests.unit.dualpilot.supervisor.concurrent.test_concurrent import NudgedVehicle, fly, mission

TUBE_M = 3.716922 * 1.5 + 3.0  # 8.575383
TUBE_MPS = 3.716922 * 0.05 + 3.5  # 3.685846
FIXED = ConcurrentParams()
TUBE = ConcurrentParams(reanchor_tol="tube")


def flying_spec() -> MissionSpec:
    """The spec of a multirotor mission at gps 1.5 m, moderate turbulence, 10 m/s of wind."""
    return MissionConfig(settings=(("plant", "multirotor"), ("gps_sigma_m", 1.5),
                                   ("turbulence", "moderate"), ("wind_speed_mps", 10.0))).spec()


def a_plan(spec: MissionSpec) -> Plan:
    """From hover at (300, 300), 1 N east and 0.5 N north for 6 steps (Eq. (1))."""
    x0 = hover_state(np.array([300.0, 300.0]), spec.dynamics)
    controls = np.tile([1.0, 0.5], (6, 1))
    return Plan(system=2, status=PlanStatus.OK, states=rollout(x0, controls, spec.dynamics),
                controls=controls, compute_time_s=0.0)


def test_the_plants_tubes_reach_the_spec() -> None:
    spec = flying_spec()
    assert spec.tracking_margin_m == pytest.approx(TUBE_M, abs=1e-5)
    assert spec.tracking_margin_mps == pytest.approx(TUBE_MPS, abs=1e-5)
    assert MissionConfig().spec().tracking_margin_mps == 0.0  # the ideal plant: no tube
    exact = MissionConfig(settings=(("plant", "multirotor"), ("turbulence", "moderate"))).spec()
    assert exact.tracking_margin_mps == 3.5  # no GPS error: no velocity error
    gusty = MissionConfig(settings=(("plant", "multirotor"), ("turbulence", "moderate"),
                                    ("gust_rate_per_min", 2.0), ("gust_peak_mps", 4.0))).spec()
    assert gusty.tracking_margin_mps == 3.5 + 4.0  # a gust's peak is a velocity


def test_the_tolerances_follow_the_tube_only_under_the_reading() -> None:
    spec = flying_spec()
    assert FIXED.reanchor_tol == "fixed"  # the default
    assert FIXED.tolerances(spec) == (2.0, 1.0)
    assert TUBE.tolerances(spec) == (spec.tracking_margin_m, spec.tracking_margin_mps)
    ideal = MissionSpec()
    assert TUBE.tolerances(ideal) == FIXED.tolerances(ideal) == (2.0, 1.0)  # tube 0: as fixed
    wide = ConcurrentParams(reanchor_tol_m=10.0, reanchor_tol_mps=5.0, reanchor_tol="tube")
    assert wide.tolerances(spec) == (10.0, 5.0)  # never below the set tolerances
    with pytest.raises(ValueError, match="reanchor_tol must be 'fixed' or 'tube', not 'wide'"):
        ConcurrentParams(reanchor_tol="wide")  # type: ignore[arg-type]


def test_a_plan_5_m_off_is_reanchored_under_the_tube_and_dropped_under_the_default() -> None:
    spec = flying_spec()
    plan = a_plan(spec)
    state = plan.states[0] + np.array([3.0, 4.0, 0.0, 0.0])  # 5 m off, same velocity
    assert reanchor(plan, state, FIXED, spec) is None  # 5 > 2 m
    moved = reanchor(plan, state, TUBE, spec)  # 5 <= 8.58 m
    assert moved is not None
    # Eq. (1) is linear and the velocity gap is 0: every state moves by the same 5 m
    assert np.allclose(moved.states, plan.states + [3.0, 4.0, 0.0, 0.0], atol=1e-9)
    assert np.array_equal(moved.controls, plan.controls)
    far = plan.states[0] + np.array([9.0, 0.0, 0.0, 0.0])  # 9 > 8.58 m: dropped all the same
    assert reanchor(plan, far, TUBE, spec) is None


def test_a_plan_2_mps_off_is_reanchored_under_the_tube_and_dropped_under_the_default() -> None:
    spec = flying_spec()
    plan = a_plan(spec)
    dv = np.array([0.0, 0.0, 1.2, 1.6])  # 2 m/s off
    assert reanchor(plan, plan.states[0] + dv, FIXED, spec) is None  # 2 > 1 m/s
    moved = reanchor(plan, plan.states[0] + dv, TUBE, spec)  # 2 <= 3.686 m/s
    assert moved is not None
    # the gap under Eq. (1) (x_{k+1} = Φ x_k + Γ u_k): the velocity gap decays by (1 − ζ) a
    # step and the position gap grows by ΔT times it: after k steps
    # Δv_k = (1 − ζ)^k Δv_0, Δp_k = ΔT Δv_0 (1 − (1 − ζ)^k) / ζ
    z, dt = spec.dynamics.zeta, spec.dynamics.dt_s
    for k in range(len(plan.states)):
        gap = moved.states[k] - plan.states[k]
        assert np.allclose(gap[2:], (1 - z) ** k * dv[2:], atol=1e-9)
        assert np.allclose(gap[:2], dt * dv[2:] * (1 - (1 - z) ** k) / z, atol=1e-9)
    assert reanchor(plan, plan.states[0] + [0.0, 0.0, 0.0, 3.7], TUBE, spec) is None  # > 3.686


def test_the_tube_is_what_the_verification_keeps_after_reanchoring() -> None:
    """The tolerance only decides which plans are re-checked: the supervisor's check keeps
    the spec's d_safe, the paper's 20 m plus the tube, whatever the tolerance."""
    spec = flying_spec()
    assert spec.d_safe_m == pytest.approx(20.0 + TUBE_M, abs=1e-5)
    assert math.isclose(spec.flight_d_safe_m, 20.0)


@pytest.mark.parametrize(("params", "expected"), [(FIXED, "s2:stale_start"),
                                                  (TUBE, "s2:adopted")])
def test_in_a_mission_a_plan_5_m_off_is_adopted_only_under_the_tube(
        params: ConcurrentParams, expected: str) -> None:
    """The vehicle of the concurrent supervisor's hand-built mission (test_concurrent) is
    pushed 5 m east after step 6; the System 2 plan due at step 8 expected it 5 m west. A
    spec with the multirotor's tubes (8.58 m, 3.686 m/s): under "tube" the plan is
    re-anchored, verified and adopted; under the default it is dropped."""
    base = MissionSpec(seed=3)
    spec = replace(base.with_tracking_margin(TUBE_M), tracking_margin_mps=TUBE_MPS)
    x0 = hover_state(np.array(spec.start), spec.dynamics)
    m = mission(vehicle=NudgedVehicle(x0, spec, at=6, offset=5.0), params=params, spec=spec)
    recs = fly(m, 9)
    assert expected in recs[8].plan_status, recs[8].plan_status
    if expected == "s2:adopted":
        assert recs[8].system == 2
        assert np.allclose(recs[8].state[:2], recs[8].planned_positions[0])
