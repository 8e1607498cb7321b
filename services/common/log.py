"""The one place that configures logging for a service process.

Structured logs on stderr: one JSON object per line (``LOG_FORMAT=json``, the
default) or ``key=value`` text (``LOG_FORMAT=text``); level from ``LOG_LEVEL``.
Modules log with ``logging.getLogger(__name__)`` and pass structured fields as
``log.info("plan sent", extra=fields(step=3, system=1))``.
"""

from __future__ import annotations

import json
import logging
import math
import os
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

_FIELDS = "fields"
_THREAD = threading.local()


def tag_vehicle(uav: str | None) -> None:
    """Log lines of the calling thread name vehicle ``uav`` (a fleet process's vehicle thread;
    None: the process's own again)."""
    if uav is None:
        _THREAD.__dict__.pop("uav", None)
    else:
        _THREAD.uav = uav


def vehicle_tag() -> str | None:
    """The vehicle the calling thread's log lines name (None: the process's own)."""
    uav = getattr(_THREAD, "uav", None)
    return None if uav is None else str(uav)


def _uav(default: str) -> str:
    return str(getattr(_THREAD, "uav", default))


def vehicle_thread(target: Callable[..., Any]) -> Callable[..., Any]:
    """``target`` wrapped to tag its thread with the calling thread's vehicle (if tagged), for
    the threads a fleet process's vehicle thread starts."""
    uav = getattr(_THREAD, "uav", None)
    if uav is None:
        return target

    def run(*args: Any, **kwargs: Any) -> Any:
        tag_vehicle(uav)
        return target(*args, **kwargs)

    return run


def fields(**kv: Any) -> dict[str, dict[str, Any]]:
    """``extra=`` argument carrying structured fields."""
    return {_FIELDS: kv}


def _plain(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return str(v)
    if isinstance(v, (str, int, float, bool)) or v is None:
        return v
    return str(v)


class JsonFormatter(logging.Formatter):
    def __init__(self, service: str, uav: str):
        super().__init__()
        self.service = service
        self.uav = uav

    def format(self, record: logging.LogRecord) -> str:
        doc: dict[str, Any] = {
            "ts": time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(record.created))
            + f".{int(record.msecs):03d}Z",
            "level": record.levelname.lower(),
            "service": self.service,
            "uav": _uav(self.uav),
            "logger": record.name,
            "msg": record.getMessage(),
        }
        for k, v in getattr(record, _FIELDS, {}).items():
            doc[k] = _plain(v)
        if record.exc_info:
            doc["exc"] = self.formatException(record.exc_info)
        return json.dumps(doc, ensure_ascii=False)


class TextFormatter(logging.Formatter):
    def __init__(self, service: str, uav: str):
        super().__init__()
        self.service, self.uav = service, uav

    def format(self, record: logging.LogRecord) -> str:
        ts = time.strftime("%H:%M:%S", time.localtime(record.created)) + f".{int(record.msecs):03d}"
        kv = " ".join(f"{k}={_plain(v)}" for k, v in getattr(record, _FIELDS, {}).items())
        prefix = f"{self.service}[{_uav(self.uav)}]"
        line = f"{ts} {record.levelname:<7} {prefix} {record.name}: {record.getMessage()}"
        line = f"{line} {kv}" if kv else line
        if record.exc_info:
            line += "\n" + self.formatException(record.exc_info)
        return line


def configure(service: str, uav: str, level: str | None = None, fmt: str | None = None) -> None:
    """Install the stderr handler on the root logger (idempotent)."""
    level = (level or os.environ.get("LOG_LEVEL", "INFO")).upper()
    fmt = (fmt or os.environ.get("LOG_FORMAT", "json")).lower()
    if fmt not in ("json", "text"):
        raise ValueError(f"LOG_FORMAT must be json or text, got {fmt!r}")
    handler = logging.StreamHandler(sys.stderr)
    formatter = JsonFormatter if fmt == "json" else TextFormatter
    handler.setFormatter(formatter(service, uav))
    root = logging.getLogger()
    for old in list(root.handlers):
        root.removeHandler(old)
    root.addHandler(handler)
    root.setLevel(level)
    # OMPL/cvxpy/matplotlib chatter stays at warnings
    for noisy in ("matplotlib", "cvxpy", "PIL"):
        logging.getLogger(noisy).setLevel(max(logging.WARNING, root.level))
