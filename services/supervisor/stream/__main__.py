"""The setpoint stream process: ``python -m services.supervisor.stream --ctl FD``.

A small process (the standard library and services/common/mavframe.py only,
about 10 MB) that keeps every vehicle link of its supervisor beating: the
current SET_POSITION_TARGET_LOCAL_NED at the link's rate and a HEARTBEAT at
its period, on the link's own UDP socket (passed from the supervisor, so the
vehicle sees one peer). A new setpoint is sent the moment it arrives. It
asks for real-time scheduling (SCHED_RR), else a higher priority (nice −10),
else runs as it is, so neither the supervisor's computing nor the GIL nor
other processes of the same priority can stretch the stream's period.

It ends when its parent does (end of file on the control socket): a dead
supervisor's vehicle must not be kept alive. A parent that stops renewing
its lease for protocol.LEASE_S is treated the same way until it speaks again.
The loop is services/supervisor/stream/streamer.py.
"""

from __future__ import annotations

import argparse
import signal
import socket
import sys

from services.supervisor.stream.streamer import Streamer


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m services.supervisor.stream",
                                description=__doc__.splitlines()[0])
    p.add_argument("--ctl", type=int, required=True, help="the control socket's descriptor")
    args = p.parse_args(argv)
    # the process group's SIGINT/SIGTERM are the supervisor's to handle: this process streams
    # until its parent has gone (end of file), so a stopping supervisor still holds its vehicle
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    return Streamer(socket.socket(fileno=args.ctl)).run()


if __name__ == "__main__":
    sys.exit(main())
