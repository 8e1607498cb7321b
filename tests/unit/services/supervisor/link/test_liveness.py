"""When the supervisor counts its vehicle as lost: 3 s without a heartbeat, on injected times."""

from __future__ import annotations

from services.supervisor.link.heartbeat import READER_PERIOD_S, heard_within

LOST_S = 3.0


def test_a_vehicle_is_alive_until_lost_after_s_without_a_heartbeat() -> None:
    # the reader listened just now: only the heartbeat's age counts
    assert heard_within(13.0, heartbeat_s=10.0, listened_s=13.0, lost_after_s=LOST_S)
    assert not heard_within(13.01, heartbeat_s=10.0, listened_s=13.01, lost_after_s=LOST_S)


def test_a_reader_kept_off_the_cpu_has_not_missed_the_heartbeats() -> None:
    # the reader last listened at 10.5 s; 5 s later the heartbeats may be waiting in its socket:
    # the deaf time beyond one reader period does not count against the vehicle
    now = 15.5
    deaf = now - 10.5 - READER_PERIOD_S
    assert heard_within(now, heartbeat_s=10.0, listened_s=10.5, lost_after_s=LOST_S)
    assert now - 10.0 - deaf <= LOST_S
    # but a reader that listened all along and heard nothing for 3 s counts it lost
    assert not heard_within(now, heartbeat_s=10.0, listened_s=now, lost_after_s=LOST_S)


def test_one_reader_period_of_deafness_is_normal() -> None:
    # within one period the reader is not deaf: the heartbeat's age alone decides
    assert not heard_within(13.05, heartbeat_s=10.0, listened_s=13.0, lost_after_s=LOST_S)
