"""A real headless browser for the web page's tests: Debian's chromium driven by playwright.

Playwright's own browser builds are never downloaded (they cannot be here, nor
on CI): it drives ``/usr/bin/chromium`` (scripts/install_browser.sh, run by
``make test``) through ``executable_path``, headless, without GPU, sandbox,
background networking, component updates or sync, in a fresh profile. Every
request the page makes is recorded (:attr:`Browser.requests`), so a test can
check that nothing was fetched from anywhere but the page's own server.
"""

from __future__ import annotations

import os
import tempfile
import urllib.parse
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import pytest

CHROMIUM = os.environ.get("CHROMIUM", "/usr/bin/chromium")
ARGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run")
VIEWPORT_PX = (1600, 900)


@dataclass
class Browser:
    """A browser context; :meth:`page` opens a tab whose requests and console lines are kept."""

    context: Any
    requests: list[str] = field(default_factory=list)
    console: list[str] = field(default_factory=list)

    def page(self) -> Any:
        page = self.context.new_page()
        page.on("request", lambda r: self.requests.append(r.url))
        page.on("console", lambda m: self.console.append(f"{m.type}: {m.text}"))
        page.on("pageerror", lambda e: self.console.append(f"pageerror: {e}"))
        return page

    def hosts(self) -> set[str]:
        """``scheme://host:port`` of every request made so far."""
        return {f"{u.scheme}://{u.netloc}" for u in map(urllib.parse.urlparse, self.requests)}


@contextmanager
def chromium() -> Iterator[Browser]:
    """Debian's chromium, headless, in a fresh profile (fails, not skips, when it is missing)."""
    if not os.access(CHROMIUM, os.X_OK):
        pytest.fail(f"{CHROMIUM} is missing: `make browser` (scripts/install_browser.sh, as root) "
                    "installs Debian's chromium", pytrace=False)
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory(prefix="dualpilot-chromium-") as profile, \
            sync_playwright() as pw:
        context = pw.chromium.launch_persistent_context(
            profile, executable_path=CHROMIUM, headless=True, args=list(ARGS),
            viewport={"width": VIEWPORT_PX[0], "height": VIEWPORT_PX[1]})
        try:
            yield Browser(context)
        finally:
            context.close()
