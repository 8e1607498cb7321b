"""dualpilot services: thin processes around the core, talking over Zenoh and MAVLink.

Each service runs with ``python -m services.<name>`` (ews, system1, system2,
supervisor, uavsim); ``python -m services.launch`` starts the whole stack.
"""
