"""Fire data grown for staleness, as a message (the stack's side of model.stale_fire).

The supervisor owes the EWS fire sub-steps it did not confirm; while the data
is stale (:class:`dualpilot.model.stale_fire.StaleFireParams`) the planners get the
last known fronts grown by :func:`dualpilot.model.stale_fire.credible_margin_m`.
"""

from __future__ import annotations

from dualpilot.model.stale_fire import grow_polygon
from services.common import codec
from services.msgs import fire_pb2


def grown_fire_msg(msg: fire_pb2.FireState, margin_m: float) -> fire_pb2.FireState:
    """A copy of ``msg`` whose fronts' regions and hulls are grown by ``margin_m`` on every side."""
    out = fire_pb2.FireState()
    out.CopyFrom(msg)
    if margin_m <= 0:
        return out
    for f in out.fronts:
        f.region.width_m += 2 * margin_m
        f.region.height_m += 2 * margin_m
        hull = grow_polygon(codec.polygon_from_msg(f.hull), margin_m)
        f.hull.Clear()
        codec.polygon_to_msg(hull, f.hull)
    return out
