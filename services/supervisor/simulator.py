"""The mission's configuration handed to the simulated vehicle before the supervisor takes it.

The supervisor builds the :class:`~dualpilot.mission.config.MissionConfig` once
(services/supervisor/options.py); the planners get it with their prepare
request, the EWS with its reset, and uavsim on ``<ns>/uavsim/mission``
(services/uavsim/missionconfig.py): the vehicle then flies the mission's
Eq. (1) in lockstep, as the in-process mission does. The reply is the
configuration the vehicle now flies; anything but this mission's is an abort.
The supervisor's own effective configuration is recorded here too (its status).
"""

from __future__ import annotations

import logging

from dualpilot.mission.config import MissionConfig
from services.common import bus, keys, rejections, wire
from services.common.convert import config as config_convert
from services.common.effective import EFFECTIVE
from services.common.log import fields
from services.msgs import config_pb2

from .ports import Aborted, StackBus

log = logging.getLogger(__name__)


def configure_vehicle(b: StackBus, config: MissionConfig) -> None:
    """Send ``config`` to the vehicle's simulator and check what it flies (Aborted else)."""
    doc = config_convert.config_to_json(config)
    EFFECTIVE.record(config.mission_id, b.uav, doc)
    key = keys.sim_mission(b.uav)
    msg = config_convert.config_to_msg(config, config_pb2.MissionConfig())
    try:
        payload, enc = b.query(key, msg, b.stack.vehicle_timeout_s, trusted=b.trusted("uavsim"))
        flies = config_convert.config_from_msg(wire.parse(payload, config_pb2.MissionConfig,
                                                          enc))
    except rejections.CodecError as err:
        rejections.rejected("MissionConfig", err, log, key=key)
        raise Aborted(f"the vehicle's answer to its mission configuration: {err}") from err
    except (TimeoutError, bus.QueryError) as err:
        raise Aborted(f"the vehicle did not take the mission configuration: {err}") from err
    if flies != config:
        raise Aborted("the vehicle flies another mission configuration than the one sent")
    log.info("vehicle configured", extra=fields(mission=config.mission_id,
                                                profile=config.profile))
