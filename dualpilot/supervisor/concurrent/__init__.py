"""The concurrent supervisor: System 2 deliberates while the UAV flies (docs/concurrent.md).

``rule.py``: its rule and parameters; ``planning.py``: its state over a mission in the
mission step.
"""
