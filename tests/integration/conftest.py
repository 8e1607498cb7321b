"""Real processes on loopback: a Zenoh router on a free port and services started against it.

Every process runs in its own session (``start_new_session``) and is stopped
with SIGINT, then SIGKILL (services.launch.ProcessGroup). Tests wait on
liveliness tokens and messages, never on fixed sleeps.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from services.common import bus
from services.launch import REPO, Proc, ProcessGroup, client_session, free_port, wait_router

UAV = "itest"


class Services:
    """Start service processes against one router; stop them all at the end."""

    def __init__(self, endpoint: str, logs: Path, uav: str = UAV):
        self.endpoint = endpoint
        self.logs = logs
        self.uav = uav
        self.group = ProcessGroup()

    def env(self, **extra: str) -> dict[str, str]:
        env = dict(os.environ)
        env.update(PYTHONPATH=str(REPO), PYTHONUNBUFFERED="1", ZENOH_CONNECT=self.endpoint,
                   UAV_ID=self.uav, LOG_FORMAT="text", LOG_LEVEL="INFO",
                   UAV_CLOCK="lockstep")  # the stack's clock (a vehicle alone runs realtime)
        env.update(extra)
        return env

    def start(self, name: str, *args: str, module: str | None = None, **env: str) -> Proc:
        argv = [sys.executable, "-m", module or f"services.{name}", *args]
        return self.group.start(name, argv, self.env(**env), self.logs / f"{name}.log")

    def log(self, name: str) -> str:
        path = self.logs / f"{name}.log"
        return path.read_text() if path.is_file() else ""

    def stop_all(self) -> dict[str, int]:
        return self.group.stop_all()


@pytest.fixture(scope="module")
def router(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """A zenoh-python router on a free loopback port; yields its endpoint."""
    logs = tmp_path_factory.mktemp("router")
    endpoint = f"tcp/127.0.0.1:{free_port('tcp')}"
    group = ProcessGroup()
    env = dict(os.environ, PYTHONPATH=str(REPO), PYTHONUNBUFFERED="1", LOG_FORMAT="text")
    proc = group.start("router", [sys.executable, "-m", "services.router", "--zenoh-listen",
                                  endpoint], env, logs / "router.log")
    try:
        yield endpoint
    finally:
        group.stop_all()
        assert proc.popen.returncode == 0, (logs / "router.log").read_text()


@pytest.fixture(scope="module")
def session(router: str) -> Iterator[Any]:
    """A Zenoh client session of the test process on the router."""
    wait_router(router, 30.0)
    with client_session(router) as sess:
        yield sess


@pytest.fixture(scope="module")
def services(router: str, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Services]:
    svc = Services(router, tmp_path_factory.mktemp("logs"))
    try:
        yield svc
    finally:
        svc.stop_all()


@pytest.fixture(scope="module")
def liveliness(session: Any) -> bus.Liveliness:
    return bus.Liveliness(session, UAV)


def _wait_until(pred: Callable[[], bool], timeout_s: float, period_s: float = 0.02) -> bool:
    """Poll ``pred`` (a message or state check, not a fixed sleep) until true or timeout."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(period_s)
    return pred()


@pytest.fixture(scope="session")
def wait_until() -> Callable[[Callable[[], bool], float], bool]:
    return _wait_until
