"""The simulated vehicle's MAVLink side: its links, the frames it acts on, the wiring of its parts.

One :class:`Endpoint` per simulated vehicle (a vehicle host runs several,
services/uavsim/hosting.py). Its links are read by links.py (a UDP datagram
is parsed on its own and judged by when it arrived; a TCP link, ArduPilot
SITL's habit, is read as a stream); it checks every frame (target, signing,
the setpoint codec) and hands it to the part that acts on
it: the parameters (params.py), the commands (commands.py), the mission
protocol (mission.py), the control arbiter (control.py) for who may steer,
and the autopilot (autopilot.py: the state machine, its failsafes and the
navigator). On the vehicle's own clock it flies every ΔT; it streams the
telemetry (telemetry.py) at the rates of intervals.py.
"""

from __future__ import annotations

import logging
import select
import threading
import time
from collections.abc import Callable, Iterable
from typing import Any

from services.common import mav, mavlink_codec, rejections
from services.common.log import fields

from . import clock as vclock
from . import plantclock
from .autopilot import FREE_RANGE_M, VehicleSetup, build
from .commands import Commands
from .control import ControlArbiter
from .intervals import Schedule
from .links import MAX_CLIENTS, Arrival, LinkReader, add_client
from .outbox import LinkOutbox, statustext
from .params import Parameters, ParamProtocol
from .setpoint import normalised
from .telemetry import Telemetry
from .vehicle import Vehicle

log = logging.getLogger("services.uavsim")
m = mav.mavlink

#: the longest wait between two passes of the loop (s): the failsafes are judged at least this
#: often
MAX_WAIT_S = 0.05
#: Messages a ground station sends that the vehicle ignores without counting them as bad
#: input (housekeeping of MAVProxy and QGroundControl).
GCS_CHATTER = frozenset({
    "REQUEST_DATA_STREAM", "SYSTEM_TIME", "TIMESYNC", "PING", "RC_CHANNELS_OVERRIDE",
    "PARAM_EXT_REQUEST_LIST", "PARAM_EXT_REQUEST_READ", "FILE_TRANSFER_PROTOCOL",
    "LOG_REQUEST_LIST", "COMMAND_ACK", "STATUSTEXT", "GPS_RTCM_DATA", "GPS_INJECT_DATA",
    "RADIO_STATUS",
})
#: Messages the vehicle acts on (besides the mission protocol, services/uavsim/mission.py).
HANDLED = frozenset({
    "HEARTBEAT", "SET_POSITION_TARGET_LOCAL_NED", "PARAM_REQUEST_LIST", "PARAM_REQUEST_READ",
    "PARAM_SET", "COMMAND_LONG", "COMMAND_INT", "SET_MODE", "MANUAL_CONTROL",
    "MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_REQUEST_LIST",
    "MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_CLEAR_ALL", "MISSION_SET_CURRENT",
    "MISSION_ACK",
})
#: Messages a keyed ground-station link refuses unsigned (control, mission upload, parameters).
SIGNED_ONLY = frozenset({"SET_POSITION_TARGET_LOCAL_NED", "COMMAND_LONG", "COMMAND_INT",
                         "SET_MODE", "PARAM_SET", "MISSION_COUNT", "MISSION_ITEM_INT",
                         "MISSION_ITEM", "MISSION_CLEAR_ALL", "MISSION_SET_CURRENT",
                         "MANUAL_CONTROL"})


class Endpoint:
    """The vehicle's MAVLink side: links, checks, the parts that act, the loop."""

    def __init__(self, vehicle: Vehicle, links: dict[str, Any], setup: VehicleSetup,
                 tlog: mav.Tlog | None = None, boot: float | None = None):
        """``boot``: when the vehicle booted (monotonic s; default now): its telemetry is due
        at boot + whole periods, so the vehicles of a host booted together send together."""
        boot = time.monotonic() if boot is None else boot
        self.setup = setup
        self.vehicle = vehicle
        self.sysid = setup.sysid
        self.links = links
        self.reader = LinkReader(links, self.handle, self.reject, self._unsigned)
        self.tlog = tlog
        self.outbox = LinkOutbox({name: mav.Sender(conn, tlog) for name, conn in links.items()})
        self.realtime = (vclock.RealtimeClock(setup.speed_factor, int(vehicle.dyn.dt_s * 1000),
                                              boot)
                         if setup.clock == vclock.REALTIME else None)
        self.schedule = Schedule(boot)
        self.params = Parameters(MAV_SYS_ID=setup.sysid, COM_OF_LOSS_T=setup.offboard_loss_s,
                                 SIM_ALT_M=setup.altitude_m, SIM_KP=vehicle.kp,
                                 BAT_CAP_NS=vehicle.capacity_ns)
        self.params.on_change(self._param_changed)
        self.arbiter = ControlArbiter(lambda: self.params["COM_OF_LOSS_T"],
                                      lambda: self.params["COM_DL_LOSS_T"])
        self.ap = build(setup, vehicle, self.params, self.outbox,
                        control_link=lambda: self.arbiter.link,
                        reject=lambda link, err: self.reject(link, err, "mavlink"))
        home_local = (float(vehicle.state[0]), float(vehicle.state[1]))
        self.telemetry = Telemetry(self.ap, self.outbox, setup.home, home_local,
                                   setup.home_amsl_m)
        self.protocol = ParamProtocol(self.params, self.outbox, self.reject)
        self.commands = Commands(self.ap, self.arbiter, self.outbox, self.schedule,
                                 self.telemetry.sender, self.reject)
        self.peers: set[tuple[str, int, int]] = set()
        self.last_reject_note = 0.0
        #: the last setpoint checked and accepted ((link, peer, payload), (target, altitude)):
        #: its repeats (the ≥ 10 Hz stream) are not decoded again; a parameter change clears it
        self.repeat: tuple[Any, Any] | None = None
        self.fault = ""  # a storage fault to report (STATUSTEXT) from the loop

    # -- the parts' callbacks ------------------------------------------------------------------
    def _param_changed(self, name: str, value: float) -> None:
        self.repeat = None  # a setpoint accepted under the old value is checked again
        v = self.vehicle
        if name == "MPC_XY_VEL_MAX":
            v.set_limits(v_max_mps=value)
        elif name == "SIM_U_MAX_N":
            v.set_limits(u_max_n=value)
        elif name == "SIM_KP":
            v.kp = value
        elif name == "BAT_CAP_NS":
            v.capacity_ns = value

    def reject(self, link: str, err: rejections.CodecError, what: str = "mavlink") -> None:
        """Count and log (rate-limited) a rejected MAVLink input under ``mavlink/<link>``."""
        rejections.rejected(what, err, log, key=f"mavlink/{link}")

    # -- incoming ------------------------------------------------------------------------------
    def handle(self, link: str, msg: Any, arrival: Arrival) -> bool:
        """Act on one decoded frame (links.py read it); False (after counting it) if it was
        rejected."""
        kind = msg.get_type()
        if self.tlog is not None:
            self.tlog.message(msg)
        # when the datagram arrived (the kernel's stamp), not when this process got to it
        now = arrival.rx_time if arrival.rx_time is not None else time.monotonic()
        if kind == "HEARTBEAT":
            self.arbiter.heard_on(link, now)
            self.on_heartbeat(link, msg, arrival.addr)
            return True
        if kind in GCS_CHATTER:
            return True
        if kind not in HANDLED:
            self.reject(link, rejections.invalid(f"{kind} is not a message the vehicle accepts",
                                                 rejections.Reason.WRONG_TYPE))
            return False
        target = getattr(msg, "target_system", None)
        comp = getattr(msg, "target_component", None)
        if (target not in (None, 0, self.sysid)
                or comp not in (None, 0, mav.MAV_COMP_ID_AUTOPILOT1)):
            self.reject(link, rejections.invalid(
                f"{kind} for system {target} component {comp} (this is {self.sysid}:1)",
                rejections.Reason.WRONG_TARGET))
            return False
        self.arbiter.heard_on(link, now)
        return self.dispatch(link, msg, now, arrival.addr)

    def on_heartbeat(self, link: str, msg: Any, addr: Any) -> None:
        """A new peer is logged and answered at once: it waits for our heartbeat to start."""
        peer = (link, msg.get_srcSystem(), msg.get_srcComponent())
        conn = self.links[link]
        if addr is not None and getattr(conn, "udp_server", False):
            add_client(conn, addr)  # a client now, so the answer reaches it
        if peer in self.peers:
            return
        if len(self.peers) >= 4 * MAX_CLIENTS:
            self.peers.clear()  # bounded: only used to answer a new peer at once
        self.peers.add(peer)
        log.info("peer", extra=fields(link=link, sysid=peer[1], compid=peer[2],
                                      mav_type=msg.type))
        self.ap.heartbeat()

    def dispatch(self, link: str, msg: Any, now: float, addr: Any) -> bool:
        """A frame addressed to this vehicle (from ``addr``), by its type."""
        kind = msg.get_type()
        peer = (addr, msg.get_srcSystem(), msg.get_srcComponent())
        if kind in ("MISSION_ITEM_INT", "MISSION_ITEM") and int(msg.current) == 2:
            return self.commands.on_guided_item(link, peer, msg, now)
        handled = self.ap.mission.handle(link, msg, now)
        if handled is not None:
            return handled
        if kind == "SET_POSITION_TARGET_LOCAL_NED":
            return self.on_setpoint(link, peer, msg, now)
        if kind == "COMMAND_LONG":
            return self.commands.on_command_long(link, peer, msg, now)
        if kind == "COMMAND_INT":
            return self.commands.on_command_int(link, peer, msg, now)
        if kind == "SET_MODE":
            return self.commands.on_set_mode(link, peer, msg, now)
        if kind == "MANUAL_CONTROL":
            if link == self.arbiter.link:  # the sticks of the link in control only
                self.ap.manual(msg, now)
            return True
        if kind == "PARAM_REQUEST_LIST":
            self.protocol.request_list(link)
        elif kind == "PARAM_REQUEST_READ":
            self.protocol.request_read(link, msg)
        elif kind == "PARAM_SET":
            return self.protocol.param_set(link, msg)
        return True

    def _unsigned(self, total: int) -> None:
        """Frames refused unsigned or wrongly signed on a signed link: SIG_REJECTED, and a
        STATUSTEXT at most every 2 s."""
        self.params.set_quietly("SIG_REJECTED", float(total))
        now = time.monotonic()
        if now - self.last_reject_note > 2.0:
            self.last_reject_note = now
            statustext(self.outbox, f"signing: {total} frames rejected", m.MAV_SEVERITY_WARNING)

    # -- setpoints -----------------------------------------------------------------------------
    def on_setpoint(self, link: str, peer: Any, msg: Any, now: float) -> bool:
        """A setpoint that is not finite, out of bounds or due too far ahead is refused (the
        vehicle keeps its last target, the stream is not kept alive); one not from the link and
        peer in control is refused too, but the companion's while a ground station holds
        control keeps its link's stream live for the hand-back."""
        key = (link, peer, bytes(msg.get_payload()))
        if (self.repeat is not None and self.repeat[0] == key and link == self.arbiter.link
                and peer == self.arbiter.controller):
            target, alt = self.repeat[1]  # the stream's repeat of a setpoint already checked
            self.arbiter.controller_heard = now
        else:
            checked = self.check_setpoint(link, msg)
            if checked is None:
                return False
            target, alt = checked
            if not self.arbiter.waiting(link):
                d = self.arbiter.check(link, peer, now)
                if d.refused:
                    self.commands.refused_control(link, "Setpoint", d.refused, now)
                    return False
                self.arbiter.commit(d, now)
                self.repeat = (key, (target, alt))
        if self.ap.setpoint(link, target, alt, int(msg.time_boot_ms), now):
            self.after_step()
        return True

    def check_setpoint(self, link: str, msg: Any) -> tuple[Any, float] | None:
        """The setpoint's target and altitude (m above home), or None after counting why it was
        refused (too far ahead, not valid)."""
        lead = (None if self.realtime is not None  # real time: the client's stamp is not a clock
                else int(msg.time_boot_ms) - self.vehicle.time_ms)
        lead_s = self.params["COM_SP_LEAD_S"]
        if lead is not None and lead > lead_s * 1000:  # never moves the clock
            self.reject(link, rejections.invalid(
                f"setpoint due {lead / 1000:.6g} s after the vehicle's clock (more than one step,"
                f" COM_SP_LEAD_S = {lead_s:g} s)", rejections.Reason.OUT_OF_RANGE), "setpoint")
            return None
        try:
            area = None if self.realtime is not None else self.setup.area_size_m
            band = None if self.realtime is not None else self.setup.band
            target = mavlink_codec.setpoint_from_mavlink(  # 3-D in lockstep under dim=3
                normalised(msg), area, lead, FREE_RANGE_M if area is None else None,
                self.vehicle.dyn.dim, band, self.setup.band_margin_m)
        except rejections.CodecError as err:
            self.reject(link, err, "setpoint")
            return None
        return target, -float(msg.z)

    def after_step(self) -> None:
        self.telemetry.position()
        x = self.vehicle.state
        log.debug("step", extra=fields(time_ms=self.vehicle.time_ms, east_m=float(x[0]),
                                       north_m=float(x[1]), alt_m=self.ap.nav.alt))

    # -- loop ----------------------------------------------------------------------------------
    # One pass of the vehicle's loop: what is due (:meth:`due_work`), a wait on the links until
    # the time it returns or a datagram, then :meth:`settle`. A vehicle host runs the passes of
    # all its vehicles in one loop (services/uavsim/host.py); :meth:`run` serves this one alone.
    def begin(self, now: float) -> float:
        """Say the vehicle is ready and do what is due; the first pass's deadline (monotonic s)."""
        statustext(self.outbox, "dualpilot uavsim ready")
        return self.due_work(now)

    def due_work(self, now: float) -> float:
        """The steps of the vehicle's own clock, the telemetry, the mission protocol's retries
        and a storage fault that are due at ``now``; when the next pass is due (monotonic s:
        at the latest :data:`MAX_WAIT_S` from now)."""
        if self.realtime is not None:
            for due_ms in self.realtime.due_steps(now):
                if self.ap.fly(due_ms, now):
                    self.after_step()
            plantclock.fly_due(self.ap, self.realtime.now_ms(now))  # a plant's 20 Hz stream
        for msg_id in self.schedule.due(now):
            self.telemetry.stream(msg_id)
        self.ap.mission.poll(now)
        if self.fault:
            statustext(self.outbox, self.fault[:50], m.MAV_SEVERITY_ERROR)
            self.fault = ""
        timeout = min(self.schedule.wait_s(now), MAX_WAIT_S)
        if self.realtime is not None:
            timeout = min(timeout, self.realtime.wall_until_next(now))
        return now + max(0.0, timeout)

    def settle(self, ready: Iterable[str], on_tick: Callable[[float], None] | None = None
               ) -> None:
        """After the wait: read the ``ready`` links, then the failsafes and landing (a vehicle
        kept off the CPU finds its queued setpoints first), then ``on_tick(now)``."""
        for link in ready:
            self.reader.receive(link)
        self.ap.watch(time.monotonic())
        if on_tick is not None:
            on_tick(time.monotonic())

    def fds(self) -> dict[int, str]:
        """The links' descriptors (a TCP link's changes when a client connects or goes)."""
        return {conn.fd: name for name, conn in self.links.items()}

    def run(self, stop: threading.Event,
            on_tick: Callable[[float], None] | None = None) -> None:
        """Serve the links until ``stop``; ``on_tick(now)`` after every pass of the loop."""
        deadline = self.begin(time.monotonic())
        while not stop.is_set():
            fds = self.fds()
            ready, _, _ = select.select(list(fds), [], [],
                                        max(0.0, deadline - time.monotonic()))
            self.settle([fds[fd] for fd in ready], on_tick)
            deadline = self.due_work(time.monotonic())
