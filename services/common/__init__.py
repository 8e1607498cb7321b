"""What every service shares: keys, bus, codec, clock, CLI settings and logging."""
