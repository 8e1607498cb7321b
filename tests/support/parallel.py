"""How ``make test`` spreads the tiers over pytest-xdist's workers (``--dist loadgroup``).

The e2e tier is CPU-bound on two cores (one serial run of it: ~0.85 of a core on average)
and its wall-clock checks (the offboard-loss failsafe, plan deadlines, the web page's
updates) fail when several of its stacks share the cores with each other. So it runs in
:data:`E2E_LANES` lanes, each an xdist group (one worker, one test at a time), its modules
dealt to the lanes longest first by their measured time (:data:`E2E_SECONDS`), a module
whole, so that its module-scoped fixtures (a stack several tests fly on) start once; the
other workers take the integration and unit tests, a test at a time, or a module at a
time when its tests share a fixture (:func:`group`). Half of test_lockstep.py is a unit of
its own (:data:`SPLIT`), with a fleet of its own.
:func:`ordered` puts the lanes first, so that they start at once on workers of their own.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

#: fixture scopes wider than a test and narrower than a worker's session
SHARED_SCOPES = frozenset({"class", "module", "package"})

#: how many e2e tests run at once (environment ``E2E_LANES``, from make test; its TEST_WORKERS
#: is this plus the workers of the other tiers)
E2E_LANES = max(1, int(os.environ.get("E2E_LANES", "2")))

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
    """The e2e unit of ``item`` (at ``rel`` under tests/): its module's path, or the unit
    :data:`SPLIT` names for it."""
    module = rel.as_posix()
    for prefix, unit in SPLIT.items():
        if f"{module}::{item.name}".startswith(prefix):
            return unit
    return module


def lanes(units: list[str]) -> dict[str, str]:
    """Each e2e unit's lane (``e2e-lane-<k>``): longest first, into the least loaded lane."""
    load = [0.0] * E2E_LANES
    out: dict[str, str] = {}
    for unit in sorted(set(units), key=lambda u: -E2E_SECONDS.get(u, UNLISTED_S)):
        k = load.index(min(load))
        load[k] += E2E_SECONDS.get(unit, UNLISTED_S)
        out[unit] = f"e2e-lane-{k}"
    return out


def group(item: pytest.Item, rel: Path) -> str | None:
    """The xdist group of a test that is not an e2e test (at ``rel`` under tests/): its own,
    if it names one (None: xdist reads the mark), else its module's when it uses a shared
    fixture, else None (a unit of its own)."""
    if any(item.iter_markers("xdist_group")):
        return None
    info = getattr(item, "_fixtureinfo", None)
    defs = info.name2fixturedefs.values() if info is not None else ()
    if any(d and d[-1].scope in SHARED_SCOPES for d in defs):
        return rel.as_posix()
    return None


def assign(items: list[pytest.Item], root: Path) -> list[pytest.Item]:
    """Mark every test's xdist group (the e2e tests' lanes) and order them: the lanes'
    tests first, each lane's units longest first, then the rest in the collection's order."""
    rels = {id(it): _rel(it, root) for it in items}
    e2e = [it for it in items if rels[id(it)].parts[:1] == ("e2e",)]
    units = {id(it): unit_of(it, rels[id(it)]) for it in e2e}
    lane = lanes(list(units.values()))
    for it in items:
        if id(it) in units:
            it.add_marker(pytest.mark.xdist_group(lane[units[id(it)]]))
        elif rels[id(it)].parts:
            named = group(it, rels[id(it)])
            if named is not None:
                it.add_marker(pytest.mark.xdist_group(named))

    def key(it: pytest.Item) -> tuple[int, float]:
        if id(it) in units:
            return 0, -E2E_SECONDS.get(units[id(it)], UNLISTED_S)
        return 1, 0.0
    return sorted(items, key=key)


def _rel(item: pytest.Item, root: Path) -> Path:
    try:
        return Path(item.path).relative_to(root)
    except ValueError:
        return Path()
