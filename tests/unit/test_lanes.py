"""make test's lanes (tests/support/parallel.py): each test's xdist group and order, and the
unit lane's priority."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support import parallel

ROOT = Path(__file__).resolve().parents[1]


class Item:
    """What :func:`parallel.assign` reads of a collected test: its path, name and marks."""

    def __init__(self, rel: str, name: str = "test_a") -> None:
        self.path = ROOT / rel
        self.name = name
        self.marks: list[pytest.Mark] = []

    def add_marker(self, marker: pytest.MarkDecorator) -> None:
        self.marks.append(marker.mark)

    def iter_markers(self, name: str) -> list[pytest.Mark]:
        return [m for m in self.marks if m.name == name]

    def group(self) -> str:
        (mark,) = self.iter_markers("xdist_group")
        return str(mark.args[0])


def test_unit_tests_share_one_lane_and_the_stack_tiers_the_stack_lane() -> None:
    items = [Item("unit/dualpilot/test_x.py"), Item("e2e/test_soak.py"),
             Item("integration/test_uavsim.py"), Item("unit/services/test_y.py"),
             Item("e2e/test_lockstep.py", "test_risk_aware_controllers_fly[cc]"),
             Item("e2e/test_lockstep.py", "test_stack_and_in_process[cc]")]
    ordered = parallel.assign(items, ROOT)  # type: ignore[arg-type]
    groups = {(it.path.relative_to(ROOT).as_posix(), it.name): it.group() for it in items}
    assert groups[("unit/dualpilot/test_x.py", "test_a")] == parallel.UNIT_LANE
    assert groups[("unit/services/test_y.py", "test_a")] == parallel.UNIT_LANE
    assert {g for (rel, _), g in groups.items() if not rel.startswith("unit/")} == \
        {"stack-lane-0"}  # E2E_LANES = 1: one stack lane
    # the stack lane's units longest first (E2E_SECONDS: 166, 146, 61 s; integration 10 s),
    # then the unit lane in the collection's order
    assert [(it.path.name, it.name) for it in ordered] == [
        ("test_lockstep.py", "test_stack_and_in_process[cc]"),
        ("test_lockstep.py", "test_risk_aware_controllers_fly[cc]"),
        ("test_soak.py", "test_a"), ("test_uavsim.py", "test_a"), ("test_x.py", "test_a"),
        ("test_y.py", "test_a")]


def test_two_stack_lanes_take_the_longest_units_apart() -> None:
    lanes = dict(zip(("e2e/test_lockstep.py", "e2e/test_lockstep.py:risk", "e2e/test_faults.py",
                      "integration/test_uavsim.py"), ("a", "b", "c", "d"), strict=True))
    original = parallel.E2E_LANES
    parallel.E2E_LANES = 2
    try:
        got = parallel.lanes(list(lanes))
    finally:
        parallel.E2E_LANES = original
    # 166 → lane 0; 146 → lane 1; 98 → lane 1 (146 < 166); 10 → lane 0 (166 < 244)
    assert got == {"e2e/test_lockstep.py": "stack-lane-0", "e2e/test_lockstep.py:risk":
                   "stack-lane-1", "e2e/test_faults.py": "stack-lane-1",
                   "integration/test_uavsim.py": "stack-lane-0"}


class Config:
    """What :func:`parallel.on_workers` reads of pytest's configuration."""

    def __init__(self, numprocesses: int | None, worker: bool) -> None:
        self.option = type("Option", (), {"numprocesses": numprocesses})()
        if worker:
            self.workerinput = {"workerid": "gw0"}


def test_the_lanes_are_marked_on_the_controller_and_on_every_worker() -> None:
    """xdist clears ``-n`` on its workers (``numprocesses = None``), where the tests are
    collected: the lanes must be marked there too, or every test is a scope of its own."""
    assert parallel.on_workers(Config(2, worker=False))  # type: ignore[arg-type]
    assert parallel.on_workers(Config(None, worker=True))  # type: ignore[arg-type]
    assert not parallel.on_workers(Config(None, worker=False))  # type: ignore[arg-type]
    assert not parallel.on_workers(Config(0, worker=False))  # type: ignore[arg-type]


YIELD = """
import os, sys
sys.path.insert(0, {root!r})
import pytest
from tests.support import parallel
class Item:
    def __init__(self, group): self.group = group
    def iter_markers(self, name): return [pytest.mark.xdist_group(self.group).mark]
before = os.nice(0)
parallel.yield_cpu(Item("stack-lane-0"))
stack = os.nice(0)
parallel.yield_cpu(Item(parallel.UNIT_LANE))
print(before, stack, os.nice(0))
"""


@pytest.mark.parametrize(("worker", "unit_nice", "unit_lane_nice"),
                         [("gw1", None, 19), (None, None, 0), ("gw1", "7", 7)])
def test_only_the_unit_lanes_worker_lowers_its_priority(worker: str | None,
                                                        unit_nice: str | None,
                                                        unit_lane_nice: int) -> None:
    """Off a worker (a serial run) nothing changes; on one, the unit lane's test lowers the
    priority to UNIT_NICE (19 unless the environment says) and a stack lane's does not. (Run
    inside the unit lane, which already has 19, the test sees 19 throughout.)"""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTEST_XDIST_WORKER", "UNIT_NICE")}
    if worker is not None:
        env["PYTEST_XDIST_WORKER"] = worker
    if unit_nice is not None:
        env["UNIT_NICE"] = unit_nice
    base = os.nice(0)
    out = subprocess.run([sys.executable, "-c", YIELD.format(root=str(ROOT.parent))], env=env,
                         capture_output=True, text=True, check=True).stdout.split()
    assert [int(v) for v in out] == [base, base, max(base, unit_lane_nice)]
