"""The forecast's risk zones with heights in 3-D (dualpilot/model/zone_heights.py, the
reading ``risk_zone_height``): the heights by hand, every consumer of the zones reading the
same ones (the run-time monitor's ``check_risk``, the concurrent supervisor's forecast
threat rule, "fast+risk"), and "fire" over fronts taller than the band giving the "band"
zones exactly."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dualpilot.mission import monitor
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.model.forecast import LEVELS, OccupancyForecast
from dualpilot.model.geometry import Rect
from dualpilot.model.plume import fire_top_m
from dualpilot.model.prism import Prism
from dualpilot.model.risk import (
    ForecastView,
    RiskMap,
    RiskParams,
    group_max_levels,
    path_risk_clearance,
    risk_map,
)
from dualpilot.model.vertical import VerticalParams, head_fire
from dualpilot.model.zone_heights import BAND, ZoneHeights
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.readings import get_profile
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.concurrent.rule import forecast_threatened
from dualpilot.system1.planner import RiskSystem1
from dualpilot.system2.fast.risk import RiskSystem2

pytestmark = pytest.mark.timeout(60)

#: start west, goal east at 50 m (3-D)
SPEC3 = MissionSpec(start=(100.0, 500.0), goal=Rect(900.0, 500.0, 100.0, 100.0), seed=5,
                    dynamics=DynamicsParams(dim=3))
#: fronts U[10, 40] m tall: a zone of cells of P = 1 is 40 − 0.1 · 30 = 37 m tall at α = 0.1
UNIFORM = ZoneHeights(uniform=(10.0, 40.0))
FIRE3 = dataclasses.replace(SPEC3, zone_heights=UNIFORM)


def grid_forecast(cells: dict[tuple[int, int], int], horizons: tuple[int, ...] = (0, 80)
                  ) -> OccupancyForecast:
    """A 10 m forecast of 100 × 100 cells, ``cells[(row, column)]`` its level, 0 elsewhere."""
    grid = np.zeros((100, 100), dtype=np.uint8)
    for (r, c), level in cells.items():
        grid[r, c] = level
    levels = np.repeat(grid[None], len(horizons), axis=0)
    return OccupancyForecast(resolution_m=10.0, substep_s=0.5, horizons=horizons, levels=levels)


def wall_forecast(x0: float, x1: float, y0: float = 0.0, y1: float = 1000.0,
                  level: int = LEVELS) -> OccupancyForecast:
    """Certain fire (``level``) on the cells whose centres lie in [x0, x1] × [y0, y1]."""
    c = (np.arange(100) + 0.5) * 10.0
    return grid_forecast({(int(r), int(k)): level for r in range(100) for k in range(100)
                          if y0 <= c[r] <= y1 and x0 <= c[k] <= x1})


def test_a_zone_under_a_uniform_law_is_as_tall_as_its_highest_cell() -> None:
    """z* = hi − (α/P)(hi − lo) with lo = 10, hi = 40, α = 0.1: P = 1 → 37 m, 0.4 → 32.5 m,
    0.2 → 25 m; a group takes its highest cell's."""
    assert UNIFORM.top_for(1.0, 0.1) == pytest.approx(37.0, abs=1e-12)
    assert UNIFORM.top_for(0.4, 0.1) == pytest.approx(32.5, abs=1e-12)
    assert UNIFORM.top_for(0.2, 0.1) == pytest.approx(25.0, abs=1e-12)
    assert UNIFORM.top_for(0.2, 0.05) == pytest.approx(32.5, abs=1e-12)
    with pytest.raises(ValueError, match="alpha < P"):
        UNIFORM.top_for(0.1, 0.1)  # not a risky cell
    # group A: cells (10, 10) at P = 0.2 and (10, 11) at P = 1; group B: (50, 50) at 0.4
    fc = grid_forecast({(10, 10): 51, (10, 11): 255, (50, 50): 102})
    view = ForecastView(fc, 1)
    assert group_max_levels(fc.level(0), 25).tolist() == [255, 102]
    zones = RiskMap(view, RiskParams(0.1), UNIFORM).slice_zones(0)
    flat = RiskMap(view, RiskParams(0.1)).slice_zones(0)
    prisms = [z for z in zones if isinstance(z, Prism)]
    assert len(prisms) == len(zones) == len(flat) == 2
    assert [p.z_hi for p in prisms] == pytest.approx([37.0, 32.5], abs=1e-12)
    for prism, base in zip(prisms, flat, strict=True):
        assert prism.z_lo == 0.0 and prism.base is base
    assert prisms[0].base.contains(np.array([105.0, 105.0]))  # group A's footprint
    assert ZoneHeights(top_m=10.7).top_for(0.2, 0.1) == 10.7
    assert BAND.planar and not UNIFORM.planar and RiskMap(view).slice_zones(0) == flat


def test_the_mission_reads_the_zones_heights_from_its_readings() -> None:
    """"band" (the default) and every 2-D mission: zones as tall as every altitude; "fire":
    the fronts' reading's heights."""
    base = MissionSpec()
    today = get_profile("today")
    assert today.altitude.risk_zone_height == "band"
    assert today.spec(base).zone_heights == BAND
    assert today.with_settings({"dim": "3"}).spec(base).zone_heights == BAND
    assert today.with_settings({"risk_zone_height": "fire"}).spec(base).zone_heights == BAND
    fire3 = today.with_settings({"dim": "3", "risk_zone_height": "fire"})
    assert fire3.spec(base).zone_heights == ZoneHeights(top_m=145.0)  # ceiling 120 + ε 25
    uniform = fire3.with_settings({"fire_height": "uniform", "fire_height_min_m": "10",
                                   "fire_height_max_m": "40"})
    assert uniform.spec(base).zone_heights == UNIFORM
    grass = fire3.with_settings({"scenario": "grass-5"})
    top = grass.spec(base).zone_heights.top_m
    assert top == fire_top_m(*head_fire("grass-5"))
    assert top == pytest.approx(10.7, abs=0.05)  # docs/three_d.md's table, grass-5's head fire
    assert fire3.with_settings({"scenario": "grass-5", "fire_height": "above-ceiling"}).spec(
        base).zone_heights == ZoneHeights(top_m=145.0)
    with pytest.raises(ValueError, match="risk_zone_height must be one of"):
        VerticalParams(risk_zone_height="sky")  # type: ignore[arg-type]


def level_plan(z: float, system: int = 2, said: float | None = None) -> Plan:
    """A plan along y = 500 at altitude ``z`` (m), 10 m a step from x = 300 (T = 40): over
    [400, 600] at τ = 10..30; it says it met the zones."""
    T = 40
    states = np.zeros((T + 1, 6))
    states[:, 0] = 300.0 + 10.0 * np.arange(T + 1)
    states[:, 1], states[:, 2], states[:, 3] = 500.0, z, 5.0
    info: dict[str, object] = {"risk": "met"}
    if said is not None:
        info["risk_clearance_m"] = said
    return Plan(system=system, status=PlanStatus.OK, states=states, controls=np.zeros((T, 3)),
                compute_time_s=0.0, info=info)


def test_a_plan_over_a_low_zone_is_accepted_under_fire_and_refused_under_band() -> None:
    """A wall of certain fire over x ∈ [400, 600]: its zone is 37 m tall under the uniform
    law. Flown at 70 m it keeps 70 − 37 = 33 m ≥ ε = 25 m: accepted by ``check_risk`` and
    not threatened by the concurrent supervisor's rule under "fire"; under "band" the zone
    is as tall as every altitude, 0 m away: refused by both. At 55 m (18 m) both refuse."""
    view = ForecastView(wall_forecast(400.0, 600.0), 1)
    over = level_plan(70.0)
    ok = monitor.check_risk(over, view, FIRE3)
    assert ok.ok and ok.clearance_m == pytest.approx(33.0, abs=1e-9)
    band = monitor.check_risk(over, view, SPEC3)
    assert not band.ok and band.clearance_m == 0.0 and "forecast risk zone" in band.reason
    low = monitor.check_risk(level_plan(55.0), view, FIRE3)
    assert not low.ok and low.clearance_m == pytest.approx(18.0, abs=1e-9)
    margin = SPEC3.clearance_m
    rule = RiskParams()
    assert not forecast_threatened(over, risk_map(view, rule, FIRE3), margin, 40)
    assert forecast_threatened(over, risk_map(view, rule, SPEC3), margin, 40)
    assert forecast_threatened(level_plan(55.0), risk_map(view, rule, FIRE3), margin, 40)
    # System 1's reported distance is measured the same way: 33 m under "fire", 0 under "band"
    said = path_risk_clearance(risk_map(view, rule, FIRE3), over.states[:, :3])
    assert said == pytest.approx(33.0, abs=1e-9)
    one = level_plan(70.0, system=1, said=said)
    assert monitor.check_risk(one, view, FIRE3).ok
    assert not monitor.check_risk(one, view, SPEC3).ok  # it keeps 0 m from the footprint


def test_fast_risk_flies_over_a_low_zone_that_the_monitor_then_accepts() -> None:
    """A wall of certain fire across the whole area: no plan goes around it. Under "fire"
    (37 m zones) "fast+risk" meets the chance constraint by climbing to 62 m (37 + ε) and
    crossing, and ``check_risk`` accepts the plan; under "band" it meets it by stopping
    ε short of the wall at its altitude."""
    view = ForecastView(wall_forecast(400.0, 600.0), 1)
    x0 = np.array([250.0, 500.0, 50.0, 5.0, 0.0, 0.0])
    plan = RiskSystem2(FIRE3).plan(x0, (), Objective.MISSION_TIME, None, forecast=view)
    assert plan.ok and plan.info["risk"] == "met", plan.info
    assert monitor.check_risk(plan, view, FIRE3).ok
    x = plan.states[:, 0]
    over = (x >= 400.0 - 25.0) & (x <= 600.0 + 25.0)  # within ε of the wall's footprint
    assert over.any() and x[-1] > 625.0  # it crosses
    assert float(plan.states[over, 2].min()) >= 62.0 - 1e-6
    band = RiskSystem2(SPEC3).plan(x0, (), Objective.MISSION_TIME, None, forecast=view)
    assert band.ok and band.info["risk"] == "met" and monitor.check_risk(band, view, SPEC3).ok
    assert float(band.states[2:, 0].max()) <= 375.0 + 1e-6  # it stops ε short of the wall
    assert float(np.ptp(band.states[:, 2])) == 0.0  # at 50 m


@pytest.mark.parametrize(("x0", "low"), [
    ([200.0, 480.0, 50.0, 5.0, 0.0, 0.0], False),  # at G_o's altitude, at rest vertically
    ([200.0, 480.0, 50.0, 5.0, 0.0, 0.0], True),  # a low front: the 3-D method
    ([200.0, 480.0, 50.0, 5.0, 1.0, 2.0], True),  # climbing
    ([150.0, 300.0, 60.0, 4.0, 3.0, -1.0], True),
    ([300.0, 700.0, 45.0, 6.0, -2.0, 0.5], True),
])
def test_fire_over_fronts_taller_than_the_band_gives_the_band_zones_exactly(
        x0: list[float], low: bool) -> None:
    """Zones ceiling + ε tall ("fire" with "above-ceiling" fronts): the zones are prisms over
    the "band" footprints, and "fast+risk"'s plan, ``check_risk``'s verdict and clearance and
    System 1's measured distance are the "band" ones bit for bit (a low front on the way too)."""
    tall = dataclasses.replace(SPEC3, zone_heights=ZoneHeights(top_m=SPEC3.above_ceiling_m))
    view = ForecastView(wall_forecast(450.0, 560.0, 380.0, 620.0), 1)
    flat = RiskMap(view, RiskParams(), BAND)
    prisms = risk_map(view, RiskParams(), tall)
    assert all(isinstance(p, Prism) and p.base is b and p.spans(SPEC3.band)
               for p, b in zip(prisms.zones(3), flat.zones(3), strict=True))
    fronts = (Prism.cuboid(Rect(600.0, 300.0, 80.0, 80.0), 0.0, 20.0),) if low else ()
    state = np.array(x0)
    a = RiskSystem2(SPEC3).plan(state, fronts, Objective.MISSION_TIME, None, forecast=view)
    b = RiskSystem2(tall).plan(state, fronts, Objective.MISSION_TIME, None, forecast=view)
    assert a.status == b.status and a.ok, a.message
    assert b.info.get("reduction", False) is not low and b.info["risk_zones"] == 2
    free = RiskSystem2(tall).plan(state, fronts, Objective.MISSION_TIME, None)
    assert not np.array_equal(free.states, b.states)  # the zones bite
    assert np.array_equal(a.states, b.states) and np.array_equal(a.controls, b.controls)
    assert a.cost == b.cost and a.info["risk"] == b.info["risk"]
    va, vb = monitor.check_risk(a, view, SPEC3), monitor.check_risk(b, view, tall)
    assert va == vb
    assert (path_risk_clearance(flat, a.states[:, :3])
            == path_risk_clearance(prisms, a.states[:, :3]))


def test_system1_risk_plans_in_a_slice_above_a_low_zone() -> None:
    """"rrt+risk" at 70 m over a wall of certain fire 37 m tall ("fire"): its slice keeps
    33 m ≥ ε from the zones, so it meets them, reports the distance ``check_risk`` measures
    and is accepted; under "band" the wall blocks the slice ("unmet": the plain plan)."""
    view = ForecastView(wall_forecast(400.0, 600.0), 1)
    x0 = np.array([250.0, 500.0, 70.0, 0.0, 0.0, 0.0])
    plan = RiskSystem1(FIRE3).plan(x0, (), Objective.MISSION_TIME, None, forecast=view)
    assert plan.ok and plan.info["risk"] == "met", plan.info
    said = plan.info["risk_clearance_m"]
    assert isinstance(said, float) and said >= SPEC3.clearance_m
    assert said == path_risk_clearance(risk_map(view, RiskParams(), FIRE3), plan.states[:, :3])
    assert monitor.check_risk(plan, view, FIRE3).ok
    band = RiskSystem1(SPEC3).plan(x0, (), Objective.MISSION_TIME, None, forecast=view)
    assert str(band.info["risk"]).startswith("unmet"), band.info
