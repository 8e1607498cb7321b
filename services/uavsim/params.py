"""The vehicle's parameters (:class:`Parameters`) and the PARAM_* protocol over them.

Each parameter drives the simulation or reports on it (:data:`PARAMS`);
read-only ones have no range. Names follow PX4 where PX4 has the same
setting (its default then too, from PX4's parameter files), ``SIM_*`` where
only the simulation has it. Defaults set by the command line win. A change
is announced to every listener (:meth:`Parameters.on_change`): the
endpoint applies the limits to the physics, the protocol sends PARAM_VALUE.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from services.common import mav, rejections
from services.common.log import fields

from .outbox import Outbox, statustext

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
    "COM_DL_LOSS_T": (10.0, 1.0, 300.0, "s without a message from a link's peers before the "
                                        "link counts as lost (PX4's data link loss time)"),
    "COM_DISARM_LAND": (2.0, 0.0, 20.0, "simulated s on the ground after landing before the "
                                        "vehicle disarms itself (PX4)"),
    "MPC_XY_VEL_MAX": (15.0, 0.1, 15.0, "speed limit per axis, or of |v| with --speed-limit "
                                        "norm, m/s (paper: 15)"),
    "MPC_XY_CRUISE": (5.0, 0.5, 15.0, "speed of goto, missions and return, m/s (PX4; "
                                      "DO_CHANGE_SPEED sets it)"),
    "MPC_Z_VEL_MAX_UP": (3.0, 0.5, 8.0, "climb rate, m/s (PX4)"),
    "MPC_Z_VEL_MAX_DN": (1.5, 0.5, 4.0, "sink rate, m/s (PX4)"),
    "MPC_LAND_SPEED": (0.7, 0.2, 2.0, "sink rate of the last MPC_LAND_ALT2 m of a landing, "
                                      "m/s (PX4)"),
    "MPC_LAND_ALT2": (5.0, 0.0, 50.0, "below this height a landing slows to MPC_LAND_SPEED, m"),
    "MIS_TAKEOFF_ALT": (2.5, 0.5, 500.0, "take-off altitude above home, m (PX4)"),
    "RTL_RETURN_ALT": (60.0, 0.0, 500.0, "return climbs to at least this height, m (PX4)"),
    "GF_ACTION": (2.0, 0.0, 5.0, "geofence breach: 0 none, 1 warn, 2 hold, 3 return, 5 land "
                                 "(PX4's values; 4 terminate is not simulated)"),
    "SIM_U_MAX_N": (7.5, 0.1, 7.5, "force limit per axis, N (paper: 7.5)"),
    "SIM_KP": (0.5, 0.0, 1.0, "position gain of the tracking controller"),
    "SIM_ALT_M": (50.0, 1.0, 500.0, "flight altitude above home in lockstep (Sec. IV is 2-D), "
                                    "m"),
    "BAT_CAP_NS": (1000.0, 1.0, 1e6, "battery capacity as impulse Σ‖u‖ΔT, N·s"),
    "MIS_ACC_RAD": (15.0, 1.0, 200.0, "a mission waypoint counts as reached within this, m "
                                      "(unless the item gives its own radius)"),
    "MIS_ID": (0.0, None, None, "mission version, +1 on every upload or clear"),
    "SIG_REJECTED": (0.0, None, None, "unsigned or wrongly signed frames ignored (offboard)"),
    "COM_SP_LEAD_S": (7.0, 1.0, 600.0, "a setpoint due later than this after the vehicle's "
                                       "clock is refused (one step: 5 dT planning + dT, +0.5)"),
    "CTL_REFUSED": (0.0, None, None, "control messages refused: not from the link and peer "
                                     "in control"),
    "SIM_FAILSAFES": (0.0, None, None, "offboard-loss failsafes so far (services/uavsim/"
                                       "failsafe.py)"),
}


class Parameters:
    """The vehicle's parameters: values, ranges and who is told of a change."""

    def __init__(self, table: dict[str, tuple[float, float | None, float | None, str]] = PARAMS,
                 **overrides: float):
        self._p = {name: Param(default, low, high, doc)
                   for name, (default, low, high, doc) in table.items()}
        for name, value in overrides.items():
            self._p[name].value = float(value)
        self._listeners: list[Callable[[str, float], None]] = []

    def __getitem__(self, name: str) -> float:
        return self._p[name].value

    def __contains__(self, name: object) -> bool:
        return name in self._p

    def names(self) -> list[str]:
        return list(self._p)

    def on_change(self, fn: Callable[[str, float], None]) -> None:
        """Call ``fn(name, value)`` after every change."""
        self._listeners.append(fn)

    def check(self, name: str, value: float) -> rejections.CodecError | None:
        """Why a PARAM_SET of ``name`` to ``value`` is refused; None when it is valid."""
        param = self._p.get(name)
        if param is None:
            return rejections.invalid(f"PARAM_SET of unknown parameter {name[:16]!r}")
        if not math.isfinite(value):
            return rejections.invalid(f"PARAM_SET {name} = {value}", rejections.Reason.NOT_FINITE)
        if param.low is None or param.high is None:
            return rejections.invalid(f"PARAM_SET {name}: read-only")
        if not param.low <= value <= param.high:
            return rejections.invalid(f"PARAM_SET {name} = {value:g} outside [{param.low:g}, "
                                      f"{param.high:g}]", rejections.Reason.OUT_OF_RANGE)
        return None

    def set(self, name: str, value: float) -> None:
        """Set ``name`` (read-only ones too: the vehicle's own counters) and tell the listeners."""
        self._p[name].value = float(value)
        for fn in self._listeners:
            fn(name, float(value))

    def set_quietly(self, name: str, value: float) -> None:
        """Set a read-only counter without telling anyone (it changes with every bad frame;
        a ground station reads it when it asks)."""
        self._p[name].value = float(value)

    def add(self, name: str, n: float = 1.0) -> None:
        self.set(name, self[name] + n)


class ParamProtocol:
    """PARAM_REQUEST_LIST, PARAM_REQUEST_READ and PARAM_SET, answered on an :class:`Outbox`.

    ``reject(link, err, what)`` counts a refused input. Every change is announced on every
    link (a PARAM_VALUE), a refused PARAM_SET is answered on its link with the unchanged
    value and a STATUSTEXT.
    """

    def __init__(self, params: Parameters, outbox: Outbox,
                 reject: Callable[[str, rejections.CodecError, str], None]):
        self.params = params
        self.outbox = outbox
        self.reject = reject
        params.on_change(lambda name, _value: self.value(None, name))

    def value(self, link: str | None, name: str) -> None:
        """PARAM_VALUE of ``name`` on ``link`` (None: every link)."""
        names = self.params.names()
        self.outbox.send(link, "param_value", name.encode(), self.params[name],
                         m.MAV_PARAM_TYPE_REAL32, len(names), names.index(name))

    def request_list(self, link: str) -> None:
        for name in self.params.names():
            self.value(link, name)

    def request_read(self, link: str, msg: Any) -> None:
        """PARAM_VALUE for the parameter named (index < 0) or at the index; unknown: nothing."""
        names = self.params.names()
        pid = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode(
            "ascii", "replace")
        name = pid.rstrip("\x00") if msg.param_index < 0 else (
            names[msg.param_index] if msg.param_index < len(names) else "")
        if name in self.params:
            self.value(link, name)

    def param_set(self, link: str, msg: Any) -> bool:
        """PARAM_SET: set and announced if valid; else refused, counted, the old value sent."""
        pid = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode(
            "ascii", "replace")
        name = pid.rstrip("\x00")
        value = float(msg.param_value)
        err = self.params.check(name, value)
        if err is not None:
            self.reject(link, err, "PARAM_SET")
            if name in self.params:  # unknown: no PARAM_VALUE, as PX4 (the GCS times out)
                statustext(self.outbox, f"{name}: refused {value:g}", m.MAV_SEVERITY_WARNING)
                self.value(link, name)
            return False
        log.info("param set", extra=fields(name=name, value=value))
        self.params.set(name, value)
        return True
