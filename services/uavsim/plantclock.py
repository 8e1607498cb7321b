"""The plant on the vehicle's own clock: the setpoint stream flown period by period, as it comes.

On its own clock (``--clock realtime``, as PX4 SITL) a vehicle flying the mission's
multirotor (services/uavsim/plantsim.py) integrates the plant for each period of the
setpoint stream (1 / ``MultirotorParams.setpoint_hz``, 50 ms at 20 Hz) once the
simulated clock has passed it (:func:`fly_due`, from the vehicle's loop,
services/uavsim/endpoint.py), towards the newest target: in OFFBOARD the companion's
newest setpoint [p*, v*] (as it arrived, services/uavsim/autopilot.py), in the other
states the navigator's target of the current ΔT (services/uavsim/navigator.py). A
vehicle on the ground or disarmed does not fly. A loop stalled for long skips ahead
rather than flying a burst (as :class:`~services.uavsim.clock.RealtimeClock`).
"""

from __future__ import annotations

from dualpilot.model.dynamics import Array

from .autopilot import Autopilot
from .flavour import Nav

#: the most stream periods one pass flies (a stalled loop skips the rest)
MAX_PERIODS = 20


def target_now(ap: Autopilot) -> Array | None:
    """The target [p*, v*] the plant flies now (module docstring; None: none yet)."""
    plant = ap.vehicle.plant
    if ap.commander.nav is Nav.OFFBOARD and ap.nav.setpoint is not None:
        return ap.nav.setpoint[0]
    return None if plant is None else plant.held


def fly_due(ap: Autopilot, now_ms: int) -> int:
    """Fly the stream periods due by ``now_ms`` (the vehicle's simulated clock, ms since boot);
    how many were flown."""
    v = ap.vehicle
    plant = v.plant
    if plant is None or not plant.own_clock:
        return 0
    period_ms = max(int(round(1000.0 / plant.plant.params.setpoint_hz)), 1)
    behind = (now_ms - plant.time_ms) // period_ms
    if behind > MAX_PERIODS:
        plant.idle(plant.time_ms + (behind - MAX_PERIODS) * period_ms)
    flown = 0
    while plant.time_ms + period_ms <= now_ms:
        end_ms = plant.time_ms + period_ms
        target = target_now(ap)
        if target is None or not ap.commander.armed or ap.nav.landed:
            plant.idle(end_ms)  # on the ground: the clock runs, nothing flies
            continue
        v.state = plant.fly_held(target, period_ms / 1000.0, end_ms)
        flown += 1
    return flown
