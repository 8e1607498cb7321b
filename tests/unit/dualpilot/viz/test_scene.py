"""The live view's plain data (dualpilot/viz/scene.py), values worked out by hand."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from dualpilot.mission.answers import format_answers, parse_answers, statuses_by_system
from dualpilot.model.fire import FireSnapshot
from dualpilot.model.forecast import OccupancyForecast
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.plan import Objective
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.paper.decision import Decision
from dualpilot.viz import scene


def test_a_rectangle_is_its_four_corners_counter_clockwise_from_south_west() -> None:
    # centre (100, 200), 40 m wide (east), 20 m high (north)
    assert scene.rect_outline(Rect(100, 200, 40, 20)).tolist() == [
        [80, 190], [120, 190], [120, 210], [80, 210]]


def test_circle_points_start_due_east_and_turn_counter_clockwise() -> None:
    assert np.allclose(scene.circle(np.array([10.0, 20.0]), 5.0, n=4),
                       [[15, 20], [10, 25], [5, 20], [10, 15]])


def test_area_view_has_the_goal_corners_and_start() -> None:
    spec = MissionSpec()  # area 1000 m, start (50, 50), goal centred (900, 900), 100 m sides
    v = scene.area_view(spec)
    assert v.size_m == spec.area_size_m
    assert v.start.tolist() == list(spec.start)
    assert v.goal.tolist() == [[850, 850], [950, 850], [950, 950], [850, 950]]


def test_fire_view_keeps_front_ids_birth_steps_and_every_hull() -> None:
    hull = Polytope.from_vertices(np.array([[0.0, 0.0], [10.0, 0.0], [5.0, 8.0]]))
    extinct = Polytope.from_vertices(np.array([[50.0, 50.0], [60.0, 50.0], [55.0, 58.0]]))
    snap = FireSnapshot(regions=(Rect(5, 3, 4, 2),), hulls=(hull, extinct), front_ids=(7,),
                        born_steps=(3,))
    v = scene.fire_view(snap)
    assert v.regions[0].tolist() == [[3, 2], [7, 2], [7, 4], [3, 4]]
    assert (v.front_ids, v.born_steps) == ((7,), (3,))
    assert len(v.hulls) == 2 and v.hulls[1].tolist() == extinct.vertices.tolist()


@pytest.mark.parametrize(("text", "want"), [
    ("s1:ok", {1: "ok"}),
    ("s2:timeout;s1:ok", {2: "timeout", 1: "ok"}),
    ("s1:unsafe[monitor: speed 16 > 15, area];s2:infeasible",
     {1: "unsafe[monitor: speed 16 > 15, area]", 2: "infeasible"}),
    ("s2:launched;s1:ok;s2:adopted", {2: "launched;adopted", 1: "ok"}),
    ("", {}),
])
def test_plan_statuses_split_the_step_text_by_system(text: str, want: dict[int, str]) -> None:
    answers = parse_answers(text)
    assert format_answers(answers) == text  # the record's text, read back
    got = statuses_by_system(answers)
    assert got == want and list(got) == list(want)  # in the order asked


def test_plan_views_give_the_flown_system_its_positions_and_the_other_none() -> None:
    pts = np.array([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]])
    s1, s2 = scene.plan_views(parse_answers("s2:timeout;s1:ok"), 1, pts)
    assert (s1.system, s1.status, s1.flown, s1.positions.tolist()) == (
        1, "ok", True, pts.tolist())
    assert (s2.system, s2.status, s2.flown, s2.positions.shape) == (2, "timeout", False, (0, 2))
    braked = scene.plan_views(parse_answers("s1:no_path"), 0, np.empty((0, 2)))
    assert [(v.status, v.flown, len(v.positions)) for v in braked] == [
        ("no_path", False, 0), ("", False, 0)]


def test_decision_doc_is_json_with_d_t_null_when_no_region_counts() -> None:
    d = Decision(t=4, d_t=math.inf, xi=np.array([1.5, 2.0, 3.0]),
                 p=np.array([0.2, 0.3, 0.5]), attention=3, psi=np.array([0.25, 0.75]),
                 system=2, objective=Objective.ENERGY)
    doc = scene.decision_doc(d, commanded=2, flown=1, time_s=24.5)
    assert doc == {"t": 4, "time_s": 24.5, "d_t_m": None, "xi": [1.5, 2.0, 3.0],
                   "p": [0.2, 0.3, 0.5], "attention": 3, "psi": [0.25, 0.75], "system": 2,
                   "commanded_system": 2, "flown_system": 1, "objective": "energy"}
    assert scene.decision_doc(replace(d, d_t=12.5), 2, 2, 0.0)["d_t_m"] == 12.5
    assert [scene.commanded_system(c, d) for c in ("cc", "s1", "s2")] == [2, 1, 2]


def test_forecast_slices_spread_evenly_keeping_the_first_and_last() -> None:
    assert scene.forecast_slices(41) == [0, 10, 20, 30, 40]
    assert scene.forecast_slices(3) == [0, 1, 2]
    assert scene.forecast_slices(9, most=3) == [0, 4, 8]
    assert scene.forecast_slices(0) == []


def test_occupancy_view_interleaves_the_chosen_slices_cell_by_cell() -> None:
    # 3 horizons (0, 2, 4 sub-steps of 0.5 s) on a 2 x 3 grid; keep 2 slices: the first, last
    levels = np.array([[[1, 2, 3], [4, 5, 6]],
                       [[0, 0, 0], [0, 0, 0]],
                       [[7, 8, 9], [10, 11, 12]]], dtype=np.uint8)
    fc = OccupancyForecast(resolution_m=10.0, substep_s=0.5, horizons=(0, 2, 4),
                           levels=levels, origin_m=(100.0, 200.0))
    v = scene.occupancy_view(fc, most=2)
    assert (v.origin_m, v.resolution_m, v.rows, v.cols) == ((100.0, 200.0), 10.0, 2, 3)
    assert v.horizons_s == (0.0, 2.0)
    # row 0 (south) first, cell by cell: (slice 0, slice 2) of each cell
    assert v.data == bytes([1, 7, 2, 8, 3, 9, 4, 10, 5, 11, 6, 12])


def test_event_lines() -> None:
    assert scene.step_text(3, 2, "s2:ok") == "step 3: S2 flew; plans s2:ok"
    assert scene.step_text(4, 0, "s1:no_path", "braking: no OK plan") == (
        "step 4: braked (no OK plan); plans s1:no_path; braking: no OK plan")
    assert scene.end_text(True, "", 56) == "mission ended after 56 steps: goal reached"
    assert scene.end_text(False, "fire_contact", 9) == (
        "mission ended after 9 steps: failed (fire_contact)")
    assert scene.start_text("cc", 7, "timing=paper") == (
        "mission started: controller cc, seed 7; timing=paper")


def test_plan_views_draw_a_3d_plan_in_the_plane() -> None:
    """A 3-D plan's positions (T+1, 3) are drawn top-down: their (x, y), whatever T."""
    pts = np.array([[1.0, 2.0, 50.0], [3.0, 4.0, 55.0], [5.0, 6.0, 60.0]])
    s1, _ = scene.plan_views(parse_answers("s1:ok"), 1, pts)
    assert s1.positions.tolist() == [[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]]
