"""The third dimension's readings and the 3-D mission spec (docs/three_d.md, §1)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.config_args import config_to_argv, parse_config
from dualpilot.model.altitude import AltitudeBand
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.model.fire import FireParams
from dualpilot.model.fire_field import FireField
from dualpilot.model.fire_height import FireHeightParams
from dualpilot.model.geometry import Rect
from dualpilot.model.vertical import VerticalParams
from dualpilot.readings import (
    PROFILES,
    READINGS,
    get_profile,
    parse_settings,
    part_of,
    settable,
    value_text,
)
from dualpilot.spec import MissionSpec, Stream, stream_rng

D3 = DynamicsParams(dim=3)


def test_the_3d_spec_says_where_the_uav_starts_and_where_g_is() -> None:
    spec = MissionSpec(start=(50.0, 60.0), goal=Rect(900.0, 900.0, 100.0, 100.0), dynamics=D3,
                       band=AltitudeBand(start_altitude_m=45.0, goal_altitude_m=70.0))
    assert spec.dim == 3
    assert spec.start_position.tolist() == [50.0, 60.0, 45.0]
    assert spec.goal_center.tolist() == [900.0, 900.0, 70.0]
    assert spec.above_ceiling_m == 120.0 + 25.0  # the ceiling plus ε
    # G over the whole band above the rectangle: entered at any altitude of the band
    assert spec.in_goal(np.array([851.0, 949.0, 119.0]))
    assert not spec.in_goal(np.array([851.0, 949.0, 121.0]))
    assert not spec.in_goal(np.array([849.0, 900.0, 70.0]))
    cube = MissionSpec(dynamics=D3, goal_vertical="cube")  # within 50 m of G_o's 50 m
    assert cube.goal_box.z_lo == 20.0 and cube.goal_box.z_hi == 100.0
    assert not cube.in_goal(np.array([900.0, 900.0, 101.0]))
    with pytest.raises(ValueError, match="vertical must be one of"):
        MissionSpec(goal_vertical="tall")  # type: ignore[arg-type]


def test_a_2d_spec_is_the_planar_one() -> None:
    spec = MissionSpec()
    assert spec.dim == 2
    assert spec.start_position.tolist() == [50.0, 50.0]
    assert spec.goal_center.tolist() == [900.0, 900.0]
    assert spec.in_goal(np.array([860.0, 940.0])) and not spec.in_goal(np.array([849.0, 900.0]))


def test_the_altitude_readings_are_settable_by_bare_name() -> None:
    names = set(settable())
    assert {"ceiling_m", "floor_m", "start_altitude_m", "goal_altitude_m", "goal_vertical",
            "fire_height", "fire_height_min_m", "fire_height_max_m", "plume_intensity",
            "uav_limit_c", "ambient_c"} <= names
    assert {part_of(n) for n in ("ceiling_m", "fire_height", "uav_limit_c",
                                 "goal_vertical")} == {"altitude"}
    settings = parse_settings(["dim=3", "ceiling_m=100", "floor_m=10", "goal_altitude_m=80",
                               "goal_vertical=cube", "fire_height=uniform",
                               "fire_height_min_m=30", "fire_height_max_m=60",
                               "uav_limit_c=60"])
    p = get_profile("today").with_settings(settings)
    assert p.dynamics.dim == 3
    assert p.altitude.band == AltitudeBand(floor_m=10.0, ceiling_m=100.0, goal_altitude_m=80.0)
    assert p.altitude.goal_vertical == "cube"
    assert p.altitude.heights == FireHeightParams("uniform", 30.0, 60.0)
    assert p.altitude.plume.uav_limit_c == 60.0
    # every value reads back from its text
    values = p.values()
    again = get_profile("today").with_settings(
        {k: value_text(v) for k, v in values.items() if k in settings})
    assert again == p
    # the spec carries the band and the goal reading
    spec = p.spec(MissionSpec())
    assert spec.band == p.altitude.band and spec.goal_vertical == "cube" and spec.dim == 3


def test_the_readings_name_the_altitude_ones() -> None:
    for name in ("dim", "ceiling_m", "floor_m", "start_altitude_m", "goal_altitude_m",
                 "goal_vertical", "fire_height", "plume_intensity", "uav_limit_c"):
        assert name in READINGS


def test_a_height_reading_must_fit_its_fire_process() -> None:
    with pytest.raises(ValueError, match="plume follows a fire-behaviour scenario"):
        get_profile("today").with_settings({"fire_height": "plume"})
    with pytest.raises(ValueError, match="uniform draws the paper's cuboids"):
        get_profile("today").with_settings({"scenario": "shrub", "fire_height": "uniform"})
    auto = FireHeightParams()
    assert auto.resolved("paper") == "above-ceiling" and auto.resolved("grass-5") == "plume"
    assert FireHeightParams("above-ceiling").resolved("shrub") == "above-ceiling"
    with pytest.raises(ValueError, match="plume_intensity must be one of"):
        FireHeightParams(plume_intensity="mean")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="goal_vertical must be one of"):
        VerticalParams(goal_vertical="sky")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="outside the band"):
        get_profile("today").with_settings({"ceiling_m": "40"})  # the start at 50 m


def test_today_3d_is_today_in_three_dimensions() -> None:
    today, flat = PROFILES["today-3d"], PROFILES["today"]
    assert today.dynamics == DynamicsParams(dim=3)
    assert today.altitude == VerticalParams()
    assert (today.fire, today.mission, today.supervisor) == (flat.fire, flat.mission,
                                                             flat.supervisor)
    assert any("120 m" in s for s in today.sources)
    config = MissionConfig(profile="today-3d", seed=3)
    spec = config.spec()
    assert spec.dim == 3 and spec.start_position.tolist() == [50.0, 50.0, 50.0]
    # the same mission as --set dim=3 on today
    assert MissionConfig(profile="today", settings=(("dim", 3),), seed=3).spec() == spec


def test_a_3d_configuration_goes_through_its_flags_unchanged() -> None:
    config = MissionConfig.named("s2", profile="today-3d", seed=11, settings=(
        ("ceiling_m", 110.0), ("goal_vertical", "cube"), ("scenario", "grass-5"),
        ("plume_intensity", "head"), ("goal_altitude_m", 60.0)))
    again = parse_config(config_to_argv(config))
    assert again == config and again.spec() == config.spec()
    assert again.spec().goal_box.center_z == 60.0


def test_the_height_stream_is_apart_from_the_fire_stream() -> None:
    seed = 42
    fire = stream_rng(seed, Stream.FIRE).random(5)
    heights = stream_rng(seed, Stream.FIRE_HEIGHT).random(5)
    assert not np.array_equal(fire, heights)
    for other in (Stream.SUPERVISOR, Stream.SYSTEM1):
        assert not np.array_equal(stream_rng(seed, other).random(5), heights)
    # its own seed sequence: the same numbers whichever streams were drawn before
    assert np.array_equal(stream_rng(seed, Stream.FIRE_HEIGHT).random(5), heights)


@pytest.mark.parametrize("reading", ["auto", "above-ceiling", "uniform"])
def test_a_3d_fire_draws_the_2d_rectangles_seed_for_seed(reading: str) -> None:
    """200 seeds: the rectangles, hulls and births of the fire stream are the 2-D process's;
    the tops come from the height stream alone (uniform: its draws, in order)."""
    params = FireParams(p_birth=0.5)
    vertical = VerticalParams(heights=FireHeightParams(reading))  # type: ignore[arg-type]
    for seed in range(200):
        spec = MissionSpec(seed=seed, dynamics=D3)
        flat = FireField(params)
        tall = FireField(params, heights=vertical.fire_heights(spec, "paper"))
        r2, r3 = spec.rng(Stream.FIRE), spec.rng(Stream.FIRE)
        for k in range(12):
            flat.substep(r2, k // 2)
            tall.substep(r3, k // 2)
        s2, s3 = flat.snapshot(), tall.snapshot()
        assert s2.regions == s3.regions and s2.front_ids == s3.front_ids
        assert all(np.array_equal(a.vertices, b.vertices) for a, b in zip(s2.hulls, s3.hulls,
                                                                           strict=True))
        assert r2.random() == r3.random()  # the fire stream stands at the same draw
        assert len(s3.tops_m) == len(s3.regions) and not s2.tops_m
        if reading != "uniform":
            assert set(s3.tops_m) <= {145.0}
    # uniform: each new rectangle's top is the height stream's next U[100, 250] draw
    spec = MissionSpec(seed=5, dynamics=D3)
    field = FireField(FireParams(p_birth=1.0, p_survive=0.0),
                      heights=vertical.fire_heights(spec, "paper"))
    field.substep(spec.rng(Stream.FIRE), 0)
    if reading == "uniform":
        want = spec.rng(Stream.FIRE_HEIGHT).uniform(100.0, 250.0)
        assert field.snapshot().tops_m == (want,)


def test_a_2d_mission_has_no_heights() -> None:
    spec = MissionSpec(seed=1)
    assert VerticalParams().fire_heights(spec, "paper") is None


@pytest.mark.parametrize(("system", "method"), [(1, "straight")])  # the example package's
def test_a_planar_method_refuses_a_3d_mission_by_name(system: int, method: str) -> None:
    from dualpilot.planners import build_planner

    spec = MissionConfig(profile="today-3d").spec()
    with pytest.raises(ValueError, match=rf"System {system} method '{re.escape(method)}' "
                                         r"plans in 2-D only, not dim=3"):
        build_planner(system, spec, method)


def test_a_mission_names_each_planner_that_refuses_3d() -> None:
    from dualpilot.mission.local import local_mission

    low = (("fire_height", "uniform"), ("fire_height_min_m", 5.0), ("fire_height_max_m", 40.0))
    refused = "System 2 method 'certified' plans dim=3 only where every front's top is above"
    with pytest.raises(ValueError, match=refused):
        local_mission(MissionConfig.named("s2", profile="today-3d", system2_method="certified",
                                          settings=low))
    with pytest.raises(ValueError, match=refused):
        local_mission(MissionConfig.named("cc", profile="today-3d",  # System 1 plans in 3-D
                                          system2_method="certified", settings=low))


def test_a_planar_supervisor_refuses_a_3d_mission_by_name() -> None:
    """The example package's "proximity" says 2-D only; every built-in supervisor says 3."""
    from dualpilot.supervisor.registry import build_supervisor

    config = MissionConfig.named("proximity", profile="today-3d")
    with pytest.raises(ValueError, match="the proximity supervisor supervises missions in 2-D "
                                         "only, not dim=3"):
        build_supervisor(config, config.spec())
    for name in ("cc", "concurrent", "lookahead"):
        built = MissionConfig.named(name, profile="today-3d")
        assert build_supervisor(built, built.spec()) is not None


def test_the_oracle_judges_a_3d_mission() -> None:
    """docs/three_d.md §9 (its verdicts: tests/unit/dualpilot/oracle/test_oracle3d.py)."""
    from dualpilot.oracle.oracle import DIMS, check_dimension

    assert sorted(DIMS) == [2, 3]
    check_dimension(MissionConfig.named("s1", profile="today-3d"))
    check_dimension(MissionConfig.named("s1", profile="today-3d",
                                        settings=(("fire_height", "uniform"),)))


def test_a_method_says_the_dimensions_it_plans_in() -> None:
    from dualpilot.planners import PlannerMethod, planner_method

    assert planner_method("rrt").dims == frozenset({2, 3})  # System 1 plans in 3-D too
    # System 2's fast method and the one built on it plan in both
    # (tests/unit/dualpilot/system2/fast/test_system2_fast3.py)
    assert planner_method("fast").dims == planner_method("thorough").dims == frozenset({2, 3})
    # the certified method plans 3-D missions over fronts taller than the ceiling only
    # (tests/unit/dualpilot/system2/certify/test_certify3.py)
    assert planner_method("certified").dims == frozenset({2, 3})
    assert planner_method("certified").scope3 is not None and planner_method("fast").scope3 is None
    with pytest.raises(ValueError, match="2-D, 3-D or both"):
        PlannerMethod(1, lambda spec, params: None, dims=frozenset({4}))  # type: ignore
