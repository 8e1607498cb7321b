"""Wind: a steady mean, Dryden turbulence (MIL-F-8785C) and discrete 1-cosine gusts.

Turbulence is the low-altitude Dryden model of MIL-F-8785C (MIL-HDBK-1797),
as JSBSim's ``ttMilspec`` and the SITLs use it, with h in ft (clamped to
10–1000 ft, the form's range) and W₂₀ the wind speed at 20 ft:

    L_w = h,  L_u = L_v = h / (0.177 + 0.000823 h)^1.2,
    σ_w = 0.1 W₂₀,  σ_u = σ_v = σ_w / (0.177 + 0.000823 h)^0.4,

with W₂₀ = 15, 30, 45 kt for light, moderate and severe turbulence. The
spectra, with spatial frequency Ω (rad/m) and airspeed V (m/s), are

    Φ_u(Ω) = σ_u² (2L_u/π) / (1 + (L_uΩ)²),
    Φ_v(Ω) = σ_v² (L_v/π) (1 + 3(L_vΩ)²) / (1 + (L_vΩ)²)²   (w alike),

that is, in time, u is a first-order Gauss–Markov process with correlation
σ_u² e^{−Vτ/L_u} and v, w have σ² e^{−ξ}(1 − ξ/2), ξ = Vτ/L. Each is drawn here
by the exact discretisation of its shaping filter (the stationary covariance P
of the filter's state and Φ P Φᵀ + Q = P), so samples carry the model's
variance and correlation at any step. u lies along the mean wind's direction,
v across it (horizontal), w up. V is the vehicle's airspeed against the mean
wind at the start of each flight segment, at least ``min_airspeed_mps`` (at
V → 0 the frozen field stops passing the vehicle).

Gusts: the discrete gust of MIL-F-8785C, v = (v_m/2)(1 − cos(πx/d_m)), rising to
v_m over the distance d_m travelled through the air, here applied as a pulse
that falls back over the next d_m; arrivals are a Poisson process, each gust in
a uniformly drawn horizontal direction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np

from dualpilot.arrays import Array

Turbulence = Literal["none", "light", "moderate", "severe"]
KNOT_MPS = 1852.0 / 3600.0
FOOT_M = 0.3048
#: MIL-F-8785C, low altitude: the wind speed at 20 ft of each turbulence level (kt)
W20_KT: dict[str, float] = {"none": 0.0, "light": 15.0, "moderate": 30.0, "severe": 45.0}


@dataclass(frozen=True)
class GustParams:
    """Discrete 1-cosine gusts: Poisson arrivals per minute, peak v_m (m/s), rise length d_m
    (m). No gusts by default."""

    rate_per_min: float = 0.0
    peak_mps: float = 5.0
    half_length_m: float = 50.0

    def __post_init__(self) -> None:
        if self.rate_per_min < 0 or self.peak_mps < 0 or self.half_length_m <= 0:
            raise ValueError(f"invalid gust parameters: {self}")


@dataclass(frozen=True)
class WindParams:
    """Steady wind, turbulence and gusts; calm air by default (the ideal plant's air)."""

    wind_speed_mps: float = 0.0
    #: the direction the wind blows towards, counter-clockwise from east (rad)
    wind_dir_rad: float = 0.0
    turbulence: Turbulence = "none"
    #: W₂₀ (m/s) instead of the level's MIL-F-8785C value (None: the level's)
    wind20_mps: float | None = None
    #: the least airspeed the frozen turbulence passes the vehicle at (m/s)
    min_airspeed_mps: float = 1.0
    gusts: GustParams = GustParams()

    def __post_init__(self) -> None:
        if self.turbulence not in get_args(Turbulence):
            raise ValueError(f"turbulence must be one of {get_args(Turbulence)}, "
                             f"not {self.turbulence!r}")
        if not (self.wind_speed_mps >= 0 and math.isfinite(self.wind_dir_rad)):
            raise ValueError(f"invalid mean wind: {self}")
        if self.wind20_mps is not None and self.wind20_mps < 0:
            raise ValueError(f"wind20_mps must be non-negative, got {self.wind20_mps}")
        if self.min_airspeed_mps <= 0:
            raise ValueError(f"min_airspeed_mps must be positive, got {self.min_airspeed_mps}")

    @property
    def w20_mps(self) -> float:
        """W₂₀ (m/s): the explicit value, or the turbulence level's."""
        if self.wind20_mps is not None:
            return self.wind20_mps
        return W20_KT[self.turbulence] * KNOT_MPS

    @property
    def mean(self) -> Array:
        """The steady wind (m/s, ENU)."""
        s = self.wind_speed_mps
        return np.array([s * math.cos(self.wind_dir_rad), s * math.sin(self.wind_dir_rad), 0.0])


def dryden_scales(altitude_m: float, w20_mps: float) -> tuple[Array, Array]:
    """(σ_u, σ_v, σ_w) (m/s) and (L_u, L_v, L_w) (m) of MIL-F-8785C's low-altitude form."""
    h = min(max(altitude_m / FOOT_M, 10.0), 1000.0)
    k = 0.177 + 0.000823 * h
    sigma_w = 0.1 * w20_mps
    sigma_uv = sigma_w / k ** 0.4
    l_uv = h / k ** 1.2 * FOOT_M
    return np.array([sigma_uv, sigma_uv, sigma_w]), np.array([l_uv, l_uv, h * FOOT_M])


def first_order_step(h: float) -> tuple[Array, Array]:
    """Transition Φ (1×1) and noise factor of a unit-variance Gauss–Markov process after
    h = VΔt/L: Φ = e^{−h}, Q = 1 − e^{−2h}."""
    a = math.exp(-h)
    return np.array([[a]]), np.array([[math.sqrt(1.0 - a * a)]])


#: stationary covariance of the second-order filter's state (z₁, z₂) for unit output variance
_P2 = np.array([[0.5, 0.25], [0.25, 0.25]])


def second_order_step(h: float) -> tuple[Array, Array]:
    """Φ and the Cholesky factor of Q = P − Φ P Φᵀ of the Dryden v/w filter after h = VΔt/L.

    The filter T z₁' = −z₁ + η, T z₂' = −z₂ + z₁ has e^{At} = e^{−h} [[1, 0], [h, 1]].
    """
    phi = math.exp(-h) * np.array([[1.0, 0.0], [h, 1.0]])
    q = _P2 - phi @ _P2 @ phi.T
    # Cholesky of the 2×2 q, written out; q is positive definite for h > 0, and a tiny h can
    # leave it semi-definite in floating point (hence the floors)
    l11 = math.sqrt(max(q[0, 0], 0.0))
    l21 = q[1, 0] / l11 if l11 > 0 else 0.0
    l22 = math.sqrt(max(q[1, 1] - l21 * l21, 0.0))
    return phi, np.array([[l11, 0.0], [l21, l22]])


class DrydenTurbulence:
    """The three Dryden components, unit-variance states scaled by σ on output."""

    def __init__(self, altitude_m: float, w20_mps: float, rng: np.random.Generator):
        self.sigma, self.length = dryden_scales(altitude_m, w20_mps)
        self.rng = rng
        # start in the stationary distribution
        self.u = rng.standard_normal(1)
        self.v = np.linalg.cholesky(_P2) @ rng.standard_normal(2)
        self.w = np.linalg.cholesky(_P2) @ rng.standard_normal(2)

    def sample(self, n: int, dt_s: float, airspeed_mps: float) -> Array:
        """The next ``n`` samples (n, 3) of (u, v, w) (m/s), ``dt_s`` apart."""
        out = np.empty((n, 3))
        noise = self.rng.standard_normal((n, 5))
        pu, gu = first_order_step(airspeed_mps * dt_s / self.length[0])
        pv, gv = second_order_step(airspeed_mps * dt_s / self.length[1])
        pw, gw = second_order_step(airspeed_mps * dt_s / self.length[2])
        from dualpilot.plant.wind_kernel import shape

        shape(pu, gu, pv, gv, pw, gw, self.u, self.v, self.w, noise, out)
        return out * self.sigma


class Gusts:
    """Discrete 1-cosine gusts, each a pulse over 2·d_m of air travelled."""

    def __init__(self, params: GustParams, rng: np.random.Generator):
        self.params = params
        self.rng = rng
        #: active gusts: (air distance travelled since onset (m), unit direction (3,))
        self.active: list[tuple[float, Array]] = []

    def sample(self, n: int, dt_s: float, airspeed_mps: float) -> Array:
        """The next ``n`` samples (n, 3) of the gust wind (m/s)."""
        p = self.params
        out = np.zeros((n, 3))
        span = n * dt_s
        arrivals = self.rng.poisson(p.rate_per_min / 60.0 * span) if p.rate_per_min > 0 else 0
        for onset in np.sort(self.rng.uniform(0.0, span, size=arrivals)):
            ang = self.rng.uniform(0.0, 2.0 * math.pi)
            self.active.append((-onset * airspeed_mps,
                                np.array([math.cos(ang), math.sin(ang), 0.0])))
        t = (np.arange(n) + 0.5) * dt_s
        kept = []
        for x0, direction in self.active:
            x = x0 + airspeed_mps * t
            inside = (x >= 0.0) & (x <= 2.0 * p.half_length_m)
            shape = np.where(inside, 0.5 * p.peak_mps * (1 - np.cos(np.pi * x / p.half_length_m)),
                             0.0)
            out += shape[:, None] * direction
            x_end = x0 + airspeed_mps * span
            if x_end < 2.0 * p.half_length_m:
                kept.append((x_end, direction))
        self.active = kept
        return out


class Wind:
    """The air a plant flies through: mean + turbulence (mean-wind axes) + gusts (ENU)."""

    def __init__(self, params: WindParams, altitude_m: float, rng: np.random.Generator):
        self.params = params
        turb_rng, gust_rng = rng.spawn(2)
        w20 = params.w20_mps
        on = params.turbulence != "none" and w20 > 0
        self.turbulence = DrydenTurbulence(altitude_m, w20, turb_rng) if on else None
        self.gusts = Gusts(params.gusts, gust_rng)
        c, s = math.cos(params.wind_dir_rad), math.sin(params.wind_dir_rad)
        #: columns: the u (along the wind), v (across, to its left) and w (up) axes in ENU
        self.axes = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    @property
    def mean(self) -> Array:
        return self.params.mean

    def sample(self, n: int, dt_s: float, velocity: Array) -> Array:
        """The wind (n, 3) (m/s, ENU) at the next ``n`` integration steps of a vehicle flying at
        ``velocity`` (m/s, ENU) at their start."""
        air = max(float(np.linalg.norm(np.asarray(velocity) - self.mean)),
                  self.params.min_airspeed_mps)
        out = np.broadcast_to(self.mean, (n, 3)).copy()
        if self.turbulence is not None:
            out += self.turbulence.sample(n, dt_s, air) @ self.axes.T
        if self.params.gusts.rate_per_min > 0 or self.gusts.active:
            out += self.gusts.sample(n, dt_s, air)
        return out
