"""End-to-end tests: the whole stack flies a mission."""
