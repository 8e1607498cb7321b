"""The service runner: every service's ``main`` runs its body here.

:func:`run_service` opens the session in a worker thread (a client blocks in
``zenoh.open`` until the router answers), keeps the main thread free for
SIGINT/SIGTERM, serves the status queryable, and exits within 2 s of a signal.
A body announces its liveliness token only after its subscribers and
queryables are declared (:meth:`Context.announce`).
"""

from __future__ import annotations

import gc
import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from types import FrameType

import zenoh

from services.common import keys, rejections, traffic
from services.common import log as logsetup
from services.common.bus.config import zenoh_config
from services.common.bus.query import Stop
from services.common.bus.status import serve_status
from services.common.cli import Settings

log = logging.getLogger("services.common.bus")

#: Seconds between SIGINT/SIGTERM and a forced exit.
STOP_GRACE_S = 1.5


@dataclass
class Context:
    """What a service body gets: settings, the session, the stop event and its announce()."""

    settings: Settings
    stop: threading.Event
    session: zenoh.Session | None = None
    token: zenoh.LivelinessToken | None = None
    holder_token: zenoh.LivelinessToken | None = None
    exit_code: int = 0

    def announce(self) -> None:
        """Declare the liveliness token (after subscribers and queryables are declared).

        The objects made while starting (modules, planners, tables) are moved to
        the permanent generation first (:func:`settle_heap`).
        """
        assert self.session is not None
        settle_heap()
        s = self.settings
        zid = str(self.session.info.zid())
        self.holder_token = self.session.liveliness().declare_token(  # who: before the token
            keys.holder(s.uav_id, s.service, zid))
        self.token = self.session.liveliness().declare_token(keys.alive(s.uav_id, s.service))
        log.info("alive", extra=logsetup.fields(key=keys.alive(s.uav_id, s.service)))


Body = Callable[[Context], None]


def settle_heap() -> None:
    """Collect once, then exempt every live object from later garbage collections.

    After start-up a service holds about a million objects (numpy, scipy,
    OMPL, protobuf); a full collection that walks them all stalls whichever
    thread triggers it, for example the one answering a Zenoh query, by tens
    of milliseconds. What is made later is still collected as usual.
    """
    gc.collect()
    gc.freeze()


SWITCH_INTERVAL_S = 0.0005


"""GIL switch interval in every service (s); CPython's default is 0.005."""


def leave(code: int) -> None:
    """End a service process with ``code`` without interpreter finalisation.

    :func:`run_service` has flushed the logs and the body has closed its
    files by now; in about 1 % of exits a Zenoh thread calling into Python
    during finalisation aborted the process ("FATAL: exception not rethrown",
    exit −6), which os._exit avoids.
    """
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def _tune_process(settings: Settings) -> str:
    """Logging, the nice value and the GIL's switch interval of a service process.

    A thread woken by I/O (a Zenoh reply, a MAVLink frame) waits for the GIL up to the
    switch interval while another thread runs Python: 5 ms by default, the whole latency
    budget of a tick. Services are I/O-bound around their one compute thread.
    """
    logsetup.configure(settings.service, settings.uav_id, settings.log_level, settings.log_format)
    priority = lower_priority(settings.nice) if settings.nice else "default"
    sys.setswitchinterval(SWITCH_INTERVAL_S)
    return priority


def lower_priority(nice: int) -> str:
    """Lower this process's priority by ``nice`` (1..19); what it did.

    Linux's scheduler shares the CPU fairly between *autogroups* first (one per
    session, when ``/proc/sys/kernel/sched_autogroup_enabled`` is 1) and a
    process's nice value only weighs against the processes of its own group.
    A service started in a session of its own (the launcher starts every one
    so) is its group: its group's nice (``/proc/self/autogroup``) is lowered
    too, else the nice value would change nothing against the other services.
    """
    os.nice(nice)  # lowering one's own priority needs no privilege
    if os.getsid(0) != os.getpid():
        return f"nice {nice}"
    try:
        with open("/proc/self/autogroup", "w") as fh:
            fh.write(str(nice))
    except OSError:  # no autogroups (a container without /proc write access, another OS)
        return f"nice {nice}"
    return f"nice {nice}, autogroup nice {nice}"


def _serve(ctx: Context, body: Body, zenoh_session: bool, started: float) -> None:
    """The worker thread: the session, the status queryable and the body; the stop is set
    when it ends, however it ends."""
    settings = ctx.settings
    try:
        if not zenoh_session:
            body(ctx)
            return
        with zenoh.open(zenoh_config(settings)) as session:
            ctx.session = session
            if ctx.stop.is_set():
                return
            log.info("zenoh session open", extra=logsetup.fields(
                mode=("client" if settings.tls_dir and settings.zenoh_mode != "router"
                      else settings.zenoh_mode),
                connect=",".join(settings.zenoh_connect), tls=settings.tls_dir,
                zid=str(session.info.zid())))
            close_status = serve_status(session, settings, ctx.stop, started)
            try:
                body(ctx)
            finally:
                close_status()
            for token in (ctx.token, ctx.holder_token):
                if token is not None:
                    token.undeclare()
    except Exception:
        log.exception("service failed")
        ctx.exit_code = 1
    finally:
        ctx.stop.set()


def run_service(settings: Settings, body: Body, zenoh_session: bool = True) -> int:
    """Run ``body`` in a worker thread until it returns or SIGINT/SIGTERM arrives.

    The body must return soon after ``ctx.stop`` is set; if it has not
    finished :data:`STOP_GRACE_S` after a signal the process exits anyway.
    """
    priority = _tune_process(settings)
    started = time.monotonic()
    stop = Stop()
    ctx = Context(settings, stop)
    signals: list[int] = []

    def on_signal(signum: int, _frame: FrameType | None) -> None:
        signals.append(signum)
        stop.set()
        if len(signals) > 1:  # a second signal: leave now
            os._exit(128 + signum)

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    log.info("starting", extra=logsetup.fields(pid=os.getpid(), priority=priority))
    thread = threading.Thread(target=_serve, args=(ctx, body, zenoh_session, started),
                              name=f"{settings.service}-main", daemon=True)
    thread.start()
    while not stop.wait(0.5):
        pass
    thread.join(STOP_GRACE_S)
    code = ctx.exit_code
    if thread.is_alive():
        log.warning("body still busy after the stop grace period; exiting anyway")
    written = traffic.write_from_env(settings.service)
    log.info("stopped", extra=logsetup.fields(
        signal=signals[0] if signals else 0, exit_code=code,
        rejections=rejections.REJECTED.total(), traffic=str(written or "")))
    logging.shutdown()
    sys.stdout.flush()
    sys.stderr.flush()
    if thread.is_alive():
        os._exit(code)
    return code
