"""The air–ground link as the air-side supervisor sees it: ``link_degraded`` and ``link_lost``.

In a split deployment (docs/deployment.md) the supervisor flies on the UAV and some of the
services it asks run on the ground, behind the radio link (``AirLinkParams.services``: the EWS
and System 2). Every exchange with them — a fire command, a forecast query, a plan request, a
health query — goes through :class:`WatchedTransport` / :class:`WatchedPlanners`, which time
it and tell :class:`LinkWatch` whether an answer came back. Once a step, the watch names what
the link did during it:

================  =========================================================================
``link_lost``     nothing from behind the link answered during the step (every exchange
                  timed out or ended without a reply), or every service behind it has lost
                  its liveliness token (the Zenoh session across the link expired)
``link_degraded`` some answered and some did not, a round trip took longer than
                  ``degraded_rtt_s``, or some (not all) of the services behind it are gone
================  =========================================================================

An error reply is an answer (the link carried it). The supervisor's counters stay as they
are (``plan_deadline``, ``fire_stale``, ``forecast_stale`` name what each wait missed); the
link faults say why. ``summary.json`` (``stack.link``) keeps the steps in each state, the
outages (runs of lost steps) and the round trips.
"""

from __future__ import annotations

import statistics
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any, TypeVar

from google.protobuf.message import Message

from services.common import bus, keys
from services.msgs import plan_pb2

from .faults import LINK_DEGRADED, LINK_LOST
from .pool import Reply, Transport
from .ports.params import AirLinkParams
from .ports.stackbus import Publish, StackTransport

OK = "ok"

T = TypeVar("T")


def service_of(key: str) -> str:
    """The service a key's exchange is with: ``…/ews/command`` → ``ews``,
    ``…/plan/system2[/zid]`` → ``system2``, ``…/status/x`` → ``x``, ``…/uavsim/mission`` →
    ``uavsim`` ("" for a key outside the vehicle's namespace)."""
    parts = key.split("/")
    if len(parts) < 4 or parts[0] != keys.ROOT:
        return ""
    head, rest = parts[2], parts[3]
    if head == "plan" or head == "status":
        return rest
    return head


@dataclass
class _Step:
    """One step's exchanges with the services behind the link."""

    answered: int = 0
    failed: int = 0
    rtts_s: list[float] = field(default_factory=list)
    why: list[str] = field(default_factory=list)


@dataclass
class LinkWatch:
    """What the services behind the link did, step by step (thread-safe: the pool asks from
    threads of its own)."""

    params: AirLinkParams
    clock: Callable[[], float] = time.monotonic
    #: steps per state (ok, link_degraded, link_lost)
    steps: dict[str, int] = field(default_factory=lambda: {OK: 0, LINK_DEGRADED: 0,
                                                            LINK_LOST: 0})
    #: runs of lost steps: first and last step, wall s from the first to the next good step
    outages: list[dict[str, Any]] = field(default_factory=list)
    _now: _Step = field(default_factory=_Step)
    _rtts_s: list[float] = field(default_factory=list)
    _lost_since: tuple[int, float] | None = None
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def behind(self, service: str) -> bool:
        return service in self.params.services

    def exchange(self, service: str, answered: bool, rtt_s: float, why: str = "") -> None:
        """One exchange with ``service`` ended: answered (a reply or an error reply) or not."""
        if not self.behind(service):
            return
        with self._lock:
            if answered:
                self._now.answered += 1
                self._now.rtts_s.append(rtt_s)
            else:
                self._now.failed += 1
                if len(self._now.why) < 4:
                    self._now.why.append(f"{service}: {why}" if why else service)

    def timed(self, service: str, call: Callable[[], T]) -> T:
        """``call()``, counted as one exchange with ``service`` (an answer unless it raised
        TimeoutError or ended without a reply)."""
        t0 = self.clock()
        try:
            out = call()
        except TimeoutError as err:
            self.exchange(service, False, self.clock() - t0, f"no reply ({err})"[:120])
            raise
        except bus.QueryError:
            self.exchange(service, True, self.clock() - t0)
            raise
        except Exception as err:  # ended without a reply, cancelled: nothing came back
            self.exchange(service, False, self.clock() - t0, type(err).__name__)
            raise
        self.exchange(service, True, self.clock() - t0)
        return out

    def step(self, t: int, missing: Iterable[str]) -> tuple[str, str]:
        """The link's state over step ``t`` (``ok``, ``link_degraded``, ``link_lost``) and
        why; ``missing``: the services whose liveliness token is gone now."""
        gone = sorted(set(missing) & self.params.services)
        with self._lock:
            now, self._now = self._now, _Step()
        self._rtts_s.extend(now.rtts_s)
        slow = [r for r in now.rtts_s if r > self.params.degraded_rtt_s]
        if (gone and len(gone) == len(self.params.services)) or (now.failed and not
                                                                  now.answered):
            state = LINK_LOST
            why = (f"{', '.join(gone)} gone" if gone else "") or "; ".join(now.why)
        elif now.failed or slow or gone:
            state = LINK_DEGRADED
            why = "; ".join(filter(None, [
                f"{now.failed} of {now.failed + now.answered} exchanges unanswered"
                if now.failed else "",
                f"round trip {max(slow):.3f} s" if slow else "",
                f"{', '.join(gone)} gone" if gone else ""]))
        else:
            state, why = OK, ""
        self._outage(t, state)
        self.steps[state] += 1
        return state, why

    def _outage(self, t: int, state: str) -> None:
        if state == LINK_LOST and self._lost_since is None:
            self._lost_since = (t, self.clock())
        elif state != LINK_LOST and self._lost_since is not None:
            first, since = self._lost_since
            self.outages.append({"first_step": first, "last_step": t - 1,
                                 "wall_s": round(self.clock() - since, 3)})
            self._lost_since = None

    def summary(self, traffic: Iterable[dict[str, Any]] = ()) -> dict[str, Any]:
        """``summary.json``'s ``stack.link`` (with the supervisor's ``traffic`` rows: the
        payload it exchanged with the services behind the link, per step)."""
        rtts = sorted(self._rtts_s)
        outages = list(self.outages)
        if self._lost_since is not None:  # lost to the end
            outages.append({"first_step": self._lost_since[0], "last_step": None,
                            "wall_s": round(self.clock() - self._lost_since[1], 3)})
        out: dict[str, Any] = {"services": sorted(self.params.services),
                               "rtt_allowance_s": self.params.rtt_s, "steps": dict(self.steps),
                               "outages": outages, "exchanges": len(rtts),
                               "payload": payload_across(traffic, self.params.services,
                                                         sum(self.steps.values()))}
        if rtts:
            out["rtt_ms"] = {"median": round(1e3 * statistics.median(rtts), 2),
                             "p95": round(1e3 * rtts[min(len(rtts) - 1,
                                                         int(0.95 * len(rtts)))], 2),
                             "max": round(1e3 * rtts[-1], 2)}
        return out


def payload_across(rows: Iterable[dict[str, Any]], services: frozenset[str],
                   steps: int) -> dict[str, Any]:
    """The supervisor's payload bytes to and from the services behind the link
    (``rows``: its traffic table, services/common/traffic.py), in all and per step."""
    up = down = 0
    for r in rows:
        if service_of(r["key"]) not in services:
            continue
        if r["direction"] == "sent":
            up += int(r["bytes"])
        else:
            down += int(r["bytes"])
    n = max(1, steps)
    return {"air_to_ground_bytes": up, "ground_to_air_bytes": down,
            "air_to_ground_per_step": round(up / n, 1),
            "ground_to_air_per_step": round(down / n, 1)}


class WatchedTransport:
    """A :class:`StackTransport` whose queries to the services behind the link are timed."""

    def __init__(self, inner: StackTransport, watch: LinkWatch):
        self.inner, self.watch = inner, watch

    def query(self, key: str, msg: Message, timeout_s: float, stop: threading.Event,
              trusted: bus.Trusted) -> tuple[bytes, str]:
        return self.watch.timed(service_of(key),
                                lambda: self.inner.query(key, msg, timeout_s, stop, trusted))

    def publisher(self, key: str) -> Publish:
        return self.inner.publisher(key)

    def put(self, key: str, msg: Message) -> None:
        self.inner.put(key, msg)

    def planners(self, uav: str, stop: threading.Event,
                 live: bus.Liveliness | None) -> Transport:
        return WatchedPlanners(self.inner.planners(uav, stop, live), self.watch)


class WatchedPlanners:
    """The planner pool's :class:`Transport`, its plan and health queries timed."""

    def __init__(self, inner: Transport, watch: LinkWatch):
        self.inner, self.watch = inner, watch

    def replicas(self, system: int) -> list[str] | None:
        return self.inner.replicas(system)

    def ask(self, system: int, replica: str, msg: plan_pb2.PlanRequest,
            timeout_s: float) -> Reply:
        return self.watch.timed(f"system{system}",
                                lambda: self.inner.ask(system, replica, msg, timeout_s))

    def health(self, system: int, timeout_s: float) -> None:
        self.watch.timed(f"system{system}", lambda: self.inner.health(system, timeout_s))
