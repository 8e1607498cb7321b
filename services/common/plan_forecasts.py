"""A planner's forecasts by reference: the grid a plan request names, from the EWS nearby.

A risk-aware plan request may carry its forecast whole or name it (services/common/convert/
plan.py, :class:`~services.common.convert.plan.ForecastRef`: the fire revision and the grid's
digest). A named one is asked of the EWS (``ews/forecasts``: the answers it already gave the
supervisor; services/ews/answers.py) through a :class:`ForecastSource`, checked against the
digest and kept (:class:`ResolvedForecasts`), so the requests of one forecast ask once. A
forecast that cannot be had (no EWS, late, evicted, a digest that does not match) is an
``ERROR_CODE_UNAVAILABLE`` error: the supervisor then sends that request's forecast whole.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import replace
from typing import Protocol

import zenoh

from dualpilot.model.risk import ForecastView
from services.common import bus, keys, rejections, wire
from services.common.convert import fire as fire_convert
from services.common.convert import plan as plan_convert
from services.msgs import common_pb2, fire_pb2

#: how long a planner waits for the EWS's answer (wall s), at most; and at most this share
#: of the request's deadline
FETCH_TIMEOUT_S = 1.0
FETCH_SHARE = 0.25


class ForecastSource(Protocol):
    """Where a planner gets the EWS's forecast answers."""

    def fetch(self, mission_id: str, ref: plan_convert.ForecastRef,
              timeout_s: float) -> fire_pb2.FireForecast:
        """The answer ``ref`` names; raises TimeoutError, :class:`bus.QueryError` or
        CodecError."""
        ...


class ZenohForecasts:
    """The EWS's ``ews/forecasts`` queryable over the planner's session; with ``live``, only
    the reply of the session holding the EWS's token counts (and the digest is checked
    whoever answers)."""

    def __init__(self, session: zenoh.Session, uav: str, stop: threading.Event | None = None,
                 live: bus.Liveliness | None = None):
        self.session, self.uav, self.stop, self.live = session, uav, stop, live
        self.stamper = wire.Stamper("planner", uav)

    def fetch(self, mission_id: str, ref: plan_convert.ForecastRef,
              timeout_s: float) -> fire_pb2.FireForecast:
        msg = fire_convert.fire_forecast_query_msg(mission_id, ref.step, ref.substeps_done,
                                                   ref.substeps_per_step, self.stamper, 0.0,
                                                   digest=ref.digest)
        trusted = None if self.live is None else self.live.holder("ews")
        payload, enc = bus.request(self.session, keys.forecasts(self.uav), msg, timeout_s,
                                   self.stop, trusted=trusted)
        update = wire.parse(payload, fire_pb2.FireUpdate, enc)
        if not update.HasField("forecast"):
            raise rejections.invalid("the EWS answered without a forecast")
        return update.forecast


def unavailable(message: str) -> rejections.CodecError:
    return rejections.CodecError(common_pb2.ERROR_CODE_UNAVAILABLE, message,
                                 rejections.Reason.UNAVAILABLE)


class ResolvedForecasts:
    """The forecasts named by reference this planner resolved, by (mission, revision,
    digest)."""

    def __init__(self, source: ForecastSource | None, keep: int = 8):
        self.source = source
        self.keep = keep
        self._held: OrderedDict[tuple[str, int, bytes], ForecastView] = OrderedDict()

    def resolve(self, query: plan_convert.PlanQuery) -> plan_convert.PlanQuery:
        """``query`` with its named forecast in its request (as if it had come whole); a query
        without one as it is. Raises CodecError (UNAVAILABLE) when it cannot be had."""
        ref = query.forecast_ref
        if ref is None:
            return query
        key = (query.mission_id, ref.substeps_done, ref.digest)  # an empty grid's digest
        # is the same at every revision: the revision is part of the name
        held = self._held.get(key)
        if held is None:
            held = self._fetch(query, ref)
            self._held[key] = held
            while len(self._held) > self.keep:
                self._held.popitem(last=False)
        view = ForecastView(held.forecast, ref.substeps_per_step, ref.offset_substeps)
        return replace(query, request=replace(query.request, forecast=view), forecast_ref=None)

    def _fetch(self, query: plan_convert.PlanQuery,
               ref: plan_convert.ForecastRef) -> ForecastView:
        if self.source is None:
            raise unavailable("this planner has no EWS to take a forecast by reference from")
        timeout = min(FETCH_TIMEOUT_S, FETCH_SHARE * query.deadline_s)
        try:
            answer = self.source.fetch(query.mission_id, ref, timeout)
            return plan_convert.resolved_view(ref, answer)
        except TimeoutError as err:
            raise unavailable(f"the EWS did not give the forecast in time: {err}") from err
        except bus.QueryError as err:
            raise unavailable(f"the EWS has no such forecast: {err}") from err
        except rejections.CodecError as err:
            raise unavailable(f"the EWS's forecast is not the one named: {err}") from err
