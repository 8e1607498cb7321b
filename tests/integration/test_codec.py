"""The wire contract: generated code is current, and the codec converts and validates.

No processes here: these are the checks every service relies on.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dualpilot.mission.ports import PlanRequest
from dualpilot.model.dynamics import DynamicsParams, step
from dualpilot.model.fire import FireParams
from dualpilot.model.fire_field import FireField
from dualpilot.model.geometry import Polytope
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.paper.decision import DecisionDynamics
from services import protogen
from services.common import limits, mavlink_codec, rejections, wire
from services.common.convert import common as common_convert
from services.common.convert import fire as fire_convert
from services.common.convert import plan as plan_convert
from services.common.convert import supervisor as supervisor_convert
from services.common.convert import vehicle as vehicle_convert
from services.msgs import common_pb2, fire_pb2, plan_pb2, plant_pb2, supervisor_pb2
from tests.support.missions import config_for

pytestmark = pytest.mark.timeout(60)


def test_generated_messages_are_up_to_date(tmp_path: Path) -> None:
    """Regenerate from proto/ into a temporary directory: services/msgs must be identical."""
    fresh = {p.name: p.read_text() for p in protogen.generate(tmp_path)}
    committed = {p.name: p.read_text() for p in protogen.MSGS_DIR.iterdir()
                 if p.suffix in (".py", ".pyi")}
    stale = sorted(n for n in fresh if committed.get(n) != fresh[n])
    extra = sorted(set(committed) - set(fresh))
    assert not stale and not extra, (
        f"services/msgs is out of date (stale {stale}, extra {extra}): run `make proto`")


def test_every_message_has_a_header_and_enums_start_unspecified() -> None:
    from services.msgs import vehicle_pb2

    bus_messages: list[Any] = [fire_pb2.FireState, fire_pb2.FireForecast, fire_pb2.FireCommand,
                    fire_pb2.FireUpdate, plan_pb2.PlanRequest, plan_pb2.Plan,
                    supervisor_pb2.Decision, supervisor_pb2.MissionEvent,
                    vehicle_pb2.VehicleState, vehicle_pb2.OperatorWaypoints, common_pb2.Clock,
                    common_pb2.Error, plant_pb2.PlantFlightRequest, plant_pb2.PlantFlight]
    for cls in bus_messages:
        assert "header" in cls.DESCRIPTOR.fields_by_name, cls.DESCRIPTOR.full_name
    for module in (common_pb2, plan_pb2, supervisor_pb2):
        for enum in module.DESCRIPTOR.enum_types_by_name.values():
            assert enum.values[0].number == 0 and enum.values[0].name.endswith("_UNSPECIFIED")


def _fires(seed: int = 3, substeps: int = 12) -> FireField:
    rng = np.random.default_rng(seed)
    field = FireField(params=FireParams(p_survive=1.0))  # every front survives: rich hulls
    for _ in range(4):
        field.spawn(rng, 0)
    for _ in range(substeps):
        field.substep(rng, 0)
    return field


def test_fire_state_round_trip_is_exact() -> None:
    field = _fires()
    snap = field.snapshot()
    assert snap.regions, "the seed should leave some fronts alive"
    msg = fire_convert.fire_state_msg(field.fronts, field.extinct_hulls, 2, field.substeps_done,
                                        0.5, wire.Stamper("ews", "uav1"), 1.5)
    back = fire_convert.snapshot_from_msg(wire.parse(msg.SerializeToString(), fire_pb2.FireState))
    assert back.regions == snap.regions
    assert back.front_ids == snap.front_ids and back.born_steps == snap.born_steps
    for a, b in zip(back.hulls, snap.hulls, strict=True):
        assert np.array_equal(a.vertices, b.vertices)
        assert np.array_equal(a.A, b.A) and np.array_equal(a.b, b.b)


def test_fast_hull_decoding_equals_from_vertices() -> None:
    rng = np.random.default_rng(0)
    for _ in range(300):
        pts = rng.normal(size=(int(rng.integers(3, 25)), 2)) * 200 + 500
        poly = Polytope.from_vertices(pts)
        m = common_pb2.Polygon()
        common_convert.polygon_to_msg(poly, m)
        back = common_convert.polygon_from_msg(m)
        assert np.array_equal(back.A, poly.A) and np.array_equal(back.b, poly.b)
        # the same vertices in another order still decode to the same polygon (slow path)
        m2 = common_pb2.Polygon()
        m2.vertices_m.extend(np.roll(poly.vertices, 1, axis=0)[::-1].ravel().tolist())
        assert np.allclose(common_convert.polygon_from_msg(m2).vertices, poly.vertices)


def test_plan_round_trip_keeps_the_trajectory() -> None:
    dyn = DynamicsParams()
    x0 = np.array([50.0, 50.0, 1.0, -2.0])
    controls = np.array([[3.0, 1.0], [-1.0, 2.0], [0.5, -7.5]])
    states = [x0]
    for u in controls:
        states.append(step(states[-1], u, dyn))
    plan = Plan(system=2, status=PlanStatus.OK, states=np.array(states), controls=controls,
                compute_time_s=0.042, objective=Objective.ENERGY, cost=12.5,
                path=np.array([[50.0, 50.0], [900.0, 900.0]]), message="ok",
                info={"source": "mpc", "iters": np.int64(3), "arr": np.zeros(2)})
    msg = plan_convert.plan_to_msg(plan, 7, 99, wire.Stamper("system2", "uav1"))
    back = plan_convert.plan_from_msg(wire.parse(msg.SerializeToString(), plan_pb2.Plan), 2)
    assert np.array_equal(back.states, plan.states)
    assert np.array_equal(back.controls, plan.controls)
    assert back.status is PlanStatus.OK and back.objective is Objective.ENERGY
    assert back.cost == 12.5 and back.compute_time_s == 0.042
    assert back.info == {"source": "mpc", "iters": 3, "arr": [0.0, 0.0]}
    assert msg.request_seq == 99 and msg.step == 7


def test_decision_round_trip() -> None:
    sup = DecisionDynamics(np.random.default_rng(1))
    d = sup.decide(3, 120.0)
    msg = supervisor_convert.decision_to_msg(d, 2, wire.Stamper("supervisor", "uav1"), 4.5)
    back = supervisor_convert.decision_from_msg(wire.parse(msg.SerializeToString(),
                                                       supervisor_pb2.Decision))
    assert back.t == 3 and back.system == d.system and back.attention == d.attention
    assert np.array_equal(back.xi, d.xi) and np.array_equal(back.psi, d.psi)
    assert msg.commanded_system == 2
    no_fire = supervisor_convert.decision_to_msg(sup.decide(4, math.inf), 1, wire.Stamper("s", "u"),
                                             0.0)
    assert supervisor_convert.decision_from_msg(no_fire).d_t == math.inf


def _changed(msg: plan_pb2.PlanRequest, changes: dict[str, Any]) -> plan_pb2.PlanRequest:
    """``msg`` with ``changes`` applied (``a__b`` is the field b of a)."""
    for path, value in changes.items():
        obj: object = msg
        *parents, leaf = path.split("__")
        for p in parents:
            obj = getattr(obj, p)
        setattr(obj, leaf, value)
    return msg


def _request(prepare: bool = False, **changes: Any) -> plan_pb2.PlanRequest:
    """Step 0's plan request avoiding the hulls of :func:`_fires` (``prepare``: the request
    that prepares the mission, its spec and configuration), with ``changes`` applied."""
    stamper = wire.Stamper("supervisor", "uav1")
    if prepare:
        spec = MissionSpec(seed=7)
        prep = plan_convert.Prepare("m-1", 1, spec, config_for(spec), deadline_s=5.0)
        return _changed(plan_convert.prepare_msg(prep, stamper, 0.0), changes)
    req = PlanRequest(t=0, system=1, state=np.array([50.0, 50.0, 0.0, 0.0]),
                      prev_control=np.zeros(2), obstacles=_fires().snapshot().hulls,
                      objective=Objective.MISSION_TIME)
    query = plan_convert.PlanQuery(req, "m-1", 0, 5.0)
    return _changed(plan_convert.plan_query_msg(query, stamper, 0.0), changes)


def test_plan_request_round_trip() -> None:
    prep = plan_convert.plan_request_from_msg(_request(prepare=True))
    assert isinstance(prep, plan_convert.Prepare)
    assert prep.system == 1 and prep.spec == MissionSpec(seed=7) and prep.mission_id == "m-1"
    assert prep.config == config_for(MissionSpec(seed=7)) and prep.deadline_s == 5.0
    query = plan_convert.plan_request_from_msg(_request())
    assert isinstance(query, plan_convert.PlanQuery)
    req = query.request
    assert req.system == 1 and query.mission_id == "m-1" and query.deadline_s == 5.0
    assert np.array_equal(req.state, [50.0, 50.0, 0.0, 0.0]) and req.t == 0
    assert [h.vertices.tolist() for h in req.obstacles] == [
        h.vertices.tolist() for h in _fires().snapshot().hulls]


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"header__schema_version": 2}, "schema_version"),
        ({"state__east_m": math.nan}, "finite"),
        ({"state__velocity_north_mps": 1e9}, "within"),
        ({"system": 3}, "system must be 1 or 2"),
        ({"deadline_s": 0.0}, "deadline_s"),
        ({"objective": 0}, "objective"),
        ({"prev_control__east_n": math.inf}, "finite"),
    ],
)
def test_invalid_plan_requests_are_rejected(changes: dict[str, Any], match: str) -> None:
    with pytest.raises(rejections.CodecError, match=match) as info:
        plan_convert.plan_request_from_msg(wire.parse(_request(**changes).SerializeToString(),
                                                      plan_pb2.PlanRequest))
    assert info.value.code == common_pb2.ERROR_CODE_INVALID


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"mission__goal__width_m": -1.0}, "positive"),
        ({"mission__d_safe_m": 30.0}, "d_safe_m <= clearance_m"),
        ({"mission__start__east_m": -5.0}, "start"),
        ({"mission__dynamics__mass_kg": 0.0}, "dynamics"),
        ({"mission__dynamics__speed_limit": 7}, "unknown speed_limit 7"),
        ({"mission_id": "another"}, "differs from the spec"),
        ({"config__seed": 8}, "differs from its configuration"),
        ({"config__controller": 9}, "controller 9 is not one of"),
        ({"config__profile": "lenient"}, "unknown profile"),
        ({"deadline_s": math.nan}, "deadline_s"),
    ],
)
def test_invalid_prepares_are_rejected(changes: dict[str, Any], match: str) -> None:
    with pytest.raises(rejections.CodecError, match=match) as info:
        plan_convert.plan_request_from_msg(wire.parse(
            _request(prepare=True, **changes).SerializeToString(), plan_pb2.PlanRequest))
    assert info.value.code == common_pb2.ERROR_CODE_INVALID


@pytest.mark.parametrize("speed_limit", ["axis", "norm"])
def test_the_speed_limit_reading_travels_in_the_spec(speed_limit: str) -> None:
    spec = MissionSpec(seed=7, dynamics=DynamicsParams(speed_limit=speed_limit))  # type: ignore[arg-type]
    msg = plan_pb2.MissionSpec()
    plan_convert.spec_to_msg("m-1", spec, msg)
    assert msg.dynamics.speed_limit == {"axis": plan_pb2.SPEED_LIMIT_AXIS,
                                        "norm": plan_pb2.SPEED_LIMIT_NORM}[speed_limit]
    back = plan_convert.spec_from_msg(wire.parse(msg.SerializeToString(),
                                                   plan_pb2.MissionSpec))[1]
    assert back == spec and back.dynamics.speed_limit == speed_limit
    msg.dynamics.speed_limit = plan_pb2.SPEED_LIMIT_UNSPECIFIED  # a sender without the field
    assert plan_convert.spec_from_msg(msg)[1].dynamics.speed_limit == "axis"


def test_a_plan_request_needs_its_mission() -> None:
    with pytest.raises(rejections.CodecError, match="without a mission_id"):
        plan_convert.plan_request_from_msg(_request(mission_id=""))
    msg = _request()
    msg.prepare = True  # a prepare request without the spec and configuration
    with pytest.raises(rejections.CodecError, match="must carry the mission spec"):
        plan_convert.plan_request_from_msg(msg)


def _query(msg: plan_pb2.PlanRequest) -> plan_convert.PlanQuery:
    got = plan_convert.plan_request_from_msg(msg)
    assert isinstance(got, plan_convert.PlanQuery)
    return got


def test_obstacles_and_state_must_lie_near_the_area() -> None:
    plan_convert.check_in_area(_query(_request()).request, MissionSpec())
    far = _query(_request(state__east_m=2500.0))
    with pytest.raises(rejections.CodecError, match="the vehicle state"):
        plan_convert.check_in_area(far.request, MissionSpec())
    msg = _request()
    msg.obstacles[0].vertices_m[0] = 5000.0
    with pytest.raises(rejections.CodecError, match="obstacle 0"):
        plan_convert.check_in_area(_query(msg).request, MissionSpec())


def test_bad_geometry_and_sizes_are_rejected() -> None:
    msg = _request()
    msg.obstacles[0].vertices_m[:] = [0.0, 0.0, 1.0, 1.0, 2.0, 2.0]  # collinear
    with pytest.raises(rejections.CodecError, match="obstacle"):
        plan_convert.plan_request_from_msg(msg)
    msg = _request()
    msg.obstacles[0].vertices_m.append(1.0)  # odd number of coordinates
    with pytest.raises(rejections.CodecError, match="multiple of 2"):
        plan_convert.plan_request_from_msg(msg)
    msg = _request()
    for _ in range(2 * limits.MAX_FRONTS + 1):
        msg.obstacles.add()
    with pytest.raises(rejections.CodecError, match="obstacles"):
        plan_convert.plan_request_from_msg(msg)


def test_fire_commands_carry_the_area_and_the_ignition_clearance() -> None:
    reset = fire_pb2.FireCommand(mission_id="m-1")
    reset.reset.seed, reset.reset.area_size_m = 3, 800.0
    cmd = fire_convert.fire_command_from_msg(reset)
    assert (cmd.kind, cmd.seed, cmd.area_size_m) == ("reset", 3, 800.0)
    adv = fire_pb2.FireCommand(mission_id="m-1")
    adv.advance.step, adv.advance.substeps = 4, 10
    assert fire_convert.fire_command_from_msg(adv).keep_out is None
    adv.advance.keep_out.east_m, adv.advance.keep_out.north_m, adv.advance.keep_out_m = 1, 2, 20
    keep = fire_convert.fire_command_from_msg(adv).keep_out
    assert keep is not None and keep[0].tolist() == [1.0, 2.0] and keep[1] == 20.0
    adv.advance.keep_out_m = -1.0
    with pytest.raises(rejections.CodecError, match="keep_out_m"):
        fire_convert.fire_command_from_msg(adv)


def test_garbage_is_malformed_and_counted() -> None:
    before = rejections.REJECTED.by_label["PlanRequest-test"]
    with pytest.raises(rejections.CodecError) as info:
        wire.parse(b"\xff\xff\xff\x00garbage", plan_pb2.PlanRequest)
    assert info.value.code == common_pb2.ERROR_CODE_MALFORMED
    rejections.rejected("PlanRequest-test", info.value)
    assert rejections.REJECTED.by_label["PlanRequest-test"] == before + 1
    with pytest.raises(rejections.CodecError, match="expected dualpilot.v1.Plan"):
        wire.parse(b"", plan_pb2.Plan, "application/protobuf;dualpilot.v1.Decision")


def test_an_ok_plan_must_be_consistent() -> None:
    msg = plan_pb2.Plan(system=1, status=plan_pb2.PLAN_STATUS_OK, compute_time_s=0.1)
    msg.states.extend([0.0] * 8)
    msg.controls.extend([0.0] * 4)  # two controls for two states
    with pytest.raises(rejections.CodecError, match="T\\+1 states"):
        plan_convert.plan_from_msg(msg)
    with pytest.raises(rejections.CodecError, match="expected 2"):
        plan_convert.plan_from_msg(plan_pb2.Plan(system=1, status=plan_pb2.PLAN_STATUS_OK), 2)


def _plan_with(**fields: float) -> plan_pb2.Plan:
    msg = plan_pb2.Plan(system=2, status=plan_pb2.PLAN_STATUS_OK, compute_time_s=0.1)
    msg.states.extend([0.0] * 8)
    msg.controls.extend([0.0] * 2)
    for name, value in fields.items():
        setattr(msg, name, value)
    return msg


def test_a_plan_bound_and_gap_round_trip() -> None:
    plan = Plan(system=2, status=PlanStatus.OK, states=np.zeros((2, 4)),
                controls=np.zeros((1, 2)), compute_time_s=0.1, cost=110.0, bound=100.0)
    msg = plan_convert.plan_to_msg(plan, 1, 1, wire.Stamper("system2", "uav1"))
    assert msg.bound == 100.0 and msg.certified_gap == pytest.approx(0.1)
    back = plan_convert.plan_from_msg(wire.parse(msg.SerializeToString(), plan_pb2.Plan), 2)
    assert back.bound == 100.0 and back.certified_gap == pytest.approx(0.1)
    # no bound: neither field is sent
    msg2 = plan_convert.plan_to_msg(replace(plan, bound=None), 1, 1, wire.Stamper("s", "u"))
    assert not msg2.HasField("bound") and not msg2.HasField("certified_gap")


@pytest.mark.parametrize(("fields", "match"), [
    ({"cost": 1.0, "bound": 2.0}, "exceeds its cost"),
    ({"bound": 2.0}, "needs its cost"),
    ({"cost": 1.0, "bound": math.nan}, "must be finite"),
    ({"cost": 1.0, "bound": -math.inf}, "must be finite"),
    ({"cost": 2.0, "certified_gap": 0.0}, "needs its bound"),
    ({"cost": 2.0, "bound": 1.0, "certified_gap": 0.5}, "is not \\(cost − bound\\)"),
    ({"cost": 2.0, "bound": 1.0, "certified_gap": math.inf}, "must be finite"),
    ({"cost": -1.0, "bound": -2.0, "certified_gap": -0.5}, "is not \\(cost − bound\\)"),
])
def test_bad_plan_bounds_are_rejected(fields: dict[str, float], match: str) -> None:
    before = rejections.REJECTED.by_label.get("Plan-bound", 0)
    with pytest.raises(rejections.CodecError, match=match) as info:
        plan_convert.plan_from_msg(_plan_with(**fields), 2)
    rejections.rejected("Plan-bound", info.value)
    assert rejections.REJECTED.by_label["Plan-bound"] == before + 1


def test_ned_mapping_swaps_axes_and_flips_altitude() -> None:
    x = np.array([100.0, 200.0, 3.0, -4.0])  # east, north, v_east, v_north
    n, e, d, vn, ve, vd = mavlink_codec.state_to_ned(x, 50.0)
    assert (n, e, d, vn, ve, vd) == (200.0, 100.0, -50.0, -4.0, 3.0, 0.0)
    assert np.array_equal(mavlink_codec.state_from_ned(n, e, vn, ve), x)
    with pytest.raises(rejections.CodecError, match="finite"):
        mavlink_codec.state_from_ned(math.nan, 0.0, 0.0, 0.0)


def test_parse_waypoints() -> None:
    wps = vehicle_convert.parse_waypoints("100,200; 300,400")
    assert wps is not None and np.array_equal(wps, [[100, 200], [300, 400]])
    assert vehicle_convert.parse_waypoints("  ") is None
    with pytest.raises(ValueError, match="waypoints"):
        vehicle_convert.parse_waypoints("1,2,3")


def _occupancy_msg() -> tuple[Any, Any]:
    from dualpilot.model.forecast import ForecastParams
    from dualpilot.model.front_forecast import front_forecast

    field = _fires()
    fc = front_forecast(field.fronts, field.params, 1000.0, np.random.default_rng(2),
                        ForecastParams(horizon_s=4.0), substeps_per_step=3, issued_substep=12)
    msg = fire_pb2.FireForecast(substeps_done=12, substep_s=0.5)
    wire.Stamper("ews", "uav1").stamp(msg.header, 6.0)
    fire_convert.occupancy_to_msg(fc, msg.occupancy)
    return fc, msg


def test_occupancy_forecast_round_trip_is_exact() -> None:
    fc, msg = _occupancy_msg()
    assert len(msg.occupancy.probabilities) == 5 and msg.occupancy.horizon_s == 4.0
    back = fire_convert.occupancy_from_msg(wire.parse(msg.SerializeToString(),
                                                        fire_pb2.FireForecast))
    assert back is not None
    assert np.array_equal(back.levels, fc.levels) and back.horizons == fc.horizons
    assert (back.resolution_m, back.substep_s, back.origin_m) == (10.0, 0.5, (0.0, 0.0))
    assert (back.issued_substep, back.substeps_per_step) == (12, fc.substeps_per_step)
    del msg.occupancy.probabilities[:]
    msg.ClearField("occupancy")
    assert fire_convert.occupancy_from_msg(msg) is None  # a forecast without a grid


def _broken(change: str) -> Any:
    _, msg = _occupancy_msg()
    g = msg.occupancy
    if change == "no cells":
        g.rows = 0
    elif change == "short slice":
        g.encoding = fire_pb2.SLICE_ENCODING_RAW
        raw = [zlib.decompress(b) for b in g.probabilities]
        raw[3] = raw[3][:-1]
        g.probabilities[:] = raw
    elif change == "cut zlib":
        g.probabilities[3] = g.probabilities[3][:-1]
    elif change == "zlib bomb":
        g.probabilities[3] = zlib.compress(bytes(2 * g.rows * g.cols))
    elif change == "zlib tail":
        g.probabilities[3] = g.probabilities[3] + b"\x00"
    elif change == "slices":
        del g.probabilities[-1]
    elif change == "order":
        g.horizons[2] = g.horizons[1]
    elif change == "horizon_s":
        g.horizon_s = 5.0
    elif change == "resolution":
        g.resolution_m = -10.0
    elif change == "origin":
        g.origin.east_m = math.inf
    elif change == "substep":
        msg.substep_s = 0.0
    elif change == "huge":
        g.rows, g.cols = 2048, 1024
    return msg


@pytest.mark.parametrize("change, match, reason", [
    ("no cells", "grid of 0 x 100", rejections.Reason.SIZE),
    ("short slice", "slice 3 has 9999 bytes", rejections.Reason.SIZE),
    ("cut zlib", "slice 3's zlib stream is cut short", rejections.Reason.SIZE),
    ("zlib bomb", "slice 3 inflates to more than the grid's 10000 bytes", rejections.Reason.SIZE),
    ("zlib tail", "slice 3 has 1 bytes after its zlib stream", rejections.Reason.SIZE),
    ("slices", "4 probability slices for 5 horizons", rejections.Reason.SIZE),
    ("order", "horizons must increase", rejections.Reason.OUT_OF_RANGE),
    ("horizon_s", "is not the last horizon", rejections.Reason.INVALID),
    ("resolution", "resolution_m must be positive", rejections.Reason.OUT_OF_RANGE),
    ("origin", "grid origin must be finite", rejections.Reason.NOT_FINITE),
    ("substep", "substep_s must be positive", rejections.Reason.OUT_OF_RANGE),
    ("huge", "allowed 1..", rejections.Reason.SIZE),
])
def test_malformed_occupancy_grids_are_rejected_and_counted(change: str, match: str,
                                                            reason: rejections.Reason) -> None:
    with pytest.raises(rejections.CodecError, match=match) as info:
        fire_convert.occupancy_from_msg(wire.parse(_broken(change).SerializeToString(),
                                                     fire_pb2.FireForecast))
    assert info.value.reason == reason
    before = rejections.REJECTED.by_label["FireForecast-test"]
    rejections.rejected("FireForecast-test", info.value)
    assert rejections.REJECTED.by_label["FireForecast-test"] == before + 1
