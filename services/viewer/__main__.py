"""Viewer service: every vehicle's mission, live, on a web page and over the Foxglove WebSocket
protocol.

``python -m services.viewer`` and open ``http://127.0.0.1:8766/`` in a browser
(the operations picture: services/viewer/page.py, served by Bokeh, offline), or
``ws://localhost:8765`` in Foxglove or Lichtblick (docs/live_view.md).
``python -m services.viewer --replay runs/latest/mission.mcap`` serves the page
of a finished run (services/viewer/replay.py), without Zenoh. Live, it
subscribes to what the stack publishes for any vehicle (``dualpilot/*/…``:
the supervisor's decision, plans, vehicle state and mission events, the EWS's
fires and forecast), validates each message in the codec (a rejection is
counted and logged, never a crash) and logs it on that vehicle's channels
(services/viewer/live.py; dualpilot/viz/foxglove.py defines them, as in
mission.mcap), served by foxglove-sdk's WebSocket server, and keeps the
newest of each in the web page's picture (services/viewer/picture.py). A vehicle's
channels are advertised when its first message arrives; the k-th vehicle's
area is placed k·(A + 100 m) east of the first in the ``world`` frame.

The Zenoh callbacks only enqueue; one loop decodes and logs. Of the fire
states and forecasts waiting in one pass only each vehicle's newest is drawn,
so a viewer that falls behind skips frames instead of queueing them; a skipped
frame is still checked (a bad one counted as rejected); the frames skipped are
logged when the viewer stops. The loops are services/viewer/serve.py.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from services.common import bus
from services.common import cli as common_cli

from .serve import DEFAULT_LISTEN, body, load_replay, parse_listen, replay_body, web_server
from .web import DEFAULT_WEB_LISTEN


def parser() -> Any:
    p = common_cli.parser("viewer", "The stack's missions, live, on a web page (Bokeh) and over "
                                    "the Foxglove WebSocket protocol (foxglove-sdk); or a run's "
                                    "mission.mcap replayed on the page.")
    p.add_argument("--listen", default=common_cli.env("VIEWER_LISTEN", DEFAULT_LISTEN),
                   help="where the WebSocket server listens, tcp/HOST:PORT [VIEWER_LISTEN]")
    p.add_argument("--port", type=int, default=None,
                   help="the WebSocket port (overrides --listen's; 0: any free port)")
    p.add_argument("--web-listen", default=common_cli.env("WEB_LISTEN", DEFAULT_WEB_LISTEN),
                   help="where the web page is served, tcp/HOST:PORT [WEB_LISTEN]")
    p.add_argument("--web-port", type=int, default=None,
                   help="the web page's port (overrides --web-listen's; 0: any free port)")
    p.add_argument("--web-origin", default=common_cli.env("WEB_ORIGIN", ""),
                   help="comma-separated HOST:PORT a browser may also reach the page by "
                        "(besides localhost and 127.0.0.1) [WEB_ORIGIN]")
    p.add_argument("--no-web", action="store_true", help="no web page (Foxglove only)")
    p.add_argument("--replay", nargs="+", type=Path, default=None, metavar="MCAP",
                   help="serve the page of these mission.mcap files (no Zenoh, no Foxglove "
                        "server): a step slider and a play button")
    return p


def main(argv: list[str] | None = None) -> int:
    p = parser()
    args = p.parse_args(argv)
    timeline = None
    try:
        settings = common_cli.settings("viewer", args)
        host, port = parse_listen(args.listen)
        if args.port is not None:
            if not 0 <= args.port <= 65535:
                raise ValueError(f"--port must be in 0..65535, got {args.port}")
            port = args.port
        web = web_server(args)
        if args.replay is not None:
            if web is None:
                raise ValueError("--replay serves the web page: drop --no-web")
            timeline = load_replay(args.replay)
    except ValueError as err:
        p.error(str(err))
    if timeline is not None:
        assert web is not None
        return bus.run_service(settings, lambda ctx: replay_body(ctx, timeline, web),
                               zenoh_session=False)
    return bus.run_service(settings, lambda ctx: body(ctx, host, port, web))


if __name__ == "__main__":
    bus.leave(main())
