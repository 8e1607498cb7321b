"""How ``make test`` spreads the tiers over pytest-xdist's workers (``--dist loadgroup``).

A worker runs one unit of work at a time and asks for the next when it is nearly done.
A test is a unit of its own, unless it shares a fixture wider than itself: then its whole
module is one unit (:func:`group`), so a module-scoped fixture, such as the stack that
several e2e tests fly on, starts once, on one worker (a test may name a group of its own
instead: half of test_lockstep.py flies on a second worker, with a fleet of its own).
:func:`ordered` hands the units out longest first (:data:`SLOW_FIRST`, then the e2e tier,
which mostly waits on processes, then the integration and unit tiers): the long ones
start at once and the short ones fill the gaps beside them, so that no long one is left
for the end. The order of the tests within a unit is kept.
"""

from __future__ import annotations

from pathlib import Path

import pytest

#: fixture scopes wider than a test and narrower than a worker's session
SHARED_SCOPES = frozenset({"class", "module", "package"})

#: the longest units, longest first: modules (paths under tests/) or groups, by their time
#: in one serial run of the integration and e2e tiers (``pytest tests/integration tests/e2e
#: --durations=120``, 2 cores, 2026-12-06: 1278 s): test_lockstep.py 312 s (two units, about
#: 166 s and 146 s), test_lockstep_lookahead.py 91 s, test_mavsdk_examples.py 83 s,
#: test_soak.py 61 s, test_stream.py 53 s, test_mavsdk.py 41 s, test_fuzz.py 31 s,
#: test_load.py 29 s, test_web_view.py 29 s; then modules of many short units (test_pool.py
#: 2 × 26 s, test_faults.py 7 × 14 s, test_flavours.py 2 × 15 s, test_attacks.py 10 × 7 s)
SLOW_FIRST: tuple[str, ...] = (
    "e2e/test_lockstep.py", "e2e/test_lockstep.py:risk", "e2e/test_lockstep_lookahead.py",
    "e2e/test_mavsdk_examples.py", "e2e/test_soak.py", "e2e/test_stream.py",
    "e2e/test_mavsdk.py", "integration/test_fuzz.py", "e2e/test_load.py",
    "e2e/test_web_view.py", "e2e/test_pool.py", "e2e/test_faults.py", "e2e/test_flavours.py",
    "e2e/test_attacks.py",
)


def group(item: pytest.Item, rel: Path) -> str | None:
    """The xdist group of ``item`` (at ``rel`` under tests/): its own, if it names one (None:
    xdist reads the mark), else its module's when it uses a shared fixture, else None."""
    if any(item.iter_markers("xdist_group")):
        return None
    info = getattr(item, "_fixtureinfo", None)
    defs = info.name2fixturedefs.values() if info is not None else ()
    if any(d and d[-1].scope in SHARED_SCOPES for d in defs):
        return rel.as_posix()
    return None


def rank(unit: str) -> int:
    """Where ``unit`` (a module's path under tests/, or a group's name) starts: the units of
    :data:`SLOW_FIRST` in its order, then the e2e tier, the integration tier, the unit tier."""
    if unit in SLOW_FIRST:
        return SLOW_FIRST.index(unit)
    return len(SLOW_FIRST) + {"e2e": 0, "integration": 1}.get(unit.split("/")[0], 2)


def ordered(items: list[pytest.Item], root: Path) -> list[pytest.Item]:
    """``items`` longest unit first (a stable sort: otherwise, the collection's order)."""
    def key(item: pytest.Item) -> int:
        named = next(item.iter_markers("xdist_group"), None)
        if named is not None and named.args and str(named.args[0]) in SLOW_FIRST:
            return rank(str(named.args[0]))
        try:
            return rank(Path(item.path).relative_to(root).as_posix())
        except ValueError:
            return rank("")
    return sorted(items, key=key)
