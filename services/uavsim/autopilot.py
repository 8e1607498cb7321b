"""The vehicle without its sockets: the state machine, its failsafes and the navigator, wired.

:class:`Autopilot` owns the components around the state machine
(services/uavsim/commander.py): the failsafe monitor (failsafe.py), the
navigator (navigator.py), the parameters (params.py), the stored mission
and fence (mission.py, geofence.py) and the offboard signal
(:class:`OffboardSignal`), and tells the ground station through an
:class:`~services.uavsim.outbox.Outbox`. It takes a snapshot of the
:class:`~services.uavsim.commander.Conditions` for every decision, carries
out the state changes the commander made (the navigator's targets, a
STATUSTEXT, a HEARTBEAT) and, on the vehicle's own clock, flies each ΔT.
The endpoint (endpoint.py) feeds it what the links receive; a unit test
feeds it directly, with injected times.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from dualpilot.model.altitude import AltitudeBand
from dualpilot.model.dynamics import Array
from services.common import mav, rejections
from services.common.log import fields
from services.common.mavlink_codec import SETPOINT_BAND_MARGIN_M

from . import geofence, missionrun
from .clock import LOCKSTEP, REALTIME
from .commander import Commander, Conditions, Outcome
from .control import OFFBOARD
from .failsafe import OFFBOARD_LOST, FailsafeMonitor
from .flavour import ARDUPILOT, Flavour, Nav
from .geofence import Geofence
from .mission import FENCE, FreeBounds, MissionServer, PlanningBounds
from .missionrun import Frame
from .navigator import Navigator
from .outbox import Outbox, statustext
from .params import Parameters
from .stream_stats import StreamStats
from .vehicle import Vehicle

log = logging.getLogger("services.uavsim")
m = mav.mavlink
#: MANUAL_CONTROL older than this is no manual control (s; PX4's COM_RC_LOSS_T is 0.5)
MANUAL_LOSS_S = 1.0
#: how far from the local frame's origin a vehicle on its own clock flies (m per axis)
FREE_RANGE_M = 50_000.0


@dataclass(frozen=True)
class VehicleSetup:
    """What a vehicle is told at start: its identity, frame, failsafe and clock."""

    sysid: int  #: MAVLink system id (component 1)
    altitude_m: float  #: the fixed flight altitude in lockstep (SIM_ALT_M)
    home: tuple[float, float]  #: deg lat, lon of the local frame's origin
    offboard_loss_s: float  #: hold after this long without setpoints (COM_OF_LOSS_T)
    area_size_m: float = 1000.0  #: lockstep: mission waypoints must lie in [0, area]²
    flavour: Flavour = ARDUPILOT  #: the autopilot it claims to be
    clock: str = LOCKSTEP  #: lockstep or realtime (services/uavsim/clock.py)
    speed_factor: float = 1.0  #: realtime: simulated s per wall s
    home_amsl_m: float = 0.0  #: the origin's altitude above mean sea level
    #: lockstep, a 3-D mission: its altitude band, which setpoints' altitudes must lie in
    #: (grown by ``band_margin_m``); None: no band known
    band: AltitudeBand | None = None
    #: m, how far outside the band a setpoint may lie: the mission's braking overshoot
    #: (services/common/mavlink_codec.py, ``setpoint_band_margin_m``)
    band_margin_m: float = SETPOINT_BAND_MARGIN_M




@dataclass
class OffboardSignal:
    """Each link's setpoint stream as arrival times (monotonic s): live within COM_OF_LOSS_T,
    lasting once live for COM_OF_RSM_T since it (re)started."""

    last: dict[str, float] = field(default_factory=dict)
    since: dict[str, float] = field(default_factory=dict)

    def heard(self, link: str, now: float, loss_s: float) -> None:
        if now - self.last.get(link, -1e18) > loss_s:
            self.since[link] = now  # a new stream starts
        self.last[link] = now

    def live(self, link: str, now: float, loss_s: float) -> bool:
        return link in self.last and now - self.last[link] <= loss_s

    def lasting(self, link: str, now: float, loss_s: float, resume_s: float) -> bool:
        return self.live(link, now, loss_s) and now - self.since[link] >= resume_s


class Autopilot:
    """One vehicle's state machine and flight, fed by the endpoint (module docstring)."""

    def __init__(self, flavour: Flavour, vehicle: Vehicle, params: Parameters, outbox: Outbox,
                 mission: MissionServer, navigator: Navigator,
                 control_link: Callable[[], str] = lambda: OFFBOARD, sysid: int = 1):
        self.flavour = flavour
        self.sysid = sysid
        self.vehicle = vehicle
        self.params = params
        self.outbox = outbox
        self.mission = mission
        self.nav = navigator
        self.control_link = control_link
        self.commander = Commander(flavour)
        self.failsafes = FailsafeMonitor()
        self.fence = Geofence()
        self.signal = OffboardSignal()
        self.stream_stats = StreamStats()
        self.failsafe_since = 0.0
        self.manual_heard = -1e18
        self.touchdown_ms: int | None = None

    # -- what the state machine sees -----------------------------------------------------------
    @property
    def own_clock(self) -> bool:
        return self.nav.own_clock

    def conditions(self, now: float, link: str | None = None) -> Conditions:
        """The snapshot a decision is made on; ``link``: the link whose stream would fly."""
        p = self.params
        link = self.control_link() if link is None else link
        loss = p["COM_OF_LOSS_T"]
        x = self.vehicle.state
        items = self.mission.items
        positional = [it for it in items if missionrun.flown_position(it)]
        return Conditions(
            offboard_signal=self.signal.live(link, now, loss),
            offboard_resumed=self.signal.lasting(link, now, loss, p["COM_OF_RSM_T"]),
            offboard_expected=not self.flavour.guided or self.nav.flown_offboard,
            manual_control=now - self.manual_heard <= MANUAL_LOSS_S,
            mission_valid=bool(positional) or any(
                it.command == missionrun.RTL for it in items),
            mission_takeoff=bool(positional) and positional[0].command == missionrun.TAKEOFF,
            own_clock=self.own_clock,
            battery_left=self.vehicle.battery_fraction > 0,
            inside_fence=self.fence.inside(float(x[0]), float(x[1])),
            landed=self.nav.landed)

    def decide(self, fn: Callable[[Conditions], Outcome], now: float, link: str | None = None
               ) -> Outcome:
        """Run one request of the state machine on a fresh snapshot, then carry out what it
        changed; the outcome's STATUSTEXT goes to the ground station."""
        armed, failsafe = self.commander.armed, self.commander.failsafe
        out = fn(self.conditions(now, link))
        if self.commander.failsafe != failsafe:  # a mode change or a disarm ended it
            self._failsafe_changed(failsafe, self.commander.failsafe, now)
        if out.text:
            statustext(self.outbox, out.text, out.severity)
        if self.commander.armed != armed:
            self._armed_changed(now)
        self.apply_changes(now)
        return out

    # -- carrying changes out ------------------------------------------------------------------
    def apply_changes(self, now: float) -> None:
        """The navigator's targets, a STATUSTEXT and a HEARTBEAT for every change of state."""
        cmd = self.commander
        while cmd.changes:
            before, after, why = cmd.changes.pop(0)
            fs = cmd.failsafe
            failsafe_hold = fs is not None and fs.cause == OFFBOARD_LOST and after is Nav.HOLD
            self.nav.enter(after, brake=self.own_clock or not failsafe_hold,
                           mission_seq=self.mission.current)
            log.info("mode", extra=fields(mode=cmd.name(after), was=cmd.name(before), why=why))
            statustext(self.outbox, f"{cmd.name(after)}: {why}")
            if after is Nav.TAKEOFF and not self.own_clock:
                cmd.done(Nav.TAKEOFF)  # lockstep: airborne at once (Sec. IV is 2-D)
        self.heartbeat()

    def _armed_changed(self, now: float) -> None:
        if self.commander.armed:
            self.nav.armed_in(self.commander.nav)
            log.info("armed", extra=fields(mode=self.commander.name()))
        else:
            self.nav.disarmed()
            self.touchdown_ms = None
            log.info("disarmed")

    def heartbeat(self) -> None:
        cmd = self.commander
        base = m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | m.MAV_MODE_FLAG_STABILIZE_ENABLED
        if cmd.nav is Nav.OFFBOARD:
            base |= m.MAV_MODE_FLAG_GUIDED_ENABLED
        if cmd.nav in (Nav.MISSION, Nav.RETURN, Nav.TAKEOFF, Nav.LAND):
            base |= m.MAV_MODE_FLAG_AUTO_ENABLED
        if cmd.armed:
            base |= m.MAV_MODE_FLAG_SAFETY_ARMED
        state = m.MAV_STATE_ACTIVE if cmd.armed else m.MAV_STATE_STANDBY
        self.outbox.send(None, "heartbeat", m.MAV_TYPE_QUADROTOR, self.flavour.autopilot,
                         int(base), self.flavour.custom_mode(cmd.nav), state)

    # -- the watch: failsafes and landing ------------------------------------------------------
    def watch(self, now: float) -> None:
        """Choose the failsafe and disarm after a landing (call after the links were read)."""
        cmd = self.commander
        c = self.conditions(now)
        before = cmd.failsafe
        fs = self.failsafes.select(cmd, c, int(self.params["GF_ACTION"]))
        for note in self.failsafes.notes:
            statustext(self.outbox, note, m.MAV_SEVERITY_WARNING)
        self.failsafes.notes.clear()
        if fs != before:
            self._failsafe_changed(before, fs, now)
            flown = cmd.nav
            cmd.set_failsafe(fs)
            if fs is not None and fs.action is flown and getattr(before, "cause", None) != fs.cause:
                self.nav.enter(flown)  # already in that state (a goto in Hold): stop there
            self.apply_changes(now)
        if (cmd.armed and c.landed and self.touchdown_ms is not None
                and self.vehicle.time_ms - self.touchdown_ms
                >= self.params["COM_DISARM_LAND"] * 1000):
            self.decide(lambda cc: cmd.disarm(cc, why="landing"), now)

    def _failsafe_changed(self, before: object, fs: object, now: float) -> None:
        was = getattr(before, "cause", None)
        cause = getattr(fs, "cause", None)
        if cause == OFFBOARD_LOST and was != OFFBOARD_LOST:
            self.failsafe_since = now
            self.stream_stats.failsafe()
            self.params.add("SIM_FAILSAFES")
            silence = round(now - self.signal.last.get(self.control_link(), now), 3)
            log.warning("offboard setpoints lost: " + (
                "braking to a hold" if self.own_clock else "holding as it is (lockstep: no "
                "simulated time passes until the next setpoint)"), extra=fields(
                    silence_s=silence, time_ms=self.vehicle.time_ms))
        elif was == OFFBOARD_LOST and cause != OFFBOARD_LOST:
            self.stream_stats.failsafe_s += now - self.failsafe_since
            log.info("offboard failsafe over", extra=fields(
                held_s=round(now - self.failsafe_since, 3)))
        if cause is not None and cause != was:
            statustext(self.outbox, f"Failsafe: {getattr(fs, 'text', cause)}",
                       m.MAV_SEVERITY_CRITICAL)
            if cause != OFFBOARD_LOST:
                log.warning("failsafe", extra=fields(cause=cause))

    @property
    def in_offboard_failsafe(self) -> bool:
        fs = self.commander.failsafe
        return fs is not None and fs.cause == OFFBOARD_LOST

    # -- flying --------------------------------------------------------------------------------
    def setpoint(self, link: str, target: Array, alt_m: float, due_ms: int, now: float) -> bool:
        """A checked setpoint from ``link``: its stream is live; the link in control's flies
        (lockstep: one step of Eq. (1) now; realtime: the newest target). True if it moved."""
        cmd = self.commander
        self.signal.heard(link, now, self.params["COM_OF_LOSS_T"])
        if link != self.control_link():
            return False  # the companion waiting for a hand-back
        self.stream_stats.setpoint(now, cmd.nav is Nav.OFFBOARD or self.in_offboard_failsafe)
        self.nav.setpoint = (target, alt_m)
        if not (cmd.nav is Nav.OFFBOARD and cmd.armed) or self.own_clock or self.nav.landed:
            return False
        if not self.nav.fly_setpoint(target, due_ms):
            return False
        self.progress()
        return True

    def fly(self, due_ms: int, now: float) -> bool:
        """One ΔT on the vehicle's own clock, ending at ``due_ms``; True if it flew."""
        cmd = self.commander
        ev = self.nav.step(cmd.nav, cmd.armed, due_ms)
        if not cmd.armed:
            return False
        if ev.touchdown:
            self.touchdown_ms = due_ms
            log.info("landed", extra=fields(time_ms=due_ms))
        for seq in ev.reached or []:
            self.outbox.send(None, "mission_item_reached", seq)
        if cmd.nav is Nav.MISSION and self.nav.mission is not None:
            if self.mission.current != self.nav.mission.current_seq:
                self.mission.current = self.nav.mission.current_seq
                self.mission.send_current()
        elif cmd.nav is Nav.OFFBOARD:
            self.progress()
        if ev.rtl:
            self.decide(cmd.rtl, now)
        if ev.done is not None:
            cmd.done(ev.done)
            self.apply_changes(now)
        return True

    def manual(self, msg: Any, now: float) -> None:
        """MANUAL_CONTROL from the link in control: the sticks of POSITION."""
        self.manual_heard = now
        self.nav.sticks = (float(msg.x), float(msg.y), float(msg.z))

    def progress(self) -> None:
        """Offboard flight past the mission's waypoints (System 1 flying the operator's route):
        MISSION_ITEM_REACHED within MIS_ACC_RAD."""
        x = self.vehicle.state
        reached = self.mission.progress(float(x[0]), float(x[1]), self.params["MIS_ACC_RAD"])
        for seq in reached:
            self.outbox.send(None, "mission_item_reached", seq)
        if reached:
            self.mission.send_current()

    def mission_changed(self, mission_type: int) -> None:
        """A stored mission or fence changed: the fence's zones (ValueError refuses the upload:
        MissionServer._commit), or MIS_ID and the ground station told."""
        ms = self.mission
        if mission_type == FENCE:
            self.fence = Geofence(tuple(geofence.zones(ms.stored[FENCE], ms.bounds.origin)))
            statustext(self.outbox, f"geofence: {len(self.fence.zones)} zones")
            return
        self.params.set("MIS_ID", float(ms.version))
        waypoints = sum(it.is_waypoint() for it in ms.items)
        statustext(self.outbox, f"mission {ms.version}: {len(ms.items)} items, "
                                f"{waypoints} waypoints")
        ms.send_current()


def build(setup: VehicleSetup, vehicle: Vehicle, params: Parameters, outbox: Outbox,
          control_link: Callable[[], str] = lambda: OFFBOARD,
          reject: Callable[[str, rejections.CodecError], None] = lambda _l, _e: None
          ) -> Autopilot:
    """The autopilot of one vehicle and its parts, as ``setup`` says (the endpoint's, and a
    unit test's with a recording outbox)."""
    own_clock = setup.clock == REALTIME
    bounds: FreeBounds | PlanningBounds = (
        FreeBounds(setup.home, FREE_RANGE_M) if own_clock
        else PlanningBounds(setup.home, setup.area_size_m))
    mission = MissionServer(outbox, bounds, on_reject=reject,
                            empty_upload_clears=setup.flavour is ARDUPILOT)
    home_local = (float(vehicle.state[0]), float(vehicle.state[1]))
    nav = Navigator(vehicle, params, home_local, Frame(setup.home, setup.home_amsl_m),
                    own_clock, lambda: mission.items)
    ap = Autopilot(setup.flavour, vehicle, params, outbox, mission, nav, control_link,
                   setup.sysid)
    mission.on_change = ap.mission_changed
    return ap
