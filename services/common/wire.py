"""Bytes on the bus ↔ protobuf messages: type names, encodings, parsing, headers and stamps.

Zenoh encoding ``application/protobuf;<full type name>``; every message's header
carries the schema version, sequence, source, vehicle id and stamps (ARCHITECTURE §5).
:func:`parse` rejects what is too large, of another type, does not parse, or comes
from another schema version (:class:`~services.common.rejections.CodecError`).
"""

from __future__ import annotations

import time
from typing import TypeVar

from google.protobuf.message import DecodeError, Message

from services.common.limits import check_floats, check_text
from services.common.rejections import CodecError, Reason, invalid
from services.msgs import common_pb2

SCHEMA_VERSION = 1
MAX_PAYLOAD_BYTES = 8 * 1024 * 1024  # any one message on the bus (a mission's are ≪ 1 MB)
#: Encodings a payload may carry besides ``application/protobuf;<its type>``
#: (a sender that does not name the type, e.g. a raw ``zenoh/bytes`` query).
NEUTRAL_ENCODINGS = frozenset({"", "zenoh/bytes", "application/octet-stream",
                               "application/protobuf"})

M = TypeVar("M", bound=Message)


def full_name(msg_or_cls: Message | type[Message]) -> str:
    return str(msg_or_cls.DESCRIPTOR.full_name)


def encoding_name(msg_or_cls: Message | type[Message]) -> str:
    """Zenoh encoding string: ``application/protobuf;<full type name>``."""
    return f"application/protobuf;{full_name(msg_or_cls)}"


def parse(payload: bytes, cls: type[M], encoding: str | None = None,
          max_bytes: int = MAX_PAYLOAD_BYTES) -> M:
    """Parse ``payload`` as ``cls`` and check its header; raises CodecError.

    Rejects a payload over ``max_bytes``, an ``encoding`` other than
    ``application/protobuf;<cls>`` or a neutral one (:data:`NEUTRAL_ENCODINGS`),
    bytes that do not parse, and a header of another schema version.
    """
    if len(payload) > max_bytes:
        raise invalid(f"{full_name(cls)} payload of {len(payload)} bytes exceeds {max_bytes}",
                      Reason.TOO_LARGE)
    if encoding and encoding not in NEUTRAL_ENCODINGS and encoding != encoding_name(cls):
        raise invalid(f"expected {full_name(cls)}, got encoding {encoding[:200]}",
                      Reason.WRONG_TYPE)
    msg = cls()
    try:
        msg.ParseFromString(bytes(payload))
    except (DecodeError, RuntimeError, ValueError, RecursionError) as err:
        raise CodecError(common_pb2.ERROR_CODE_MALFORMED,
                         f"{full_name(cls)} does not parse: {err}", Reason.MALFORMED) from err
    if "header" in cls.DESCRIPTOR.fields_by_name:
        check_header(msg.header)  # type: ignore[attr-defined]
    return msg


def check_header(h: common_pb2.Header) -> None:
    if h.schema_version != SCHEMA_VERSION:
        raise invalid(f"schema_version {h.schema_version}, this build speaks {SCHEMA_VERSION}",
                      Reason.SCHEMA_VERSION)
    check_floats([h.sim_time_s], "header sim_time_s", 1e12)
    if h.sim_time_s < 0:
        raise invalid(f"header sim_time_s must be >= 0, got {h.sim_time_s}", Reason.OUT_OF_RANGE)
    check_text(h.source, "header.source", 256)
    check_text(h.vehicle_id, "header.vehicle_id", 256)


class Stamper:
    """Fills headers for one sender: schema version, source, vehicle id, sequence, stamps."""

    def __init__(self, source: str, vehicle_id: str):
        self.source = source
        self.vehicle_id = vehicle_id
        self.seq = 0

    def stamp(self, header: common_pb2.Header, sim_time_s: float = 0.0) -> int:
        self.seq += 1
        header.schema_version = SCHEMA_VERSION
        header.seq = self.seq
        header.source = self.source
        header.vehicle_id = self.vehicle_id
        header.sim_time_s = float(sim_time_s)
        header.wall_time_ns = time.time_ns()
        return self.seq
