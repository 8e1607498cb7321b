"""Which failsafe is active: offboard loss, geofence breach, empty battery (PX4's framework).

:meth:`FailsafeMonitor.select` looks at the :class:`~services.uavsim.commander.Conditions`
and the state machine and returns the failsafe to fly, the worst action
winning (PX4's order: warn < hold < return < land), each cleared by its own
rule (``Failsafe.clears``):

==============  ======================================  ==================  =====================
cause           when                                    action              clears
==============  ======================================  ==================  =====================
offboard_lost   intended OFFBOARD, no setpoint for      hold                the stream back for
                COM_OF_LOSS_T (ArduPilot's GUIDED:                          COM_OF_RSM_T, a mode
                only once a stream has flown it)                            change, disarming
manual_lost     intended POSITION, no MANUAL_CONTROL    hold                the sticks back, a
                for 1 s (PX4: NAV_RCL_ACT)                                  mode change
geofence        armed, in the air, the vehicle leaves   GF_ACTION: none,    a mode change,
                the fence                               warn, hold, return, disarming
                                                        land
battery_empty   armed, no charge left                   land                disarming
==============  ======================================  ==================  =====================

What the offboard-loss hold does depends on who keeps time
(services/uavsim/clock.py): on the vehicle's own clock (PX4 SITL) it brakes
to a stop; in lockstep, where the supervisor is the clock, it holds *as it
is*: no simulated time passes until the next stamp, so a silent companion
pauses the simulated world instead of changing it (services/uavsim/navigator.py).
The failsafe stays visible to a ground station (mode, STATUSTEXT,
``SIM_FAILSAFES``) and the supervisor records it as the fault ``vehicle_hold``
(services/supervisor/faults.py).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .commander import Commander, Conditions, Failsafe
from .flavour import Nav

OFFBOARD_LOST = "offboard_lost"
MANUAL_LOST = "manual_lost"
GEOFENCE = "geofence"
BATTERY_EMPTY = "battery_empty"
#: GF_ACTION (PX4's values) → the state flown; 1 (warn) and 0 (none) fly nothing
GF_ACTIONS: dict[int, Nav] = {2: Nav.HOLD, 3: Nav.RETURN, 5: Nav.LAND}
#: PX4's failsafe Action order: the worst wins
RANK = {None: 0, Nav.HOLD: 1, Nav.RETURN: 2, Nav.LAND: 3}


@dataclass
class FailsafeMonitor:
    """Chooses the active failsafe; breaches count on the way out of the fence (an edge), so
    a ground station can fly the vehicle back in after it has taken over."""

    _was_inside: bool = True
    _had_charge: bool = True
    #: warnings to show (GF_ACTION 1), taken by the endpoint
    notes: list[str] = field(default_factory=list)

    def select(self, cmd: Commander, c: Conditions, gf_action: int) -> Failsafe | None:
        active = self._still_active(cmd, c)
        candidates = [] if active is None else [active]
        if (cmd.armed and cmd.intended is Nav.OFFBOARD and c.offboard_expected
                and not c.offboard_signal):
            candidates.append(Failsafe(OFFBOARD_LOST, Nav.HOLD, "offboard lost", "condition"))
        if cmd.armed and cmd.intended is Nav.POSITION and not c.manual_control:
            candidates.append(Failsafe(MANUAL_LOST, Nav.HOLD, "manual control lost",
                                       "condition"))
        breach = not c.inside_fence
        if cmd.armed and not c.landed and breach and self._was_inside:
            action = GF_ACTIONS.get(gf_action)
            if action is not None:
                candidates.append(Failsafe(GEOFENCE, action, "geofence breached", "mode"))
            elif gf_action == 1:
                self.notes.append("Geofence breached")
        self._was_inside = not breach or not cmd.armed
        empty = not c.battery_left
        if cmd.armed and empty and self._had_charge:
            candidates.append(Failsafe(BATTERY_EMPTY, Nav.LAND, "battery empty", "disarm"))
        self._had_charge = not empty
        return max(candidates, key=lambda f: RANK[f.action], default=None)

    @staticmethod
    def _still_active(cmd: Commander, c: Conditions) -> Failsafe | None:
        """The active failsafe, unless its own rule has cleared it."""
        fs = cmd.failsafe
        if fs is None or not cmd.armed:
            return None
        if fs.cause == OFFBOARD_LOST and (c.offboard_resumed or cmd.intended is not Nav.OFFBOARD):
            return None
        if fs.cause == MANUAL_LOST and (c.manual_control or cmd.intended is not Nav.POSITION):
            return None
        return fs
