"""The simulated vehicle's physics and position/velocity controller (no I/O here).

Physics: Eq. (1), x_t = Φ x_{t−1} + Γ u_t with ΔT = 1 s (:func:`dualpilot.dynamics.step`,
which clips u to U and v to the speed limit, like an autopilot's limits).

Controller: a setpoint gives the target state x* = [p*, v*] due at the end of
the step. In Eq. (1) the next position p + ΔT·v does not depend on u, so the
force sets the next velocity; the controller aims the velocity at
v_cmd = v* + k_p (p* − (p + ΔT v)) / ΔT and solves Eq. (1) for the force,

    u = m / ΔT · (v_cmd − (1 − ζ) v).

On a planned trajectory (x* = Φ x + Γ u_plan) the correction term is 0 and u
equals the plan's control: the vehicle flies exactly what was planned.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dualpilot.dynamics import Array, DynamicsParams, hover_state, step

EARTH_RADIUS_M = 6_378_137.0


def tracking_control(x: Array, target: Array, dyn: DynamicsParams, kp: float = 0.5) -> Array:
    """The force (N) that drives state ``x`` towards ``target`` [p*, v*] in one ΔT, clipped to U."""
    n = dyn.dim
    p, v = x[:n], x[n:]
    p_next = p + dyn.dt_s * v
    v_cmd = target[n:] + kp * (target[:n] - p_next) / dyn.dt_s
    u = dyn.mass_kg / dyn.dt_s * (v_cmd - (1.0 - dyn.zeta) * v)
    return np.asarray(np.clip(u, -dyn.u_max_n, dyn.u_max_n))


@dataclass
class Vehicle:
    """State, clock (ms since boot) and the last setpoint of the simulated vehicle."""

    state: Array
    time_ms: int = 0
    dyn: DynamicsParams = DynamicsParams()
    kp: float = 0.5
    steps: int = 0

    @staticmethod
    def at(east_m: float, north_m: float, dyn: DynamicsParams = DynamicsParams()) -> Vehicle:
        return Vehicle(state=hover_state(np.array([east_m, north_m]), dyn), dyn=dyn)

    def apply(self, target: Array, due_ms: int) -> bool:
        """One step of Eq. (1) towards ``target`` if the setpoint is new (due later than now).

        Lockstep: each new setpoint is one ΔT of flight; repeats of the
        current setpoint (the ≥ 10 Hz stream) change nothing. Returns True if
        the vehicle moved.
        """
        if due_ms <= self.time_ms:
            return False
        u = tracking_control(self.state, np.asarray(target, dtype=float), self.dyn, self.kp)
        self.state = step(self.state, u, self.dyn)
        self.time_ms = int(due_ms)
        self.steps += 1
        return True


def to_geodetic(east_m: float, north_m: float, home: tuple[float, float]) -> tuple[float, float]:
    """Flat-earth conversion of local metres to (lat, lon) degrees around ``home``."""
    lat0, lon0 = home
    lat = lat0 + math.degrees(north_m / EARTH_RADIUS_M)
    lon = lon0 + math.degrees(east_m / (EARTH_RADIUS_M * math.cos(math.radians(lat0))))
    return lat, lon
