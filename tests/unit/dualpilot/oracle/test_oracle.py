"""The oracle on missions whose answer is known by hand, and its certificate against its own
witnesses on random small missions."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from dualpilot.mission.config import MissionConfig
from dualpilot.model.geometry import Rect
from dualpilot.oracle.certificate import certify, scope_of
from dualpilot.oracle.oracle import FEASIBLE, IMPOSSIBLE, solve
from dualpilot.oracle.search import SearchParams, search
from dualpilot.oracle.witness import fly_witness
from dualpilot.spacetime.plan import Stage
from tests.support.scripted_fires import ScriptedFire, ScriptedFront, moving_box

START, GOAL = (50.0, 500.0), Rect(900.0, 500.0, 100.0, 100.0)


def config(**fields: object) -> MissionConfig:
    return MissionConfig.named("s1", start=START, goal=GOAL, **fields)  # type: ignore[arg-type]


def wall(speed: float) -> ScriptedFire:
    """A fire across the whole area, its east edge at x = −200 + speed·s after s sub-steps."""
    return ScriptedFire([ScriptedFront(0, moving_box(-1200.0, -100.0, -200.0, 1100.0, speed))])


def corridor(closes: int) -> ScriptedFire:
    """A wall x ∈ [400, 600] across the area with a gap y ∈ [440, 560], filled from sub-step
    ``closes`` on."""
    return ScriptedFire([
        ScriptedFront(0, moving_box(400.0, -100.0, 600.0, 440.0)),
        ScriptedFront(1, moving_box(400.0, 560.0, 600.0, 1100.0)),
        ScriptedFront(2, moving_box(400.0, 440.0, 600.0, 560.0), born=closes),
    ])


def test_a_fire_wall_faster_than_the_uav_cannot_be_outrun() -> None:
    """By hand: during sub-step s the UAV is at most 50 + 15·(s − 1) m east (one step a
    sub-step at most, 15 m a step), the wall's edge at 40·s − 200; the UAV is within
    d_safe = 20 m of it from 25·s ≥ 215, s = 9, on, and G lies 800 m east."""
    fire = wall(40.0)
    verdict = solve(config(), future=fire, fires=fire.port())
    assert verdict.verdict == IMPOSSIBLE, verdict
    assert verdict.certificate is not None
    assert verdict.reason.startswith("no position survives")
    assert verdict.certificate.substeps <= 9


def test_a_fire_wall_slower_than_the_uav_is_outrun() -> None:
    """10 m a sub-step against the UAV's 15 m: the oracle's witness flies to G (flown by the
    mission step against the same fires), in no fewer steps than the hand bound: from rest
    the UAV covers 0, 7.1, 20, 35, then 15 m more a step, so x = 850 needs 55 steps."""
    fire = wall(10.0)
    verdict = solve(config(), future=fire, fires=fire.port())
    assert verdict.verdict == FEASIBLE, verdict
    assert verdict.flight is not None and verdict.flight.success
    assert 55 <= verdict.flight.steps <= 60


def test_a_corridor_that_closes_late_enough_is_flown_through() -> None:
    """The gap closes at sub-step 60; the UAV is past x = 620 after 40 steps (35 + 15·36 m
    from rest), so the straight line through the gap works: feasible, and the witness is
    east of the wall (x ≥ 620) when the gap closes."""
    fire = corridor(60)
    verdict = solve(config(), future=fire, fires=fire.port())
    assert verdict.verdict == FEASIBLE, verdict
    assert verdict.flight is not None
    x_when_closed = verdict.flight.records[59].state[0]
    assert x_when_closed >= 620.0


def test_a_corridor_that_closes_early_makes_the_mission_impossible() -> None:
    """The gap closes at sub-step 25: the UAV is then at most 50 + 15·24 = 410 m east, short
    of the wall's far side plus d_safe (620 m), and the wall stays: G is out of reach."""
    fire = corridor(25)
    verdict = solve(config(), future=fire, fires=fire.port())
    assert verdict.verdict == IMPOSSIBLE, verdict
    assert verdict.reason.startswith("G out of reach")
    assert verdict.certificate is not None
    assert verdict.certificate.substeps == scope_of(config()).substeps


def test_an_open_area_is_feasible_and_the_certificate_sees_g() -> None:
    fire = ScriptedFire([])
    verdict = solve(config(), future=fire, fires=fire.port())
    assert verdict.verdict == FEASIBLE
    assert certify(config(), fire).verdict == "reachable"


# -- the certificate never calls a mission the oracle flies impossible --------------------------

AREA = 300.0
coordinate = st.floats(20.0, AREA - 20.0)


@st.composite
def small_missions(draw: st.DrawFn) -> tuple[MissionConfig, ScriptedFire]:
    """A 300 m area, a start, a goal box and up to six moving, appearing and dying boxes."""
    start = (draw(coordinate), draw(coordinate))
    gx, gy = draw(st.floats(40.0, AREA - 40.0)), draw(st.floats(40.0, AREA - 40.0))
    fronts = []
    for k in range(draw(st.integers(0, 6))):
        x, y = draw(coordinate), draw(coordinate)
        w, h = draw(st.floats(20.0, 250.0)), draw(st.floats(20.0, 250.0))
        vx, vy = draw(st.floats(-20.0, 20.0)), draw(st.floats(-20.0, 20.0))
        born = draw(st.integers(0, 20))
        life = draw(st.one_of(st.none(), st.integers(1, 40)))
        fronts.append(ScriptedFront(k, moving_box(x - w / 2, y - h / 2, x + w / 2, y + h / 2,
                                                  vx, vy), born,
                                    None if life is None else born + life))
    cfg = MissionConfig.named("s1", start=start, goal=Rect(gx, gy, 60.0, 60.0),
                              area_size_m=AREA, settings=(("max_steps", 60),))
    return cfg, ScriptedFire(fronts)


#: a smaller search budget: the property is about the witnesses the search does find
QUICK = SearchParams(stages=(Stage(5.0, 20_000, weight=1.5), Stage(2.5, 20_000, weight=1.5)))


@settings(max_examples=150, suppress_health_check=[HealthCheck.too_slow])
@given(small_missions())
def test_the_certificate_never_calls_a_flown_witness_impossible(
        case: tuple[MissionConfig, ScriptedFire]) -> None:
    cfg, fire = case
    spec = cfg.spec()
    start_clear = all(Rect(*((b[:2] + b[2:]) / 2), *(b[2:] - b[:2])).distance(spec.start)
                      >= spec.d_safe_m for b in fire.regions(0))
    assume(start_clear and not spec.goal.contains(spec.start))
    found = search(cfg, fire, QUICK)
    cert = certify(cfg, fire)
    if found.witness is not None:
        flight, _ = fly_witness(cfg, found.witness, fire.port())
        assert flight.success, flight.failure_cause
        assert cert.verdict != IMPOSSIBLE, cert
    if cert.verdict == IMPOSSIBLE:
        assert found.witness is None


@pytest.mark.parametrize("scenario", ["", "grass-15"])
def test_on_the_missions_own_fires_the_witness_flies_and_is_not_called_impossible(
        scenario: str) -> None:
    """Three evaluation missions of seed 0 (today's reading; and grass-15): a witness is found,
    flies to G on the mission's own fire process, and the certificate does not contradict it."""
    from dualpilot.evaluation.missions import Task
    from dualpilot.oracle.future import FireFuture

    settings_ = (("scenario", scenario),) if scenario else ()
    for i in range(3):
        cfg = Task.of(i, 0, "s1", MissionConfig(settings=settings_)).mission()
        verdict = solve(cfg)
        assert verdict.verdict == FEASIBLE, (i, verdict.reason)
        assert verdict.flight is not None and verdict.flight.success
        assert np.isclose(verdict.flight.mission_time_s, verdict.flight.steps * 1.0)
        assert certify(cfg, FireFuture(cfg)).verdict != IMPOSSIBLE
