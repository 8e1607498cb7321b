"""The test bed: hosts as network namespaces, joined by shaped links, up and down as one.

>>> with TestBed() as bed:                                   # doctest: +SKIP
...     ground = bed.host("ground")
...     router = ground.start("router", [sys.executable, "-m", "services.router",
...                                      "--zenoh-listen", f"tcp/{ground.address('air')}:7447"])
...     bed.link("radio").set(Impairment(delay_ms=150, jitter_ms=20, loss=0.05, rate_mbit=1))
...     bed.link("radio").outage(10.0)

Each host has its loopback and one interface per link, named after the link (``radio``,
``telem``), with its address and a permanent neighbour entry for the other end (no ARP crosses
a link, so an outage never leaves a host without its neighbour). The links' other ends are in
the wire namespace, where a link's two ends are joined by the user-space impairer, or by a
bridge with netem where the kernel has netem (``impairer="auto"``). :meth:`TestBed.down` —
on leaving the ``with``, whatever happened inside — stops every process started through the
test bed and deletes the namespaces, which takes every interface and qdisc with them.
"""

from __future__ import annotations

import itertools
import logging
import os
import subprocess
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from types import TracebackType
from typing import Any

from services.launch import Proc, ProcessGroup
from services.testbed import leftovers, netns, shaping
from services.testbed.links import REPO, ImpairedLink, Link, NetemLink
from services.testbed.topology import TOPOLOGY, WIRE, LinkSpec, Topology, netns_name

log = logging.getLogger(__name__)

_SERIAL = itertools.count(1)
IMPAIRERS = ("auto", "impairer", "netem")


class Host:
    """One host of the test bed: a network namespace and the processes started in it."""

    def __init__(self, bed: TestBed, name: str, ns: str):
        self.bed, self.name, self.netns = bed, name, ns

    def address(self, peer: str) -> str:
        """This host's address on the link it shares with ``peer``."""
        topo = self.bed.topology
        return topo.address(topo.link_between(self.name, peer), self.name)

    def argv(self, cmd: Sequence[str]) -> list[str]:
        """``cmd`` as a command line that runs inside this host."""
        return netns.exec_argv(self.netns, cmd)

    def run(self, cmd: Sequence[str], timeout: float = 60.0, check: bool = True,
            **kwargs: Any) -> subprocess.CompletedProcess[str]:
        """Run ``cmd`` in this host to its end; its output as text."""
        return subprocess.run(self.argv(cmd), timeout=timeout, check=check, text=True,
                              capture_output=True, stdin=subprocess.DEVNULL, **kwargs)

    def start(self, name: str, cmd: Sequence[str], env: Mapping[str, str] | None = None,
              log_path: Path | None = None) -> Proc:
        """Start ``cmd`` in this host (own session, output to ``log_path``); stopped by down()
        (SIGINT, then SIGKILL) or by ``bed.processes.stop(proc)``."""
        full = dict(os.environ, PYTHONPATH=str(REPO), PYTHONUNBUFFERED="1")
        full.update(env or {})
        path = log_path or self.bed.logs / f"{self.name}-{name}.log"
        return self.bed.processes.start(f"{self.name}/{name}", self.argv(cmd), full, path)


class TestBed:
    """Hosts and links of ``topology`` on this machine (a context manager).

    Parameters
    ----------
    topology : the hosts and links (default: air, ground, gcs; radio and telem).
    impairer : ``"auto"`` (netem where the kernel has it, else the user-space impairer),
        ``"impairer"`` or ``"netem"``.
    seed : seed of the impairers' loss and jitter draws (link k draws from ``seed + k``).
    logs : where the processes' logs go (default: the test bed's scratch directory, removed by
        down()).
    """

    __test__ = False  # not a pytest class

    def __init__(self, topology: Topology = TOPOLOGY, impairer: str = "auto", seed: int = 0,
                 logs: Path | None = None):
        if impairer not in IMPAIRERS:
            raise ValueError(f"impairer must be one of {IMPAIRERS}, got {impairer!r}")
        self.topology, self.impairer, self.seed = topology, impairer, seed
        self.pid, self.serial = os.getpid(), next(_SERIAL)
        self.scratch = leftovers.scratch_dir(self.pid, self.serial)
        self.logs = logs or self.scratch
        self.wire = netns_name(self.pid, self.serial, WIRE)
        self.hosts = {h: Host(self, h, netns_name(self.pid, self.serial, h))
                      for h in topology.hosts}
        self.links: dict[str, Link] = {}
        self.processes = ProcessGroup()
        self.netem = False
        self._up = False

    # -- access ----------------------------------------------------------------------------
    def host(self, name: str) -> Host:
        if name not in self.hosts:
            raise KeyError(f"no host {name!r} (hosts: {list(self.hosts)})")
        return self.hosts[name]

    def link(self, name: str) -> Link:
        if name not in self.links:
            raise KeyError(f"no link {name!r} (links: {list(self.links)})")
        return self.links[name]

    @property
    def namespaces(self) -> list[str]:
        return [h.netns for h in self.hosts.values()] + [self.wire]

    # -- up and down -----------------------------------------------------------------------
    def __enter__(self) -> TestBed:
        self.up()
        return self

    def __exit__(self, kind: type[BaseException] | None, err: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.down()

    def up(self) -> None:
        """Make the namespaces, the links and their shaping; on any failure undo it all."""
        self._up = True
        try:
            self.scratch.mkdir(parents=True, exist_ok=True)
            self.logs.mkdir(parents=True, exist_ok=True)
            for ns in self.namespaces:
                self._namespace(ns)
            self.netem = self._use_netem()
            for spec in self.topology.links:
                self._cable(spec)
            for spec in self.topology.links:
                link: Link = (NetemLink(spec, self.wire) if self.netem else
                              ImpairedLink(spec, self.wire, self.scratch, self.seed + spec.number))
                self.links[spec.name] = link
                link.start()
        except BaseException:
            self.down()
            raise
        log.info("test bed up: %s (links shaped by %s)", ", ".join(self.namespaces),
                 "netem" if self.netem else "the user-space impairer")

    def down(self) -> None:
        """Stop every process, remove every namespace (and so every interface); idempotent."""
        if not self._up:
            return
        self._up = False
        steps: list[Callable[[], object]] = [self.processes.stop_all,
                                             *(lk.stop for lk in self.links.values())]
        for step in steps:
            try:
                step()
            except Exception:  # whatever failed, the namespaces still go
                log.exception("test bed down: %s failed", step)
        leftovers.remove(self.namespaces, self.scratch)

    def _use_netem(self) -> bool:
        if self.impairer == "impairer":
            return False
        have = shaping.netem_available(self.wire)
        if self.impairer == "netem" and not have:
            raise netns.NetnsError("impairer='netem' but this kernel has no netem qdisc")
        return have

    def _namespace(self, ns: str) -> None:
        netns.ip("netns", "add", ns)
        netns.ip("link", "set", "lo", "up", ns=ns)
        # IPv6's own chatter (router solicitations, duplicate address detection) would cross
        # the links and the impairer: the test bed speaks IPv4 only
        for key in ("net.ipv6.conf.all.disable_ipv6", "net.ipv6.conf.default.disable_ipv6"):
            netns.sysctl(ns, key, "1")

    def _cable(self, spec: LinkSpec) -> None:
        topo = self.topology
        for h in spec.hosts:
            host_ns, end = self.hosts[h].netns, spec.wire_end(h)
            netns.ip("link", "add", end, "type", "veth", "peer", "name", spec.name,
                     "address", topo.mac(spec, h), "netns", host_ns, ns=self.wire)
            netns.ip("addr", "add", f"{topo.address(spec, h)}/24", "dev", spec.name, ns=host_ns)
            netns.ip("link", "set", spec.name, "up", ns=host_ns)
            netns.ip("link", "set", end, "up", ns=self.wire)
            if not self.netem:
                netns.offloads_off(host_ns, spec.name)
                netns.offloads_off(self.wire, end)
        a, b = spec.hosts
        for h, peer in ((a, b), (b, a)):
            netns.ip("neigh", "replace", topo.address(spec, peer), "lladdr", topo.mac(spec, peer),
                     "dev", spec.name, "nud", "permanent", ns=self.hosts[h].netns)

    # -- for people ------------------------------------------------------------------------
    def describe(self) -> str:
        """The hosts, their addresses and how to run a command in each."""
        lines = [f"links shaped by {'netem' if self.netem else 'the user-space impairer'}"]
        for h in self.hosts.values():
            addrs = ", ".join(f"{lk.name} {self.topology.address(lk, h.name)}"
                              for lk in self.topology.links_of(h.name))
            lines.append(f"  {h.name:7s} {addrs:34s} ip netns exec {h.netns} COMMAND")
        for name, link in self.links.items():
            lines.append(f"  link {name}: {' <-> '.join(link.spec.hosts)}"
                         + (f", control {link.control_path}"
                            if isinstance(link, ImpairedLink) else ""))
        return "\n".join(lines)
