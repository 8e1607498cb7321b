"""The mission configuration a simulated vehicle flies: Eq. (1) of its reading, its area.

The supervisor builds a mission's :class:`~dualpilot.mission.config.MissionConfig`
once and, before it takes the vehicle, sends it to uavsim on
``<ns>/uavsim/mission`` (a query; services/supervisor/simulator.py), as it sends
it to the planners and the EWS. uavsim then flies in lockstep the dynamics of
the mission's spec (Eq. (1): ΔT, ζ, m, the force and speed limits and the
speed-limit reading, ``config.spec().dynamics``) and checks setpoints and
uploaded waypoints against its area, exactly as the in-process mission does:
the vehicle reads no reading of its own. Until a configuration arrives it flies
the default configuration's (a vehicle on its own: a ground station, MAVSDK).
A 3-D configuration (``dim=3``, docs/three_d.md) makes the lockstep vehicle fly
Eq. (1) in 3-D from the band's start altitude (:func:`vertical`: its lockstep climb
is instantaneous, as its take-off to SIM_ALT_M is in 2-D); on its own clock the
vehicle keeps the planar Eq. (1) and its altitude controller.

The callback only enqueues; the vehicle's loop takes the configuration between
two passes (services/uavsim/sidechannel.py, so no step runs half on the old
dynamics), decodes and checks it (services/common/convert/config.py), applies
it and answers with the configuration it now flies. Only the session that holds
the vehicle's ``alive/supervisor`` token may configure it; anything else gets an
error reply, counted per key and reason.
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np
import zenoh

from dualpilot.mission.config import MissionConfig
from dualpilot.model.altitude import lift_state, planar_state
from dualpilot.model.dynamics import DynamicsParams
from services.common import bus, keys, rejections, wire
from services.common.convert import config as config_convert
from services.common.effective import EFFECTIVE
from services.common.log import fields
from services.common.mavlink_codec import setpoint_band_margin_m
from services.msgs import config_pb2

from .endpoint import Endpoint
from .mission import PlanningBounds
from .plantsim import PlantSim
from .sidechannel import SideChannel
from .vehicle import Vehicle

log = logging.getLogger("services.uavsim")


def apply(endpoint: Endpoint, config: MissionConfig) -> None:
    """Fly ``config``'s Eq. (1), or its plant, and, in lockstep, check against its area (and,
    in 3-D, its altitude band) (ValueError: a vehicle on its own clock cannot change its ΔT; a
    plant it cannot fly)."""
    spec = config.spec()
    dyn = spec.dynamics
    v = endpoint.vehicle
    if endpoint.realtime is not None and dyn.dt_s != v.dyn.dt_s:
        raise ValueError(f"a vehicle on its own clock steps every {v.dyn.dt_s:g} s; the "
                         f"mission's ΔT is {dyn.dt_s:g} s")
    if endpoint.realtime is not None:
        dyn = replace(dyn, dim=2)  # its own clock: the altitude controller flies z (climb)
    vertical(v, dyn, spec.band.start_altitude_m)
    fly_plant(v, config, own_clock=endpoint.realtime is not None)
    if endpoint.realtime is None:
        endpoint.setup = replace(endpoint.setup, area_size_m=config.area_size_m,
                                 band=spec.band if spec.dim == 3 else None,
                                 band_margin_m=setpoint_band_margin_m(dyn))
        endpoint.ap.mission.bounds = PlanningBounds(endpoint.setup.home, config.area_size_m)
    endpoint.repeat = None  # a setpoint accepted under the old limits is checked again


def fly_plant(v: Vehicle, config: MissionConfig, own_clock: bool) -> None:
    """The plant of ``config`` flies ``v`` from where it is (services/uavsim/plantsim.py; the
    ideal plant: Eq. (1), none); the same configuration again keeps the plant flying. Called
    after :func:`vertical`, so a 3-D plant is made at the band's start altitude; the vehicle
    then reports the plant's estimate."""
    if v.plant is None or v.plant_config != config:
        here = v.state
        if v.plant is not None and len(v.plant.plant.state) == len(v.state):
            here = v.plant.plant.state  # the truth, not its estimate
        v.plant = PlantSim.for_config(config, here, v.time_ms, own_clock)
        v.plant_config = config if v.plant is not None else None
    if v.plant is not None:
        v.state = v.plant.measured()


def vertical(v: Vehicle, dyn: DynamicsParams, start_altitude_m: float) -> None:
    """Fly ``dyn`` (Eq. (1) of its dimension): a planar vehicle taking a 3-D Eq. (1) is lifted
    to ``start_altitude_m`` (m above home), climbing at 0; a 3-D one taking a planar Eq. (1)
    keeps its position and velocity in the plane (its altitude: the lockstep SIM_ALT_M)."""
    if dyn.dim == 3:
        x = v.state if len(v.state) == 4 else planar_state(v.state)
        v.state = lift_state(x, start_altitude_m)
        v.control = np.zeros(3)
    elif len(v.state) == 6:
        v.state = planar_state(v.state)
        v.control = np.zeros(2)
    v.dyn = dyn


class MissionConfigs:
    """The configurations one vehicle takes: those its supervisor sends, applied and answered
    with the configuration it now flies (:func:`mission_configs`: their queryable)."""

    def __init__(self, uav: str, endpoint: Endpoint, live: bus.Liveliness):
        self.uav = uav
        self.endpoint = endpoint
        self.live = live

    def answer(self, item: bus.Received) -> config_pb2.MissionConfig:
        """Take the configuration of ``item``; the one now flown (CodecError: refused)."""
        config = self._check(item)
        try:
            apply(self.endpoint, config)
        except ValueError as bad:
            raise rejections.invalid(str(bad), rejections.Reason.OUT_OF_RANGE) from bad
        self._took(config)
        return config_convert.config_to_msg(config, config_pb2.MissionConfig())

    def _check(self, item: bus.Received) -> MissionConfig:
        """The configuration of ``item`` from the vehicle's supervisor (CodecError else)."""
        who = item.attachment.decode("ascii", "replace")
        holders = self.live.holders.get("supervisor", [])
        if who not in holders:
            raise rejections.invalid(f"a mission configuration from {who or '?'}, not from this "
                                     f"vehicle's supervisor ({', '.join(holders) or 'none'})")
        config = config_convert.config_from_msg(
            wire.parse(item.payload, config_pb2.MissionConfig, item.encoding))
        if config.uav_id and config.uav_id != self.uav:
            raise rejections.invalid(f"a mission configuration of vehicle {config.uav_id!r} "
                                     f"sent to {self.uav!r}")
        return config

    def _took(self, config: MissionConfig) -> None:
        dyn = self.endpoint.vehicle.dyn
        EFFECTIVE.record(config.mission_id, self.uav, config_convert.config_to_json(config),
                         dynamics=dyn, area_size_m=self.endpoint.setup.area_size_m)
        log.info("mission configuration", extra=fields(
            mission=config.mission_id, profile=config.profile, dt_s=dyn.dt_s, zeta=dyn.zeta,
            mass_kg=dyn.mass_kg, u_max_n=dyn.u_max_n, v_max_mps=dyn.v_max_mps,
            speed_limit=dyn.speed_limit, area_size_m=self.endpoint.setup.area_size_m,
            plant=config.reading().plant.plant))


def mission_configs(session: zenoh.Session, configs: MissionConfigs) -> SideChannel:
    """The ``uavsim/mission`` queryable of ``configs``'s vehicle, answered from its loop."""
    return SideChannel(session, keys.sim_mission(configs.uav), configs.answer, "MissionConfig",
                       wire.Stamper("uavsim", configs.uav), max_items=16,
                       max_bytes=1024 * 1024)
