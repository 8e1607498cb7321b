"""The supervisor service: decision loop, offboard companion (``python -m services.supervisor``)."""
