"""The independent checks in 3-D (docs/three_d.md, §4): verify_trajectory, verify_p2_plan and
the run-time monitor against prisms and the altitude band."""

from __future__ import annotations

import numpy as np
import pytest

from dualpilot.mission import monitor
from dualpilot.mission.config import MissionConfig
from dualpilot.model.altitude import lift_controls, lift_state
from dualpilot.model.dynamics import DynamicsParams, hover_state, rollout
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.model.prism import Cuboid, Prism
from dualpilot.plan import Objective
from dualpilot.spec import MissionSpec
from dualpilot.system2.problem import check_request, disjunction_margin, verify_p2_plan
from dualpilot.verify import verify_trajectory

SPEC3 = MissionConfig(profile="today-3d").spec()
D2, D3 = DynamicsParams(), DynamicsParams(dim=3)
FIRE = Cuboid(Rect(500.0, 500.0, 100.0, 100.0), 10.0)  # a 10 m grass fire, 100 m wide


def _eastwards(z: float, T: int = 25) -> tuple[np.ndarray, np.ndarray]:
    """From rest at (400, 500, z), 2 N east for T steps: over the fire at altitude z."""
    controls = np.tile([2.0, 0.0, 0.0], (T, 1))
    return rollout(hover_state(np.array([400.0, 500.0, z]), D3), controls, D3), controls


def test_a_plan_through_the_gap_above_a_low_fire_is_accepted() -> None:
    states, controls = _eastwards(31.0)  # 21 m above the fire's top
    assert states[:, 0].max() > 560.0  # it does cross the fire
    v = monitor.check_plan(states, controls, states[0], (FIRE.prism,), SPEC3)
    assert v.ok, v.reason
    assert v.clearance_m == pytest.approx(21.0)
    assert verify_trajectory(states, controls, (FIRE.prism,), D3, 20.0, band=SPEC3.band).ok


def test_the_same_plan_1_m_too_low_is_refused_with_its_distance() -> None:
    states, controls = _eastwards(29.0)  # 19 m above the top
    v = monitor.check_plan(states, controls, states[0], (FIRE.prism,), SPEC3)
    assert not v.ok and "passes 19.00 m from a fire region or hull" in v.reason
    w = verify_trajectory(states, controls, (FIRE.prism,), D3, 20.0, band=SPEC3.band)
    assert not w.ok and "clearance 19.00 m" in w.reason


def test_a_plan_leaving_the_band_is_refused() -> None:
    up = rollout(hover_state(np.array([400.0, 500.0, 110.0]), D3), np.tile([0, 0, 3.0], (8, 1)),
                 D3)
    v = monitor.check_plan(up, np.tile([0, 0, 3.0], (8, 1)), up[0], (), SPEC3)
    assert not v.ok and "above the ceiling 120 m" in v.reason
    down = rollout(hover_state(np.array([400.0, 500.0, 30.0]), D3),
                   np.tile([0, 0, -3.0], (8, 1)), D3)
    v = monitor.check_plan(down, np.tile([0, 0, -3.0], (8, 1)), down[0], (), SPEC3)
    assert not v.ok and "below the floor 20 m" in v.reason
    w = verify_trajectory(down, np.tile([0, 0, -3.0], (8, 1)), (), D3, 20.0, band=SPEC3.band)
    assert not w.ok and "leaves the band [20, 120]" in w.reason
    # without a band, verify_trajectory leaves the altitudes to its caller
    assert verify_trajectory(down, np.tile([0, 0, -3.0], (8, 1)), (), D3, 20.0).ok


def test_a_3d_plan_against_planar_obstacles_is_refused() -> None:
    states, controls = _eastwards(60.0)
    v = monitor.check_plan(states, controls, states[0], (FIRE.rect.polytope(),), SPEC3)
    assert not v.ok and "planar obstacles" in v.reason
    assert not verify_trajectory(states, controls, (FIRE.rect.polytope(),), D3, 20.0).ok


def test_p2s_disjunction_uses_the_top_face() -> None:
    """Eq. (P2_3)-(P2_4) over the six faces: a position ε above the top satisfies it."""
    prism = FIRE.prism
    assert prism.n_faces == 6
    assert disjunction_margin(np.array([[500.0, 500.0, 35.0]]), [prism], 25.0) == 0.0
    assert disjunction_margin(np.array([[500.0, 500.0, 34.0]]), [prism], 25.0) == -1.0
    states, controls = _eastwards(36.0)
    assert verify_p2_plan(states, controls, [prism], D3, 25.0, 20.0, 1000.0,
                          band=SPEC3.band).ok
    states, controls = _eastwards(33.0)
    v = verify_p2_plan(states, controls, [prism], D3, 25.0, 20.0, 1000.0, band=SPEC3.band)
    assert not v.ok and "ε-disjunction of (P2) violated by 2 m" in v.reason
    x0 = hover_state(np.array([1.0, 2.0, 50.0]), D3)
    fast = Objective.MISSION_TIME
    assert isinstance(check_request(x0, [prism], fast, None, 3), tuple)
    assert "6 finite numbers" in str(check_request(x0[:4], [prism], fast, None, 3))
    assert "Prism instances" in str(check_request(x0, [prism.base], fast, None, 3))  # type: ignore


def _corpus(n: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, list[Polytope]]]:
    """Random planar plans near random hulls: (states, controls, measured, hulls), of every
    kind the checks refuse (too fast, forces past U, off the measured state, out of the area,
    too close) and many they accept."""
    rng = np.random.default_rng(8)
    out = []
    for _ in range(n):
        x0 = np.concatenate([rng.uniform(-5.0, 1005.0, 2), rng.uniform(-16.0, 16.0, 2)])
        controls = rng.uniform(-8.0, 8.0, (int(rng.integers(1, 30)), 2))
        states = rollout(x0, controls, D2)
        hulls = [Polytope.from_vertices(rng.uniform(0.0, 1000.0, 2) + rng.uniform(
            -120.0, 120.0, (6, 2))) for _ in range(int(rng.integers(0, 5)))]
        measured = x0 + (rng.normal(0.0, 1e-3, 4) if rng.random() < 0.2 else 0.0)
        out.append((states, controls, measured, hulls))
    return out


def test_every_2d_check_lifted_to_3d_gives_the_same_verdict_bit_for_bit() -> None:
    """Planar plans at 50 m, not climbing, against prisms taller than the band: the 2-D
    verdicts, reasons and clearances of the monitor, verify_trajectory and verify_p2_plan."""
    spec2 = MissionSpec()
    refusals = set()
    for states, controls, measured, hulls in _corpus(600):
        s3 = np.array([lift_state(x, 50.0) for x in states])
        u3 = lift_controls(controls)
        m3 = lift_state(measured, 50.0)
        prisms = [Prism(h, 0.0, SPEC3.above_ceiling_m) for h in hulls]
        a = monitor.check_plan(states, controls, measured, hulls, spec2)
        b = monitor.check_plan(s3, u3, m3, prisms, SPEC3)
        assert (a.ok, a.reason) == (b.ok, b.reason)
        assert a.clearance_m == b.clearance_m or (np.isnan(a.clearance_m)
                                                  and np.isnan(b.clearance_m))
        refusals.add(a.reason.split(" ")[0])
        c = verify_trajectory(states, controls, hulls, D2, 25.0)
        d = verify_trajectory(s3, u3, prisms, D3, 25.0, band=SPEC3.band)
        assert (c.ok, c.reason) == (d.ok, d.reason)
        assert c.clearance_m == d.clearance_m or np.isnan(c.clearance_m)
        e = verify_p2_plan(states, controls, hulls, D2, 25.0, 20.0, 1000.0)
        f = verify_p2_plan(s3, u3, prisms, D3, 25.0, 20.0, 1000.0, band=SPEC3.band)
        assert e.ok == f.ok and (e.clearance_m == f.clearance_m or np.isnan(e.clearance_m))
        if "disjunction" not in e.reason:  # (P2_3) in 3-D may also escape through a face
            assert e.reason == f.reason  # the bottom's, under ground: not so far inside
    assert {"ok", "passes", "|v|", "|u|", "starts", "leaves"} <= refusals
