"""End to end: the live view's web page in a real headless browser (Debian's chromium, driven by
playwright) while the whole stack flies a mission, then the run's mission.mcap replayed on it.

What the page holds (its Bokeh data sources, read in the browser) is checked against the
supervisor's own record (steps.jsonl); what it shows is checked in screenshots: the fire
regions' pixels where the page's axes put them, the vehicle's marker in its system's colour
where the vehicle is, at two moments far apart. Nothing may be fetched from anywhere but the
page's own server. The screenshots go to docs/figures/ (docs/live_view.md shows them).
"""

from __future__ import annotations

import io
import math
import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.path import Path as Polygon

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.records import read_step_log
from e2e.conftest import router_ready
from services import launch
from services.launch.processes import REPO, free_port
from tests.support.browser import Browser, chromium
from tests.support.waits import check, logs_in, wait_for

pytestmark = [pytest.mark.slow, pytest.mark.timeout(300)]

UAV = "webv"
SEED = 26
#: the pace: a step (~6 simulated s) lasts ~0.3 s, so the page, refreshed every 250 ms, still
#: sees most steps and fires (41 of the 56 steps in one run; the test asks for 10)
SPEED = 20.0
FIGURES = REPO / "docs" / "figures"
#: set to 1 to refresh docs/figures' screenshots from this run (each run keeps its own in its
#: run directory either way, so a test run leaves the checkout as it found it)
REFRESH_DOCS = "DUALPILOT_REFRESH_DOCS_FIGURES"
#: the page's fills (services/viewer/page.py): each fire region #ff4019 at opacity 0.55 and the
#: goal #1fcc4d at 0.35, over a white background. One fire region over white shows
#: 0.55 × (255, 64, 25) + 0.45 × 255 = (255, 150, 129); two overlapping ones (255, 103, 72);
#: one over the goal (0.35 × (31, 204, 77) + 0.65 × 255 = (177, 237, 193)) shows (220, 142, 101)
FIRE_FILL, FIRE_ALPHA = np.array([255.0, 64.0, 25.0]), 0.55
GOAL_FILL, GOAL_ALPHA = np.array([31.0, 204.0, 77.0]), 0.35
WHITE = np.array([255.0, 255.0, 255.0])
#: screen points this close to a region's outline (CSS px) are not judged: a line is drawn there
OUTLINE_PX = 3.0
SYSTEM_RGB = {"#3399ff": (51, 153, 255), "#e633e6": (230, 51, 230), "#e03c31": (224, 60, 49)}

#: what the page holds, and where its map puts a point on the screen (CSS px)
SAMPLE_JS = """() => {
  const doc = Bokeh.documents[0];
  const col = (name, key) => Array.from(doc.get_model_by_name(name).data[key] ?? []);
  const view = Bokeh.index.find_one(doc.get_model_by_name('map'));
  const box = view.el.getBoundingClientRect();
  const px = (x, y) => [box.left + view.frame.x_scale.compute(x),
                        box.top + view.frame.y_scale.compute(y)];
  const x = col('vehicles', 'x'), y = col('vehicles', 'y');
  const fy = col('fires', 'ys').map(a => Array.from(a));
  const gy = col('goal', 'ys').map(a => Array.from(a));
  return {
    uav: col('vehicles', 'uav'), x: x, y: y, step: col('vehicles', 'step'),
    color: col('vehicles', 'color'), marker_px: x.map((v, i) => px(v, y[i])),
    fires_px: col('fires', 'xs').map((xs, i) => Array.from(xs).map((v, j) => px(v, fy[i][j]))),
    goal_px: col('goal', 'xs').map((xs, i) => Array.from(xs).map((v, j) => px(v, gy[i][j]))),
    forecast_horizons: col('forecast', 'horizon_s'), trail: col('trails', 'xs').length,
    plans: col('plans', 'system'), psi_t: col('psi', 't'), psi1: col('psi', 'psi1'),
    psi2: col('psi', 'psi2'), flown: col('psi', 'flown'),
    fleet: doc.get_model_by_name('fleet').text, header: doc.get_model_by_name('header').text,
  };
}"""
READY_JS = ("() => window.Bokeh !== undefined && Bokeh.documents.length > 0 && "
            "Bokeh.documents[0].get_model_by_name('vehicles') !== null && "
            "Bokeh.documents[0].get_model_by_name('vehicles').data.x.length > 0")


@dataclass
class Shot:
    """A screenshot and what the page held just before and after it (the same)."""

    png: bytes
    sample: dict[str, Any]

    def rgb(self) -> Any:
        from PIL import Image

        return np.asarray(Image.open(io.BytesIO(self.png)).convert("RGB")).astype(int)


@dataclass
class Watched:
    run_dir: Path
    outcome: launch.Outcome
    codes: dict[str, int]
    url: str
    browser_hosts: set[str]
    console: list[str]
    samples: list[dict[str, Any]] = field(default_factory=list)
    fire_shots: list[Shot] = field(default_factory=list)  # the heat map hidden
    docs_shots: list[Shot] = field(default_factory=list)  # the same moments as a person sees
    fleet_cells: dict[str, str] = field(default_factory=dict)  # the table's cells in the DOM
    marker_shots: list[Shot] = field(default_factory=list)
    replay: dict[str, Any] = field(default_factory=dict)


def drawn(page: Any) -> dict[str, Any]:
    """What the page holds (the header's "newest message … s ago" left out: it changes at every
    refresh)."""
    return {k: v for k, v in page.evaluate(SAMPLE_JS).items() if k != "header"}


def set_model(page: Any, name: str, attr: str, value: Any) -> None:
    """Set a widget's or renderer's property in the browser, as a click would."""
    page.evaluate("([n, a, v]) => { Bokeh.documents[0].get_model_by_name(n)[a] = v }",
                  [name, attr, value])


def frozen_shots(page: Any, heat_map_too: bool = False) -> tuple[Shot, Shot | None] | None:
    """The page frozen (its "freeze" toggle: the session stops redrawing), a screenshot, and with
    ``heat_map_too`` one more with the heat map hidden; None when the data changed meanwhile."""
    set_model(page, "freeze", "active", True)
    time.sleep(0.4)  # a redraw under way when the toggle arrived has reached the browser
    before = drawn(page)
    first = Shot(page.screenshot(), before)
    second = None
    if heat_map_too:
        set_model(page, "forecast_image", "visible", False)
        time.sleep(0.2)
        second = Shot(page.screenshot(), before)
        set_model(page, "forecast_image", "visible", True)
    steady = drawn(page) == before
    set_model(page, "freeze", "active", False)
    return (first, second) if steady else None


def open_page(page: Any, url: str, logs: Any) -> None:
    """Load ``url`` (its server may still be starting) and wait until it shows a vehicle."""
    def loaded() -> bool:
        try:
            page.goto(url, timeout=10_000)
            return True
        except Exception:  # connection refused while the viewer starts
            time.sleep(0.3)
            return False

    wait_for(loaded, 60, f"the web page at {url} to load", logs)
    page.wait_for_function(READY_JS, timeout=60_000)


def watch_live(browser: Browser, stack: launch.Stack, w: Watched) -> None:
    """Follow the mission on the page until it ends: samples, fire and marker screenshots."""
    result: dict[str, launch.Outcome] = {}
    follower = threading.Thread(target=lambda: result.setdefault(
        "outcome", launch.follow(stack, timeout_s=180.0, quiet=True)), daemon=True)
    follower.start()
    page = browser.page()
    open_page(page, w.url, logs_in(stack.logs))
    last_fire = 0.0
    while follower.is_alive():
        sample = page.evaluate(SAMPLE_JS)
        w.samples.append(sample)
        if not w.marker_shots and sample["color"][0] in SYSTEM_RGB and (
                got := frozen_shots(page)) is not None:
            w.marker_shots.append(got[0])
        if not w.fleet_cells and sample["step"][0] >= 3:  # the table as the DOM holds it
            w.fleet_cells = {k: page.locator(f"table.fleet td.{k}").first.inner_text()
                             for k in ("uav", "step", "flies")}
        if sample["fires_px"] and time.monotonic() - last_fire > 1.0:
            got = frozen_shots(page, heat_map_too=True)
            if got is not None and got[1] is not None and got[0].sample["fires_px"]:
                w.docs_shots.append(got[0])
                w.fire_shots.append(got[1])
                last_fire = time.monotonic()
        time.sleep(0.15)
    end = wait_for(lambda: frozen_shots(page), 10, "a steady page after the mission's end")
    w.marker_shots.append(end[0])
    page.close()  # before the stack stops: the page would report its lost connection
    save_live_figure(w)
    w.outcome = result.get("outcome", launch.Outcome(False, message="follow raised"))


def keep_figure(w: Watched, name: str, png: bytes) -> None:
    """``png`` as ``name`` in the run directory, and in docs/figures with :data:`REFRESH_DOCS`."""
    (w.run_dir / name).write_bytes(png)
    if os.environ.get(REFRESH_DOCS) == "1":
        (FIGURES / name).write_bytes(png)


def save_live_figure(w: Watched) -> None:
    """web_view_live.png: of the moments with fires, the one nearest mid-mission (a trail
    behind the vehicle, its plan ahead)."""
    if w.docs_shots:
        mid = max(s["step"][0] for s in w.samples) / 2
        best = min(w.docs_shots, key=lambda d: abs(d.sample["step"][0] - mid))
        keep_figure(w, "web_view_live.png", best.png)


def watch_replay(browser: Browser, w: Watched) -> None:
    """``python -m services.viewer --replay mission.mcap``: the last step, then step 10."""
    port = free_port("tcp")
    log = w.run_dir / "logs" / "viewer-replay.log"
    with log.open("w") as out:
        proc = subprocess.Popen([sys.executable, "-m", "services.viewer", "--replay",
                                 str(w.run_dir / "mission.mcap"), "--web-port", str(port),
                                 "--log-format", "text"], stdout=out, stderr=subprocess.STDOUT,
                                cwd=REPO)
    try:
        page = browser.page()
        open_page(page, f"http://127.0.0.1:{port}/", [log])
        end = page.evaluate("() => Bokeh.documents[0].get_model_by_name('replay_step').end")
        w.replay["last"] = page.evaluate(SAMPLE_JS)
        w.replay["end"] = end
        page.evaluate("() => { Bokeh.documents[0].get_model_by_name('replay_step').value = 10 }")
        # the page sends its sources one at a time (the vehicles before Ψ): wait for both
        page.wait_for_function("() => { const d = Bokeh.documents[0]; "
                               "const t = d.get_model_by_name('psi').data.t; "
                               "return d.get_model_by_name('vehicles').data.step[0] == 10 "
                               "&& t.length > 0 && t[t.length - 1] == 10 }", timeout=20_000)
        w.replay["step10"] = page.evaluate(SAMPLE_JS)
        page.evaluate(f"() => {{ Bokeh.documents[0].get_model_by_name('replay_step').value = "
                      f"{end} }}")
        page.wait_for_function(f"() => Bokeh.documents[0].get_model_by_name('vehicles')"
                               f".data.x[0] == {w.replay['last']['x'][0]}", timeout=20_000)
        time.sleep(0.5)
        keep_figure(w, "web_view_replay.png", page.screenshot())
        w.replay["port"] = port
        page.close()
    finally:
        proc.send_signal(signal.SIGINT)
        w.replay["code"] = proc.wait(timeout=20)
        w.replay["log"] = log


@pytest.fixture(scope="module")
def watched(tmp_path_factory: pytest.TempPathFactory) -> Watched:
    run_dir = tmp_path_factory.mktemp("web") / f"web-cc-s{SEED}"
    cfg = launch.StackConfig(run_dir=run_dir, mission=MissionConfig(seed=SEED),
                             speed_factor=SPEED, free_ports=True, uav_id=UAV, log_format="text",
                             profiles=("viewer",))
    stack = launch.Stack(cfg)
    w = Watched(run_dir, launch.Outcome(False), {}, stack.web_url(), set(), [])
    FIGURES.mkdir(parents=True, exist_ok=True)
    with chromium() as browser:
        with stack:
            router_ready(stack.endpoint, logs_in(stack.logs))
            watch_live(browser, stack, w)
        w.codes = {p.name: int(p.popen.returncode) for p in stack.group.procs}
        watch_replay(browser, w)
        w.browser_hosts, w.console = browser.hosts(), browser.console
    return w


def expected_state(steps: dict[int, Any], end: dict[str, Any], step: int) -> Any:
    """The state the supervisor recorded for the vehicle at ``step`` (the start of that step;
    the final state after the last)."""
    return steps[step]["state"] if step in steps else end["final_state"]


def record(run_dir: Path) -> tuple[dict[int, Any], dict[str, Any]]:
    entries = read_step_log(run_dir / "steps.jsonl")
    return ({e["t"]: e for e in entries if e["kind"] == "step"},
            next(e for e in entries if e["kind"] == "end"))


def test_the_page_follows_every_step_it_shows_from_the_supervisors_record(
        watched: Watched) -> None:
    w = watched
    logs = logs_in(w.run_dir)
    check(w.outcome.ended, "the mission to end", logs, w.outcome)
    check(w.url.startswith("http://127.0.0.1:"), "a loopback URL for the page", logs, w.url)
    steps, end = record(w.run_dir)
    seen = {}
    for s in w.samples:
        assert s["uav"] == [UAV]
        seen[s["step"][0]] = (s["x"][0], s["y"][0])
    assert len(seen) >= 10, sorted(seen)  # the marker moved from step to step
    for step, xy in seen.items():
        assert np.allclose(xy, expected_state(steps, end, step)[:2], atol=1e-6), step
    last = w.samples[-1]
    assert last["trail"] == 1 and last["forecast_horizons"] and last["forecast_horizons"][0] > 0
    # Ψ on the page: each step's Ψ_t and flown system as the supervisor recorded them
    assert len(last["psi_t"]) >= len(steps) // 2
    for t, p1, p2, flown in zip(last["psi_t"], last["psi1"], last["psi2"], last["flown"],
                                strict=True):
        assert np.allclose([p1, p2], steps[t]["decision"]["psi"], atol=1e-9), t
        assert flown == {0: "braked", 1: "S1", 2: "S2"}[steps[t]["system"]], t
    assert f"{UAV} " in last["header"] and "1 vehicle(s)" in last["header"]
    assert "newest message" in last["header"]
    # the fleet table in the browser's DOM: the vehicle, a step it flew, and who flew it
    cells = w.fleet_cells
    assert cells["uav"] == UAV and int(cells["step"]) >= 3, cells
    assert cells["flies"] in ("S1", "S2", "braked"), cells
    assert f'<td class="uav">{UAV}</td>' in last["fleet"]


def expected_rgb(x: float, y: float, fires_px: list[Any], goal_px: list[Any]) -> Any:
    """The colour the page must show at the screen point (x, y): the fire fill composited once
    for every fire region over it, over the goal's fill where the goal is beneath, else over
    white; None within :data:`OUTLINE_PX` of a region's outline."""
    regions = [np.array(c, dtype=float) for c in (*fires_px, *goal_px)]
    if any(outline_distance(x, y, c) < OUTLINE_PX for c in regions):
        return None
    colour = WHITE
    if any(Polygon(np.array(c)).contains_point((x, y)) for c in goal_px):
        colour = GOAL_ALPHA * GOAL_FILL + (1 - GOAL_ALPHA) * colour
    for c in fires_px:
        if Polygon(np.array(c)).contains_point((x, y)):
            colour = FIRE_ALPHA * FIRE_FILL + (1 - FIRE_ALPHA) * colour
    return colour


def outline_distance(x: float, y: float, corners: Any) -> float:
    """The distance (px) from (x, y) to the closed polygon through ``corners``."""
    a, b = corners, np.roll(corners, -1, axis=0)
    d, p = b - a, np.array([x, y]) - a
    t = np.clip((p * d).sum(axis=1) / np.maximum((d * d).sum(axis=1), 1e-12), 0.0, 1.0)
    return float(np.min(np.hypot(*(p - t[:, None] * d).T)))


def test_fire_regions_are_drawn_where_the_axes_put_them(watched: Watched) -> None:
    w = watched
    check(w.fire_shots, "a screenshot while a fire region was on the page",
          logs_in(w.run_dir), f"{len(w.samples)} samples")
    checked = 0
    for s in w.fire_shots:
        rgb = s.rgb()
        for corners in s.sample["fires_px"]:
            c = np.array(corners)
            (x0, y0), (x1, y1) = c.min(axis=0), c.max(axis=0)
            if x1 - x0 < 8 or y1 - y0 < 8:
                continue  # too small on screen to sample inside its outline
            xs = np.linspace(x0 + 0.25 * (x1 - x0), x1 - 0.25 * (x1 - x0), 5).round()
            ys = np.linspace(y0 + 0.25 * (y1 - y0), y1 - 0.25 * (y1 - y0), 5).round()
            judged = [(rgb[int(y), int(x)], want) for y in ys for x in xs if (
                want := expected_rgb(x, y, s.sample["fires_px"], s.sample["goal_px"]))
                is not None]
            if len(judged) < 10:
                continue  # near outlines (a small or crowded region): too few points to judge
            near = [np.abs(got - want).max() <= 30 for got, want in judged]
            assert np.mean(near) >= 0.8, (corners, [(got.tolist(), want.round().tolist())
                                                    for got, want in judged])
            checked += 1
    assert checked >= 1


def test_the_vehicle_marker_moves_in_its_systems_colour(watched: Watched) -> None:
    first, last = watched.marker_shots[0], watched.marker_shots[-1]
    centres = []
    for s in (first, last):
        (px, py), = s.sample["marker_px"]
        rgb = s.rgb()
        patch = rgb[int(py) - 1:int(py) + 2, int(px) - 1:int(px) + 2].reshape(-1, 3)
        colour = np.median(patch, axis=0)
        want = np.array(SYSTEM_RGB[s.sample["color"][0]])
        assert np.abs(colour - want).max() <= 40, (s.sample["color"], colour.tolist())
        centres.append((px, py))
    (x0, y0), (x1, y1) = centres
    assert math.hypot(x1 - x0, y1 - y0) > 100  # CSS px across the map


def test_nothing_is_fetched_but_from_the_pages_own_server(watched: Watched) -> None:
    w = watched
    live = w.url.rstrip("/").removeprefix("http://")
    replay = f"127.0.0.1:{w.replay['port']}"
    allowed = {f"{scheme}://{host}" for scheme in ("http", "ws") for host in (live, replay)}
    assert w.browser_hosts <= allowed, w.browser_hosts - allowed
    assert not [c for c in w.console if c.startswith(("pageerror", "error"))], w.console


def test_the_run_replays_from_its_mission_mcap(watched: Watched) -> None:
    w = watched
    steps, end = record(w.run_dir)
    check(w.replay.get("code") == 0, "the replay server to stop with 0 on SIGINT",
          [w.replay["log"]], w.replay.get("code"))
    assert w.replay["end"] == len(steps)  # a frame a step, and the end
    last = w.replay["last"]
    assert np.allclose([last["x"][0], last["y"][0]], end["final_state"][:2], atol=1e-6)
    at10 = w.replay["step10"]
    assert np.allclose([at10["x"][0], at10["y"][0]], steps[10]["state"][:2], atol=1e-6)
    assert at10["psi_t"] == list(range(11))  # the Ψ history up to the slider's step
    assert len(last["psi_t"]) == len(steps)


def test_the_viewer_stopped_cleanly(watched: Watched) -> None:
    w = watched
    viewer_log = w.run_dir / "logs" / "viewer.log"
    text = viewer_log.read_text()
    check("serving the web page" in text and "web page stopped" in text,
          "the viewer to log that it served the web page and stopped", [viewer_log])
    check(w.codes.get("viewer") == 0, "the viewer to exit with 0", [viewer_log], w.codes)
