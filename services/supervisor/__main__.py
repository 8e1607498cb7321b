"""Supervisor service: the cognitive controller's decision loop, the vehicle's offboard companion.

Waits for the EWS, the planners it needs and the vehicle (liveliness tokens
and a MAVLink heartbeat), takes the vehicle in MAVSDK/PX4 order (setpoints,
offboard mode, arm; services/supervisor/link.py), takes the vehicle's mission
as System 1's operator waypoints, flies one mission (services/supervisor/session.py),
writes its records to ``--out`` and announces the end on ``mission/event``.
It then keeps streaming the last setpoint until stopped, or, with
``--exit-after-mission``, exits: 0 when the mission succeeded, 1 when it was
aborted (or could not start), 3 when it ended in failure.

``--uav-ids`` makes one process the companion of several vehicles
(services/common/fleet.py): vehicle k (from 0) flies seed ``--seed`` + k (or
the k-th of ``--seeds``) on MAVLink instance k (the URL's port + k, system id
``--sysid`` + k), into ``--out`` with ``{uav}`` replaced by its id, each in a
thread of its own; one stream process keeps every vehicle's setpoints
beating. With ``--exit-after-mission`` the process exits when every mission
has ended, with the worst vehicle's code.
"""

from __future__ import annotations

import logging

from services.common import bus, fleet

from .companion import fly
from .options import parse
from .stream.client import close_stream_process
from .warm import warm_kernels

log = logging.getLogger("services.supervisor")


def main(argv: list[str] | None = None) -> int:
    opts = parse(argv, __doc__.splitlines()[0])
    codes: dict[str, int] = {}

    def body(ctx: bus.Context) -> None:
        codes[ctx.settings.uav_id] = fly(ctx, opts)

    def serve(ctx: bus.Context) -> None:
        # the compiled kernels the step itself runs (hulls, risk zones, the lookahead's lattice),
        # loaded before the first mission: else the step that meets the first fire waits for them
        warm_kernels()
        try:
            fleet.for_each(ctx, opts.uavs, body)
        finally:
            close_stream_process()  # every link is closed: its vehicles' streams end here
        ctx.exit_code = max([ctx.exit_code, *codes.values()])

    return bus.run_service(opts.settings, serve)


if __name__ == "__main__":
    bus.leave(main())
