"""Generated protobuf messages of dualpilot.v1 (``make proto``; do not edit)."""
