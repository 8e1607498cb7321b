"""Soak, small: 20 consecutive missions through the stack (benchmarks/soak.py, which runs more).

The router, the EWS and the planners run throughout; each mission starts and
stops its own uavsim and supervisor. Checks: every mission ended and was
recorded, no process was left behind, every exit was clean, no service's
file descriptors grew, and the long-lived services' memory grew by at most
25 % after a 5-mission warm-up (generous: the benchmark's target is 10 %
after a longer warm-up).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from e2e.test_load import _bench
from tests.support.waits import check, logs_in

pytestmark = [pytest.mark.slow, pytest.mark.timeout(420)]

MISSIONS = 20
WARMUP = 5


def test_twenty_consecutive_missions(tmp_path: Path) -> None:
    soak = _bench("soak")
    result = soak.run_soak(MISSIONS, tmp_path, speed_factor=1000.0, timeout_s=120.0)
    rep = result.report(WARMUP)
    assert result.missions == MISSIONS
    # the missions that did not end (or were not recorded), their logs and the shared ones
    failed = [tmp_path / f"m{k:04d}" for k in result.not_recorded]
    logs = [*(log for d in failed for log in logs_in(d)), *logs_in(tmp_path / "logs")]
    check(not result.not_ended and not result.not_recorded, "every mission to end and be "
          "recorded", logs, rep)
    check(not result.leaked and not result.bad_exits, "no process left behind, every exit "
          "clean", logs_in(tmp_path / "logs"), rep)
    growth = rep["rss_growth_after_warmup"]
    assert growth and max(growth.values()) <= 0.25, rep
    for name in soak.LONG_LIVED:
        assert rep["fds_last"][name] <= rep["fds_first"][name] + 4, rep
        assert rep["children_max"][name] == 0, rep
    print(f"\nsoak: {MISSIONS} missions in {result.wall_s:.0f} s, RSS growth after warm-up "
          f"{growth}, fds {rep['fds_last']}")
