"""System 1 in 3-D (docs/three_d.md, System 1): the tree in the band, the reading
``s1_altitude``, the climb-over, the planar grid test, the LQR per axis, the reduction."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from dualpilot.evaluation.instances import make_instance
from dualpilot.mission import monitor
from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import local_mission
from dualpilot.mission.params import Timing
from dualpilot.mission.result import MissionResult
from dualpilot.model.altitude import lift_state
from dualpilot.model.dynamics import DynamicsParams, hover_state, transition_matrices
from dualpilot.model.geometry import Rect
from dualpilot.model.prism import Prism
from dualpilot.model.segment3 import SegmentChecker3
from dualpilot.plan import Objective, Plan
from dualpilot.planners import build_planner, planner_method
from dualpilot.readings import get_profile
from dualpilot.spec import MissionSpec
from dualpilot.system1.altitude import plan_in_band, slice_bases
from dualpilot.system1.lqr import lqr_gain, reference_states, track, tracker_gain
from dualpilot.system1.planner import System1, System1Params
from dualpilot.system1.reach import band_blockers, certainly_unreachable
from dualpilot.system1.rrt import RrtParams, plan_path
from dualpilot.system1.rrt3 import plan_path3
from dualpilot.verify import verify_trajectory

SPEC2 = MissionSpec()
SPEC3 = replace(SPEC2, dynamics=DynamicsParams(dim=3))
BAND = SPEC3.band
Z0 = BAND.start_altitude_m  # 50 m
TALL = SPEC3.above_ceiling_m  # 145 m: every cuboid this tall spans the band
CLEAR, D_SAFE = SPEC3.clearance_m, SPEC3.d_safe_m  # 25 m, 20 m
#: a wall of fire 40 m tall across the whole area between the start and G: the slice at
#: 50 m (within 25 m of its top) has no path, the air above 65 m has
WALL = Prism.cuboid(Rect(500.0, 450.0, 1000.0, 100.0), 0.0, 40.0)


def s1(spec: MissionSpec, seed: int = 0, **kw: object) -> System1:
    return System1(spec, System1Params(**kw), np.random.default_rng(seed))  # type: ignore[arg-type]


def independent_check(plan: Plan, prisms: tuple[Prism, ...]) -> None:
    """Eq. (1), the limits, the band and the exact 3-D clearance of every segment, the last
    by the prisms' own distances (not the planner's checker)."""
    assert plan.ok, plan.message
    assert plan.states.shape == (81, 6) and plan.controls.shape == (80, 3)
    v = verify_trajectory(plan.states, plan.controls, prisms, SPEC3.dynamics, D_SAFE, band=BAND)
    assert v.ok, v.reason
    pts = plan.states[:, :3]
    d = min((p.segment_distance(a, b) for p in prisms for a, b in zip(pts[:-1], pts[1:],
                                                                       strict=True)),
            default=np.inf)
    assert d >= D_SAFE - 1e-3


# -- the LQR per axis -----------------------------------------------------------------------------
@pytest.mark.parametrize("r_delta_u", [None, 100.0])
def test_the_3d_gain_is_the_planar_scalars_on_every_axis(r_delta_u: float | None) -> None:
    k3 = tracker_gain(SPEC3.dynamics, 2.0, 0.1, r_delta_u)
    k2 = tracker_gain(SPEC2.dynamics, 2.0, 0.1, r_delta_u)
    blocks = k3.shape[1] // 3
    assert k3.shape == (3, 3 * blocks) and k2.shape == (2, 2 * blocks)
    for b in range(blocks):  # the same floats, k·I on every axis
        np.testing.assert_array_equal(k3[:, 3 * b:3 * b + 3], k2[0, 2 * b] * np.eye(3))
    if r_delta_u is None:  # and the 6×6 DARE's gain to rounding (its own solve)
        phi, gamma = transition_matrices(SPEC3.dynamics)
        p = solve_discrete_are(phi, gamma, 2.0 * np.eye(6), 0.1 * np.eye(3))
        k = np.linalg.solve(0.1 * np.eye(3) + gamma.T @ p @ gamma, gamma.T @ p @ phi)
        np.testing.assert_allclose(k3, k, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("speed_limit", ["axis", "norm"])
@pytest.mark.parametrize("du", [False, True])
def test_the_3d_lqr_tracks_the_planar_axes_bit_for_bit(speed_limit: str, du: bool) -> None:
    rng = np.random.default_rng(3)
    dyn2 = DynamicsParams(speed_limit=speed_limit)  # type: ignore[arg-type]
    dyn3 = replace(dyn2, dim=3)
    r = 100.0 if du else None
    k2, k3 = tracker_gain(dyn2, 2.0, 0.1, r), tracker_gain(dyn3, 2.0, 0.1, r)
    for _ in range(100):
        path2 = np.cumsum(rng.uniform(-80.0, 120.0, size=(int(rng.integers(2, 6)), 2)), axis=0)
        x2 = np.concatenate([path2[0], rng.uniform(-12.0, 12.0, 2)])
        z = float(rng.uniform(20.0, 120.0))
        # under "axis" the z axis is independent: let it climb; under "norm" it stays put
        vz = float(rng.uniform(-5.0, 5.0)) if speed_limit == "axis" else 0.0
        x3 = np.array([x2[0], x2[1], z, x2[2], x2[3], vz])
        path3 = np.column_stack([path2, np.full(len(path2), z)])
        ref2 = reference_states(path2, 80, 12.0, dyn2, 3.0)
        ref3 = reference_states(path3, 80, 12.0, dyn3, 3.0)
        np.testing.assert_array_equal(ref3[:, [0, 1, 3, 4]], ref2)
        u_prev = rng.uniform(-3.0, 3.0, 2)
        kw2 = {"prev_control": u_prev} if du else {}
        kw3 = {"prev_control": np.append(u_prev, 0.0)} if du else {}
        s2, c2 = track(x2, ref2, k2, dyn2, **kw2)  # type: ignore[arg-type]
        s3, c3 = track(x3, ref3, k3, dyn3, **kw3)  # type: ignore[arg-type]
        np.testing.assert_array_equal(s3[:, [0, 1, 3, 4]], s2)
        np.testing.assert_array_equal(c3[:, :2], c2)
        if speed_limit == "norm":
            assert np.all(s3[:, 2] == z) and np.all(c3[:, 2] == 0.0)


# -- the tree in the band -------------------------------------------------------------------------
def test_the_slice_has_no_path_through_the_low_wall() -> None:
    start = np.array([50.0, 50.0])
    bases = slice_bases((WALL,), Z0, CLEAR)
    assert len(bases) == 1  # 50 m lies within 25 m of the wall's 40 m top
    assert slice_bases((WALL,), 66.0, CLEAR) == ()  # 66 m does not
    res = plan_path(start, SPEC2.goal, bases, np.random.default_rng(0), CLEAR, 1000.0,
                    start_clearance_m=D_SAFE)
    assert res.status == "unreachable" and res.path is None


@pytest.mark.parametrize("try_direct", [True, False])
def test_a_3d_path_crosses_above_the_low_wall(try_direct: bool) -> None:
    p = np.array([50.0, 50.0, Z0])
    res = plan_path3(p, SPEC3.goal_box, (WALL,), np.random.default_rng(1), CLEAR, 1000.0, BAND,
                     RrtParams(try_direct=try_direct), start_clearance_m=D_SAFE)
    assert res.found and res.path is not None, res.status
    path = res.path
    np.testing.assert_array_equal(path[0], p)
    assert SPEC3.goal_box.contains(path[-1])
    assert np.all((path[:, 2] >= BAND.floor_m) & (path[:, 2] <= BAND.ceiling_m))
    assert res.status == ("direct" if try_direct else "exact")
    # every segment keeps the clearance from the wall, by the prism's own exact distance
    assert min(WALL.segment_distance(a, b) for a, b in zip(path[:-1], path[1:], strict=True)) \
        >= CLEAR - 1e-9
    # where the ground track is over the wall the path is 25 m above its top
    xy_over = [(a + t * (b - a)) for a, b in zip(path[:-1], path[1:], strict=True)
               for t in np.linspace(0, 1, 50) if WALL.base.contains((a + t * (b - a))[:2])]
    assert xy_over and min(q[2] for q in xy_over) >= 40.0 + CLEAR - 1e-9


def test_system1_flies_over_the_low_wall_and_the_plan_verifies() -> None:
    x = hover_state(np.array([50.0, 50.0, Z0]), SPEC3.dynamics)
    for altitude in ("slice-first", "volume"):
        plan = s1(SPEC3, 4, altitude=altitude).plan(x, (WALL,))
        independent_check(plan, (WALL,))
        assert plan.states[:, 2].max() >= 40.0 + D_SAFE
        assert plan.path is not None and plan.path.shape[1] == 3


def test_slice_first_keeps_the_altitude_when_the_slice_has_a_path() -> None:
    block = Prism.cuboid(Rect(650.0, 650.0, 200.0, 200.0), 0.0, 30.0)  # 30 m: in the slice
    x = hover_state(np.array([50.0, 50.0, Z0]), SPEC3.dynamics)
    plan = s1(SPEC3, 5).plan(x, (block,))
    independent_check(plan, (block,))
    assert plan.path is not None and np.all(plan.path[:, 2] == Z0)
    assert np.all(plan.states[:, 2] == Z0) and np.all(plan.controls[:, 2] == 0.0)


def test_the_grid_test_takes_only_the_prisms_that_span_the_band() -> None:
    tall = replace(WALL, z_hi=TALL)
    assert band_blockers((WALL, tall), BAND) == (tall.base,)
    start = np.array([50.0, 50.0])
    # the low wall blocks the ground track but not the band: "a path may exist"
    assert not certainly_unreachable(start, SPEC2.goal, band_blockers((WALL,), BAND), CLEAR,
                                     1000.0)
    assert certainly_unreachable(start, SPEC2.goal, band_blockers((tall,), BAND), CLEAR, 1000.0)
    p = np.array([50.0, 50.0, Z0])
    res = plan_in_band(p, (tall,), np.random.default_rng(0), SPEC3, RrtParams(), "volume")
    assert res.status == "unreachable"


def test_a_risk_aware_plan_does_not_leave_the_slice() -> None:
    class _NoZones:  # an ArcRisk with no zone anywhere
        def segment_clear(self, *a: float) -> bool:
            return True

    p = np.array([50.0, 50.0, Z0])
    res = plan_in_band(p, (WALL,), np.random.default_rng(0), SPEC3, RrtParams(),
                       "slice-first", risk=_NoZones())  # type: ignore[arg-type]
    assert not res.found and res.status == "unreachable"  # the slice's answer


# -- the reduction: fires taller than the band ----------------------------------------------------
def _reduction_case(index: int, seed: int) -> None:
    inst = make_instance(index, seed, 1 + index % 6)
    prisms = tuple(Prism(h, 0.0, TALL) for h in inst.hulls)
    x2 = inst.state
    a, b = s1(SPEC2, index), s1(SPEC3, index)
    for _ in range(2):  # a fresh plan, then (the UAV 5 steps on) a reused or fresh one
        p2 = a.plan(x2, inst.hulls)
        p3 = b.plan(lift_state(x2, Z0), prisms)
        assert (p3.status, p3.message) == (p2.status, p2.message)
        assert p3.info.get("rrt_iterations") == p2.info.get("rrt_iterations")
        if not p2.ok:
            return
        np.testing.assert_array_equal(p3.states[:, [0, 1, 3, 4]], p2.states)
        np.testing.assert_array_equal(p3.controls[:, :2], p2.controls)
        assert np.all(p3.states[:, 2] == Z0) and np.all(p3.states[:, 5] == 0.0)
        assert np.all(p3.controls[:, 2] == 0.0)
        assert p3.path is not None and p2.path is not None
        np.testing.assert_array_equal(p3.path[:, :2], p2.path)
        assert p3.info["clearance_m"] == p2.info["clearance_m"]
        x2 = p2.states[5]


@pytest.mark.parametrize("index", range(12))
def test_tall_fires_give_the_2d_plans_bit_for_bit(index: int) -> None:
    _reduction_case(index, 11)


@pytest.mark.slow
def test_tall_fires_give_the_2d_plans_bit_for_bit_on_200_instances() -> None:
    for index in range(200):
        _reduction_case(index, 12)


# -- "volume": the 3-D tree at once ---------------------------------------------------------------
def _volume_case(index: int, seed: int) -> tuple[bool, bool]:
    """(planned, climbed) of one random instance with fires of random heights."""
    inst = make_instance(index, seed, 1 + index % 6)
    rng = np.random.default_rng([seed, index])
    prisms = tuple(Prism(h, 0.0, float(rng.choice([rng.uniform(5.0, 60.0), TALL])))
                   for h in inst.hulls)
    x = lift_state(inst.state, Z0)
    plan = s1(SPEC3, index, altitude="volume").plan(x, prisms)
    if not plan.ok:
        return False, False
    independent_check(plan, prisms)
    return True, bool(np.ptp(plan.states[:, 2]) > 1.0)


@pytest.mark.parametrize("index", range(10))
def test_volume_plans_verify(index: int) -> None:
    _volume_case(index, 21)


@pytest.mark.slow
def test_volume_plans_verify_on_200_instances() -> None:
    results = [_volume_case(index, 22) for index in range(200)]
    planned = sum(p for p, _ in results)
    climbed = sum(c for _, c in results)
    assert planned >= 150 and climbed >= 20, (planned, climbed)


# -- operator waypoints, the registry, the reading ------------------------------------------------
def test_operator_waypoints_keep_their_altitude_and_a_planar_list_flies_level() -> None:
    x = hover_state(np.array([50.0, 50.0, Z0]), SPEC3.dynamics)
    planner = s1(SPEC3)
    planner.set_waypoints(np.array([[300.0, 300.0, 80.0], [900.0, 900.0, 80.0]]))
    plan = planner.plan(x, ())
    assert plan.ok and plan.info["source"] == "operator"
    np.testing.assert_array_equal(plan.path, [[50.0, 50.0, Z0], [300.0, 300.0, 80.0],
                                              [900.0, 900.0, 80.0]])
    planner = s1(SPEC3)
    planner.set_waypoints(np.array([[300.0, 300.0], [900.0, 900.0]]))
    plan = planner.plan(x, ())
    assert plan.ok and plan.info["source"] == "operator"
    np.testing.assert_array_equal(plan.path, [[50.0, 50.0, Z0], [300.0, 300.0, Z0],
                                              [900.0, 900.0, Z0]])
    with pytest.raises(ValueError, match="band"):
        planner.set_waypoints(np.array([[300.0, 300.0, 130.0]]))
    with pytest.raises(ValueError, match="shape"):
        s1(SPEC2).set_waypoints(np.array([[300.0, 300.0, 80.0]]))


def test_system1_methods_plan_in_2d_and_3d() -> None:
    for name in ("rrt", "rrt+du"):
        assert planner_method(name).dims == frozenset({2, 3})
        for risk in (False, True):
            planner = build_planner(1, SPEC3, name, risk=risk)
            assert planner.system == 1
    x = hover_state(np.array([50.0, 50.0, Z0]), SPEC3.dynamics)
    with pytest.raises(ValueError, match="prisms"):
        s1(SPEC3).plan(x, (WALL.base,))  # type: ignore[arg-type]
    assert s1(SPEC2).gain.shape == (2, 4) and s1(SPEC3).gain.shape == (3, 6)
    np.testing.assert_array_equal(s1(SPEC2).gain, lqr_gain(SPEC2.dynamics)[0])


def test_the_reading_s1_altitude_reaches_system1() -> None:
    assert get_profile("today-3d").readings()["s1_altitude"] == "slice-first"
    config = MissionConfig.named("s1", settings={"dim": "3", "s1_altitude": "volume"})
    assert config.system1_params().altitude == "volume"
    assert MissionConfig.named("s1").system1_params() == System1Params()
    with pytest.raises(ValueError, match="s1_altitude"):
        MissionConfig.named("s1", settings={"s1_altitude": "up"})
    with pytest.raises(ValueError, match="altitude"):
        System1Params(altitude="up")  # type: ignore[arg-type]


def test_checker3_is_what_the_planner_verifies_with() -> None:
    # a plan of the low wall, checked again with a freshly built SegmentChecker3
    x = hover_state(np.array([50.0, 50.0, Z0]), SPEC3.dynamics)
    plan = s1(SPEC3, 7).plan(x, (WALL,))
    assert plan.ok
    v = verify_trajectory(plan.states, plan.controls, (WALL,), SPEC3.dynamics, D_SAFE,
                          checker=SegmentChecker3((WALL,)), band=BAND)
    assert v.ok and v.clearance_m >= D_SAFE


# -- missions -------------------------------------------------------------------------------------
class _Checked(System1):
    """System 1 whose every plan is checked again, independently, against what it was given."""

    def __init__(self, spec: MissionSpec, params: System1Params):
        super().__init__(spec, params)
        self.ok = 0
        self.refused: list[str] = []

    def plan(self, state, hulls, objective=Objective.MISSION_TIME,  # type: ignore[no-untyped-def]
             prev_control=None) -> Plan:
        plan = super().plan(state, hulls, objective, prev_control)
        if plan.ok:
            self.ok += 1
            v = verify_trajectory(plan.states, plan.controls, hulls, self.spec.dynamics,
                                  self.spec.d_safe_m, band=self.spec.band)
            m = monitor.check(plan, state, hulls, self.spec)
            np.testing.assert_array_equal(plan.states[0], state)
            if not (v.ok and m.ok):
                self.refused.append(f"{v.reason}; {m.reason}")
        return plan


def _fly(config: MissionConfig) -> tuple[_Checked, MissionResult]:
    spec = config.spec()
    planner = _Checked(spec, config.system1_params())
    mission = local_mission(config, {1: planner})
    return planner, mission.run()


@pytest.mark.parametrize("profile, settings", [("today", {"dim": "3"}), ("today-3d", {}),
                                               ("today-3d", {"s1_altitude": "volume"})])
def test_a_3d_s1_mission_flies_to_its_end_and_every_plan_passes_the_check(
        profile: str, settings: dict[str, str]) -> None:
    config = MissionConfig.named("s1", seed=26, timing=Timing.PAPER, profile=profile,
                                 settings=settings)
    planner, result = _fly(config)
    assert result.ending is not None and planner.ok > 10
    assert planner.refused == []
    if settings.get("s1_altitude") != "volume":  # tall fires: the 2-D mission, flown at 50 m
        two_d = local_mission(MissionConfig.named("s1", seed=26, timing=Timing.PAPER)).run()
        assert (result.ending, result.steps, result.energy) == (two_d.ending, two_d.steps,
                                                                two_d.energy)
        for r3, r2 in zip(result.records, two_d.records, strict=True):
            np.testing.assert_array_equal(r3.state[[0, 1, 3, 4]], r2.state)
            assert r3.state[2] == Z0 and r3.state[5] == 0.0


@pytest.mark.slow
@pytest.mark.parametrize("altitude", ["slice-first", "volume"])
def test_3d_s1_missions_over_low_grass_fires(altitude: str) -> None:
    climbs = 0
    for seed in (0, 4, 26):
        config = MissionConfig.named("s1", seed=seed, timing=Timing.PAPER, profile="today-3d",
                                     settings={"scenario": "grass-15", "s1_altitude": altitude})
        planner, result = _fly(config)
        assert result.ending is not None and planner.ok > 0
        assert planner.refused == []
        climbs += max(r.state[2] for r in result.records) > Z0 + 1.0
    if altitude == "volume":  # the tree uses the air above the 31 m grass fires
        assert climbs >= 2
