"""The plant's readings: which plant flies, in what air, measured how, with what margin.

These are not readings of the paper: the paper's vehicle *is* Eq. (1) (Sec. II-A,
"x_t = Φ x_{t−1} + Γ u_t"; Sec. IV flies it in one-second jumps), with no wind
and exact measurements. They say how far the world departs from that model, in
the terms the SITLs use: PX4's ``SIH``/Gazebo wind and ArduPilot SITL's
``SIM_WIND_SPD``, ``SIM_WIND_DIR`` and ``SIM_WIND_TURB``; turbulence levels are
those of the Dryden model of MIL-F-8785C / MIL-HDBK-1797 (:mod:`dualpilot.plant.wind`),
the GPS error that of Beard & McLain (2012), Sec. 7.5 (:mod:`dualpilot.plant.sensors`).
The defaults are today's vehicle: ``plant = "ideal"``, calm air, exact measurements,
no margin.

The tube margin (``tracking_margin_m = "auto"``, :func:`auto_margin_m`) is what a
plan keeps beyond d_safe (and ε) so that the flight keeps d_safe: the horizontal
GPS error's 99.9th percentile (its distance is Rayleigh-distributed with the per-axis
σ = ``gps_sigma_m``: σ·√(2 ln 1000) = 3.717 σ) plus the flight's own tracking error's
99.9th percentile at the turbulence level (:data:`TRACKING_P999_M`, measured in the
mission loop, docs/plant.md) plus, with gusts, the gust's peak
times one second (the velocity loop's settling, a reading: gusts are not measured).
Its velocity counterpart (:func:`auto_velocity_margin_mps`) is derived the same way: the
horizontal velocity error's 99.9th percentile (Rayleigh with σ = ``vel_sigma_mps``) plus the
flight's own velocity tracking error's 99.9th percentile (:data:`TRACKING_VEL_P999_MPS`) plus
the gust's peak; the concurrent supervisor's ``reanchor_tol = "tube"`` reads the two.

In a 3-D mission the planners keep d_safe plus the tube at the Euclidean 3-D distance from
the fronts' cuboids (Sec. II-B's "d_t = ‖x_t^p − ŷ_t^p‖₂"), and the estimate the vehicle
flies on is wrong upwards too (Beard & McLain's vertical σ, 0.40/0.21 of the horizontal).
``tube_vertical`` says how that error enters the tube (a reading; a 2-D mission's tube is
the horizontal one whatever it says): ``"norm"`` (the default) the 99.9th percentile of the
3-D error's length (:func:`gps_norm_p999_m`: σ = (σ, σ, 1.905 σ), 6.454 σ) plus the flight's
own 3-D tracking error's 99.9th percentile (:data:`TRACKING3_P999_M`), so the tube covers the
error towards a cuboid's top as towards its sides; ``"horizontal"`` the 2-D tube, which
leaves the vertical error uncovered over a low front.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from typing import Literal, get_args

from dualpilot.model.scenarios import PAPER, get_scenario
from dualpilot.plant.plant import PlantKind, PlantParams
from dualpilot.plant.sensors import VERTICAL_RATIO, GpsParams
from dualpilot.plant.wind import GustParams, Turbulence, WindParams

#: the Rayleigh quantile factor of the 99.9th percentile: σ·√(2 ln 1000)
RAYLEIGH_P999 = math.sqrt(2.0 * math.log(1000.0))
#: the multirotor's horizontal tracking error's 99.9th percentile (m) with exact
#: measurements, per turbulence level: its path against the planned straight segment in
#: the mission loop, which flies the plan's velocities (dualpilot/mission/flight.py), so
#: the tail is the vehicle accelerating and turning ahead of Eq. (1)'s positions, not the
#: air. Measured over 8 missions per level (cc and lookahead+risk, missions 0–3 of seed 0)
#: at winds 0 and 10 m/s: 2.62–2.87 m (largest 3.78 m); rounded up (docs/plant.md)
TRACKING_P999_M: dict[str, float] = {"none": 3.0, "light": 3.0, "moderate": 3.0,
                                     "severe": 3.0}
#: the multirotor's velocity tracking error's 99.9th percentile (m/s) with exact
#: measurements: the measured velocity at the end of a flown step against the velocity the
#: kept plan expected there (Eq. (1)'s v_{t+1}). Measured over 16 missions (concurrent and
#: lookahead+risk, missions 0–3 of seed 0, winds 0 and 10 m/s, moderate turbulence; 1,412
#: steps): 3.12 m/s (largest 3.18 m/s); rounded up to 3.5 m/s. The other levels take the
#: moderate level's value (not measured; docs/plant.md)
TRACKING_VEL_P999_MPS: dict[str, float] = {"none": 3.5, "light": 3.5, "moderate": 3.5,
                                           "severe": 3.5}
#: the multirotor's 3-D tracking error's 99.9th percentile (m) with exact measurements in the
#: 3-D missions: the 3-D distance between its path and the planned straight segment, whose
#: vertical part is PX4's climb and sink limits (MPC_Z_VEL_MAX_UP / _DN, 3 / 1.5 m/s) behind
#: Eq. (1)'s. Measured (benchmarks/plant_tube3d.py) over 40 missions (cc and lookahead+risk,
#: configurations 0–9 of seed 0, winds 0 and 10 m/s, moderate turbulence, fronts U[5, 40] m
#: tall, ``s1_altitude = volume``; 2,310 steps): 3.06 m (largest 4.04 m; horizontal part
#: 2.92, vertical 2.31); rounded up to 3.5 m. The other levels take the moderate level's
#: value (not measured; docs/plant.md)
TRACKING3_P999_M: dict[str, float] = {"none": 3.5, "light": 3.5, "moderate": 3.5,
                                      "severe": 3.5}
#: how long (s) a gust's peak is taken to push the vehicle before its velocity loop holds it
GUST_SETTLE_S = 1.0

Margin = float | Literal["auto"]
#: how the vertical error enters a 3-D mission's tube (module docstring)
TubeVertical = Literal["norm", "horizontal"]


@dataclass(frozen=True)
class PlantReading:
    """The plant readings of a mission (see module docstring); every field is a setting.

    ``wind_speed_mps`` and ``wind_dir_rad`` None: the fire scenario's own 10-m wind on
    a fire-behaviour scenario (``FireParams.scenario``), calm air on the paper's
    rectangles; a value differing from a scenario's own is refused (one world, one
    wind). ``wind_dir_rad`` is the direction the wind blows towards, counter-clockwise
    from east, as the scenarios write it.
    """

    #: "ideal" (Eq. (1) exactly: today's vehicle) or "multirotor" (dualpilot/plant)
    plant: PlantKind = "ideal"
    #: the mean wind (m/s) at the vehicle (ArduPilot SITL SIM_WIND_SPD); None: the scenario's
    wind_speed_mps: float | None = None
    #: where the mean wind blows towards (rad, from east); None: the scenario's
    wind_dir_rad: float | None = None
    #: MIL-F-8785C Dryden turbulence level (ArduPilot SITL SIM_WIND_TURB)
    turbulence: Turbulence = "none"
    #: discrete 1-cosine gusts per minute (MIL-F-8785C), Poisson arrivals
    gust_rate_per_min: float = 0.0
    #: a gust's peak (m/s)
    gust_peak_mps: float = GustParams().peak_mps
    #: the stationary σ (m) of the horizontal position error per axis (GPS/EKF)
    gps_sigma_m: float = 0.0
    #: the tube (m) plans keep beyond d_safe and ε; "auto": :func:`auto_margin_m`
    tracking_margin_m: Margin = "auto"
    #: a 3-D mission's "auto" tube: "norm" of the 3-D error, or "horizontal" (module docstring)
    tube_vertical: TubeVertical = "norm"

    def __post_init__(self) -> None:
        if self.plant not in get_args(PlantKind):
            raise ValueError(f"plant must be one of {get_args(PlantKind)}, not {self.plant!r}")
        if self.turbulence not in get_args(Turbulence):
            raise ValueError(f"turbulence must be one of {get_args(Turbulence)}, "
                             f"not {self.turbulence!r}")
        for name in ("wind_speed_mps", "gust_rate_per_min", "gust_peak_mps", "gps_sigma_m"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"{name} must be a number >= 0, got {v!r}")
        if self.wind_dir_rad is not None and not math.isfinite(self.wind_dir_rad):
            raise ValueError(f"wind_dir_rad must be finite, got {self.wind_dir_rad!r}")
        if self.tube_vertical not in get_args(TubeVertical):
            raise ValueError(f"tube_vertical must be one of {get_args(TubeVertical)}, "
                             f"not {self.tube_vertical!r}")
        m = self.tracking_margin_m
        if m != "auto" and not (isinstance(m, (int, float)) and math.isfinite(m) and m >= 0):
            raise ValueError(f"tracking_margin_m must be 'auto' or a number >= 0, got {m!r}")

    def margin_m(self, dim: int = 2) -> float:
        """The tube (m) of a ``dim``-D mission: the set value, or :func:`auto_margin_m`."""
        if self.tracking_margin_m == "auto":
            return auto_margin_m(self, dim)
        return float(self.tracking_margin_m)


def auto_margin_m(reading: PlantReading, dim: int = 2) -> float:
    """The tube (m) of the ``"auto"`` margin: 0 for the ideal plant; for the multirotor
    3.717·``gps_sigma_m`` + :data:`TRACKING_P999_M` [turbulence] (a 2-D mission, or
    ``tube_vertical = "horizontal"``), or :func:`gps_norm_p999_m` + :data:`TRACKING3_P999_M`
    [turbulence] (a 3-D mission under ``"norm"``), + ``gust_peak_mps`` ×
    :data:`GUST_SETTLE_S` when gusts blow (module docstring)."""
    if reading.plant == "ideal":
        return 0.0
    gusts = reading.gust_peak_mps * GUST_SETTLE_S if reading.gust_rate_per_min > 0 else 0.0
    if dim == 3 and reading.tube_vertical == "norm":
        return (gps_norm_p999_m(reading.gps_sigma_m) + TRACKING3_P999_M[reading.turbulence]
                + gusts)
    return RAYLEIGH_P999 * reading.gps_sigma_m + TRACKING_P999_M[reading.turbulence] + gusts


@cache
def _norm_p999_factor(ratio: float) -> float:
    """The 99.9th percentile of ‖e‖ for e ~ N(0, diag(1, 1, ratio²)): the r with
    P(‖e‖ ≤ r) = ∫_{−r}^{r} (1 − e^{−(r² − z²)/2}) φ(z / ratio) / ratio dz = 0.999 (the
    horizontal part's squared length is χ²₂, exponential with mean 2)."""
    from scipy.integrate import quad
    from scipy.optimize import brentq

    def cdf(r: float) -> float:
        def inner(z: float) -> float:
            dens = math.exp(-0.5 * (z / ratio) ** 2) / (ratio * math.sqrt(2.0 * math.pi))
            return (1.0 - math.exp(-0.5 * (r * r - z * z))) * dens
        return float(quad(inner, -r, r, epsabs=1e-13, epsrel=1e-12)[0])

    return float(brentq(lambda r: cdf(r) - 0.999, 1.0, 50.0, xtol=1e-12))


def gps_norm_p999_m(gps_sigma_m: float) -> float:
    """The 99.9th percentile (m) of the 3-D GPS error's length, σ = ``gps_sigma_m`` per
    horizontal axis and ``VERTICAL_RATIO`` times it upwards (Beard & McLain (2012),
    Sec. 7.5): 6.454·σ."""
    if gps_sigma_m == 0.0:
        return 0.0
    return gps_sigma_m * _norm_p999_factor(VERTICAL_RATIO)


def auto_velocity_margin_mps(reading: PlantReading) -> float:
    """The velocity tube (m/s), derived as :func:`auto_margin_m`'s: 0 for the ideal plant;
    for the multirotor 3.717·``vel_sigma_mps`` (the horizontal velocity error's 99.9th
    percentile, Rayleigh; only with a GPS error, ``gps_sigma_m`` > 0) +
    :data:`TRACKING_VEL_P999_MPS` [turbulence] + ``gust_peak_mps`` when gusts blow (a
    gust's peak is a velocity). 3.686 m/s at ``gps_sigma_m`` = 1.5, moderate turbulence."""
    if reading.plant == "ideal":
        return 0.0
    sensor = RAYLEIGH_P999 * GpsParams().vel_sigma_mps if reading.gps_sigma_m > 0 else 0.0
    gusts = reading.gust_peak_mps if reading.gust_rate_per_min > 0 else 0.0
    return sensor + TRACKING_VEL_P999_MPS[reading.turbulence] + gusts


#: how many standard deviations of the difference of two measurements the monitor allows
MEASUREMENT_SIGMAS = 4.0


def measurement_tol(reading: PlantReading, interval_s: float, dim: int = 2) -> float:
    """How far (m and m/s, ∞-norm) two measurements of one state ``interval_s`` (s) apart may
    differ: :data:`MEASUREMENT_SIGMAS` standard deviations of the difference, per axis, of
    the position error (Gauss–Markov: σ√(2(1 − e^{−Δt/τ})), σ the vertical one in 3-D) or of
    the velocity error (white: √2 σ_v), whichever is larger (:mod:`dualpilot.plant.sensors`);
    0 for exact measurements (``gps_sigma_m`` = 0, and the ideal plant, which measures
    exactly)."""
    if reading.plant == "ideal" or reading.gps_sigma_m == 0.0:
        return 0.0
    gps = GpsParams(gps_sigma_m=reading.gps_sigma_m)
    sigma = float(gps.sigma[2]) if dim == 3 else gps.gps_sigma_m
    pos = sigma * math.sqrt(2.0 * (1.0 - math.exp(-interval_s / gps.tau_s)))
    vel = math.sqrt(2.0) * gps.vel_sigma_mps
    return MEASUREMENT_SIGMAS * max(pos, vel)


def mean_wind(reading: PlantReading, scenario: str) -> tuple[float, float]:
    """(speed m/s, direction rad) of the mean wind: the scenario's own on a fire-behaviour
    scenario, else the reading's (calm by default). ValueError for a set value that is not
    the scenario's."""
    if scenario == PAPER:
        return (reading.wind_speed_mps or 0.0, reading.wind_dir_rad or 0.0)
    own = get_scenario(scenario).params
    for name, mine, theirs in (("wind_speed_mps", reading.wind_speed_mps, own.wind_speed_mps),
                               ("wind_dir_rad", reading.wind_dir_rad, own.wind_direction_rad)):
        if mine is not None and mine != theirs:
            raise ValueError(f"{name} = {mine:g} is not the wind of fire scenario {scenario!r} "
                             f"({theirs:g}): on a fire-behaviour scenario the mean wind is its "
                             "own; leave it unset")
    return (own.wind_speed_mps, own.wind_direction_rad)


def plant_params(reading: PlantReading, scenario: str = PAPER) -> PlantParams:
    """The :class:`PlantParams` the mission flies under ``reading`` on fire ``scenario``."""
    speed, direction = mean_wind(reading, scenario)
    gusts = GustParams(rate_per_min=reading.gust_rate_per_min, peak_mps=reading.gust_peak_mps)
    wind = WindParams(wind_speed_mps=speed, wind_dir_rad=direction,
                      turbulence=reading.turbulence, gusts=gusts)
    return PlantParams(kind=reading.plant, wind=wind,
                       gps=GpsParams(gps_sigma_m=reading.gps_sigma_m))
