"""A 3-D mission's altitude figure (dualpilot/viz/altitude.py): the side view's data worked out
by hand on a two-step record, and the figure written for a 3-D run and only for one."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle

from dualpilot.mission.answers import Answer, SystemStatus
from dualpilot.mission.records import write_all
from dualpilot.mission.result import Ending, MissionResult, StepRecord
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.model.fire import FireSnapshot
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.plan import Objective
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.paper.decision import Decision
from dualpilot.viz import altitude
from dualpilot.viz import mission as plots
from tests.unit.dualpilot.viz.test_plots import ALL_FIGURES, scripted_run


def two_steps() -> dict[str, Any]:
    """A trace.json document of two steps: at t = 0 three fronts, two within 20 m of the UAV
    (at 10 m each: 30 m and 45 m tall) and one 190 m away; at t = 1 one front 80 m away."""
    return {
        "altitude": {"floor_m": 20.0, "ceiling_m": 120.0, "start_m": 50.0, "goal_m": 50.0,
                     "goal_box_m": [20.0, 120.0]},
        "goal": [900.0, 900.0, 100.0, 100.0], "area_size_m": 1000.0,
        "final_position": [120.0, 100.0, 58.0],
        "steps": [
            {"t": 0, "system": 1, "position": [100.0, 100.0, 50.0],
             "plan": [[100.0, 100.0, 50.0], [110.0, 100.0, 55.0], [120.0, 100.0, 60.0]],
             "regions": [[130.0, 100.0, 40.0, 20.0], [100.0, 85.0, 10.0, 10.0],
                         [100.0, 300.0, 20.0, 20.0]],
             "tops": [30.0, 45.0, 90.0]},
            {"t": 1, "system": 0, "position": [110.0, 100.0, 55.0], "plan": [],
             "regions": [[200.0, 100.0, 20.0, 20.0]], "tops": [60.0]},
        ],
    }


def test_rect_distance() -> None:
    assert altitude.rect_distance(0.0, 0.0, [13.0, 14.0, 6.0, 8.0]) == pytest.approx(
        math.sqrt(200.0))  # 10 m east and 10 m north of the nearest corner
    assert altitude.rect_distance(30.0, 0.0, [30.0, 0.0, 2.0, 2.0]) == 0.0  # inside
    assert altitude.rect_distance(0.0, 0.0, [30.0, 0.0, 20.0, 20.0]) == 20.0  # on d_safe


def test_side_view_of_two_steps() -> None:
    sv = altitude.side_view(two_steps())
    assert list(sv.t) == [0.0, 1.0, 2.0]  # the two steps, then the final position
    assert list(sv.flown_m) == [50.0, 55.0, 58.0]
    assert len(sv.plans) == 1  # t = 1 braked: no plan
    system, ts, zs = sv.plans[0]
    assert system == 1 and list(ts) == [0.0, 1.0, 2.0] and list(zs) == [50.0, 55.0, 60.0]
    assert list(sv.step_t) == [0.0, 1.0]
    assert sv.fire_top_m[0] == 45.0 and math.isnan(sv.fire_top_m[1])  # the taller near one
    assert sv.fire_region == ([100.0, 85.0, 10.0, 10.0], [])
    assert (sv.floor_m, sv.ceiling_m) == (20.0, 120.0)
    # a wider reach takes the front 80 m away in
    assert list(altitude.side_view(two_steps(), near_m=80.0).fire_top_m) == [45.0, 60.0]


def test_no_side_view_in_2d() -> None:
    doc = two_steps()
    del doc["altitude"]
    with pytest.raises(ValueError, match="a 2-D run has no altitude"):
        altitude.side_view(doc)


def xs(line: Line2D) -> list[float]:
    return [float(v) for v in np.asarray(line.get_xdata(), dtype=float)]


def ys(line: Line2D) -> list[float]:
    return [float(v) for v in np.asarray(line.get_ydata(), dtype=float)]


def run_3d(out: Path) -> Path:
    """Hand-made records of a 3-D mission: three steps climbing 50 → 56 → 62 m, ending at
    68 m; a 30 m front under the UAV at t = 1 only."""
    spec = MissionSpec(dynamics=DynamicsParams(dim=3))
    front = Rect(140.0, 100.0, 40.0, 40.0)
    hull = Polytope.from_vertices(front.corners())
    records = []
    for t in range(3):
        pos = np.array([100.0 + 40.0 * t, 100.0, 50.0 + 6.0 * t])
        snap = (FireSnapshot((front,), (hull,), (0,), (1,), (30.0,), (30.0,)) if t == 1
                else FireSnapshot((), ()))
        dec = Decision(t=t, d_t=math.inf, xi=np.ones(3), p=np.ones(3) / 3, attention=1,
                       psi=np.array([0.4, -0.4]), system=1, objective=Objective.MISSION_TIME)
        records.append(StepRecord(
            t=t, state=np.concatenate([pos, [40.0, 0.0, 6.0]]), control=np.zeros(3),
            decision=dec, system=1, answers=(Answer(1, SystemStatus.OK),), planning_time_s=0.1,
            fire_substeps=1, d_t=math.inf, fires_active=len(snap.regions),
            planned_positions=np.array([pos, pos + [40.0, 0.0, 6.0]]), snapshot=snap,
            time_s=float(t)))
    final = np.array([220.0, 100.0, 68.0, 40.0, 0.0, 6.0])
    write_all(MissionResult(controller="s1", timing="paper", spec=spec, steps=3,
                            records=records, final_state=final, ending=Ending.STEP_LIMIT,
                            sim_time_s=3.0), out)
    return out


def test_a_3d_run_gets_its_altitude_figure(tmp_path: Path) -> None:
    run = run_3d(tmp_path / "r3")
    paths = plots.make_figures(run)
    assert {p.name for p in paths} == ALL_FIGURES | {altitude.FIG_ALTITUDE}
    assert (run / altitude.FIG_ALTITUDE).stat().st_size > 5_000
    fig = plots.figure_altitude(plots.load_run(run))
    top, side, bar = fig.axes  # the two panels and the colour bar
    assert bar.get_ylabel() == "flown altitude (m)"
    track = next(c for c in top.collections if isinstance(c, LineCollection))
    # each segment coloured by the mean of its ends' altitudes: 50/56, 56/62, 62/68 m
    assert np.asarray(track.get_array()).tolist() == [53.0, 59.0, 65.0]
    assert track.norm.vmin == 50.0 and track.norm.vmax == 68.0
    bars = [p for p in side.patches if isinstance(p, Rectangle)]
    assert [b.get_height() for b in bars] == [30.0]  # the one front under the UAV
    assert (bars[0].get_x(), bars[0].get_width()) == (0.5, 1.0)  # t = 1, one step wide
    plans, flown, floor, ceiling = side.lines[:3], side.lines[3], side.lines[4], side.lines[5]
    assert [ys(ln) for ln in plans] == [[50.0, 56.0], [56.0, 62.0], [62.0, 68.0]]
    assert [xs(ln) for ln in plans] == [[0.0, 1.0], [1.0, 2.0], [2.0, 3.0]]
    assert xs(flown) == [0.0, 1.0, 2.0, 3.0]  # the final position at t = 3
    assert ys(flown) == [50.0, 56.0, 62.0, 68.0]
    assert ys(floor) == [20.0, 20.0] and ys(ceiling) == [120.0, 120.0]
    assert side.get_ylim() == (0.0, pytest.approx(120.0 * 1.08))  # the band, the 30 m front in it


def test_a_front_above_the_band_is_drawn_whole(tmp_path: Path) -> None:
    doc = two_steps()
    doc["steps"][0]["tops"] = [30.0, 145.0, 90.0]  # the near front taller than the ceiling
    fig = Figure()
    altitude.draw_altitude(fig, doc)
    side = fig.axes[1]
    assert [p.get_height() for p in side.patches if isinstance(p, Rectangle)] == [145.0]
    assert side.get_ylim() == (0.0, pytest.approx(145.0 * 1.08))


def test_a_2d_run_gets_the_five_figures_as_before(tmp_path: Path) -> None:
    run = scripted_run(tmp_path / "r2")
    assert {p.name for p in plots.make_figures(run)} == ALL_FIGURES
    assert not (run / altitude.FIG_ALTITUDE).exists()
    with pytest.raises(ValueError, match="a 2-D run has no altitude"):
        plots.figure_altitude(plots.load_run(run))
