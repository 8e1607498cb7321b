"""Integration tests: real service processes on loopback."""
