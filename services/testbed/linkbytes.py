"""The bytes that cross a link: its interface counters, and the payload per key expression.

Two views of the same traffic:

* **on the wire**, :func:`counters`: the bytes and packets a host's link interface sent
  and received (``ip -s -j link``): everything that crossed, Zenoh's framing, keep-alives,
  liveliness, TCP/IP headers and retransmissions included;
* **per key expression**, :func:`crossing`: the payload each process counted
  (services/common/traffic.py, written at exit to ``TRAFFIC_PATH``), put together by host.
  A key's messages cross from host A to host B when a process on A sends them and processes
  on B receive them: what B's processes received on a key only A's processes send is the
  payload that crossed from A (a key both sides send is marked ``both_sides``: its received
  bytes may include local traffic).
"""

from __future__ import annotations

import json
from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from services.testbed import netns


@dataclass(frozen=True)
class Counters:
    """One interface's counters at one moment (bytes and packets, each way)."""

    tx_bytes: int
    rx_bytes: int
    tx_packets: int
    rx_packets: int

    def __sub__(self, other: Counters) -> Counters:
        return Counters(self.tx_bytes - other.tx_bytes, self.rx_bytes - other.rx_bytes,
                        self.tx_packets - other.tx_packets, self.rx_packets - other.rx_packets)

    def wire(self) -> dict[str, int]:
        return {"tx_bytes": self.tx_bytes, "rx_bytes": self.rx_bytes,
                "tx_packets": self.tx_packets, "rx_packets": self.rx_packets}


def counters(ns: str, ifname: str) -> Counters:
    """``ifname``'s counters in namespace ``ns`` now."""
    out = netns.ip("-s", "-j", "link", "show", "dev", ifname, ns=ns).stdout
    stats = json.loads(out)[0]["stats64"]
    return Counters(int(stats["tx"]["bytes"]), int(stats["rx"]["bytes"]),
                    int(stats["tx"]["packets"]), int(stats["rx"]["packets"]))


def read_tables(dirs: Iterable[Path]) -> list[dict[str, Any]]:
    """Every traffic table (``*.json`` of services/common/traffic.py) in ``dirs``."""
    out = []
    for d in dirs:
        for path in sorted(Path(d).glob("*.json")):
            doc = json.loads(path.read_text())
            if isinstance(doc, dict) and "rows" in doc:
                out.append(doc)
    return out


def crossing(tables: Sequence[dict[str, Any]], a: str, b: str) -> list[dict[str, Any]]:
    """The payload per key expression and kind that crossed between hosts ``a`` and ``b``:
    rows ``{"key", "kind", "from", "to", "messages", "bytes", "both_sides"}``, largest first.

    Processes with another host (or none) are left out: a host's own processes talking to each
    other never cross.
    """
    sent: dict[tuple[str, str], set[str]] = defaultdict(set)
    got: dict[tuple[str, str, str], list[int]] = defaultdict(lambda: [0, 0])
    for t in tables:
        host = t.get("host", "")
        if host not in (a, b):
            continue
        for r in t["rows"]:
            k = (r["key"], r["kind"])
            if r["direction"] == "sent":
                sent[k].add(host)
            else:
                cell = got[(*k, host)]
                cell[0] += int(r["messages"])
                cell[1] += int(r["bytes"])
    rows = []
    for (key, kind, to), (messages, nbytes) in got.items():
        origin = sent.get((key, kind), set()) - {to}
        if not origin:
            continue  # sent only on the receiving host: it never crossed
        rows.append({"key": key, "kind": kind, "from": b if to == a else a, "to": to,
                     "messages": messages, "bytes": nbytes,
                     "both_sides": to in sent[(key, kind)]})
    return sorted(rows, key=lambda r: (-r["bytes"], r["key"], r["kind"]))


def per_step(rows: Sequence[dict[str, Any]], steps: int) -> list[dict[str, Any]]:
    """``rows`` with ``bytes_per_step`` (``bytes`` / ``steps``, 1 decimal)."""
    n = max(1, steps)
    return [{**r, "bytes_per_step": round(r["bytes"] / n, 1)} for r in rows]
