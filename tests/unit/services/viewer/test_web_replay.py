"""mission.mcap back into the web page's picture (services/viewer/replay.py), and the page's
document built from a picture (services/viewer/page.py) without a browser: views drawn on
Foxglove channels into a real MCAP file come back as the same views."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dualpilot.mission.answers import PlanView
from dualpilot.model.fire import FireSnapshot
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.viz import foxglove as fx
from dualpilot.viz import scene
from services.viewer import columns as C
from services.viewer.picture import Picture
from services.viewer.replay import load

GOAL = scene.rect_outline(Rect(900, 900, 100, 100))
HULL = Polytope.from_vertices(np.array([[90.0, 190.0], [130.0, 190.0], [110.0, 230.0]]))
FIRES = scene.fire_view(FireSnapshot((Rect(100, 200, 40, 20),), (HULL,), (3,), (2,)))
FORECAST = scene.OccupancyView((0.0, 0.0), 10.0, 2, 3, (0.0, 20.0), bytes(range(12)))


def decision(t: int) -> dict[str, object]:
    return {"t": t, "time_s": 6.0 * t, "d_t_m": None, "xi": [1.0, 2.0, 3.0], "p": [.2, .3, .5],
            "attention": 1, "psi": [0.5 - t, t - 0.5], "system": 1, "commanded_system": 1,
            "flown_system": 1 + t % 2, "objective": "mission_time"}


def write(path: Path, uav: str, steps: int = 3) -> None:
    """A small mission's channels, one log time a step (as dualpilot.viz.foxglove.log_mission)."""
    import foxglove

    context = foxglove.Context()
    with foxglove.open_mcap(str(path), allow_overwrite=True, context=context):
        ch = fx.VehicleChannels(uav, context)
        ch.transform(0)
        for t in range(steps):
            t_ns = t * 6_000_000_000
            ch.area(scene.AreaView(1000.0, np.array([50.0, 50.0]), GOAL), t_ns)
            ch.fires(FIRES, t_ns)
            ch.vehicle(np.array([50.0 + 10 * t, 50.0, 10.0 / 6, 0.0]), t, 20.0, t_ns)
            ch.path(np.array([[50.0 + 10 * k, 50.0] for k in range(t + 1)]), t_ns)
            ch.decision(decision(t), t_ns)
            ch.plans([PlanView(1, "ok", np.array([[50.0 + 10 * t, 50.0], [70.0, 60.0]]), True),
                      PlanView(2, "timeout", np.empty((0, 2)), False)], t, t_ns)
            ch.forecast(FORECAST, t_ns)
            ch.event(f"step {t}: S1 flew", t_ns)
        ch.close()


def test_a_recording_comes_back_as_the_views_it_was_drawn_from(tmp_path: Path) -> None:
    write(tmp_path / "mission.mcap", "uav4")
    tl = load([tmp_path / "mission.mcap"])
    assert len(tl.frames) == 3  # one a log time, a step
    v = tl.at(1).vehicles[0]
    assert (v.uav, v.offset_m, v.step, v.d_safe_m) == ("uav4", (0.0, 0.0), 1, pytest.approx(20.))
    assert np.allclose(v.state, [60.0, 50.0, 10.0 / 6, 0.0])  # type: ignore[arg-type]
    assert np.allclose(v.path, [[50.0, 50.0], [60.0, 50.0]])
    assert v.area is not None and v.area.size_m == 1000.0 and np.allclose(v.area.goal, GOAL)
    assert np.allclose(v.area.start, [50.0, 50.0])
    assert v.fires is not None and v.fires.front_ids == (3,) and v.fires.born_steps == (2,)
    assert np.allclose(v.fires.regions[0], FIRES.regions[0])
    assert np.allclose(v.fires.hulls[0], HULL.vertices)
    assert [(p.system, p.status, p.flown) for p in v.plans] == [(1, "ok", True),
                                                               (2, "timeout", False)]
    assert np.allclose(v.plans[0].positions, [[60.0, 50.0], [70.0, 60.0]])
    assert [d["t"] for d in v.decisions] == [0, 1] and v.decision == decision(1)
    assert v.forecast == FORECAST
    assert v.events[-1][1:] == ("info", "step 1: S1 flew")
    assert tl.at(99) is tl.frames[-1] and tl.at(-5) is tl.frames[0]


def test_two_recordings_of_one_vehicle_id_are_replayed_side_by_side(tmp_path: Path) -> None:
    write(tmp_path / "a.mcap", "uav1", 2)
    write(tmp_path / "b.mcap", "uav1", 3)
    tl = load([tmp_path / "a.mcap", tmp_path / "b.mcap"])
    last = tl.frames[-1]
    assert [(v.uav, v.offset_m) for v in last.vehicles] == [("uav1", (0.0, 0.0)),
                                                             ("uav1-2", (1100.0, 0.0))]
    assert C.vehicle_columns(last)["vehicles"]["x"] == [60.0, 1170.0]


def test_an_empty_recording_is_refused(tmp_path: Path) -> None:
    import foxglove

    path = tmp_path / "empty.mcap"
    with foxglove.open_mcap(str(path), context=foxglove.Context()):
        pass
    with pytest.raises(ValueError, match="no messages"):
        load([path])


def test_the_page_draws_the_newest_frame_and_a_replay_its_sliders_step(tmp_path: Path) -> None:
    from bokeh.document import Document

    from services.viewer.page import Page

    pic = Picture()
    live = Page(Document(), "live", frames=pic.frame)
    assert live.src["vehicles"].data["x"] == [] and live.slider is None
    s = pic.scene("uav1")
    s.vehicle(np.array([60.0, 70.0, 0.0, 1.0]), 2, 20.0, 1)
    s.fires(FIRES, 1)
    live.refresh()
    assert live.src["vehicles"].data["x"] == [60.0] and len(live.src["fires"].data["xs"]) == 1
    assert live.uav.value == "uav1" and "1 vehicle(s)" in live.header.text

    write(tmp_path / "m.mcap", "uav4")
    tl = load([tmp_path / "m.mcap"])
    doc = Document()
    page = Page(doc, "replay", step_frames=tl.at, replay_steps=len(tl.frames))
    assert page.slider is not None and (page.slider.value, page.slider.end) == (2, 2)
    assert page.src["vehicles"].data["x"] == [70.0]
    page.slider.value = 0  # what a browser's slider does (its change reaches the server)
    assert page.src["vehicles"].data["x"] == [50.0] and page.src["psi"].data["t"] == [0]
    assert doc.get_model_by_name("vehicles") is page.src["vehicles"]
    assert "replay: step 0 of 2" in page.header.text


def test_a_file_that_is_no_recording_is_refused_with_its_name(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from services.viewer.__main__ import main

    bad = tmp_path / "notes.mcap"
    bad.write_text("not a recording")
    for argv, said in ((["--replay", str(bad)], f"cannot replay {bad}: not a mission.mcap"),
                       (["--replay", str(tmp_path / "gone.mcap")], "no such recording"),
                       (["--replay", str(bad), "--no-web"], "drop --no-web")):
        with pytest.raises(SystemExit) as stop:
            main(argv)
        assert stop.value.code == 2 and said in capsys.readouterr().err
