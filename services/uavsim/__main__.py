"""uavsim: a simulated vehicle that speaks MAVLink like an autopilot and flies Eq. (1).

Two links (pymavlink, MAVLink 2, system ``--sysid``, component 1): the
offboard link (``--mavlink-url``), where a companion (the supervisor, MAVSDK)
streams SET_POSITION_TARGET_LOCAL_NED, optionally signed, and the ground-station
link (``--gcs-url``) for MAVProxy or QGroundControl. Both get HEARTBEAT and
telemetry and answer parameters, commands and the mission protocol;
``--tlog`` records them in MAVProxy's ``.tlog`` format. Without the flags the
vehicle does what its autopilot's SITL does (services/uavsim/flavour.py):
``--autopilot px4`` *sends* to 127.0.0.1:14540 (MAVSDK's examples listen
there) and 127.0.0.1:14550 (QGroundControl listens there) and boots at PX4
SITL's home; ``--autopilot ardupilot`` serves TCP 5762 (offboard) and 5760
(ground station), ArduPilot SITL's SERIAL1 and SERIAL0. The local frame (m
east/north) has its origin at ``--home``.

``--clock realtime`` (the default: a vehicle on its own, as SITL) flies
Eq. (1) on the vehicle's own clock, one ΔT every ΔT / ``--speed-factor``
wall seconds; ``--clock lockstep`` (the stack: ``make run``, compose, every
mission) makes each setpoint, stamped with the simulated time it is due,
one ΔT step of Eq. (1) (services/uavsim/clock.py), with the dynamics and the
area of the mission's configuration, which the supervisor sends it on Zenoh
(missionconfig.py; until then the default configuration's).
``--uav-ids`` hosts several vehicles, served by one loop (host.py, hosting.py).
The parts: options.py (flags), endpoint.py (links), commander.py (modes and
arming), failsafe.py, navigator.py, missionrun.py, geofence.py, commands.py,
params.py, telemetry.py, mission.py, control.py, vehicle.py (physics).
"""

from __future__ import annotations

import sys

from services.common import bus

from .hosting import serve
from .options import check, parser


def main(argv: list[str] | None = None) -> int:
    p = parser()
    raw_argv = sys.argv[1:] if argv is None else argv
    args = p.parse_args(argv)
    try:
        opts = check(args, raw_argv)
    except (ValueError, OSError) as err:
        p.error(str(err))
    return bus.run_service(opts.settings, lambda ctx: serve(ctx, opts),
                           zenoh_session=opts.use_zenoh)


if __name__ == "__main__":
    bus.leave(main())
