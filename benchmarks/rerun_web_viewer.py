"""The alternative weighed for the web page: rerun's bundled web viewer, measured the same way.

rerun-sdk is not a dependency of the project: run this in a virtual environment of its own,

    python3 -m venv /tmp/rr && /tmp/rr/bin/pip install rerun-sdk==0.41.0 playwright==1.65.2 psutil
    /tmp/rr/bin/python benchmarks/rerun_web_viewer.py

It serves rerun's web viewer from the wheel (``rr.serve_grpc`` + ``rr.serve_web_viewer``),
logs a scene like the page's (the area, a vehicle moving with its trail, a fire region) at
5 Hz for ``--seconds``, opens it in Debian's headless chromium (software rendering: no GPU)
and reports the browser's CPU seconds per wall second, every host the page asked for, and
the installed size of rerun's packages; a screenshot goes to ``--shot``.
"""

from __future__ import annotations

import argparse
import importlib
import tempfile
import threading
import time
import urllib.parse
from pathlib import Path
from typing import Any

import psutil

ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run"]


def rerun() -> Any:
    """rerun-sdk (not a dependency of the project: see the module's docstring)."""
    return importlib.import_module("rerun")


def feed(stop: threading.Event) -> None:
    """The scene at 5 Hz: the area, the vehicle and its trail, a fire region."""
    rr = rerun()
    trail: list[list[float]] = []
    t = 0
    while not stop.is_set():
        rr.set_time("step", sequence=t)
        pos = [50.0 + 8.0 * t, 50.0 + 8.0 * t]
        trail.append(pos)
        rr.log("map/area", rr.Boxes2D(mins=[[0, 0]], sizes=[[1000, 1000]]))
        rr.log("map/fire", rr.Boxes2D(mins=[[300, 700]], sizes=[[80, 120]],
                                      colors=[[255, 64, 25]]))
        rr.log("map/trail", rr.LineStrips2D([trail]))
        rr.log("map/uav", rr.Points2D([pos], radii=8, colors=[[230, 51, 230]]))
        t += 1
        stop.wait(0.2)


def installed_mb() -> float:
    site = Path(rerun().__file__).resolve().parent.parent
    return sum(f.stat().st_size for d in ("rerun", "rerun_bindings", "rerun_cli")
               for f in (site / d).rglob("*") if f.is_file()) / 1e6


def main() -> None:
    from playwright.sync_api import sync_playwright

    rr = rerun()
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=20.0)
    p.add_argument("--port", type=int, default=9091)
    p.add_argument("--shot", type=Path, default=Path("runs/rerun_web_viewer.png"))
    args = p.parse_args()
    rr.init("dualpilot-compare")
    uri = rr.serve_grpc()
    rr.serve_web_viewer(web_port=args.port, open_browser=False, connect_to=uri)
    stop = threading.Event()
    threading.Thread(target=feed, args=(stop,), daemon=True).start()
    hosts: set[str] = set()
    with sync_playwright() as pw:
        ctx = pw.chromium.launch_persistent_context(
            tempfile.mkdtemp(), executable_path="/usr/bin/chromium", headless=True, args=ARGS,
            viewport={"width": 1600, "height": 900})
        page = ctx.new_page()
        page.on("request", lambda r: hosts.add(urllib.parse.urlparse(r.url).netloc))
        page.goto(f"http://127.0.0.1:{args.port}/?url={urllib.parse.quote(uri)}")
        time.sleep(5.0)  # the wasm viewer loads and connects

        def browser() -> float:
            return sum(sum(c.cpu_times()[:2]) for c in psutil.Process().children(recursive=True)
                       if "chrom" in c.name().lower())

        c0, t0 = browser(), time.monotonic()
        time.sleep(args.seconds)
        per_s = (browser() - c0) / (time.monotonic() - t0)
        args.shot.parent.mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(args.shot))
        ctx.close()
    stop.set()
    print(f"rerun-sdk {rr.__version__}: browser {per_s:.2f} CPU s/s over {args.seconds:g} s; "
          f"installed {installed_mb():.0f} MB; hosts asked for: {sorted(hosts)}")


if __name__ == "__main__":
    main()
