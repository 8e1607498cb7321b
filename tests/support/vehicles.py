"""A simulated vehicle without sockets: the autopilot's parts wired to a recording outbox.

The unit tests of services/uavsim drive it with decoded MAVLink messages and
injected times (monotonic s), and read what a ground station would have
received (:class:`~services.uavsim.outbox.RecordingOutbox`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from services.common import mav
from services.uavsim import flavour as fl
from services.uavsim.autopilot import Autopilot, VehicleSetup, build
from services.uavsim.clock import LOCKSTEP, REALTIME
from services.uavsim.commands import Commands
from services.uavsim.control import ControlArbiter
from services.uavsim.intervals import Schedule
from services.uavsim.outbox import RecordingOutbox
from services.uavsim.params import Parameters
from services.uavsim.telemetry import Telemetry
from services.uavsim.vehicle import Vehicle

m = mav.mavlink
#: PX4 SITL's home (services/uavsim/flavour.py)
HOME = (47.397742, 8.545594)
HOME_AMSL_M = 488.0
GCS_PEER = (("127.0.0.1", 14550), 255, 190)
COMPANION = (("127.0.0.1", 14540), 1, 191)
_SENDER = m.MAVLink(None, srcSystem=255, srcComponent=190)


def wire(msg: Any, src: tuple[int, int] = (255, 190)) -> Any:
    """``msg`` as decoded off the wire (with its source system and component)."""
    sender = m.MAVLink(None, srcSystem=src[0], srcComponent=src[1])
    return m.MAVLink(None).decode(bytearray(msg.pack(sender)))


def command_long(cmd: int, *params: float) -> Any:
    p = [*params, *([float("nan")] * (7 - len(params)))]
    return wire(m.MAVLink_command_long_message(1, 1, cmd, 0, *p))


def setpoint_msg(north: float, east: float, down: float, due_ms: int = 0,
                 mask: int = mav.TYPE_MASK_POS) -> Any:
    return wire(m.MAVLink_set_position_target_local_ned_message(
        due_ms, 1, 1, m.MAV_FRAME_LOCAL_NED, mask, north, east, down, 0, 0, 0, 0, 0, 0, 0, 0),
        (1, 191))


@dataclass
class Rig:
    """One vehicle's parts and what they sent."""

    ap: Autopilot
    out: RecordingOutbox
    arbiter: ControlArbiter
    commands: Commands
    telemetry: Telemetry
    params: Parameters
    acks: list[tuple[int, int]] = field(default_factory=list)

    def command(self, cmd: int, *params: float, link: str = "gcs",
                peer: tuple[Any, int, int] = GCS_PEER, now: float = 0.0) -> int:
        """COMMAND_LONG ``cmd`` (unset parameters NaN, as MAVSDK) from ``link``: its ACK."""
        self.out.clear()
        self.commands.on_command_long(link, peer, command_long(cmd, *params), now)
        acks = [a for a in self.out.named("command_ack") if a[0] == cmd]
        assert len(acks) == 1, self.out.sent
        return int(acks[0][1])

    def texts(self) -> list[str]:
        return self.out.texts()

    def fly(self, seconds: float, now: float = 0.0) -> None:
        """``seconds`` of simulated flight on the vehicle's own clock, ΔT at a time."""
        v = self.ap.vehicle
        for _ in range(round(seconds / v.dyn.dt_s)):
            self.ap.fly(v.time_ms + int(v.dyn.dt_s * 1000), now)
            self.ap.watch(now)

    @property
    def nav(self) -> fl.Nav:
        return self.ap.commander.nav


def rig(flavour: fl.Flavour = fl.PX4, realtime: bool = True,
        start: tuple[float, float] = (0.0, 0.0)) -> Rig:
    """A vehicle of ``flavour`` at ``start`` (m east, north of PX4 SITL's home)."""
    setup = VehicleSetup(sysid=1, altitude_m=50.0, home=HOME, offboard_loss_s=1.0,
                         flavour=flavour, clock=REALTIME if realtime else LOCKSTEP,
                         home_amsl_m=HOME_AMSL_M)
    out = RecordingOutbox()
    params = Parameters()
    arbiter = ControlArbiter(lambda: params["COM_OF_LOSS_T"], lambda: params["COM_DL_LOSS_T"])
    ap = build(setup, Vehicle.at(*start), params, out, lambda: arbiter.link)
    telemetry = Telemetry(ap, out, HOME, start, HOME_AMSL_M)
    commands = Commands(ap, arbiter, out, Schedule(0.0), telemetry.sender,
                        lambda _link, _err, _what: None)
    return Rig(ap, out, arbiter, commands, telemetry, params)
