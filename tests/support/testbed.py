"""The test bed's hosts for a test, or a skip that says why they cannot be made here.

``testbed`` (a fixture, registered for every test by tests/conftest.py) yields a
:class:`~services.testbed.bed.TestBed` that is up, with its processes' logs in the test's
``tmp_path``, and takes it down after the test, passed or failed. Where network namespaces
cannot be made (not root, no ``ip``, a kernel or container that refuses) the test is skipped
with :func:`~services.testbed.availability.unavailable`'s reason, never failed.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

from services.testbed import leftovers
from services.testbed.availability import unavailable

if TYPE_CHECKING:  # the test bed imports the launcher (seconds): only when a test uses it
    from services.testbed.bed import TestBed

SKIP_PREFIX = "the test bed's network namespaces cannot be made here: "


def testbed_or_skip(logs: Path, **kwargs: object) -> TestBed:
    """A test bed not yet up, or ``pytest.skip`` with the reason namespaces cannot be made."""
    reason = unavailable()
    if reason:
        pytest.skip(SKIP_PREFIX + reason)
    from services.testbed.bed import TestBed

    leftovers.remove_stale()  # a crashed run's namespaces (their owner is gone)
    return TestBed(logs=logs, **kwargs)  # type: ignore[arg-type]


@pytest.fixture
def testbed(tmp_path: Path) -> Iterator[TestBed]:
    """The air, ground and gcs hosts, up; down after the test whatever its outcome."""
    with testbed_or_skip(tmp_path / "testbed") as bed:
        yield bed
