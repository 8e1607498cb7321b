"""The live view: the stack's missions over the Foxglove WebSocket protocol."""
