"""What the live view's web page costs: CPU of the browser and of the viewer, bytes loaded.

One cc mission (``--seed``, paper timing, ``--speed-factor``) through the stack
with the viewer (``python -m services.launch --viewer``), ``--rounds`` times with
the page open in headless chromium (Debian's, driven by playwright, as in
tests/e2e/test_web_view.py) and as many times without a browser, alternating.
Reported per case: CPU seconds per wall second of the mission of the browser's
processes and of the viewer process, the mission's wall time, and the
supervisor's tick-to-setpoint p99 (does the page disturb the stack?); with the
page, the bytes its first load fetched and from which hosts.

    .venv/bin/python benchmarks/web_view_cost.py --rounds 2
"""

from __future__ import annotations

import argparse
import json
import tempfile
import threading
import time
import urllib.parse
from pathlib import Path
from typing import Any

import harness  # the repository on the path: before its packages
import psutil

from dualpilot.mission.config import MissionConfig
from services import launch

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run"]


def cpu_s(procs: list[psutil.Process]) -> float:
    total = 0.0
    for p in procs:
        try:
            t = p.cpu_times()
            total += t.user + t.system
        except psutil.NoSuchProcess:
            pass
    return total


def browser_procs() -> list[psutil.Process]:
    return [p for p in psutil.Process().children(recursive=True)
            if "chrom" in (p.name() or "").lower()]


def open_page(pw: Any, url: str, out: dict[str, Any]) -> Any:
    """Chromium on ``url`` (retried while the viewer starts), its loaded bytes counted."""
    ctx = pw.chromium.launch_persistent_context(tempfile.mkdtemp(), executable_path=CHROMIUM,
                                                headless=True, args=ARGS,
                                                viewport={"width": 1600, "height": 900})
    page = ctx.new_page()
    sizes: list[int] = []
    page.on("response", lambda r: sizes.append(int(r.headers.get("content-length", 0) or 0)))
    page.on("request", lambda r: out.setdefault("hosts", set()).add(
        urllib.parse.urlparse(r.url).netloc))
    for _ in range(100):
        try:
            page.goto(url, timeout=10_000)
            break
        except Exception:
            time.sleep(0.3)
    page.wait_for_function("() => window.Bokeh !== undefined && Bokeh.documents.length > 0",
                           timeout=60_000)
    out["bytes"] = sum(sizes)
    return ctx


def one_mission(seed: int, speed: float, with_page: bool, out_dir: Path) -> dict[str, Any]:
    """Fly one mission with the viewer, the page open or not; what it cost."""
    cfg = launch.StackConfig(run_dir=out_dir, mission=MissionConfig(seed=seed),
                             speed_factor=speed, free_ports=True, log_format="text",
                             profiles=("viewer",))
    stack = launch.Stack(cfg)
    row: dict[str, Any] = {"page": with_page}
    with stack:
        launch.wait_router(stack.endpoint)
        viewer = psutil.Process(next(p for p in stack.group.procs
                                     if p.name == "viewer").popen.pid)
        result: dict[str, launch.Outcome] = {}
        follower = threading.Thread(target=lambda: result.setdefault(
            "o", launch.follow(stack, 300.0, quiet=True)))
        follower.start()
        ctx = pw_ctx = None
        if with_page:
            from playwright.sync_api import sync_playwright

            pw_ctx = sync_playwright().start()
            ctx = open_page(pw_ctx, stack.web_url(), row)
        t0, b0, v0 = time.monotonic(), cpu_s(browser_procs()), cpu_s([viewer])
        follower.join()
        wall = time.monotonic() - t0
        row["browser_cpu_per_s"] = (cpu_s(browser_procs()) - b0) / wall
        row["viewer_cpu_per_s"] = (cpu_s([viewer]) - v0) / wall
        if ctx is not None and pw_ctx is not None:
            ctx.close()
            pw_ctx.stop()
    summary = json.loads((out_dir / "summary.json").read_text())
    row.update(wall_s=round(wall, 1), ended=result["o"].ended,
               overhead_p99_ms=summary["stack"]["setpoint_overhead"]["p99_ms"])
    row["hosts"] = sorted(row.get("hosts", ()))
    return row


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seed", type=int, default=26)
    p.add_argument("--speed-factor", type=float, default=10.0)
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument("--out", type=Path, default=harness.REPO / "runs" / "web_view_cost")
    args = p.parse_args()
    rows = []
    for k in range(args.rounds):
        for with_page in (True, False):
            row = one_mission(args.seed, args.speed_factor, with_page,
                              args.out / f"r{k}-{'page' if with_page else 'none'}")
            print(json.dumps(row), flush=True)
            rows.append(row)
    for with_page in (True, False):
        sel = [r for r in rows if r["page"] == with_page]
        med = {key: float(sorted(r[key] for r in sel)[len(sel) // 2]) for key in (
            "browser_cpu_per_s", "viewer_cpu_per_s", "wall_s", "overhead_p99_ms")}
        print(f"{'page open' if with_page else 'no page  '}: browser "
              f"{med['browser_cpu_per_s']:.2f} CPU s/s, viewer {med['viewer_cpu_per_s']:.2f} "
              f"CPU s/s, mission {med['wall_s']:.1f} s wall, tick→setpoint p99 "
              f"{med['overhead_p99_ms']:.1f} ms (median of {len(sel)})")
    loads = [r for r in rows if r["page"]]
    print(f"page load: {loads[0]['bytes'] / 1e6:.2f} MB from {loads[0]['hosts']}")


if __name__ == "__main__":
    main()
