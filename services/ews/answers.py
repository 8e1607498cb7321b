"""The forecasts the EWS answered its supervisor, kept for the planners: ``ews/forecasts``.

A risk-aware plan request names its forecast by reference (services/common/convert/plan.py:
the fire revision and the grid's digest) instead of carrying it; the planner asks the EWS on
its own side of the link for that answer (:func:`serve`, a queryable on a thread of its
own: the EWS's loop may be pacing an advance). Only answers already given are served, byte
for byte as the supervisor got them: nothing is computed here, and the fire process is not
touched, so any session may ask. A digest the EWS does not hold (evicted, another mission, a
restarted EWS) is answered with ``ERROR_CODE_UNAVAILABLE``: the supervisor then sends that
request's forecast whole.
"""

from __future__ import annotations

import logging
import threading
from collections import OrderedDict
from collections.abc import Callable

import zenoh

from services.common import bus, keys, rejections, wire
from services.common.convert import common as common_convert
from services.common.convert import fire as fire_convert
from services.common.traffic import TRAFFIC
from services.msgs import common_pb2, fire_pb2

log = logging.getLogger("services.ews")

#: answers kept per EWS process (a concurrent supervisor's pending System 2 request names a
#: forecast a few steps old; a fleet's vehicles share the EWS)
KEEP = 64


class AnsweredForecasts:
    """The latest :data:`KEEP` forecast answers, by (mission id, revision, grid digest);
    thread-safe."""

    def __init__(self, keep: int = KEEP):
        self.keep = keep
        self._lock = threading.Lock()
        self._answers: OrderedDict[tuple[str, int, bytes], bytes] = OrderedDict()

    def put(self, mission_id: str, update: fire_pb2.FireUpdate) -> bytes:
        """Keep ``update`` (a forecast answer, as sent); its grid's digest."""
        digest = fire_convert.grid_digest(update.forecast.occupancy)
        key = (mission_id, int(update.forecast.substeps_done), digest)  # an empty grid's
        with self._lock:  # digest is the same at every revision
            self._answers[key] = update.SerializeToString()
            self._answers.move_to_end(key)
            while len(self._answers) > self.keep:
                self._answers.popitem(last=False)
        return digest

    def get(self, cmd: fire_convert.FireCommand) -> bytes:
        """The answer ``cmd`` (a forecast query with its digest) names, serialized; raises
        CodecError (UNAVAILABLE) when it is not held, or is of another revision."""
        if not cmd.digest:
            raise rejections.invalid("a forecast by reference needs its digest")
        with self._lock:
            held = self._answers.get((cmd.mission_id, cmd.substeps_done, cmd.digest))
        if held is None:
            raise rejections.CodecError(
                common_pb2.ERROR_CODE_UNAVAILABLE,
                f"no forecast of mission {cmd.mission_id!r} from revision {cmd.substeps_done} "
                f"with digest {cmd.digest.hex()[:12]}… is held here", rejections.Reason.UNAVAILABLE)
        return held


def answer(answers: AnsweredForecasts, payload: bytes, encoding: str,
           stamper: wire.Stamper) -> tuple[bytes, str] | common_pb2.Error:
    """One ``ews/forecasts`` query: the answer's bytes and encoding, or an Error."""
    try:
        cmd = fire_convert.fire_command_from_msg(wire.parse(payload, fire_pb2.FireCommand,
                                                            encoding))
        if cmd.kind != "forecast":
            raise rejections.invalid(f"ews/forecasts answers forecast queries, not {cmd.kind}")
        return answers.get(cmd), wire.encoding_name(fire_pb2.FireUpdate)
    except rejections.CodecError as err:
        rejections.rejected("FireCommand", err, log, key=keys.forecasts(stamper.vehicle_id))
        return common_convert.error_msg(stamper, err.code, str(err))


def serve(session: zenoh.Session, uav: str, answers: AnsweredForecasts,
          stop: threading.Event) -> Callable[[], None]:
    """Answer ``keys.forecasts(uav)`` from a thread of its own; returns the closer."""
    stamper = wire.Stamper("ews", uav)
    key = keys.forecasts(uav)
    inbox = bus.Inbox(key, max_items=256)
    queryable = session.declare_queryable(key, inbox.on_query)
    done = threading.Event()
    encoding = bus.encoding(fire_pb2.FireUpdate)

    def loop() -> None:
        while not (stop.is_set() or done.is_set()):
            item = inbox.get(timeout=0.2)
            if item is None or item.query is None:
                continue
            out = answer(answers, item.payload, item.encoding, stamper)
            if isinstance(out, common_pb2.Error):
                bus.reply_error(item.query, out)
                continue
            try:
                item.query.reply(item.query.key_expr, out[0], encoding=encoding)
                TRAFFIC.sent(key, "reply", len(out[0]))
            finally:
                item.query.drop()

    thread = threading.Thread(target=loop, name="ews-forecasts", daemon=True)
    thread.start()

    def close() -> None:
        done.set()
        thread.join(1.0)
        queryable.undeclare()

    return close
