"""Zenoh plumbing shared by the services: sessions, inboxes, queries, liveliness, the runner.

Rules we keep (ARCHITECTURE §4): Zenoh callbacks only enqueue — never call
Zenoh or block inside one; sessions are context managers; a service
announces its liveliness token only after its subscribers and queryables
are declared, so whoever waits on the token can use them at once.

:func:`run_service` is every service's ``main``: it opens the session in a
worker thread (a client blocks in ``zenoh.open`` until the router answers),
keeps the main thread free for SIGINT/SIGTERM, and exits within 2 s of one.

Bad input: every service counts the inputs it rejects per key and reason
(:data:`rejections.REJECTED`, filled by :func:`rejections.rejected` and by a full
:class:`Inbox`) and serves them, with no code of its own, on the queryable
``<ns>/status/<service>`` (:func:`keys.status`) that :func:`run_service`
declares: a JSON object (:func:`status`). :func:`alias` maps a service's
label for a message kind to the key it arrives on; :func:`accept` decodes a
received sample or query, counting and logging a rejection.
"""

from __future__ import annotations

import gc
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
from typing import Any, TypeVar

import zenoh
from google.protobuf.message import Message

from services.msgs import common_pb2

from . import acl, keys, rejections, wire
from . import log as logsetup
from .cli import Settings

log = logging.getLogger(__name__)

#: Seconds between SIGINT/SIGTERM and a forced exit.
STOP_GRACE_S = 1.5
#: An inbox holds at most this many items and bytes; what arrives beyond is dropped and
#: counted (reason ``overflow``): a flood costs bounded memory.
INBOX_MAX_ITEMS = 1000
INBOX_MAX_BYTES = 64 * 1024 * 1024
STATUS_ENCODING = "application/json"

T = TypeVar("T")
M = TypeVar("M", bound=Message)


def zenoh_config(s: Settings) -> zenoh.Config:
    """Mode, endpoints, no multicast scouting, no shared memory, a client that waits for its router.

    Shared memory is off: by default Zenoh puts every message over 3 KB (a
    plan, a fire update) in a 16 MB shared-memory pool that it builds lazily,
    inside the first such send, which stalled the sender for 5–6 ms early in
    every mission; our messages are a few kB, and containers do not share
    /dev/shm anyway.

    With ``ZENOH_TLS_DIR`` (``s.tls_dir``) the endpoints are ``tls/``, each
    session presents its service's certificate (mutual TLS, :func:`tls_config`),
    every non-router session is a client, and the router enforces the access
    control of :mod:`services.common.acl`.
    """
    conf = zenoh.Config()
    mode, connect, listen = s.zenoh_mode, list(s.zenoh_connect), list(s.zenoh_listen)
    if s.tls_dir:
        # TLS and access control (services/common/acl.py): every service is a client, so all
        # its traffic crosses the router, where the access control is enforced (a peer's
        # direct links to other peers would bypass it)
        if mode != "router":
            mode, listen = "client", []
        connect, listen = tls_endpoints(connect), tls_endpoints(listen)
        conf.insert_json5("transport/link/tls", json.dumps(tls_config(s.tls_dir, s.service)))
        if mode == "router":
            conf.insert_json5("access_control", json.dumps(acl.config()))
    conf.insert_json5("mode", json.dumps(mode))
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("transport/shared_memory/enabled", "false")
    conf.insert_json5("connect/endpoints", json.dumps(connect))
    conf.insert_json5("listen/endpoints", json.dumps(listen))
    # wait (forever) for the router, retrying quickly: compose starts services in any order
    conf.insert_json5("connect/timeout_ms", "-1")
    conf.insert_json5("connect/exit_on_failure", "false")
    conf.insert_json5("connect/retry",
                      "{period_init_ms: 100, period_max_ms: 1000, period_increase_factor: 2}")
    return conf


def tls_endpoints(endpoints: Iterable[str]) -> list[str]:
    """``tcp/host:port`` → ``tls/host:port`` (other endpoints as they are)."""
    return ["tls/" + e.removeprefix("tcp/") if e.startswith("tcp/") else e for e in endpoints]


def tls_config(tls_dir: str, identity: str) -> dict[str, Any]:
    """``transport/link/tls`` for mutual TLS: ``identity``'s key and certificate from
    ``tls_dir`` (made by ``python -m services.certs``) both ways, peers checked against its CA.

    The names are checked too (``verify_name_on_connect``): the router's certificate names
    localhost, 127.0.0.1 and the compose host ``zenoh``.
    """
    d = os.path.abspath(tls_dir)
    key, cert = os.path.join(d, f"{identity}.key"), os.path.join(d, f"{identity}.pem")
    for path in (key, cert, os.path.join(d, "ca.pem")):
        if not os.path.isfile(path):
            raise FileNotFoundError(f"ZENOH_TLS_DIR: no {path} (python -m services.certs "
                                    f"--out {tls_dir})")
    return {"root_ca_certificate": os.path.join(d, "ca.pem"), "enable_mtls": True,
            "listen_private_key": key, "listen_certificate": cert,
            "connect_private_key": key, "connect_certificate": cert,
            "verify_name_on_connect": True}


def encoding(msg: Message | type[Message]) -> zenoh.Encoding:
    return zenoh.Encoding.APPLICATION_PROTOBUF.with_schema(wire.full_name(msg))


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
    attachment: bytes = b""  # a query's attachment: the session id the querier states


class Inbox:
    """A thread-safe, bounded queue fed by Zenoh callbacks (the callbacks only enqueue).

    ``key``, when given, is the key expression this inbox was declared on;
    it names the entry point in the rejection counters (else the key of the
    sample or query). An item that would exceed ``max_items`` or
    ``max_bytes`` is dropped and counted as an ``overflow`` rejection (a
    dropped query is finalized without a reply).
    """

    def __init__(self, key: str | None = None, max_items: int = INBOX_MAX_ITEMS,
                 max_bytes: int = INBOX_MAX_BYTES) -> None:
        self.key = key
        self.q: queue.Queue[Received] = queue.Queue()
        self.max_items = max_items
        self.max_bytes = max_bytes
        self._bytes = 0
        self._lock = threading.Lock()

    def _push(self, item: Received) -> None:
        with self._lock:
            full = (self.q.qsize() >= self.max_items
                    or self._bytes + len(item.payload) > self.max_bytes)
            if not full:
                self._bytes += len(item.payload)
                self.q.put(item)
        if full:
            rejections.rejected("input", rejections.invalid(
                f"inbox full ({self.q.qsize()} items, {self._bytes} bytes): "
                f"{len(item.payload)} bytes dropped", rejections.Reason.OVERFLOW),
                log, key=self.key or item.key)

    def on_sample(self, sample: zenoh.Sample) -> None:
        self._push(Received(str(sample.key_expr), sample.payload.to_bytes(),
                            str(sample.encoding), None, time.perf_counter_ns()))

    def on_query(self, query: zenoh.Query) -> None:
        payload = query.payload.to_bytes() if query.payload is not None else b""
        enc = str(query.encoding) if query.encoding is not None else ""
        att = query.attachment.to_bytes()[:64] if query.attachment is not None else b""
        self._push(Received(str(query.key_expr), payload, enc, query, time.perf_counter_ns(),
                            att))

    def get(self, timeout: float | None = None) -> Received | None:
        try:
            item = self.q.get(timeout=timeout)
        except queue.Empty:
            return None
        with self._lock:
            self._bytes -= len(item.payload)
        return item

    def entry(self, item: Received) -> str:
        """The key a rejection of ``item`` is counted under."""
        return self.key or item.key


def accept(item: Received, cls: type[M], convert: Callable[[M], T], key: str | None = None,
           logger: logging.Logger = log) -> T | None:
    """``convert(parse(item))``, or None after counting and logging the rejection under
    ``key`` (default: the item's key)."""
    try:
        return convert(wire.parse(item.payload, cls, item.encoding))
    except rejections.CodecError as err:
        rejections.rejected(wire.full_name(cls).rsplit(".", 1)[-1], err, logger,
                            key=key or item.key)
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


class Stop(threading.Event):
    """A stop event that also ends the queries waiting on it (:func:`request`).

    ``set()`` cancels every registered Zenoh query, so a service blocked in a
    reply channel stops at once instead of at the query's timeout.
    """

    def __init__(self) -> None:
        super().__init__()
        self._lock = threading.RLock()  # set() may run in a signal handler on the main thread
        self._tokens: set[zenoh.CancellationToken] = set()

    def set(self) -> None:
        super().set()
        with self._lock:
            tokens = list(self._tokens)
        for token in tokens:
            token.cancel()

    def watch(self, token: zenoh.CancellationToken) -> None:
        with self._lock:
            self._tokens.add(token)
        if self.is_set():
            token.cancel()

    def forget(self, token: zenoh.CancellationToken) -> None:
        with self._lock:
            self._tokens.discard(token)


def replier(reply: zenoh.Reply) -> str:
    """The Zenoh id of the session that sent ``reply`` ("" when Zenoh does not say)."""
    rid = reply.replier_id
    return "" if rid is None else str(rid.zid)


Trusted = str | frozenset[str] | None
"""Whose replies count: one Zenoh id, a set of them (a service's replicas), or None (anyone);
"" or an empty set trusts nobody."""


def _trusts(trusted: Trusted, sender: str) -> bool:
    if trusted is None:
        return True
    if isinstance(trusted, str):
        return bool(sender) and sender == trusted
    return sender in trusted


def _trusted_text(trusted: Trusted) -> str:
    if isinstance(trusted, frozenset):
        return ",".join(sorted(trusted)) or "none"
    return trusted or "none"


def first_reply(session: zenoh.Session, key: str, timeout_s: float,
                stop: threading.Event | None = None, trusted: Trusted = None,
                count_key: str = "", **get: Any) -> zenoh.Reply:
    """Send a query (``get``: payload, encoding, …) and wait for its first reply.

    The calling thread waits in Zenoh's own reply channel (no Python callback
    and no hand-off between threads on the way back). A :class:`Stop` ends
    the wait when it is set; with a plain Event the wait ends at the timeout.
    With ``trusted`` (a Zenoh id or a set of them; "" trusts nobody) only a
    reply from that session counts: one from any other session is logged and
    counted under ``count_key`` (default ``key``; reason ``untrusted``) and the
    wait goes on.
    Raises TimeoutError when nobody (trusted) answers within ``timeout_s`` (or on stop).
    """
    if stop is not None and stop.is_set():
        raise TimeoutError(f"stopped before asking {key}")
    token = zenoh.CancellationToken()
    if isinstance(stop, Stop):
        stop.watch(token)
    try:
        replies = session.get(key, timeout=timeout_s, consolidation=zenoh.ConsolidationMode.NONE,
                              cancellation_token=token, **get)
        untrusted = 0
        while True:
            try:
                reply: zenoh.Reply = replies.recv()
            except zenoh.ZError:  # the channel closed without a reply: cancelled, or none came
                why = "stopped" if stop is not None and stop.is_set() else "no reply"
                if untrusted:
                    why = f"no reply from the token holder ({untrusted} from others)"
                raise TimeoutError(f"{why} on {key} within {timeout_s:.3g} s") from None
            if trusted is None or _is_local_timeout(reply):
                break
            sender = replier(reply)
            if _trusts(trusted, sender):
                # answers from others already here are counted too (not waited for)
                while (late := _try_recv(replies)) is not None:
                    if not _trusts(trusted, replier(late)) and not _is_local_timeout(late):
                        _count_untrusted(count_key or key, replier(late), trusted)
                break
            untrusted += 1
            _count_untrusted(count_key or key, sender, trusted)
    finally:
        if isinstance(stop, Stop):
            stop.forget(token)
    if _is_local_timeout(reply):
        raise TimeoutError(f"no reply on {key} within {timeout_s:.3g} s")  # Zenoh's own reply
    return reply


#: the rejection reason of a reply from a session that does not hold the service's token
UNTRUSTED = "untrusted"


def _count_untrusted(key: str, sender: str, trusted: Trusted) -> None:
    rejections.rejected("reply", rejections.invalid(
        f"reply on {key} from session {sender or '?'}, not from the holder of the "
        f"service's liveliness token ({_trusted_text(trusted)})"), log, key=key,
        reason=UNTRUSTED)


def _try_recv(replies: Any) -> zenoh.Reply | None:
    try:
        got: zenoh.Reply | None = replies.try_recv()
    except zenoh.ZError:
        return None
    return got


def _is_local_timeout(reply: zenoh.Reply) -> bool:
    """Zenoh's own "Timeout" error reply.

    It comes from this session (no replier id) or from a router or the
    queryable's session on the way (their id), so it ends the wait whoever
    sent it: at worst an impostor makes a query time out early, it never
    gets an answer accepted.
    """
    return (reply.err is not None
            and reply.err.payload.to_bytes().strip().lower() == b"timeout")


def request(session: zenoh.Session, key: str, msg: Message, timeout_s: float,
            stop: threading.Event | None = None, trusted: Trusted = None,
            count_key: str = "") -> tuple[bytes, str]:
    """Send ``msg`` as a query and return the first (trusted) reply's (payload, encoding).

    Waits as :func:`first_reply`; raises TimeoutError when nobody answers
    within ``timeout_s`` (or on stop) and QueryError for an error reply.
    """
    item = first_reply(session, key, timeout_s, stop, trusted, count_key,
                       payload=msg.SerializeToString(), encoding=encoding(msg),
                       attachment=str(session.info.zid()).encode())
    if item.ok is not None:
        return item.ok.payload.to_bytes(), str(item.ok.encoding)
    assert item.err is not None  # a reply is either ok or an error
    err_bytes = item.err.payload.to_bytes()
    try:
        err = wire.parse(err_bytes, common_pb2.Error)
    except rejections.CodecError as bad:
        rejections.rejected("Error", bad, log, key=key)  # an error reply we cannot read
        raise QueryError(0, err_bytes[:500].decode("utf-8", "replace")) from None
    raise QueryError(err.code, err.message)


class Liveliness:
    """Tracks which services of a vehicle are alive and which session holds each one's token.

    A service is alive while its ``alive/<service>`` token is up. Its holder is
    the session named by its ``alive/<service>/<zid>`` token (declared first,
    :meth:`Context.announce`); while several sessions claim one service the
    first seen stays the holder (:meth:`holder`) and every other claim is
    logged and counted (``alive/<service>``, reason ``untrusted``). A
    replicated service (:data:`keys.REPLICATED`, the planners) is alive while
    any replica holds its token, and every holder is one of its replicas
    (:meth:`replicas`).
    """

    def __init__(self, session: zenoh.Session, uav: str):
        self.alive: set[str] = set()
        self.holders: dict[str, list[str]] = {}
        self.claims = 0  # holder tokens beyond the first per service (impostors, duplicates)
        self.uav = uav
        self.cond = threading.Condition()
        self.sub = session.liveliness().declare_subscriber(
            keys.alive_tree(uav), self._on, history=True)

    def _on(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        held = keys.holder_of(key)
        put = sample.kind == zenoh.SampleKind.PUT
        second = ""
        with self.cond:
            if held is None:
                if put:
                    self.alive.add(keys.service_of(key))
                else:
                    self.alive.discard(keys.service_of(key))
            else:
                name, zid = held
                zids = self.holders.setdefault(name, [])
                if put and zid not in zids:
                    zids.append(zid)
                    if len(zids) > 1 and name not in keys.REPLICATED:
                        self.claims += 1
                        second = f"{name} claimed by {zid} while {zids[0]} holds it"
                elif not put and zid in zids:
                    zids.remove(zid)
            self.cond.notify_all()
        if second:  # only counting and logging here: never Zenoh in a callback
            rejections.rejected("liveliness", rejections.invalid(second), log, key=key,
                                reason=UNTRUSTED)

    def holder(self, service: str) -> str:
        """The Zenoh id of the session holding ``service``'s token ("" while nobody does)."""
        with self.cond:
            zids = self.holders.get(service)
            return zids[0] if zids else ""

    def replicas(self, service: str) -> list[str]:
        """The Zenoh ids of every session holding ``service``'s token, first seen first."""
        with self.cond:
            return list(self.holders.get(service, []))

    def _up(self) -> set[str]:
        """The services alive now (caller holds the lock)."""
        return self.alive | {name for name in keys.REPLICATED if self.holders.get(name)}

    def others(self, service: str, own: str) -> list[str]:
        """Sessions other than ``own`` that claim ``service``."""
        with self.cond:
            return [z for z in self.holders.get(service, []) if z != own]

    def wait_for(self, services: Iterable[str], timeout_s: float,
                 stop: threading.Event | None = None) -> bool:
        wanted = set(services)
        deadline = time.monotonic() + timeout_s
        with self.cond:
            while not wanted <= self._up():
                remaining = deadline - time.monotonic()
                if remaining <= 0 or (stop is not None and stop.is_set()):
                    return False
                self.cond.wait(min(remaining, 0.2))
            return True

    def missing(self, services: Iterable[str]) -> set[str]:
        with self.cond:
            return set(services) - self._up()

    def wait_any(self, services: Iterable[str], timeout_s: float,
                 stop: threading.Event | None = None) -> bool:
        """Wait until at least one of ``services`` is alive (True) or the time is up."""
        wanted = set(services)
        deadline = time.monotonic() + timeout_s
        with self.cond:
            while not wanted & self._up():
                remaining = deadline - time.monotonic()
                if remaining <= 0 or (stop is not None and stop.is_set()):
                    return False
                self.cond.wait(min(remaining, 0.2))
            return True

    def wait_gone(self, service: str, timeout_s: float,
                  stop: threading.Event | None = None) -> bool:
        """Wait until ``service``'s token is gone (True) or the time is up."""
        deadline = time.monotonic() + timeout_s
        with self.cond:
            while service in self._up():
                remaining = deadline - time.monotonic()
                if remaining <= 0 or (stop is not None and stop.is_set()):
                    return False
                self.cond.wait(min(remaining, 0.2))
            return True


# -- status -------------------------------------------------------------------------------------
def status(settings: Settings, started: float) -> dict[str, Any]:
    """The service's status: who it is and what it rejected (per key and reason)."""
    rejected = rejections.REJECTED.snapshot()
    return {
        "service": settings.service, "uav": settings.uav_id, "pid": os.getpid(),
        "uptime_s": round(time.monotonic() - started, 3),
        "schema_version": wire.SCHEMA_VERSION,
        "rejected_total": sum(sum(c.values()) for c in rejected.values()),
        "rejected": rejected,
        "reasons": [r.value for r in rejections.Reason],
        "log_lines_suppressed": rejections.REJECTED.suppressed_total,
    }


def serve_status(session: zenoh.Session, settings: Settings, stop: threading.Event,
                 started: float) -> Callable[[], None]:
    """Answer ``keys.status(uav, service)`` from a thread of its own; returns the closer.

    The query's payload is ignored (whatever it is). The callback only
    enqueues; the thread replies.
    """
    key = keys.status(settings.uav_id, settings.service)
    inbox = Inbox(key, max_items=64, max_bytes=1024 * 1024)
    queryable = session.declare_queryable(key, inbox.on_query)
    done = threading.Event()

    def loop() -> None:
        while not (stop.is_set() or done.is_set()):
            item = inbox.get(timeout=0.2)
            if item is None or item.query is None:
                continue
            try:
                body = json.dumps(status(settings, started)).encode()
                item.query.reply(key, body, encoding=zenoh.Encoding(STATUS_ENCODING))
            except Exception:  # a status reply must never take the service down
                log.exception("status reply failed")
            finally:
                item.query.drop()

    thread = threading.Thread(target=loop, name=f"{settings.service}-status", daemon=True)
    thread.start()

    def close() -> None:
        done.set()
        thread.join(1.0)
        queryable.undeclare()

    return close


def query_status(session: zenoh.Session, uav: str, service: str,
                 timeout_s: float = 5.0, trusted: Trusted = None,
                 stop: threading.Event | None = None) -> dict[str, Any]:
    """Ask a service for its status (raises TimeoutError if it (``trusted``) does not answer)."""
    reply = first_reply(session, keys.status(uav, service), timeout_s, stop, trusted)
    if reply.ok is None:
        raise TimeoutError(f"no status from {service} within {timeout_s:.3g} s")
    doc: dict[str, Any] = json.loads(reply.ok.payload.to_bytes())
    return doc


# -- the service runner ---------------------------------------------------------------------------
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


def run_service(settings: Settings, body: Body, zenoh_session: bool = True) -> int:
    """Run ``body`` in a worker thread until it returns or SIGINT/SIGTERM arrives.

    The body must return soon after ``ctx.stop`` is set; if it has not
    finished :data:`STOP_GRACE_S` after a signal the process exits anyway.
    """
    logsetup.configure(settings.service, settings.uav_id, settings.log_level, settings.log_format)
    if settings.nice:
        os.nice(settings.nice)  # lowering one's own priority needs no privilege
    # A thread woken by I/O (a Zenoh reply, a MAVLink frame) waits for the GIL up to the
    # switch interval while another thread runs Python: 5 ms by default, the whole latency
    # budget of a tick. Services are I/O-bound around their one compute thread.
    sys.setswitchinterval(SWITCH_INTERVAL_S)
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
                    mode=("client" if settings.tls_dir and settings.zenoh_mode != "router"
                          else settings.zenoh_mode),
                    connect=",".join(settings.zenoh_connect), tls=settings.tls_dir,
                    zid=str(session.info.zid())))
                close_status = serve_status(session, settings, stop, started)
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
        rejections=rejections.REJECTED.total()))
    logging.shutdown()
    sys.stdout.flush()
    sys.stderr.flush()
    if thread.is_alive():
        os._exit(code)
    return code
