"""The planner pool: which replica of a planner a request goes to, and what comes back.

Each system may run as several replicas (each holder of its liveliness token
is one). A mission's requests go to its replica: the first by rendezvous
hashing of (mission id, replica id), so the vehicles of a fleet spread over
the pool and a mission keeps its replica (and that replica's warm start)
while it lives. A replica that let a request time out goes to the end of the
order (*suspect*) until it answers again. A request whose replica vanished
(the query ended without any reply: Zenoh finalises the queries of a closed
session) is asked again of the next replica within what is left of the same
deadline (a *failover*).

A reply is checked before it is used: it must come from the replica asked,
answer this step's request (step and sequence number), arrive within the
request's deadline and decode as a valid plan; anything else is a failed plan,
never flown. A system that misses ``deadline_misses`` deadlines in a row is
unavailable until it answers a health query (at most every
``health_every_s``).

The pool speaks to the replicas through a :class:`Transport` (the stack's:
:class:`ZenohTransport`) and keeps time on an injected clock, so every rule
above is unit-tested with a fake transport (tests/unit/services/supervisor/test_pool.py).
"""

from __future__ import annotations

import hashlib
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import zenoh

from dualpilot.plan import Plan, PlanStatus
from services.common import bus, keys, rejections, wire
from services.common.convert import plan as plan_convert
from services.common.log import fields
from services.msgs import common_pb2, plan_pb2

log = logging.getLogger("services.supervisor.ports")


class NoReply(TimeoutError):
    """The query ended without any reply before its timeout: nobody (left) to answer it."""


@dataclass(frozen=True)
class Reply:
    """A reply's payload as it arrived, and the Zenoh id of the session that sent it."""

    replier: str
    payload: bytes
    encoding: str


class Transport(Protocol):
    """How the pool reaches the planner replicas."""

    def replicas(self, system: int) -> list[str] | None:
        """The replicas' ids holding ``system``'s token (None: nobody tracks them; then the
        shared key is asked, whoever answers)."""
        ...

    def ask(self, system: int, replica: str, msg: plan_pb2.PlanRequest,
            timeout_s: float) -> Reply:
        """Send ``msg`` to ``replica`` ("": the shared key); the first reply. Raises
        :class:`NoReply` when the query ended without a reply, TimeoutError at the timeout,
        :class:`services.common.bus.QueryError` for an error reply."""
        ...

    def health(self, system: int, timeout_s: float) -> None:
        """Ask ``system``'s status queryable; raises TimeoutError (or ValueError) without an
        answer."""
        ...


@dataclass(frozen=True)
class PoolParams:
    """The pool's rules (wall seconds)."""

    #: a system that misses this many deadlines in a row is unavailable until it answers a
    #: health query (its ``status/<service>`` queryable)
    deadline_misses: int = 2
    health_every_s: float = 2.0
    health_timeout_s: float = 0.5
    #: a prepare (a planner's warm-up, not a flight plan) may take this long
    prepare_timeout_s: float = 60.0
    #: what System 1's and System 2's health queries wait beyond ``health_timeout_s``: the
    #: air–ground link's round trip for a system behind it (StackParams.link)
    health_extra_s: tuple[float, float] = (0.0, 0.0)


def rendezvous(mission_id: str, replicas: list[str]) -> list[str]:
    """``replicas`` in the mission's order: by the hash of (mission id, replica id)."""
    return sorted(replicas, key=lambda z: hashlib.blake2b(
        f"{mission_id}/{z}".encode(), digest_size=8).digest())


@dataclass
class _Ask:
    """One request in flight: what was sent, when, and by when it must be answered (and
    what the answering service reports of its own time, s)."""

    system: int
    step: int
    msg: plan_pb2.PlanRequest
    deadline_s: float
    t0: float
    account: bool
    service_s: float = 0.0


@dataclass(frozen=True)
class Answered:
    """One plan request as the pool saw it: the step that asked, the system, whether it was
    asked in the background (off the step's path), its round trip and the part of it the
    service reports (s: decode, plan, encode; 0 without a reply), the request's size (bytes)
    and the answer's status."""

    step: int
    system: int
    background: bool
    round_trip_s: float
    service_s: float
    request_bytes: int
    status: str


@dataclass
class PlannerPool:
    """Plan requests to the replicas of the planners, checked, failed over, deadline-counted."""

    transport: Transport
    uav: str
    mission_id: str
    deadline_s: Callable[[int], float]
    params: PoolParams = field(default_factory=PoolParams)
    clock: Callable[[], float] = time.perf_counter
    #: requests asked again of another replica (theirs vanished)
    failovers: int = field(default=0, init=False)
    #: every missed deadline (the named fault plan_deadline)
    deadline_misses: int = field(default=0, init=False)
    request_wall_s: float = field(default=0.0, init=False)  # this step's wall time in requests
    #: this step's share of it the services report (decode, plan, encode)
    service_s: float = field(default=0.0, init=False)
    requests: int = field(default=0, init=False)  # this step's requests

    def __post_init__(self) -> None:
        self.misses = {1: 0, 2: 0}  # deadlines missed in a row
        self.demoted: dict[int, float] = {}  # system → clock time of its last health query
        self.suspect: dict[int, set[str]] = {1: set(), 2: set()}  # replicas that timed out
        self._lock = threading.Lock()  # a background request's thread counts too
        self._answered: list[Answered] = []  # every request since the last take_answered

    # -- which replica ------------------------------------------------------------------------
    def order(self, system: int) -> list[str]:
        """The replicas of ``system`` in this mission's order, suspects last ([""]: the shared
        key, without a liveliness tracker)."""
        zids = self.transport.replicas(system)
        if zids is None:
            return [""]
        ordered = rendezvous(self.mission_id, zids)
        suspect = self.suspect[system]
        return [z for z in ordered if z not in suspect] + [z for z in ordered if z in suspect]

    def begin_step(self) -> None:
        self.request_wall_s = self.service_s = 0.0
        self.requests = 0

    # -- availability -------------------------------------------------------------------------
    def available(self, system: int) -> bool:
        """Not demoted, or a demoted system that answered its health query just now."""
        if system not in self.demoted:
            return True
        now = self.clock()
        if now - self.demoted[system] < self.params.health_every_s:
            return False
        self.demoted[system] = now
        try:
            self.transport.health(system, self.params.health_timeout_s
                                  + self.params.health_extra_s[system - 1])
        except (TimeoutError, ValueError) as err:
            log.info("planner still unavailable", extra=fields(system=system, error=str(err)))
            return False
        log.info("planner available again: it answered its health query",
                 extra=fields(system=system))
        del self.demoted[system]
        self.misses[system] = 0
        return True

    def count(self, system: int, plan: Plan) -> None:
        """A plan's deadline: a TIMEOUT is a miss; ``deadline_misses`` in a row demote."""
        if plan.status is not PlanStatus.TIMEOUT:
            self.misses[system] = 0
            return
        self.misses[system] += 1
        with self._lock:
            self.deadline_misses += 1
        if self.misses[system] >= self.params.deadline_misses and system not in self.demoted:
            self.demoted[system] = self.clock()
            log.warning("planner unavailable: missed its deadline", extra=fields(
                system=system, misses=self.misses[system], deadline_s=self.deadline_s(system)))

    def count_background(self, plan: Plan) -> None:
        """A background request's deadline: a TIMEOUT counts as a miss (never demotes: the
        concurrent supervisor decides without waiting for it)."""
        if plan.status is PlanStatus.TIMEOUT:
            with self._lock:
                self.deadline_misses += 1

    # -- prepare --------------------------------------------------------------------------------
    def prepare(self, system: int, msg: plan_pb2.PlanRequest) -> list[str]:
        """Every replica of ``system`` builds the mission's planner; the replicas that could not
        (their reasons). Raises RuntimeError when none could."""
        timeout = max(self.deadline_s(system), self.params.prepare_timeout_s)
        targets = self.order(system)
        errors = []
        for zid in targets:
            try:
                reply = self.transport.ask(system, zid, msg, timeout)
                self._check_replier(system, zid, reply)
                wire.parse(reply.payload, plan_pb2.Plan, reply.encoding)
            except (TimeoutError, bus.QueryError, rejections.CodecError) as err:
                errors.append(f"{zid or 'system'}: {err}")
        if len(errors) == len(targets):
            raise RuntimeError(f"system{system} could not prepare the mission: "
                               f"{'; '.join(errors)}")
        for why in errors:
            log.warning("a planner replica could not prepare the mission",
                        extra=fields(system=system, error=why))
        return errors

    # -- plan -----------------------------------------------------------------------------------
    def ask(self, system: int, step: int, msg: plan_pb2.PlanRequest,
            account: bool = True) -> Plan:
        """One checked request, failed over between replicas; ``account``: add it to this
        step's counters (a background request runs on its own thread and is not the step's)."""
        job = _Ask(system, step, msg, self.deadline_s(system), self.clock(), account)
        if account:
            self.requests += 1
        plan: Plan | None = None
        for zid in self.order(system):
            remaining = job.deadline_s - (self.clock() - job.t0)
            if remaining <= 0:
                break
            plan = self._ask_one(job, zid, remaining)
            if self._failed_over(job, zid, plan):
                plan = None
                continue
            if plan.status is PlanStatus.TIMEOUT and zid:
                self.suspect[system].add(zid)  # asked last from now on
            elif zid:
                self.suspect[system].discard(zid)
            break
        if plan is None:
            plan = Plan.failed(system, PlanStatus.TIMEOUT, self.clock() - job.t0,
                               f"no replica of system{system} answered within "
                               f"{job.deadline_s:g} s")
        wall = self.clock() - job.t0
        if account:
            self.request_wall_s += wall
        with self._lock:
            self._answered.append(Answered(step, system, not account, wall, job.service_s,
                                           msg.ByteSize(), plan.status.value))
        return plan

    def take_answered(self) -> list[Answered]:
        """Every request answered (or given up) since the last call, foreground and
        background."""
        with self._lock:
            out, self._answered = self._answered, []
        return out

    def _failed_over(self, job: _Ask, zid: str, plan: Plan) -> bool:
        """Whether ``zid`` vanished with the request (no reply, time left): ask the next."""
        left = job.deadline_s - (self.clock() - job.t0)
        if not (plan.info.get("no_reply") and zid and left > 0.01):
            return False
        with self._lock:
            self.failovers += 1
        log.warning("plan request failed over: the replica vanished", extra=fields(
            system=job.system, step=job.step, replica=zid, left_s=round(left, 4)))
        return True

    def _check_replier(self, system: int, zid: str, reply: Reply) -> None:
        """Refuse a reply from another session than the replica asked (or than any replica,
        for the shared key): counted as untrusted."""
        zids = self.transport.replicas(system)
        trusted = zid or (None if zids is None else frozenset(zids))
        ok = (reply.replier == trusted if isinstance(trusted, str)
              else trusted is None or reply.replier in trusted)
        if not ok:
            key = keys.plan(self.uav, system)
            rejections.rejected("reply", rejections.invalid(
                f"plan reply from session {reply.replier or '?'}, not from the replica asked "
                f"({zid or 'any'})"), log, key=key, reason=bus.UNTRUSTED)
            raise rejections.invalid(f"reply from {reply.replier or '?'}, not the replica asked")

    def _ask_one(self, job: _Ask, zid: str, timeout_s: float) -> Plan:
        """Ask replica ``zid`` ("" the shared key) once; a failed plan says why."""
        system = job.system
        log.debug("plan request sent", extra=fields(system=system, step=job.step,
                                                    replica=zid or "any", seq=job.msg.header.seq,
                                                    stamped_ns=job.msg.header.wall_time_ns))
        try:
            reply = self.transport.ask(system, zid, job.msg, timeout_s)
            self._check_replier(system, zid, reply)
            return self._checked(job, zid, wire.parse(reply.payload, plan_pb2.Plan,
                                                      reply.encoding))
        except NoReply as err:
            plan = Plan.failed(system, PlanStatus.TIMEOUT, self.clock() - job.t0, str(err))
            plan.info["no_reply"] = True
        except TimeoutError as err:
            plan = Plan.failed(system, PlanStatus.TIMEOUT, self.clock() - job.t0, str(err))
        except bus.QueryError as err:
            status = (PlanStatus.INVALID_INPUT if err.code == common_pb2.ERROR_CODE_INVALID
                      else PlanStatus.ERROR)
            plan = Plan.failed(system, status, self.clock() - job.t0, f"system{system}: {err}")
            if err.code == common_pb2.ERROR_CODE_UNPREPARED:
                plan.info["unprepared"] = True
            elif err.code == common_pb2.ERROR_CODE_UNAVAILABLE:  # a forecast by reference
                plan.info["forecast_unavailable"] = True
        except rejections.CodecError as err:
            rejections.rejected("Plan", err, log, key=keys.plan(self.uav, system))
            plan = Plan.failed(system, PlanStatus.ERROR, self.clock() - job.t0, str(err))
        return plan

    def _checked(self, job: _Ask, zid: str, reply: plan_pb2.Plan) -> Plan:
        """The reply's plan if it answers this request within its deadline, else a failed one."""
        system = job.system
        log.debug("plan reply received", extra=fields(system=system, step=job.step,
                                                      replica=zid or "any",
                                                      seq=reply.request_seq))
        dim = 3 if job.msg.state.dim == 3 else 2  # the request's: its plan's rows
        plan = plan_convert.plan_from_msg(reply, system, dim)
        job.service_s = reply.service_time_s
        if job.account:
            self.service_s += reply.service_time_s
        age = self.clock() - job.t0
        if reply.step != job.step or reply.request_seq != job.msg.header.seq:
            return Plan.failed(system, PlanStatus.ERROR, plan.compute_time_s,
                               f"system{system} answered step {reply.step} request "
                               f"{reply.request_seq}, not step {job.step} request "
                               f"{job.msg.header.seq}")
        if age > job.deadline_s:  # a plan older than its deadline is never flown
            log.warning("late plan not flown", extra=fields(
                system=system, step=job.step, age_s=round(age, 4), deadline_s=job.deadline_s))
            late = Plan.failed(system, PlanStatus.TIMEOUT, plan.compute_time_s,
                               f"plan {age:.3f} s old, past its {job.deadline_s:g} s deadline")
            late.info["late_s"] = round(age, 4)
            return late
        return plan


class ZenohTransport:
    """The pool's transport over Zenoh: ``plan/system<k>/<zid>`` queries to the replicas
    named by the liveliness tracker, trusting only the replica asked."""

    def __init__(self, session: zenoh.Session, uav: str, stop: threading.Event,
                 live: bus.Liveliness | None):
        self.session, self.uav, self.stop, self.live = session, uav, stop, live

    def replicas(self, system: int) -> list[str] | None:
        return None if self.live is None else self.live.replicas(f"system{system}")

    def _trusted(self, system: int, replica: str) -> bus.Trusted:
        if replica:
            return replica
        return None if self.live is None else self.live.holder(f"system{system}")

    def ask(self, system: int, replica: str, msg: plan_pb2.PlanRequest,
            timeout_s: float) -> Reply:
        base = keys.plan(self.uav, system)
        key = keys.plan_replica(self.uav, system, replica) if replica else base
        try:
            payload, enc, replier = bus.request_from(
                self.session, key, msg, timeout_s, self.stop,
                trusted=self._trusted(system, replica), count_key=base)
        except bus.EndedWithoutReply as err:
            raise NoReply(str(err)) from None
        return Reply(replier, payload, enc)

    def health(self, system: int, timeout_s: float) -> None:
        zids = self.replicas(system)
        trusted = None if zids is None else frozenset(zids)
        bus.query_status(self.session, self.uav, f"system{system}", timeout_s, trusted=trusted,
                         stop=self.stop)
