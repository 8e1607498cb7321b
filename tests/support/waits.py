"""Waits that explain themselves: what was awaited, for how long, and the processes' last lines.

A wait in an end-to-end test is a timeout, not an assertion on the scheduler:
it polls a condition (a message, a token, a file) and, if the condition never
holds, fails with a message a reader of CI's output can act on. Every wait
names what it waited for and the logs of the processes involved, whose last
lines are appended to the failure (:func:`tail`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any, TypeVar

import pytest

T = TypeVar("T")

#: lines of each process log a failed wait shows
TAIL_LINES = 40

#: where a log comes from: a path, or a callable giving its text
LogSource = Path | str | Callable[[], str]
Logs = Mapping[str, LogSource] | Iterable[Path] | None


def _text(source: LogSource) -> str:
    if callable(source):
        try:
            return source()
        except Exception as err:  # a failing log reader must not hide the wait's failure
            return f"(log not readable: {err})"
    path = Path(source)
    try:
        return path.read_text(errors="replace")
    except OSError as err:
        return f"(no log at {path}: {err.strerror})"


def _named(logs: Logs) -> list[tuple[str, LogSource]]:
    if logs is None:
        return []
    if isinstance(logs, Mapping):
        return list(logs.items())
    return [(Path(p).name, p) for p in logs]


def tail(logs: Logs, lines: int = TAIL_LINES) -> str:
    """The last ``lines`` lines of each log, under a header naming it ("" without logs)."""
    parts = []
    for name, source in _named(logs):
        text = _text(source).rstrip("\n").splitlines()
        shown = "\n".join(text[-lines:]) if text else "(empty)"
        parts.append(f"--- last {min(lines, len(text))} lines of {name} ---\n{shown}")
    return "\n".join(parts)


def logs_in(directory: Path, pattern: str = "*.log") -> list[Path]:
    """Every log file under ``directory`` (recursively), sorted: a run directory's logs."""
    return sorted(directory.rglob(pattern)) if directory.is_dir() else []


def explain(what: str, logs: Logs = None, detail: str = "") -> str:
    """A failure message: what was expected, a detail (the last value seen) and the logs."""
    parts = [what]
    if detail:
        parts.append(detail)
    shown = tail(logs)
    if shown:
        parts.append(shown)
    return "\n".join(parts)


def wait_for(pred: Callable[[], T | None], timeout_s: float, what: str, logs: Logs = None,
             period_s: float = 0.05, last: Callable[[], Any] | None = None) -> T:
    """Poll ``pred`` until it returns a truthy value (returned) or ``timeout_s`` passes.

    On timeout the test fails with "timed out after N s waiting for <what>", the
    value of ``last()`` (what was seen instead) and the tails of ``logs``.
    """
    deadline = time.monotonic() + timeout_s
    while True:
        got = pred()
        if got:
            return got
        if time.monotonic() >= deadline:
            break
        time.sleep(period_s)
    got = pred()
    if got:
        return got
    detail = ""
    if last is not None:
        try:
            detail = f"last seen: {last()!r}"[:2000]
        except Exception as err:
            detail = f"last seen: (unavailable: {err})"
    pytest.fail(explain(f"timed out after {timeout_s:g} s waiting for {what}", logs, detail),
                pytrace=False)


def check(ok: object, what: str, logs: Logs = None, detail: object = "") -> None:
    """Fail with ``what``, ``detail`` and the logs' tails unless ``ok``: an assertion on an
    outcome some processes produced, so a failure shows their last lines."""
    if not ok:
        pytest.fail(explain(what, logs, str(detail)[:4000] if detail != "" else ""),
                    pytrace=False)
