"""The air-side supervisor's view of the air–ground link, on injected exchanges and times.

Each step's state is worked out by hand from the exchanges fed in: nothing answered is
``link_lost``, some answered is ``link_degraded``, a slow round trip is ``link_degraded``, every
service behind the link gone is ``link_lost``; services on the air host never count.
"""

from __future__ import annotations

import threading

import pytest

from services.common import bus
from services.supervisor.airlink import OK, LinkWatch, WatchedTransport, service_of
from services.supervisor.faults import LINK_DEGRADED, LINK_LOST, NAMES
from services.supervisor.ports.params import AirLinkParams, StackParams

BEHIND = frozenset({"ews", "system2"})


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def watch(clock: Clock | None = None) -> LinkWatch:
    return LinkWatch(AirLinkParams(BEHIND, rtt_s=0.6, degraded_rtt_s=1.0),
                     clock=clock or Clock())


def test_keys_name_the_service_they_reach() -> None:
    assert service_of("dualpilot/uav1/ews/command") == "ews"
    assert service_of("dualpilot/uav1/ews/forecasts") == "ews"
    assert service_of("dualpilot/uav1/plan/system2") == "system2"
    assert service_of("dualpilot/uav1/plan/system2/0a1b2c") == "system2"
    assert service_of("dualpilot/uav1/status/system1") == "system1"
    assert service_of("dualpilot/uav1/uavsim/mission") == "uavsim"
    assert service_of("other/uav1/ews/command") == ""


def test_link_faults_are_named_faults() -> None:
    assert LINK_DEGRADED in NAMES and LINK_LOST in NAMES


def test_every_exchange_answered_quickly_is_ok() -> None:
    w = watch()
    w.exchange("ews", True, 0.12)
    w.exchange("system2", True, 0.40)
    assert w.step(0, []) == (OK, "")


def test_nothing_answered_is_lost_and_says_what_did_not_answer() -> None:
    w = watch()
    w.exchange("ews", False, 1.5, "no reply")
    w.exchange("system2", False, 6.0, "no reply")
    state, why = w.step(3, [])
    assert state == LINK_LOST
    assert why == "ews: no reply; system2: no reply"


def test_some_answered_is_degraded() -> None:
    w = watch()
    w.exchange("ews", True, 0.1)
    w.exchange("system2", False, 6.0)
    assert w.step(0, []) == (LINK_DEGRADED, "1 of 2 exchanges unanswered")


def test_a_slow_round_trip_is_degraded() -> None:
    w = watch()
    w.exchange("ews", True, 1.25)  # over degraded_rtt_s = 1.0
    assert w.step(0, []) == (LINK_DEGRADED, "round trip 1.250 s")


def test_every_service_behind_the_link_gone_is_lost_even_without_an_exchange() -> None:
    w = watch()
    assert w.step(0, ["system2", "ews", "system1"]) == (LINK_LOST, "ews, system2 gone")
    w2 = watch()
    assert w2.step(0, ["system2"]) == (LINK_DEGRADED, "system2 gone")


def test_services_on_this_host_never_count() -> None:
    w = watch()
    w.exchange("system1", False, 2.0)
    w.exchange("uavsim", False, 2.0)
    assert w.step(0, ["system1"]) == (OK, "")


def test_a_run_of_lost_steps_is_one_outage_with_its_wall_time() -> None:
    clock = Clock()
    w = watch(clock)
    for t in range(3):  # ok, ok, ok
        w.exchange("ews", True, 0.1)
        w.step(t, [])
    for t in range(3, 7):  # four lost steps, 8 s of wall time
        if t == 3:
            clock.t = 110.0
        w.exchange("ews", False, 2.0)
        w.step(t, [])
    clock.t = 118.0
    w.exchange("ews", True, 0.1)
    w.step(7, [])
    s = w.summary()
    assert s["steps"] == {OK: 4, LINK_DEGRADED: 0, LINK_LOST: 4}
    assert s["outages"] == [{"first_step": 3, "last_step": 6, "wall_s": 8.0}]
    assert s["services"] == ["ews", "system2"] and s["rtt_allowance_s"] == 0.6
    assert s["exchanges"] == 4 and s["rtt_ms"]["max"] == 100.0


def test_an_outage_to_the_end_has_no_last_step() -> None:
    clock = Clock()
    w = watch(clock)
    w.step(0, ["ews", "system2"])
    clock.t = 104.5
    assert w.summary()["outages"] == [{"first_step": 0, "last_step": None, "wall_s": 4.5}]


class Transport:
    """A transport whose EWS times out and whose System 2 answers with an error."""

    def query(self, key: str, msg: object, timeout_s: float, stop: threading.Event,
              trusted: bus.Trusted) -> tuple[bytes, str]:
        if "ews" in key:
            raise TimeoutError("no reply on ews/command within 1 s")
        raise bus.QueryError(4, "unprepared")

    def publisher(self, key: str) -> object:
        raise AssertionError("not used")

    def put(self, key: str, msg: object) -> None:
        raise AssertionError("not used")

    def planners(self, uav: str, stop: threading.Event, live: object) -> object:
        raise AssertionError("not used")


def test_the_watched_transport_counts_a_timeout_as_unanswered_an_error_as_answered() -> None:
    w = watch()
    t = WatchedTransport(Transport(), w)  # type: ignore[arg-type]
    with pytest.raises(TimeoutError):
        t.query("dualpilot/uav1/ews/command", None, 1.0, threading.Event(), None)  # type: ignore[arg-type]
    with pytest.raises(bus.QueryError):
        t.query("dualpilot/uav1/plan/system2", None, 1.0, threading.Event(), None)  # type: ignore[arg-type]
    state, why = w.step(0, [])
    assert state == LINK_DEGRADED and why == "1 of 2 exchanges unanswered"


def test_waits_for_services_behind_the_link_allow_its_round_trip() -> None:
    link = AirLinkParams(BEHIND, rtt_s=0.6)
    st = StackParams(link=link)
    assert link.allowance_s("system2") == 0.6 and link.allowance_s("system1") == 0.0
    # the forecast: 0.5 ΔT of a 1 s period, plus the round trip (EWS behind the link)
    assert st.forecast_wait_s(1.0, 1.0) == pytest.approx(1.1)
    assert st.forecast_wait_s(1.0, 0.0) == st.forecast_timeout_s  # lockstep: unchanged
    # a paced fire advance: its pacing 0.8 s + 1 ΔT + 0.6 s; off by default (fire_timeout_s)
    paced = StackParams(link=link, fire_deadline_periods=1.0)
    assert paced.fire_wait_s(0.8, 1.0, 1.0) == pytest.approx(2.4)
    assert paced.fire_wait_s(0.8, 1.0, 0.0) == paced.fire_timeout_s
    assert StackParams().fire_wait_s(0.8, 1.0, 1.0) == StackParams().fire_timeout_s
    assert StackParams().forecast_wait_s(1.0, 1.0) == 0.5  # no link: as before


def test_the_plan_deadline_of_a_system_behind_the_link_allows_its_round_trip() -> None:
    from services.common import wire
    from services.common.clock import SimClock
    from services.supervisor.ports import StackBus

    def bus_of(st: StackParams) -> StackBus:
        return StackBus(None, "u1", "m1", wire.Stamper("s", "u1"), SimClock(1.0),  # type: ignore[arg-type]
                        threading.Event(), st, dt_s=1.0)

    linked = bus_of(StackParams(link=AirLinkParams(BEHIND, rtt_s=0.6)))
    assert linked.deadline_s(1) == 2.0 and linked.deadline_s(2) == pytest.approx(5.6)
    explicit = bus_of(StackParams(plan_deadline_s=(1.0, 3.0),
                                  link=AirLinkParams(BEHIND, rtt_s=0.25)))
    assert explicit.deadline_s(2) == 3.25 and explicit.deadline_s(1) == 1.0
    assert bus_of(StackParams()).deadline_s(2) == 5.0  # loopback: the paper's 5 s


def test_the_supervisors_payload_across_the_link_per_step() -> None:
    from services.supervisor.airlink import payload_across

    rows = [
        {"key": "dualpilot/*/ews/command", "kind": "query", "direction": "sent", "bytes": 800},
        {"key": "dualpilot/*/ews/command", "kind": "reply", "direction": "received",
         "bytes": 90_000},
        {"key": "dualpilot/*/plan/system2/*", "kind": "query", "direction": "sent",
         "bytes": 1_200},
        {"key": "dualpilot/*/plan/system1/*", "kind": "query", "direction": "sent",
         "bytes": 50_000},  # System 1 is on the air host
        {"key": "dualpilot/*/vehicle/state", "kind": "put", "direction": "sent", "bytes": 7},
    ]
    assert payload_across(rows, BEHIND, 10) == {
        "air_to_ground_bytes": 2_000, "ground_to_air_bytes": 90_000,
        "air_to_ground_per_step": 200.0, "ground_to_air_per_step": 9000.0}
    w = watch()
    w.step(0, [])
    w.step(1, [])
    assert w.summary(rows)["payload"]["ground_to_air_per_step"] == 45_000.0


def test_a_plan_from_behind_the_link_took_the_requests_whole_wall_time() -> None:
    import numpy as np

    from dualpilot.plan import Plan, PlanStatus
    from services.supervisor.ports.planners import across_link

    def plan(system: int, status: PlanStatus = PlanStatus.OK) -> Plan:
        return Plan(system, status, np.zeros((1, 4)), np.zeros((0, 2)), compute_time_s=0.8)

    link = AirLinkParams(BEHIND, rtt_s=0.6)
    got = across_link(plan(2), 1.1, link)  # 0.8 s of compute, 0.3 s of link
    assert got.compute_time_s == 1.1 and got.info["planner_compute_s"] == 0.8
    assert across_link(plan(1), 1.1, link).compute_time_s == 0.8  # System 1: onboard
    assert across_link(plan(2), 1.1, AirLinkParams()).compute_time_s == 0.8  # one host
    assert across_link(plan(2, PlanStatus.TIMEOUT), 6.0, link).compute_time_s == 0.8


class Silent:
    """System 2 behind a dead link: every request times out; its health query's wait kept."""

    def __init__(self) -> None:
        self.now = 0.0
        self.health_waits: list[float] = []

    def replicas(self, system: int) -> list[str] | None:
        return ["z2"]

    def ask(self, system: int, replica: str, msg: object, timeout_s: float) -> object:
        self.now += timeout_s
        raise TimeoutError("no reply")

    def health(self, system: int, timeout_s: float) -> None:
        self.health_waits.append(timeout_s)


def test_a_demoted_system_behind_the_link_gets_its_health_query_the_round_trip_longer() -> None:
    from services.msgs import plan_pb2
    from services.supervisor.pool import PlannerPool, PoolParams

    t = Silent()
    params = PoolParams(deadline_misses=1, health_timeout_s=0.5, health_extra_s=(0.0, 0.6))
    pool = PlannerPool(t, "u1", "m1", lambda system: 5.0, params, clock=lambda: t.now)  # type: ignore[arg-type]
    req = plan_pb2.PlanRequest(step=3, system=2)
    req.header.seq = 1
    pool.count(2, pool.ask(2, 3, req))
    assert not pool.available(2)  # demoted
    t.now += 2.0
    assert pool.available(2) and t.health_waits == [pytest.approx(1.1)]
