"""Who is alive: the services' liveliness tokens and the sessions that hold them."""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Iterable

import zenoh

from services.common import keys, rejections
from services.common.bus.query import UNTRUSTED

log = logging.getLogger("services.common.bus")


class Liveliness:
    """Tracks which services of a vehicle are alive and which session holds each one's token.

    A service is alive while its ``alive/<service>`` token is up. Its holder is
    the session named by its ``alive/<service>/<zid>`` token (declared first,
    :meth:`Context.announce`); while several sessions claim one service the
    first seen stays the holder (:meth:`holder`) and every other claim is
    logged and counted (``alive/<service>``, reason ``untrusted``). A
    replicated service (:data:`keys.REPLICATED`, the planners) is alive while
    any replica holds its token, and every holder is one of its replicas
    (:meth:`replicas`).
    """

    def __init__(self, session: zenoh.Session, uav: str):
        self.alive: set[str] = set()
        self.holders: dict[str, list[str]] = {}
        self.claims = 0  # holder tokens beyond the first per service (impostors, duplicates)
        self.uav = uav
        self.cond = threading.Condition()
        self.sub = session.liveliness().declare_subscriber(
            keys.alive_tree(uav), self._on, history=True)

    def _on(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        held = keys.holder_of(key)
        put = sample.kind == zenoh.SampleKind.PUT
        second = ""
        with self.cond:
            if held is None:
                if put:
                    self.alive.add(keys.service_of(key))
                else:
                    self.alive.discard(keys.service_of(key))
            else:
                name, zid = held
                zids = self.holders.setdefault(name, [])
                if put and zid not in zids:
                    zids.append(zid)
                    if len(zids) > 1 and name not in keys.REPLICATED:
                        self.claims += 1
                        second = f"{name} claimed by {zid} while {zids[0]} holds it"
                elif not put and zid in zids:
                    zids.remove(zid)
            self.cond.notify_all()
        if second:  # only counting and logging here: never Zenoh in a callback
            rejections.rejected("liveliness", rejections.invalid(second), log, key=key,
                                reason=UNTRUSTED)

    def holder(self, service: str) -> str:
        """The Zenoh id of the session holding ``service``'s token ("" while nobody does)."""
        with self.cond:
            zids = self.holders.get(service)
            return zids[0] if zids else ""

    def replicas(self, service: str) -> list[str]:
        """The Zenoh ids of every session holding ``service``'s token, first seen first."""
        with self.cond:
            return list(self.holders.get(service, []))

    def _up(self) -> set[str]:
        """The services alive now (caller holds the lock)."""
        return self.alive | {name for name in keys.REPLICATED if self.holders.get(name)}

    def others(self, service: str, own: str) -> list[str]:
        """Sessions other than ``own`` that claim ``service``."""
        with self.cond:
            return [z for z in self.holders.get(service, []) if z != own]

    def wait_for(self, services: Iterable[str], timeout_s: float,
                 stop: threading.Event | None = None) -> bool:
        wanted = set(services)
        deadline = time.monotonic() + timeout_s
        with self.cond:
            while not wanted <= self._up():
                remaining = deadline - time.monotonic()
                if remaining <= 0 or (stop is not None and stop.is_set()):
                    return False
                self.cond.wait(min(remaining, 0.2))
            return True

    def missing(self, services: Iterable[str]) -> set[str]:
        with self.cond:
            return set(services) - self._up()

    def wait_any(self, services: Iterable[str], timeout_s: float,
                 stop: threading.Event | None = None) -> bool:
        """Wait until at least one of ``services`` is alive (True) or the time is up."""
        wanted = set(services)
        deadline = time.monotonic() + timeout_s
        with self.cond:
            while not wanted & self._up():
                remaining = deadline - time.monotonic()
                if remaining <= 0 or (stop is not None and stop.is_set()):
                    return False
                self.cond.wait(min(remaining, 0.2))
            return True

    def wait_gone(self, service: str, timeout_s: float,
                  stop: threading.Event | None = None) -> bool:
        """Wait until ``service``'s token is gone (True) or the time is up."""
        deadline = time.monotonic() + timeout_s
        with self.cond:
            while service in self._up():
                remaining = deadline - time.monotonic()
                if remaining <= 0 or (stop is not None and stop.is_set()):
                    return False
                self.cond.wait(min(remaining, 0.2))
            return True
