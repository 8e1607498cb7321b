"""The floor under the setpoint latency: one Zenoh query round trip between two Python processes.

    .venv/bin/python benchmarks/bench_zenoh_query.py --queries 2000

A replier process answers an 8 KB query (the size of a plan request with
fires) with an 8 KB reply; this process asks, one query per ``--period-ms``
(a tick, not back-to-back), and records each round trip. Variants, run in
alternating blocks so they see the same load:

* ``router``: both are clients of a router process (services.router), as in
  the stack; ``peer``: the querier connects straight to the replier.
* replier ``inbox`` (a Zenoh callback queues the query in a queue.Queue, a
  Python thread answers), ``channel`` (that thread waits in the
  queryable's own FIFO channel) or ``callback`` (answered in the callback);
* querier ``queue`` (a Python callback fills a queue.Queue, the stack's
  ``bus.request`` before) or ``channel`` (Zenoh's own FIFO channel, ``recv()``).

Prints the median and p99 of each variant in ms. Loopback only.
"""

from __future__ import annotations

import argparse
import queue
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import harness  # the repository on the path: before its packages
import numpy as np
import zenoh

from services.common import bus
from services.common.cli import Settings
from services.launch import free_port

PAYLOAD = bytes(8192)


def config(mode: str, connect: list[str], listen: list[str]) -> zenoh.Config:
    """The stack's own session configuration (services.common.bus.zenoh_config)."""
    return bus.zenoh_config(Settings(service="bench", uav_id="bench", zenoh_connect=tuple(connect),
                                     zenoh_listen=tuple(listen), zenoh_mode=mode,
                                     speed_factor=0.0, mavlink_url="", log_level="WARNING",
                                     log_format="text"))


def serve(mode: str, connect: str, listen: str, style: str) -> None:
    """The replier: answer every query on bench/** until stdin closes."""
    sys.setswitchinterval(bus.SWITCH_INTERVAL_S)  # as every service
    session = zenoh.open(config(mode, [connect] if connect else [], [listen] if listen else []))
    inbox = bus.Inbox("bench")  # the planner services' hand-off

    def on_query(q: zenoh.Query) -> None:
        if style == "callback":
            q.reply(q.key_expr, PAYLOAD)
        else:
            inbox.on_query(q)

    qbl: Any
    if style == "channel":  # the main thread waits in Zenoh's own channel
        qbl = session.declare_queryable("bench/**")

        def answer_from_channel() -> None:
            while True:
                q = qbl.handler.recv()
                q.reply(q.key_expr, PAYLOAD)
                q.drop()
        threading.Thread(target=answer_from_channel, daemon=True).start()
    else:
        qbl = session.declare_queryable("bench/**", on_query)
    print("ready", flush=True)
    if style == "inbox":
        def answer() -> None:
            while True:
                item = inbox.get(timeout=None)
                if item is not None and item.query is not None:
                    item.query.reply(item.query.key_expr, PAYLOAD)
                    item.query.drop()
        threading.Thread(target=answer, daemon=True).start()
    sys.stdin.read()
    qbl.undeclare()
    session.close()


def ask_queue(session: zenoh.Session, key: str) -> None:
    q: queue.Queue[object] = queue.Queue()
    session.get(key, zenoh.handlers.Callback(q.put, lambda: None), payload=PAYLOAD, timeout=2.0)
    reply = q.get(timeout=3.0)
    assert reply.ok is not None  # type: ignore[attr-defined]


def ask_channel(session: zenoh.Session, key: str) -> None:
    reply = bus.first_reply(session, key, 2.0, payload=PAYLOAD)  # the stack's own wait
    assert reply.ok is not None


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--queries", type=int, default=2000, help="per variant")
    p.add_argument("--period-ms", type=float, default=5.0)
    p.add_argument("--block", type=int, default=100, help="queries per variant per turn")
    p.add_argument("--serve", nargs=4, metavar=("MODE", "CONNECT", "LISTEN", "STYLE"),
                   help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.serve:
        serve(*args.serve)
        return 0
    sys.setswitchinterval(bus.SWITCH_INTERVAL_S)
    router_ep = f"tcp/127.0.0.1:{free_port()}"
    procs: list[subprocess.Popen[str]] = []

    def start(cmd: list[str]) -> subprocess.Popen[str]:
        proc = subprocess.Popen(cmd, cwd=harness.REPO, stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, text=True)
        procs.append(proc)
        return proc

    router = start([sys.executable, "-m", "services.router", "--zenoh-listen", router_ep,
                    "--log-level", "WARNING"])
    sessions: dict[str, zenoh.Session] = {}
    try:
        time.sleep(1.0)  # the router binds its port
        if router.poll() is not None:
            raise RuntimeError("router did not start")
        variants: dict[str, tuple[zenoh.Session, str, Callable[[zenoh.Session, str], None]]] = {}
        for style in ("inbox", "channel", "callback"):
            peer_ep = f"tcp/127.0.0.1:{free_port()}"
            for mode, connect, listen in (("client", router_ep, ""), ("peer", "", peer_ep)):
                replier = start([sys.executable, __file__, "--serve", mode, connect, listen,
                                 style])
                assert replier.stdout is not None
                if replier.stdout.readline().strip() != "ready":
                    raise RuntimeError("replier did not start")
                name = "router" if mode == "client" else "peer"
                conn = router_ep if mode == "client" else peer_ep
                skey = f"{name}-{style}"
                if skey not in sessions:
                    sessions[skey] = zenoh.open(config("client" if mode == "client" else "peer",
                                                       [conn], []))
                for how in ("queue", "channel"):
                    variants[f"{name} replier={style} querier={how}"] = (
                        sessions[skey], f"bench/{style}/{name}",
                        ask_queue if how == "queue" else ask_channel)
        time.sleep(1.0)
        for sess, key, ask in variants.values():  # warm-up and route discovery
            for _ in range(20):
                ask(sess, key)
        times: dict[str, list[float]] = {name: [] for name in variants}
        period = args.period_ms / 1e3
        while min(len(v) for v in times.values()) < args.queries:
            for name, (sess, key, ask) in variants.items():
                for _ in range(args.block):
                    t0 = time.perf_counter()
                    ask(sess, key)
                    times[name].append(time.perf_counter() - t0)
                    time.sleep(max(0.0, period - (time.perf_counter() - t0)))
        for name, ts in times.items():
            ms = np.array(ts) * 1e3
            print(f"{name:42s} median {np.median(ms):5.2f} ms  p90 {np.percentile(ms, 90):5.2f}"
                  f"  p99 {np.percentile(ms, 99):6.2f}  max {ms.max():6.1f}  (n={len(ms)})")
    finally:
        for s in sessions.values():
            s.close()
        for proc in procs:
            if proc.stdin:
                proc.stdin.close()
            proc.terminate()
        for proc in procs:
            proc.wait(timeout=5)
    return 0


if __name__ == "__main__":
    sys.exit(main())
