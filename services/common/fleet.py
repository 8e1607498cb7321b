"""One service process for several vehicles: the shared services and vehicle hosts of a fleet.

Keys are namespaced by vehicle id (services/common/keys.py), so serving a
fleet is serving each id's keys: ``--uav-ids uav1,uav2,…`` (``UAV_IDS``) runs
the service's body once per id, each in a thread of its own over the one
Zenoh session, with its own state (one fire field, one planner cache, one
simulated vehicle or one mission per vehicle) and its own liveliness token;
the vehicle host (uavsim) serves its vehicles from one loop instead
(:func:`contexts`, services/uavsim/host.py).
Without the flag the service serves ``--uav-id`` alone, exactly as before.
The status queryable stays the one of ``--uav-id``; it counts the rejections
of every id's keys. A vehicle's own MAVLink link is instance k of the fleet
(:func:`instance_url`: the port + k, as PX4 SITL numbers its instances), and
its files are named with ``{uav}`` (:func:`per_vehicle`).
"""

from __future__ import annotations

import argparse
import logging
import re
import threading
from collections.abc import Callable
from dataclasses import replace

from . import bus, keys
from .cli import env
from .log import fields, tag_vehicle

log = logging.getLogger(__name__)

MAX_VEHICLES = 64


def add_argument(p: argparse._ActionsContainer,
                 what: str = "a fleet sharing this service") -> None:
    """The ``--uav-ids`` flag (default ``UAV_IDS``; empty: ``--uav-id`` alone)."""
    p.add_argument("--uav-ids", default=env("UAV_IDS", ""),
                   help=f"serve these comma-separated vehicle ids ({what}); empty: --uav-id "
                        "alone [UAV_IDS]")


_PORT = re.compile(r"^(udpin|udpout|udp|tcpin|tcp):([^:]*):(\d{1,5})$")


def instance_url(url: str, k: int) -> str:
    """Vehicle instance ``k``'s MAVLink URL: ``url`` with its port + k (k = 0: ``url`` itself).

    Raises ValueError for a URL without a port, or a port beyond 65535.
    """
    if k == 0:
        return url
    found = _PORT.match(url)
    if found is None:
        raise ValueError(f"{url!r} has no port to number vehicle instances from")
    port = int(found.group(3)) + k
    if port > 65535:
        raise ValueError(f"{url!r} + {k} vehicles passes port 65535")
    return f"{found.group(1)}:{found.group(2)}:{port}"


def per_vehicle(path: str, uav: str) -> str:
    """``path`` with ``{uav}`` replaced by the vehicle id ("" stays "")."""
    return path.replace("{uav}", uav)


def uav_ids(text: str, default: str) -> tuple[str, ...]:
    """The vehicle ids to serve: ``text`` split on commas (checked, de-duplicated, in order), or
    ``(default,)`` when empty. Raises ValueError for a bad id or more than MAX_VEHICLES."""
    ids = [keys.check_id(t.strip()) for t in text.split(",") if t.strip()]
    ids = list(dict.fromkeys(ids)) or [keys.check_id(default)]
    if len(ids) > MAX_VEHICLES:
        raise ValueError(f"at most {MAX_VEHICLES} vehicle ids, got {len(ids)}")
    return tuple(ids)


def contexts(ctx: bus.Context, ids: tuple[str, ...]) -> list[bus.Context]:
    """Each vehicle's :class:`bus.Context`: ``ctx`` itself for its own id alone, else one per id
    carrying it, sharing the session and the stop event (for a service that serves its
    vehicles from one loop; :func:`release` undeclares their tokens)."""
    if ids == (ctx.settings.uav_id,):
        return [ctx]
    return [bus.Context(replace(ctx.settings, uav_id=uav), ctx.stop, ctx.session) for uav in ids]


def release(ctx: bus.Context, subs: list[bus.Context]) -> None:
    """Undeclare the liveliness tokens of the contexts :func:`contexts` made (not ``ctx``'s)."""
    for sub in subs:
        if sub is not ctx and sub.token is not None:
            sub.token.undeclare()


def for_each(ctx: bus.Context, ids: tuple[str, ...], body: Callable[[bus.Context], None]) -> None:
    """Run ``body`` for every vehicle id: directly for one id, else one thread per id.

    Each thread gets a :class:`bus.Context` whose settings carry its id and
    share the session and the stop event; an exception in one body stops
    them all and is re-raised here (the service then exits non-zero).
    """
    if ids == (ctx.settings.uav_id,):
        body(ctx)
        return
    subs = contexts(ctx, ids)
    errors: list[BaseException] = []

    def run(sub: bus.Context) -> None:
        tag_vehicle(sub.settings.uav_id)  # this thread's log lines name its vehicle
        try:
            body(sub)
        except BaseException as err:  # re-raised by the caller's thread
            log.exception("vehicle body failed", extra=fields(uav=sub.settings.uav_id))
            errors.append(err)
            ctx.stop.set()

    threads = [threading.Thread(target=run, args=(sub,), daemon=True,
                                name=f"{ctx.settings.service}-{sub.settings.uav_id}")
               for sub in subs]
    for th in threads:
        th.start()
    log.info("serving vehicles", extra=fields(uavs=",".join(ids)))
    for th in threads:
        th.join()
    release(ctx, subs)
    if errors:
        raise errors[0]
