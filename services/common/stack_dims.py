"""The dimensions of the missions the stack flies (docs/three_d.md).

The stack flies the top-down evaluation only: MAVLink setpoints are streamed at one
altitude (the supervisor's ``--altitude-m``), and neither the plan request nor the fires
on the wire carry an altitude or a height yet. A mission of another dimension is refused
where it enters the stack (the supervisor's and the launcher's flags), before any
service is asked, with the controller's own refusal first (dualpilot/mission/dimension.py).
"""

from __future__ import annotations

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.dimension import check_dimension

__all__ = ["STACK_DIMS", "check_stack_dimension"]

#: the dimensions (``DynamicsParams.dim``) of the missions the stack flies
STACK_DIMS = frozenset({2})


def check_stack_dimension(config: MissionConfig) -> None:
    """Nothing if the stack flies ``config``'s mission; else ValueError: the controller's
    refusal (:func:`~dualpilot.mission.dimension.check_dimension`), or the stack's."""
    check_dimension(config)
    dim = config.spec().dim
    if dim not in STACK_DIMS:
        raise ValueError(f"the stack flies planar missions only (dim=2), not dim={dim}: its "
                         "setpoints, plan requests and fires carry no altitude yet "
                         "(docs/three_d.md, Status)")
