"""A service's --nice lowers its priority against the other services, each in a session of its own.

Under Linux's autogroups the CPU is shared between sessions first, so a nice
value alone changes nothing against a process of another session: two busy
processes in sessions of their own, one at nice 10, get the same CPU. The
service's :func:`lower_priority` lowers its session's autogroup too.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from services.launch.processes import REPO

AUTOGROUP = Path("/proc/self/autogroup")
CHILD = """
import sys
from services.common.bus.service import lower_priority
print(lower_priority(int(sys.argv[1])))
print(open('/proc/self/autogroup').read().strip())
"""


def _run(nice: int, new_session: bool) -> list[str]:
    out = subprocess.run([sys.executable, "-c", CHILD, str(nice)], capture_output=True,
                         text=True, check=True, start_new_session=new_session,
                         env=dict(os.environ, PYTHONPATH=str(REPO)), cwd=REPO)
    return out.stdout.splitlines()


@pytest.mark.skipif(not AUTOGROUP.exists(), reason="the kernel has no autogroups")
def test_a_service_in_its_own_session_lowers_its_autogroup() -> None:
    said, group = _run(7, new_session=True)
    assert said == "nice 7, autogroup nice 7"
    assert group.endswith("nice 7")  # e.g. "/autogroup-1234 nice 7"


@pytest.mark.skipif(not AUTOGROUP.exists(), reason="the kernel has no autogroups")
def test_a_process_in_another_s_session_leaves_that_session_s_group_alone() -> None:
    before = AUTOGROUP.read_text().strip()
    said, group = _run(7, new_session=False)
    assert said == "nice 7"
    assert group == before  # the test's own session keeps its priority
