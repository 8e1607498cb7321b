"""The vehicle's parameters: what a ground station reads and sets (PARAM_* messages).

Each parameter drives the simulation or reports on it (:data:`PARAMS`);
read-only ones have no range. Defaults set by the command line win.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from services.common import mav, rejections
from services.common.log import fields

if TYPE_CHECKING:
    from .endpoint import Endpoint

log = logging.getLogger("services.uavsim")
m = mav.mavlink


@dataclass
class Param:
    """A vehicle parameter: value, allowed range (None: read-only) and what it sets."""

    value: float
    low: float | None = None
    high: float | None = None
    doc: str = ""


#: name → (default, low, high, meaning); low/high None = read-only. Defaults set by flags win.
PARAMS: dict[str, tuple[float, float | None, float | None, str]] = {
    "MAV_SYS_ID": (1.0, None, None, "system id (--sysid)"),
    "COM_OF_LOSS_T": (1.0, 0.1, 60.0, "s without a setpoint before the failsafe hold (PX4)"),
    "COM_OF_RSM_T": (0.5, 0.0, 10.0, "s of live setpoint stream before it resumes control"),
    "MPC_XY_VEL_MAX": (15.0, 0.1, 15.0, "speed limit per axis, or of |v| with --speed-limit "
                                        "norm, m/s (paper: 15)"),
    "SIM_U_MAX_N": (7.5, 0.1, 7.5, "force limit per axis, N (paper: 7.5)"),
    "SIM_KP": (0.5, 0.0, 1.0, "position gain of the tracking controller"),
    "SIM_ALT_M": (50.0, 1.0, 500.0, "flight altitude above home, m"),
    "BAT_CAP_NS": (1000.0, 1.0, 1e6, "battery capacity as impulse Σ‖u‖ΔT, N·s"),
    "MIS_ACC_RAD": (15.0, 1.0, 200.0, "a mission waypoint counts as reached within this, m"),
    "MIS_ID": (0.0, None, None, "mission version, +1 on every upload or clear"),
    "SIG_REJECTED": (0.0, None, None, "unsigned or wrongly signed frames ignored (offboard)"),
    "COM_SP_LEAD_S": (7.0, 1.0, 600.0, "a setpoint due later than this after the vehicle's "
                                       "clock is refused (one step: 5 dT planning + dT, +0.5)"),
    "CTL_REFUSED": (0.0, None, None, "control messages refused: not from the link and peer "
                                     "in control"),
    "SIM_FAILSAFES": (0.0, None, None, "offboard-loss failsafes so far (services/uavsim/"
                                       "failsafe.py)"),
}


def param_set(ep: Endpoint, link: str, msg: Any) -> bool:
    """PARAM_SET: a settable parameter within its range is set, announced and applied to the
    simulation; anything else is refused, counted and answered with the unchanged value."""
    pid = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode(
        "ascii", "replace")
    name = pid.rstrip("\x00")
    param = ep.params.get(name)
    if param is None:  # unknown: no PARAM_VALUE, as PX4 (the GCS times out)
        ep.reject(link, rejections.invalid(f"PARAM_SET of unknown parameter {name[:16]!r}"),
                  "PARAM_SET")
        return False
    value = float(msg.param_value)
    err: rejections.CodecError | None = None
    if not math.isfinite(value):
        err = rejections.invalid(f"PARAM_SET {name} = {value}", rejections.Reason.NOT_FINITE)
    elif param.low is None or param.high is None:
        err = rejections.invalid(f"PARAM_SET {name}: read-only")
    elif not param.low <= value <= param.high:
        err = rejections.invalid(f"PARAM_SET {name} = {value:g} outside [{param.low:g}, "
                                 f"{param.high:g}]", rejections.Reason.OUT_OF_RANGE)
    if err is not None:
        ep.reject(link, err, "PARAM_SET")
        ep.statustext(f"{name}: refused {value:g}", m.MAV_SEVERITY_WARNING)
        ep.param_value(link, name)  # the unchanged value tells the GCS it was refused
        return False
    param.value = value
    ep.repeat = None  # a setpoint accepted under the old value is checked again
    if name == "MPC_XY_VEL_MAX":
        ep.vehicle.set_limits(v_max_mps=value)
    elif name == "SIM_U_MAX_N":
        ep.vehicle.set_limits(u_max_n=value)
    elif name == "SIM_KP":
        ep.vehicle.kp = value
    elif name == "BAT_CAP_NS":
        ep.vehicle.capacity_ns = value
    log.info("param set", extra=fields(name=name, value=value))
    ep.param_value(None, name)
    return True
