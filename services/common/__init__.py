"""What every service shares: keys, bus, clock, CLI settings and logging, and the codec:
wire (bytes ↔ protobuf messages), convert/ (messages ↔ core types, one module per .proto),
mavlink_codec (MAVLink ↔ core types), limits (the ranges every decoder checks) and
rejections (the counted, logged errors of a bad input)."""
