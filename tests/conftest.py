"""The test tiers: every test is marked by the folder it lives in.

``unit`` (tests/unit): pure, seeded, no process started, no port opened beyond
loopback sockets of its own; ``integration`` (tests/integration): real service
processes on loopback, one concern at a time; ``e2e`` (tests/e2e): whole missions
through the stack, ground stations and SDKs as real clients. ``slow`` marks the
long suites of any tier. ``make test-fast`` runs ``unit and not slow``; ``make test``
runs everything.

``make test`` runs the tiers side by side on pytest-xdist's workers: the integration and e2e
tests in a lane of one test at a time, the unit tests beside them in a lane of their own at
the lowest CPU priority (tests/support/parallel.py).

Hypothesis runs with no deadline: a property is a statement about values, never
about how long an example took (a loaded machine must not fail it).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import settings

from tests.support import parallel

TIERS = ("unit", "integration", "e2e")

# the ``testbed`` fixture: the deployment test bed's hosts, or a skip saying why not
pytest_plugins = ["tests.support.testbed"]

settings.register_profile("dualpilot", deadline=None)
settings.load_profile("dualpilot")


@pytest.hookimpl(tryfirst=True)  # before -m selects and before xdist reads the groups
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    root = Path(__file__).parent
    for item in items:
        try:
            rel = Path(item.path).relative_to(root)
        except ValueError:
            continue
        if rel.parts[0] in TIERS:
            item.add_marker(getattr(pytest.mark, rel.parts[0]))
    if parallel.on_workers(config):  # TEST_WORKERS: on the controller and every worker
        items[:] = parallel.assign(items, root)


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    parallel.yield_cpu(item)  # the unit lane's worker, before its first test
