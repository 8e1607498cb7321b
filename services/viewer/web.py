"""The web page's server: Bokeh's (Tornado), in a thread of its own, serving the page offline.

The page and BokehJS come from this process (``/static/`` out of the bokeh
wheel: no CDN, nothing fetched at run time); each browser session gets its own
document (services/viewer/page.py) over Bokeh's WebSocket. :class:`WebServer`
starts the server on its own asyncio loop and stops it from any thread.
"""

from __future__ import annotations

import asyncio
import logging
import threading
from collections.abc import Callable, Sequence
from typing import Any

from services.common.log import fields

from .page import Page
from .picture import Frame

log = logging.getLogger("services.viewer.web")

DEFAULT_WEB_LISTEN = "tcp/127.0.0.1:8766"
#: the page's path
APP_PATH = "/"


def origins(host: str, port: int, extra: Sequence[str] = ()) -> list[str]:
    """The ``Origin`` hosts whose browsers may open the page's WebSocket: this address, its
    loopback names and ``extra`` (e.g. a host name the page is reached by)."""
    hosts = ["localhost", "127.0.0.1"] + ([host] if host not in ("0.0.0.0", "::", "") else [])
    return sorted({f"{h}:{port}" for h in hosts} | {e for e in extra if e})


def _bokeh_logs_through_ours() -> None:
    """Bokeh prints its log lines itself when imported before logging is set up: send them
    through this service's handlers (services/common/log.py) instead."""
    from bokeh.util import logconfig

    if logconfig.default_handler is not None:
        logging.getLogger("bokeh").removeHandler(logconfig.default_handler)
        logging.getLogger("bokeh").propagate = True


class WebServer:
    """Bokeh's server for the page, in a thread: ``start()`` returns its URL, ``stop()`` ends
    it. ``port`` is a real port (the allowed origins name it). Live, ``frames`` gives the
    newest frame; a replay of ``replay_steps`` steps takes each session's from ``step_frames``
    (its slider's step)."""

    def __init__(self, host: str, port: int, title: str, frames: Callable[[], Frame] | None,
                 step_frames: Callable[[int], Frame] | None = None, replay_steps: int = 0,
                 allow_origins: Sequence[str] = ()):
        self.host, self.port, self.title = host, port, title
        self.frames, self.step_frames, self.replay_steps = frames, step_frames, replay_steps
        self.allow_origins = allow_origins
        self.server: Any = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="web-page", daemon=True)

    def make_document(self, doc: Any) -> None:
        Page(doc, self.title, self.frames, self.step_frames, self.replay_steps)

    def _run(self) -> None:
        _bokeh_logs_through_ours()
        from bokeh.application import Application
        from bokeh.application.handlers.function import FunctionHandler
        from bokeh.server.server import Server
        from tornado.ioloop import IOLoop

        asyncio.set_event_loop(asyncio.new_event_loop())
        try:
            self.server = Server({APP_PATH: Application(FunctionHandler(self.make_document))},
                                 io_loop=IOLoop.current(), address=self.host, port=self.port,
                                 allow_websocket_origin=origins(self.host, self.port,
                                                                self.allow_origins),
                                 check_unused_sessions_milliseconds=2000,
                                 unused_session_lifetime_milliseconds=5000)
            self.server.start()
        except BaseException as err:
            self._error = err
            self._ready.set()
            return
        self._ready.set()
        self.server.io_loop.start()

    @property
    def url(self) -> str:
        host = "127.0.0.1" if self.host in ("0.0.0.0", "::", "") else self.host
        return f"http://{host}:{self.port}{APP_PATH}"

    def start(self, timeout_s: float = 30.0) -> str:
        """Start serving; the page's URL. Raises what the server raised (e.g. a taken port)."""
        self._thread.start()
        if not self._ready.wait(timeout_s):
            raise TimeoutError(f"the web page's server did not start within {timeout_s} s")
        if self._error is not None:
            raise self._error
        log.info("serving the web page", extra=fields(url=self.url, port=self.port))
        return self.url

    def stop(self) -> None:
        if self.server is None or not self._thread.is_alive():
            return
        loop = self.server.io_loop

        def halt() -> None:
            self.server.stop(wait=False)
            loop.stop()

        loop.add_callback(halt)
        self._thread.join(5.0)
        log.info("web page stopped", extra=fields(url=self.url))
