"""``python -m services.testbed.impairer``: forward frames between two interfaces, impaired.

Runs until SIGINT or SIGTERM, or until the process that started it dies (a test bed's owner
that crashed: the kernel sends SIGTERM, ``PR_SET_PDEATHSIG``). Logs its counters at exit.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import logging
import os
import signal
import threading

from services.common import log as common_log
from services.testbed.impairer.control import ControlServer, Request
from services.testbed.impairer.forward import Forwarder
from services.testbed.impairment import Impairment

log = logging.getLogger("services.testbed.impairer")
PR_SET_PDEATHSIG = 1


def _end(text: str) -> tuple[str, str]:
    host, sep, ifname = text.partition("=")
    if not (sep and host and ifname):
        raise argparse.ArgumentTypeError(f"--end is HOST=INTERFACE, got {text!r}")
    return host, ifname


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m services.testbed.impairer",
                                description=__doc__.splitlines()[0])
    p.add_argument("--end", type=_end, action="append", required=True,
                   help="HOST=INTERFACE, twice: the link's two ends in this namespace")
    p.add_argument("--control", required=True, help="the control socket's path")
    p.add_argument("--seed", type=int, default=0, help="seed of the loss and jitter draws")
    p.add_argument("--delay-ms", type=float, default=0.0)
    p.add_argument("--jitter-ms", type=float, default=0.0)
    p.add_argument("--loss", type=float, default=0.0)
    p.add_argument("--log-level", default=os.environ.get("LOG_LEVEL", "INFO"))
    p.add_argument("--log-format", default=os.environ.get("LOG_FORMAT", "text"),
                   choices=["json", "text"])
    return p


def main(argv: list[str] | None = None) -> int:
    p = parser()
    args = p.parse_args(argv)
    ends = dict(args.end)
    if len(ends) != 2:
        p.error(f"two distinct --end HOST=INTERFACE, got {args.end}")
    try:
        first = Impairment(args.delay_ms, args.jitter_ms, args.loss)
    except ValueError as err:
        p.error(str(err))
    common_log.configure("impairer", "-", args.log_level, args.log_format)
    ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    fwd = Forwarder(ends, args.seed)
    fwd.handle(Request("set", impairment=first))
    server = ControlServer(args.control, fwd.hosts, fwd.handle)
    server.start()  # the ends are bound: a "ping" answered means frames are forwarded
    log.info("forwarding %s", " <-> ".join(f"{h} ({i})" for h, i in ends.items()))
    try:
        fwd.run(stop)
    finally:
        server.close()
        log.info("stopped: %s", json.dumps(fwd.stats(fwd.clock())))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
