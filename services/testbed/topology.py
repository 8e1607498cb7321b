"""The test bed's hosts and links, and the names they get on this machine.

Three hosts, each a network namespace: ``air`` (the UAV's companion computer), ``ground``
(the ground server) and ``gcs`` (a ground station). Two links, each an L2 segment between two
hosts that passes through the wire namespace, where it is shaped: ``radio`` (air–ground, the
lossy radio or LTE link) and ``telem`` (gcs–air, the ground station's own telemetry radio,
MAVLink over UDP). Link ``k`` (from 1) is the subnet ``10.10.k.0/24``; a host's address on
it ends in the host's number (air 1, ground 2, gcs 3). The addresses exist only inside the
namespaces; no host has a route anywhere else.

Names on the machine carry :data:`PREFIX` and the owning process's id
(``dptb<pid>-<n>-<host>``), so test beds of several processes never clash and a leftover
whose owner died is recognised (:func:`owner`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

PREFIX = "dptb"
WIRE = "wire"
_NAME = re.compile(rf"^{PREFIX}(\d+)-(\d+)-([a-z][a-z0-9]*)$")


@dataclass(frozen=True)
class LinkSpec:
    """A link between hosts ``a`` and ``b`` on subnet ``10.10.<number>.0/24``."""

    name: str
    a: str
    b: str
    number: int

    @property
    def hosts(self) -> tuple[str, str]:
        return (self.a, self.b)

    def wire_end(self, host: str) -> str:
        """The wire namespace's interface that faces ``host`` (veth peer of its link iface)."""
        return f"{self.name}-{host}"[:15]


@dataclass(frozen=True)
class Topology:
    hosts: tuple[str, ...]
    links: tuple[LinkSpec, ...]

    def number(self, host: str) -> int:
        return self.hosts.index(host) + 1

    def address(self, link: LinkSpec, host: str) -> str:
        """``host``'s IPv4 address on ``link``."""
        return f"10.10.{link.number}.{self.number(host)}"

    def mac(self, link: LinkSpec, host: str) -> str:
        """``host``'s interface MAC on ``link`` (locally administered, fixed)."""
        return f"02:10:10:{link.number:02x}:{self.number(host):02x}:01"

    def link_between(self, host: str, peer: str) -> LinkSpec:
        for link in self.links:
            if {host, peer} == set(link.hosts):
                return link
        raise KeyError(f"no link between {host} and {peer} (links: "
                       f"{[f'{lk.a}-{lk.b}' for lk in self.links]})")

    def links_of(self, host: str) -> list[LinkSpec]:
        return [lk for lk in self.links if host in lk.hosts]


#: air–ground over the radio, the ground station to the vehicle over its telemetry radio
TOPOLOGY = Topology(
    hosts=("air", "ground", "gcs"),
    links=(LinkSpec("radio", "air", "ground", 1), LinkSpec("telem", "gcs", "air", 2)),
)


def netns_name(pid: int, serial: int, host: str) -> str:
    return f"{PREFIX}{pid}-{serial}-{host}"


def owner(name: str) -> tuple[int, int] | None:
    """(pid, serial) of a test bed's namespace name; None for any other name."""
    m = _NAME.match(name)
    return (int(m.group(1)), int(m.group(2))) if m else None
