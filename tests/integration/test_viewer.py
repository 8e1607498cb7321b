"""The viewer service on a real router: two vehicles' messages, as the stack publishes them, come
out of its Foxglove WebSocket server to a real client (websockets, foxglove.websocket.v1), and
onto its web page in a real browser (Debian's chromium), side by side."""

from __future__ import annotations

import asyncio
import math
from typing import Any

import numpy as np
import pytest

from dualpilot.mission.answers import parse_answers
from dualpilot.mission.result import StepRecord
from dualpilot.model.fire import FireFront, FireSnapshot
from dualpilot.model.forecast import OccupancyForecast
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.model.risk import RiskNote
from dualpilot.plan import Objective
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.paper.decision import Decision
from services.common import bus, keys, wire
from services.common.convert import fire as fire_convert
from services.common.convert import supervisor as supervisor_convert
from services.common.convert import vehicle as vehicle_convert
from services.launch import free_port
from services.msgs import fire_pb2, supervisor_pb2, vehicle_pb2

from .foxglove_check import FoxgloveClient, meta, points, rect_corners

pytestmark = pytest.mark.timeout(120)

VEHICLES = ("alpha", "bravo")
TOPICS = ("tf", "area", "fires", "forecast", "risk", "plan/system1", "plan/system2", "path",
          "uav", "decision", "events")
SCHEMAS = {"tf": "foxglove.FrameTransform", "forecast": "foxglove.Grid",
           "decision": "dualpilot.Decision", "events": "foxglove.Log"}
HULL = Polytope.from_vertices(np.array([[380.0, 580.0], [430.0, 580.0], [420.0, 640.0]]))
DECISION = Decision(t=3, d_t=math.inf, xi=np.array([1.25, 2.5, 4.0]),
                    p=np.array([0.125, 0.375, 0.5]), attention=3, psi=np.array([0.4, 0.6]),
                    system=2, objective=Objective.ENERGY)
PLAN = np.array([[100.0, 110.0], [115.0, 125.0], [130.0, 140.0]])
#: the risk zone the flown plan was made against (the forecast's cells above α = 0.1)
ZONE = Rect(300.0, 300.0, 20.0, 10.0).polytope()


def publish_round(session: Any, uav: str, k: int) -> dict[str, int]:
    """One step of ``uav`` as the supervisor and the EWS publish it; the wall stamps by kind."""
    st = wire.Stamper("supervisor", uav)
    snap = FireSnapshot(regions=(Rect(400 + k, 600, 40, 30),), hulls=(HULL,), front_ids=(9,),
                        born_steps=(1,))
    record = StepRecord(t=3, state=np.array([100.0, 110.0, 15.0, 15.0]),
                        control=np.zeros(2), decision=DECISION, system=1,
                        answers=parse_answers("s2:timeout;s1:ok"), planned_positions=PLAN,
                        planning_time_s=5.0,
                        fire_substeps=10, d_t=math.inf, fires_active=1, snapshot=snap,
                        time_s=18.0, risk=RiskNote(None, (ZONE,), 0.1))
    msgs: dict[str, Any] = {
        "mission/event": supervisor_pb2.MissionEvent(
            kind=supervisor_pb2.MISSION_EVENT_KIND_STARTED, mission_id=f"m-{uav}",
            controller="cc", seed=5, message="timing=paper"),
        "supervisor/decision": supervisor_convert.decision_to_msg(DECISION, 2, st, 18.0),
        "supervisor/plans": supervisor_convert.step_plans_msg(record, f"m-{uav}",
                                                              MissionSpec(seed=5), st, 18.0),
        "vehicle/state": vehicle_convert.state_to_msg(np.array([115.0 + k, 125.0, 15.0, 15.0]), 4,
                                                     vehicle_pb2.VehicleState()),
        "ews/fires": fire_convert.fire_state_msg(
            [FireFront(9, 1, 2.0, 0.5, snap.regions[0], HULL)], [], 3, 40, 0.5,
            wire.Stamper("ews", uav), 20.0),
    }
    st.stamp(msgs["mission/event"].header, 0.0)
    st.stamp(msgs["vehicle/state"].header, 19.0)
    fc = fire_pb2.FireForecast(substeps_done=40, substep_s=0.5)
    wire.Stamper("ews", uav).stamp(fc.header, 20.0)
    levels = np.arange(2 * 2 * 3, dtype=np.uint8).reshape(2, 2, 3)  # horizons 0, 4 on 2 x 3
    fire_convert.occupancy_to_msg(OccupancyForecast(10.0, 0.5, (0, 4), levels, (0.0, 0.0)),
                                    fc.occupancy)
    msgs["ews/forecast"] = fc
    for kind, m in msgs.items():
        bus.put(session, f"{keys.ns(uav)}/{kind}", m)
    return {kind: int(m.header.wall_time_ns) for kind, m in msgs.items()}


def test_viewer_serves_every_vehicle_over_the_foxglove_protocol(
        services: Any, session: Any, liveliness: bus.Liveliness) -> None:
    port, web_port = free_port("tcp"), free_port("tcp")
    services.start("viewer", "--listen", f"tcp/127.0.0.1:{port}", "--web-port", str(web_port))
    assert liveliness.wait_for(["viewer"], 60), services.log("viewer")
    wanted = {f"/{u}/{t}" for u in VEHICLES for t in TOPICS}

    async def scenario() -> tuple[FoxgloveClient, dict[str, dict[str, int]]]:
        async with FoxgloveClient(f"ws://127.0.0.1:{port}") as c:
            await c.pump(0.5)
            assert c.server_info.get("name") == "dualpilot", c.server_info
            for k, u in enumerate(VEHICLES):  # channels appear with each vehicle's first data
                publish_round(session, u, k)
                for _ in range(100):
                    await c.pump(0.1)
                    if {f"/{u}/{t}" for t in TOPICS} <= set(c.by_topic()):
                        break
            assert wanted <= set(c.by_topic()), sorted(c.by_topic())
            await c.subscribe(sorted(wanted))
            await c.pump(0.3)
            bus.put(session, keys.step_plans("alpha"), supervisor_pb2.Decision())  # wrong kind
            session.put(keys.fires("bravo"), b"\x08\xff\xff garbage")
            stamps = {u: publish_round(session, u, k) for k, u in enumerate(VEHICLES)}
            for _ in range(100):
                await c.pump(0.1)
                if all(c.received.get(t) for t in wanted):
                    break
            return c, stamps

    client, stamps = asyncio.run(scenario())
    missing = sorted(t for t in wanted if not client.received.get(t))
    assert not missing, (missing, services.log("viewer")[-3000:])
    channels = client.by_topic()
    for u in VEHICLES:
        for t in TOPICS:
            c = channels[f"/{u}/{t}"]
            assert c["schemaName"] == SCHEMAS.get(t, "foxglove.SceneUpdate"), (u, t)
            assert (c["encoding"], c["schemaEncoding"]) == (
                ("json", "jsonschema") if t == "decision" else ("protobuf", "protobuf"))

    for k, u in enumerate(VEHICLES):
        got = {t: client.received[f"/{u}/{t}"][-1] for t in TOPICS}
        t_ns, doc = got["decision"]
        assert doc == {"t": 3, "time_s": 18.0, "d_t_m": None, "xi": [1.25, 2.5, 4.0],
                       "p": [0.125, 0.375, 0.5], "attention": 3, "psi": [0.4, 0.6],
                       "system": 2, "commanded_system": 2, "flown_system": 1,
                       "objective": "energy"}
        # logged when the second of the step's Decision and StepPlans arrived
        assert t_ns in (stamps[u]["supervisor/decision"], stamps[u]["supervisor/plans"])
        (s1,), (s2,) = got["plan/system1"][1].entities, got["plan/system2"][1].entities
        assert meta(s1) == {"system": "1", "step": "3", "status": "ok", "flown": "true"}
        assert np.allclose(points(s1.lines[0]), PLAN)
        assert meta(s2) == {"system": "2", "step": "3", "status": "timeout", "flown": "false"}
        (front,) = got["fires"][1].entities
        assert (front.id, meta(front)) == ("front/9", {"front_id": "9", "born_step": "1"})
        assert np.allclose(points(front.lines[0]), rect_corners(400 + k, 600, 40, 30))
        assert np.allclose(points(front.lines[1]), HULL.vertices)
        assert got["fires"][0] == stamps[u]["ews/fires"]
        (uav,) = got["uav"][1].entities
        assert (uav.cubes[0].pose.position.x, uav.cubes[0].pose.position.y) == (115.0 + k,
                                                                               125.0)
        assert got["uav"][0] == stamps[u]["vehicle/state"]
        (zone,) = got["risk"][1].entities
        assert (zone.id, meta(zone)) == ("zone/0", {"step": "3", "alpha": "0.1"})
        assert np.allclose(points(zone.lines[0]), ZONE.vertices)
        grid = got["forecast"][1]
        assert [f.name for f in grid.fields] == ["p_0s", "p_2s"]  # horizon 4 x 0.5 s
        assert (grid.column_count, grid.cell_stride) == (3, 2)
        assert grid.data == bytes([0, 6, 1, 7, 2, 8, 3, 9, 4, 10, 5, 11])
        area = got["area"][1]
        assert np.allclose(points(area.entities[1].lines[0]),
                           rect_corners(900, 900, 100, 100))  # the goal of MissionSpec()
        assert client.received[f"/{u}/events"][-1][1].message == (
            "mission started: controller cc, seed 5; timing=paper")
    offsets = sorted(client.received[f"/{u}/tf"][-1][1].translation.x for u in VEHICLES)
    assert offsets == [0.0, 1100.0]  # side by side: area 1000 m + 100 m apart

    check_web_page(f"http://127.0.0.1:{web_port}/")
    status = bus.query_status(session, "itest", "viewer", 10.0)
    rejected = status["rejected"]
    assert rejected.get(keys.step_plans("alpha"), {}) == {"wrong_type": 1}, rejected
    assert sum(rejected.get(keys.fires("bravo"), {}).values()) == 1, rejected
    assert services.group.procs[-1].popen.poll() is None  # still serving


FLEET_JS = """() => {
  const doc = Bokeh.documents[0];
  const col = (name, key) => Array.from(doc.get_model_by_name(name).data[key] ?? []);
  return {uav: col('vehicles', 'uav'), x: col('vehicles', 'x'), y: col('vehicles', 'y'),
          flies: col('vehicles', 'flies'), fires: col('fires', 'xs').map(a => Array.from(a)),
          areas: col('area', 'xs').map(a => Array.from(a)), forecast: col('forecast', 'x'),
          plans: col('plans', 'system')};
}"""


def check_web_page(url: str) -> None:
    """Both vehicles on the page, each in its own area (the second 1100 m east): markers,
    fires, areas, forecasts and plans where the Foxglove view puts them; the fleet table's
    rows in the browser's DOM."""
    from tests.support.browser import chromium

    with chromium() as browser:
        page = browser.page()
        page.goto(url)
        page.wait_for_function("() => window.Bokeh !== undefined && Bokeh.documents.length > 0"
                               " && Bokeh.documents[0].get_model_by_name('vehicles')"
                               ".data.x.length == 2", timeout=30_000)
        # the page sends its sources and the fleet table one at a time: wait for its rows too
        page.locator("table.fleet td.uav").nth(1).wait_for(timeout=30_000)
        got = page.evaluate(FLEET_JS)
        rows = page.locator("table.fleet td.uav").all_inner_texts()
        flies = page.locator("table.fleet td.flies").all_inner_texts()
        page.close()
    assert got["uav"] == list(VEHICLES) and got["x"] == [115.0, 1100.0 + 116.0]
    assert got["y"] == [125.0, 125.0] and got["flies"] == ["S1", "S1"]  # flown_system 1
    assert [min(xs) for xs in got["fires"]] == [380.0, 1100.0 + 381.0]  # Rect(400 + k, …, 40)
    assert [min(xs) for xs in got["areas"]] == [0.0, 1100.0]
    assert got["forecast"] == [0.0, 1100.0] and got["plans"] == [1, 1]
    assert rows == list(VEHICLES) and flies == ["S1", "S1"]
    assert browser.hosts() <= {f"http://127.0.0.1:{url.split(':')[2].strip('/')}",
                               f"ws://127.0.0.1:{url.split(':')[2].strip('/')}"}
