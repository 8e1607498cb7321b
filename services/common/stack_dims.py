"""The dimensions of the missions the stack flies (docs/three_d.md, section 10).

The stack flies the top-down evaluation (``dim=2``: MAVLink setpoints at one altitude,
the supervisor's ``--altitude-m``) and the paper's 3-D world (``dim=3``: the plan
request's state, its obstacles' altitudes, the plans' rows, the fires' tops, the
setpoints' z and LOCAL_POSITION_NED's z and vz carry the third dimension, and uavsim
flies the 3-D Eq. (1) in lockstep). A mission is refused where it enters the stack
(the supervisor's and the launcher's flags), before any service is asked, when its
controller does not fly its dimension (dualpilot/mission/dimension.py: the controllers
that fly 3-D in-process are the ones the stack flies in 3-D).
"""

from __future__ import annotations

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.dimension import check_dimension

__all__ = ["STACK_DIMS", "check_stack_dimension"]

#: the dimensions (``DynamicsParams.dim``) of the missions the stack flies
STACK_DIMS = frozenset({2, 3})


def check_stack_dimension(config: MissionConfig) -> None:
    """Nothing if the stack flies ``config``'s mission; else ValueError: the controller's
    refusal (:func:`~dualpilot.mission.dimension.check_dimension`), or the stack's."""
    check_dimension(config)
    dim = config.spec().dim
    if dim not in STACK_DIMS:
        raise ValueError(f"the stack flies missions of dim {sorted(STACK_DIMS)}, not "
                         f"dim={dim} (docs/three_d.md, Status)")
