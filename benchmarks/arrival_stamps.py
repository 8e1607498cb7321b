"""How far the kernel's receive stamp lies from the send, on loopback, quiet and under load.

The vehicle takes a setpoint's arrival from the kernel's SO_TIMESTAMPNS stamp
mapped onto the monotonic clock (services/uavsim/arrivals.py). This measures
that mapping end to end: ``--datagrams`` datagrams are sent on loopback, each
read ``--read-delay-ms`` later, and the arrival is compared with the monotonic
time just before the send. Reported: the lag's quantiles (p50, p99, p99.9,
p99.99, max, in ms), how many came without a kernel stamp (the arrival then
being the read time), and how long after ``setsockopt`` the kernel first
stamped (it turns stamping on in deferred work). ``--load N`` runs N busy
processes beside it; tests/unit/services/uavsim/test_arrivals.py's tolerance is set from these
figures (docs/testing.md).

    .venv/bin/python benchmarks/arrival_stamps.py --datagrams 20000 --load 4
"""

from __future__ import annotations

import argparse
import socket
import sys
import time
from pathlib import Path

import harness  # the repository on the path: before its packages
import numpy as np

from services.uavsim import arrivals

QUANTILES = (0.5, 0.99, 0.999, 0.9999)


def first_stamp_s(rx: socket.socket, tx: socket.socket, probe_delay_s: float = 0.02,
                  limit_s: float = 10.0) -> float:
    """Seconds from enabling stamps until a datagram read late carries its send time."""
    t_enable = time.monotonic()
    arrivals.enable(rx)
    while time.monotonic() - t_enable < limit_s:
        sent = time.monotonic()
        tx.sendto(b"probe", rx.getsockname())
        time.sleep(probe_delay_s)
        _, _, arrived = arrivals.recv(rx)
        if time.monotonic() - arrived >= probe_delay_s / 2 and arrived >= sent - 0.001:
            return sent - t_enable
    return float("nan")


def measure(n: int, read_delay_s: float) -> dict[str, object]:
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        enabled_after = first_stamp_s(rx, tx)
        lags, unstamped = np.empty(n), 0
        for k in range(n):
            sent = time.monotonic()
            tx.sendto(b"setpoint", rx.getsockname())
            if read_delay_s:
                time.sleep(read_delay_s)
            data, anc, _flags, _addr = rx.recvmsg(64, socket.CMSG_SPACE(16))
            mono, wall = time.monotonic(), time.time()
            stamp = arrivals.kernel_stamp(anc)
            unstamped += stamp is None
            lags[k] = arrivals.arrival(stamp, mono, wall) - sent
    finally:
        rx.close()
        tx.close()
    ms = lags * 1e3
    return {"datagrams": n, "read_delay_ms": read_delay_s * 1e3,
            "stamping_on_after_ms": round(enabled_after * 1e3, 3), "unstamped": unstamped,
            **{f"p{100 * q:g}_ms": round(float(np.quantile(ms, q)), 4) for q in QUANTILES},
            "min_ms": round(float(ms.min()), 4), "max_ms": round(float(ms.max()), 4)}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--datagrams", type=int, default=20000)
    p.add_argument("--read-delay-ms", type=float, default=1.0,
                   help="how long each datagram waits before it is read (ms)")
    p.add_argument("--load", type=int, default=0, help="busy processes beside the measurement")
    p.add_argument("--out", type=Path, default=None, help="also write the figures as JSON here")
    args = p.parse_args(argv)
    with harness.busy(args.load):
        doc = measure(args.datagrams, args.read_delay_ms / 1e3)
    doc["load_processes"] = args.load
    harness.emit(doc, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
