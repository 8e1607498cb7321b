"""The web page's picture (services/viewer/picture.py) and its columns (columns.py): what each
layer holds, worked out by hand, with no browser and no server."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dualpilot.mission.answers import PlanView
from dualpilot.model.fire import FireSnapshot
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.viz import scene
from services.viewer import columns as C
from services.viewer.picture import MAX_EVENTS, Picture

GOAL = scene.rect_outline(Rect(900, 900, 100, 100))
AREA = scene.AreaView(1000.0, np.array([50.0, 50.0]), GOAL)


def doc(t: int, psi: tuple[float, float], flown: int, attention: int = 2,
        d_t: float | None = 120.0) -> dict[str, object]:
    return {"t": t, "time_s": 6.0 * t, "d_t_m": d_t, "xi": [1.0, 2.0, 3.0],
            "p": [0.2, 0.3, 0.5], "attention": attention, "psi": list(psi), "system": flown or 1,
            "commanded_system": flown or 1, "flown_system": flown, "objective": "mission_time"}


def test_a_frame_is_a_copy_and_only_the_changed_layer_moves_on() -> None:
    pic = Picture()
    s = pic.scene("uav2", (1100.0, 0.0))
    s.area(AREA, 10)
    before = pic.frame()
    s.vehicle(np.array([60.0, 70.0, 1.0, 0.0]), 3, 20.0, 20)
    after = pic.frame()
    assert before.vehicles[0].state is None and after.vehicles[0].step == 3
    assert after.version > before.version
    assert after.layer_key("vehicle") == (("uav2", 1),) and after.layer_key("area") == (
        ("uav2", 1),) and after.layer_key("fires") == (("uav2", 0),)
    assert after.vehicles[0].updated_ns == 20
    assert pic.scene("uav2") is s  # the same scene; its offset stays the first one
    assert after.vehicles[0].offset_m == (1100.0, 0.0)


def test_decisions_are_kept_per_mission_and_events_bounded() -> None:
    pic = Picture()
    s = pic.scene("a")
    s.decision(doc(0, (0.4, -0.4), 1), 1)
    s.decision(doc(1, (-0.2, 0.2), 2), 2)
    assert [d["t"] for d in pic.frame().vehicles[0].decisions] == [0, 1]
    assert pic.frame().vehicles[0].decision["flown_system"] == 2  # type: ignore[index]
    s.new_mission()
    assert pic.frame().vehicles[0].decisions == ()
    for k in range(MAX_EVENTS + 5):
        s.event(f"e{k}", k)
    events = pic.frame().vehicles[0].events
    last = MAX_EVENTS + 4
    assert len(events) == MAX_EVENTS and events[-1] == (last, "info", f"e{last}")


def test_areas_and_fires_are_shifted_by_the_vehicles_offset() -> None:
    pic = Picture()
    s = pic.scene("uav2", (1100.0, 0.0))
    s.area(AREA, 1)
    hull = Polytope.from_vertices(np.array([[90.0, 190.0], [130.0, 190.0], [110.0, 230.0]]))
    s.fires(scene.fire_view(FireSnapshot((Rect(100, 200, 40, 20),), (hull,), (3,), (2,))), 2)
    f = pic.frame()
    area = C.area_columns(f)
    assert area["area"]["xs"] == [[1100.0, 2100.0, 2100.0, 1100.0, 1100.0]]
    assert area["area"]["ys"] == [[0.0, 0.0, 1000.0, 1000.0, 0.0]]
    assert (area["start"]["x"], area["start"]["y"]) == ([1150.0], [50.0])
    assert area["goal"]["xs"] == [[1950.0, 2050.0, 2050.0, 1950.0]]
    fires = C.fire_columns(f)
    assert fires["fires"]["xs"] == [[1180.0, 1220.0, 1220.0, 1180.0]]
    assert fires["fires"]["ys"] == [[190.0, 190.0, 210.0, 210.0]]
    assert (fires["fires"]["front_id"], fires["fires"]["born_step"]) == ([3], [2])
    # a hull is drawn closed: its first vertex again at the end
    xs = fires["hulls"]["xs"][0]
    assert xs[0] == xs[-1] and sorted(set(xs)) == [1190.0, 1210.0, 1230.0]
    assert fires["risk"]["xs"] == []


@pytest.mark.parametrize(("v", "angle"), [((1.0, 0.0), -math.pi / 2), ((0.0, 2.0), 0.0),
                                          ((-1.0, 0.0), math.pi / 2), ((0.0, 0.0), 0.0)])
def test_the_marker_points_along_the_velocity(v: tuple[float, float], angle: float) -> None:
    assert C.heading_rad(np.array([0.0, 0.0, *v])) == pytest.approx(angle)


def test_a_vehicle_its_trail_plan_and_who_flies() -> None:
    pic = Picture()
    s = pic.scene("uav1")
    s.vehicle(np.array([60.0, 70.0, 3.0, 4.0]), 5, 20.0, 1)
    s.path(np.array([[50.0, 50.0], [60.0, 70.0]]), 1)
    s.plans([PlanView(1, "", np.empty((0, 2)), False),
             PlanView(2, "ok", np.array([[60.0, 70.0], [75.0, 85.0]]), True)], 4, 1)
    s.decision(doc(4, (-0.9, 0.9), 2), 1)
    got = C.vehicle_columns(pic.frame())
    v = got["vehicles"]
    assert (v["x"], v["y"], v["step"], v["flies"], v["color"]) == (
        [60.0], [70.0], [5], ["S2"], [C.SYSTEM_COLORS[2]])
    assert v["speed"] == [5.0] and v["label"] == ["uav1 S2 t=5"]
    assert (v["psi1"], v["psi2"]) == ([-0.9], [0.9])
    assert got["trails"]["xs"] == [[50.0, 60.0]]
    assert got["plans"]["xs"] == [[60.0, 75.0]] and got["plans"]["system"] == [2]
    assert got["plans"]["status"] == ["ok"] and got["plans"]["step"] == [4]
    # the d_safe disc: 48 points on the circle of 20 m, closed
    ring = np.column_stack([got["safety"]["xs"][0], got["safety"]["ys"][0]])
    assert len(ring) == 49 and np.allclose(np.hypot(*(ring - [60.0, 70.0]).T), 20.0)
    s.decision(doc(5, (0.1, -0.1), 0), 2)
    assert C.vehicle_columns(pic.frame())["vehicles"]["color"] == [C.BRAKED_COLOR]


def test_the_fleet_table_and_psi_history() -> None:
    pic = Picture()
    a, b = pic.scene("a"), pic.scene("b", (1100.0, 0.0))
    a.decision(doc(0, (0.5, -0.5), 1, attention=1, d_t=None), 1)
    a.decision(doc(1, (-0.3, 0.3), 2, attention=3, d_t=42.5), 2)
    a.plans([PlanView(1, "timeout", np.empty((0, 2)), False),
             PlanView(2, "ok", np.empty((0, 2)), True)], 1, 2)
    a.event("step 1: S2 flew; plans s2:ok", 3)
    b.event("mission started", 1)
    f = pic.frame()
    t = C.table_columns(f)
    assert t["uav"] == ["a", "b"] and t["flies"] == ["S2", "-"]
    assert (t["psi1"][0], t["psi2"][0], t["attention"][0], t["d_t_m"][0]) == (-0.3, 0.3, 3, 42.5)
    assert math.isnan(t["psi1"][1]) and t["plans"][0] == "S1 timeout; S2 ok"
    assert t["event"] == ["step 1: S2 flew; plans s2:ok", "mission started"]
    psi = C.psi_columns(f, "a")
    assert (psi["t"], psi["psi1"], psi["psi2"], psi["flown"]) == (
        [0, 1], [0.5, -0.3], [-0.5, 0.3], ["S1", "S2"])
    # the flown strip: a tenth of Ψ's span (1.0) below its lowest value (-0.5)
    assert psi["flown_y"] == [pytest.approx(-0.6)] * 2
    assert C.psi_columns(f, "nobody")["t"] == []
    assert C.event_lines(f, most=2) == [("a", "info", "step 1: S2 flew; plans s2:ok"),
                                        ("b", "info", "mission started")]


def test_the_forecast_heat_map_is_p_per_cell_south_row_first() -> None:
    # 2 rows × 3 cols × 2 horizons, interleaved: cell (r, c) holds bytes 2(3r + c), 2(3r + c) + 1
    view = scene.OccupancyView((10.0, 20.0), 5.0, 2, 3, (0.0, 30.0), bytes(range(12)))
    p = C.forecast_image(view, 1)
    assert p.shape == (2, 3)
    assert np.allclose(p, np.array([[1, 3, 5], [7, 9, 11]]) / 255.0)
    first = C.forecast_image(view, 0)
    assert math.isnan(first[0, 0]) and first[1, 2] == pytest.approx(10 / 255)  # P = 0: clear
    pic = Picture()
    pic.scene("a", (1100.0, 0.0)).forecast(view, 1)
    cols = C.forecast_columns(pic.frame())
    assert (cols["x"], cols["y"], cols["dw"], cols["dh"], cols["horizon_s"]) == (
        [1110.0], [20.0], [15.0], [10.0], [30.0])
    assert C.forecast_columns(pic.frame(), 0)["horizon_s"] == [0.0]


def test_the_heat_palette_fades_low_probabilities_out() -> None:
    pal = C.heat_palette(11)  # log10 P = -3, -2.7, …, 0
    assert pal[0] == "#ffffcc00"  # P = 0.001: clear
    assert pal[5][-2:] == f"{round(255 * 0.85 * 0.25):02x}"  # P ≈ 0.03: a quarter of full
    assert pal[10] == "#800026d9"  # P = 1: 0.85 · 255 = 217
    assert [int(c[-2:], 16) for c in pal] == sorted(int(c[-2:], 16) for c in pal)


def test_the_fleet_table_shows_who_flies_in_its_colour() -> None:
    from services.viewer.page import fleet_html

    pic = Picture()
    pic.scene("a").decision(doc(3, (-0.25, 0.25), 2, attention=3, d_t=None), 1)
    pic.scene("b<x>")
    text = fleet_html(pic.frame())
    assert text.count("<tr>") == 3  # the header, a row a vehicle
    assert (f'<td class="flies" style="color:{C.SYSTEM_COLORS[2]};font-weight:bold">S2</td>'
            in text)
    assert '<td class="psi1">-0.250</td>' in text and '<td class="d_t_m">-</td>' in text
    assert '<td class="uav">b&lt;x&gt;</td>' in text  # escaped


def test_web_origins_name_the_port() -> None:
    from services.viewer.web import origins

    assert origins("0.0.0.0", 8766) == ["127.0.0.1:8766", "localhost:8766"]
    assert origins("10.1.2.3", 80, ["ops.example:8766"]) == [
        "10.1.2.3:80", "127.0.0.1:80", "localhost:80", "ops.example:8766"]
