"""The lookahead supervisor: the concurrent choice, guarded by the known future
(docs/yardstick.md).

``rule.py``: its rule and parameters; ``planning.py``: its state over a mission in the
mission step.
"""
