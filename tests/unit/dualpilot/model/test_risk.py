"""Risk zones of the fire forecast (dualpilot/model/risk.py) and the planners and supervisor
that use them (the risk-aware variants of "rrt" and "fast", threat = "forecast"), on
hand-built forecasts."""

from __future__ import annotations

import dataclasses
import json
from typing import Any

import numpy as np
import pytest

from dualpilot.evaluation.missions import mission_spec
from dualpilot.mission import monitor
from dualpilot.mission.config import MissionConfig, parse_controller
from dualpilot.mission.local import LocalFires, local_mission
from dualpilot.mission.params import Controller
from dualpilot.model.dynamics import hover_state
from dualpilot.model.fire import FireParams
from dualpilot.model.forecast import LEVELS, OccupancyForecast
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.model.risk import ArcRisk, ForecastView, RiskMap, RiskParams, cell_hulls
from dualpilot.plan import Objective
from dualpilot.planners import build_planner
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.concurrent.rule import forecast_threatened
from tests.support.missions import config_for

pytestmark = pytest.mark.timeout(120)

#: start west, goal east: the straight line y = 500 crosses the corridor box
SPEC = MissionSpec(start=(100.0, 500.0), goal=Rect(900.0, 500.0, 100.0, 100.0), seed=5)
#: a box of certain fire on the straight line, at every horizon
BOX = (400.0, 430.0, 600.0, 570.0)


def box_forecast(box: tuple[float, float, float, float] = BOX, level: int = LEVELS,
                 horizons: tuple[int, ...] = tuple(range(0, 81, 2))) -> OccupancyForecast:
    """A 10 m forecast that is ``level`` on the cells whose centres lie in ``box``, 0 elsewhere."""
    x0, y0, x1, y1 = box
    c = (np.arange(100) + 0.5) * 10.0
    grid = ((c[:, None] >= y0) & (c[:, None] <= y1) & (c[None, :] >= x0) & (c[None, :] <= x1))
    levels = np.repeat((grid * level).astype(np.uint8)[None], len(horizons), axis=0)
    return OccupancyForecast(resolution_m=10.0, substep_s=0.5, horizons=horizons, levels=levels)


def box_polytope(box: tuple[float, float, float, float] = BOX) -> Polytope:
    x0, y0, x1, y1 = box
    return Rect((x0 + x1) / 2, (y0 + y1) / 2, x1 - x0, y1 - y0).polytope()


def test_view_windows_by_hand() -> None:
    view = ForecastView(box_forecast(), substeps_per_step=10, offset_substeps=4)
    assert view.window(0) == (4, 14) and view.window(3) == (34, 44)
    assert view.last_step == 7  # step 7 starts at sub-step 74 <= 80, step 8 at 84
    fc = view.forecast
    assert fc.slices(3, 3) == range(1, 3)  # between slices 2 and 4: both stand for it
    assert fc.slices(4, 8) == range(2, 5)
    assert fc.slices(81, 90) == range(0) and fc.window(81, 90) is None


def test_threshold_is_strictly_above_alpha() -> None:
    risk = RiskMap(ForecastView(box_forecast(), 1), RiskParams(alpha=0.1))
    assert risk.threshold == 25  # 25/255 = 0.098 is not above 0.1, 26/255 = 0.102 is
    quiet = RiskMap(ForecastView(box_forecast(level=25), 1))
    assert quiet.zones(3) == ()
    loud = RiskMap(ForecastView(box_forecast(level=26), 1))
    assert len(loud.slice_zones(1)) == 1
    assert len(loud.zones(3)) == 2  # step 3's window (3, 4) stands on the slices at 2 and 4


def test_cell_hulls_by_hand() -> None:
    """An L of cells has the hull of its squares; a diagonal touch joins two cells into one
    group; apart, they are two."""
    grid = np.zeros((10, 10), dtype=bool)
    grid[2, 2:5] = True  # row 2, columns 2..4
    grid[3:5, 2] = True  # column 2, rows 3..4
    (hull,) = cell_hulls(grid, 10.0)
    expect = {(20.0, 20.0), (50.0, 20.0), (50.0, 30.0), (30.0, 50.0), (20.0, 50.0)}
    assert {tuple(v) for v in hull.vertices.tolist()} == expect
    diag = np.zeros((10, 10), dtype=bool)
    diag[1, 1] = diag[2, 2] = True
    assert len(cell_hulls(diag, 10.0)) == 1
    diag[2, 2], diag[3, 3] = False, True
    assert len(cell_hulls(diag, 10.0)) == 2
    assert cell_hulls(np.zeros((4, 4), dtype=bool), 10.0) == ()


def test_slices_with_the_same_risky_cells_share_their_zones() -> None:
    """The box forecast is the same at every horizon: every slice's zones are one tuple."""
    risk = RiskMap(ForecastView(box_forecast(), 1))
    first = risk.slice_zones(0)
    assert len(first) == 1 and all(risk.slice_zones(i) is first for i in range(1, 6))


def test_zones_cover_every_risky_cell() -> None:
    risk = RiskMap(ForecastView(box_forecast(), 1))
    (zone,) = risk.slice_zones(5)
    for x in (405.0, 595.0):
        for y in (435.0, 565.0):
            assert zone.distance(np.array([x, y])) == 0.0
    assert zone.distance(np.array([395.0, 500.0])) > 0.0


def test_arc_risk_times_a_segment_by_its_path_length() -> None:
    """A zone on the cells of [450, 550]² only in the slices at sub-steps 10 and 12: at one
    sub-step a step it stands for steps 8..13 (windows [τ, τ+1] bracketed by the slices every
    2 sub-steps), flown 84..156 m along a path at 12 m a step."""
    levels = np.zeros((41, 100, 100), dtype=np.uint8)
    levels[5:7, 45:55, 45:55] = LEVELS  # slices 5 and 6: sub-steps 10 and 12
    fc = OccupancyForecast(10.0, 0.5, tuple(range(0, 81, 2)), levels)
    risk = RiskMap(ForecastView(fc, 1))
    assert [tau for tau in range(20) if risk.zones(tau)] == list(range(8, 14))
    arc = ArcRisk(risk, speed_mps=12.0, dt_s=1.0, clearance_m=25.0)
    # (400, 500)-(600, 500) comes within 25 m of the zone 25..175 m along it
    assert not arc.segment_clear(400.0, 500.0, 600.0, 500.0, s0=0.0)  # meets steps 8..13
    assert arc.segment_clear(400.0, 500.0, 600.0, 500.0, s0=240.0)  # steps 23..35: no zone
    # a 12 m hop over the zone's centre: flown in step 11 (120..132 m), refused; in step 3, clear
    assert not arc.segment_clear(494.0, 500.0, 506.0, 500.0, s0=120.0)
    assert arc.segment_clear(494.0, 500.0, 506.0, 500.0, s0=24.0)


def _state() -> np.ndarray:
    return hover_state(np.array(SPEC.start), SPEC.dynamics)


@pytest.mark.parametrize("method", ["rrt", "rrt+du"])
def test_system1_risk_avoids_the_corridor_the_paper_planner_takes(method: str) -> None:
    box = box_polytope()
    plain = build_planner(1, SPEC, "rrt").plan(_state(), ())
    assert plain.ok and plain.path is not None
    assert box.segment_distance(plain.path[0], plain.path[-1]) == 0.0  # straight on
    risky = build_planner(1, SPEC, method, risk=True)
    assert risky.method == f"{method}+risk"
    plan = risky.plan(_state(), (), forecast=ForecastView(box_forecast(), 1))  # type: ignore[call-arg]
    assert plan.ok and plan.info["risk"] == "met" and plan.path is not None
    path_gap = min(box.segment_distance(a, b) for a, b in zip(plan.path[:-1], plan.path[1:],
                                                             strict=True))
    assert path_gap >= SPEC.clearance_m - 1e-6
    assert monitor.check(plan, _state(), (), SPEC).ok


def test_system2_risk_avoids_the_corridor_the_paper_planner_takes() -> None:
    box = box_polytope()
    plain = build_planner(2, SPEC, "fast").plan(_state(), ())
    assert plain.ok
    assert min(box.distance(p) for p in plain.states[1:, :2]) == 0.0  # through the box
    plan = build_planner(2, SPEC, "fast", risk=True).plan(  # type: ignore[call-arg]
        _state(), (), forecast=ForecastView(box_forecast(), 1))
    assert plan.ok and plan.info["risk"] == "met", plan.message
    # every planned position of steps 2..79 (the forecast's) keeps ε from the box
    gaps = [box.distance(p) for p in plan.states[2:80, :2]]
    assert min(gaps) >= SPEC.clearance_m - 1e-6
    assert monitor.check(plan, _state(), (), SPEC).ok


def test_risk_planners_keep_todays_checks_against_the_hulls() -> None:
    """A hull beside the corridor: the risk plans avoid both and pass the run-time monitor."""
    hull = Rect(500.0, 650.0, 120.0, 80.0).polytope()
    view = ForecastView(box_forecast(), 1)
    for system, method in ((1, "rrt"), (2, "fast")):
        plan = build_planner(system, SPEC, method, risk=True).plan(  # type: ignore[call-arg]
            _state(), (hull,), forecast=view)
        assert plan.ok, (method, plan.message)
        assert monitor.check(plan, _state(), (hull,), SPEC).ok
        assert min(hull.distance(p) for p in plan.states[:, :2]) >= SPEC.d_safe_m


def test_without_a_forecast_the_risk_methods_are_the_paper_methods() -> None:
    hull = Rect(500.0, 520.0, 120.0, 80.0).polytope()
    for system, base in ((1, "rrt"), (2, "fast")):
        a = build_planner(system, SPEC, base).plan(_state(), (hull,), Objective.ENERGY)
        b = build_planner(system, SPEC, base, risk=True).plan(_state(), (hull,),
                                                              Objective.ENERGY)
        assert a.ok and np.array_equal(a.states, b.states) and np.array_equal(a.controls,
                                                                             b.controls)


def test_an_unmet_chance_constraint_falls_back_to_the_paper_plan() -> None:
    """A zone over the UAV itself at every step cannot be left in time: the plan returned is
    the paper method's, and says so."""
    box = (0.0, 400.0, 250.0, 600.0)
    plain = build_planner(2, SPEC, "fast").plan(_state(), ())
    plan = build_planner(2, SPEC, "fast", risk=True).plan(  # type: ignore[call-arg]
        _state(), (), forecast=ForecastView(box_forecast(box), 1))
    assert plan.ok and str(plan.info["risk"]).startswith("unmet")
    assert np.array_equal(plan.states, plain.states)


def test_the_forecast_threat_rule() -> None:
    """A plan whose next steps run through the box is threatened on the forecast; one that
    passes 60 m south of it is not."""
    risk = RiskMap(ForecastView(box_forecast(), 1))
    s1 = build_planner(1, SPEC, "rrt")
    through = s1.plan(_state(), ())
    x_near = hover_state(np.array([330.0, 500.0]), SPEC.dynamics)
    near = build_planner(1, SPEC, "rrt").plan(x_near, ())
    assert not forecast_threatened(through, risk, SPEC.clearance_m, 10)  # 10 steps: not there
    assert forecast_threatened(near, risk, SPEC.clearance_m, 10)
    south = hover_state(np.array([330.0, 345.0]), SPEC.dynamics)
    other = build_planner(1, MissionSpec(start=(330.0, 345.0), goal=Rect(900.0, 345.0, 100.0,
                                                                          100.0)), "rrt")
    assert not forecast_threatened(other.plan(south, ()), risk, SPEC.clearance_m, 10)


def test_controller_names() -> None:
    assert parse_controller("concurrent+risk") == (Controller.CC, "concurrent",
                                                   True)
    assert parse_controller("s2+risk") == (Controller.S2, "paper", True)
    assert parse_controller("cc") == (Controller.CC, "paper", False)
    assert MissionConfig.named("concurrent+risk").concurrent.threat == "forecast"


def test_the_forecast_never_moves_the_fire_stream() -> None:
    """Fronts ignite anywhere (today): the fires of an S2 mission and an S2+risk mission are
    the same step for step, and a forecast leaves the fire stream where it was."""
    spec = mission_spec(0, 3)
    fires = LocalFires(spec, FireParams())
    for t in range(5):
        fires.advance(t, 3, None)
    before = fires.rng.bit_generator.state
    fires.forecast(10)
    assert fires.rng.bit_generator.state == before
    plain = local_mission(config_for(spec, "s2")).run()
    risky = local_mission(config_for(spec, "s2+risk")).run()
    n = min(len(plain.records), len(risky.records))
    assert n > 3
    for a, b in zip(plain.records[:n], risky.records[:n], strict=True):
        assert a.snapshot.regions == b.snapshot.regions


def test_the_step_asks_for_the_forecast_only_for_risk_aware_planners() -> None:
    """Paper timing: a System 1 step is ⌈0.155 / 0.5⌉ = 1 sub-step, a System 2 step 10; the
    paper's planners are never sent a forecast (none is made)."""
    spec = mission_spec(0, 1)
    for risk in (False, True):
        mission = local_mission(config_for(spec, "cc+risk" if risk else "cc"))
        assert mission.forecast_systems == (frozenset({1, 2}) if risk else frozenset())
        seen: list[tuple[int, int | None]] = []
        planners = mission.planners
        ask = planners.plan

        def spy(request, ask=ask, seen=seen):  # type: ignore[no-untyped-def]
            view = request.forecast
            seen.append((request.system, None if view is None else view.substeps_per_step))
            return ask(request)

        planners.plan = spy  # type: ignore[method-assign]
        for _ in range(6):
            mission.step()
        assert seen
        want = {1: 1, 2: 10} if risk else {1: None, 2: None}
        assert all(n == want[s] for s, n in seen), seen


def test_the_monitor_refuses_a_plan_that_says_it_met_the_zones_and_does_not() -> None:
    """The paper plan runs straight through the box: said to have met the zones, the monitor
    finds its p_τ inside them (distance 0); the honest risk plan and a plan that says it did
    not meet them pass (the hulls' checks still hold for every plan)."""
    view = ForecastView(box_forecast(), 1)
    plain = build_planner(2, SPEC, "fast").plan(_state(), ())
    liar = dataclasses.replace(plain, info={**plain.info, "risk": "met"})
    verdict = monitor.check_risk(liar, view, SPEC)
    assert not verdict.ok and verdict.clearance_m == 0.0 and "risk zone" in verdict.reason
    unmet = dataclasses.replace(plain, info={**plain.info, "risk": "unmet (no plan)"})
    assert monitor.check_risk(unmet, view, SPEC).ok
    assert monitor.check_risk(liar, None, SPEC).ok  # no forecast sent: nothing promised
    honest = build_planner(2, SPEC, "fast", risk=True).plan(  # type: ignore[call-arg]
        _state(), (), forecast=view)
    ok = monitor.check_risk(honest, view, SPEC)
    assert ok.ok and ok.clearance_m >= SPEC.clearance_m - 1e-6


def test_the_monitor_refuses_a_system1_plan_that_misstates_its_distance() -> None:
    view = ForecastView(box_forecast(), 1)
    honest = build_planner(1, SPEC, "rrt", risk=True).plan(  # type: ignore[call-arg]
        _state(), (), forecast=view)
    assert honest.info["risk"] == "met" and monitor.check_risk(honest, view, SPEC).ok
    said = float(honest.info["risk_clearance_m"])  # type: ignore[arg-type]
    liar = dataclasses.replace(honest, info={**honest.info, "risk_clearance_m": said + 5.0})
    verdict = monitor.check_risk(liar, view, SPEC)
    assert not verdict.ok and verdict.clearance_m == pytest.approx(said)
    missing = dataclasses.replace(honest, info={"risk": "met"})
    assert not monitor.check_risk(missing, view, SPEC).ok


@pytest.mark.slow
def test_the_records_and_mission_mcap_show_the_zones_each_plan_was_made_against(
        tmp_path: Any) -> None:
    """grass-15, seed 1, concurrent+risk: each flown step's note holds the zones of the view
    its plan was made on (recomputed here), and mission.mcap draws them and the next slice."""
    from integration.foxglove_check import read_mcap

    from dualpilot.mission.records import record_from_json, record_to_json
    from dualpilot.viz.foxglove import write_mcap

    config = MissionConfig.named("concurrent+risk", seed=1, profile="today",
                                 settings=(("scenario", "grass-15"),))
    result = local_mission(config).run()
    noted = [r for r in result.records if r.risk is not None]
    assert len(noted) > 10 and any(r.risk.zones for r in noted)  # type: ignore[union-attr]
    for r in noted:
        assert r.risk is not None and r.risk.alpha == monitor.PLANNER_RISK.alpha
        assert r.risk.heat is None or len(r.risk.heat.horizons) == 1
        back = record_from_json(json.loads(json.dumps(record_to_json(r))))
        assert back.risk is not None and len(back.risk.zones) == len(r.risk.zones)
    rec = read_mcap(write_mcap(result, tmp_path))
    risk = rec.messages["/uav1/risk"]
    assert len(risk) == len(result.records)
    by_t = {int(r.t): r for r in result.records}
    for _, update in risk:
        if update.entities:
            t = int(next(kv.value for kv in update.entities[0].metadata if kv.key == "step"))
            assert len(update.entities) == len(by_t[t].risk.zones)  # type: ignore[union-attr]
    assert len(rec.messages["/uav1/forecast"]) == sum(
        1 for r in noted if r.risk is not None and r.risk.heat is not None)
