"""Zenoh plumbing shared by the services, one concern a module.

``config`` (the session's configuration, TLS), ``inbox`` (publishing, bounded
inboxes fed by callbacks, replies), ``query`` (trusted first replies, a stop that
ends queries), ``liveliness`` (who is alive, who holds each token), ``status``
(every service's status queryable) and ``service`` (the runner every service's
``main`` uses). The names below are the services' one import: ``from
services.common import bus``.

Bad input: every service counts the inputs it rejects per key and reason
(:data:`services.common.rejections.REJECTED`) and serves them on
``<ns>/status/<service>``, with no code of its own.
"""

from services.common.bus.config import tls_config, tls_endpoints, zenoh_config
from services.common.bus.inbox import (
    INBOX_MAX_BYTES,
    INBOX_MAX_ITEMS,
    Inbox,
    Received,
    accept,
    encoding,
    put,
    reply,
    reply_error,
)
from services.common.bus.liveliness import Liveliness
from services.common.bus.query import (
    UNTRUSTED,
    EndedWithoutReply,
    QueryError,
    Stop,
    Trusted,
    first_reply,
    replier,
    request,
    request_from,
)
from services.common.bus.service import (
    STOP_GRACE_S,
    SWITCH_INTERVAL_S,
    Body,
    Context,
    leave,
    run_service,
    settle_heap,
)
from services.common.bus.status import STATUS_ENCODING, query_status, serve_status, status

__all__ = [
    "INBOX_MAX_BYTES", "INBOX_MAX_ITEMS", "STATUS_ENCODING", "STOP_GRACE_S", "SWITCH_INTERVAL_S",
    "UNTRUSTED", "Body", "Context", "EndedWithoutReply", "Inbox", "Liveliness", "QueryError",
    "Received", "Stop", "Trusted", "accept", "encoding", "first_reply", "leave", "put",
    "query_status", "replier", "reply", "reply_error", "request", "request_from", "run_service",
    "serve_status", "settle_heap", "status", "tls_config", "tls_endpoints", "zenoh_config",
]
