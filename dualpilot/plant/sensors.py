"""The measured state: a GPS/EKF-like error on position and velocity.

Following Beard & McLain, *Small Unmanned Aircraft* (2012), Sec. 7.5, the
position error is a first-order Gauss–Markov process per axis,

    e[k+1] = e^{−Δt/τ} e[k] + η[k],

with time constant τ = 1100 s; here it is parameterised by its stationary
standard deviation (``gps_sigma_m`` horizontally, the book's vertical-to-
horizontal ratio 0.40/0.21 upwards), so η has variance σ²(1 − e^{−2Δt/τ}). The
velocity error is white, σ_v = 0.05 m/s (the book's ground-speed noise); it is
consistent with the position error, whose one-second increments have standard
deviation σ√(1 − e^{−2/τ}) ≈ 0.064 m at σ = 1.5 m. The autopilot flies on the
estimate (its position controller sees p + e, like PX4 on EKF2's output), and
the supervisor plans from the measured state (LOCAL_POSITION_NED).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dualpilot.arrays import Array

#: Beard & McLain (2012), Sec. 7.5: σ of the altitude error over that of north/east
VERTICAL_RATIO = 0.40 / 0.21


@dataclass(frozen=True)
class GpsParams:
    """The measurement error; exact by default (``gps_sigma_m`` = 0)."""

    gps_sigma_m: float = 0.0  #: stationary σ of the horizontal position error per axis (m)
    tau_s: float = 1100.0  #: its correlation time (s), Beard & McLain (2012)
    vel_sigma_mps: float = 0.05  #: σ of the velocity error per axis (m/s), ibid.

    def __post_init__(self) -> None:
        if not (self.gps_sigma_m >= 0 and self.tau_s > 0 and self.vel_sigma_mps >= 0):
            raise ValueError(f"invalid GPS error parameters: {self}")

    @property
    def sigma(self) -> Array:
        """Stationary σ of the position error per ENU axis (m)."""
        s = self.gps_sigma_m
        return np.array([s, s, s * VERTICAL_RATIO])


class GpsError:
    """The estimate's position error, drawn from a seeded generator."""

    def __init__(self, params: GpsParams, rng: np.random.Generator):
        self.params = params
        self.rng = rng
        self.error = params.sigma * rng.standard_normal(3)  # stationary start

    def sample(self, n: int, dt_s: float) -> Array:
        """The position error (n, 3) (m) over the next ``n`` steps of ``dt_s``; the last row is
        the error at the end."""
        if self.params.gps_sigma_m == 0.0:
            return np.zeros((n, 3))
        a = math.exp(-dt_s / self.params.tau_s)
        drive = self.rng.standard_normal((n, 3)) * (self.params.sigma * math.sqrt(1 - a * a))
        from scipy.signal import lfilter  # 1 s to import: only where a noisy flight needs it

        out, _ = lfilter([1.0], [1.0, -a], drive, axis=0, zi=(a * self.error)[None, :])
        self.error = out[-1].copy()
        return np.asarray(out)

    def measure(self, position: Array, velocity: Array) -> tuple[Array, Array]:
        """The measured position and velocity (m, m/s) now."""
        if self.params.gps_sigma_m == 0.0:
            return np.asarray(position, dtype=float).copy(), np.asarray(velocity,
                                                                        dtype=float).copy()
        noise = self.params.vel_sigma_mps * self.rng.standard_normal(3)
        return position + self.error, velocity + noise
