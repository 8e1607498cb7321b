"""The one pause/resume policy on a fake clock: announced, bounded, stoppable."""

from __future__ import annotations

import threading

import pytest

from services.supervisor.pause import PausePolicy
from services.supervisor.ports import Aborted


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def policy(limit_s: float = 10.0) -> tuple[PausePolicy, Clock, list[tuple[str, str]]]:
    clock, said = Clock(), []
    stop = threading.Event()

    def wait(period: float) -> None:  # the wait passes on the fake clock, not the wall's
        clock.now += period

    p = PausePolicy(stop, limit_s, lambda kind, msg: said.append((kind, msg)), clock, wait)
    return p, clock, said


def test_a_pause_is_announced_and_ends_when_the_need_is_met() -> None:
    p, clock, said = policy()
    back_at = 2.0
    paused = p.hold("vehicle lost", lambda: clock.now >= back_at, period_s=0.5)
    assert paused == pytest.approx(2.0)
    assert said == [("paused", "vehicle lost"), ("resumed", "paused 2.0 s")]
    assert p.pauses == 1 and p.paused_s == pytest.approx(2.0)


def test_the_tick_runs_while_paused_and_may_end_the_mission() -> None:
    p, clock, _ = policy()
    ticks: list[float] = []

    def tick(paused: float) -> None:
        ticks.append(paused)
        if paused >= 1.0:
            raise Aborted("gone for good")

    with pytest.raises(Aborted, match="gone for good"):
        p.hold("vehicle lost", lambda: False, tick, period_s=0.5)
    assert ticks == [0.0, 0.5, 1.0]


def test_a_pause_longer_than_the_limit_aborts() -> None:
    p, _, said = policy(limit_s=3.0)
    with pytest.raises(Aborted, match="paused for more than 3 s: no planner alive"):
        p.hold("no planner alive", lambda: False, period_s=1.0)
    assert said == [("paused", "no planner alive")]  # never resumed


def test_a_stop_aborts_the_pause() -> None:
    p, _, _ = policy()
    p.stop.set()
    with pytest.raises(Aborted, match="stopped"):
        p.hold("vehicle lost", lambda: False)


def test_the_resume_message_is_the_callers() -> None:
    p, clock, said = policy()
    p.hold("holding", lambda: clock.now >= 1.0, period_s=0.25,
           resumed=lambda s: f"system2 back after {s:.1f} s")
    assert said[-1] == ("resumed", "system2 back after 1.0 s")
