"""Protobuf messages ↔ core dataclasses, one module per .proto file (ARCHITECTURE §5).

The only place messages are built or read: ``common`` (geometry, the clock,
errors), ``config`` (the mission configuration), ``fire``, ``plan``,
``supervisor`` and ``vehicle``. Every decoder validates what the core would
otherwise trust and raises :class:`~services.common.rejections.CodecError`;
bytes ↔ messages is services/common/wire.py, MAVLink services/common/mavlink_codec.py.
"""
