"""A killable worker process for the exact solvers: built once, killed past a deadline.

SCIP's time limit is soft (a cut round once ran 40 s past it) and SCIP 10
corrupted its heap on one instance (abort or hang). Every exact path runs
its solver here: a crash or an overrun costs one answer, never the caller.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from typing import Any

#: Builds, inside the worker, the function that answers each request (picklable for "spawn").
Factory = Callable[[], Callable[..., Any]]


@dataclass(frozen=True)
class PlannerFactory:
    """Builds ``cls(spec, params, **options)`` in the worker; requests call its ``answer`` method.

    Module-level classes pickle by reference, so this is a valid "spawn" factory.
    """

    cls: Callable[..., Any]
    spec: Any
    params: Any
    options: Mapping[str, Any] = field(default_factory=dict)
    answer: str = "plan"

    def __call__(self) -> Callable[..., Any]:
        return getattr(self.cls(self.spec, self.params, **self.options), self.answer)


def _exit_with_parent(parent_pid: int) -> None:
    """Watchdog thread: a worker never outlives the process that started it."""
    while True:
        time.sleep(0.5)
        if os.getppid() != parent_pid:
            os._exit(0)


def _worker_main(factory: Factory, conn: Connection, parent_pid: int) -> None:
    """Worker loop: build the handler once, then answer each request tuple with it."""
    threading.Thread(target=_exit_with_parent, args=(parent_pid,), daemon=True).start()
    handler = factory()
    conn.send("ready")
    while True:
        try:
            req = conn.recv()
        except EOFError:
            return
        if req is None:
            return
        conn.send(handler(*req))


class Worker:
    """A handler in its own process, killed when an answer is not back by the deadline.

    :meth:`solve` returns the answer, or None and why ("crashed …", "killed
    after … s"); the next call then starts a fresh process.

    Parameters
    ----------
    factory : callable
        Builds the handler inside the worker (picklable for "spawn").
    context : str
        multiprocessing start method; "spawn" is safe in threaded services.
    startup_timeout_s : float
        How long a fresh worker may take to build its handler (s); not
        counted against a request's deadline.
    """

    def __init__(self, factory: Factory, context: str = "spawn",
                 startup_timeout_s: float = 120.0) -> None:
        self.factory = factory
        self.ctx: Any = mp.get_context(context)
        self.startup_timeout_s = float(startup_timeout_s)
        self._proc: Any = None
        self._conn: Connection | None = None
        self._ready = False
        self.restarts = 0

    @property
    def pid(self) -> int | None:
        return self._proc.pid if self._proc is not None else None

    def alive(self) -> bool:
        return self._proc is not None and self._proc.is_alive()

    def start(self) -> None:
        """Start the worker now (it builds its handler in the background)."""
        if self.alive():
            return
        self.stop()
        parent, child = self.ctx.Pipe()
        proc = self.ctx.Process(target=_worker_main, args=(self.factory, child, os.getpid()),
                                daemon=True, name="dualpilot-system2-worker")
        proc.start()
        child.close()
        self._proc, self._conn = proc, parent
        self._ready = False
        self.restarts += 1

    def _wait_ready(self) -> str | None:
        """Wait for the handler to be built; None when ready, else why not."""
        if self._ready:
            return None
        assert self._conn is not None
        t_end = time.monotonic() + self.startup_timeout_s
        while time.monotonic() < t_end:
            if self._conn.poll(0.05):
                msg = self._conn.recv()
                self._ready = msg == "ready"
                return None if self._ready else f"bad start message {msg!r}"
            if not self._proc.is_alive():
                return f"crashed at start (exit code {self._proc.exitcode})"
        return f"not ready after {self.startup_timeout_s:.0f} s"

    def solve(self, request: tuple[Any, ...], deadline_s: float) -> tuple[Any | None, str]:
        """Send one request; the answer and "ok", or None and why.

        The deadline counts from the moment the worker is ready.
        """
        self.start()
        assert self._conn is not None
        try:
            why = self._wait_ready()
        except (EOFError, OSError) as exc:
            why = f"crashed at start ({type(exc).__name__})"
        if why is not None:
            self.stop()
            return None, why
        t_end = time.monotonic() + deadline_s
        try:
            self._conn.send(request)
            while True:
                left = t_end - time.monotonic()
                if left <= 0:
                    self.stop()
                    return None, f"killed after {deadline_s:.1f} s"
                if self._conn.poll(min(left, 0.05)):
                    return self._conn.recv(), "ok"
                if not self._proc.is_alive():
                    code = self._proc.exitcode
                    self.stop()
                    return None, f"crashed (exit code {code})"
        except (EOFError, OSError) as exc:
            self.stop()
            return None, f"crashed ({type(exc).__name__})"

    def stop(self) -> None:
        """Kill the worker process (if any); the next :meth:`solve` starts a new one."""
        proc, conn = self._proc, self._conn
        self._proc, self._conn, self._ready = None, None, False
        if conn is not None:
            conn.close()
        if proc is not None:
            if proc.is_alive():
                proc.kill()
            proc.join(timeout=5.0)

    def __del__(self) -> None:  # pragma: no cover - best effort at interpreter exit
        with contextlib.suppress(Exception):
            self.stop()
