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

pytestmark = [pytest.mark.slow, pytest.mark.timeout(420)]

MISSIONS = 20
WARMUP = 5


def test_twenty_consecutive_missions(tmp_path: Path) -> None:
    soak = _bench("soak")
    result = soak.run_soak(MISSIONS, tmp_path, speed_factor=1000.0, timeout_s=120.0)
    rep = result.report(WARMUP)
    assert result.missions == MISSIONS
    assert not result.not_ended and not result.not_recorded, rep
    assert not result.leaked and not result.bad_exits, rep
    growth = rep["rss_growth_after_warmup"]
    assert growth and max(growth.values()) <= 0.25, rep
    for name in soak.LONG_LIVED:
        assert rep["fds_last"][name] <= rep["fds_first"][name] + 4, rep
        assert rep["children_max"][name] == 0, rep
    print(f"\nsoak: {MISSIONS} missions in {result.wall_s:.0f} s, RSS growth after warm-up "
          f"{growth}, fds {rep['fds_last']}")
