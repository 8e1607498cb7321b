"""``tc`` command lines: a token-bucket bandwidth (tbf) and, where the kernel has it, netem.

A direction of a link is shaped on the egress of the wire namespace's interface that faces
the receiving host, so both the user-space impairer's frames and the kernel bridge's pass
through it. The bucket holds :data:`BURST_S` of traffic (at least two full frames) and its
queue ``queue_ms`` of it (at least the bucket); a frame that finds the queue full is dropped,
as a radio modem's full buffer drops it.
"""

from __future__ import annotations

import math

from services.testbed import netns
from services.testbed.impairment import Impairment

FRAME = 1514           # the largest frame on a 1500-byte MTU, bytes
BURST_S = 0.005        # the token bucket's depth in time at the rate, s
NETEM_HANDLE = "10:"


def bucket(rate_mbit: float, queue_ms: float) -> tuple[int, int, int]:
    """(rate bit/s, burst bytes, queue limit bytes) of a tbf at ``rate_mbit``."""
    rate = round(rate_mbit * 1e6)
    burst = max(2 * FRAME, math.ceil(rate / 8 * BURST_S))
    limit = max(burst, math.ceil(rate / 8 * queue_ms / 1000))
    return rate, burst, limit


def tbf_argv(dev: str, rate_mbit: float, queue_ms: float) -> list[str]:
    rate, burst, limit = bucket(rate_mbit, queue_ms)
    return ["tc", "qdisc", "replace", "dev", dev, "root", "handle", "1:", "tbf",
            "rate", f"{rate}bit", "burst", str(burst), "limit", str(limit)]


def netem_args(imp: Impairment, down: bool = False) -> list[str]:
    """``netem``'s arguments for ``imp`` (``down``: every frame lost, an outage)."""
    args = ["netem", "delay", f"{imp.delay_ms:g}ms"]
    if imp.jitter_ms > 0:
        args.append(f"{imp.jitter_ms:g}ms")
    args += ["loss", "100%" if down else f"{imp.loss * 100:g}%"]
    return args


def qdisc_argvs(dev: str, imp: Impairment, netem: bool, down: bool = False) -> list[list[str]]:
    """The commands that give ``dev`` exactly ``imp`` (after :func:`clear_argv`).

    Without netem only the bandwidth is the kernel's (the impairer does the rest); with it, a
    tbf root with netem as its child (tbf's documented layout), or netem alone.
    """
    per_frame = netem and (imp.per_frame or down)
    out = []
    if imp.rate_mbit is not None:
        out.append(tbf_argv(dev, imp.rate_mbit, imp.queue_ms))
    if per_frame:
        parent = ["parent", "1:1"] if imp.rate_mbit is not None else ["root"]
        out.append(["tc", "qdisc", "replace", "dev", dev, *parent, "handle", NETEM_HANDLE,
                    *netem_args(imp, down)])
    return out


def clear_argv(dev: str) -> list[str]:
    return ["tc", "qdisc", "del", "dev", dev, "root"]


def apply(ns: str, dev: str, imp: Impairment, netem: bool, down: bool = False) -> None:
    """Give ``dev`` in ``ns`` the qdiscs of ``imp``.

    A bandwidth alone is changed in place (``tc qdisc replace``: the frames queued in the
    bucket stay); with netem the qdiscs are made anew, which drops what they held.
    """
    argvs = qdisc_argvs(dev, imp, netem, down)
    if netem or not argvs:
        netns.command(in_ns(ns, clear_argv(dev)), check=False)  # none there yet is fine
    for argv in argvs:
        netns.command(in_ns(ns, argv))


def in_ns(ns: str, argv: list[str]) -> list[str]:
    """``tc ARGS`` → ``tc -n NS ARGS``."""
    return [argv[0], "-n", ns, *argv[1:]]


def netem_available(ns: str) -> bool:
    """Whether the kernel takes a netem qdisc (tried on ``lo`` of namespace ``ns``)."""
    probe = ["tc", "qdisc", "add", "dev", "lo", "root", "netem", "delay", "1ms"]
    ok = netns.command(in_ns(ns, probe), check=False).returncode == 0
    if ok:
        netns.command(in_ns(ns, clear_argv("lo")), check=False)
    return ok
