"""uavsim flying the mission's multirotor (services/uavsim/{plantsim,plantclock,truth,wind}.py).

The lockstep flights are the in-process mission's (dualpilot/mission/flight.py's
PlantVehicle) bit for bit; on its own clock the vehicle flies the 20 Hz setpoint stream as
it comes; the truth crosses the side channel checked both ways; a ground station gets the
wind of the flavour's own message, worked out by hand from the mean wind.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.flight import PlantVehicle
from dualpilot.mission.local import local_vehicle
from dualpilot.model.dynamics import DynamicsParams, hover_state, step
from services.common import mav, rejections, wire
from services.common.convert import plant as plant_convert
from services.msgs import common_pb2, plant_pb2
from services.uavsim import flavour as fl
from services.uavsim import plantclock
from services.uavsim.flavour import Nav
from services.uavsim.missionconfig import fly_plant, vertical
from services.uavsim.truth import answer
from services.uavsim.vehicle import Vehicle, tracking_control
from tests.support.vehicles import COMPANION, rig

m = mav.mavlink
#: the multirotor in a 5 m/s wind, moderate turbulence, GPS σ 1.5 m
PLANT = (("plant", "multirotor"), ("wind_speed_mps", 5.0), ("turbulence", "moderate"),
         ("gps_sigma_m", 1.5))
STAMPER = wire.Stamper("test", "u1")


def config(*settings: tuple[str, object], seed: int = 3) -> MissionConfig:
    return MissionConfig.named("cc", seed=seed, settings=settings)


def fly_both(v: Vehicle, inproc: PlantVehicle, dyn: DynamicsParams) -> Iterator[Any]:
    """Eight random controls (seeded) flown by uavsim's vehicle ``v`` and the in-process
    ``inproc`` alike: after each, the same measured state, and the vehicle's truth (yielded)
    is the in-process flight's path, segment, tracking error and true position over the
    mission's axes."""
    assert v.plant is not None
    rng = np.random.default_rng(1)
    for k in range(8):
        u = rng.uniform(-7.5, 7.5, dyn.dim)
        target = step(v.state, u, dyn)
        inproc.command(target, u, 1.0)
        assert v.apply(target, 1000 * (k + 1))
        assert np.array_equal(inproc.observe(), v.state)
        truth = v.plant.truth()
        assert inproc.flight is not None
        assert np.array_equal(truth.path, inproc.flight.positions[:, :dyn.dim])
        assert np.array_equal(truth.planned, inproc.flight.reference[:, :dyn.dim])
        assert np.array_equal(truth.tracking_error_m(), inproc.tracking_error_m[-1])
        assert np.array_equal(truth.state[:dyn.dim], inproc.true_position())
        yield truth


def test_lockstep_flights_are_the_in_process_plant_vehicles_bit_for_bit() -> None:
    """The same mission configuration, the same controls: uavsim's vehicle (flying towards each
    setpoint x_{t+1} = Eq. (1) from its measured state) reports the in-process vehicle's
    measured states, and its truth is the in-process flight's path, segment and error."""
    cfg = config(*PLANT)
    spec = cfg.spec()
    inproc = local_vehicle(cfg, spec, hover_state(np.array(spec.start_position), spec.dynamics))
    assert isinstance(inproc, PlantVehicle)
    east, north = (float(c) for c in spec.start_position)
    v = Vehicle.at(east, north, dyn=spec.dynamics)
    fly_plant(v, cfg, own_clock=False)
    assert v.plant is not None
    assert np.array_equal(inproc.observe(), v.state)
    assert not np.array_equal(v.state[:2], spec.start_position)  # the GPS error
    for k, truth in enumerate(fly_both(v, inproc, spec.dynamics)):
        assert truth.time_ms == 1000 * (k + 1) and truth.flights == k + 1


def test_the_ideal_plant_leaves_the_vehicle_as_it_always_was() -> None:
    v = Vehicle.at(100.0, 200.0)
    fly_plant(v, config(), own_clock=False)
    assert v.plant is None and np.array_equal(v.state, [100.0, 200.0, 0.0, 0.0])
    target = np.array([110.0, 200.0, 10.0, 0.0])
    v.apply(target, 1000)
    u = tracking_control(np.array([100.0, 200.0, 0.0, 0.0]), target, DynamicsParams())
    assert np.array_equal(v.state, step(np.array([100.0, 200.0, 0.0, 0.0]), u, DynamicsParams()))


def test_the_same_configuration_keeps_its_plant_and_another_starts_from_the_truth() -> None:
    cfg = config(*PLANT)
    v = Vehicle.at(50.0, 50.0)
    fly_plant(v, cfg, own_clock=False)
    plant = v.plant
    assert plant is not None
    v.apply(step(v.state, np.array([7.5, 0.0]), DynamicsParams()), 1000)
    fly_plant(v, cfg, own_clock=False)
    assert v.plant is plant
    truth = plant.plant.state
    fly_plant(v, config(*PLANT, seed=4), own_clock=False)
    assert v.plant is not plant and v.plant is not None
    assert np.array_equal(v.plant.plant.state, truth)
    fly_plant(v, config(), own_clock=False)
    assert v.plant is None


def test_a_3d_mission_on_the_vehicles_own_clock_is_refused_by_the_plant() -> None:
    """The plant flies a 3-D mission in lockstep only so far (on its own clock the vehicle
    keeps the planar Eq. (1) and its altitude controller)."""
    cfg = MissionConfig.named("cc", seed=0, profile="today-3d", settings=PLANT)
    v = Vehicle.at(50.0, 50.0)
    with pytest.raises(ValueError, match="in lockstep only"):
        fly_plant(v, cfg, own_clock=True)
    assert v.plant is None


def test_lockstep_3d_flights_are_the_in_process_plant_vehicles_bit_for_bit() -> None:
    """A 3-D configuration: the vehicle is lifted to the band's start altitude and the plant
    made there (missionconfig's order: :func:`vertical`, then :func:`fly_plant`); under random
    3-D controls it reports the in-process vehicle's measured states (z and v_z with the
    vertical GPS error), and its truth is the in-process flight's 3-D path and segment."""
    cfg = MissionConfig.named("cc", seed=3, profile="today-3d",
                              settings=PLANT + (("start_altitude_m", 40.0),))
    spec = cfg.spec()
    assert spec.start_position[2] == 40.0
    start = hover_state(np.array(spec.start_position), spec.dynamics)
    inproc = local_vehicle(cfg, spec, start)
    assert isinstance(inproc, PlantVehicle)
    east, north = (float(c) for c in spec.start_position[:2])
    v = Vehicle.at(east, north)
    vertical(v, spec.dynamics, spec.band.start_altitude_m)
    fly_plant(v, cfg, own_clock=False)
    assert v.plant is not None and v.plant.plant.state[2] == 40.0
    assert np.array_equal(inproc.observe(), v.state) and v.state[2] != 40.0  # the GPS error
    for truth in fly_both(v, inproc, spec.dynamics):
        assert truth.path.shape == (101, 3)
        got = plant_convert.flight_from_msg(plant_convert.flight_msg(truth, STAMPER))
        for a, b in ((got.state, truth.state), (got.path, truth.path),
                     (got.planned, truth.planned)):
            assert np.array_equal(a, b)
    assert abs(float(v.plant.plant.state[2]) - 40.0) > 1.0  # it climbed or sank


def test_a_bad_3d_truth_is_refused() -> None:
    """A 3-D flight carries its altitude and climb and (east, north, up) triples; a planar
    message with an altitude, a dimension other than 2 or 3, a path below the ground or
    a path that does not end at the true altitude are refused."""
    truth = plant_convert.FlightTruth(1000, np.array([10.0, 20.0, 45.0, 1.0, 0.0, -0.5]),
                                      np.array([[9.0, 20.0, 45.5], [10.0, 20.0, 45.0]]),
                                      np.array([[9.0, 20.0, 45.5], [10.0, 20.0, 47.0]]), 1)
    msg = plant_convert.flight_msg(truth, STAMPER)
    assert msg.dim == 3 and msg.altitude_m == 45.0 and msg.velocity_up_mps == -0.5
    assert np.array_equal(plant_convert.flight_from_msg(msg).tracking_error_m(), [2.0])
    flat = plant_convert.flight_msg(plant_convert.FlightTruth(
        1000, np.array([10.0, 20.0, 1.0, 0.0]), np.array([[9.0, 20.0], [10.0, 20.0]]),
        np.array([[9.0, 20.0], [10.0, 20.0]]), 1), STAMPER)
    assert flat.dim == 0 and flat.altitude_m == 0.0 and flat.velocity_up_mps == 0.0
    bad = [plant_pb2.PlantFlight() for _ in range(4)]
    for b in bad[:3]:
        b.CopyFrom(msg)
    bad[0].dim = 4
    bad[1].path_m[2] = -1.0  # below the ground
    bad[2].altitude_m = 46.0  # the path ends at 45 m
    bad[3].CopyFrom(flat)
    bad[3].altitude_m = 50.0  # an altitude on a planar flight
    for b in bad:
        with pytest.raises(rejections.CodecError):
            plant_convert.flight_from_msg(b)


def test_on_its_own_clock_the_plant_flies_the_20_hz_stream_as_it_comes() -> None:
    """Offboard on the vehicle's own clock: each 50 ms of simulated time flies the newest
    setpoint; a setpoint that moves on is flown from the period it arrived in."""
    r = rig(fl.PX4, realtime=True, start=(100.0, 100.0))
    ap = r.ap
    calm = config(("plant", "multirotor"))
    fly_plant(ap.vehicle, calm, own_clock=True)
    plant = ap.vehicle.plant
    assert plant is not None and plant.own_clock
    here = np.array([100.0, 100.0, 0.0, 0.0])
    r.arbiter.heard_on("offboard", 0.0)
    ap.setpoint("offboard", here, 50.0, 0, now=0.0)
    r.arbiter.commit(r.arbiter.check("offboard", COMPANION, 0.0), 0.0)
    for cmd, params in ((m.MAV_CMD_DO_SET_MODE, (1, 6, 0)),
                        (m.MAV_CMD_COMPONENT_ARM_DISARM, (1,))):
        assert r.command(cmd, *params, link="offboard", peer=COMPANION, now=0.1) == \
            m.MAV_RESULT_ACCEPTED
    assert r.nav is Nav.OFFBOARD
    r.fly(1.0)  # the navigator's ΔT: airborne (climbing), the plant holds the setpoint
    assert plantclock.fly_due(ap, plant.time_ms + 49) == 0  # not a whole period yet
    assert plantclock.fly_due(ap, plant.time_ms + 50) == 1
    start_ms = plant.time_ms
    east = np.array([120.0, 100.0, 0.0, 0.0])
    path = []
    for k in range(1, 201):  # 10 s of the stream: hold 20 m east of here
        ap.setpoint("offboard", east, 50.0, 0, now=0.1 + 0.05 * k)
        assert plantclock.fly_due(ap, start_ms + 50 * k) == 1
        assert np.array_equal(plant.truth().planned[-1], east[:2])  # flown towards it
        path.append(plant.plant.state[:2].copy())
    assert plant.flights == 201 and plant.time_ms == start_ms + 10_000
    # the truth: the path of the last ΔT (20 periods of 5 integration steps, joined) and the
    # setpoint held along it, what the supervisor's port judges
    truth = plant.truth()
    assert truth.path.shape == (101, 2) and np.array_equal(truth.path[-1], path[-1])
    assert np.array_equal(truth.path[0], path[-21]) and (truth.planned == east[:2]).all()
    # a position step under PX4's controller (docs/plant.md: a 10 m step overshoots 7.9 %
    # and is inside ±0.5 m after 3.8 s): on its way after 1 s, there after 10 s
    assert 100.5 < path[19][0] < 119.5 and abs(path[-1][0] - 120.0) < 0.5
    assert max(abs(p[1] - 100.0) for p in path) < 0.5
    assert np.array_equal(ap.vehicle.state, plant.measured())
    # a stalled loop skips ahead: at most MAX_PERIODS periods in one pass
    assert plantclock.fly_due(ap, plant.time_ms + 10_000) == plantclock.MAX_PERIODS
    assert plant.time_ms == start_ms + 20_000
    assert plant.truth().path.shape == (101, 2)  # only what was flown after the skip
    # on the ground nothing flies and the path is forgotten
    assert r.command(m.MAV_CMD_COMPONENT_ARM_DISARM, 0, 21196, link="offboard",
                     peer=COMPANION, now=20.0) == m.MAV_RESULT_ACCEPTED
    held = plant.plant.state.copy()
    assert plantclock.fly_due(ap, plant.time_ms + 1000) == 0
    assert np.array_equal(plant.plant.state, held) and plant.truth().path.shape == (0, 2)


def test_the_truth_crosses_the_side_channel_checked() -> None:
    v = Vehicle.at(50.0, 50.0)

    def ask(after_ms: int) -> plant_pb2.PlantFlight:
        req = plant_convert.request_msg(after_ms, STAMPER)
        return answer(v, STAMPER, req.SerializeToString(), wire.encoding_name(req))

    with pytest.raises(rejections.CodecError) as ideal:
        ask(0)
    assert ideal.value.code == common_pb2.ERROR_CODE_UNAVAILABLE
    fly_plant(v, config(*PLANT), own_clock=False)
    at_rest = plant_convert.flight_from_msg(ask(0))
    assert at_rest.flights == 0 and at_rest.path.shape == (0, 2)
    assert np.array_equal(at_rest.state, [50.0, 50.0, 0.0, 0.0])  # the truth, not the estimate
    with pytest.raises(rejections.CodecError) as later:
        ask(1000)
    assert later.value.code == common_pb2.ERROR_CODE_UNAVAILABLE
    v.apply(step(v.state, np.array([5.0, -5.0]), DynamicsParams()), 1000)
    got = plant_convert.flight_from_msg(ask(1000))
    assert v.plant is not None
    want = v.plant.truth()
    assert got.time_ms == 1000 and got.flights == 1 and got.path.shape == (101, 2)
    for a, b in ((got.state, want.state), (got.path, want.path), (got.planned, want.planned)):
        assert np.array_equal(a, b)
    with pytest.raises(rejections.CodecError):  # not a request
        answer(v, STAMPER, b"\xff\x00garbage", wire.encoding_name(plant_pb2.PlantFlightRequest))


def test_a_bad_truth_is_refused() -> None:
    truth = plant_convert.FlightTruth(1000, np.array([10.0, 20.0, 1.0, 0.0]),
                                      np.array([[9.0, 20.0], [10.0, 20.0]]),
                                      np.array([[9.0, 20.0], [10.5, 20.0]]), 1)
    msg = plant_convert.flight_msg(truth, STAMPER)
    assert np.array_equal(plant_convert.flight_from_msg(msg).tracking_error_m(), [0.5])
    bad = [plant_pb2.PlantFlight(), plant_pb2.PlantFlight(), plant_pb2.PlantFlight(),
           plant_pb2.PlantFlight()]
    for b in bad:
        b.CopyFrom(msg)
    bad[0].path_m[0] = math.nan  # not finite
    del bad[1].planned_m[-2:]  # one point fewer than the path
    bad[2].position.east_m = 11.0  # the path does not end where the vehicle is
    del bad[3].path_m[2:]  # a path of one point
    del bad[3].planned_m[2:]
    for b in bad:
        with pytest.raises(rejections.CodecError):
            plant_convert.flight_from_msg(b)


@pytest.mark.parametrize("flavour", [fl.PX4, fl.ARDUPILOT])
def test_a_ground_station_gets_the_flavours_wind_message(flavour: fl.Flavour) -> None:
    """A 6 m/s wind towards the north-east in calm air: PX4's WIND_COV says 6/√2 m/s north
    and east, no variance; ArduPilot's WIND that it comes from the south-west (−135°) at 6
    m/s; the other flavour's message is not sent, and neither before a plant flies."""
    r = rig(flavour, realtime=False)
    for msg_id in (m.MAVLINK_MSG_ID_WIND_COV, m.MAVLINK_MSG_ID_WIND):
        r.telemetry.stream(msg_id)
        assert r.telemetry.sender("gcs", msg_id) is None
    assert r.out.named("wind_cov") == [] and r.out.named("wind") == []
    fly_plant(r.ap.vehicle, config(("plant", "multirotor"), ("wind_speed_mps", 6.0),
                                   ("wind_dir_rad", math.pi / 4)), own_clock=False)
    for msg_id in (m.MAVLINK_MSG_ID_WIND_COV, m.MAVLINK_MSG_ID_WIND):
        r.telemetry.stream(msg_id)
    wind, wind_cov = r.out.named("wind"), r.out.named("wind_cov")
    half = 6.0 / math.sqrt(2.0)
    if flavour is fl.PX4:
        assert wind == [] and len(wind_cov) == 1
        _t, north, east, down, var_h, var_v, alt, h_acc, v_acc = wind_cov[0]
        assert (north, east, down) == pytest.approx((half, half, 0.0), abs=1e-9)
        assert (var_h, var_v) == (0.0, 0.0) and math.isnan(h_acc) and math.isnan(v_acc)
        assert alt == pytest.approx(r.telemetry.home_amsl_m + r.ap.nav.alt)
    else:
        assert wind_cov == [] and len(wind) == 1
        direction, speed, speed_z = wind[0]
        assert (direction, speed, speed_z) == pytest.approx((-135.0, 6.0, 0.0), abs=1e-9)
    own = m.MAVLINK_MSG_ID_WIND_COV if flavour is fl.PX4 else m.MAVLINK_MSG_ID_WIND
    assert r.telemetry.sender("gcs", own) is not None


def test_the_wind_report_carries_the_turbulence_flown_through() -> None:
    """After a flight in moderate turbulence the report is the last second's air: its mean
    near the 5 m/s mean wind (σ_u 2.46 m/s: within 3σ) and a variance above zero."""
    r = rig(fl.PX4, realtime=False)
    v = r.ap.vehicle
    fly_plant(v, config(*PLANT), own_clock=False)
    assert v.plant is not None
    for k in range(3):
        v.apply(step(v.state, np.zeros(2), DynamicsParams()), 1000 * (k + 1))
    mean, var_h, var_v = v.plant.air()
    assert abs(mean[0] - 5.0) < 3 * 2.46 and abs(mean[1]) < 3 * 2.46
    assert var_h > 0.0 and var_v > 0.0
    assert len(v.plant.air_samples) == 100  # one second at 100 Hz
