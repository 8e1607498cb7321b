"""Which SET_POSITION_TARGET_LOCAL_NED type masks the vehicle flies.

``type_mask`` bits mean *ignore* (MAVLink POSITION_TARGET_TYPEMASK). The
vehicle tracks a position, optionally with a velocity (Eq. 1 has no
acceleration or attitude input), so it accepts:

* position used (bits 0–2 clear), velocity either all used (bits 3–5 clear)
  or all ignored (set), acceleration ignored (bits 6–8 set);
* bit 9 (force setpoint) and the yaw bits 10–11 either way: the yaw follows
  the velocity (services/uavsim/vehicle.py), so a yaw or yaw-rate target is
  ignored. MAVSDK's ``set_position_ned`` sends 2552 (yaw used),
  ``set_position_velocity_ned`` 2496; our supervisor 3520 and 3576.

Anything else (a velocity-only or acceleration setpoint, PX4's takeoff/land
setpoint-type bits ≥ 12) is refused. :func:`normalised` maps an accepted
mask onto the two the codec checks (3520, 3576).
"""

from __future__ import annotations

from typing import Any

from services.common import mav

#: bits the vehicle accepts either way: force setpoint, yaw, yaw rate
IGNORED_EITHER_WAY = mav.TYPE_MASK_FORCE_BIT | mav.TYPE_MASK_YAW_BITS
KNOWN_BITS = (mav.TYPE_MASK_POSITION_BITS | mav.TYPE_MASK_VELOCITY_BITS
              | mav.TYPE_MASK_ACCEL_BITS | IGNORED_EITHER_WAY)


def canonical_mask(type_mask: int) -> int | None:
    """3520 (position + velocity) or 3576 (position only) for an accepted mask, else None."""
    if type_mask & ~KNOWN_BITS or type_mask & mav.TYPE_MASK_POSITION_BITS:
        return None
    if type_mask & mav.TYPE_MASK_ACCEL_BITS != mav.TYPE_MASK_ACCEL_BITS:
        return None
    vel = type_mask & mav.TYPE_MASK_VELOCITY_BITS
    if vel == 0:
        return mav.TYPE_MASK_POS_VEL
    if vel == mav.TYPE_MASK_VELOCITY_BITS:
        return mav.TYPE_MASK_POS
    return None


class _Normalised:
    """A setpoint message seen with its type mask replaced (every other field unchanged)."""

    def __init__(self, msg: Any, type_mask: int):
        self._msg = msg
        self.type_mask = type_mask

    def __getattr__(self, name: str) -> Any:
        return getattr(self._msg, name)


def normalised(msg: Any) -> Any:
    """``msg`` with an accepted type mask as 3520/3576; unchanged (the codec refuses it) else."""
    mask = canonical_mask(int(msg.type_mask))
    return msg if mask is None else _Normalised(msg, mask)
