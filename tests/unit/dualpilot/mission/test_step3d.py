"""The mission step in 3-D (docs/three_d.md, §3): d_t, d_safe, the failure rules and G, on
cuboids placed by hand."""

from __future__ import annotations

import numpy as np
import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import LocalPlanners, LocalVehicle
from dualpilot.mission.params import MissionParams
from dualpilot.mission.result import Ending
from dualpilot.mission.step import (
    Mission,
    MissionPorts,
    attention_distance,
    flight_outcome,
    segment_within,
)
from dualpilot.model.dynamics import hover_state
from dualpilot.model.fire import FireSnapshot
from dualpilot.model.geometry import Rect
from dualpilot.model.prism import Cuboid
from tests.support.scripted_fires import ScriptedFire, ScriptedFront, moving_box

LOW = Rect(500.0, 500.0, 100.0, 100.0)  # a 10 m grass fire under the UAV


def _snapshot(top: float, born: int = 0) -> FireSnapshot:
    return FireSnapshot(regions=(LOW,), hulls=(Rect(500.0, 500.0, 140.0, 100.0).polytope(),),
                        front_ids=(0,), born_steps=(born,), tops_m=(top,), hull_tops_m=(top,))


def test_d_t_is_the_3d_distance_to_the_nearest_cuboid() -> None:
    snap = _snapshot(10.0)
    above = np.array([500.0, 500.0, 40.0])
    beside = np.array([580.0, 500.0, 40.0])  # 30 m east of the rectangle, 30 m above its top
    for reading, want_above, want_beside in (("active", 30.0, np.hypot(30.0, 30.0)),
                                             ("hull", 30.0, np.hypot(10.0, 30.0))):
        params = MissionParams(d_t_reading=reading)  # type: ignore[arg-type]
        assert attention_distance(above, snap, 1, params) == pytest.approx(want_above)
        assert attention_distance(beside, snap, 1, params) == pytest.approx(want_beside)
    newborn = MissionParams(d_t_reading="newborn")
    assert attention_distance(above, _snapshot(10.0, born=0), 1, newborn) == 30.0
    assert attention_distance(above, _snapshot(10.0, born=1), 1, newborn) == float("inf")
    # a cuboid taller than the band: the planar distance, bit for bit
    tall = _snapshot(145.0)
    assert attention_distance(beside, tall, 1, MissionParams()) == LOW.distance(beside[:2])


def _mission(z: float, rule: str, born: int = 3) -> Mission:
    """A hovering UAV at (500, 500, z) over which a 10 m fire ignites at sub-step ``born``;
    no planner: the UAV brakes (stays)."""
    config = MissionConfig.named("s1", profile="today-3d", start=(500.0, 500.0),
                                 settings=(("start_altitude_m", z), ("failure_rule", rule),
                                           ("max_steps", 6)))
    spec = config.spec()
    fire = ScriptedFire([ScriptedFront(0, moving_box(450.0, 450.0, 550.0, 550.0), born=born,
                                       top_m=10.0)])
    state = hover_state(spec.start_position, spec.dynamics)
    ports = MissionPorts(fire.port(), LocalPlanners({}), LocalVehicle(state, spec.dynamics))
    return Mission(config, spec, ports, state)


@pytest.mark.parametrize("rule", ["any", "newborn", "become"])
def test_a_uav_30_m_above_a_10_m_fire_is_clear(rule: str) -> None:
    result = _mission(40.0, rule).run()
    assert result.ending is Ending.STEP_LIMIT
    assert [r.d_t for r in result.records][-1] == 30.0
    assert result.records[-1].state.tolist() == [500.0, 500.0, 40.0, 0.0, 0.0, 0.0]


@pytest.mark.parametrize(("rule", "ending"), [("any", Ending.FIRE_WHILE_PLANNING),
                                              ("newborn", Ending.FIRE_WHILE_STALE),
                                              ("become", Ending.STEP_LIMIT)])
def test_the_same_uav_at_25_m_is_caught(rule: str, ending: Ending) -> None:
    """15 m above the top: within d_safe. "newborn" counts the fronts stamped with the step
    being checked: the scripted front is stamped with its sub-step, 3, which runs in step
    2's planning, so step 3's first check finds it. "become" does not fail a front born
    within d_safe (it was never clear of the UAV), as in 2-D."""
    assert _mission(25.0, rule).run().ending is ending


def test_a_start_within_d_safe_of_a_cuboid_is_refused() -> None:
    with pytest.raises(ValueError, match="within d_safe"):
        _mission(25.0, "any", born=0)
    _mission(31.0, "any", born=0)  # 21 m above it: a start


def test_the_flown_segment_is_measured_to_the_cuboids() -> None:
    spec = MissionConfig(profile="today-3d").spec()
    fire = (Cuboid(LOW, 10.0),)
    over = (np.array([420.0, 500.0, 40.0]), np.array([580.0, 500.0, 40.0]))
    low = (np.array([420.0, 500.0, 25.0]), np.array([580.0, 500.0, 25.0]))
    params = MissionParams()
    assert flight_outcome(*over, fire, 3, spec, params) is None
    assert flight_outcome(*low, fire, 3, spec, params) is Ending.FIRE_CONTACT
    assert not segment_within(*over, fire, 20.0) and segment_within(*over, fire, 30.5)
    # the box prefilter's altitude gap: 200 m above the fire's box
    assert not segment_within(over[0] + [0, 0, 200.0], over[1] + [0, 0, 200.0], fire, 20.0)


def test_g_entered_from_above() -> None:
    """The goal box under the "cube" reading: [20, 100] m above the rectangle."""
    config = MissionConfig(profile="today-3d", settings=(("goal_vertical", "cube"),))
    spec = config.spec()
    params = MissionParams()
    above = np.array([900.0, 900.0, 110.0])
    assert flight_outcome(above - [40.0, 0, 0], above, (), 3, spec, params) is None
    assert flight_outcome(above, above - [0, 0, 12.0], (), 4, spec, params) is Ending.GOAL
    band = MissionConfig(profile="today-3d").spec()  # the whole band: 110 m is in G already
    assert flight_outcome(above - [40.0, 0, 0], above, (), 3, band, params) is Ending.GOAL
