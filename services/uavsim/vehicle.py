"""The simulated vehicle's physics, controller, battery and attitude (no I/O here).

Physics: Eq. (1), x_t = Φ x_{t−1} + Γ u_t with ΔT = 1 s (:func:`dualpilot.dynamics.step`,
which clips u to U and v to the speed limit, per axis or as a norm
(``DynamicsParams.speed_limit``), like an autopilot's limits).

Controller: a setpoint gives the target state x* = [p*, v*] due at the end of
the step. In Eq. (1) the next position p + ΔT·v does not depend on u, so the
force sets the next velocity; the controller aims the velocity at
v_cmd = v* + k_p (p* − (p + ΔT v)) / ΔT and solves Eq. (1) for the force,

    u = m / ΔT · (v_cmd − (1 − ζ) v).

On a planned trajectory (x* = Φ x + Γ u_plan) the correction term is 0 and u
equals the plan's control: the vehicle flies exactly what was planned. A mission of
another plant (``plant=multirotor``) flies that plant instead (services/uavsim/plantsim.py).

Altitude: Sec. IV is 2-D at a fixed altitude, so Eq. (1) has no vertical
axis. On its own clock the vehicle still climbs and descends like a
multicopter's altitude controller: each ΔT the altitude moves towards its
target by at most ``up`` (climb) or ``down`` (sink) m/s × ΔT
(:meth:`Vehicle.climb`; PX4's MPC_Z_VEL_MAX_UP / _DN, services/uavsim/params.py).
In lockstep the altitude is the fixed one (services/uavsim/navigator.py), or under a 3-D
mission configuration the state's own: Eq. (1) with 3×3 blocks, the same :meth:`apply`
(services/uavsim/missionconfig.py).

Battery: the charge used is the impulse Σ‖u_t‖ΔT (N·s) of the flown controls
against a capacity of ``BATTERY_CAPACITY_NS`` = 1000 N·s (about five of the
paper's missions: cruising at 12 m/s against the drag ζ costs ‖u‖ ≈ 2.5 N).
The voltage falls linearly from 16.8 V (4S full) to 13.2 V (empty).

Attitude: a multirotor tilts its thrust to make the horizontal force u; with
thrust ≈ m·g the roll is atan(u_east / m g) and the pitch −atan(u_north / m g)
(nose north-east-down frame); the yaw follows the velocity.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from dualpilot.model.dynamics import Array, DynamicsParams, hover_state, step
from services.common.mav import to_geodetic, to_local

from .plantsim import PlantSim

__all__ = ["Vehicle", "tracking_control", "to_geodetic", "to_local"]

BATTERY_CAPACITY_NS = 1000.0
VOLT_FULL_V, VOLT_EMPTY_V = 16.8, 13.2
GRAVITY_MPS2 = 9.81


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
    """State, clock (ms since boot), the last control and the charge used by the vehicle."""

    state: Array
    time_ms: int = 0
    dyn: DynamicsParams = DynamicsParams()
    kp: float = 0.5
    steps: int = 0
    impulse_ns: float = 0.0
    capacity_ns: float = BATTERY_CAPACITY_NS
    control: Array = field(default_factory=lambda: np.zeros(2))
    alt_m: float = 0.0  #: above home
    vz_mps: float = 0.0  #: climb rate (up is positive)
    #: the mission's plant when it is not Eq. (1) (``plant=multirotor``; state: its estimate)
    plant: PlantSim | None = None
    plant_config: object = None  #: the mission configuration the plant was made for

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
        if self.plant is not None:  # the mission's multirotor (services/uavsim/plantsim.py)
            self.state = self.plant.apply(self.state, target, int(due_ms))
        else:
            self.state = step(self.state, u, self.dyn)
        self.control = u
        self.impulse_ns += float(np.linalg.norm(u)) * self.dyn.dt_s
        self.time_ms = int(due_ms)
        self.steps += 1
        return True

    def climb(self, target_m: float, up_mps: float, down_mps: float) -> None:
        """One ΔT of the altitude towards ``target_m`` (m above home, never below 0) at most
        ``up_mps`` up or ``down_mps`` down."""
        dt = self.dyn.dt_s
        target = max(0.0, float(target_m))
        change = min(max(target - self.alt_m, -down_mps * dt), up_mps * dt)
        self.alt_m = max(0.0, self.alt_m + change)
        self.vz_mps = change / dt

    def brake(self) -> None:
        """Hold: stop where it is (a multirotor's position hold), keeping the clock (a plant
        brakes under its own controller, towards the position held)."""
        if self.plant is not None:
            self.plant.held = hover_state(self.state[: self.dyn.dim], self.dyn)
        else:
            self.state = hover_state(self.state[: self.dyn.dim], self.dyn)
        self.control = np.zeros(self.dyn.dim)
        self.vz_mps = 0.0

    def set_limits(self, u_max_n: float | None = None, v_max_mps: float | None = None) -> None:
        """New force/speed limits (parameters); raises ValueError if not positive."""
        self.dyn = replace(self.dyn, u_max_n=self.dyn.u_max_n if u_max_n is None else u_max_n,
                           v_max_mps=self.dyn.v_max_mps if v_max_mps is None else v_max_mps)

    # -- battery -------------------------------------------------------------------------------
    @property
    def battery_fraction(self) -> float:
        """Charge left, 0..1."""
        return max(0.0, 1.0 - self.impulse_ns / self.capacity_ns)

    @property
    def voltage_v(self) -> float:
        return VOLT_EMPTY_V + (VOLT_FULL_V - VOLT_EMPTY_V) * self.battery_fraction

    # -- attitude ------------------------------------------------------------------------------
    def attitude(self) -> tuple[float, float, float]:
        """(roll, pitch, yaw) in rad from the last control and the velocity (module docstring)."""
        ue, un = (float(v) for v in self.control[:2])
        weight = self.dyn.mass_kg * GRAVITY_MPS2
        ve, vn = (float(v) for v in self.state[self.dyn.dim: self.dyn.dim + 2])
        yaw = math.atan2(ve, vn) if (ve or vn) else 0.0
        return math.atan2(ue, weight), -math.atan2(un, weight), yaw
