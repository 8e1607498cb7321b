"""A 3-D mission's altitude on the web page: from the stack's VehicleState (which carries it)
and from a mission.mcap, to the vehicle's label and hover; a 2-D mission's page unchanged."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from bokeh.models import HoverTool

from dualpilot.viz import scene
from services.common import bus, keys, wire
from services.common.convert import vehicle as vehicle_convert
from services.msgs import vehicle_pb2
from services.viewer import columns as C
from services.viewer.picture import Picture
from services.viewer.replay import load, read_messages, vehicle_of
from tests.unit.dualpilot.viz.test_altitude import run_3d


def test_a_3d_state_is_drawn_from_above_with_its_altitude() -> None:
    pic = Picture()
    s = pic.scene("uav1")
    s.vehicle(np.array([60.0, 70.0, 65.44, 3.0, 4.0, -1.5]), 5, 20.0, 1)
    v = pic.frame().vehicles[0]
    assert v.state is not None and v.state.tolist() == [60.0, 70.0, 3.0, 4.0]
    assert v.altitude_m == 65.44
    cols = C.vehicle_columns(pic.frame())["vehicles"]
    assert (cols["x"], cols["y"], cols["speed"]) == ([60.0], [70.0], [5.0])  # |(3, 4)|
    assert cols["angle"] == [pytest.approx(math.atan2(4.0, 3.0) - math.pi / 2)]
    assert cols["altitude"] == [65.44] and cols["label"] == ["uav1 - t=5 z=65.4 m"]


def test_a_3d_trail_is_cut_into_segments_with_their_mean_altitude() -> None:
    pic = Picture()
    s = pic.scene("uav2", (1100.0, 0.0))
    s.path(np.array([[50.0, 50.0, 50.0], [60.0, 50.0, 54.0], [70.0, 60.0, 60.0]]), 1)
    (v,) = pic.frame().vehicles
    assert v.path.tolist() == [[50.0, 50.0], [60.0, 50.0], [70.0, 60.0]]
    assert C.vehicle_columns(pic.frame())["trails"]["xs"] == [[1150.0, 1160.0, 1170.0]]
    assert C.altitude_trail_columns(pic.frame()) == {
        "xs": [[1150.0, 1160.0], [1160.0, 1170.0]], "ys": [[50.0, 50.0], [50.0, 60.0]],
        "uav": ["uav2", "uav2"], "altitude": [52.0, 57.0]}


def test_a_2d_state_has_no_altitude() -> None:
    pic = Picture()
    pic.scene("uav1").vehicle(np.array([60.0, 70.0, 3.0, 4.0]), 5, 20.0, 1)
    pic.scene("uav1").path(np.array([[50.0, 50.0], [60.0, 70.0]]), 2)
    assert pic.frame().vehicles[0].path_altitudes == ()
    assert C.altitude_trail_columns(pic.frame())["xs"] == []
    assert pic.frame().vehicles[0].altitude_m is None
    cols = C.vehicle_columns(pic.frame())["vehicles"]
    assert math.isnan(cols["altitude"][0]) and cols["label"] == ["uav1 - t=5"]
    assert scene.altitude_text(None) == "" and scene.altitude_text(44.51) == " z=44.5 m"


def test_the_live_viewer_keeps_the_altitude_a_vehicle_state_carries() -> None:
    import foxglove

    from services.viewer.serve import Viewer

    pic = Picture()
    viewer = Viewer(foxglove.Context(), pic)

    def receive(state: list[float], step: int) -> None:  # uav3's VehicleState at ``step``
        msg = vehicle_convert.state_to_msg(np.array(state), step, vehicle_pb2.VehicleState())
        wire.Stamper("uavsim", "uav3").stamp(msg.header, float(step))
        viewer.handle(bus.Received(key=keys.vehicle_state("uav3"),
                                   payload=msg.SerializeToString(), encoding=""))

    receive([115.0, 125.0, 58.5, 15.0, 0.0, 2.0], 4)
    (v,) = pic.frame().vehicles
    assert (v.uav, v.step, v.altitude_m) == ("uav3", 4, 58.5)
    assert v.state is not None and v.state.tolist() == [115.0, 125.0, 15.0, 0.0]
    assert v.path.tolist() == [[115.0, 125.0]]
    assert C.vehicle_columns(pic.frame())["vehicles"]["label"] == ["uav3 - t=4 z=58.5 m"]
    receive([130.0, 125.0, 61.5, 15.0, 0.0, 3.0], 5)
    (v,) = pic.frame().vehicles
    assert v.path.tolist() == [[115.0, 125.0], [130.0, 125.0]] and v.path_altitudes == (58.5,
                                                                                          61.5)
    trail = C.altitude_trail_columns(pic.frame())
    assert trail == {"xs": [[115.0, 130.0]], "ys": [[125.0, 125.0]], "uav": ["uav3"],
                     "altitude": [60.0]}  # the segment's mean altitude


def test_a_3d_recording_replays_with_its_altitude(tmp_path: Path) -> None:
    run = run_3d(tmp_path / "r3")  # at 40 m/s east and 6 m/s up: 50, 56, 62 m, ending at 68 m
    tl = load([run / "mission.mcap"])
    seen = [(v.step, v.altitude_m, None if v.state is None else v.state.tolist())
            for v in (f.vehicles[0] for f in tl.frames)]  # one frame a second: a step, the end
    assert seen == [(0, 50.0, [100.0, 100.0, 40.0, 0.0]), (1, 56.0, [140.0, 100.0, 40.0, 0.0]),
                    (2, 62.0, [180.0, 100.0, 40.0, 0.0]), (3, 68.0, [220.0, 100.0, 40.0, 0.0])]
    assert C.vehicle_columns(tl.frames[-1])["vehicles"]["altitude"] == [68.0]


def test_a_3d_recording_keeps_the_altitude_and_climb_in_the_uavs_metadata(tmp_path: Path) -> None:
    run = run_3d(tmp_path / "r3")
    uav = [m for m in read_messages(run / "mission.mcap") if m.kind == "uav"]
    (e,) = uav[1].body.entities  # step 1: (140, 100, 56) m, (40, 0, 6) m/s
    meta = {kv.key: kv.value for kv in e.metadata}
    assert meta == {"step": "1", "east_m": "140.0", "north_m": "100.0", "v_east_mps": "40.0",
                    "v_north_mps": "0.0", "altitude_m": "56.0", "v_up_mps": "6.0"}
    assert e.texts[0].text == "uav1 t=1 z=56.0 m"
    x, step, _ = vehicle_of(uav[1].body)
    assert step == 1 and x.tolist() == [140.0, 100.0, 56.0, 40.0, 0.0, 6.0]


def test_the_pages_document_holds_the_altitude() -> None:
    from bokeh.document import Document

    from services.viewer.page import Page

    pic = Picture()
    page = Page(Document(), "live", frames=pic.frame)
    bar = page.doc.select_one({"name": "altitude_bar"})
    pic.scene("uav1").vehicle(np.array([60.0, 70.0, 44.5, 0.0, 1.0, 0.0]), 2, 20.0, 1)
    pic.scene("uav1").path(np.array([[60.0, 50.0], [60.0, 70.0]]), 1)  # 2-D: no colours
    page.refresh()
    data = page.src["vehicles"].data
    assert data["altitude"] == [44.5] and data["label"] == ["uav1 - t=2 z=44.5 m"]
    assert page.src["altitude_trails"].data["xs"] == [] and not bar.visible
    pic.scene("uav1").path(np.array([[60.0, 50.0, 40.0], [60.0, 60.0, 42.0], [60.0, 70.0, 44.5]]),
                           2)
    page.refresh()
    assert page.src["altitude_trails"].data["altitude"] == [41.0, 43.25] and bar.visible
    assert (page.altitude.low, page.altitude.high) == (41.0, 43.25)  # the trail's range
    hover = [t for t in page.doc.select({"type": HoverTool}) if ("altitude", "@altitude{0.0} m")
             in t.tooltips]
    assert len(hover) == 1  # the vehicles' tooltip shows it
