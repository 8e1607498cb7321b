"""A datagram's arrival is the kernel's stamp, not the time the vehicle process read it."""

from __future__ import annotations

import socket
import time

from services.uavsim import arrivals


def test_a_datagram_read_late_keeps_its_arrival_time() -> None:
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    arrivals.enable(rx)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        # the kernel turns receive stamping on in deferred work: a datagram that arrives before
        # it runs is stamped when read; one read through first, as a vehicle's link has
        tx.sendto(b"first", rx.getsockname())
        arrivals.recv(rx)
        sent = time.monotonic()
        tx.sendto(b"setpoint", rx.getsockname())
        time.sleep(0.3)  # the reader is busy elsewhere
        data, addr, arrived = arrivals.recv(rx)
        read = time.monotonic()
        assert data == b"setpoint" and addr[1] == tx.getsockname()[1]
        assert sent - 0.01 <= arrived <= sent + 0.1, (arrived - sent)
        assert read - arrived >= 0.25
    finally:
        rx.close()
        tx.close()
