"""The oracle over the band (docs/three_d.md §9): the 3-D lattice search over a low wall worked
out by hand, the certificate's columns by hand and against the planar certificate where the
fronts are taller than any UAV flies, and the certificate never "impossible" where the
search flies a witness on random 3-D futures."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from dualpilot.evaluation.missions import Task
from dualpilot.mission.config import MissionConfig
from dualpilot.model.geometry import Rect
from dualpilot.oracle.certificate import certify
from dualpilot.oracle.columns import certify3, drop_failing3
from dualpilot.oracle.future import FireFuture
from dualpilot.oracle.reduction import planar_twin
from dualpilot.oracle.search3 import SearchParams3, Stage3, altitude_range, search3
from dualpilot.oracle.witness import fly_witness
from dualpilot.spacetime.plan import Stage
from tests.support.scripted_fires import ScriptedFire, ScriptedFront, moving_box

START, GOAL = (50.0, 500.0), Rect(900.0, 500.0, 100.0, 100.0)
#: fronts 5-40 m tall (the paper's process with the uniform reading)
LOW = (("dim", 3), ("fire_height", "uniform"), ("fire_height_min_m", 5.0),
       ("fire_height_max_m", 40.0))


def config(**fields: object) -> MissionConfig:
    return MissionConfig.named("s1", start=START, goal=GOAL, settings=LOW,
                               **fields)  # type: ignore[arg-type]


def wall(top: float) -> ScriptedFire:
    """A still wall x ∈ [400, 600] across the whole area, ``top`` m tall."""
    return ScriptedFire([ScriptedFront(0, moving_box(400.0, -100.0, 600.0, 1100.0),
                                       top_m=top)])


def test_a_witness_climbs_over_a_low_wall_the_plane_cannot_pass() -> None:
    """A 35 m wall across the area: at the start's 50 m the UAV is 15 m above it, within
    d_safe = 20 m, so it must fly over at 35 + 20 + 0.05 (the margin) = 55.05 m or more: on
    the lattice (50 + 5·k m) 60 m. The two levels are 50 and 60 m (altitude_range). From rest
    x = 850 m needs 55 flights (0, 7.1, 20, 35, then 15 m a flight), and the climb costs none
    of them. The witness flies through the 3-D mission step to G; the same wall 145 m tall
    (above the ceiling) leaves no way: the columns' certificate says impossible."""
    fire = wall(35.0)
    assert altitude_range(config(), np.array([35.0]), "two", 5.0, 20.05) == (0, 2)
    found = search3(config(), fire.cuboids())
    assert found.witness is not None, found
    states = found.witness.states
    assert states.shape[1] == 6
    over = (states[:, 0] >= 400.0) & (states[:, 0] <= 600.0)
    assert over.any() and states[over, 2].min() >= 55.05
    assert set(np.round(states[:, 2], 9)) <= {50.0, 55.0, 60.0}
    flight, replay = fly_witness(config(), found.witness, fire.port())
    assert flight.success and not replay.refusals
    assert 55 <= flight.steps <= 60
    assert certify3(config(), fire.cuboids()).verdict == "reachable"
    tall = certify3(config(), wall(145.0).cuboids())
    assert tall.verdict == "impossible", tall
    assert search3(config(), wall(145.0).cuboids(), QUICK).witness is None


def test_a_column_loses_the_altitudes_every_point_of_its_cell_fails_at() -> None:
    """Cells of 10 m from the origin, the cuboid [0, 5]² × [0, 30], d = 20 m: cell (0, 0)'s
    farthest corner (10, 10) is √50 m off in the plane, so every point of it below
    30 + √(400 − 50) = 48.708 m fails; cell (0, 1) (x ∈ [10, 20]): corner (20, 10), √250 m,
    30 + √150 = 42.247 m; cell (1, 1): corner (20, 20), √450 m > 20: nothing is lost.
    A column whose top is below its new floor is empty."""
    lo, hi = np.full((2, 2), 20.0), np.full((2, 2), 100.0)
    hi[1, 0] = 40.0
    drop_failing3(lo, hi, np.array([[0.0, 0.0, 5.0, 5.0, 30.0]]), 0.0, 10.0, 20.0)
    assert lo[0, 0] == pytest.approx(30 + math.sqrt(350), abs=1e-5)
    assert lo[0, 1] == pytest.approx(30 + math.sqrt(150), abs=1e-5)
    assert lo[1, 1] == 20.0
    assert lo[1, 0] == pytest.approx(30 + math.sqrt(150), abs=1e-5) and lo[1, 0] > hi[1, 0]


def tall_pair(index: int) -> tuple[str, str, int, int]:
    tall = Task.of(index, 100, "s1", MissionConfig(settings=(("dim", 3),))).mission()
    flat = planar_twin(tall)
    a, b = certify(flat, FireFuture(flat)), certify3(tall, FireFuture(tall))
    return a.verdict, b.verdict, a.substeps, b.substeps


@pytest.mark.parametrize("index", range(3))
def test_the_columns_are_the_planar_certificate_when_every_front_is_above_the_ceiling(
        index: int) -> None:
    """Every cuboid 145 m tall, no UAV above 139.86 m: a column is lost whole where the
    planar cell is, so the verdict and its sub-step are the plane's."""
    a, b, sa, sb = tall_pair(index)
    assert (a, sa) == (b, sb)


@pytest.mark.slow
def test_the_columns_are_the_planar_certificate_on_200_tall_missions() -> None:
    assert all(a == b and sa == sb for a, b, sa, sb in map(tall_pair, range(200)))


# -- the certificate never calls a mission the search flies impossible --------------------------

AREA = 300.0
coordinate = st.floats(20.0, AREA - 20.0)


@st.composite
def small_missions(draw: st.DrawFn) -> tuple[MissionConfig, ScriptedFire]:
    """A 300 m area, a start, a goal box and up to six moving, appearing and dying cuboids
    5-100 m tall (some under the start's 50 m, some over it, some above the band)."""
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
                                    None if life is None else born + life,
                                    draw(st.floats(5.0, 100.0))))
    cfg = MissionConfig.named("s1", start=start, goal=Rect(gx, gy, 60.0, 60.0),
                              area_size_m=AREA, settings=(("max_steps", 60),) + LOW)
    return cfg, ScriptedFire(fronts)


#: a smaller search budget: the property is about the witnesses the search does find
QUICK = SearchParams3(stages=(Stage3(Stage(5.0, 20_000, weight=1.5), "two"),
                              Stage3(Stage(5.0, 20_000, weight=1.5), "band")))


def check_sound(case: tuple[MissionConfig, ScriptedFire]) -> None:
    cfg, fire = case
    spec = cfg.spec()
    start = spec.start_position
    start_clear = all(
        math.hypot(Rect(*((b[:2] + b[2:4]) / 2), *(b[2:4] - b[:2])).distance(start[:2]),
                   max(0.0, start[2] - b[4])) >= spec.d_safe_m
        for b in fire.cuboids().regions(0))
    assume(start_clear and not spec.goal.contains(spec.start))
    found = search3(cfg, fire.cuboids(), QUICK)
    cert = certify3(cfg, fire.cuboids())
    if found.witness is not None:
        flight, _ = fly_witness(cfg, found.witness, fire.port())
        assert flight.success, flight.failure_cause
        assert cert.verdict != "impossible", cert
    if cert.verdict == "impossible":
        assert found.witness is None


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(small_missions())
def test_the_columns_never_call_a_flown_witness_impossible(
        case: tuple[MissionConfig, ScriptedFire]) -> None:
    check_sound(case)


@pytest.mark.slow
@settings(max_examples=1000, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(small_missions())
def test_the_columns_never_call_a_flown_witness_impossible_on_1000_futures(
        case: tuple[MissionConfig, ScriptedFire]) -> None:
    check_sound(case)


def low_pair(index: int) -> tuple[str, str]:
    """The oracle's verdicts on mission ``index`` of seed 200 in 2-D and in 3-D over fronts
    5-40 m tall (the same rectangles)."""
    from dualpilot.oracle.oracle import solve

    low = Task.of(index, 200, "s1", MissionConfig(settings=LOW)).mission()
    flat, got = solve(planar_twin(low)), solve(low)
    assert not got.problem and (got.flight is None or got.flight.success)
    return flat.verdict, got.verdict


def assert_altitude_helps(pairs: list[tuple[str, str]]) -> None:
    """A UAV is never nearer a cuboid than its footprint, so a 2-D witness is a 3-D one and
    the columns keep at least the planar cells: 3-D impossible only where 2-D is."""
    for flat, got in pairs:
        assert not (flat == "feasible" and got == "impossible"), (flat, got)
        assert got != "impossible" or flat == "impossible", (flat, got)


def test_over_low_fronts_the_oracle_never_says_less_than_in_2d() -> None:
    assert_altitude_helps([low_pair(i) for i in range(3)])


@pytest.mark.slow
def test_over_low_fronts_the_oracle_never_says_less_than_in_2d_on_100_missions() -> None:
    assert_altitude_helps([low_pair(i) for i in range(100)])


def test_the_anatomy_names_the_front_by_its_3d_distance() -> None:
    """A UAV braking at rest at (50, 500, 50 m): front 0, 10 m tall, right under it (0 m off
    in the plane, 40 m in 3-D); front 1, born at sub-step 1, 45 m tall, 10 m off in the
    plane: √(10² + 5²) = 11.2 m < d_safe. The mission fails on front 1, and the anatomy's
    culprit is front 1 (the plane would name front 0)."""
    from dualpilot.evaluation.anatomy import culprit
    from dualpilot.oracle.search import Witness

    fire = ScriptedFire([ScriptedFront(0, moving_box(30.0, 480.0, 70.0, 520.0), top_m=10.0),
                         ScriptedFront(1, moving_box(60.0, 480.0, 100.0, 520.0), born=1,
                                       top_m=45.0)])
    port = fire.port()
    idle = Witness(np.zeros((1, 6)), np.zeros((0, 3)))  # no plan: the UAV brakes at rest
    flight, _ = fly_witness(config(), idle, port)  # START is (50, 500)
    assert not flight.success and flight.records[-1].state[2] == 50.0
    assert culprit(flight, port.snapshot(), 20.0)[0] == 1
