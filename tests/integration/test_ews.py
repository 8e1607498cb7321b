"""The EWS service: the fire process of the in-process mission, published on Zenoh."""

from __future__ import annotations

import queue
import time
from typing import Any

import numpy as np
import pytest

from dualpilot.mission.local import LocalFires
from dualpilot.model.fire_field import FireField
from dualpilot.spec import MissionSpec
from services.common import bus, keys, wire
from services.common.clock import Anchor
from services.common.convert import common as common_convert
from services.common.convert import fire as fire_convert
from services.msgs import common_pb2, fire_pb2

pytestmark = pytest.mark.timeout(90)


@pytest.fixture(scope="module")
def ews(services: Any, liveliness: bus.Liveliness) -> Any:
    services.start("ews")
    assert liveliness.wait_for(["ews"], 60), services.log("ews")[-2000:]
    return services


def command(session: Any, uav: str, mission: str, **kind: Any) -> fire_pb2.FireUpdate:
    cmd = fire_pb2.FireCommand(mission_id=mission)
    wire.Stamper("test", uav).stamp(cmd.header)
    if "seed" in kind:
        cmd.reset.seed = kind["seed"]
    else:
        cmd.advance.step, cmd.advance.substeps = kind["step"], kind["substeps"]
        if "anchor" in kind:
            common_convert.clock_to_msg(kind["anchor"], cmd.advance.clock)
    payload, enc = bus.request(session, keys.fire_command(uav), cmd, 30.0)
    return wire.parse(payload, fire_pb2.FireUpdate, enc)


def test_fires_match_the_in_process_fire_stream(ews: Any, session: Any) -> None:
    seed = 26
    published: queue.Queue[fire_pb2.FireState] = queue.Queue()
    sub = session.declare_subscriber(keys.fires(ews.uav), lambda s: published.put(
        fire_pb2.FireState.FromString(s.payload.to_bytes())))
    first = command(session, ews.uav, "m1", seed=seed)
    assert len(first.states) == 1 and not first.states[0].fronts
    # the in-process mission's fire stream: SeedSequence(seed).spawn(2)[0]
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[0])
    field = FireField()
    for t, n in enumerate([10, 1, 1, 10, 3, 10, 10]):
        update = command(session, ews.uav, "m1", step=t, substeps=n)
        assert len(update.states) == n
        for state in update.states:
            field.substep(rng, t)
            got = fire_convert.snapshot_from_msg(state)
            want = field.snapshot()
            assert got.regions == want.regions and got.front_ids == want.front_ids
            assert all(np.array_equal(a.vertices, b.vertices)
                       for a, b in zip(got.hulls, want.hulls, strict=True))
            assert state.step == t and state.substeps_done == field.substeps_done
    assert field.substeps_done == 45 and field.next_id > 0, "the seed should give some fires"
    seen: list[int] = []
    deadline = time.monotonic() + 10
    while len(seen) < 46 and time.monotonic() < deadline:
        try:
            seen.append(published.get(timeout=0.5).substeps_done)
        except queue.Empty:
            continue
    sub.undeclare()
    assert seen == list(range(46)), "every sub-step is published once, in order"


def test_publications_follow_the_clock(ews: Any, session: Any) -> None:
    """At speed factor 10, sub-step k of 0.5 s is due 0.05·k s after the anchor: none is
    published before it is due (lower bounds only: a loaded machine makes them later)."""
    command(session, ews.uav, "m2", seed=1)
    anchor = Anchor(sim_time_s=0.0, wall_ns=time.time_ns(), speed_factor=10.0)
    t0 = time.monotonic()
    update = command(session, ews.uav, "m2", step=0, substeps=6, anchor=anchor)
    wall = time.monotonic() - t0
    assert wall >= 0.3 - 0.01  # the last sub-step is due 0.3 s after the anchor (before t0)
    assert [s.substeps_done for s in update.states] == [1, 2, 3, 4, 5, 6]
    for k, state in enumerate(update.states, start=1):
        due_ns = anchor.wall_ns + round(k * 0.5 / 10.0 * 1e9)
        assert state.header.wall_time_ns >= due_ns - 1_000_000, (k, state.header.wall_time_ns
                                                                 - due_ns)
    assert 0.0 <= update.paced_wait_s <= wall


def test_forecast_is_published(ews: Any, session: Any) -> None:
    forecasts: queue.Queue[fire_pb2.FireForecast] = queue.Queue()
    sub = session.declare_subscriber(keys.forecast(ews.uav), lambda s: forecasts.put(
        fire_pb2.FireForecast.FromString(s.payload.to_bytes())))
    command(session, ews.uav, "m3", seed=26)
    command(session, ews.uav, "m3", step=0, substeps=10)
    last = None
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        try:
            last = forecasts.get(timeout=0.5)
        except queue.Empty:
            break
    sub.undeclare()
    assert last is not None and last.horizon_s == 80.0
    for front in last.fronts:
        assert len(front.regions) == 160 and len(front.envelope.vertices_m) >= 8
    # the occupancy grid is the in-process fire port's forecast, level for level
    grid = fire_convert.occupancy_from_msg(last)
    assert grid is not None and grid.shape == (100, 100) and grid.horizons[-1] == 80
    fires = LocalFires(MissionSpec(seed=26))
    fires.advance(0, 10, None)
    assert last.substeps_done == fires.field.substeps_done == grid.issued_substep
    local = fires.forecast(10)
    assert local is not None and np.array_equal(grid.levels, local.levels)


def test_bad_commands_get_error_replies(ews: Any, session: Any) -> None:
    with pytest.raises(bus.QueryError, match="send reset first") as info:
        command(session, ews.uav, "never-reset", step=0, substeps=1)
    assert info.value.code == common_pb2.ERROR_CODE_INVALID
    with pytest.raises(bus.QueryError, match="carries no reset, advance or forecast"):
        cmd = fire_pb2.FireCommand(mission_id="x")
        wire.Stamper("test", ews.uav).stamp(cmd.header)
        bus.request(session, keys.fire_command(ews.uav), cmd, 10.0)
    command(session, ews.uav, "m4", seed=2)  # still serving
