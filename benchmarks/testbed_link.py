"""What the test bed's radio link does, measured: latency, loss and throughput at 10, 1 and
0.25 Mbit/s (and unshaped), clean and radio-like, and a Zenoh session's recovery after 10 s
outages.

    .venv/bin/python benchmarks/testbed_link.py --out runs/testbed-link.json

Root only (network namespaces). Per bandwidth and shape, across the radio link from air to
ground: 20 ICMP echoes on the idle link (round trip), a paced UDP flow of 200-byte datagrams
at half the bandwidth for 4 s (one-way delay on one clock, loss), and a TCP transfer of
4 s worth of the bandwidth (goodput; cut after 20 s). ``capacity``: the impairer alone,
unshaped, offered 20000 datagrams/s of 64 bytes for 2 s. ``zenoh``: the router on ground, the probe
(services/testbed/zprobe.py) on air asking its status every 0.2 s over the radio link at
1 Mbit/s and 100 ± 20 ms; the link goes down for 10 s, ``--outages`` times, and each
recovery is the time from the link's return to the first answer to a query sent after it.
``--congestion-control cubic`` sets the TCP transfers' congestion control (default: the
machine's; the output names it). Figures are reported, never asserted.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import harness  # the repository on the path: before its packages

from services.testbed import measure
from services.testbed.availability import unavailable
from services.testbed.bed import TestBed
from services.testbed.impairment import Impairment

RATES: tuple[float | None, ...] = (None, 10.0, 1.0, 0.25)
SHAPES = {"clean": Impairment(), "radio": Impairment(delay_ms=100.0, jitter_ms=20.0, loss=0.05)}
FRAME_OVERHEAD = 42  # Ethernet 14 + IPv4 20 + UDP 8 bytes around a datagram's payload
PAYLOAD = 200
SECONDS = 4.0
TCP_LIMIT_S = 20.0  # a transfer still going then is cut (``tcp_complete`` false)


COUNTED = ("offered", "delivered", "lost", "queue_full")


def counters(bed: TestBed) -> dict[str, int]:
    """The impairer's counters of the air → ground direction (netem: none)."""
    if bed.netem:
        return {}
    up = bed.link("radio").stats()["directions"]["air"]
    return {k: int(up[k]) for k in COUNTED}


def delta(after: dict[str, int], before: dict[str, int]) -> dict[str, int]:
    return {k: after[k] - before[k] for k in after}


def cell(bed: TestBed, rate: float | None, shape: Impairment,
         congestion: str) -> dict[str, Any]:
    air, ground = bed.host("air"), bed.host("ground")
    bed.link("radio").set(Impairment(shape.delay_ms, shape.jitter_ms, shape.loss, rate))
    rtts = measure.ping(air, ground, 20, 0.05)
    got = [r for r in rtts if r is not None]
    pps = 2000.0 if rate is None else rate * 1e6 / 2 / ((PAYLOAD + FRAME_OVERHEAD) * 8)
    before = counters(bed)
    flow = measure.udp_flow(air, ground, int(pps * SECONDS), pps, PAYLOAD, drain_s=1.5)
    udp_link = delta(counters(bed), before)
    nbytes = int((20e6 if rate is None else rate * 1e6 / 8) * SECONDS)
    tcp = measure.tcp_transfer(air, ground, nbytes, timeout_s=60.0, congestion=congestion,
                               limit_s=TCP_LIMIT_S)
    return {
        "rate_mbit": rate, "shape": shape.wire(),
        "ping_rtt_ms": harness.quantiles(got, (50, 95)), "ping_lost": len(rtts) - len(got),
        "udp_pps": round(pps, 1), "udp_sent": flow.sent, "udp_loss": round(flow.loss, 4),
        "udp_one_way_ms": harness.quantiles(flow.delays_ms.values(), (50, 95)),
        "udp_out_of_order": flow.out_of_order, "udp_link": udp_link,
        "tcp_bytes": tcp.nbytes, "tcp_s": round(tcp.seconds, 3),
        "tcp_mbit_s": round(tcp.mbit_s, 3), "tcp_complete": tcp.complete,
    }


def capacity(bed: TestBed) -> dict[str, Any]:
    bed.link("radio").set(Impairment())
    before = counters(bed)
    flow = measure.udp_flow(bed.host("air"), bed.host("ground"), 40000, 20000.0, 64, drain_s=1.0)
    span = flow.sent_at[-1] - flow.sent_at[0]
    return {"offered_pps": round(flow.sent / span), "received": flow.received,
            "sent": flow.sent, "loss": round(flow.loss, 4),
            "one_way_ms": harness.quantiles(flow.delays_ms.values(), (50, 95)),
            "link": delta(counters(bed), before),
            "kernel_drops": 0 if bed.netem else bed.link("radio").stats()["kernel_drops"]}


def zenoh_recovery(bed: TestBed, outages: int, logs: Path) -> dict[str, Any]:
    air, ground = bed.host("air"), bed.host("ground")
    bed.link("radio").set(Impairment(delay_ms=100.0, jitter_ms=20.0, rate_mbit=1.0))
    endpoint = f"tcp/{ground.address('air')}:7447"
    env = {"LOG_FORMAT": "text", "UAV_ID": "tb"}
    ground.start("router", [sys.executable, "-m", "services.router", "--zenoh-listen",
                            endpoint], env)
    out = logs / "probe.jsonl"
    air.start("zprobe", [sys.executable, "-m", "services.testbed.zprobe", "--zenoh-connect",
                         endpoint, "--out", str(out)], env)

    def record() -> list[dict[str, Any]]:
        text = out.read_text() if out.is_file() else ""
        return [json.loads(x) for x in text.splitlines() if x.endswith("}")]

    deadline = time.monotonic() + 60
    while sum(x["ok"] for x in record()) < 10 and time.monotonic() < deadline:
        time.sleep(0.1)
    runs = []
    for _ in range(outages):
        before = time.monotonic()
        bed.link("radio").outage(10.0)
        back = before + 10.0
        deadline = back + 60
        first = None
        while first is None and time.monotonic() < deadline:
            time.sleep(0.1)
            first = next((x for x in record() if x["ok"] and x["sent"] >= back), None)
        during = [x for x in record() if before <= x["sent"] < back]
        runs.append({"recovered_s": None if first is None else round(first["done"] - back, 3),
                     "lost_router": any(x["routers"] == 0 for x in during)})
        time.sleep(5.0)
    ok_rtts = [(x["done"] - x["sent"]) * 1000 for x in record() if x["ok"]]
    return {"outage_s": 10.0, "runs": runs, "query_rtt_ms": harness.quantiles(ok_rtts, (50, 95))}


def table(cells: list[dict[str, Any]]) -> str:
    rows = ["| bandwidth | shape | ping RTT p50 / p95 | UDP one-way p50 / p95 | UDP loss | "
            "TCP goodput |", "|---|---|---|---|---|---|"]
    for c in cells:
        rate = "unshaped" if c["rate_mbit"] is None else f"{c['rate_mbit']:g} Mbit/s"
        shape = "clean" if c["shape"]["delay_ms"] == 0 else "100 ± 20 ms, 5 % loss"
        p, u = c["ping_rtt_ms"], c["udp_one_way_ms"]
        rows.append(f"| {rate} | {shape} | {p['p50']:.1f} / {p['p95']:.1f} ms | "
                    f"{u['p50']:.1f} / {u['p95']:.1f} ms | {c['udp_loss'] * 100:.1f} % | "
                    f"{c['tcp_mbit_s']:.2f} Mbit/s |")
    return "\n".join(rows)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=None)
    p.add_argument("--outages", type=int, default=3)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--congestion-control", default="",
                   help="the TCP transfers' congestion control (default: the machine's)")
    p.add_argument("--no-zenoh", action="store_true", help="leave out the Zenoh outages")
    args = p.parse_args()
    if reason := unavailable():
        sys.exit(f"the test bed cannot be made here: {reason}")
    logs = Path(args.out.parent if args.out else Path("runs")) / "testbed-link-logs"
    with TestBed(seed=args.seed, logs=logs) as bed:
        cc = args.congestion_control or bed.host("air").run(
            ["cat", "/proc/sys/net/ipv4/tcp_congestion_control"]).stdout.strip()
        cells = [cell(bed, rate, shape, args.congestion_control)
                 for rate in RATES for shape in SHAPES.values()]
        doc = {"impairer": "netem" if bed.netem else "user-space",
               "tcp_congestion_control": cc, "cells": cells,
               "capacity": capacity(bed),
               "zenoh": None if args.no_zenoh else zenoh_recovery(bed, args.outages, logs)}
    harness.emit(doc, args.out)
    print(table(cells))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
