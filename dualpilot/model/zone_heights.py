"""How tall the forecast's risk zones are in 3-D: the reading ``risk_zone_height``.

The fire forecast (dualpilot/model/forecast.py) is a map of the ground: P_xy, the chance
that a cell's centre lies in a front's footprint. A risk zone (dualpilot/model/risk.py) is
the hull of a group of cells with P_xy > α. In 3-D (docs/three_d.md, "7. The risk-aware
variants") a zone needs a height; the forecast stays planar on the wire and every
consumer of the zones (the risk-aware planners, the run-time monitor's ``check_risk``, the
concurrent supervisor's forecast threat rule) gives it the same one, read from the
mission's spec (:attr:`dualpilot.spec.MissionSpec.zone_heights`). Two readings,
:data:`ZoneReading`:

* ``"band"`` (the default): a zone is as tall as every altitude, its footprint checked
  against the plan's ground track: conservative over low fires, and every number as
  before the zones had heights.
* ``"fire"``: a zone is as tall as the fires it forecasts, from the reading the mission
  already carries for its fronts (:class:`~dualpilot.model.fire_height.FireHeightParams`):

  - a fire-behaviour scenario's ``"plume"``: as tall as the scenario's head fire
    (:func:`dualpilot.model.plume.fire_top_m` of its head fireline intensity and midflame
    wind, a constant per scenario; no front of a uniform fuel bed on flat ground burns
    hotter than its head: on grass-5 the fronts' tops reach 10.6895 m, the head fire's
    top to 2e-6 m, pyretechnics' level set against its flat-ground formula);
  - ``"above-ceiling"``: the fronts' top, the ceiling + ε, above the band: the ``"band"``
    zones exactly;
  - the paper's process with ``"uniform"`` heights U[lo, hi]: a front's height is drawn
    apart from its rectangle, so the chance that altitude z of a cell is in a fire is
    P_xy · S(z), S(z) = P(H > z) the height's survival function; the cell is risky up to
    the z where P_xy · S(z) = α, z* = hi − (α / P_xy)(hi − lo) (in (lo, hi) for
    P_xy > α), and a zone's prism is as tall as its highest cell's (the z* of its largest
    P_xy: a superset of the cells risky at every altitude).

Lengths m above ground.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, get_args

#: The readings of a risk zone's height (module docstring).
ZoneReading = Literal["band", "fire"]


@dataclass(frozen=True)
class ZoneHeights:
    """The height law of the risk zones (module docstring): every zone ``top_m`` tall, or,
    with ``uniform`` = (lo, hi), the z* of its highest cell; the default (``top_m`` = inf,
    no law) is the ``"band"`` reading, a zone as tall as every altitude."""

    top_m: float = math.inf
    uniform: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if self.uniform is not None:
            lo, hi = self.uniform
            if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo <= hi):
                raise ValueError(f"need 0 < lo <= hi for a uniform height law, got {lo}, {hi}")
        elif not self.top_m > 0.0:
            raise ValueError(f"a zone's top must be > 0 m, got {self.top_m}")

    @property
    def planar(self) -> bool:
        """Whether the zones are as tall as every altitude (the ``"band"`` reading)."""
        return self.uniform is None and math.isinf(self.top_m)

    def top_for(self, p_xy: float, alpha: float) -> float:
        """The top (m) of a zone whose highest cell's forecast probability is ``p_xy``
        (> ``alpha``): ``top_m``, or z* = hi − (α / P_xy)(hi − lo) under a uniform law."""
        if self.uniform is None:
            return self.top_m
        if not alpha < p_xy <= 1.0:
            raise ValueError(f"a risky cell has alpha < P <= 1, got P = {p_xy}, alpha {alpha}")
        lo, hi = self.uniform
        return hi - (alpha / p_xy) * (hi - lo)


#: The ``"band"`` reading (and every 2-D mission's): zones as tall as every altitude.
BAND = ZoneHeights()


def check_reading(reading: str) -> None:
    """ValueError unless ``reading`` is one of :data:`ZoneReading`."""
    if reading not in get_args(ZoneReading):
        raise ValueError(f"risk_zone_height must be one of {get_args(ZoneReading)}, "
                         f"not {reading!r}")
