"""The vehicle's modes and arming: one table-driven state machine, modelled on PX4's commander.

PX4's commander keeps an arming state (disarmed, armed), the navigation state
the user intends (``nav_state_user_intention``) and, over it, the action of
the worst active failsafe; the state flown is the failsafe's when there is
one (``Commander.cpp``, ``failsafe/framework.cpp``). This module does the same
for the navigation states of :class:`~services.uavsim.flavour.Nav`, from
three tables:

* :data:`REQUIREMENTS`: what a state needs to run (PX4's ``mode_requirements.cpp``):
  a live setpoint stream for OFFBOARD (not under ArduPilot's GUIDED), a valid
  mission for MISSION, the sticks for POSITION, a home for RETURN, and the
  vehicle's own clock for the states that need flight time (in lockstep the
  companion's stamps are the only clock: services/uavsim/clock.py). A request
  for a state that cannot run is refused.
* :data:`ARMING_CHECKS` and :data:`PREVENTS_ARMING`: the pre-arm checks (charge
  left, home, inside the geofence, the current state can run) and the states
  in which the vehicle never arms (PX4: Return and Land; ArduPilot also AUTO).
* :data:`DONE`: the automatic transitions when a state's job is done
  (take-off → Hold, or GUIDED for ArduPilot; mission → Hold; return → Land).

Every refusal is an :class:`Outcome`: the COMMAND_ACK result (the flavour's:
PX4 TEMPORARILY_REJECTED, ArduPilot FAILED; DENIED for a mission start
without a mission, as PX4) and the STATUSTEXT a ground station shows.
Failsafes are chosen by services/uavsim/failsafe.py from the same
:class:`Conditions`. Nothing here does I/O or reads a clock.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

from services.common import mav

from .flavour import Flavour, Nav

m = mav.mavlink
ACCEPTED = int(m.MAV_RESULT_ACCEPTED)


class Req(Enum):
    """What a navigation state needs to run."""

    OFFBOARD_SIGNAL = "no setpoint stream"
    MISSION = "no valid mission"
    MANUAL_CONTROL = "no manual control"
    HOME = "no home position"
    OWN_CLOCK = "lockstep clock: no flight time"


@dataclass(frozen=True)
class Conditions:
    """What the state machine knows of the vehicle when it decides (the endpoint's snapshot)."""

    offboard_signal: bool = False  #: setpoints heard within COM_OF_LOSS_T
    offboard_resumed: bool = False  #: and live for COM_OF_RSM_T since the stream (re)started
    offboard_expected: bool = True  #: a stream has flown this offboard episode (ArduPilot)
    manual_control: bool = False  #: MANUAL_CONTROL heard recently
    mission_valid: bool = False  #: a mission with an item to fly
    mission_takeoff: bool = False  #: it starts with a take-off item
    home_valid: bool = True
    own_clock: bool = True  #: the vehicle flies on its own clock (realtime)
    battery_left: bool = True
    inside_fence: bool = True
    landed: bool = True


REQUIREMENTS: dict[Nav, frozenset[Req]] = {
    Nav.OFFBOARD: frozenset({Req.OFFBOARD_SIGNAL}),
    Nav.HOLD: frozenset(),
    Nav.TAKEOFF: frozenset(),
    Nav.LAND: frozenset(),
    Nav.RETURN: frozenset({Req.HOME, Req.OWN_CLOCK}),
    Nav.MISSION: frozenset({Req.MISSION, Req.OWN_CLOCK}),
    Nav.POSITION: frozenset({Req.MANUAL_CONTROL, Req.OWN_CLOCK}),
}
#: the states the vehicle does not arm in (PX4: mode_req_prevent_arming; ArduPilot: RTL, LAND
#: and AUTO are not armable modes)
PREVENTS_ARMING = {"px4": frozenset({Nav.RETURN, Nav.LAND}),
                   "ardupilot": frozenset({Nav.RETURN, Nav.LAND, Nav.MISSION})}
#: the pre-arm checks, in order: (condition that must hold, why the arming is refused)
ARMING_CHECKS: tuple[tuple[str, str], ...] = (
    ("battery_left", "battery empty"),
    ("home_valid", "no home position"),
    ("inside_fence", "vehicle outside geofence"),
)
#: a state's job done → the state that follows (ArduPilot's take-off stays in GUIDED, its
#: finished mission in AUTO, holding at the last waypoint)
DONE: dict[str, dict[Nav, Nav]] = {
    "px4": {Nav.TAKEOFF: Nav.HOLD, Nav.MISSION: Nav.HOLD, Nav.RETURN: Nav.LAND},
    "ardupilot": {Nav.TAKEOFF: Nav.OFFBOARD, Nav.MISSION: Nav.MISSION, Nav.RETURN: Nav.LAND},
}


@dataclass(frozen=True)
class Outcome:
    """A command's answer: the COMMAND_ACK result and the STATUSTEXT ('' for none)."""

    result: int
    text: str = ""
    severity: int = int(m.MAV_SEVERITY_INFO)

    @property
    def accepted(self) -> bool:
        return self.result == ACCEPTED


@dataclass(frozen=True)
class Failsafe:
    """An active failsafe: why, the state it flies, when it clears (services/uavsim/failsafe.py)."""

    cause: str  #: offboard_lost, geofence, battery_empty
    action: Nav | None  #: None: a warning only
    text: str
    #: "condition" (the state returns once the cause is gone), "mode" (a mode change or a
    #: disarm ends it), "disarm"
    clears: str


@dataclass
class Commander:
    """Arming state, intended navigation state and active failsafe of one vehicle."""

    flavour: Flavour
    armed: bool = False
    intended: Nav = Nav.HOLD
    failsafe: Failsafe | None = None
    #: (from, to, why) of every change of the state flown, oldest first; the endpoint takes them
    changes: list[tuple[Nav, Nav, str]] = field(default_factory=list)

    @property
    def nav(self) -> Nav:
        """The state flown: the failsafe's action when one is active, else the intended one."""
        if self.failsafe is not None and self.failsafe.action is not None:
            return self.failsafe.action
        return self.intended

    def name(self, nav: Nav | None = None) -> str:
        return self.flavour.names[nav or self.nav]

    # -- checks --------------------------------------------------------------------------------
    def missing(self, nav: Nav, c: Conditions) -> Req | None:
        """The first requirement of ``nav`` that does not hold; None when it can run."""
        needs = REQUIREMENTS[nav]
        if nav is Nav.OFFBOARD and self.flavour.guided:
            needs = needs - {Req.OFFBOARD_SIGNAL}  # GUIDED holds until a setpoint comes
        have = {Req.OFFBOARD_SIGNAL: c.offboard_signal, Req.MISSION: c.mission_valid,
                Req.MANUAL_CONTROL: c.manual_control, Req.HOME: c.home_valid,
                Req.OWN_CLOCK: c.own_clock}
        return next((r for r in Req if r in needs and not have[r]), None)

    def refuse(self, text: str, result: int | None = None) -> Outcome:
        return Outcome(self.flavour.refused if result is None else result, text,
                       int(m.MAV_SEVERITY_WARNING))

    # -- requests ------------------------------------------------------------------------------
    def request(self, nav: Nav, c: Conditions, why: str = "commanded") -> Outcome:
        """A mode change (DO_SET_MODE, SET_MODE, or a command that implies one)."""
        name = self.name(nav)
        need = self.missing(nav, c)
        if need is not None:
            return self.refuse(f"{name} refused: {need.value}")
        if (nav is Nav.MISSION and self.flavour.guided and self.armed and c.landed
                and not c.mission_takeoff):
            return self.refuse("Auto: Missing Takeoff Cmd")  # ArduCopter's ModeAuto::init
        self._set(nav, why, clear_failsafe=True)
        return Outcome(ACCEPTED)

    def arm(self, c: Conditions) -> Outcome:
        if self.armed:
            return Outcome(ACCEPTED)
        refused = self.arming_refusal(c, self.intended)
        if refused is not None:
            return refused
        self.armed = True
        return Outcome(ACCEPTED, "Armed by external command")

    def arming_refusal(self, c: Conditions, nav: Nav) -> Outcome | None:
        """Why the vehicle would not arm in ``nav`` (the pre-arm checks); None: it would."""
        for condition, why in ARMING_CHECKS:
            if not getattr(c, condition):
                return self.refuse(f"Arming denied: {why}")
        if nav in PREVENTS_ARMING[self.flavour.name]:
            return self.refuse(f"Arming denied: not in {self.name(nav)}")
        need = self.missing(nav, c)
        if need is not None:
            return self.refuse(f"Arming denied: {self.name(nav)}: {need.value}")
        return None

    def disarm(self, c: Conditions, forced: bool = False, why: str = "external command"
               ) -> Outcome:
        if not self.armed:
            return Outcome(ACCEPTED)
        if not (c.landed or forced):
            return self.refuse("Disarming denied: not landed")
        self.armed = False
        self.failsafe = None
        if self.intended in PREVENTS_ARMING[self.flavour.name] and not self.flavour.guided:
            # PX4 leaves a state it cannot arm in; ArduPilot stays (MAVSDK sets a mode first)
            self._set(Nav.HOLD, "disarmed")
        return Outcome(ACCEPTED, f"Disarmed by {why}")

    def takeoff(self, c: Conditions) -> Outcome:
        if not self.armed:
            return self.refuse("Takeoff denied: not armed")
        if self.flavour.guided and self.nav is not Nav.OFFBOARD:
            return self.refuse(f"Takeoff denied: not in {self.name(Nav.OFFBOARD)}")
        return self.request(Nav.TAKEOFF, c, "take-off")

    def land(self, c: Conditions) -> Outcome:
        out = self.request(Nav.LAND, c, "land")
        return Outcome(ACCEPTED, "Landing at current position") if out.accepted else out

    def rtl(self, c: Conditions) -> Outcome:
        out = self.request(Nav.RETURN, c, "return")
        return Outcome(ACCEPTED, "Returning to launch") if out.accepted else out

    def mission_start(self, c: Conditions) -> Outcome:
        """MISSION_START: Mission, and arm (PX4's commander does both; ArduCopter starts only
        an armed vehicle)."""
        if not c.mission_valid:
            return self.refuse("Mission start denied! No valid mission",
                               int(m.MAV_RESULT_DENIED))
        if not self.armed:
            if self.flavour.guided:
                return self.refuse("Mission start denied: not armed")
            refused = self.arming_refusal(c, Nav.MISSION)
            if refused is not None:
                return refused
        out = self.request(Nav.MISSION, c, "mission start")
        if out.accepted and not self.armed:
            self.armed = True
            return Outcome(ACCEPTED, "Armed by mission start")
        return out

    def reposition(self, c: Conditions, change_mode: bool) -> Outcome:
        """DO_REPOSITION: PX4 flies it in Hold, ArduPilot in GUIDED; only in the air."""
        target = Nav.OFFBOARD if self.flavour.guided else Nav.HOLD
        if not self.armed or c.landed:
            return self.refuse("Reposition denied: not flying")
        if not c.own_clock:
            return self.refuse(f"Reposition denied: {Req.OWN_CLOCK.value}")
        if self.nav is not target and not change_mode:
            return Outcome(int(m.MAV_RESULT_UNSUPPORTED), "Reposition: mode change flag unset",
                           int(m.MAV_SEVERITY_WARNING))
        return self.request(target, c, "reposition")

    # -- automatic transitions -----------------------------------------------------------------
    def done(self, nav: Nav) -> None:
        """``nav``'s job is done (take-off altitude, last mission item, home reached)."""
        if self.nav is nav:
            follow = DONE[self.flavour.name].get(nav)
            if follow is not None and follow is not nav:
                self._set(follow, f"{self.name(nav)} done")

    def set_failsafe(self, fs: Failsafe | None) -> None:
        """Make ``fs`` the active failsafe (None: none); the state flown follows it."""
        before = self.nav
        self.failsafe = fs
        if self.nav is not before:
            self.changes.append((before, self.nav, fs.text if fs is not None else "recovered"))

    def _set(self, nav: Nav, why: str, clear_failsafe: bool = False) -> None:
        before = self.nav
        self.intended = nav
        if clear_failsafe and self.failsafe is not None and self.failsafe.clears != "disarm":
            self.failsafe = None  # the user took over with a mode switch
        if self.nav is not before:
            self.changes.append((before, self.nav, why))
