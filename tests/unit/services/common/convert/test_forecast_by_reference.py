"""A risk-aware plan request's forecast by reference: System 2 takes it from the EWS beside it.

The supervisor names the forecast (its fire revision and its grid's BLAKE2b-128 digest); the
planner asks the EWS for the answer it gave (services/ews/answers.py), checks the digest and
plans on it. The mission must be its in-process twin's step for step, as with the forecast
carried whole; a planner that cannot have the forecast refuses (counted, logged) and the
supervisor sends that request whole: never a plan on another forecast.
"""

from __future__ import annotations

import threading
from dataclasses import replace
from pathlib import Path

import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.model.risk import ForecastView
from services.common import rejections
from services.common.convert import fire as fire_convert
from services.common.convert import plan as plan_convert
from services.ews.answers import AnsweredForecasts
from services.msgs import fire_pb2, plan_pb2
from services.supervisor.ports import StackParams
from tests.support.stack import InProcessStack, in_process_ews, planner_services, rig
from tests.unit.services.common.convert.test_forecast_wire import forecast
from tests.unit.services.supervisor.test_session import assert_same_mission, twin

#: System 2 risk-aware for 12 steps: a forecast every step
CONFIG = MissionConfig.named("s2+risk", seed=26, settings=(("max_steps", 12),))


def grid() -> fire_pb2.OccupancyGrid:
    """A forecast's grid as the EWS sends it (20 × 30 cells, 5 slices)."""
    return fire_convert.wire_grid(forecast())


def test_by_reference_the_forecast_is_its_digest_a_few_bytes_instead_of_kilobytes() -> None:
    fc = forecast()
    view = ForecastView(fc, 10, 3)
    whole, ref = plan_pb2.PlanForecast(), plan_pb2.PlanForecast()
    plan_convert.forecast_to_msg(view, 7, whole)
    plan_convert.forecast_to_msg(view, 7, ref, by_reference=True)
    assert not ref.HasField("occupancy") and ref.digest == fire_convert.grid_digest(grid())
    assert (ref.step, ref.substeps_done, ref.substeps_per_step, ref.offset_substeps) == (
        7, 40, 10, 3)
    # 3000 random cells a slice do not compress: the whole grid is kilobytes, the name 30 B
    assert whole.ByteSize() > 3000 and ref.ByteSize() < 40
    wire = plan_pb2.PlanForecast.FromString(ref.SerializeToString())
    assert plan_convert.forecast_ref_from_msg(wire, 7).digest == ref.digest


def test_a_request_by_reference_carries_the_digest_not_the_grid() -> None:
    m = plan_pb2.PlanForecast(step=7, substeps_done=40, substep_s=0.5, substeps_per_step=10,
                              offset_substeps=3, digest=bytes(range(16)))
    ref = plan_convert.forecast_ref_from_msg(m, 7)
    assert ref == plan_convert.ForecastRef(7, 40, 0.5, 10, 3, bytes(range(16)))
    with pytest.raises(rejections.CodecError, match="digest of 16 bytes, got 3") as err:
        plan_convert.forecast_ref_from_msg(replace_digest(m, b"abc"), 7)
    assert err.value.reason is rejections.Reason.SIZE
    with pytest.raises(rejections.CodecError, match="made for step 7, the request is for step 8"):
        plan_convert.forecast_ref_from_msg(m, 8)
    bad_tf = plan_pb2.PlanForecast()
    bad_tf.CopyFrom(m)
    bad_tf.substep_s = 0.0
    with pytest.raises(rejections.CodecError, match="substep_s must be positive"):
        plan_convert.forecast_ref_from_msg(bad_tf, 7)


def replace_digest(m: plan_pb2.PlanForecast, digest: bytes) -> plan_pb2.PlanForecast:
    out = plan_pb2.PlanForecast()
    out.CopyFrom(m)
    out.digest = digest
    return out


def test_the_ews_gives_only_the_answer_of_that_revision_and_digest() -> None:
    answers = AnsweredForecasts(keep=2)
    update = fire_pb2.FireUpdate()
    update.forecast.substeps_done = 40
    update.forecast.substep_s = 0.5
    update.forecast.occupancy.CopyFrom(grid())
    digest = answers.put("m1", update)
    assert digest == fire_convert.grid_digest(grid()) and len(digest) == 16
    cmd = fire_convert.FireCommand("m1", "forecast", step=3, substeps=10, substeps_done=40,
                                   digest=digest)
    assert answers.get(cmd) == update.SerializeToString()
    for other in (replace(cmd, substeps_done=41), replace(cmd, mission_id="m2"),
                  replace(cmd, digest=bytes(16))):
        with pytest.raises(rejections.CodecError, match="is held here") as err:
            answers.get(other)
        assert err.value.reason is rejections.Reason.UNAVAILABLE


def test_a_grid_that_is_not_the_one_named_is_refused() -> None:
    forecast = fire_pb2.FireForecast(substeps_done=40, substep_s=0.5)
    forecast.occupancy.CopyFrom(grid())
    ref = plan_convert.ForecastRef(3, 40, 0.5, 10, 0, fire_convert.grid_digest(grid()))
    assert plan_convert.resolved_view(ref, forecast).substeps_per_step == 10
    with pytest.raises(rejections.CodecError, match="digest differs"):
        plan_convert.resolved_view(replace(ref, digest=bytes(16)), forecast)
    with pytest.raises(rejections.CodecError, match="answered revision 40 .* for revision 39"):
        plan_convert.resolved_view(replace(ref, substeps_done=39), forecast)


def test_system2_plans_on_the_forecast_it_takes_from_the_ews(tmp_path: Path) -> None:
    r = rig(CONFIG, tmp_path)  # the default: System 2's forecast by reference
    result = r.session.run()
    r.session.close()
    assert_same_mission(result, twin(CONFIG))
    # every System 2 request named its forecast; the planner took each from the EWS once
    assert r.stack.fetched and set(r.stack.fetched) == {"ok"}
    assert r.session.planners is not None and r.session.planners.forecast_resends == 0


def test_a_planner_without_the_forecast_refuses_and_the_request_goes_whole(
        tmp_path: Path) -> None:
    stop = threading.Event()
    # an EWS that keeps no answer: every forecast by reference is unavailable
    stack = InProcessStack(in_process_ews(stop), planner_services(),
                           answers=AnsweredForecasts(keep=0))
    before = rejections.REJECTED.snapshot()
    r = rig(CONFIG, tmp_path, stack=stack)
    result = r.session.run()
    r.session.close()
    assert_same_mission(result, twin(CONFIG))  # the same plans: sent whole the second time
    assert r.session.planners is not None
    resends = r.session.planners.forecast_resends
    assert resends >= 1 and stack.fetched == ["unavailable"] * resends
    after = rejections.REJECTED.snapshot()
    key = "dualpilot/uav1/plan/system2"
    got = {k: v for k, v in after.items() if "plan/system2" in k}
    counted = sum(v.get("unavailable", 0) for v in got.values()) - sum(
        v.get("unavailable", 0) for k, v in before.items() if "plan/system2" in k)
    assert counted == resends, (key, got)


def test_the_old_path_stays_when_no_system_takes_it_by_reference(tmp_path: Path) -> None:
    params = StackParams(forecast_by_reference=frozenset())
    r = rig(CONFIG, tmp_path, params=params)
    result = r.session.run()
    r.session.close()
    assert_same_mission(result, twin(CONFIG))
    assert r.stack.fetched == []  # the forecast travelled whole in every request
