"""The wire in 3-D (docs/three_d.md, section 10): round trips and rejections of every new field,
and a planar message with none of them (its bytes as before).

No processes here: the converters every service relies on.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.ports import PlanRequest
from dualpilot.model.altitude import lift_state
from dualpilot.model.dynamics import DynamicsParams, hover_state
from dualpilot.model.fire import FireFront
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.model.prism import Cuboid, Prism
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.spec import MissionSpec
from services.common import mav, mavlink_codec, rejections, wire
from services.common.convert import fire as fire_convert
from services.common.convert import plan as plan_convert
from services.common.convert import vehicle as vehicle_convert
from services.msgs import fire_pb2, plan_pb2, vehicle_pb2

pytestmark = pytest.mark.timeout(60)

STAMP = wire.Stamper("supervisor", "u")
SQUARE = Rect(500.0, 500.0, 100.0, 60.0).polytope()
#: fields the 3-D wire adds (message, field): absent from every planar message
NEW_FIELDS = {("Force2", "up_n"), ("VehicleState", "velocity_up_mps"), ("VehicleState", "dim"),
              ("Dynamics", "dim"), ("PlanRequest", "obstacle_altitudes_m"),
              ("FireFront", "top_m"), ("FireFront", "hull_top_m"),
              ("FireState", "extinct_hull_tops_m")}


def rejects(fn: Callable[[], Any]) -> rejections.CodecError:
    with pytest.raises(rejections.CodecError) as err:
        fn()
    return err.value


def fields_set(msg: Any) -> set[tuple[str, str]]:
    """(message name, field name) of every field set anywhere in ``msg``."""
    out = set()
    for fd, value in msg.ListFields():
        out.add((msg.DESCRIPTOR.name, fd.name))
        if fd.message_type is not None:
            for sub in (value if fd.is_repeated else [value]):
                out |= fields_set(sub)
    return out


def request(state: np.ndarray, u: np.ndarray, obstacles: Any) -> plan_pb2.PlanRequest:
    req = PlanRequest(t=3, system=2, state=state, prev_control=u, obstacles=obstacles,
                      objective=Objective.ENERGY)
    return plan_convert.plan_query_msg(plan_convert.PlanQuery(req, "m1", 7, 30.0), STAMP, 1.0)


def decode(m: plan_pb2.PlanRequest) -> PlanRequest:
    got = plan_convert.plan_request_from_msg(
        plan_pb2.PlanRequest.FromString(m.SerializeToString()))
    assert isinstance(got, plan_convert.PlanQuery)
    return got.request


STATE3 = np.array([120.0, 340.0, 63.25, 4.5, -2.0, 1.25])
U3 = np.array([1.5, -0.25, 2.0])
PRISM = Prism(SQUARE, 0.0, 37.5)


def test_a_planar_message_carries_none_of_the_3d_fields() -> None:
    """2-D request, prepare, plan, fire state and vehicle state: no new field is set, so each
    serialises to the bytes it did before the third dimension (proto3 writes no default)."""
    x = hover_state(np.array([100.0, 200.0]), DynamicsParams())
    msgs: list[Any] = [request(x, np.array([0.5, -0.5]), (SQUARE,))]
    config = MissionConfig(seed=4)
    prep = plan_convert.Prepare("m1", 1, config.spec(), config)
    msgs.append(plan_convert.prepare_msg(prep, STAMP, 0.0))
    plan = Plan(system=2, status=PlanStatus.OK, states=np.zeros((3, 4)),
                controls=np.ones((2, 2)), compute_time_s=0.1)
    msgs.append(plan_convert.plan_to_msg(plan, 3, 7, STAMP))
    front = FireFront(1, 0, 2.0, 0.5, Rect(300.0, 300.0, 120.0, 150.0), SQUARE)
    msgs.append(fire_convert.fire_state_msg([front], [SQUARE], 1, 2, 0.5, STAMP, 1.0))
    msgs.append(vehicle_convert.vehicle_state_msg(x, 1, STAMP, 1.0, 50.0))
    for m in msgs:
        assert not fields_set(m) & NEW_FIELDS, (type(m).__name__, fields_set(m) & NEW_FIELDS)
    assert mavlink_codec.state_to_ned(x, 50.0) == (200.0, 100.0, -50.0, 0.0, 0.0, 0.0)


def test_a_3d_plan_request_round_trips_with_its_prisms() -> None:
    got = decode(request(STATE3, U3, (PRISM, Prism(SQUARE, 5.0, 150.0))))
    assert np.array_equal(got.state, STATE3) and np.array_equal(got.prev_control, U3)
    assert [type(o) for o in got.obstacles] == [Prism, Prism]
    for sent, back in zip((PRISM, Prism(SQUARE, 5.0, 150.0)), got.obstacles, strict=True):
        assert isinstance(back, Prism)
        assert (back.z_lo, back.z_hi) == (sent.z_lo, sent.z_hi)
        assert np.array_equal(back.A, sent.A) and np.array_equal(back.b, sent.b)
    spec3 = MissionConfig(settings=(("dim", 3),)).spec()
    plan_convert.check_in_area(got, spec3)
    err = rejects(lambda: plan_convert.check_in_area(got, MissionSpec()))
    assert err.reason == "out_of_range" and "dim 3 for a mission of dim 2" in str(err)


@pytest.mark.parametrize(("change", "reason", "words"), [
    (lambda m: m.obstacle_altitudes_m.pop(), "size", "(bottom, top) for each"),
    (lambda m: m.obstacle_altitudes_m.__setitem__(0, -1.0), "out_of_range", "[0, 10000]"),
    (lambda m: m.obstacle_altitudes_m.__setitem__(1, math.nan), "not_finite", "finite"),
    (lambda m: m.obstacle_altitudes_m.__setitem__(0, 40.0), "out_of_range", "not below"),
    (lambda m: setattr(m.state, "altitude_m", -0.5), "out_of_range", "altitude"),
    (lambda m: setattr(m.state, "velocity_up_mps", 2e3), "out_of_range", "velocity"),
    (lambda m: setattr(m.state, "dim", 4), "out_of_range", "dim must be 2 or 3"),
    (lambda m: setattr(m.prev_control, "up_n", math.inf), "not_finite", "prev_control"),
])
def test_a_malformed_3d_request_is_rejected(change: Callable[[Any], None], reason: str,
                                            words: str) -> None:
    m = request(STATE3, U3, (PRISM,))
    change(m)
    err = rejects(lambda: decode(m))
    assert err.reason == reason and words in str(err), err


@pytest.mark.parametrize(("change", "words"), [
    (lambda m: m.obstacle_altitudes_m.extend((0.0, 30.0)), "carries 2 obstacle altitudes"),
    (lambda m: setattr(m.state, "velocity_up_mps", 1.0), "no velocity_up_mps"),
    (lambda m: setattr(m.prev_control, "up_n", 1.0), "no up_n"),
])
def test_a_planar_request_with_a_3d_field_is_rejected(change: Callable[[Any], None],
                                                      words: str) -> None:
    m = request(hover_state(np.array([100.0, 200.0]), DynamicsParams()), np.zeros(2),
                (SQUARE,))
    change(m)
    assert words in str(rejects(lambda: decode(m)))


def test_a_3d_prepare_takes_its_band_from_the_configuration() -> None:
    config = MissionConfig(seed=4, settings=(("dim", 3), ("ceiling_m", 100.0),
                                             ("start_altitude_m", 30.0)))
    m = plan_convert.prepare_msg(plan_convert.Prepare("m1", 2, config.spec(), config),
                                 STAMP, 0.0)
    assert m.mission.dynamics.dim == 3
    got = plan_convert.plan_request_from_msg(plan_pb2.PlanRequest.FromString(
        m.SerializeToString()))
    assert isinstance(got, plan_convert.Prepare)
    assert got.spec == config.spec()
    bad = plan_pb2.PlanRequest()
    bad.CopyFrom(m)
    bad.mission.dynamics.dim = 2
    assert "dim 2 differs from its configuration's 3" in str(rejects(
        lambda: plan_convert.plan_request_from_msg(bad)))
    bad.mission.dynamics.dim = 5
    assert rejects(lambda: plan_convert.plan_request_from_msg(bad)).reason == "out_of_range"


def test_a_3d_plan_round_trips_and_is_read_by_its_dimension() -> None:
    states = np.array([STATE3, STATE3 + 1.0, STATE3 + 2.0, STATE3 + 3.0])
    controls = np.array([U3, U3 * 0.5, -U3])
    plan = Plan(system=2, status=PlanStatus.OK, states=states, controls=controls,
                compute_time_s=0.25, path=states[:, :3])
    m = plan_pb2.Plan.FromString(plan_convert.plan_to_msg(plan, 3, 7, STAMP).SerializeToString())
    back = plan_convert.plan_from_msg(m, 2, dim=3)
    assert np.array_equal(back.states, states) and np.array_equal(back.controls, controls)
    assert back.path is not None and np.array_equal(back.path, states[:, :3])
    assert rejects(lambda: plan_convert.plan_from_msg(m, 2)).reason == "size"  # read as 2-D
    m.states[2] = -3.0  # the first state's altitude below the ground
    err = rejects(lambda: plan_convert.plan_from_msg(m, 2, dim=3))
    assert err.reason == "out_of_range" and "altitudes" in str(err)


def fronts3() -> list[FireFront]:
    return [FireFront(1, 0, 2.0, 0.5, Rect(300.0, 300.0, 120.0, 150.0), SQUARE, 12.5, 14.0),
            FireFront(4, 2, 1.0, -0.5, Rect(700.0, 600.0, 100.0, 100.0), SQUARE, 150.0, 150.0)]


def fire_state3() -> fire_pb2.FireState:
    return fire_convert.fire_state_msg(fronts3(), [SQUARE], 1, 2, 0.5, STAMP, 1.0, [9.0])


def test_a_3d_fire_state_carries_each_fronts_tops() -> None:
    m = fire_pb2.FireState.FromString(fire_state3().SerializeToString())
    snap = fire_convert.snapshot_from_msg(m)
    assert snap.tops_m == (12.5, 150.0) and snap.hull_tops_m == (14.0, 150.0, 9.0)
    regions = fire_convert.current_from_msg(m)
    assert regions == (Cuboid(fronts3()[0].region, 12.5), Cuboid(fronts3()[1].region, 150.0))
    assert snap.current() == regions
    assert fire_convert.regions_from_msg(m) == tuple(f.region for f in fronts3())


@pytest.mark.parametrize(("change", "reason", "words"), [
    (lambda m: m.fronts[1].ClearField("top_m"), "size", "all, or none"),
    (lambda m: m.fronts[0].ClearField("hull_top_m"), "size", "all, or none"),
    (lambda m: m.extinct_hull_tops_m.append(3.0), "size", "2 extinct hull tops for 1"),
    (lambda m: setattr(m.fronts[0], "top_m", -2.0), "out_of_range", "[0, 10000]"),
    (lambda m: setattr(m.fronts[0], "top_m", 0.0), "out_of_range", "above the ground"),
    (lambda m: setattr(m.fronts[0], "hull_top_m", math.nan), "not_finite", "finite"),
    (lambda m: setattr(m.fronts[0], "hull_top_m", 10.0), "out_of_range", "below its cuboid"),
])
def test_a_malformed_3d_fire_state_is_rejected(change: Callable[[Any], None], reason: str,
                                               words: str) -> None:
    m = fire_state3()
    change(m)
    for decoder in (fire_convert.snapshot_from_msg, fire_convert.regions_from_msg,
                    fire_convert.current_from_msg):
        err = rejects(lambda d=decoder: d(m))  # type: ignore[misc]
        assert err.reason == reason and words in str(err), err


def test_a_3d_vehicle_state_round_trips() -> None:
    m = vehicle_convert.vehicle_state_msg(STATE3, 4, STAMP, 1.0, altitude_m=50.0)
    assert (m.dim, m.altitude_m, m.velocity_up_mps) == (3, 63.25, 1.25)  # its own altitude
    back = vehicle_convert.state_from_msg(vehicle_pb2.VehicleState.FromString(
        m.SerializeToString()))
    assert np.array_equal(back, STATE3)


def setpoint(z: float, vz: float, mask: int = mav.TYPE_MASK_POS_VEL) -> Any:
    return SimpleNamespace(coordinate_frame=mav.MAV_FRAME_LOCAL_NED, type_mask=mask,
                           x=340.0, y=120.0, z=z, vx=-2.0, vy=4.5, vz=vz)


def test_mavlink_carries_the_altitude_down_positive() -> None:
    """NED: z = −p_up and vz = −v_up, both ways; a planar state keeps the fixed altitude."""
    ned = mavlink_codec.state_to_ned(STATE3, 50.0)
    assert ned == (340.0, 120.0, -63.25, -2.0, 4.5, -1.25)
    assert np.array_equal(mavlink_codec.state_from_ned(340.0, 120.0, -2.0, 4.5, -63.25, -1.25),
                          STATE3)
    target = mavlink_codec.setpoint_from_mavlink(setpoint(-63.25, -1.25), 1000.0, 0, dim=3)
    assert np.array_equal(target, STATE3)
    held = mavlink_codec.setpoint_from_mavlink(setpoint(-63.25, -1.25, mav.TYPE_MASK_POS),
                                               1000.0, 0, dim=3)
    assert np.array_equal(held, lift_state([120.0, 340.0, 0.0, 0.0], 63.25))
    assert mavlink_codec.setpoint_from_mavlink(setpoint(-63.25, -1.25), 1000.0, 0).shape == (4,)


@pytest.mark.parametrize(("z", "vz", "reason", "words"), [
    (0.5, 0.0, "out_of_range", "altitude -0.5 m"),
    (math.nan, 0.0, "not_finite", "setpoint z"),
    (-2e4, 0.0, "out_of_range", "setpoint z"),
    (-50.0, 150.0, "out_of_range", "setpoint vz"),
    (-50.0, math.inf, "not_finite", "setpoint vz"),
])
def test_a_malformed_3d_setpoint_is_rejected(z: float, vz: float, reason: str,
                                             words: str) -> None:
    err = rejects(lambda: mavlink_codec.setpoint_from_mavlink(setpoint(z, vz), 1000.0, 0,
                                                              dim=3))
    assert err.reason == reason and words in str(err), err


def test_a_3d_position_below_the_ground_is_rejected() -> None:
    err = rejects(lambda: mavlink_codec.state_from_ned(340.0, 120.0, 0.0, 0.0, 3.0, 0.0))
    assert err.reason == "out_of_range" and "altitude" in str(err)


def test_polytope_round_trip_is_exact() -> None:
    """A prism's base crosses as a polygon: the 3-D plans are the 2-D geometry's, bit for bit."""
    m = request(STATE3, U3, (PRISM,))
    back = decode(m).obstacles[0]
    assert isinstance(back, Prism) and isinstance(back.base, Polytope)
    assert np.array_equal(back.base.vertices, SQUARE.vertices)
