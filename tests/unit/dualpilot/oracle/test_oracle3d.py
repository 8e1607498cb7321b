"""The oracle in 3-D where every front is taller than any UAV can fly: the planar oracle's
verdicts, its witnesses flown at one altitude through the 3-D mission; every other 3-D
mission judged over the band (docs/three_d.md §9; tests/unit/dualpilot/oracle/test_lattice3.py)."""

from __future__ import annotations

import numpy as np
import pytest

from dualpilot.evaluation.missions import Task
from dualpilot.mission.config import MissionConfig
from dualpilot.oracle.certificate import scope_of
from dualpilot.oracle.oracle import FEASIBLE, IMPOSSIBLE, Verdict, solve
from dualpilot.oracle.reduction import highest_uav_m, lowest_top_m, not_reduced, planar_twin
from tests.support.lifted import assert_same_mission
from tests.support.scripted_fires import ScriptedFire, ScriptedFront
from tests.unit.dualpilot.oracle.test_oracle import GOAL, START, corridor

#: the paper's process with every front above the ceiling (the default of dim=3 there)
TALL = (("dim", 3),)
#: drawn heights, every one at least 140 m: above the highest a UAV can fly (139.86 m)
DRAWN = (("dim", 3), ("fire_height", "uniform"), ("fire_height_min_m", 140.0),
         ("fire_height_max_m", 250.0))


def pair(index: int, seed: int, settings: tuple[tuple[str, object], ...],
         extra: tuple[tuple[str, object], ...] = ()) -> tuple[Verdict, Verdict]:
    """The oracle's verdicts on evaluation mission ``index`` of ``seed`` in 2-D (``extra``'s
    reading) and in 3-D (``extra`` and ``settings``)."""
    flat = Task.of(index, seed, "s1", MissionConfig(settings=extra)).mission()
    tall = Task.of(index, seed, "s1", MissionConfig(settings=extra + settings)).mission()
    assert flat.spec().dim == 2 and tall.spec().dim == 3
    return solve(flat), solve(tall)


def assert_same_verdict(flat: Verdict, tall: Verdict, same_rows: bool) -> None:
    """``tall`` (3-D) is ``flat`` (2-D): the verdict, its reason, the search's expansions and
    the certificate; a witness flown to G at 50 m with no climb, the 2-D flight's planar
    states (row for row when ``same_rows``: fires above the ceiling, tops all 145 m)."""
    assert (tall.verdict, tall.reason, tall.expansions, tall.problem) == (
        flat.verdict, flat.reason, flat.expansions, flat.problem)
    assert (flat.certificate is None) == (tall.certificate is None)
    if flat.certificate is not None and tall.certificate is not None:
        assert flat.certificate == tall.certificate
    assert (flat.flight is None) == (tall.flight is None)
    if flat.flight is None or tall.flight is None:
        return
    assert tall.flight.success and tall.flight.spec.dim == 3
    if same_rows:
        assert_same_mission(flat.flight, tall.flight)
        return
    assert (flat.flight.steps, flat.flight.energy) == (tall.flight.steps, tall.flight.energy)
    for a, b in zip(flat.flight.records, tall.flight.records, strict=True):
        assert np.array_equal(a.state, b.state[[0, 1, 3, 4]])
        assert b.state[2] == 50.0 and b.state[5] == 0.0 and b.control[2] == 0.0


@pytest.mark.parametrize("index", range(4))
def test_with_fronts_above_the_ceiling_the_3d_verdict_is_the_2d_one(index: int) -> None:
    flat, tall = pair(index, 0, TALL)
    assert_same_verdict(flat, tall, same_rows=True)


def test_with_drawn_fronts_taller_than_any_uav_flies_the_3d_verdict_is_the_2d_one() -> None:
    flat, tall = pair(0, 0, DRAWN)
    assert flat.verdict == FEASIBLE
    assert_same_verdict(flat, tall, same_rows=False)
    tops = {t for r in tall.flight.records for t in r.snapshot.tops_m}  # type: ignore[union-attr]
    assert tops and min(tops) >= 140.0 and len(tops) > 1  # drawn, not the ceiling's 145 m


def test_on_a_scenario_with_fronts_above_the_ceiling_the_3d_verdict_is_the_2d_one() -> None:
    extra = (("scenario", "grass-15"),)
    flat, tall = pair(0, 0, (("dim", 3), ("fire_height", "above-ceiling")), extra)
    assert_same_verdict(flat, tall, same_rows=True)


@pytest.mark.slow
def test_on_200_missions_with_tall_fronts_the_3d_verdicts_are_the_2d_ones() -> None:
    """150 missions with fronts above the ceiling, 50 with drawn heights of 140-250 m; both
    verdicts occur, so the comparison is not of one kind only."""
    seen = set()
    for i in range(200):
        tall, same = (TALL, True) if i < 150 else (DRAWN, False)
        flat, got = pair(i, 100, tall)
        assert_same_verdict(flat, got, same_rows=same)
        seen.add(flat.verdict)
    assert {FEASIBLE, IMPOSSIBLE} <= seen, seen


def three_d(settings: tuple[tuple[str, object], ...] = TALL, **fields: object) -> MissionConfig:
    return MissionConfig.named("s1", start=START, goal=GOAL, settings=settings,
                               **fields)  # type: ignore[arg-type]


def tall_corridor(closes: int) -> ScriptedFire:
    """:func:`corridor` with cuboids 145 m tall (the ceiling + ε)."""
    return ScriptedFire([ScriptedFront(f.front_id, f.box, f.born, f.dies, 145.0)
                         for f in corridor(closes).fronts])


def test_a_tall_corridor_that_closes_late_is_flown_through_in_3d() -> None:
    """test_oracle's hand bounds, in 3-D: the gap closes at sub-step 60, after the UAV is past
    the wall's east side plus d_safe (x ≥ 620 m after 40 steps), at 50 m throughout."""
    fire = tall_corridor(60)
    verdict = solve(three_d(), future=fire, fires=fire.port())
    assert verdict.verdict == FEASIBLE, verdict
    flight = verdict.flight
    assert flight is not None and flight.success and flight.spec.dim == 3
    assert flight.records[59].state[0] >= 620.0
    states = np.array([r.state for r in flight.records])
    assert states.shape[1] == 6 and np.all(states[:, 2] == 50.0) and np.all(states[:, 5] == 0.0)


def test_a_tall_corridor_that_closes_early_makes_the_3d_mission_impossible() -> None:
    """The gap closes at sub-step 25, the UAV at most 50 + 15·24 = 410 m east by then: G out
    of reach, the certificate over the whole scope (the planar one's)."""
    fire = tall_corridor(25)
    verdict = solve(three_d(), future=fire, fires=fire.port())
    assert verdict.verdict == IMPOSSIBLE, verdict
    assert verdict.reason.startswith("G out of reach")
    assert verdict.certificate is not None
    assert verdict.certificate.substeps == scope_of(three_d()).substeps


def test_a_uav_flies_no_higher_than_the_ceiling_and_braking_from_the_speed_limit() -> None:
    """By hand, the paper's values: braking from 15 m/s asks −1.05·0.8·15 = −12.6 N, clipped
    to −7.5 N: the UAV moves 15 m, its speed 0.8·15 − 7.5/1.05 = 4.857143 m/s, then stops
    after 4.857143 m more; so 120 m + 0.001 m (the monitor's allowance) + 19.857143 m."""
    assert highest_uav_m(three_d()) == pytest.approx(139.858143, abs=1e-6)
    assert lowest_top_m(three_d()) == 145.0
    assert lowest_top_m(three_d(settings=DRAWN)) == 140.0
    assert not_reduced(three_d()) == "" and not_reduced(three_d(settings=DRAWN)) == ""
    assert not_reduced(MissionConfig()) == ""


@pytest.mark.parametrize(("settings", "why"), [
    ((("dim", 3), ("fire_height", "uniform")),
     "fire_height=uniform lets a front's top (100 m) be lower than a UAV can fly (139.86 m"),
    ((("dim", 3), ("fire_height", "uniform"), ("fire_height_min_m", 139.0)),
     "fire_height=uniform lets a front's top (139 m) be lower"),
    ((("dim", 3), ("scenario", "grass-15")),
     "fire_height=plume gives fronts lower than the band"),
    ((("dim", 3), ("goal_altitude_m", 80.0)),
     "the start (50 m) and G_o (80 m) are at different altitudes"),
])
def test_other_3d_missions_do_not_reduce_to_the_plane_and_say_why(
        settings: tuple[tuple[str, object], ...], why: str) -> None:
    assert why in not_reduced(MissionConfig(settings=settings))


def test_a_mission_to_a_higher_g_o_is_judged_over_the_band() -> None:
    """G_o at 110 m under the "cube" reading (the goal box within 50 m of it: 60-120 m), the
    start at 50 m, fronts above the ceiling: the reduction does not apply, the lattice over
    the band flies a witness that climbs at least 10 m into the box, through the 3-D mission
    step, to G."""
    config = Task.of(0, 0, "s1", MissionConfig(settings=TALL + (
        ("goal_altitude_m", 110.0), ("goal_vertical", "cube")))).mission()
    assert config.spec().goal_box.z_lo == 60.0
    verdict = solve(config)
    assert verdict.verdict == FEASIBLE, verdict.reason
    flight = verdict.flight
    assert flight is not None and flight.success and flight.final_state is not None
    assert flight.final_state[2] >= 60.0 and config.spec().goal_box.contains(
        flight.final_state[:3])


def test_the_planar_twin_is_the_same_mission_in_2d() -> None:
    config = three_d(seed=5)
    twin = planar_twin(config)
    assert twin.spec().dim == 2 and twin.seed == 5
    assert twin.spec() == MissionConfig.named("s1", start=START, goal=GOAL, seed=5).spec()
    flat = MissionConfig()
    assert planar_twin(flat) is flat


@pytest.mark.parametrize("index", [21, 35])
def test_the_anatomy_of_a_3d_failure_with_tall_fronts_is_the_2d_one(index: int) -> None:
    """s1's missions 21 (no plan) and 35 (a known front) of seed 0 fail in 2-D and in 3-D
    alike; the certificate from the first sight of the front (no_escape) runs on the 3-D
    flight's state, planar twin, and finds an escape in both."""
    from dualpilot.evaluation.anatomy import classify, no_escape, replay

    flat = Task.of(index, 0, "s1", MissionConfig()).mission()
    tall = flat.with_settings(dict(TALL))
    (r2, f2), (r3, f3) = replay(flat), replay(tall)
    assert not r2.success and not r3.success and r3.spec.dim == 3
    a, b = classify(r2, f2, flat), classify(r3, f3, tall)
    assert a == b and a.cls in {"no_plan", "known_front"}
    assert no_escape(r3, tall, b.front_id) is no_escape(r2, flat, a.front_id) is False
