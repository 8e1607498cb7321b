"""Parameters of the multirotor plant: airframe, flight controller, integration.

The plant is what flies, apart from the planners' model (Eq. 1). Each default
names its source:

- PX4's multicopter position controller (``mc_pos_control``: PositionControl.cpp
  and its parameter files ``multicopter_position_control_gain_params.yaml``,
  ``…_limits_params.yaml``, ``multicopter_position_control_params.yaml``) and
  attitude controller (``mc_att_control_params.yaml``).
- PX4's simulator-in-hardware quadrotor preset as RotorPy carries it
  (``rotorpy/vehicles/px4_sihsim_quadx_params.py``: a thrust-to-weight of 2 and
  the motor time constant ``SIH_T_TAU`` = 0.05 s).
- JSBSim's F450 quadcopter (``aircraft/F450``: mass 1.4 kg, drag coefficient 1.0
  on a reference area of 0.016129 m²).
- The paper, Sec. IV-A: ζ = 0.2 on m = 1.05 kg over ΔT = 1 s is a linear drag of
  ζ·m/ΔT = 0.21 N per m/s, taken here as the rotor drag.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

GRAVITY_MPS2 = 9.80665
AIR_DENSITY_KGPM3 = 1.225


@dataclass(frozen=True)
class AirframeParams:
    """A ~1.4 kg quadrotor: mass, thrust and drag, and the lags of its rotors and rate loop."""

    #: JSBSim F450 (aircraft/F450/Mass.xml: emptywt 1.4 kg)
    mass_kg: float = 1.4
    #: total thrust at full throttle over the weight; 2 puts the hover thrust at 0.5, PX4's
    #: MPC_THR_HOVER default (and the PX4 SIH quadrotor's 4 × 5 N for 1 kg)
    thrust_to_weight: float = 2.0
    #: first-order lag of the collective thrust (s): PX4 SIH_T_TAU (RotorPy's SIH preset)
    motor_tau_s: float = 0.05
    #: closed-loop lag of the body rates behind the attitude controller's rate setpoint (s):
    #: the rate loop and the rotational inertia as one first-order lag, a time-scale
    #: separation (Mahony, Kumar & Corke 2012, IEEE RAM 19(3), "hierarchical control")
    rate_tau_s: float = 0.05
    #: linear (rotor) drag, N per m/s of airspeed: the paper's ζ·m/ΔT = 0.2·1.05/1
    linear_drag_nspm: float = 0.21
    #: quadratic (body) drag area C_D·S (m²): JSBSim F450 (CD0 = 1.0, S = 0.016129 m²)
    drag_area_m2: float = 0.016129

    def __post_init__(self) -> None:
        if not (self.mass_kg > 0 and self.thrust_to_weight > 1):
            raise ValueError(f"need mass > 0 and thrust_to_weight > 1, got {self}")
        if not (self.motor_tau_s > 0 and self.rate_tau_s > 0):
            raise ValueError(f"lags must be positive, got {self}")
        if self.linear_drag_nspm < 0 or self.drag_area_m2 < 0:
            raise ValueError(f"drag must be non-negative, got {self}")

    @property
    def max_thrust_n(self) -> float:
        """Full-throttle collective thrust (N)."""
        return self.thrust_to_weight * self.mass_kg * GRAVITY_MPS2

    @property
    def quadratic_drag(self) -> float:
        """½ ρ C_D S (N per (m/s)²)."""
        return 0.5 * AIR_DENSITY_KGPM3 * self.drag_area_m2


@dataclass(frozen=True)
class ControllerParams:
    """PX4's cascaded multicopter controller: position P → velocity PID → thrust vector →
    attitude P (→ rate loop, see :attr:`AirframeParams.rate_tau_s`); PX4 defaults."""

    xy_p: float = 0.95  #: MPC_XY_P (1/s)
    z_p: float = 1.0  #: MPC_Z_P (1/s)
    xy_vel_p: float = 1.8  #: MPC_XY_VEL_P_ACC (1/s)
    xy_vel_i: float = 0.4  #: MPC_XY_VEL_I_ACC (1/s²)
    xy_vel_d: float = 0.2  #: MPC_XY_VEL_D_ACC (s⁰)
    z_vel_p: float = 4.0  #: MPC_Z_VEL_P_ACC (1/s)
    z_vel_i: float = 2.0  #: MPC_Z_VEL_I_ACC (1/s²)
    z_vel_d: float = 0.0  #: MPC_Z_VEL_D_ACC
    #: MPC_XY_VEL_MAX raised from PX4's 12 m/s so that the model's fastest plan flies: Eq. (1)
    #: with the "axis" speed limit allows 15·√2 = 21.2 m/s on a diagonal (Sec. IV-A)
    xy_vel_max_mps: float = 21.5
    z_vel_max_up_mps: float = 3.0  #: MPC_Z_VEL_MAX_UP
    z_vel_max_dn_mps: float = 1.5  #: MPC_Z_VEL_MAX_DN
    tilt_max_rad: float = math.radians(45.0)  #: MPC_TILTMAX_AIR
    thr_min: float = 0.12  #: MPC_THR_MIN (normalised thrust)
    thr_max: float = 1.0  #: MPC_THR_MAX
    thr_xy_margin: float = 0.3  #: MPC_THR_XY_MARG
    #: MPC_THR_HOVER; the plant's own hover thrust is 1/thrust_to_weight (0.5 by default)
    thr_hover: float = 0.5
    veld_lp_hz: float = 5.0  #: MPC_VELD_LP: low-pass of the velocity derivative (D term)
    att_p: float = 4.0  #: MC_ROLL_P = MC_PITCH_P (rad/s per rad)
    rate_max_rps: float = math.radians(220.0)  #: MC_ROLLRATE_MAX = MC_PITCHRATE_MAX

    def __post_init__(self) -> None:
        if not (0 < self.tilt_max_rad < math.pi / 2):
            raise ValueError(f"tilt_max_rad must lie in (0, π/2), got {self.tilt_max_rad}")
        if not (0 < self.thr_min < self.thr_hover < self.thr_max <= 1):
            raise ValueError(f"need 0 < thr_min < thr_hover < thr_max <= 1, got {self}")
        gains = (self.xy_p, self.z_p, self.xy_vel_p, self.z_vel_p, self.att_p, self.rate_max_rps)
        if min(gains) <= 0 or min(self.xy_vel_i, self.z_vel_i, self.xy_vel_d, self.z_vel_d) < 0:
            raise ValueError(f"gains must be positive (I, D non-negative), got {self}")


@dataclass(frozen=True)
class MultirotorParams:
    """The multirotor plant: airframe, controller, the integration and setpoint rates (Hz),
    and the altitude a 2-D mission holds (m)."""

    airframe: AirframeParams = field(default_factory=AirframeParams)
    controller: ControllerParams = field(default_factory=ControllerParams)
    #: integration (and path) rate; the position controller runs at every integration step
    rate_hz: float = 100.0
    #: the supervisor's SET_POSITION_TARGET_LOCAL_NED stream (services/supervisor/stream)
    setpoint_hz: float = 20.0
    #: the fixed altitude of the 2-D missions of Sec. IV (m above home)
    altitude_m: float = 50.0

    def __post_init__(self) -> None:
        if not (self.rate_hz >= 100.0 and self.setpoint_hz > 0):
            raise ValueError(f"need rate_hz >= 100 and setpoint_hz > 0, got {self}")
        if self.setpoint_hz > self.rate_hz:
            raise ValueError("the setpoint stream cannot be faster than the integration")
        if not (self.altitude_m > 0):
            raise ValueError(f"altitude_m must be positive, got {self.altitude_m}")
