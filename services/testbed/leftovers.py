"""Removing test beds: one by its namespaces, or every one whose owner is gone.

A test bed's namespaces carry its owner's process id (:mod:`.topology`). Removing one kills
the processes still inside its namespaces (they were started there by the test bed or its
user), deletes the namespaces — and with them every veth, bridge and qdisc, which live only
there — and its scratch directory. ``python -m services.testbed down`` runs :func:`remove_stale`
after a crash; a test bed's own exit runs :func:`remove`.
"""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
import signal
import tempfile
import time
from pathlib import Path

from services.testbed import netns
from services.testbed.topology import PREFIX, owner

log = logging.getLogger(__name__)


def scratch_dir(pid: int, serial: int) -> Path:
    """Where a test bed keeps its control sockets and impairer logs."""
    return Path(tempfile.gettempdir()) / f"{PREFIX}{pid}-{serial}"


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove(namespaces: list[str], scratch: Path | None = None) -> None:
    """Kill what runs in ``namespaces``, delete them and ``scratch``; never raises."""
    for ns in namespaces:
        for pid in netns.pids(ns):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
    present = set(_names())
    for ns in namespaces:
        for _ in range(50):  # a killed process may hold the namespace for a moment
            if not netns.pids(ns):
                break
            time.sleep(0.02)
        if ns in present:
            done = netns.ip("netns", "del", ns, check=False)
            if done.returncode != 0:
                log.error("could not delete namespace %s: %s", ns, done.stderr.strip())
    if scratch is not None:
        shutil.rmtree(scratch, ignore_errors=True)


def _names() -> list[str]:
    try:
        return netns.names()
    except (netns.NetnsError, OSError):
        return []


def beds() -> dict[tuple[int, int], list[str]]:
    """Every test bed's namespaces on this machine, by (owner pid, serial)."""
    out: dict[tuple[int, int], list[str]] = {}
    for ns in _names():
        key = owner(ns)
        if key is not None:
            out.setdefault(key, []).append(ns)
    for path in Path(tempfile.gettempdir()).glob(f"{PREFIX}*-*"):
        key = owner(path.name + "-x")
        if key is not None:
            out.setdefault(key, [])
    return out


def remove_stale(everything: bool = False) -> list[str]:
    """Remove the test beds whose owner process is gone (``everything``: all of them)."""
    removed = []
    for (pid, serial), namespaces in sorted(beds().items()):
        if everything or not alive(pid):
            remove(namespaces, scratch_dir(pid, serial))
            removed += namespaces or [str(scratch_dir(pid, serial))]
    return removed
