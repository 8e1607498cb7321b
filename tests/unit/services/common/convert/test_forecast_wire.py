"""The fire forecast on the wire (services/common/convert/fire.py, plan.py): a PlanForecast
carries the grid byte for byte, zlib-compressed, and the decoders refuse what does not fit."""

from __future__ import annotations

import zlib

import numpy as np
import pytest

from dualpilot.model.forecast import OccupancyForecast
from dualpilot.model.risk import ForecastView
from services.common import rejections
from services.common.convert import fire as fire_convert
from services.common.convert import plan as plan_convert
from services.common.limits import MAX_SUBSTEPS
from services.msgs import fire_pb2, plan_pb2


def forecast(rows: int = 20, cols: int = 30, slices: int = 5, seed: int = 1) -> OccupancyForecast:
    levels = np.random.default_rng(seed).integers(0, 256, (slices, rows, cols), dtype=np.uint8)
    return OccupancyForecast(resolution_m=10.0, substep_s=0.5,
                             horizons=tuple(range(0, 2 * slices, 2)), levels=levels,
                             origin_m=(5.0, -10.0), issued_substep=40, substeps_per_step=10)


def wire_form(view: ForecastView, step: int = 7) -> plan_pb2.PlanForecast:
    out = plan_pb2.PlanForecast()
    plan_convert.forecast_to_msg(view, step, out)
    return plan_pb2.PlanForecast.FromString(out.SerializeToString())


def test_a_forecast_crosses_byte_for_byte() -> None:
    fc = forecast()
    got = plan_convert.forecast_from_msg(wire_form(ForecastView(fc, 10, 3)), 7)
    assert (got.substeps_per_step, got.offset_substeps) == (10, 3)
    g = got.forecast
    assert g.horizons == fc.horizons and g.issued_substep == 40 and g.substep_s == 0.5
    assert g.origin_m == (5.0, -10.0) and g.resolution_m == 10.0 and g.shape == fc.shape
    for a, b in zip(g.layers, fc.layers, strict=True):
        assert np.array_equal(a, b)


def test_slices_are_compressed_and_encoded_once() -> None:
    fc = forecast()
    fc_zero = OccupancyForecast(10.0, 0.5, (0, 2), np.zeros((2, 100, 100), dtype=np.uint8))
    m = wire_form(ForecastView(fc_zero, 1))
    assert m.occupancy.encoding == fire_pb2.SLICE_ENCODING_ZLIB
    assert sum(len(p) for p in m.occupancy.probabilities) < 200  # 20000 zero bytes
    view = ForecastView(fc, 10)
    first = fire_convert.wire_grid(fc)
    wire_form(view)
    assert fire_convert.wire_grid(fc) is first  # the memo: one encoding a forecast


def test_a_raw_grid_is_read_as_well() -> None:
    fc = forecast()
    grid = fire_convert.occupancy_to_msg(fc, fire_pb2.OccupancyGrid(), compress=False)
    assert grid.encoding == fire_pb2.SLICE_ENCODING_RAW
    got = fire_convert.grid_from_msg(grid, 0.5, 40)
    assert all(np.array_equal(a, b) for a, b in zip(got.layers, fc.layers, strict=True))


def refused(m: plan_pb2.PlanForecast, step: int = 7) -> rejections.CodecError:
    with pytest.raises(rejections.CodecError) as info:
        plan_convert.forecast_from_msg(m, step)
    return info.value


def test_a_slice_that_inflates_past_its_grid_is_refused() -> None:
    """A zlib bomb: 600 cells of grid, a slice that inflates to 10 MB."""
    m = wire_form(ForecastView(forecast(), 10))
    m.occupancy.probabilities[0] = zlib.compress(bytes(10_000_000), 9)
    err = refused(m)
    assert err.reason is rejections.Reason.SIZE and "slice 0" in str(err)


@pytest.mark.parametrize(("mutate", "reason", "match"), [
    (lambda m: m.occupancy.probabilities.__setitem__(1, b"not zlib"), "invalid",
     "not zlib data"),
    (lambda m: m.occupancy.probabilities.__setitem__(2, zlib.compress(bytes(599))), "size",
     "599 bytes"),
    (lambda m: m.occupancy.probabilities.__setitem__(
        2, zlib.compress(bytes(600)) + b"tail"), "size", "slice 2"),
    (lambda m: setattr(m, "step", 6), "stale", "made for step 6"),
    (lambda m: m.ClearField("occupancy"), "invalid", "without its occupancy grid"),
    (lambda m: setattr(m, "substeps_per_step", 0), "out_of_range", "substeps_per_step"),
    (lambda m: setattr(m, "offset_substeps", MAX_SUBSTEPS + 1), "out_of_range",
     "offset_substeps"),
    (lambda m: m.occupancy.horizons.__setitem__(1, 0), "out_of_range", "must increase"),
    (lambda m: setattr(m, "substep_s", float("nan")), "not_finite", "substep_s"),
])
def test_a_bad_plan_forecast_is_refused_with_its_reason(mutate, reason: str,  # type: ignore[no-untyped-def]
                                                        match: str) -> None:
    m = wire_form(ForecastView(forecast(), 10))
    mutate(m)
    err = refused(m)
    assert err.reason == reason and match in str(err), (err.reason, str(err))


def test_windows_past_the_horizon_are_a_plan_with_no_zones() -> None:
    """As in-process: a later System 2 start (the concurrent supervisor's offset) may lie
    past the forecast's last slice; the view then has no step inside it."""
    fc = forecast()  # horizons 0..8
    got = plan_convert.forecast_from_msg(wire_form(ForecastView(fc, 10, 50)), 7)
    assert got.offset_substeps == 50 and got.last_step == ForecastView(fc, 10, 50).last_step
    assert got.last_step == -1
