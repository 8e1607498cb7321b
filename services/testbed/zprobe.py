"""``python -m services.testbed.zprobe``: a Zenoh session that keeps asking a service across a
link, and writes down each answer — or its absence.

Every ``--period-s`` it queries the status of ``--target`` (every service answers
``keys.status``; the router too) with a ``--timeout-s`` and appends one JSON line to ``--out``:
``{"seq", "sent", "done", "ok", "routers"}`` — the query's send and end times on the machine's
monotonic clock (the test bed's hosts share it), whether an answer came, and how many routers
the session was connected to when it asked. The session is the services' own
(:func:`services.common.bus.zenoh_config`: it reconnects by itself), so the lines show whether
and when a session across the link comes back after an outage.
"""

from __future__ import annotations

import json
import logging
import time

from services.common import bus
from services.common import cli as common_cli

log = logging.getLogger("services.testbed.zprobe")


def main(argv: list[str] | None = None) -> int:
    p = common_cli.parser("zprobe", __doc__.splitlines()[0])
    p.add_argument("--target", default="router", help="the service whose status is asked")
    p.add_argument("--period-s", type=float, default=0.2)
    p.add_argument("--timeout-s", type=float, default=1.0)
    p.add_argument("--out", required=True, help="the JSON-lines file written")
    args = p.parse_args(argv)
    if not (args.period_s > 0 and args.timeout_s > 0):
        p.error("--period-s and --timeout-s must be > 0")
    try:
        settings = common_cli.settings("zprobe", args)
    except ValueError as err:
        p.error(str(err))

    def body(ctx: bus.Context) -> None:
        assert ctx.session is not None
        with open(args.out, "a", buffering=1) as out:
            seq = 0
            while not ctx.stop.is_set():
                sent = time.monotonic()
                routers = len(list(ctx.session.info.routers_zid()))
                try:
                    bus.query_status(ctx.session, settings.uav_id, args.target,
                                     timeout_s=args.timeout_s, stop=ctx.stop)
                    ok = True
                except TimeoutError:
                    ok = False
                done = time.monotonic()
                out.write(json.dumps({"seq": seq, "sent": sent, "done": done, "ok": ok,
                                      "routers": routers}) + "\n")
                seq += 1
                ctx.stop.wait(max(0.0, sent + args.period_s - time.monotonic()))

    return bus.run_service(settings, body)


if __name__ == "__main__":
    bus.leave(main())
