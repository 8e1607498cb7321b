"""The vehicle's telemetry log on a disk that may fail: a write error never stops the vehicle.

A full disk (ENOSPC), a read-only or vanished directory: the first failed
write is logged, counted (``storage/tlog``, reason ``write_error``, on the
status queryable) and reported to the ground station (STATUSTEXT, through
``on_fault``); the log then stops and the vehicle flies on (the policy: the
tlog is a record, not a flight function).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

from services.common import mav, rejections
from services.common.log import fields

log = logging.getLogger("services.uavsim")

WRITE_ERROR = "write_error"
KEY = "storage/tlog"


class SafeTlog(mav.Tlog):
    """A :class:`services.common.mav.Tlog` whose write errors end the log, not the process."""

    def __init__(self, path: str | Path, on_fault: Callable[[str], None] | None = None):
        self.failed = ""
        self.on_fault = on_fault
        self.errors = 0
        super().__init__(path)

    def write(self, frame: bytes, t_s: float | None = None) -> None:
        if self.failed:
            return
        try:
            super().write(frame, t_s)
        except (OSError, ValueError) as err:
            self._fail(err)

    def _fail(self, err: Exception) -> None:
        self.errors += 1
        self.failed = f"tlog write failed: {err}"
        rejections.rejected("tlog", rejections.invalid(self.failed), log, key=KEY,
                            reason=WRITE_ERROR)
        log.error("tlog stopped, the vehicle flies on", extra=fields(
            path=str(self.path), error=str(err), frames=self.frames))
        try:
            super().close()
        except OSError:
            self._fh = None
        if self.on_fault is not None:
            self.on_fault(self.failed)

    def close(self) -> None:
        try:
            super().close()
        except OSError as err:
            log.error("tlog close failed", extra=fields(path=str(self.path), error=str(err)))
            self._fh = None


def open_tlog(path: str, on_fault: Callable[[str], None] | None = None) -> SafeTlog | None:
    """The tlog at ``path``, or None (logged, counted) when it cannot be created."""
    try:
        return SafeTlog(path, on_fault)
    except OSError as err:
        rejections.rejected("tlog", rejections.invalid(f"tlog not created: {err}"), log, key=KEY,
                            reason=WRITE_ERROR)
        log.error("no tlog: the vehicle flies without one", extra=fields(path=path,
                                                                          error=str(err)))
        return None
