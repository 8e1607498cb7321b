"""The physics fire process: Rothermel spread on pyretechnics' level set behind FireField."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from dualpilot.mission import monitor
from dualpilot.model.dynamics import hover_state
from dualpilot.model.fire import FireParams
from dualpilot.model.fire_field import FireField
from dualpilot.model.physics_fire import (
    PhysicsFire,
    clip_to_box,
    covered_area_m2,
    head_spread_rate_mps,
    midflame_wind_m_min,
    rothermel_spread,
    upwind_azimuth_deg,
)
from dualpilot.model.scenarios import (
    SCENARIOS,
    FuelMoisture,
    PhysicsFireParams,
    get_scenario,
    scenario_names,
)
from dualpilot.planners import build_planner
from dualpilot.readings import get_profile
from dualpilot.spec import MissionSpec, Stream
from tests.support.missions import config_for

pytestmark = pytest.mark.timeout(120)

#: pyretechnics' example moisture (1h, 10h, 100h, live herbaceous, live woody)
DOC_MOISTURE = FuelMoisture(0.05, 0.10, 0.15, 0.90, 0.60)


def test_rothermel_reproduces_pyretechnics_documented_values():
    """Fuel model GR1 (101) at the example moisture, as pyretechnics documents it.

    Source: pyretechnics' literate program (org/pyretechnics.org, its API
    documentation), "Surface Fire Equations (pyretechnics.surface_fire) / For
    Users": "How to Calculate the No-Wind-No-Slope Surface Fire Behavior" prints
    'base_spread_rate': 0.12637242674827576 (m/min); "How to Calculate the
    Surface Fire Behavior in the Direction of Maximum Spread" (midflame wind
    500 m/min, upwind 215°, slope 0.2, aspect 270°, length-to-width model
    "rothermel") prints 'max_spread_rate': 2.29646897315979 (m/min) with the
    effective wind speed limit and 23.33468246459961 without it.
    """
    base, head = rothermel_spread(101, DOC_MOISTURE, 500.0, 215.0, 0.2, 270.0, "rothermel")
    assert base == pytest.approx(0.12637242674827576, rel=1e-6)
    assert head == pytest.approx(2.29646897315979, rel=1e-6)
    _, unlimited = rothermel_spread(101, DOC_MOISTURE, 500.0, 215.0, 0.2, 270.0, "rothermel",
                                    use_wind_limit=False)
    assert unlimited == pytest.approx(23.33468246459961, rel=1e-6)


def test_midflame_wind_and_azimuths_by_hand():
    # fuel model 1: depth 1 ft, unsheltered WAF 1.83 / ln((20 + 0.36) / 0.13) = 0.36238
    # 10 m/s = 36 km/h at 10 m -> / 1.15 at 20 ft = 31.304 km/h = 521.74 m/min
    waf = 1.83 / math.log(20.36 / 0.13)
    assert midflame_wind_m_min(1, 10.0) == pytest.approx(36.0 / 1.15 / 0.06 * waf, rel=1e-5)
    assert upwind_azimuth_deg(math.pi / 4) == pytest.approx(225.0)  # towards NE: from SW
    assert upwind_azimuth_deg(0.0) == pytest.approx(270.0)  # towards east: from the west
    assert upwind_azimuth_deg(math.pi / 2) == pytest.approx(180.0)  # towards north


@pytest.mark.parametrize("cell_m", [10.0, 20.0])
def test_the_burned_area_grows_downwind_at_the_head_rate_on_the_grid(cell_m: float) -> None:
    """The region's downwind edge advances at Rothermel's head rate on the grid.

    Short grass (fuel model 1, D1L1) under a 15 m/s wind towards +x: head rate
    2.495 m/s (pyretechnics, wind-limited). From 36 s after a point ignition to
    180 s the head crosses ~360 m; the edge of the burned cells may be off by one
    cell, so the tolerance is one cell plus 3 % of the distance. The upwind edge
    (the backing fire) moves less than a tenth of that.
    """
    physics = PhysicsFireParams(fuel_model=1, wind_speed_mps=15.0, wind_direction_rad=0.0,
                                cell_m=cell_m)
    fire = PhysicsFire(physics, FireParams(p_birth=0.0), 1000.0)
    head = head_spread_rate_mps(physics)
    assert head == pytest.approx(2.495, abs=0.002)
    rng = np.random.default_rng(0)
    fire.spawn(rng, 0, center=(50.0, 500.0))
    edges = {}
    for k in range(1, 361):
        fire.substep(rng, k, life=True, keep_out=None)
        if k in (72, 360):
            (front,) = fire.fronts
            edges[k] = (front.region.bounds[0], front.region.bounds[2])
    expected = head * (360 - 72) * 0.5
    assert edges[360][1] - edges[72][1] == pytest.approx(expected, abs=cell_m + 0.03 * expected)
    assert edges[72][0] - edges[360][0] < 0.1 * expected


def test_spread_direction_follows_the_wind_towards_north_east():
    fire = PhysicsFire(get_scenario("grass-15").params, FireParams(p_birth=0.0), 1000.0)
    rng = np.random.default_rng(0)
    fire.spawn(rng, 0, center=(300.0, 300.0))
    for k in range(100):
        fire.substep(rng, k, life=True, keep_out=None)
    x0, y0, x1, y1 = fire.fronts[0].region.bounds
    assert x1 - 300 > 3 * (300 - x0) and y1 - 300 > 3 * (300 - y0)
    assert (x1 - 300) == pytest.approx(y1 - 300, abs=fire.cell_m)


def _run(params: FireParams, seed: int, substeps: int,
         keep_out: tuple[np.ndarray, float] | None = None) -> FireField:
    spec = MissionSpec(seed=seed)
    field = FireField(params=params, area_size_m=spec.area_size_m)
    rng = spec.rng(Stream.FIRE)
    for k in range(substeps):
        field.substep(rng, k // 10, keep_out=keep_out)
    return field


def _same(a: FireField, b: FireField) -> bool:
    sa, sb = a.snapshot(), b.snapshot()
    return (sa.regions == sb.regions and sa.front_ids == sb.front_ids
            and sa.born_steps == sb.born_steps
            and all(np.array_equal(x.vertices, y.vertices)
                    for x, y in zip(sa.hulls, sb.hulls, strict=True)))


def test_a_seed_reproduces_the_fires_and_another_seed_does_not():
    params = FireParams(scenario="grass-5")
    a, b, c = _run(params, 3, 120), _run(params, 3, 120), _run(params, 4, 120)
    assert a.next_id > 2
    assert _same(a, b)
    assert not _same(a, c)


def test_the_spotting_scenario_is_deterministic_per_seed():
    params = replace(FireParams(scenario="grass-15-spotting"), p_birth=0.05)
    a, b = _run(params, 5, 200), _run(params, 5, 200)
    assert _same(a, b) and a.physics is not None and b.physics is not None
    assert a.physics.spots == b.physics.spots


def test_births_keep_clear_of_the_keep_out():
    uav = np.array([500.0, 500.0])
    params = replace(FireParams(scenario="grass-5"), p_birth=1.0)
    field = FireField(params=params)
    rng = np.random.default_rng(1)
    for k in range(60):
        for front in field.substep(rng, k, keep_out=(uav, 150.0)):
            assert front.region.distance(uav) >= 150.0
    assert field.next_id >= 50
    none = FireField(params=params)
    for k in range(3):
        none.substep(rng, k, keep_out=(uav, 5000.0))
    assert none.fronts == [] and none.births_skipped == 3


def test_regions_and_hulls_are_convex_inside_the_area_and_cover_the_fire():
    field = _run(replace(FireParams(scenario="grass-15"), p_birth=0.1), 8, 300)
    assert field.physics is not None
    fire = field.physics
    snap = field.snapshot()
    assert len(snap.regions) >= 3
    area = MissionSpec().area
    for region, hull in zip(snap.regions, snap.hulls, strict=True):
        assert region.inside(area)
        v = hull.vertices
        assert v.min() >= 0.0 and v.max() <= 1000.0
        e = np.roll(v, -1, axis=0) - v
        turns = e[:, 0] * np.roll(e[:, 1], -1) - e[:, 1] * np.roll(e[:, 0], -1)
        assert (turns > 0).all()  # counter-clockwise, strictly convex
        for corner in region.corners():
            assert hull.contains(corner, margin=1e-6)  # the hull holds the region
    # every burned cell's centre lies in a front's hull (or an extinct area's)
    rows, cols = np.nonzero(fire.burned())
    centres = np.column_stack([cols + 0.5, rows + 0.5]) * fire.cell_m
    inside = np.zeros(len(centres), dtype=bool)
    for hull in snap.hulls:
        inside |= (centres @ hull.A.T <= hull.b + 1e-9).all(axis=1)
    assert inside.all()


def test_clip_to_box_cuts_a_polygon_to_the_area():
    square = np.array([[-10.0, -10.0], [50.0, -10.0], [50.0, 50.0], [-10.0, 50.0]])
    got = clip_to_box(square, 0.0, 40.0)
    assert sorted(map(tuple, got)) == [(0.0, 0.0), (0.0, 40.0), (40.0, 0.0), (40.0, 40.0)]


def test_the_paper_stays_the_default_and_scenarios_are_checked():
    assert FireParams().scenario == "paper" and FireField().physics is None
    assert scenario_names() == ("paper", "grass-5", "grass-15", "shrub", "grass-15-spotting")
    assert get_profile("today").with_settings({"scenario": "shrub"}).fire.scenario == "shrub"
    with pytest.raises(ValueError, match="scenario must be one of"):
        FireParams(scenario="tundra")
    with pytest.raises(ValueError, match="unknown fire scenario"):
        get_scenario("paper")
    with pytest.raises(ValueError, match="does not burn"):
        PhysicsFire(PhysicsFireParams(fuel_model=91), FireParams(), 1000.0)
    for s in SCENARIOS.values():
        assert s.source and s.summary


def test_both_planners_plan_verified_paths_around_physics_fires():
    field = _run(replace(FireParams(scenario="grass-15"), p_birth=0.1), 8, 120)
    spec = MissionSpec(seed=8)
    state = hover_state(np.array(spec.start), spec.dynamics)
    snap = field.snapshot()
    obstacles = snap.obstacles_for(state[:2], spec.clearance_m)
    assert len(obstacles) >= 3
    for system in (1, 2):
        plan = build_planner(system, spec).plan(state, obstacles)
        assert plan.ok, plan.status
        verdict = monitor.check(plan, state, obstacles, spec)
        assert verdict.ok, verdict.reason


def test_firebrands_start_spot_fires_downwind_of_the_fire():
    """grass-15-spotting, one ignition and no births: fronts appear downwind of it.

    pyretechnics lands a firebrand after twice Albini's (1979) lofting time and would
    ignite it 20 min later; the scenario counts the spot from its landing, so within
    the 6 min here spot fires start, north-east of the ignition, apart from it.
    """
    fire = PhysicsFire(get_scenario("grass-15-spotting").params, FireParams(p_birth=0.0),
                       1000.0)
    rng = np.random.default_rng(0)
    fire.spawn(rng, 0, center=(150.0, 150.0))
    spots = []
    for k in range(1, 721):
        spots += fire.substep(rng, k // 10, life=True, keep_out=None)
    assert spots and fire.spots
    for front in spots:
        assert front.front_id > 0 and front.born_step > 0
        x, y = front.region.center
        assert x > 300.0 and y > 300.0  # downwind (north-east) of the ignition


def test_a_fire_born_after_an_idle_spell_spreads_from_its_birth():
    """With no fire the level set does not run; a later birth restarts it at the fire clock,
    so 20 s after a birth at 100 s the head has run ~20 s × 2.495 m/s, not 120 s of it."""
    physics = replace(get_scenario("grass-15").params, wind_direction_rad=0.0)
    fire = PhysicsFire(physics, FireParams(p_birth=0.0), 1000.0)
    rng = np.random.default_rng(0)
    for k in range(200):
        fire.substep(rng, k, life=True, keep_out=None)
    assert fire.fronts == [] and fire.clock_s == pytest.approx(100.0)
    fire.spawn(rng, 200, center=(110.0, 510.0))
    for k in range(40):
        fire.substep(rng, 200 + k, life=True, keep_out=None)
    (front,) = fire.fronts
    run = front.region.bounds[2] - fire.pad_m - 120.0  # past the ignition cell's east edge
    assert run == pytest.approx(20.0 * fire.head_rate_mps, abs=fire.cell_m + 5.0)


def test_the_command_line_selects_a_scenario(tmp_path, capsys):
    from dualpilot.cli import build_parser, main
    from dualpilot.mission.config_args import config_from_args

    assert main(["scenarios"]) == 0
    listing = capsys.readouterr().out
    assert all(name in listing for name in scenario_names())
    parser = build_parser()
    for command in ("evaluate", "sweep"):
        assert parser.parse_args([command, "--scenario", "shrub"]).reading_scenario == "shrub"
    mission = parser.parse_args(["mission", "--scenario", "shrub"])
    assert config_from_args(mission).reading().fire.scenario == "shrub"
    with pytest.raises(ValueError, match="scenario must be one of"):
        config_from_args(parser.parse_args(["mission", "--scenario", "tundra"]))
    assert main(["scenarios", "--measure", "--seeds", "1", "--substeps", "4"]) == 0
    rows = [line.split() for line in capsys.readouterr().out.splitlines()[-4:]]
    assert [r[0] for r in rows] == list(SCENARIOS) and all(r[1] == "4" for r in rows)
    out = tmp_path / "run"
    assert main(["mission", "--controller", "s1", "--seed", "7", "--scenario", "grass-15",
                 "--quiet", "--no-figures", "--out", str(out)]) == 0
    assert '"controller": "s1"' in capsys.readouterr().out and (out / "summary.json").exists()


def test_a_mission_flies_on_the_physics_fires():
    from dualpilot.mission.local import local_mission
    from dualpilot.mission.params import Controller

    spec = MissionSpec(seed=7)
    mission = local_mission(config_for(spec, Controller.S1,
                                       fire=FireParams(scenario="grass-15")))
    assert mission.fires.field.physics is not None  # type: ignore[attr-defined]
    result = mission.run()
    assert result.steps > 10 and max(r.fires_active for r in result.records) >= 2
    for rec in result.records:
        for region, hull in zip(rec.snapshot.regions, rec.snapshot.hulls, strict=True):
            assert all(hull.contains(c, margin=1e-6) for c in region.corners())


def test_the_hulls_cover_a_burned_cell_grown_by_the_pad():
    """One ignited cell of 20 m: burned 400 m²; its hull is the cell grown by the pad on
    every side, pad = 10 m + 0.338 m/s × 1 s (grass-5's head rate), (20 + 2 pad)² m²."""
    fire = PhysicsFire(get_scenario("grass-5").params, FireParams(p_birth=0.0), 1000.0)
    fire.spawn(np.random.default_rng(0), 0, center=(510.0, 510.0))
    assert fire.pad_m == pytest.approx(10.0 + 0.338, abs=1e-3)
    burned, hulls = covered_area_m2(fire, resolution_m=0.5)
    assert burned == 400.0
    side = 20.0 + 2 * fire.pad_m  # counted on a 0.5 m lattice: up to one row more a side
    assert hulls == pytest.approx(side**2, abs=4 * side * 0.5)


def test_fires_that_meet_are_one_front_under_the_older_id():
    fire = PhysicsFire(get_scenario("grass-15").params, FireParams(p_birth=0.0), 1000.0)
    rng = np.random.default_rng(0)
    first = fire.spawn(rng, 0, center=(300.0, 300.0))
    second = fire.spawn(rng, 1, center=(350.0, 350.0))  # one cell between them
    assert (first.front_id, second.front_id) == (0, 1) and len(fire.fronts) == 2
    for k in range(60):
        fire.substep(rng, 2 + k, life=True, keep_out=None)
    (merged,) = fire.fronts
    assert merged.front_id == 0 and merged.born_step == 0
    assert fire.spawn(rng, 30, center=(10.0, 990.0)).front_id == 2  # ids are never reused
