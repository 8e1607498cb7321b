"""The Foxglove messages of dualpilot/viz/foxglove.py, decoded from a real MCAP with the schemas
it carries; the expected values are worked out by hand."""

from __future__ import annotations

import io
import json
from typing import Any

import numpy as np
import pytest

from dualpilot.mission.answers import parse_answers
from dualpilot.model.fire import FireSnapshot
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.model.risk import RiskNote
from dualpilot.viz import foxglove as fx
from dualpilot.viz import scene

pytest.importorskip("mcap_protobuf", reason="dev extra: mcap-protobuf-support")


def record(draw: Any) -> dict[str, list[tuple[int, str, Any]]]:
    """Run ``draw(channels)`` into an in-memory MCAP; topic → [(log time, schema, message)]."""
    import foxglove
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    buf = io.BytesIO()
    context = foxglove.Context()
    with foxglove.open_mcap(buf, context=context):
        ch = fx.VehicleChannels("uav7", context, offset_m=(1100.0, 0.0))
        draw(ch)
        ch.close()
    buf.seek(0)
    out: dict[str, list[tuple[int, str, Any]]] = {}
    for schema, channel, message in make_reader(buf).iter_messages():
        assert schema is not None
        if channel.message_encoding == "json":
            value = json.loads(message.data)
        else:
            decoder = DecoderFactory().decoder_for(channel.message_encoding, schema)
            assert decoder is not None
            value = decoder(message.data)
        out.setdefault(channel.topic, []).append((message.log_time, schema.name, value))
    return out


def pts(line: Any) -> list[list[float]]:
    return [[p.x, p.y] for p in line.points]


def meta(e: Any) -> dict[str, str]:
    return {kv.key: kv.value for kv in e.metadata}


def test_topics_are_namespaced_by_vehicle() -> None:
    import foxglove

    ch = fx.VehicleChannels("uav7", foxglove.Context())
    assert ch.topics() == ["/uav7/tf", "/uav7/area", "/uav7/fires", "/uav7/forecast",
                           "/uav7/risk", "/uav7/plan/system1", "/uav7/plan/system2", "/uav7/path",
                           "/uav7/uav", "/uav7/decision", "/uav7/events"]
    ch.close()


def test_a_front_is_its_region_filled_and_outlined_then_its_hull() -> None:
    hull = Polytope.from_vertices(np.array([[90.0, 190.0], [130.0, 190.0], [110.0, 230.0]]))
    gone = Polytope.from_vertices(np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]]))
    snap = FireSnapshot(regions=(Rect(100, 200, 40, 20),), hulls=(hull, gone), front_ids=(3,),
                        born_steps=(2,))
    got = record(lambda ch: ch.fires(scene.fire_view(snap), 5_500_000_000))
    ((t_ns, schema, u),) = got["/uav7/fires"]
    assert (t_ns, schema) == (5_500_000_000, "foxglove.SceneUpdate")
    assert [d.type for d in u.deletions] == [1]  # ALL
    front, extinct = u.entities
    assert (front.id, front.frame_id, meta(front)) == (
        "front/3", "uav7/area", {"front_id": "3", "born_step": "2"})
    assert (front.timestamp.seconds, front.timestamp.nanos) == (5, 500_000_000)
    corners = [[80, 190], [120, 190], [120, 210], [80, 210]]
    assert front.lines[0].type == 1 and pts(front.lines[0]) == corners  # LINE_LOOP
    assert pts(front.lines[1]) == hull.vertices.tolist()
    # the fill: a fan of two triangles (c0, c1, c2), (c0, c2, c3)
    c = corners
    assert pts(front.triangles[0]) == [c[0], c[1], c[2], c[0], c[2], c[3]]
    assert {p.z for p in front.lines[0].points} == {fx.Z_FIRE}
    assert (extinct.id, meta(extinct)) == ("hull/1", {"extinct": "true"})
    assert pts(extinct.lines[0]) == gone.vertices.tolist()


def test_plans_carry_status_and_the_flown_positions() -> None:
    views = scene.plan_views(parse_answers("s2:timeout;s1:ok"), 1,
                             np.array([[50.0, 50.0], [65.0, 65.0]]))
    got = record(lambda ch: ch.plans(views, 12, 7_000_000_000))
    ((_, schema1, s1),) = got["/uav7/plan/system1"]
    ((_, _, s2),) = got["/uav7/plan/system2"]
    assert schema1 == "foxglove.SceneUpdate"
    (e1,), (e2,) = s1.entities, s2.entities
    assert meta(e1) == {"system": "1", "step": "12", "status": "ok", "flown": "true"}
    assert e1.lines[0].type == 0 and pts(e1.lines[0]) == [[50, 50], [65, 65]]  # LINE_STRIP
    assert e1.texts[0].text == "S1 ok"
    assert meta(e2) == {"system": "2", "step": "12", "status": "timeout", "flown": "false"}
    assert not e2.lines


def test_risk_zones_are_outlined_and_cleared_with_no_note() -> None:
    zone = Rect(300, 300, 20, 10).polytope()
    note = RiskNote(None, (zone,), 0.1)

    def draw(ch: fx.VehicleChannels) -> None:
        ch.risk(scene.risk_view(note), 4, 1)
        ch.risk(scene.risk_view(None), 5, 2)

    (_, schema, first), (_, _, second) = record(draw)["/uav7/risk"]
    assert schema == "foxglove.SceneUpdate"
    (e,) = first.entities
    assert (e.id, meta(e)) == ("zone/0", {"step": "4", "alpha": "0.1"})
    assert e.lines[0].type == 1 and pts(e.lines[0]) == zone.vertices.tolist()
    assert {p.z for p in e.lines[0].points} == {fx.Z_RISK}
    assert not second.entities and [d.type for d in second.deletions] == [1]


def test_uav_area_path_decision_forecast_events_and_frame() -> None:
    spec_view = scene.AreaView(1000.0, np.array([50.0, 50.0]),
                               scene.rect_outline(Rect(900, 900, 100, 100)))
    fc = scene.OccupancyView((0.0, 0.0), 10.0, 2, 3, (0.0, 20.0), bytes(range(12)))
    doc = {"t": 1, "time_s": 6.0, "xi": [1.0, 2.0, 3.0]}

    def draw(ch: fx.VehicleChannels) -> None:
        ch.transform(0)
        ch.area(spec_view, 1)
        ch.vehicle(np.array([60.0, 70.0, 1.5, -2.0]), 4, 20.0, 2)
        ch.path(np.array([[50.0, 50.0], [60.0, 70.0]]), 3)
        ch.decision(doc, 4)
        ch.forecast(fc, 5)
        ch.event("step 4: S1 flew; plans s1:ok", 6, "warning")

    got = record(draw)
    ((_, schema, tf),) = got["/uav7/tf"]
    assert schema == "foxglove.FrameTransform"
    assert (tf.parent_frame_id, tf.child_frame_id) == ("world", "uav7/area")
    assert (tf.translation.x, tf.translation.y, tf.rotation.w) == (1100.0, 0.0, 1.0)
    ((_, _, area),) = got["/uav7/area"]
    boundary, goal, start = area.entities
    assert pts(boundary.lines[0]) == [[0, 0], [1000, 0], [1000, 1000], [0, 1000]]
    assert pts(goal.lines[0]) == [[850, 850], [950, 850], [950, 950], [850, 950]]
    assert (start.spheres[0].pose.position.x, start.spheres[0].pose.position.y) == (50, 50)
    ((_, _, uav),) = got["/uav7/uav"]
    (e,) = uav.entities
    assert (e.cubes[0].pose.position.x, e.cubes[0].pose.position.y) == (60.0, 70.0)
    assert meta(e) == {"step": "4", "east_m": "60.0", "north_m": "70.0", "v_east_mps": "1.5",
                       "v_north_mps": "-2.0"}
    disc = np.array(pts(e.lines[0]))
    assert np.allclose(np.hypot(disc[:, 0] - 60, disc[:, 1] - 70), 20.0)  # d_safe around it
    ((_, _, path),) = got["/uav7/path"]
    assert pts(path.entities[0].lines[0]) == [[50, 50], [60, 70]]
    ((t_ns, schema, d),) = got["/uav7/decision"]
    assert (t_ns, schema, d) == (4, "dualpilot.Decision", doc)
    ((_, schema, g),) = got["/uav7/forecast"]
    assert schema == "foxglove.Grid"
    assert (g.column_count, g.cell_size.x, g.cell_stride, g.row_stride) == (3, 10.0, 2, 6)
    assert [(f.name, f.offset, f.type) for f in g.fields] == [("p_0s", 0, 1), ("p_20s", 1, 1)]
    assert g.data == bytes(range(12)) and g.frame_id == "uav7/area"
    ((_, schema, lg),) = got["/uav7/events"]
    assert (schema, lg.level, lg.message, lg.name) == (
        "foxglove.Log", 3, "step 4: S1 flew; plans s1:ok", "uav7")  # 3: WARNING
