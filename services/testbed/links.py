"""A link's shaping, changed while it runs: the user-space impairer or netem, and tbf.

Both kinds answer the same calls — :meth:`Link.set` (delay, jitter, loss and bandwidth of one
direction or both), :meth:`Link.outage` (the link down for N s, or until :meth:`Link.restore`)
and :meth:`Link.stats` — so a test reads the same whichever the kernel allows. A direction is
named by the host that sends.
"""

from __future__ import annotations

import logging
import os
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

from services.testbed import netns, shaping
from services.testbed.impairer.control import ControlClient, ImpairerError
from services.testbed.impairment import Impairment
from services.testbed.topology import LinkSpec

log = logging.getLogger(__name__)

READY_TIMEOUT_S = 20.0
REPO = Path(__file__).resolve().parents[2]


class Link:
    """The shaping of one link in the wire namespace ``wire`` (subclasses: the mechanism)."""

    kind = ""

    def __init__(self, spec: LinkSpec, wire: str):
        self.spec, self.wire = spec, wire
        self.settings = {h: Impairment() for h in spec.hosts}

    @property
    def name(self) -> str:
        return self.spec.name

    def start(self) -> None:
        raise NotImplementedError

    def stop(self) -> None:
        raise NotImplementedError

    def set(self, imp: Impairment, source: str | None = None) -> None:
        """Give the direction leaving host ``source`` (None: both) the impairment ``imp``."""
        sources = self.spec.hosts if source is None else (source,)
        for h in sources:
            if h not in self.spec.hosts:
                raise ValueError(f"link {self.name} joins {self.spec.hosts}, not {h!r}")
        for h in sources:
            self.settings[h] = imp
            self._apply(h)

    def _egress(self, source: str) -> str:
        """The wire interface that carries the frames sent by ``source``."""
        a, b = self.spec.hosts
        return self.spec.wire_end(b if source == a else a)

    def _apply(self, source: str) -> None:
        raise NotImplementedError

    def outage(self, seconds: float | None) -> None:
        """The link down (both directions) for ``seconds`` from now; None: until restore()."""
        raise NotImplementedError

    def restore(self) -> None:
        """The link up again now."""
        raise NotImplementedError

    def stats(self) -> dict[str, Any]:
        raise NotImplementedError


class ImpairedLink(Link):
    """Delay, jitter, loss and outages in the user-space impairer; the bandwidth in tbf."""

    kind = "impairer"

    def __init__(self, spec: LinkSpec, wire: str, workdir: Path, seed: int):
        super().__init__(spec, wire)
        self.control_path = str(workdir / f"{spec.name}.sock")
        self.log_path = workdir / f"impairer-{spec.name}.log"
        self.seed = seed
        self.control = ControlClient(self.control_path)
        self.proc: subprocess.Popen[bytes] | None = None

    def start(self) -> None:
        ends = [f"--end={h}={self.spec.wire_end(h)}" for h in self.spec.hosts]
        argv = [sys.executable, "-m", "services.testbed.impairer", *ends,
                "--control", self.control_path, "--seed", str(self.seed)]
        env = dict(os.environ, PYTHONPATH=str(REPO), PYTHONUNBUFFERED="1")
        with self.log_path.open("wb") as fh:
            self.proc = subprocess.Popen(netns.exec_argv(self.wire, argv), cwd=REPO, env=env,
                                         stdin=subprocess.DEVNULL, stdout=fh,
                                         stderr=subprocess.STDOUT, start_new_session=True)
        deadline = time.monotonic() + READY_TIMEOUT_S
        while True:
            if self.proc.poll() is not None:
                raise netns.NetnsError(f"impairer of {self.name} exited "
                                       f"{self.proc.returncode}: {self.log_path.read_text()}")
            try:
                self.control.call(cmd="ping")
                return
            except ImpairerError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.05)

    def stop(self) -> None:
        if self.proc is None or self.proc.poll() is not None:
            return
        self.proc.terminate()
        try:
            self.proc.wait(5.0)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()

    def _apply(self, source: str) -> None:
        imp = self.settings[source]
        self.control.call(cmd="set", source=source, delay_ms=imp.delay_ms,
                          jitter_ms=imp.jitter_ms, loss=imp.loss)
        shaping.apply(self.wire, self._egress(source), imp, netem=False)

    def outage(self, seconds: float | None) -> None:
        self.control.call(cmd="outage", seconds=seconds)

    def restore(self) -> None:
        self.control.call(cmd="up")

    def stats(self) -> dict[str, Any]:
        reply = self.control.call(cmd="stats")
        reply.pop("ok", None)
        return reply


class NetemLink(Link):
    """A kernel bridge between the two ends, netem and tbf on each end's egress."""

    kind = "netem"

    def __init__(self, spec: LinkSpec, wire: str):
        super().__init__(spec, wire)
        self.bridge = f"br-{spec.name}"[:15]
        self._down_until: float | None = None
        self._timer: threading.Timer | None = None
        self._lock = threading.Lock()

    def start(self) -> None:
        netns.ip("link", "add", self.bridge, "type", "bridge", ns=self.wire)
        for h in self.spec.hosts:
            netns.ip("link", "set", self.spec.wire_end(h), "master", self.bridge, ns=self.wire)
        netns.ip("link", "set", self.bridge, "up", ns=self.wire)

    def stop(self) -> None:
        with self._lock:
            if self._timer is not None:
                self._timer.cancel()

    def _apply(self, source: str) -> None:
        down = self._down_until is not None and time.monotonic() < self._down_until
        shaping.apply(self.wire, self._egress(source), self.settings[source], netem=True,
                      down=down)

    def outage(self, seconds: float | None) -> None:
        with self._lock:
            if self._timer is not None:
                self._timer.cancel()
            self._down_until = float("inf") if seconds is None else time.monotonic() + seconds
            for h in self.spec.hosts:
                self._apply(h)
            if seconds is not None:
                self._timer = threading.Timer(seconds, self.restore)
                self._timer.daemon = True
                self._timer.start()

    def restore(self) -> None:
        self._down_until = None
        for h in self.spec.hosts:
            self._apply(h)

    def stats(self) -> dict[str, Any]:
        out = {}
        for h in self.spec.hosts:
            done = netns.command(shaping.in_ns(self.wire, ["tc", "-s", "qdisc", "show", "dev",
                                                           self._egress(h)]))
            out[h] = {**self.settings[h].wire(), "tc": done.stdout}
        until = self._down_until
        return {"directions": out,
                "down_for_s": None if until is None else max(0.0, until - time.monotonic())}
