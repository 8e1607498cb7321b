"""Zenoh plumbing shared by the services: sessions, inboxes, queries, liveliness, the runner.

Rules we keep (ARCHITECTURE §4): Zenoh callbacks only enqueue — never call
Zenoh or block inside one; sessions are context managers; a service
announces its liveliness token only after its subscribers and queryables
are declared, so whoever waits on the token can use them at once.

:func:`run_service` is every service's ``main``: it opens the session in a
worker thread (a client blocks in ``zenoh.open`` until the router answers),
keeps the main thread free for SIGINT/SIGTERM, and exits within 2 s of one.
"""

from __future__ import annotations

import json
import logging
import os
import queue
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from types import FrameType
from typing import Any

import zenoh
from google.protobuf.message import Message

from . import codec, keys
from . import log as logsetup
from .cli import Settings

log = logging.getLogger(__name__)

#: Seconds between SIGINT/SIGTERM and a forced exit.
STOP_GRACE_S = 1.5


def zenoh_config(s: Settings) -> zenoh.Config:
    """Mode, endpoints, no multicast scouting, and a client that waits for its router."""
    conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps(s.zenoh_mode))
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("connect/endpoints", json.dumps(list(s.zenoh_connect)))
    conf.insert_json5("listen/endpoints", json.dumps(list(s.zenoh_listen)))
    # wait (forever) for the router, retrying quickly: compose starts services in any order
    conf.insert_json5("connect/timeout_ms", "-1")
    conf.insert_json5("connect/exit_on_failure", "false")
    conf.insert_json5("connect/retry",
                      "{period_init_ms: 100, period_max_ms: 1000, period_increase_factor: 2}")
    return conf


def encoding(msg: Message | type[Message]) -> zenoh.Encoding:
    return zenoh.Encoding.APPLICATION_PROTOBUF.with_schema(codec.full_name(msg))


def put(target: zenoh.Session | zenoh.Publisher, key: str, msg: Message) -> None:
    """Publish a protobuf message (``key`` is ignored for a Publisher)."""
    payload = msg.SerializeToString()
    if isinstance(target, zenoh.Publisher):
        target.put(payload, encoding=encoding(msg))
    else:
        target.put(key, payload, encoding=encoding(msg))


@dataclass(frozen=True)
class Received:
    """A sample or query payload taken out of a Zenoh callback."""

    key: str
    payload: bytes
    encoding: str
    query: zenoh.Query | None = None
    received_ns: int = 0


class Inbox:
    """A thread-safe queue fed by Zenoh callbacks (the callbacks only enqueue)."""

    def __init__(self) -> None:
        self.q: queue.Queue[Received] = queue.Queue()

    def _push(self, item: Received) -> None:
        self.q.put(item)

    def on_sample(self, sample: zenoh.Sample) -> None:
        self._push(Received(str(sample.key_expr), sample.payload.to_bytes(),
                            str(sample.encoding), None, time.perf_counter_ns()))

    def on_query(self, query: zenoh.Query) -> None:
        payload = query.payload.to_bytes() if query.payload is not None else b""
        enc = str(query.encoding) if query.encoding is not None else ""
        self._push(Received(str(query.key_expr), payload, enc, query, time.perf_counter_ns()))

    def get(self, timeout: float | None = None) -> Received | None:
        try:
            return self.q.get(timeout=timeout)
        except queue.Empty:
            return None


def reply(query: zenoh.Query, msg: Message) -> None:
    """Reply to a query with a message and finalize it."""
    try:
        query.reply(query.key_expr, msg.SerializeToString(), encoding=encoding(msg))
    finally:
        query.drop()


def reply_error(query: zenoh.Query, err: Message) -> None:
    try:
        query.reply_err(err.SerializeToString(), encoding=encoding(err))
    finally:
        query.drop()


class QueryError(RuntimeError):
    """The queryable answered with an error reply (``code``/``text`` from dualpilot.v1.Error)."""

    def __init__(self, code: int, text: str):
        super().__init__(text)
        self.code = code


_END = object()


def request(session: zenoh.Session, key: str, msg: Message, timeout_s: float,
            stop: threading.Event | None = None) -> tuple[bytes, str]:
    """Send a query and return the first reply's (payload, encoding).

    Raises TimeoutError when nobody answers within ``timeout_s`` and
    QueryError for an error reply.
    """
    q: queue.Queue[Any] = queue.Queue()
    session.get(
        key,
        zenoh.handlers.Callback(q.put, lambda: q.put(_END)),
        payload=msg.SerializeToString(), encoding=encoding(msg), timeout=timeout_s,
        consolidation=zenoh.ConsolidationMode.NONE,
    )
    deadline = time.monotonic() + timeout_s + 1.0
    while True:
        remaining = deadline - time.monotonic()
        if remaining <= 0 or (stop is not None and stop.is_set()):
            raise TimeoutError(f"no reply on {key} within {timeout_s:.3g} s")
        try:
            item = q.get(timeout=min(remaining, 0.2))
        except queue.Empty:
            continue
        if item is _END:
            raise TimeoutError(f"no reply on {key} within {timeout_s:.3g} s")
        if item.ok is not None:
            return item.ok.payload.to_bytes(), str(item.ok.encoding)
        err_bytes = item.err.payload.to_bytes()
        try:
            err = codec.parse(err_bytes, codec.common_pb2.Error)
            raise QueryError(err.code, err.message)
        except codec.CodecError:
            raise QueryError(0, err_bytes.decode("utf-8", "replace")) from None


class Liveliness:
    """Tracks which services of a vehicle are alive (liveliness subscriber with history)."""

    def __init__(self, session: zenoh.Session, uav: str):
        self.alive: set[str] = set()
        self.cond = threading.Condition()
        self.sub = session.liveliness().declare_subscriber(
            keys.alive_all(uav), self._on, history=True)

    def _on(self, sample: zenoh.Sample) -> None:
        name = keys.service_of(str(sample.key_expr))
        with self.cond:
            if sample.kind == zenoh.SampleKind.PUT:
                self.alive.add(name)
            else:
                self.alive.discard(name)
            self.cond.notify_all()

    def wait_for(self, services: Iterable[str], timeout_s: float,
                 stop: threading.Event | None = None) -> bool:
        wanted = set(services)
        deadline = time.monotonic() + timeout_s
        with self.cond:
            while not wanted <= self.alive:
                remaining = deadline - time.monotonic()
                if remaining <= 0 or (stop is not None and stop.is_set()):
                    return False
                self.cond.wait(min(remaining, 0.2))
            return True

    def missing(self, services: Iterable[str]) -> set[str]:
        with self.cond:
            return set(services) - self.alive


# -- the service runner ---------------------------------------------------------------------------
@dataclass
class Context:
    """What a service body gets: settings, the session, the stop event and its announce()."""

    settings: Settings
    stop: threading.Event
    session: zenoh.Session | None = None
    token: zenoh.LivelinessToken | None = None
    exit_code: int = 0

    def announce(self) -> None:
        """Declare the liveliness token (after subscribers and queryables are declared)."""
        assert self.session is not None
        s = self.settings
        self.token = self.session.liveliness().declare_token(keys.alive(s.uav_id, s.service))
        log.info("alive", extra=logsetup.fields(key=keys.alive(s.uav_id, s.service)))


Body = Callable[[Context], None]


def run_service(settings: Settings, body: Body, zenoh_session: bool = True) -> int:
    """Run ``body`` in a worker thread until it returns or SIGINT/SIGTERM arrives.

    The body must return soon after ``ctx.stop`` is set; if it has not
    finished :data:`STOP_GRACE_S` after a signal the process exits anyway.
    """
    logsetup.configure(settings.service, settings.uav_id, settings.log_level, settings.log_format)
    stop = threading.Event()
    ctx = Context(settings, stop)
    signals: list[int] = []

    def on_signal(signum: int, _frame: FrameType | None) -> None:
        signals.append(signum)
        stop.set()
        if len(signals) > 1:  # a second signal: leave now
            os._exit(128 + signum)

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)

    def worker() -> None:
        try:
            if not zenoh_session:
                body(ctx)
                return
            with zenoh.open(zenoh_config(settings)) as session:
                ctx.session = session
                if stop.is_set():
                    return
                log.info("zenoh session open", extra=logsetup.fields(
                    mode=settings.zenoh_mode, connect=",".join(settings.zenoh_connect),
                    zid=str(session.info.zid())))
                body(ctx)
                if ctx.token is not None:
                    ctx.token.undeclare()
        except Exception:
            log.exception("service failed")
            ctx.exit_code = 1
        finally:
            stop.set()

    log.info("starting", extra=logsetup.fields(pid=os.getpid()))
    thread = threading.Thread(target=worker, name=f"{settings.service}-main", daemon=True)
    thread.start()
    while not stop.wait(0.5):
        pass
    thread.join(STOP_GRACE_S)
    code = ctx.exit_code
    if thread.is_alive():
        log.warning("body still busy after the stop grace period; exiting anyway")
    log.info("stopped", extra=logsetup.fields(
        signal=signals[0] if signals else 0, exit_code=code,
        rejections=sum(codec.REJECTIONS.values())))
    logging.shutdown()
    sys.stdout.flush()
    sys.stderr.flush()
    if thread.is_alive():
        os._exit(code)
    return code
