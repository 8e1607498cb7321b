"""What the UAV flies with no OK plan (dualpilot/mission/braking.py): braking, or an escape.

Eq. (1) at the paper's values: p_{t+1} = p_t + ΔT v_t, v_{t+1} = 0.8 v_t + u_t / 1.05, so a
force of 7.5 N changes the velocity by 7.5 / 1.05 = 7.142857 m/s in one step, and braking
(u = −0.84 v) stops a UAV slower than 8.93 m/s in one step.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dualpilot.mission.braking import (
    ESCAPE_HEADINGS,
    braked_landing,
    escape_candidates,
    no_plan_control,
)
from dualpilot.mission.params import MissionParams
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.model.geometry import Rect

DYN = DynamicsParams()
AREA = Rect(500.0, 500.0, 1000.0, 1000.0)
#: 7.5 N for one second on 1.05 kg (m/s)
KICK = 7.5 / 1.05
CLEARANCE = 25.0


def _square_east_of(x0: float) -> Rect:
    """A 40 m square from x0 eastwards, y 480–520."""
    return Rect(x0 + 20.0, 500.0, 40.0, 40.0)


def _distance_to(rect: Rect):  # type: ignore[no-untyped-def]
    return lambda p: rect.polytope().distance(np.asarray(p)[:2])


def test_at_rest_20_m_from_a_front_it_flies_straight_away_at_full_force() -> None:
    """At rest 20 m west of a square, braking lands 20 m from it (< 25 m): the escape flies
    west, −7.5 N, and lands 20 + 7.142857 = 27.142857 m away (every other heading lands
    nearer: 157.5° at 20 + 7.142857·cos 22.5° = 26.599 m)."""
    state = np.array([500.0, 500.0, 0.0, 0.0])
    hull = _square_east_of(520.0)
    control, escaped = no_plan_control(state, DYN, _distance_to(hull), CLEARANCE, AREA)
    assert escaped
    np.testing.assert_allclose(control, [-7.5, 0.0], atol=1e-9)
    landing = braked_landing(state, control, DYN)
    np.testing.assert_allclose(landing, [500.0 - KICK, 500.0], atol=1e-9)
    assert hull.polytope().distance(landing) == pytest.approx(20.0 + KICK)


def test_it_brakes_when_braking_lands_clear_of_every_hull() -> None:
    """Moving east at 5 m/s, 215 m short of a hull: braking (−0.84 · 5 = −4.2 N) stops it at
    x = 305 m, 215 m ≥ 25 m away: no escape."""
    state = np.array([300.0, 500.0, 5.0, 0.0])
    control, escaped = no_plan_control(state, DYN, _distance_to(_square_east_of(520.0)),
                                       CLEARANCE, AREA)
    assert not escaped
    np.testing.assert_allclose(control, [-4.2, 0.0])


def test_an_escape_never_leaves_the_area() -> None:
    """At rest at x = 5 m, 20 m west of a square: west lands at x = −2.14 m and 157.5° at
    x = −1.60 m, both outside; 112.5° lands at (2.2666, 506.599), 22.733 m from the square,
    the farthest inside (90° lands 20 m away), and ties with 247.5° go to the first."""
    state = np.array([5.0, 500.0, 0.0, 0.0])
    control, escaped = no_plan_control(state, DYN, _distance_to(_square_east_of(25.0)),
                                       CLEARANCE, AREA)
    assert escaped
    angle = math.radians(112.5)
    np.testing.assert_allclose(control, [7.5 * math.cos(angle), 7.5 * math.sin(angle)],
                               atol=1e-9)
    landing = braked_landing(state, control, DYN)
    assert landing[0] == pytest.approx(5.0 - KICK * math.cos(math.radians(67.5)))
    assert 25.0 - landing[0] == pytest.approx(22.733, abs=1e-3)


def test_braking_stays_when_no_heading_lands_farther() -> None:
    """Inside a corridor 20 m wide on each side, every heading lands at most 20 m from a wall
    (along the corridor exactly 20 m: not strictly farther), so it brakes."""
    state = np.array([500.0, 500.0, 0.0, 0.0])
    walls = [Rect(500.0, 540.0, 1000.0, 40.0), Rect(500.0, 460.0, 1000.0, 40.0)]

    def distance(p):  # type: ignore[no-untyped-def]
        return min(w.polytope().distance(np.asarray(p)[:2]) for w in walls)

    control, escaped = no_plan_control(state, DYN, distance, CLEARANCE, AREA)
    assert not escaped
    np.testing.assert_allclose(control, [0.0, 0.0])


def test_a_heading_is_cut_to_the_force_that_keeps_the_speed_limit() -> None:
    """At 15 m/s west, west can add only what keeps v_x ≥ −15: −12 − s/1.05 ≥ −15, s = 3.15 N;
    east keeps the full 7.5 N. Under the norm limit, north-west (135°) needs
    (−12 − a)² + a² ≤ 225 with a = s·cos 45°/1.05: 2a² + 24a − 81 = 0, s = 4.0783 N."""
    state = np.array([500.0, 500.0, -15.0, 0.0])
    axis = escape_candidates(state, DYN)
    assert len(axis) == 1 + ESCAPE_HEADINGS
    east, west = axis[1], axis[1 + ESCAPE_HEADINGS // 2]
    np.testing.assert_allclose(east, [7.5, 0.0], atol=1e-12)
    np.testing.assert_allclose(west, [-3.15, 0.0], atol=1e-6)
    norm_dyn = DynamicsParams(speed_limit="norm")
    north_west = escape_candidates(state, norm_dyn)[1 + 3 * ESCAPE_HEADINGS // 8]
    a = (-24.0 + math.sqrt(24.0**2 + 8.0 * 81.0)) / 4.0
    s = a * 1.05 / math.cos(math.radians(45.0))
    np.testing.assert_allclose(north_west, [-s * math.cos(math.radians(45.0)),
                                            s * math.sin(math.radians(45.0))], atol=1e-6)
    assert s == pytest.approx(4.0783, abs=1e-4)


def test_in_3d_an_escape_keeps_braking_vertically() -> None:
    """In 3-D every candidate's vertical force is braking's (−0.84 · 2 = −1.68 N at 2 m/s up),
    so an escape neither climbs nor sinks; the horizontal escape is the planar one."""
    dyn3 = DynamicsParams(dim=3)
    state = np.array([500.0, 500.0, 50.0, 0.0, 0.0, 2.0])
    candidates = escape_candidates(state, dyn3)
    assert all(c[2] == pytest.approx(-1.68) for c in candidates)
    control, escaped = no_plan_control(state, dyn3, _distance_to(_square_east_of(520.0)),
                                       CLEARANCE, AREA)
    assert escaped
    np.testing.assert_allclose(control, [-7.5, 0.0, -1.68], atol=1e-9)


def test_the_default_brakes_and_a_bad_value_is_refused() -> None:
    assert MissionParams().no_plan == "brake"
    with pytest.raises(ValueError, match="no_plan must be one of"):
        MissionParams(no_plan="hover")  # type: ignore[arg-type]


def _grass15_mission(no_plan: str):  # type: ignore[no-untyped-def]
    """Mission 127 of concurrent's grass-15 evaluation (seed 0) on the multirotor: braking in
    the tube's band, where no planner takes the start, ends it in a tracking_breach at step
    19 (docs/plant.md)."""
    from dataclasses import replace

    from dualpilot.mission.config import MissionConfig
    from dualpilot.mission.local import local_mission
    from dualpilot.mission.params import Timing

    settings = (("scenario", "grass-15"), ("plant", "multirotor"), ("turbulence", "moderate"),
                ("gps_sigma_m", 1.5), ("no_plan", no_plan))
    config = MissionConfig.named("concurrent", seed=3145347817, timing=Timing.PAPER,
                                 profile="today", settings=settings)
    config = replace(config, start=(179.53717484108245, 80.56460399597145),
                     goal=Rect(867.6699085824072, 808.4257312573413, 100.0, 100.0))
    return local_mission(config).run()


def test_a_mission_that_brakes_into_a_breach_escapes_and_plans_again() -> None:
    braked = _grass15_mission("brake")
    assert braked.ending is not None and braked.ending.value == "tracking_breach"
    assert braked.steps == 19
    assert not any(r.info.get("source") == "escape" for r in braked.records)
    escaped = _grass15_mission("escape")
    escapes = [r for r in escaped.records if r.info.get("source") == "escape"]
    assert escapes and all(r.system == 0 for r in escapes)
    # each escape is a heading at the full 7.5 N (the speed limit is far: |v| < 9 m/s)
    assert all(np.linalg.norm(r.control) == pytest.approx(7.5) for r in escapes)
    after = escaped.records[escaped.records.index(escapes[-1]) + 1]
    assert after.system == 1 and "s1:ok" in after.plan_status  # a planner takes it again
    assert escaped.steps > 19
