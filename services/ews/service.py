"""The EWS's loop: FireCommands on ``<ns>/ews/command`` answered by one vehicle's fire process;
the forecasts it answered kept for the planners on ``<ns>/ews/forecasts`` (services/ews/answers.py).

The fire process belongs to the supervisor session that reset it
(:class:`Binding`); a bad command gets an error reply (dualpilot.v1.Error),
counted per key and reason, never a crash.
"""

from __future__ import annotations

import logging

from services.common import bus, keys, rejections, wire
from services.common.convert import common as common_convert
from services.common.convert import fire as fire_convert
from services.common.log import fields
from services.msgs import common_pb2, fire_pb2

from .answers import AnsweredForecasts, serve
from .fireprocess import Ews
from .warm import Warmer

log = logging.getLogger("services.ews")


class Binding:
    """The fire process belongs to the session that reset it (the query's stated session id).

    While that session holds the vehicle's ``alive/supervisor`` token, commands
    from any other session are refused (a second supervisor, a replayed or
    rogue command); once it is gone, a reset from another session takes the
    fire process over (a restarted supervisor resuming the mission).
    """

    def __init__(self, live: bus.Liveliness):
        self.live = live
        self.session = ""
        self.mission_id = ""

    def check(self, cmd: fire_convert.FireCommand, who: str) -> None:
        """Raise CodecError when ``who`` may not send ``cmd``; a reset binds."""
        bound = self.session
        if bound and who != bound and bound in self.live.holders.get("supervisor", []):
            raise rejections.invalid(f"fire process of mission {self.mission_id!r} is bound to "
                                     f"supervisor session {bound}; {cmd.kind} from {who or '?'} "
                                     f"refused")
        if cmd.kind == "reset":
            if bound and who != bound:
                log.warning("fire process taken over", extra=fields(
                    mission=cmd.mission_id, previous=bound, session=who))
            self.session, self.mission_id = who, cmd.mission_id


def body(ctx: bus.Context, forecast_horizon_s: float, warmer: Warmer | None = None) -> None:
    """Serve vehicle ``ctx.settings.uav_id``'s fire process until stopped."""
    assert ctx.session is not None
    uav = ctx.settings.uav_id
    ews = Ews(ctx.session, uav, forecast_horizon_s, ctx.stop, warmer)
    key = keys.fire_command(uav)
    inbox = bus.Inbox(key)
    queryable = ctx.session.declare_queryable(key, inbox.on_query)
    binding = Binding(bus.Liveliness(ctx.session, uav))
    answers = AnsweredForecasts()  # the planners' forecasts by reference (ews/forecasts)
    close_answers = serve(ctx.session, uav, answers, ctx.stop)
    ctx.announce()
    while not ctx.stop.is_set():
        item = inbox.get(timeout=0.2)
        if item is None or item.query is None:
            continue
        try:
            cmd = fire_convert.fire_command_from_msg(
                wire.parse(item.payload, fire_pb2.FireCommand, item.encoding))
            binding.check(cmd, item.attachment.decode("ascii", "replace"))
            update = ews.handle(cmd)
            # Before the reply: once answered, the supervisor starts its next step at once,
            # and a forecast computed then would take the CPU its plan request needs.
            if cmd.kind != "forecast":
                ews.publish_forecast()
            if cmd.kind == "forecast":  # kept before the reply: a plan request may name it
                answers.put(cmd.mission_id, update)
            bus.reply(item.query, update)
            if cmd.kind == "forecast":  # after the reply: the plan request goes first
                ews.publish_answer(update.forecast)
        except rejections.CodecError as err:
            rejections.rejected("FireCommand", err, log, key=key)
            bus.reply_error(item.query, common_convert.error_msg(ews.stamper, err.code, str(err)))
        except Exception as err:  # a bug must not take the fire process down with it
            log.exception("fire command failed")
            bus.reply_error(item.query, common_convert.error_msg(
                ews.stamper, common_pb2.ERROR_CODE_INTERNAL, f"{type(err).__name__}: {err}"))
    queryable.undeclare()
    close_answers()
