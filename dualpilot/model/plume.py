"""How tall a burning front is to a small UAV: the flame and the hot plume above a line fire.

On a fire-behaviour scenario (dualpilot/model/scenarios.py) a front's cuboid C_t is as
tall as the air a UAV must not enter above it, which follows the fire:

* **the flame**: Byram's (1959) flame length from the fireline intensity I (kW/m),
  L = 0.0775 I^0.46 (m) (Byram, "Combustion of forest fuels", in Davis (ed.), *Forest
  Fire: Control and Use*, McGraw-Hill, 1959; pyretechnics computes the same from its
  English form 0.45 I^0.46 ft, I in Btu/ft/s);
* **the plume**: the height above a line fire at which the plume's temperature excess
  over the ambient air falls to ΔT. Van Wagner's (1973) crown scorch model is exactly
  this height for ΔT = 60 °C − T_a, the needles' lethal temperature ("Height of crown
  scorch in forest fires", Can. J. For. Res. 3:373–378): from line-plume theory
  (Thomas 1963) the excess falls as I^(2/3)/z in calm air, and the cross wind U bends
  and cools the plume, h ∝ I^(7/6) / (ΔT·(a·I + U³)^(1/2)), the constants fitted on 13
  outdoor fires (I 67–1256 kW/m, scorch heights 2–17 m). In the English units of
  Albini (1976, USDA FS GTR INT-30), as BehavePlus computes it,

      h = 63 / ΔT_F · I^(7/6) / (I + U³)^(1/2)   (h ft, I Btu/ft/s, U mph midflame, ΔT_F °F),

  with ΔT_F = 140 °F − T_a for scorch; here ΔT is the UAV's limit less the ambient air.
  Beyond Van Wagner's intensities it is an extrapolation of the same line-plume law.

**The UAV's limit**: 50 °C, the upper operating temperature of the small multirotors used
over fires (DJI's Matrice 300 RTK and Matrice 30 specifications: −20 °C to 50 °C); air
hotter than that is outside the vehicle's envelope. The ambient air is 30 °C, the
scenarios' spotting temperature (:class:`dualpilot.model.scenarios.SpottingParams`).

A front's top is the larger of the two: a creeping grass fire (grass-5, head intensity
≈ 400 kW/m) is about 11 m tall and may be crossed above within the altitude band; an
intense shrub front (≈ 26,000 kW/m) is about 190 m tall, above the 120 m ceiling, and
may never be. The plume's updraft gives no height of its own: a line plume's vertical
speed does not fall with height in calm air (Thomas 1963), so only the temperature
bounds it. Units: I kW/m, lengths m, temperatures °C, speeds m/s (converted exactly
to Albini's units: 1 ft = 0.3048 m, 1 mph = 0.44704 m/s, 1 Btu = 1055.05585262 J).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

#: Byram's (1959) flame length coefficient and exponent: L = 0.0775 I^0.46 (m, I kW/m).
BYRAM_COEFF = 0.0775
BYRAM_EXPONENT = 0.46
#: Albini's (1976) English form of Van Wagner's (1973) plume height: 63 / ΔT_F (ft, °F).
VAN_WAGNER_COEFF = 63.0
#: Exact conversions to Albini's units.
FT_M = 0.3048
MPH_MPS = 0.44704
BTU_FT_S_KW_M = 1055.05585262 / FT_M / 1000.0  # 1 Btu/ft/s in kW/m (≈ 3.4615)
#: A temperature difference of 1 °C in °F.
DEG_C_F = 1.8

#: The UAV's upper operating temperature (°C): DJI Matrice 300 RTK / Matrice 30 specs.
UAV_LIMIT_C = 50.0
#: The ambient air (°C): the scenarios' spotting temperature.
AMBIENT_C = 30.0


@dataclass(frozen=True)
class PlumeParams:
    """The air a UAV must not enter: hotter than ``uav_limit_c`` over ``ambient_c`` (°C)."""

    uav_limit_c: float = UAV_LIMIT_C
    ambient_c: float = AMBIENT_C

    def __post_init__(self) -> None:
        if not (math.isfinite(self.uav_limit_c) and math.isfinite(self.ambient_c)):
            raise ValueError(f"temperatures must be finite: {self}")
        if not self.uav_limit_c > self.ambient_c:
            raise ValueError(f"the UAV's limit {self.uav_limit_c} °C must exceed the ambient "
                             f"air {self.ambient_c} °C")

    @property
    def excess_c(self) -> float:
        """The temperature excess (°C) over the ambient air the UAV must not enter."""
        return self.uav_limit_c - self.ambient_c


DEFAULT_PLUME = PlumeParams()


def _check_intensity(intensity_kw_m: float) -> float:
    i = float(intensity_kw_m)
    if not (math.isfinite(i) and i >= 0.0):
        raise ValueError(f"fireline intensity must be finite and >= 0 kW/m, got {i}")
    return i


def flame_length_m(intensity_kw_m: float) -> float:
    """Byram's flame length L = 0.0775 I^0.46 (m) of a fireline intensity I (kW/m)."""
    return BYRAM_COEFF * _check_intensity(intensity_kw_m) ** BYRAM_EXPONENT


def plume_height_m(intensity_kw_m: float, wind_mps: float, excess_c: float) -> float:
    """The height (m) above a line fire of intensity I (kW/m) under a midflame wind U (m/s)
    at which the plume's temperature excess falls to ``excess_c`` (°C): Van Wagner (1973)
    in Albini's (1976) form (module docstring); 0 for a fire that does not burn."""
    i = _check_intensity(intensity_kw_m)
    u = float(wind_mps)
    if not (math.isfinite(u) and u >= 0.0):
        raise ValueError(f"wind must be finite and >= 0 m/s, got {u}")
    if not (math.isfinite(excess_c) and excess_c > 0.0):
        raise ValueError(f"the temperature excess must be positive, got {excess_c}")
    if i == 0.0:
        return 0.0
    i_b = i / BTU_FT_S_KW_M
    u_mph = u / MPH_MPS
    h_ft = VAN_WAGNER_COEFF / (DEG_C_F * excess_c) * i_b ** (7.0 / 6.0) / math.sqrt(
        i_b + u_mph**3)
    return h_ft * FT_M


def fire_top_m(intensity_kw_m: float, wind_mps: float,
               plume: PlumeParams = DEFAULT_PLUME) -> float:
    """The top (m above ground) of a front's cuboid: the flame or the air hotter than the
    UAV's limit above it, whichever reaches higher."""
    return max(flame_length_m(intensity_kw_m),
               plume_height_m(intensity_kw_m, wind_mps, plume.excess_c))


def front_intensity_kw_m(intensity_kw_m: ArrayLike, active: ArrayLike) -> float:
    """A front's fireline intensity (kW/m): the largest over its active perimeter cells
    (``active``, a mask over the grid of ``intensity_kw_m``, such as pyretechnics'
    ``fireline_intensity`` layer); 0 when no cell of the front burns."""
    vals = np.asarray(intensity_kw_m, dtype=float)
    mask = np.asarray(active, dtype=bool)
    if vals.shape != mask.shape:
        raise ValueError(f"intensity {vals.shape} and mask {mask.shape} differ in shape")
    sel = vals[mask]
    if not np.all(np.isfinite(sel)) or np.any(sel < 0.0):
        raise ValueError("fireline intensities must be finite and >= 0 kW/m")
    return float(sel.max()) if sel.size else 0.0


def crossable(top_m: float, ceiling_m: float, d_safe_m: float) -> bool:
    """Whether a UAV can pass over a cuboid ``top_m`` tall keeping d_safe below a ceiling."""
    return top_m + d_safe_m <= ceiling_m

