"""System 1 service: the fast, human-like planner (``python -m services.system1``)."""
