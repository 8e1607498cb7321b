"""Queries: the first reply from the session that holds a service's token, and a stop that
ends every query waiting on it.

Trust only the token holder (ARCHITECTURE §4): with ``trusted`` a reply counts
only from that session (its Zenoh id); one from another session is logged and
counted (reason ``untrusted``) and the wait goes on.
"""

from __future__ import annotations

import logging
import threading
from typing import Any

import zenoh
from google.protobuf.message import Message

from services.common import rejections, wire
from services.common.bus.inbox import encoding
from services.common.traffic import TRAFFIC
from services.msgs import common_pb2

log = logging.getLogger("services.common.bus")


class EndedWithoutReply(TimeoutError):
    """The query ended without any reply before its timeout: no queryable matched it, or the
    one that had it went away (Zenoh finalises the queries of a closed session)."""


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
        TRAFFIC.sent(key, "query", len(get.get("payload", b"") or b""))
        untrusted = 0
        while True:
            try:
                reply: zenoh.Reply = replies.recv()
            except zenoh.ZError:  # the channel closed without a reply: cancelled, or none came
                if stop is not None and stop.is_set():
                    raise TimeoutError(f"stopped on {key} within {timeout_s:.3g} s") from None
                why = "no reply"
                if untrusted:
                    why = f"no reply from the token holder ({untrusted} from others)"
                raise EndedWithoutReply(f"{why} on {key} within {timeout_s:.3g} s") from None
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
    sample = reply.ok if reply.ok is not None else reply.err
    TRAFFIC.received(key, "reply", 0 if sample is None else len(sample.payload.to_bytes()))
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
    within ``timeout_s`` (or on stop; :class:`EndedWithoutReply` when the query
    ended without any reply) and QueryError for an error reply.
    """
    payload, enc, _ = request_from(session, key, msg, timeout_s, stop, trusted, count_key)
    return payload, enc


def request_from(session: zenoh.Session, key: str, msg: Message, timeout_s: float,
                 stop: threading.Event | None = None, trusted: Trusted = None,
                 count_key: str = "") -> tuple[bytes, str, str]:
    """:func:`request`, with the Zenoh id of the session that replied."""
    item = first_reply(session, key, timeout_s, stop, trusted, count_key,
                       payload=msg.SerializeToString(), encoding=encoding(msg),
                       attachment=str(session.info.zid()).encode())
    if item.ok is not None:
        return item.ok.payload.to_bytes(), str(item.ok.encoding), replier(item)
    assert item.err is not None  # a reply is either ok or an error
    err_bytes = item.err.payload.to_bytes()
    try:
        err = wire.parse(err_bytes, common_pb2.Error)
    except rejections.CodecError as bad:
        rejections.rejected("Error", bad, log, key=key)  # an error reply we cannot read
        raise QueryError(0, err_bytes[:500].decode("utf-8", "replace")) from None
    raise QueryError(err.code, err.message)
