"""``python -m services.testbed``: the test bed up until Ctrl-C, then down; a mission across it;
or remove leftovers.

``python -m services.testbed [up] [--delay-ms 150 --jitter-ms 20 --loss 0.05 --rate-mbit 1]``
brings the hosts up with the radio link so shaped, prints them and how to run a command in
each, and waits; Ctrl-C, SIGTERM or SIGHUP takes it all down. ``python -m services.testbed
down`` removes test beds whose owner process is gone (``--all``: every one on the machine).
``python -m services.testbed mission [--outage-at-step 10 --outage-s 10] [mission flags]``
flies one mission across the hosts (services/testbed/mission.py: the ground's part in
``ground``, the air's in ``air``), the radio link shaped by the flags, and prints its run
directory (``runs/<time>-testbed-…`` unless ``--out``).
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading
import time
from pathlib import Path

from services.common import log as common_log
from services.testbed import leftovers
from services.testbed.availability import unavailable
from services.testbed.bed import IMPAIRERS, TestBed
from services.testbed.impairment import Impairment
from services.testbed.mission import MISSION

log = logging.getLogger("services.testbed")


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m services.testbed",
                                description=__doc__.splitlines()[0])
    p.add_argument("action", nargs="?", default="up", choices=["up", "down", "mission"])
    p.add_argument("--all", action="store_true",
                   help="down: every test bed on the machine, not only those whose owner died")
    p.add_argument("--impairer", default="auto", choices=IMPAIRERS)
    p.add_argument("--impairer-seed", type=int, default=0,
                   help="the impairers' draws (loss, jitter); a mission's --seed is the mission's")
    p.add_argument("--link", default="radio", help="the link the shaping flags apply to")
    p.add_argument("--delay-ms", type=float, default=0.0)
    p.add_argument("--jitter-ms", type=float, default=0.0)
    p.add_argument("--loss", type=float, default=0.0, help="a fraction, 0..1")
    p.add_argument("--rate-mbit", type=float, default=None)
    p.add_argument("--queue-ms", type=float, default=500.0)
    g = p.add_argument_group("mission: one mission across the hosts (other flags: the mission's, "
                             "as dualpilot mission's; default " + " ".join(MISSION) + ")")
    g.add_argument("--out", default="", help="its run directory (default runs/<time>-testbed-…)")
    g.add_argument("--speed-factor", type=float, default=2.0)
    g.add_argument("--outage-at-step", type=int, default=None,
                   help="take the radio link down once the record holds this step")
    g.add_argument("--outage-s", type=float, default=10.0)
    g.add_argument("--timeout-s", type=float, default=300.0)
    return p


def _mission(args: argparse.Namespace, extra: list[str], shape: Impairment) -> int:
    """Fly one mission across a test bed; prints what crossed the link and the run directory."""
    from services.launch.processes import REPO
    from services.testbed.mission import FlightPlan, LinkPlan, describe, fly

    name = f"{time.strftime('%Y%m%d-%H%M%S')}-testbed-" + "-".join(
        a.lstrip("-") for a in (extra or list(MISSION))[1::2][:2])
    run_dir = Path(args.out) if args.out else REPO / "runs" / name.replace("+", "-")
    plan = FlightPlan(mission=tuple(extra) or MISSION, speed_factor=args.speed_factor,
                      link=LinkPlan(radio=shape, outage_at_step=args.outage_at_step,
                                    outage_s=args.outage_s), timeout_s=args.timeout_s)
    with TestBed(impairer=args.impairer, seed=args.impairer_seed, logs=run_dir / "testbed") as bed:
        flown = fly(bed, run_dir.resolve(), plan)
    sys.stdout.write(describe(flown) + f"\nrun directory: {run_dir}\n")
    return 0 if flown.air_exit == 0 else 1


def _stop_on_signals(stop: threading.Event) -> None:
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, lambda *_: stop.set())


def main(argv: list[str] | None = None) -> int:
    p = parser()
    args, extra = p.parse_known_args(argv)
    if extra and args.action != "mission":
        p.error(f"unrecognized arguments: {' '.join(extra)}")
    common_log.configure("testbed", "-", fmt="text")
    if args.action == "down":
        removed = leftovers.remove_stale(everything=args.all)
        log.info("removed %s", ", ".join(removed) if removed else "nothing")
        return 0
    try:
        shape = Impairment(args.delay_ms, args.jitter_ms, args.loss, args.rate_mbit,
                           args.queue_ms)
    except ValueError as err:
        p.error(str(err))
    reason = unavailable()
    if reason:
        log.error("the test bed cannot be made here: %s", reason)
        return 2
    stale = leftovers.remove_stale()
    if stale:
        log.info("removed leftovers of a crashed test bed: %s", ", ".join(stale))
    if args.action == "mission":
        return _mission(args, extra, shape)
    stop = threading.Event()
    _stop_on_signals(stop)
    with TestBed(impairer=args.impairer, seed=args.impairer_seed) as bed:
        bed.link(args.link).set(shape)
        sys.stdout.write(bed.describe() + f"\n  {args.link}: {shape}\n"
                         "up; Ctrl-C takes it down\n")
        sys.stdout.flush()
        stop.wait()
    log.info("test bed down")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
