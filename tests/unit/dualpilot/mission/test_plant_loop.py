"""The plant in the mission loop: the ideal plant flies today's missions bit for bit, a flight
that leaves its plan's segment breaches d_safe as ``tracking_breach``, and the plant's
readings resolve to the margins and tolerances their formulas give."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from dualpilot.evaluation.missions import COLUMNS, Task
from dualpilot.evaluation.stats import summarize
from dualpilot.mission.config import MissionConfig
from dualpilot.mission.flight import PlantVehicle, judge_flight, plan_stream
from dualpilot.mission.local import LocalFires, LocalPlanners, LocalVehicle, local_mission
from dualpilot.mission.monitor import check_plan
from dualpilot.mission.result import Ending
from dualpilot.mission.step import Mission, MissionPorts
from dualpilot.model.dynamics import Array, DynamicsParams, hover_state, rollout, step
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.plant import IdealPlant, MultirotorPlant, PlantParams
from dualpilot.plant.reading import PlantReading, auto_margin_m, measurement_tol, plant_params
from dualpilot.spec import MissionSpec, Stream, stream_rng
from tests.support.scripted_fires import ScriptedFire, ScriptedFront, moving_box

MULTIROTOR = (("plant", "multirotor"), ("tracking_margin_m", 0.0))


# -- the ideal plant through the step -----------------------------------------------------------
@pytest.mark.parametrize("controller", ["cc", "concurrent"])
@pytest.mark.parametrize("index", [0, 1, 3])
def test_the_ideal_plant_flies_the_mission_of_today_bit_for_bit(controller: str,
                                                                index: int) -> None:
    """A mission whose vehicle is the ideal plant behind the flight hook (PlantVehicle,
    judge_flight, the true position) records the very states, controls and ending of
    today's vehicle (Eq. (1), LocalVehicle)."""
    config = Task.of(index, 0, controller).mission()
    today = local_mission(config)
    assert isinstance(today.vehicle, LocalVehicle)
    expected = today.run()
    spec = config.spec()
    assert spec == config.spec() and spec.tracking_margin_m == 0.0
    assert spec.measurement_tol == 0.0 and spec.flight_d_safe_m == spec.d_safe_m == 20.0
    from dualpilot.planners import build_planners

    planners = build_planners(spec, config.methods(), risk=config.risk,
                              system2_params=config.system2_params())
    state = hover_state(np.array(spec.start), spec.dynamics)
    vehicle = PlantVehicle(IdealPlant(state, spec.dynamics))
    ports = MissionPorts(LocalFires(spec, config.reading().fire, config.forecast),
                         LocalPlanners(planners), vehicle)
    got = Mission(config, spec, ports, vehicle.measured()).run()
    assert got.ending is expected.ending and got.steps == expected.steps
    assert got.energy == expected.energy and got.switches == expected.switches
    assert len(got.records) == len(expected.records)
    for a, b in zip(got.records, expected.records, strict=True):
        assert np.array_equal(a.state, b.state) and np.array_equal(a.control, b.control)
        assert a.system == b.system and a.plan_status == b.plan_status
    assert got.final_state is not None and expected.final_state is not None
    assert np.array_equal(got.final_state, expected.final_state)
    # the ideal plant's path is its plan's straight segment: no tracking error
    assert all(float(e.max()) < 1e-9 for e in vehicle.tracking_error_m)


# -- a breach the plan did not make ------------------------------------------------------------
class Pushing:
    """A one-step planner: full force east from wherever it is asked (a plan of Eq. (1))."""

    system = 1
    method = "pushing"

    def __init__(self, dyn: DynamicsParams):
        self.dyn = dyn

    def plan(self, state: Array, hulls: tuple[Polytope, ...],
             objective: Objective = Objective.MISSION_TIME,
             prev_control: Array | None = None) -> Plan:
        u = np.array([[self.dyn.u_max_n, 0.0]])
        return Plan(1, PlanStatus.OK, rollout(np.asarray(state), u, self.dyn), u, 0.0)


def configured(**settings: str) -> MissionConfig:
    """The default mission with these reading settings (their text)."""
    return MissionConfig().with_settings(settings)


def pushed_mission(settings: tuple[tuple[str, object], ...], edge_x: float) -> Mission:
    """From rest at (100, 500), a plan that accelerates east towards a wall whose west face
    is at ``edge_x``; one step (max_steps = 1)."""
    config = MissionConfig.named("s1", settings=settings + (("max_steps", 1),),
                                 start=(100.0, 500.0))
    spec = config.spec()
    wall = ScriptedFire([ScriptedFront(0, moving_box(edge_x, 300.0, edge_x + 100.0, 700.0))])
    state = hover_state(np.array(spec.start), spec.dynamics)
    if config.reading().plant.plant == "ideal":
        vehicle: LocalVehicle | PlantVehicle = LocalVehicle(state, spec.dynamics)
    else:
        plant = MultirotorPlant(state, spec.dynamics, spec.rng(Stream.PLANT),
                                config.reading().plant_params())
        vehicle = PlantVehicle(plant)
    ports = MissionPorts(wall.port(), LocalPlanners({1: Pushing(spec.dynamics)}), vehicle)
    return Mission(config, spec, ports, state)


def test_a_flight_that_leaves_its_plan_breaches_d_safe_as_tracking_breach() -> None:
    """Eq. (1) from rest does not move the position in the first step (p₁ = p₀ + ΔT·v₀);
    the multirotor, flying the step's velocities, moves east. With the wall 21 m east of
    the start, the plan keeps d_safe = 20 m (the monitor accepts it) and the idle UAV too;
    the flown path comes within 20 m: the mission ends in a tracking breach. The ideal
    plant, on the same mission, reaches the step limit."""
    edge = 100.0 + 21.0
    mission = pushed_mission(MULTIROTOR, edge)
    result = mission.run()
    assert result.ending is Ending.TRACKING_BREACH, result.ending
    assert result.records[0].system == 1  # the plan was flown: the monitor accepted it
    assert isinstance(mission.vehicle, PlantVehicle)
    flight = mission.vehicle.flight
    assert flight is not None
    east = float(flight.positions[:, 0].max())
    assert edge - 20.0 < east < edge  # within d_safe of the wall, never in it
    planned = mission.vehicle.planned_path()
    assert np.allclose(planned, [[100.0, 500.0], [100.0, 500.0]])  # Eq. (1) did not move
    ideal = pushed_mission((), edge).run()
    assert ideal.ending is Ending.STEP_LIMIT


def test_a_flight_whose_plan_also_came_within_d_safe_is_fire_contact() -> None:
    """The verdict of :func:`judge_flight` by hand: the flown path within d_safe of a region
    is a tracking breach when the planned segment keeps d_safe, a fire contact when it does
    not; a path clear of every region is no ending, and leaves nothing for the straight
    segment's check."""
    dyn = DynamicsParams()
    state = np.array([100.0, 500.0, 0.0, 0.0])
    vehicle = PlantVehicle(MultirotorPlant(state, dyn, np.random.default_rng(1)))
    vehicle.command(step(state, np.array([7.5, 0.0]), dyn), np.array([7.5, 0.0]), 1.0)
    vehicle.observe()
    assert vehicle.flight is not None
    reach = float(vehicle.flight.positions[:, 0].max())
    assert reach > 101.0
    wall = (Rect(100.0 + 20.5 + 50.0, 500.0, 100.0, 400.0),)  # west face 20.5 m east
    assert judge_flight(vehicle, wall, 20.0) == (Ending.TRACKING_BREACH, ())
    near = (Rect(100.0 + 19.5 + 50.0, 500.0, 100.0, 400.0),)  # the plan too: 19.5 m
    assert judge_flight(vehicle, near, 20.0) == (Ending.FIRE_CONTACT, ())
    far = (Rect(100.0 + 40.0 + 50.0, 500.0, 100.0, 400.0),)
    assert judge_flight(vehicle, far, 20.0) == (None, ())
    today = LocalVehicle(state, dyn)
    assert judge_flight(today, wall, 20.0) == (None, wall)  # the step checks its segment


def test_the_stream_flies_the_step_s_velocities() -> None:
    """The setpoints of a step are the parabola from p_t with v_t to v_{t+1} of Eq. (1):
    its velocity ramps linearly, its acceleration is Δv/ΔT, it starts at p_t and would end
    at p_t + ΔT(v_t + v_{t+1})/2."""
    dyn = DynamicsParams()
    mr = MultirotorPlant(np.zeros(4), dyn, np.random.default_rng(0)).params
    start = np.array([10.0, 20.0, 3.0, -2.0])
    u = np.array([7.5, 3.0])
    nxt = step(start, u, dyn)
    stream = plan_stream(start, u, dyn, mr)
    n = round(dyn.dt_s * mr.setpoint_hz)
    s = np.arange(n) / mr.setpoint_hz
    a = (nxt[2:] - start[2:]) / dyn.dt_s
    assert np.allclose(stream[:, :2], start[:2] + np.outer(s, start[2:]) + 0.5 * np.outer(s**2, a))
    assert np.allclose(stream[:, 2], mr.altitude_m)
    assert np.allclose(stream[:, 3:5], start[2:] + np.outer(s, a))
    assert np.allclose(stream[:, 6:8], a)


def test_the_multirotor_picks_up_speed_in_the_loop() -> None:
    """Replanned every step from its measured state under full force east, the multirotor
    flying the step's velocities is within 25 % of Eq. (1)'s distance after 8 s."""
    dyn = DynamicsParams()
    x = np.array([100.0, 100.0, 0.0, 0.0])
    vehicle = PlantVehicle(MultirotorPlant(x, dyn, np.random.default_rng(0)))
    model = x.copy()
    u = np.array([7.5, 0.0])
    for _ in range(8):
        vehicle.command(step(vehicle.measured(), u, dyn), u, 1.0)
        vehicle.observe()
        model = step(model, u, dyn)
    flown = vehicle.true_position()[0] - 100.0
    assert flown > 0.75 * (model[0] - 100.0) > 50.0


# -- the readings -------------------------------------------------------------------------------
def test_the_auto_margin_is_gps_p99_9_plus_tracking_plus_gusts() -> None:
    """"auto": 0 for the ideal plant; else 3.717·σ + 3.0 m (+ the gust peak × 1 s)."""
    assert auto_margin_m(PlantReading()) == 0.0
    assert auto_margin_m(PlantReading(gps_sigma_m=1.5)) == 0.0  # ideal: exact and on plan
    rayleigh = math.sqrt(-2.0 * math.log(1.0 - 0.999))  # the Rayleigh quantile, by hand
    assert rayleigh == pytest.approx(3.7169, abs=1e-4)
    mr = PlantReading(plant="multirotor", gps_sigma_m=1.5, turbulence="moderate")
    assert auto_margin_m(mr) == pytest.approx(1.5 * rayleigh + 3.0)
    assert mr.margin_m() == pytest.approx(8.5754, abs=1e-4)
    gusty = replace(mr, gust_rate_per_min=2.0, gust_peak_mps=4.0)
    assert auto_margin_m(gusty) == pytest.approx(1.5 * rayleigh + 3.0 + 4.0)
    assert replace(mr, tracking_margin_m=2.5).margin_m() == 2.5


def test_the_margin_widens_what_plans_keep_not_what_the_flight_is_judged_by() -> None:
    config = configured(plant="multirotor", gps_sigma_m="1.5", turbulence="moderate")
    spec = config.spec()
    m = spec.tracking_margin_m
    assert m == pytest.approx(1.5 * 3.7169 + 3.0, abs=1e-3)
    assert spec.d_safe_m == 20.0 + m and spec.clearance_m == 25.0 + m
    assert spec.flight_d_safe_m == 20.0  # exactly
    # the velocity tube (re-anchoring's, ConcurrentParams.reanchor_tol): the Rayleigh p99.9
    # of the 0.05 m/s velocity error plus the flight's own 3.5 m/s; the position margin does
    # not touch it
    assert spec.tracking_margin_mps == pytest.approx(0.05 * 3.7169 + 3.5, abs=1e-3)
    assert spec.with_tracking_margin(0.0) == replace(
        MissionSpec(), measurement_tol=spec.measurement_tol,
        tracking_margin_mps=spec.tracking_margin_mps)
    set_by_hand = configured(plant="multirotor", tracking_margin_m="3")
    assert set_by_hand.spec().d_safe_m == 23.0 and set_by_hand.spec().clearance_m == 28.0
    with pytest.raises(ValueError, match="tracking_margin_m"):
        configured(tracking_margin_m="-1")
    with pytest.raises(ValueError, match="tracking_margin_m"):
        MissionSpec().with_tracking_margin(21.0)


def test_the_monitor_s_start_tolerance_follows_the_measurement_noise() -> None:
    """4 σ of the difference of two measurements one ΔT apart: max(σ_p√(2(1 − e^{−1/1100})),
    √2·0.05) = 0.0707 m/s at σ_p = 1.5 m → 0.283; exact measurements: 0."""
    noisy = PlantReading(plant="multirotor", gps_sigma_m=1.5)
    assert measurement_tol(noisy, 1.0) == pytest.approx(4 * math.sqrt(2) * 0.05)
    assert measurement_tol(PlantReading(plant="multirotor"), 1.0) == 0.0
    assert measurement_tol(PlantReading(gps_sigma_m=1.5), 1.0) == 0.0
    big = PlantReading(plant="multirotor", gps_sigma_m=40.0)
    assert measurement_tol(big, 1.0) == pytest.approx(4 * 40.0 * math.sqrt(2 * (1 - math.exp(
        -1.0 / 1100.0))))
    spec = configured(plant="multirotor", gps_sigma_m="1.5").spec()
    x = np.array([100.0, 100.0, 1.0, 0.0])
    plan = rollout(x, np.zeros((3, 2)), spec.dynamics)
    off = x + np.array([0.2, 0.0, 0.0, 0.1])  # a second measurement of the same state
    assert check_plan(plan, np.zeros((3, 2)), off, (), spec).ok
    assert not check_plan(plan, np.zeros((3, 2)), off, (), MissionSpec()).ok
    assert not check_plan(plan, np.zeros((3, 2)), x + 0.3, (), spec).ok


def test_the_wind_of_a_fire_scenario_is_its_own() -> None:
    p = plant_params(PlantReading(plant="multirotor"), "grass-15")
    assert p.wind.wind_speed_mps == 15.0 and p.wind.wind_dir_rad == pytest.approx(math.pi / 4)
    assert plant_params(PlantReading(plant="multirotor"), "paper").wind.wind_speed_mps == 0.0
    same = PlantReading(plant="multirotor", wind_speed_mps=15.0)
    assert plant_params(same, "grass-15").wind.wind_speed_mps == 15.0
    with pytest.raises(ValueError, match="grass-15"):
        configured(scenario="grass-15", wind_speed_mps="5")
    got = configured(plant="multirotor", wind_speed_mps="10", wind_dir_rad="1.5",
                     turbulence="severe", gust_rate_per_min="2").reading().plant_params()
    assert got == PlantParams(kind="multirotor", wind=got.wind, gps=got.gps)
    assert (got.wind.wind_speed_mps, got.wind.wind_dir_rad, got.wind.turbulence,
            got.wind.gusts.rate_per_min) == (10.0, 1.5, "severe", 2.0)
    with pytest.raises(ValueError, match="turbulence"):
        configured(turbulence="gale")


def test_the_plant_stream_is_new_and_the_others_draw_as_before() -> None:
    """The streams of the seed, worked out from their definition: fire and supervisor the
    two children of SeedSequence(seed), System 1 SeedSequence([seed, 7]); the plant's is
    SeedSequence([seed, 17]), apart from all three and from the fronts' heights (13)."""
    seed = 2968811710
    fire, sup = np.random.SeedSequence(seed).spawn(2)
    expected = {Stream.FIRE: fire, Stream.SUPERVISOR: sup,
                Stream.SYSTEM1: np.random.SeedSequence([seed, 7]),
                Stream.FIRE_HEIGHT: np.random.SeedSequence([seed, 13]),
                Stream.PLANT: np.random.SeedSequence([seed, 17])}
    draws = {}
    for s, seq in expected.items():
        got = stream_rng(seed, s).random(4)
        assert np.array_equal(got, np.random.default_rng(seq).random(4))
        draws[s] = tuple(got)
    assert len(set(draws.values())) == 5


def test_a_multirotor_mission_is_reproduced_by_its_seed() -> None:
    noisy = configured(plant="multirotor", turbulence="moderate", gps_sigma_m="1.5",
                       wind_speed_mps="5")
    config = Task.of(1, 0, "cc", noisy).mission()
    a, b = local_mission(config).run(), local_mission(config).run()
    assert a.ending is b.ending and a.steps == b.steps > 1
    assert all(np.array_equal(x.state, y.state) for x, y in zip(a.records, b.records,
                                                                strict=True))
    assert a.summary()["tracking_margin_m"] == a.spec.tracking_margin_m > 8.5  # the tube
    assert "tracking_margin_m" not in local_mission(Task.of(1, 0, "cc").mission()).result.summary()
    assert a.tracking_error_m and all(np.array_equal(x, y) for x, y in
                                      zip(a.tracking_error_m, b.tracking_error_m, strict=True))


# -- the evaluation's columns -------------------------------------------------------------------
def test_results_csv_appends_the_tracking_columns_and_old_rows_still_summarise() -> None:
    assert COLUMNS[-3:] == ["tracking_breach", "tracking_error_p50_m", "tracking_error_p99_m"]
    assert COLUMNS[:23][-2:] == ["wall_s", "error"]
    old = {"controller": "cc", "success": "0", "failure_cause": "fire_contact",
           "mission_time_s": "", "energy": "", "planning_time_s_median": "", "steps": "3",
           "fire_substeps": "4", "switches": "0", "switch_energy": "0", "error": ""}
    new = dict(old, failure_cause="tracking_breach", tracking_breach="1",
               tracking_error_p50_m="1.5", tracking_error_p99_m="4.0")
    ctrl = summarize([old], 1, "paper")["controllers"]["cc"]  # type: ignore[index]
    assert ctrl["tracking_breaches"] == 0 and math.isnan(ctrl["tracking_error_p99_m_max"])
    ctrl = summarize([old, new], 2, "paper")["controllers"]["cc"]  # type: ignore[index]
    assert ctrl["tracking_breaches"] == 1 and ctrl["tracking_error_p99_m_max"] == 4.0
    assert ctrl["failure_causes"] == {"fire_contact": 1, "tracking_breach": 1}
