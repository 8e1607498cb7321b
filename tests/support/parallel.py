"""How ``make test`` spreads the tiers over pytest-xdist's workers (``--dist loadgroup``).

Every test runs in a lane: an xdist group, so one worker and one test at a time.

* **Stack lanes** (:data:`E2E_LANES`, one by default): the integration and e2e tests. They
  start real processes, and some check wall-clock behaviour (the offboard-loss failsafe,
  plan deadlines, the web page's updates), so they run at the machine's normal priority,
  as in a serial run. Their modules are dealt to the lanes longest first by their measured
  time (:data:`E2E_SECONDS`), a module whole, so that a stack its tests share starts once;
  half of test_lockstep.py is a unit of its own (:data:`SPLIT`), with a fleet of its own.
* **The unit lane** (:data:`UNIT_LANE`): every unit test, on a worker that lowers its own
  CPU priority to :data:`UNIT_NICE` at its first test (:func:`yield_cpu`). It takes the
  cycles the stack lane leaves idle (a serial run of the stack tiers uses ~0.9 of a core on
  average), not the time the stack's processes need: no unit test checks a duration
  (docs/testing.md).

With the pytest this project pins, xdist's loadgroup does not keep these groups
(docs/testing.md: pytest-xdist issue #1386); ``make test`` runs two pytest processes instead
(scripts/test_lanes.sh).

``TEST_WORKERS=N make test`` runs N workers; :func:`assign` marks and orders the lanes.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

#: how many stack lanes (integration and e2e tests) run at once (environment ``E2E_LANES``,
#: from make test; its TEST_WORKERS is this plus one, the unit lane's)
E2E_LANES = max(1, int(os.environ.get("E2E_LANES", "1")))
#: the xdist group of every unit test
UNIT_LANE = "unit-lane"
#: the niceness the unit lane's worker takes (nice(2); 19 is the lowest priority: it gets
#: ~1.5 % of a core a niceness-0 process wants, all of a core nobody wants); the
#: environment's UNIT_NICE, as scripts/test_lanes.sh's (the flake hunt's 0 beside its load)
UNIT_NICE = int(os.environ.get("UNIT_NICE", "19"))
#: the tiers that run in the stack lanes
STACK_TIERS = ("integration", "e2e")

#: seconds of each e2e unit (a module, or a group a test names) in one serial run of the
#: integration and e2e tiers (``pytest tests/integration tests/e2e --durations=120``, 2 cores,
#: 2026-12-06, 1278 s in all; test_lockstep.py's 312 s in its two units); a unit not listed
#: counts :data:`UNLISTED_S`
E2E_SECONDS: dict[str, float] = {
    "e2e/test_lockstep.py": 166, "e2e/test_lockstep.py:risk": 146, "e2e/test_faults.py": 98,
    "e2e/test_lockstep_lookahead.py": 90, "e2e/test_mavsdk_examples.py": 82,
    "e2e/test_attacks.py": 68, "e2e/test_soak.py": 61, "e2e/test_stream.py": 53,
    "e2e/test_pool.py": 53, "e2e/test_mavsdk.py": 41, "e2e/test_flavours.py": 30,
    "e2e/test_web_view.py": 29, "e2e/test_load.py": 29, "e2e/test_launcher.py": 15,
    "e2e/test_ground_station.py": 14, "e2e/test_fuzz_mission.py": 12,
    "e2e/test_mavlink_fuzz_mission.py": 11, "e2e/test_tls_acl.py": 11,
    "e2e/test_live_view.py": 10, "e2e/test_mission.py": 10, "e2e/test_config_road.py": 9,
    "e2e/test_lockstep_plugin.py": 9, "e2e/test_mavproxy_ardupilot.py": 8,
}
UNLISTED_S = 10.0

#: e2e tests that are a unit apart from the rest of their module (with module fixtures of
#: their own, on their own lane): test name prefix (module::test) -> unit
SPLIT: dict[str, str] = {
    "e2e/test_lockstep.py::test_risk_aware_controllers": "e2e/test_lockstep.py:risk",
}


def unit_of(item: pytest.Item, rel: Path) -> str:
    """The stack unit of ``item`` (at ``rel`` under tests/): its module's path, or the unit
    :data:`SPLIT` names for it."""
    module = rel.as_posix()
    for prefix, unit in SPLIT.items():
        if f"{module}::{item.name}".startswith(prefix):
            return unit
    return module


def lanes(units: list[str]) -> dict[str, str]:
    """Each stack unit's lane (``stack-lane-<k>``): longest first, into the least loaded
    lane."""
    load = [0.0] * E2E_LANES
    out: dict[str, str] = {}
    for unit in sorted(set(units), key=lambda u: -E2E_SECONDS.get(u, UNLISTED_S)):
        k = load.index(min(load))
        load[k] += E2E_SECONDS.get(unit, UNLISTED_S)
        out[unit] = f"stack-lane-{k}"
    return out


def on_workers(config: pytest.Config) -> bool:
    """Whether this run spreads its tests over xdist's workers: on the controller ``-n``
    says so; on a worker xdist clears ``-n`` and leaves ``workerinput``. The lanes must be
    marked where the tests are collected, on every worker."""
    return bool(getattr(config.option, "numprocesses", None)) or hasattr(config,
                                                                         "workerinput")


def assign(items: list[pytest.Item], root: Path) -> list[pytest.Item]:
    """Mark every test's lane (its xdist group) and order them: the stack lanes' units
    longest first, then the unit lane in the collection's order."""
    rels = {id(it): _rel(it, root) for it in items}
    stack = [it for it in items if rels[id(it)].parts[:1] in {(t,) for t in STACK_TIERS}]
    units = {id(it): unit_of(it, rels[id(it)]) for it in stack}
    lane = lanes(list(units.values()))
    for it in items:
        named = lane[units[id(it)]] if id(it) in units else UNIT_LANE
        it.add_marker(pytest.mark.xdist_group(named))

    def key(it: pytest.Item) -> tuple[int, float]:
        if id(it) in units:
            return 0, -E2E_SECONDS.get(units[id(it)], UNLISTED_S)
        return 1, 0.0
    return sorted(items, key=key)


def yield_cpu(item: pytest.Item) -> None:
    """On an xdist worker, lower the worker's CPU priority to :data:`UNIT_NICE` before the
    unit lane's first test (a worker never runs two lanes; priority only goes down)."""
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        return
    groups = [m.args[0] for m in item.iter_markers("xdist_group") if m.args]
    if UNIT_LANE in groups and os.nice(0) < UNIT_NICE:
        os.nice(UNIT_NICE - os.nice(0))


def _rel(item: pytest.Item, root: Path) -> Path:
    try:
        return Path(item.path).relative_to(root)
    except ValueError:
        return Path()
