"""dualpilot: dual-process (fast and slow) UAV planning for disaster response.

The pure core of Papaioannou et al., "Synergising Human-like Responses and
Machine Intelligence for Planning in Disaster Response". It imports no
network code (no zenoh, pymavlink or generated messages).
"""

__version__ = "0.1.0"
