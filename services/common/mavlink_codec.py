"""MAVLink messages ↔ core types, validated: the LOCAL_NED frame, setpoints, bad frames.

The core's local frame is (east, north) in metres, state x = [p_east, p_north,
v_east, v_north] (Sec. IV, 2-D at fixed altitude), or in 3-D (docs/three_d.md)
x = [p_east, p_north, p_up, v_east, v_north, v_up] (z up, m above flat ground).
MAVLink's LOCAL_NED is (north, east, down): z = −p_up, vz = −v_up.
:func:`state_to_ned` and :func:`state_from_ned` are the only conversions between the
two. Its constants are in services/common/mav.py, the
stdlib framing in services/common/mavframe.py.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import numpy as np

from dualpilot.mission.braking import braking_overshoot_m
from dualpilot.model.altitude import AltitudeBand
from dualpilot.model.dynamics import Array, DynamicsParams
from services.common import mav
from services.common.limits import check_state_values, finite
from services.common.rejections import Reason, invalid

#: A setpoint may lie at most this fraction of the area outside it (a braking target near the
#: edge can overshoot; planners keep their plans inside).
SETPOINT_AREA_MARGIN = 0.1
#: A 3-D setpoint's altitude may lie at most this far (m) outside the mission's band
#: [floor_m, ceiling_m] (docs/three_d.md), where the vehicle knows it (else [0,
#: MAX_SETPOINT_ALT_M]): planners keep their plans in the band, and braking from the band
#: at the speed limit overshoots it by 19.86 m at the paper's Eq. (1) values (p_(t+1) = p_t +
#: ΔT v_t: 15 m, then 0.8·15 − 7.5/1.05 = 4.86 m, then at rest). A vehicle that knows the
#: mission's Eq. (1) grows the band by :func:`setpoint_band_margin_m` (never less than this).
SETPOINT_BAND_MARGIN_M = 20.0


def setpoint_band_margin_m(dynamics: DynamicsParams) -> float:
    """How far (m) a 3-D setpoint may lie outside the band under ``dynamics``: the braking
    overshoot from the speed limit (:func:`dualpilot.mission.braking.braking_overshoot_m`)
    rounded up to the metre (a µm of floating-point error aside), at least
    :data:`SETPOINT_BAND_MARGIN_M`."""
    return max(SETPOINT_BAND_MARGIN_M, float(math.ceil(braking_overshoot_m(dynamics) - 1e-6)))
MAX_SETPOINT_SPEED_MPS = 100.0
MAX_SETPOINT_ALT_M = 10_000.0
#: The longest a setpoint may be stamped ahead of the vehicle's clock (s of simulated time):
#: one step is ΔT plus the planning interval, at most the supervisor's plan deadline.
MAX_SETPOINT_LEAD_S = 600.0
#: The largest UDP datagram a vehicle link parses (one MAVLink 2 frame is at most 280 bytes;
#: a sender may pack a few); larger ones are rejected unread (``too_large``).
MAX_MAVLINK_DATAGRAM = 4096


def state_to_ned(x: Array, altitude_m: float) -> tuple[float, float, float, float, float, float]:
    """Core state → NED (x, y, z, vx, vy, vz): a planar one (east, north, v_east, v_north) at
    the fixed ``altitude_m`` and vz = 0, a 3-D one (6 entries) at its own altitude and climb
    (``altitude_m`` unused)."""
    x = check_state_values(x)
    if len(x) == 6:
        return (float(x[1]), float(x[0]), -float(x[2]), float(x[4]), float(x[3]),
                -float(x[5]))
    return (float(x[1]), float(x[0]), -float(altitude_m), float(x[3]), float(x[2]), 0.0)


def state_from_ned(n: float, e: float, vn: float, ve: float,
                   d: float | None = None, vd: float | None = None) -> Array:
    """NED north/east position and velocity → core state (with ``d`` and ``vd``, down
    positive, the 3-D state: p_up = −d, v_up = −vd); raises CodecError if out of range."""
    if d is not None and vd is not None:
        return check_state_values(np.array([e, n, -d, ve, vn, -vd], dtype=float),
                                  "MAVLink state")
    return check_state_values(np.array([e, n, ve, vn], dtype=float), "MAVLink state")


def setpoint_from_mavlink(msg: Any, area_size_m: float | None = None,
                          lead_ms: int | None = None, range_m: float | None = None,
                          dim: int = 2, band: AltitudeBand | None = None,
                          band_margin_m: float = SETPOINT_BAND_MARGIN_M) -> Array:
    """A SET_POSITION_TARGET_LOCAL_NED as the core target state [p_e, p_n, v_e, v_n] (with
    ``dim`` 3: [p_e, p_n, p_up, v_e, v_n, v_up], p_up = −z, v_up = −vz, the altitude within
    [0, :data:`MAX_SETPOINT_ALT_M`], with ``band`` (a planning mission's) within the band
    grown by ``band_margin_m`` too, and the climb within
    :data:`MAX_SETPOINT_SPEED_MPS` whatever the other checks; ``band`` is unused in 2-D).

    Accepts LOCAL_NED with type_mask 3520 (position + velocity) or 3576
    (position only; velocity target 0). With ``area_size_m`` the position must
    lie in the area [0, A]² grown by :data:`SETPOINT_AREA_MARGIN` × A (a
    planning mission), with ``range_m`` within ``range_m`` of the origin on
    each axis (a vehicle flying where its user puts it); with either, the
    velocity must lie within :data:`MAX_SETPOINT_SPEED_MPS` per axis and the
    altitude (``-z``) within [0, :data:`MAX_SETPOINT_ALT_M`]; with ``lead_ms``
    (the setpoint's ``time_boot_ms`` minus the vehicle's clock) it must be due
    at most :data:`MAX_SETPOINT_LEAD_S` ahead. Raises CodecError (reasons
    ``invalid``, ``not_finite``, ``out_of_range``).
    """
    if msg.coordinate_frame != mav.MAV_FRAME_LOCAL_NED:
        raise invalid(f"setpoint frame {msg.coordinate_frame}, only LOCAL_NED "
                      f"({mav.MAV_FRAME_LOCAL_NED}) is supported")
    if msg.type_mask == mav.TYPE_MASK_POS_VEL:
        x = state_from_ned(msg.x, msg.y, msg.vx, msg.vy)
    elif msg.type_mask == mav.TYPE_MASK_POS:
        x = state_from_ned(msg.x, msg.y, 0.0, 0.0)
    else:
        raise invalid(f"setpoint type_mask {msg.type_mask}: only {mav.TYPE_MASK_POS_VEL} and "
                      f"{mav.TYPE_MASK_POS} are supported")
    if dim == 3:
        return _setpoint3(msg, msg.vz if msg.type_mask == mav.TYPE_MASK_POS_VEL else 0.0,
                          area_size_m, lead_ms, range_m, band, band_margin_m)
    if area_size_m is not None or range_m is not None:
        finite([msg.z], "setpoint z", MAX_SETPOINT_ALT_M)
        if area_size_m is not None:
            margin = SETPOINT_AREA_MARGIN * area_size_m
            if not (np.all(x[:2] >= -margin) and np.all(x[:2] <= area_size_m + margin)):
                raise invalid(f"setpoint position ({x[0]:.6g}, {x[1]:.6g}) m is outside the "
                              f"area [0, {area_size_m:g}]² grown by {margin:g} m",
                              Reason.OUT_OF_RANGE)
        if range_m is not None and np.any(np.abs(x[:2]) > range_m):
            raise invalid(f"setpoint position ({x[0]:.6g}, {x[1]:.6g}) m is more than "
                          f"{range_m:g} m from the origin", Reason.OUT_OF_RANGE)
        if np.any(np.abs(x[2:]) > MAX_SETPOINT_SPEED_MPS) or not -msg.z >= 0.0:
            raise invalid(f"setpoint velocity ({x[2]:.6g}, {x[3]:.6g}) m/s or altitude "
                          f"{-msg.z:.6g} m out of range", Reason.OUT_OF_RANGE)
    if lead_ms is not None and lead_ms > MAX_SETPOINT_LEAD_S * 1000:
        raise invalid(f"setpoint due {lead_ms / 1000:.6g} s after the vehicle's clock "
                      f"(at most {MAX_SETPOINT_LEAD_S:g} s)", Reason.OUT_OF_RANGE)
    return x


def _setpoint3(msg: Any, vz: float, area_size_m: float | None, lead_ms: int | None,
               range_m: float | None, band: AltitudeBand | None, band_margin_m: float) -> Array:
    """The 3-D target of a setpoint: the planar checks on its horizontal part, then its
    altitude (and the ``band``'s, grown by ``band_margin_m``) and climb
    (CodecError ``not_finite`` or ``out_of_range``)."""
    horizontal = setpoint_from_mavlink(msg, area_size_m, lead_ms, range_m)
    finite([msg.z], "setpoint z", MAX_SETPOINT_ALT_M)
    finite([vz], "setpoint vz", MAX_SETPOINT_SPEED_MPS)
    if not -msg.z >= 0.0:
        raise invalid(f"setpoint altitude {-msg.z:.6g} m (z = {msg.z:.6g}) is below the "
                      f"ground", Reason.OUT_OF_RANGE)
    if band is not None and not band.contains(-float(msg.z), band_margin_m):
        raise invalid(f"setpoint altitude {-msg.z:.6g} m is outside the band "
                      f"[{band.floor_m:g}, {band.ceiling_m:g}] m grown by "
                      f"{band_margin_m:g} m", Reason.OUT_OF_RANGE)
    return check_state_values(np.array([horizontal[0], horizontal[1], -float(msg.z),
                                        horizontal[2], horizontal[3], -float(vz)]),
                              "setpoint")


def mavlink_frame_reason(bad_data_reason: str) -> Reason:
    """The :class:`Reason` for a frame pymavlink could not decode (its BAD_DATA ``reason``)."""
    why = bad_data_reason.lower()
    if "signature" in why or "signed" in why:
        return Reason.UNSIGNED
    if "crc" in why:
        return Reason.BAD_CRC
    return Reason.MALFORMED


def check_finite_fields(msg: Any, names: Iterable[str], what: str) -> None:
    """Raise CodecError (``not_finite``) if any of the float fields ``names`` is NaN or ±inf."""
    for name in names:
        value = getattr(msg, name)
        if not math.isfinite(value):
            raise invalid(f"{what}.{name} is {value}", Reason.NOT_FINITE)
