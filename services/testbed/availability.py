"""Can this process make the test bed's hosts? None, or the reason it cannot.

A test that needs the hosts skips with this reason where namespaces cannot be made (not
Linux, no ``ip`` or ``tc``, not root, or the kernel refuses: a container without
``CAP_SYS_ADMIN``); it never fails for it.
"""

from __future__ import annotations

import os
import shutil
import sys

from services.testbed import netns
from services.testbed.topology import netns_name


def unavailable() -> str | None:
    """Why network namespaces cannot be made here (None: they can, tried for real)."""
    if not sys.platform.startswith("linux"):
        return f"network namespaces are Linux's ({sys.platform} here)"
    for tool, package in (("ip", "iproute2"), ("tc", "iproute2")):
        if shutil.which(tool) is None:
            return f"no `{tool}` on PATH (Debian package {package})"
    if os.geteuid() != 0:
        return f"not root (uid {os.geteuid()}): `ip netns add` needs CAP_SYS_ADMIN"
    probe = netns_name(os.getpid(), 0, "probe")  # serial 0: never a test bed's
    try:
        done = netns.ip("netns", "add", probe, check=False)
    except OSError as err:
        return f"`ip netns add` could not run: {err}"
    if done.returncode != 0:
        return f"`ip netns add` refused: {done.stderr.strip()}"
    netns.ip("netns", "del", probe, check=False)
    return None
