"""Child processes of the launcher (each in its own session, stopped with SIGINT then SIGKILL)
and free loopback ports. A service may come from the fork server instead of a fresh
interpreter (services/forking/server.py, the e2e tests' choice)."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import threading
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import IO

from services.forking import server as forkserver

REPO = Path(__file__).resolve().parent.parent.parent
STOP_GRACE_S = 2.0


# -- ports ----------------------------------------------------------------------------------------
def free_port(proto: str = "tcp") -> int:
    kind = socket.SOCK_STREAM if proto == "tcp" else socket.SOCK_DGRAM
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def free_port_run(n: int, proto: str = "udp", tries: int = 200) -> int:
    """The first of ``n`` consecutive free loopback ports (a fleet's instances: port + k)."""
    for _ in range(tries):
        base = free_port(proto)
        if base + n - 1 <= 65535 and all(port_is_free(base + k, proto) for k in range(1, n)):
            return base
    raise OSError(f"no run of {n} free {proto} ports")


def port_is_free(port: int, proto: str) -> bool:
    kind = socket.SOCK_STREAM if proto == "tcp" else socket.SOCK_DGRAM
    with socket.socket(socket.AF_INET, kind) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
        return True



# -- processes ------------------------------------------------------------------------------------
@dataclass
class Proc:
    name: str
    popen: subprocess.Popen[bytes] | forkserver.ForkedProcess
    log_path: Path
    log_file: IO[bytes]


class ProcessGroup:
    """Child processes, each in its own session, stopped with SIGINT then SIGKILL."""

    def __init__(self) -> None:
        self.procs: list[Proc] = []

    def start(self, name: str, argv: list[str], env: Mapping[str, str], log_path: Path) -> Proc:
        log_path.parent.mkdir(parents=True, exist_ok=True)
        fh = log_path.open("wb")  # a forked service appends to it by its path
        popen = forkserver.start(argv, env, REPO, log_path) or subprocess.Popen(
            argv, env=dict(env), cwd=REPO, stdin=subprocess.DEVNULL, stdout=fh,
            stderr=subprocess.STDOUT, start_new_session=True)
        proc = Proc(name, popen, log_path, fh)
        self.procs.append(proc)
        return proc

    def dead(self) -> list[Proc]:
        return [p for p in self.procs if p.popen.poll() is not None]

    def stop(self, proc: Proc, grace_s: float = STOP_GRACE_S) -> int:
        """SIGINT, wait ``grace_s``, then SIGKILL; returns the exit code."""
        if proc.popen.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.popen.pid, signal.SIGINT)
            try:
                proc.popen.wait(grace_s)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(proc.popen.pid, signal.SIGKILL)
                proc.popen.wait()
        proc.log_file.close()
        return int(proc.popen.returncode)

    def stop_all(self, grace_s: float = STOP_GRACE_S, last: str | None = None) -> dict[str, int]:
        """Stop every process (in parallel), the one named ``last`` after the others."""
        first = [p for p in self.procs if p.name != last]
        codes: dict[str, int] = {}
        threads = [threading.Thread(target=lambda p=p: codes.__setitem__(p.name,
                                                                          self.stop(p, grace_s)))
                   for p in first]
        for th in threads:
            th.start()
        for th in threads:
            th.join()
        for p in self.procs:
            if p.name == last:
                codes[p.name] = self.stop(p, grace_s)
        return codes
