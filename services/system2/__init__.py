"""System 2 service: the slow, deliberate MPC planner (``python -m services.system2``)."""
