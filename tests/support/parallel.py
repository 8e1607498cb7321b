"""How ``make test`` spreads the tiers over pytest-xdist's workers (``--dist loadgroup``).

A worker runs one unit of work at a time and asks for the next when it is nearly done.
A test is a unit of its own, unless it shares a fixture wider than itself: then its whole
module is one unit (:func:`group`), so a module-scoped fixture, such as the stack that
several e2e tests fly on, starts once, on one worker. xdist hands out the units with the
most tests first (those modules run their tests one after another, on one worker: the
lockstep missions, the MAVSDK examples on UDP 14540, …), then the single tests in the
order :func:`ordered` gives them: the e2e tier, which mostly waits on processes, first,
and the unit and integration tests filling the gaps beside it, so that no long test is
left for the end. The order of the tests within a module is kept.
"""

from __future__ import annotations

from pathlib import Path

import pytest

#: fixture scopes wider than a test and narrower than a worker's session
SHARED_SCOPES = frozenset({"class", "module", "package"})


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


def rank(module: str) -> int:
    """Where ``module`` (a path under tests/) starts: the e2e tier first, then the
    integration tier, then the unit tier."""
    return {"e2e": 0, "integration": 1}.get(module.split("/")[0], 2)


def ordered(items: list[pytest.Item], root: Path) -> list[pytest.Item]:
    """``items`` tier by tier (a stable sort: within a tier, the collection's order)."""
    def key(item: pytest.Item) -> int:
        try:
            return rank(Path(item.path).relative_to(root).as_posix())
        except ValueError:
            return rank("")
    return sorted(items, key=key)
