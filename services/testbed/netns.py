"""Network namespaces through iproute2's ``ip``, and sockets opened inside them.

Everything the test bed does to the machine goes through :func:`ip` (and ``tc``,
:mod:`services.testbed.shaping`), so the commands can be read in its log and repeated by
hand. :func:`socket_in` opens a socket inside a namespace from this process (a thread that
enters the namespace with ``setns``, opens the socket and ends: the socket stays in that
namespace), which lets a test or a benchmark measure a flow between two hosts without a
process per end; :func:`offloads_off` uses it for the ``ethtool`` ioctls.
"""

from __future__ import annotations

import ctypes
import fcntl
import logging
import os
import socket
import struct
import subprocess
import threading
from collections.abc import Callable, Sequence
from typing import TypeVar

log = logging.getLogger(__name__)

NETNS_DIR = "/run/netns"
CLONE_NEWNET = 0x40000000
SIOCETHTOOL = 0x8946
#: the legacy ethtool "set" commands for TX checksumming, TSO, GSO and GRO
ETHTOOL_OFFLOADS = {"tx-checksum": 0x17, "tso": 0x1F, "gso": 0x24, "gro": 0x2C}

T = TypeVar("T")


class NetnsError(RuntimeError):
    """An ``ip``/``tc`` command failed (its command line and stderr in the message)."""


def command(argv: Sequence[str], check: bool = True) -> subprocess.CompletedProcess[str]:
    """Run ``argv``; NetnsError with its stderr when it fails and ``check``."""
    log.debug("%s", " ".join(argv))
    done = subprocess.run(list(argv), capture_output=True, text=True, stdin=subprocess.DEVNULL,
                          timeout=30)
    if check and done.returncode != 0:
        raise NetnsError(f"{' '.join(argv)}: {done.stderr.strip() or done.returncode}")
    return done


def ip(*args: str, ns: str | None = None, check: bool = True) -> subprocess.CompletedProcess[str]:
    """``ip [-n NS] ARGS``."""
    return command(["ip", *(("-n", ns) if ns else ()), *args], check)


def exec_argv(ns: str, argv: Sequence[str]) -> list[str]:
    """The command line that runs ``argv`` inside namespace ``ns``."""
    return ["ip", "netns", "exec", ns, *argv]


def names() -> list[str]:
    """The named network namespaces (``ip netns list``)."""
    out = ip("netns", "list").stdout
    return [line.split()[0] for line in out.splitlines() if line.strip()]


def pids(ns: str) -> list[int]:
    """The processes inside namespace ``ns``."""
    done = ip("netns", "pids", ns, check=False)
    return [int(p) for p in done.stdout.split()] if done.returncode == 0 else []


def sysctl(ns: str, key: str, value: str) -> None:
    """Set ``key`` (dotted, e.g. ``net.ipv6.conf.all.disable_ipv6``) inside ``ns``."""
    path = "/proc/sys/" + key.replace(".", "/")
    command(exec_argv(ns, ["sh", "-c", f'echo {value} > "$0"', path]))


def in_netns(ns: str, fn: Callable[[], T]) -> T:
    """Call ``fn`` on a thread that has entered namespace ``ns`` (and ends after it)."""
    result: list[T] = []
    error: list[BaseException] = []

    def body() -> None:
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            fd = os.open(os.path.join(NETNS_DIR, ns), os.O_RDONLY)
            try:
                if libc.setns(fd, CLONE_NEWNET) != 0:
                    err = ctypes.get_errno()
                    raise OSError(err, f"setns({ns}): {os.strerror(err)}")
            finally:
                os.close(fd)
            result.append(fn())
        except BaseException as err:  # handed to the caller's thread
            error.append(err)

    th = threading.Thread(target=body, name=f"netns-{ns}")
    th.start()
    th.join()
    if error:
        raise error[0]
    return result[0]


def socket_in(ns: str, family: int = socket.AF_INET, kind: int = socket.SOCK_DGRAM,
              proto: int = 0) -> socket.socket:
    """A socket that lives in namespace ``ns``."""
    return in_netns(ns, lambda: socket.socket(family, kind, proto))


def offloads_off(ns: str, ifname: str) -> None:
    """Turn off TX checksumming, TSO, GSO and GRO on ``ifname`` in ``ns``.

    The user-space impairer reads and writes whole frames: with offloads on, a sender's frames
    leave with the checksum left for the hardware to fill in (which no veth does when the frame
    is written back by a socket) and TCP's segments as one 64 kB frame.
    """
    def apply() -> None:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            for cmd in ETHTOOL_OFFLOADS.values():
                value = ctypes.create_string_buffer(struct.pack("II", cmd, 0), 8)
                ifreq = struct.pack("16sP", ifname.encode(), ctypes.addressof(value))
                fcntl.ioctl(s.fileno(), SIOCETHTOOL, ifreq)

    in_netns(ns, apply)
