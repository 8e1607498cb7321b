"""End to end: a 3-D mission on the live view's web page in a real headless browser (Debian's
chromium, driven by playwright) while the whole stack flies it (docs/three_d.md, section 11).

The mission climbs and sinks over fronts 10–40 m tall (the 3-D lockstep test's mission on the
paper's process, tests/e2e/test_lockstep3d.py). What the page holds is checked against the
supervisor's own record (steps.jsonl): the vehicle's altitude, its label's ``z=… m`` and the
trail's segments, each with the mean altitude of its two ends. What it shows is checked in a
screenshot: each trail segment's pixels in the Viridis colour its altitude maps to on the
altitude colour bar's range, worked out here from the record, not read from the page.
"""

from __future__ import annotations

import io
import math
import os
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bokeh.palettes import Viridis256

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.params import Timing
from e2e.conftest import router_ready
from services import launch
from tests.e2e.test_web_view import (
    FIGURES,
    REFRESH_DOCS,
    expected_state,
    frozen_shots,
    open_page,
    record,
)
from tests.support.browser import chromium
from tests.support.waits import check, logs_in, wait_for

pytestmark = [pytest.mark.slow, pytest.mark.timeout(300)]

UAV = "webz"
#: the 3-D lockstep test's mission on the paper's process: 69 steps to the goal, climbing
#: from 50 m to 65.4 m and sinking to 44.5 m over fronts 10–40 m tall
MISSION = MissionConfig.named("cc", seed=0, timing=Timing.PAPER, settings=(
    ("dim", 3), ("fire_height", "uniform"), ("fire_height_min_m", 10.0),
    ("fire_height_max_m", 40.0), ("s1_altitude", "volume")))
#: the pace of the 2-D page test (a step lasts ~0.3 s; the page refreshes every 250 ms)
SPEED = 20.0
#: a trail segment is judged on screen where its midpoint is this far (CSS px) from the
#: vehicle's marker and its label (drawn over the trail), and it is this long on screen
MARKER_CLEAR_PX, SEGMENT_MIN_PX = 40.0, 10.0

#: what the page holds of a 3-D mission, and where its map puts a point on the screen (CSS px)
SAMPLE_JS = """() => {
  const doc = Bokeh.documents[0];
  const arr = a => Array.from(a ?? []);
  const v = doc.get_model_by_name('vehicles').data;
  const tr = doc.get_model_by_name('altitude_trails').data;
  const view = Bokeh.index.find_one(doc.get_model_by_name('map'));
  const box = view.el.getBoundingClientRect();
  const px = (x, y) => [box.left + view.frame.x_scale.compute(x),
                        box.top + view.frame.y_scale.compute(y)];
  const mapper = doc.get_model_by_name('altitude_mapper');
  const x = arr(v.x), y = arr(v.y);
  const xs = arr(tr.xs).map(arr), ys = arr(tr.ys).map(arr);
  return {
    uav: arr(v.uav), step: arr(v.step), x: x, y: y, altitude: arr(v.altitude),
    label: arr(v.label), marker_px: x.map((e, i) => px(e, y[i])),
    trail_xs: xs, trail_ys: ys, trail_altitude: arr(tr.altitude),
    trail_px: xs.map((s, i) => s.map((e, j) => px(e, ys[i][j]))),
    low: mapper.low, high: mapper.high,
    bar: doc.get_model_by_name('altitude_bar').visible,
  };
}"""


@dataclass
class Watched3d:
    run_dir: Path
    outcome: launch.Outcome
    codes: dict[str, int]
    samples: list[dict[str, Any]] = field(default_factory=list)
    end_png: bytes = b""
    end: dict[str, Any] = field(default_factory=dict)
    console: list[str] = field(default_factory=list)


def watch(page: Any, stack: launch.Stack, w: Watched3d) -> None:
    """Sample the page until the mission ends, then a screenshot of the steady page."""
    result: dict[str, launch.Outcome] = {}
    follower = threading.Thread(target=lambda: result.setdefault(
        "outcome", launch.follow(stack, timeout_s=180.0, quiet=True)), daemon=True)
    follower.start()
    open_page(page, stack.web_url(), logs_in(stack.logs))
    while follower.is_alive():
        w.samples.append(page.evaluate(SAMPLE_JS))
        time.sleep(0.15)
    follower.join()
    # the page draws every 250 ms: it shows the final state (published as the mission's last
    # step ended) before it is frozen for the steady screenshot
    w.outcome = result.get("outcome", launch.Outcome(False, message="follow raised"))
    if w.outcome.ended:
        final = record(w.run_dir)[1]["steps"]
        wait_for(lambda: page.evaluate(SAMPLE_JS)["step"] == [final], 10,
                 f"the page to show the final state (step {final})", logs_in(stack.logs))

    def steady() -> Any:
        shot = frozen_shots(page)
        return None if shot is None else (shot[0].png, page.evaluate(SAMPLE_JS))

    w.end_png, w.end = wait_for(steady, 10, "a steady page after the mission's end")


@pytest.fixture(scope="module")
def watched3d(tmp_path_factory: pytest.TempPathFactory) -> Watched3d:
    run_dir = tmp_path_factory.mktemp("web3d") / "web-cc-3d-s0"
    cfg = launch.StackConfig(run_dir=run_dir, mission=MISSION, speed_factor=SPEED,
                             free_ports=True, uav_id=UAV, log_format="text",
                             profiles=("viewer",))
    stack = launch.Stack(cfg)
    w = Watched3d(run_dir, launch.Outcome(False), {})
    with chromium() as browser:
        with stack:
            router_ready(stack.endpoint, logs_in(stack.logs))
            page = browser.page()
            watch(page, stack, w)
            page.close()  # before the stack stops: the page would report its lost connection
        w.codes = {p.name: int(p.popen.returncode) for p in stack.group.procs}
        w.console = browser.console
    (w.run_dir / "web_view_3d.png").write_bytes(w.end_png)
    if os.environ.get(REFRESH_DOCS) == "1":
        (FIGURES / "web_view_3d.png").write_bytes(w.end_png)
    return w


def recorded_positions(run_dir: Path) -> np.ndarray:
    """The supervisor's recorded 3-D positions, step by step, then the final one."""
    steps, end = record(run_dir)
    return np.array([steps[t]["state"][:3] for t in sorted(steps)] + [end["final_state"][:3]])


def test_the_label_and_the_altitude_follow_the_supervisors_record(watched3d: Watched3d) -> None:
    w = watched3d
    logs = logs_in(w.run_dir)
    check(w.outcome.ended and w.outcome.success, "the 3-D mission to reach the goal", logs,
          w.outcome)
    steps, end = record(w.run_dir)
    seen: dict[int, tuple[float, str]] = {}
    for s in w.samples:
        if s["uav"]:
            assert s["uav"] == [UAV]
            seen[s["step"][0]] = (s["altitude"][0], s["label"][0])
    assert len(seen) >= 10, sorted(seen)
    for step, (altitude, label) in seen.items():
        z = float(expected_state(steps, end, step)[2])
        assert altitude == pytest.approx(z, abs=1e-6), step
        assert label.endswith(f" t={step} z={z:.1f} m"), (step, label)
    flown = [a for a, _ in seen.values()]
    assert max(flown) - min(flown) > 5.0  # the page saw the vehicle climb or sink


def test_the_trail_holds_the_recorded_path_with_each_segments_mean_altitude(
        watched3d: Watched3d) -> None:
    w, end = watched3d, watched3d.end
    path = recorded_positions(w.run_dir)
    points = [(xs[0], ys[0]) for xs, ys in zip(end["trail_xs"], end["trail_ys"], strict=True)]
    points.append((end["trail_xs"][-1][1], end["trail_ys"][-1][1]))
    # every trail point is a recorded position, in the order flown (the page may miss a state)
    at, matched = 0, []
    for p in points:
        while at < len(path) and not np.allclose(path[at, :2], p, atol=1e-6):
            at += 1
        assert at < len(path), f"trail point {p} is not a recorded position after the last"
        matched.append(at)
    assert len(matched) >= len(path) // 2, (len(matched), len(path))
    assert matched[-1] == len(path) - 1  # the trail ends where the mission did
    z = path[matched, 2]
    assert end["trail_altitude"] == pytest.approx(list(0.5 * (z[:-1] + z[1:])), abs=1e-9)
    assert end["bar"] is True
    assert (end["low"], end["high"]) == pytest.approx(
        (float(np.min(0.5 * (z[:-1] + z[1:]))), float(np.max(0.5 * (z[:-1] + z[1:])))))


def viridis_rgb(altitude: float, low: float, high: float) -> np.ndarray:
    """The colour a linear mapper over [low, high] gives ``altitude`` on Viridis256."""
    i = min(int(math.floor((altitude - low) / (high - low) * 256)), 255)
    hexa = Viridis256[max(i, 0)]
    return np.array([int(hexa[k:k + 2], 16) for k in (1, 3, 5)], dtype=float)


def test_the_trail_is_drawn_in_the_colour_of_its_altitude(watched3d: Watched3d) -> None:
    from PIL import Image

    w, end = watched3d, watched3d.end
    z = recorded_positions(w.run_dir)[:, 2]
    low, high = float(end["low"]), float(end["high"])
    rgb = np.asarray(Image.open(io.BytesIO(w.end_png)).convert("RGB")).astype(int)
    marker = np.array(end["marker_px"][0])
    judged = []
    for (a, b), altitude in zip(end["trail_px"], end["trail_altitude"], strict=True):
        a, b = np.array(a), np.array(b)
        mid = 0.5 * (a + b)
        if np.linalg.norm(b - a) < SEGMENT_MIN_PX or np.linalg.norm(mid - marker) < MARKER_CLEAR_PX:
            continue
        x, y = int(round(mid[0])), int(round(mid[1]))
        patch = rgb[y - 1:y + 2, x - 1:x + 2].reshape(-1, 3)
        judged.append((np.median(patch, axis=0), viridis_rgb(altitude, low, high), altitude))
    assert len(judged) >= 10, len(judged)
    near = [np.abs(got - want).max() <= 40 for got, want, _ in judged]
    assert np.mean(near) >= 0.8, [(got.tolist(), want.tolist(), a) for got, want, a in judged]
    # the colours differ as the altitudes do: the lowest and the highest segment judged
    lo = min(judged, key=lambda j: j[2])
    hi = max(judged, key=lambda j: j[2])
    assert hi[2] - lo[2] > 5.0 and np.abs(hi[0] - lo[0]).max() > 60, (lo, hi, z.min(), z.max())


def test_the_page_and_the_stack_stopped_cleanly(watched3d: Watched3d) -> None:
    w = watched3d
    assert not [c for c in w.console if c.startswith(("pageerror", "error"))], w.console
    check(w.codes.get("viewer") == 0, "the viewer to exit with 0",
          [w.run_dir / "logs" / "viewer.log"], w.codes)
