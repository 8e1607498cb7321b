"""The closed loop of Sec. IV with the real System 1 (System 2 tests live with System 2)."""

import csv
import json

import numpy as np
import pytest

from dualpilot.mission.braking import brake_control
from dualpilot.mission.local import local_mission
from dualpilot.mission.params import Controller, MissionParams, Timing
from dualpilot.mission.records import STEP_COLUMNS, write_all
from dualpilot.mission.result import Ending
from dualpilot.mission.step import nearest_region_distance
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.model.fire import FireParams
from dualpilot.planners import build_planner
from dualpilot.spec import MissionSpec
from tests.support.missions import config_for


def s1_mission(seed, fire_params=FireParams(), controller=Controller.S1, params=None, **kw):
    spec = MissionSpec(seed=seed)
    s1 = build_planner(1, spec)
    config = config_for(spec, controller, fire=fire_params, mission=params, timing=Timing.PAPER,
                        **kw)
    return local_mission(config, planners={1: s1, 2: s1})


def test_open_sky_mission_reaches_goal_and_energy_is_sum_of_control_changes():
    result = s1_mission(3, FireParams(p_birth=0.0)).run()
    assert result.success and result.failure_cause == ""
    assert MissionSpec().goal.contains(result.final_state[:2])
    controls = np.array([r.control for r in result.records])
    du = np.diff(np.vstack([np.zeros(2), controls]), axis=0)
    assert result.energy == pytest.approx(float(np.sum(du**2)))
    assert result.mission_time_s == result.steps * 1.0
    # paper timing: System 1's 155 ms is one fire sub-step per step
    assert {r.fire_substeps for r in result.records} == {1}


def test_same_seed_reproduces_the_mission_exactly():
    a = s1_mission(5).run()
    b = s1_mission(5).run()
    assert a.steps == b.steps and a.success == b.success
    assert np.array_equal(
        np.array([r.state for r in a.records]), np.array([r.state for r in b.records])
    )
    assert [r.decision.attention for r in a.records] == [r.decision.attention for r in b.records]


def test_fire_born_on_the_uav_fails_the_mission():
    m = s1_mission(1, FireParams(p_birth=0.0, p_survive=1.0))
    m.fires.field.spawn(m.fires.rng, 0, center=(60.0, 60.0))
    m.step()
    assert m.done and not m.result.success
    assert m.result.failure_cause == "fire_while_planning"


def test_a_spec_outside_its_area_is_rejected():
    spec = MissionSpec()
    with pytest.raises(ValueError, match="outside"):
        MissionSpec(goal=spec.goal.__class__(990.0, 990.0, 100.0, 100.0))
    with pytest.raises(ValueError, match="start"):
        MissionSpec(start=(-5.0, 10.0))
    with pytest.raises(ValueError, match="d_safe_m <= clearance_m"):
        MissionSpec(d_safe_m=30.0, clearance_m=25.0)


def test_flown_path_never_comes_within_d_safe_of_a_fire_before_the_end():
    for seed in range(4):
        result = s1_mission(seed).run()
        recs = result.records
        last = len(recs) - 1 if not result.success else len(recs)
        for r in recs[:last]:
            assert nearest_region_distance(r.state[:2], r.snapshot.regions) >= 20.0


def test_step_limit_and_brake():
    result = s1_mission(2, FireParams(p_birth=0.0), params=MissionParams(max_steps=5)).run()
    assert not result.success and result.failure_cause == "step_limit" and result.steps == 5
    u = brake_control(np.array([0, 0, 10.0, -2.0]), DynamicsParams())
    # -m (1 - ζ) v / ΔT = -1.05 * 0.8 * [10, -2] = [-8.4, 1.68] -> clipped to ±7.5 N
    assert u == pytest.approx([-7.5, 1.68])


def test_records_on_disk(tmp_path):
    result = s1_mission(4).run()
    write_all(result, tmp_path)
    summary = json.loads((tmp_path / "summary.json").read_text())
    for key in (
        "success",
        "steps",
        "mission_time_s",
        "energy",
        "controller",
        "seed",
        "timing",
        "planning_time_s",
        "switches",
    ):
        assert key in summary
    with (tmp_path / "steps.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0].keys()) == STEP_COLUMNS
    assert len(rows) == len(result.records)
    assert {r["system"] for r in rows} <= {"0", "1"}
    trace = json.loads((tmp_path / "trace.json").read_text())
    assert len(trace["steps"]) == len(rows)


def test_single_system_controllers_never_switch():
    for seed in range(3):
        assert s1_mission(seed).run().switches == 0


def test_flight_outcome_rules_and_planning_order():
    from dualpilot.mission.step import flight_outcome
    from dualpilot.model.geometry import Rect
    from dualpilot.supervisor.paper.planning import planning_order

    cfg, params = MissionSpec(), MissionParams(max_steps=10)
    fire = (Rect(100.0, 0.0, 20.0, 20.0),)  # x in [90, 110]
    # passing 15 m from the fire's edge is contact (< d_safe = 20 m)
    assert (
        flight_outcome(np.array([80.0, 25.0]), np.array([120.0, 25.0]), fire, 1, cfg, params)
        is Ending.FIRE_CONTACT
    )
    goal = flight_outcome(np.array([880.0, 880.0]), np.array([900.0, 900.0]), (), 1, cfg, params)
    assert goal is Ending.GOAL and goal.success and goal.failure_cause == ""
    assert (
        flight_outcome(np.array([0.0, 0.0]), np.array([1.0, 1.0]), (), 10, cfg, params)
        is Ending.STEP_LIMIT
    )
    assert flight_outcome(np.array([0.0, 0.0]), np.array([1.0, 1.0]), (), 9, cfg, params) is None
    assert planning_order(Controller.CC, 2, MissionParams()) == [2, 1]
    assert planning_order(Controller.S1, 2, MissionParams()) == [1]
    assert planning_order(Controller.CC, 1, MissionParams(fallback=False)) == [1]


def test_segment_within_culls_by_box_and_agrees_with_the_exact_distance():
    """The box gap is a lower bound: culling by it never changes the contact verdict."""
    from dualpilot.mission.step import segment_region_distance, segment_within
    from dualpilot.model.geometry import Rect

    fire = (Rect(100.0, 0.0, 20.0, 20.0),)  # x in [90, 110], y in [-10, 10]
    # 15 m above the top edge: within 20 m; the box gap is 15 m
    assert segment_within(np.array([80.0, 25.0]), np.array([120.0, 25.0]), fire, 20.0)
    assert not segment_within(np.array([80.0, 25.0]), np.array([120.0, 25.0]), fire, 15.0)
    # past the corner (110, 10) diagonally: box gap (10, 10) but the true distance 10·√2
    p0, p1 = np.array([120.0, 20.0]), np.array([130.0, 30.0])
    assert segment_region_distance(p0, p1, fire) == pytest.approx(10.0 * np.sqrt(2.0))
    assert segment_within(p0, p1, fire, 14.5) and not segment_within(p0, p1, fire, 14.0)
    rng = np.random.default_rng(5)
    for _ in range(3000):
        regions = tuple(Rect(*rng.uniform(0.0, 1000.0, 2), *rng.uniform(100.0, 250.0, 2))
                        for _ in range(rng.integers(0, 4)))
        p0 = rng.uniform(0.0, 1000.0, 2)
        p1 = p0 + rng.normal(scale=15.0, size=2)
        assert segment_within(p0, p1, regions, 20.0) == (
            segment_region_distance(p0, p1, regions) < 20.0)


def test_rect_distance_matches_the_polytope_distance():
    from dualpilot.model.geometry import Rect

    r = Rect(10.0, -5.0, 40.0, 20.0)
    rng = np.random.default_rng(0)
    for p in rng.uniform(-100, 100, size=(200, 2)):
        assert r.distance(p) == pytest.approx(r.polytope().distance(p), abs=1e-9)
