"""The concurrent and lookahead supervisors in 3-D (docs/three_d.md, 8).

With every cuboid taller than the ceiling (``fire_height = above-ceiling``) a 3-D mission of
either supervisor, with the real 3-D planners, is the 2-D mission row for row
(tests/support/lifted.py's ``assert_same_mission``): its System 1 and System 2 plan the 2-D
plans under the reduction, and the supervisors' own distances, checks and space-time plans
give the 2-D numbers. With low fronts (the paper's process with heights U[5, 40] m) the
plans use the altitude, and the flown path keeps d_safe from every cuboid by the exact 3-D
distance.
"""

from __future__ import annotations

import numpy as np
import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import local_mission
from dualpilot.mission.params import Timing
from dualpilot.mission.result import MissionResult
from dualpilot.model.altitude import lift_controls, lift_state
from dualpilot.model.dynamics import DynamicsParams, hover_state, rollout
from dualpilot.model.prism import Cuboid, Prism
from dualpilot.plan import Plan, PlanStatus
from dualpilot.supervisor.lookahead.vertical import lift_plan, low, spanning
from tests.support.lifted import assert_same_mission

THREE_D = {"dim": 3, "fire_height": "above-ceiling"}
LOW = (("fire_height", "uniform"), ("fire_height_min_m", 5.0), ("fire_height_max_m", 40.0))


def _pair(name: str, seed: int, scenario: str) -> tuple[MissionResult, MissionResult]:
    flat = MissionConfig.named(name, seed=seed, timing=Timing.PAPER,
                               settings=(("scenario", scenario), ("max_steps", 150)))
    return local_mission(flat).run(), local_mission(flat.with_settings(THREE_D)).run()


def _notes(result: MissionResult) -> set[str]:
    return {a.note for r in result.records for a in r.answers if a.note}


@pytest.mark.parametrize(("name", "scenario", "seed"), [
    ("concurrent", "paper", 0),  # to G in 58 steps, System 2 deliberating while it flies
    ("concurrent+risk", "grass-5", 4),
    ("lookahead", "paper", 7),  # a space-time plan flown
    ("lookahead+risk", "shrub", 1)])
def test_tall_fires_give_the_2d_mission_row_for_row(name: str, scenario: str,
                                                    seed: int) -> None:
    flat, tall = _pair(name, seed, scenario)
    assert_same_mission(flat, tall)
    if (name, seed) == ("lookahead", 7):
        assert "[space-time]" in _notes(tall)  # the lattice plan, lifted to 50 m


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["paper", "grass-5", "shrub"])
@pytest.mark.parametrize("name", ["concurrent", "concurrent+risk", "lookahead",
                                  "lookahead+risk"])
def test_tall_fires_give_the_2d_missions_eight_seeds(name: str, scenario: str) -> None:
    for seed in range(8):
        assert_same_mission(*_pair(name, seed, scenario))


def _low_fires(name: str, seed: int,
               extra: tuple[tuple[str, object], ...] = ()) -> MissionResult:
    config = MissionConfig.named(name, seed=seed, timing=Timing.PAPER, profile="today-3d",
                                 settings=LOW + extra)
    result = local_mission(config).run()
    spec = config.spec()
    for r in result.records:  # the flown path keeps d_safe from every cuboid, in 3-D
        for region, top in zip(r.snapshot.regions, r.snapshot.tops_m, strict=True):
            assert top < spec.band.ceiling_m  # low fronts
            assert Cuboid(region, top).distance(r.state[:3]) >= spec.flight_d_safe_m
    return result


def test_concurrent_flies_over_a_low_front() -> None:
    """Seed 13: the UAV crosses the footprint of a front's swept cuboid 37.1 m tall at 60.6 m,
    above the 50 m the 2-D plans fly at and more than d_safe above its top."""
    result = _low_fires("concurrent", 13)
    assert result.success
    over = [(r.state[2], top) for r in result.records
            for hull, top in zip(r.snapshot.hulls, r.snapshot.hull_tops_m, strict=True)
            if hull.distance(r.state[:2]) == 0.0 and top + 20.0 > 50.0]
    assert over and all(z >= top + 20.0 for z, top in over)
    assert max(z for z, _ in over) > 60.0


def test_lookahead_climbs_over_low_fronts() -> None:
    """Seed 8: System 2's plans climb to 72 m over low fronts and the UAV reaches G."""
    result = _low_fires("lookahead", 8)
    assert result.success
    assert max(float(r.state[2]) for r in result.records) > 70.0


def test_lookahead_flies_over_a_low_front_with_the_zones_heights() -> None:
    """Seed 13 under ``risk_zone_height = "fire"``: the known future's cuboids and its forecast
    cells' heights (z* of the uniform law) make the concurrent choice over a front's footprint
    sound; the UAV crosses the swept cuboid 37.1 m tall at 60.6 m, more than d_safe above
    it, and reaches G in 64 steps (before the known future kept the heights the guard flew
    around it: 87 steps, never above 50.01 m)."""
    result = _low_fires("lookahead", 13, (("risk_zone_height", "fire"),))
    assert result.success and result.steps == 64
    d = result.spec.flight_d_safe_m
    over = [(float(r.state[2]), top) for r in result.records
            for hull, top in zip(r.snapshot.hulls, r.snapshot.hull_tops_m, strict=True)
            if hull.distance(r.state[:2]) == 0.0 and top + d > 50.0]
    assert over and all(z >= top + d for z, top in over)
    assert max(z for z, _ in over) > 60.0 and max(top for _, top in over) > 37.0


# -- the lookahead's planar plans in 3-D ---------------------------------------------------------
DYN3 = DynamicsParams(dim=3)


def _planar_plan() -> Plan:
    dyn2 = DynamicsParams()
    x0 = np.array([100.0, 200.0, 6.0, -3.0])
    controls = np.column_stack([np.linspace(3.0, -3.0, 12), np.linspace(-2.0, 2.0, 12)])
    assert np.abs(rollout(x0, controls, dyn2)[:, 2:]).max() < dyn2.v_max_mps  # within X
    return Plan(1, PlanStatus.OK, rollout(x0, controls, dyn2), controls, 0.0)


def test_a_level_uav_flies_the_planar_plan_at_its_altitude_bit_for_bit() -> None:
    flat = _planar_plan()
    lifted = lift_plan(flat, lift_state(flat.states[0], 63.0), DYN3)
    assert lifted is not None
    assert np.array_equal(lifted.states[:, [0, 1, 3, 4]], flat.states)
    assert np.all(lifted.states[:, 2] == 63.0) and np.all(lifted.states[:, 5] == 0.0)
    assert np.array_equal(lifted.controls, lift_controls(flat.controls))
    # and it is Eq. (1) in 3-D
    np.testing.assert_allclose(lifted.states, rollout(lifted.states[0], lifted.controls, DYN3),
                               atol=1e-9)


def test_a_climbing_uav_brakes_its_climb_on_the_planar_track() -> None:
    """v_z = 4 m/s: u_z = −m(1−ζ)v_z/ΔT = −3.36 N stops the climb in one step (|u_z| ≤ 7.5 N),
    so z rises by ΔT·v_z = 4 m and stays; the ground track is the planar plan's (per-axis
    limit: the axes are independent)."""
    flat = _planar_plan()
    x0 = lift_state(flat.states[0], 60.0)
    x0[5] = 4.0
    lifted = lift_plan(flat, x0, DYN3)
    assert lifted is not None
    np.testing.assert_allclose(lifted.controls[0, 2], -1.05 * 0.8 * 4.0, rtol=1e-12)
    np.testing.assert_allclose(lifted.states[1:, 2], 64.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(lifted.states[1:, 5], 0.0, atol=1e-12)
    np.testing.assert_allclose(lifted.states[:, [0, 1, 3, 4]], flat.states, rtol=0, atol=1e-9)
    norm = DynamicsParams(dim=3, speed_limit="norm")
    assert lift_plan(flat, x0, norm) is None  # the axes couple: no such plan


def test_the_prisms_that_span_the_band_and_the_low_ones() -> None:
    from dualpilot.model.altitude import AltitudeBand
    from dualpilot.model.geometry import Rect

    band = AltitudeBand()
    tall = Prism.cuboid(Rect(300.0, 300.0, 50.0, 50.0), 0.0, 145.0)
    grass = Prism.cuboid(Rect(500.0, 300.0, 50.0, 50.0), 0.0, 30.8)
    assert spanning((tall, grass), band) == (tall.base,)
    assert low((tall, grass), band) == (grass,)
    flat = (tall.base, grass.base)
    assert spanning(flat, band) == flat and low(flat, band) == ()
    assert hover_state(np.zeros(3), DYN3).shape == (6,)
