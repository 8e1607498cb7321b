"""Rejected inputs: the errors a decoder raises, counted per key and reason and logged.

A bad message raises :class:`CodecError` (a ValueError) with a code (MALFORMED: does
not parse; INVALID: parses but fails validation) and a ``reason`` from the closed set
:class:`Reason` (why, for counters); services call :func:`rejected`, which counts it
per input key and reason in :data:`REJECTED` (served as each service's status,
services/common/bus.py) and logs one line per rejection, rate-limited so a flood
cannot fill the disk. Services never crash on input.
"""

from __future__ import annotations

import collections
import logging
import threading
import time
from enum import StrEnum

from services.msgs import common_pb2

log = logging.getLogger(__name__)


class Reason(StrEnum):
    """Why an input was rejected: the closed set the counters use."""

    MALFORMED = "malformed"            # does not parse
    TOO_LARGE = "too_large"            # payload over MAX_PAYLOAD_BYTES
    WRONG_TYPE = "wrong_type"          # encoding names another message type
    SCHEMA_VERSION = "schema_version"  # header from another version of the contract
    NOT_FINITE = "not_finite"          # NaN or ±inf where a number is needed
    OUT_OF_RANGE = "out_of_range"      # a number or coordinate outside its range or the area
    SIZE = "size"                      # too many or too few items, a wrong length
    INVALID = "invalid"                # anything else: missing field, unknown enum, geometry...
    OVERFLOW = "overflow"              # dropped: the service's inbox was full
    STALE = "stale"                    # about another revision than the one held (a forecast)
    UNAVAILABLE = "unavailable"        # names by reference what cannot be had here (a
                                       # forecast the EWS nearby does not give)
    # MAVLink links of the vehicle (services/uavsim): frames that are not usable MAVLink 2
    BAD_CRC = "bad_crc"                # a frame whose checksum does not match
    UNKNOWN_MESSAGE = "unknown_message"  # a message id the dialect does not define
    MAVLINK1 = "mavlink1"              # a MAVLink 1 frame (only its HEARTBEAT is accepted)
    WRONG_TARGET = "wrong_target"      # addressed to another system or component
    UNSIGNED = "unsigned"              # unsigned or wrongly signed on a signed link


class CodecError(ValueError):
    """A message that cannot be used; ``code`` is an ErrorCode value, ``reason`` a Reason."""

    def __init__(self, code: common_pb2.ErrorCode, message: str,
                 reason: Reason = Reason.INVALID):
        super().__init__(message)
        self.code = code
        self.reason = reason


def invalid(message: str, reason: Reason = Reason.INVALID) -> CodecError:
    return CodecError(common_pb2.ERROR_CODE_INVALID, message, reason)


class Rejections:
    """Rejected inputs of this process per key and :class:`Reason` (thread-safe).

    ``key`` is the Zenoh key the input came in on; a caller that does not
    know it passes a label (the message kind), which :meth:`alias` can map to
    the key. At most ``max_keys`` keys are kept, the rest count under
    ``"(other)"``. Log lines are a token bucket (``log_burst`` lines, then
    ``log_per_s`` a second); the lines it holds back are counted and reported
    on the next line that is written.
    """

    OTHER = "(other)"

    def __init__(self, max_keys: int = 256, log_burst: float = 20.0, log_per_s: float = 2.0):
        self.max_keys = max_keys
        self.log_burst = log_burst
        self.log_per_s = log_per_s
        self._lock = threading.Lock()
        self._counts: dict[str, collections.Counter[str]] = {}
        self._aliases: dict[str, str] = {}
        #: rejections by the label callers passed (the message kind), as before keys existed
        self.by_label: collections.Counter[str] = collections.Counter()
        self._tokens = log_burst
        self._refilled = time.monotonic()
        self.suppressed = 0  # log lines held back since the last one written
        self.suppressed_total = 0

    def alias(self, label: str, key: str) -> None:
        """Count rejections reported under ``label`` as rejections on ``key``."""
        with self._lock:
            self._aliases[label] = key

    def add(self, key: str, reason: str, label: str | None = None) -> tuple[str, int, int]:
        """Count one rejection; returns (key counted under, its total, lines to log: 0 or
        1 + the number held back before it)."""
        with self._lock:
            self.by_label[label or key] += 1
            key = self._aliases.get(key, key)
            if key not in self._counts and len(self._counts) >= self.max_keys:
                key = self.OTHER
            counts = self._counts.setdefault(key, collections.Counter())
            counts[reason] += 1
            now = time.monotonic()
            self._tokens = min(self.log_burst,
                               self._tokens + (now - self._refilled) * self.log_per_s)
            self._refilled = now
            if self._tokens < 1.0:
                self.suppressed += 1
                self.suppressed_total += 1
                return key, sum(counts.values()), 0
            self._tokens -= 1.0
            held, self.suppressed = self.suppressed, 0
            return key, sum(counts.values()), 1 + held

    def snapshot(self) -> dict[str, dict[str, int]]:
        """{key: {reason: count}} (a copy)."""
        with self._lock:
            return {k: dict(c) for k, c in self._counts.items()}

    def total(self) -> int:
        with self._lock:
            return sum(sum(c.values()) for c in self._counts.values())

    def clear(self) -> None:
        with self._lock:
            self._counts.clear()
            self.by_label.clear()


#: Rejected inputs of this process per key and reason (each service serves it as its status);
#: ``REJECTED.by_label``: by kind (the label passed to :func:`rejected`) since the process started.
REJECTED = Rejections()


def rejected(what: str, err: Exception, logger: logging.Logger = log, key: str | None = None,
             reason: str | None = None) -> None:
    """Count a rejected input under ``key`` (default: ``what``, or its alias) and log it.

    Never raises. The log line is rate-limited (see :class:`Rejections`);
    the counters are exact.
    """
    try:
        why = str(reason or getattr(err, "reason", Reason.INVALID))
        counted, n, lines = REJECTED.add(key or what, why, what)
        if lines:
            code = getattr(err, "code", common_pb2.ERROR_CODE_INVALID)
            logger.warning(
                "rejected %s on %s (%s): %s", what, counted, why, str(err)[:500],
                extra={"fields": {"what": what, "key": counted, "reason": why,
                                  "code": common_pb2.ErrorCode.Name(code),
                                  "rejections": n, "suppressed_before": lines - 1}},
            )
    except Exception:  # counting must never take a service down
        log.exception("could not count a rejection")
