"""A side channel of the simulated vehicle: one Zenoh queryable, answered from its loop.

uavsim's side channels (the mission configuration, services/uavsim/missionconfig.py; the
plant's ground truth, services/uavsim/truth.py) are queryables on the vehicle's keys. The
Zenoh callback only enqueues into a bounded inbox (ARCHITECTURE §4); the vehicle's loop
answers between two passes (:meth:`SideChannel.poll`), so an answer never sees half a step.
What a query gets is its channel's ``answer`` (a reply message), or the error reply of the
:class:`~services.common.rejections.CodecError` it raised: a bad request is counted and
logged per key and reason, an ``ERROR_CODE_UNAVAILABLE`` one (what the vehicle cannot give
yet) is not, as it is no bad request.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

import zenoh
from google.protobuf.message import Message

from services.common import bus, rejections, wire
from services.common.convert import common as common_convert
from services.msgs import common_pb2

log = logging.getLogger("services.uavsim")

#: The reply to one query (raises CodecError for a query it refuses).
Answer = Callable[[bus.Received], Message]


class SideChannel:
    """The queryable ``key`` of one vehicle: a bounded inbox, answered by :meth:`poll`.

    ``what`` names the request in the rejection counters and log lines (the message kind);
    errors are stamped by ``stamper``; the inbox holds at most ``max_items`` queries and
    ``max_bytes`` of payload (the rest: ``overflow`` rejections).
    """

    def __init__(self, session: zenoh.Session, key: str, answer: Answer, what: str,
                 stamper: wire.Stamper, max_items: int, max_bytes: int):
        self.key = key
        self.answer = answer
        self.what = what
        self.stamper = stamper
        self.inbox = bus.Inbox(key, max_items=max_items, max_bytes=max_bytes)
        self.queryable = session.declare_queryable(key, self.inbox.on_query)

    def poll(self, _now: float = 0.0) -> None:
        """Answer what arrived (the vehicle loop's tick, between two passes)."""
        while (item := self.inbox.get(timeout=0)) is not None:
            if item.query is None:
                continue
            try:
                reply = self.answer(item)
            except rejections.CodecError as err:
                if err.code != common_pb2.ERROR_CODE_UNAVAILABLE:  # a bad request, counted
                    rejections.rejected(self.what, err, log, key=self.key)
                bus.reply_error(item.query, common_convert.error_msg(self.stamper, err.code,
                                                                     str(err)))
                continue
            bus.reply(item.query, reply)

    def close(self) -> None:
        self.queryable.undeclare()
