"""Publishing, and what Zenoh callbacks hand over: bounded inboxes, replies to queries.

Zenoh callbacks only enqueue (ARCHITECTURE §4): :class:`Inbox` takes samples
and queries out of them; the service's own thread decodes (:func:`accept`) and
replies (:func:`reply`, :func:`reply_error`).
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

import zenoh
from google.protobuf.message import Message

from services.common import rejections, wire
from services.common.traffic import TRAFFIC

log = logging.getLogger("services.common.bus")

#: An inbox holds at most this many items and bytes; what arrives beyond is dropped and
#: counted (reason ``overflow``): a flood costs bounded memory.
INBOX_MAX_ITEMS = 1000


INBOX_MAX_BYTES = 64 * 1024 * 1024


T = TypeVar("T")


M = TypeVar("M", bound=Message)


def encoding(msg: Message | type[Message]) -> zenoh.Encoding:
    return zenoh.Encoding.APPLICATION_PROTOBUF.with_schema(wire.full_name(msg))


def put(target: zenoh.Session | zenoh.Publisher, key: str, msg: Message) -> None:
    """Publish a protobuf message (``key`` is ignored for a Publisher)."""
    payload = msg.SerializeToString()
    if isinstance(target, zenoh.Publisher):
        target.put(payload, encoding=encoding(msg))
        TRAFFIC.sent(str(target.key_expr), "put", len(payload))
    else:
        target.put(key, payload, encoding=encoding(msg))
        TRAFFIC.sent(key, "put", len(payload))


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
        payload = sample.payload.to_bytes()
        TRAFFIC.received(str(sample.key_expr), "put", len(payload))
        self._push(Received(str(sample.key_expr), payload, str(sample.encoding), None,
                            time.perf_counter_ns()))

    def on_query(self, query: zenoh.Query) -> None:
        payload = query.payload.to_bytes() if query.payload is not None else b""
        enc = str(query.encoding) if query.encoding is not None else ""
        att = query.attachment.to_bytes()[:64] if query.attachment is not None else b""
        TRAFFIC.received(str(query.key_expr), "query", len(payload))
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
    payload = msg.SerializeToString()
    try:
        query.reply(query.key_expr, payload, encoding=encoding(msg))
        TRAFFIC.sent(str(query.key_expr), "reply", len(payload))
    finally:
        query.drop()


def reply_error(query: zenoh.Query, err: Message) -> None:
    payload = err.SerializeToString()
    try:
        query.reply_err(payload, encoding=encoding(err))
        TRAFFIC.sent(str(query.key_expr), "reply", len(payload))
    finally:
        query.drop()
