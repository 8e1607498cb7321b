"""The planner pool's rules on a fake transport and a fake clock: no process, no sleep.

Replicas that answer, vanish (killed), never answer (muted), answer late (slow)
or are impersonated (a reply from another session); the rendezvous order, the
failover within the deadline, suspects last, demotion after missed deadlines
and the health query that brings a system back.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import numpy as np
import pytest

from dualpilot.plan import Objective, Plan, PlanStatus
from services.common import bus, rejections, wire
from services.common.convert import plan as plan_convert
from services.msgs import common_pb2, plan_pb2
from services.supervisor.pool import NoReply, PlannerPool, PoolParams, Reply, rendezvous

UAV = "u1"
DEADLINE_S = 5.0
SERVICE_S = 0.125  # what every fake reply says the service took (s)


@dataclass
class FakeClock:
    now: float = 100.0

    def __call__(self) -> float:
        return self.now


@dataclass
class Replica:
    """What one replica does with a request: answer after ``delay_s`` (of the fake clock),
    vanish (``killed``), stay silent until the timeout (``muted``), answer as another
    session (``impostor``), or answer with an error."""

    zid: str
    delay_s: float = 0.01
    killed: bool = False
    muted: bool = False
    impostor: bool = False
    error: int = 0
    wrong_step: bool = False


@dataclass
class FakeTransport:
    clock: FakeClock
    replicas_: dict[int, list[Replica]]
    asked: list[tuple[int, str, float]] = field(default_factory=list)
    healthy: bool = True
    health_asked: int = 0
    tracked: bool = True

    def replicas(self, system: int) -> list[str] | None:
        return [r.zid for r in self.replicas_[system]] if self.tracked else None

    def _replica(self, system: int, zid: str) -> Replica:
        if not zid:
            return self.replicas_[system][0]
        return next(r for r in self.replicas_[system] if r.zid == zid)

    def ask(self, system: int, replica: str, msg: plan_pb2.PlanRequest,
            timeout_s: float) -> Reply:
        self.asked.append((system, replica, timeout_s))
        r = self._replica(system, replica)
        if r.killed:
            self.clock.now += 0.02
            raise NoReply(f"no reply on plan/system{system}/{replica}")
        if r.muted:
            self.clock.now += timeout_s
            raise TimeoutError(f"no reply within {timeout_s:.3g} s")
        if r.error:
            self.clock.now += r.delay_s
            raise bus.QueryError(r.error, "bad request")
        self.clock.now += r.delay_s
        return Reply(("f" * 32) if r.impostor else r.zid, *_plan_reply(msg, system,
                                                                      r.wrong_step))

    def health(self, system: int, timeout_s: float) -> None:
        self.health_asked += 1
        if not self.healthy:
            raise TimeoutError("no status")


def _plan_reply(msg: plan_pb2.PlanRequest, system: int, wrong_step: bool) -> tuple[bytes, str]:
    states = np.array([[50.0, 50.0, 0.0, 0.0], [51.0, 51.0, 1.0, 1.0]])
    plan = Plan(system, PlanStatus.OK, states, np.array([[0.5, 0.5]]), 0.004,
                objective=Objective.MISSION_TIME)
    step = msg.step + (1 if wrong_step else 0)
    reply = plan_convert.plan_to_msg(plan, step, msg.header.seq, wire.Stamper("s", UAV))
    reply.service_time_s = SERVICE_S
    return reply.SerializeToString(), wire.encoding_name(reply)


def zids(n: int) -> list[str]:
    return [hashlib.md5(str(k).encode()).hexdigest() for k in range(n)]


def pool(replicas: list[Replica], params: PoolParams = PoolParams(),
         tracked: bool = True) -> tuple[PlannerPool, FakeTransport, FakeClock]:
    clock = FakeClock()
    transport = FakeTransport(clock, {2: replicas, 1: [Replica(zids(9)[8])]}, tracked=tracked)
    return (PlannerPool(transport, UAV, "mission-7", lambda s: DEADLINE_S, params, clock),
            transport, clock)


def request(step: int = 3) -> plan_pb2.PlanRequest:
    m = plan_pb2.PlanRequest(step=step, system=2, mission_id="mission-7", deadline_s=DEADLINE_S)
    wire.Stamper("supervisor", UAV).stamp(m.header)
    return m


def test_a_mission_keeps_the_first_replica_of_its_rendezvous_order() -> None:
    ids = zids(3)
    p, transport, _ = pool([Replica(z) for z in ids])
    first = rendezvous("mission-7", ids)[0]
    assert p.order(2)[0] == first
    for step in range(4):
        assert p.ask(2, step, request(step)).ok
    assert {zid for _, zid, _ in transport.asked} == {first}
    # the order is the hash's, whoever lists the replicas first
    assert rendezvous("mission-7", list(reversed(ids))) == rendezvous("mission-7", ids)


def test_missions_spread_over_the_replicas() -> None:
    ids = zids(3)
    firsts = {rendezvous(f"mission-{k}", ids)[0] for k in range(30)}
    assert firsts == set(ids)


def test_a_killed_replica_fails_over_within_the_same_deadline() -> None:
    ids = rendezvous("mission-7", zids(3))
    p, transport, _ = pool([Replica(ids[0], killed=True), Replica(ids[1]), Replica(ids[2])])
    plan = p.ask(2, 3, request())
    assert plan.ok and p.failovers == 1
    (_, first, t1), (_, second, t2) = transport.asked
    assert (first, second) == (ids[0], ids[1])
    assert t2 == pytest.approx(t1 - 0.02)  # what was left of the deadline, not a new one


def test_a_muted_replica_costs_its_deadline_is_suspect_and_asked_last() -> None:
    ids = rendezvous("mission-7", zids(2))
    muted = Replica(ids[0], muted=True)
    p, transport, _ = pool([muted, Replica(ids[1])])
    plan = p.ask(2, 3, request())
    assert plan.status is PlanStatus.TIMEOUT and p.failovers == 0
    assert [zid for _, zid, _ in transport.asked] == [ids[0]]  # no time left for another
    assert p.order(2) == [ids[1], ids[0]]  # suspect: last from now on
    assert p.ask(2, 4, request(4)).ok and transport.asked[-1][1] == ids[1]
    # a suspect that answers again (its peer gone) is no longer suspect
    muted.muted = False
    p.transport.replicas_[2] = [muted]  # type: ignore[attr-defined]
    assert p.ask(2, 5, request(5)).ok and p.suspect[2] == set()


def test_a_slow_reply_past_its_deadline_is_never_flown() -> None:
    ids = zids(1)
    p, _, _ = pool([Replica(ids[0], delay_s=DEADLINE_S + 0.5)])
    plan = p.ask(2, 3, request())
    assert plan.status is PlanStatus.TIMEOUT and plan.info["late_s"] == pytest.approx(5.5)
    assert "past its 5 s deadline" in plan.message


def test_an_impostors_reply_is_refused_and_counted() -> None:
    before = rejections.REJECTED.snapshot().get(f"dualpilot/{UAV}/plan/system2", {})
    p, _, _ = pool([Replica(zids(1)[0], impostor=True)])
    plan = p.ask(2, 3, request())
    assert plan.status is PlanStatus.ERROR and "not the replica asked" in plan.message
    after = rejections.REJECTED.snapshot()[f"dualpilot/{UAV}/plan/system2"]
    assert after.get(bus.UNTRUSTED, 0) == before.get(bus.UNTRUSTED, 0) + 1


def test_a_reply_to_another_step_is_refused() -> None:
    p, _, _ = pool([Replica(zids(1)[0], wrong_step=True)])
    plan = p.ask(2, 3, request())
    assert plan.status is PlanStatus.ERROR and "answered step 4" in plan.message


def test_error_replies_say_what_they_were() -> None:
    p, _, _ = pool([Replica(zids(1)[0], error=common_pb2.ERROR_CODE_INVALID)])
    assert p.ask(2, 3, request()).status is PlanStatus.INVALID_INPUT
    p, _, _ = pool([Replica(zids(1)[0], error=common_pb2.ERROR_CODE_UNPREPARED)])
    plan = p.ask(2, 3, request())
    assert plan.status is PlanStatus.ERROR and plan.info["unprepared"]


def test_k_missed_deadlines_demote_until_a_health_query_is_answered() -> None:
    ids = zids(1)
    p, transport, clock = pool([Replica(ids[0], muted=True)], PoolParams(deadline_misses=2))
    for step in (3, 4):
        assert p.available(2)
        p.count(2, p.ask(2, step, request(step)))
    assert p.deadline_misses == 2 and not p.available(2)  # demoted at the second miss
    assert transport.health_asked == 0  # no health query before health_every_s
    transport.healthy = False
    clock.now += 2.0
    assert not p.available(2) and transport.health_asked == 1
    assert not p.available(2) and transport.health_asked == 1  # again only after 2 s
    transport.healthy = True
    clock.now += 2.0
    assert p.available(2) and p.misses[2] == 0


def test_without_a_tracker_the_shared_key_is_asked() -> None:
    p, transport, _ = pool([Replica(zids(1)[0])], tracked=False)
    assert p.order(2) == [""]
    assert p.ask(2, 3, request()).ok and transport.asked[0][1] == ""


def test_prepare_reaches_every_replica_and_fails_only_when_none_could() -> None:
    ids = zids(3)
    p, transport, _ = pool([Replica(ids[0]), Replica(ids[1], killed=True), Replica(ids[2])])
    errors = p.prepare(2, request(0))
    assert len(errors) == 1 and ids[1] in errors[0]
    assert {zid for _, zid, _ in transport.asked} == set(ids)
    dead, _, _ = pool([Replica(z, killed=True) for z in ids])
    with pytest.raises(RuntimeError, match="could not prepare the mission"):
        dead.prepare(2, request(0))


def test_the_step_counters_add_up_the_requests() -> None:
    p, _, clock = pool([Replica(zids(1)[0], delay_s=0.25)])
    p.begin_step()
    p.ask(2, 3, request())
    p.ask(2, 4, request(4), account=False)  # a background request is not the step's
    assert p.requests == 1 and p.request_wall_s == pytest.approx(0.25)


def test_every_request_is_kept_with_its_round_trip_and_class() -> None:
    """One row per request, waited-for or background, answered or not: its step, system,
    round trip on the pool's clock, the service's reported time, size and status."""
    p, _, _ = pool([Replica(zids(1)[0], delay_s=0.25)])
    p.ask(2, 3, request())
    p.ask(2, 4, request(4), account=False)
    muted, *_ = pool([Replica(zids(1)[0], muted=True)])
    muted.ask(2, 5, request(5))
    rows = p.take_answered()
    assert [(a.step, a.system, a.background, a.status) for a in rows] == [
        (3, 2, False, "ok"), (4, 2, True, "ok")]
    assert all(a.round_trip_s == pytest.approx(0.25) for a in rows)
    assert all(a.request_bytes == request(a.step).ByteSize() for a in rows)
    assert all(a.service_s == SERVICE_S for a in rows)
    assert p.take_answered() == []  # taken once
    (lost,) = muted.take_answered()
    assert (lost.step, lost.status, lost.round_trip_s, lost.service_s) == (
        5, "timeout", DEADLINE_S, 0.0)
