"""The multirotor's flight: rigid-body translation under PX4's cascaded controller (compiled).

Frame: local east-north-up (m), gravity along −z. The vehicle state is
position p, velocity v, the thrust axis b₃ (unit vector, body z), the body
rate ω (rad/s, world frame) and the collective thrust T (N). The airframe is

    m v̇ = T b₃ − m g e₃ − k_l (v − w) − ½ρC_DS ‖v − w‖ (v − w),     ṗ = v,

with w the wind (m/s); T and ω follow their commands through first-order lags
(the motors, SIH_T_TAU; the rate loop, see ``AirframeParams.rate_tau_s``), and
b₃ turns with ω (Mahony, Kumar & Corke 2012, Eqs. (1)–(3), reduced to the thrust
axis: yaw does not move a symmetric quadrotor).

The controller is PX4's ``PositionControl`` (mc_pos_control/PositionControl/
PositionControl.cpp), line for line in ENU: velocity setpoint = feed-forward +
MPC_XY_P·position error, constrained to MPC_XY_VEL_MAX with the P part first
(``ControlMath::constrainXY``); acceleration = feed-forward + PID on the velocity
error (D on the low-passed velocity derivative); thrust direction from the
acceleration and gravity, limited to MPC_TILTMAX_AIR; collective thrust scaled
by the hover thrust; vertical priority with the MPC_THR_XY_MARG margin; the
horizontal tracking anti-windup and the vertical integrator clamp. The attitude
controller (mc_att_control) turns b₃ towards the thrust direction with rate
MC_ROLL_P·angle, at most MC_ROLLRATE_MAX.

Semi-implicit Euler at the integration step; the lags are integrated exactly.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from dualpilot.arrays import Array
from dualpilot.plant.layout import B3, STATE_LEN, VDOT, VINT, VPREV, P, T, V, W
from dualpilot.plant.params import GRAVITY_MPS2, MultirotorParams


def hover_vector(position: Array, velocity: Array, params: MultirotorParams) -> Array:
    """The plant's state at ``position`` (m, ENU) with ``velocity`` (m/s), level and at
    hover thrust, the controller's integrators at rest."""
    x = np.zeros(STATE_LEN)
    x[P:P + 3] = position
    x[V:V + 3] = velocity
    x[VPREV:VPREV + 3] = velocity
    x[B3 + 2] = 1.0
    x[T] = params.airframe.mass_kg * GRAVITY_MPS2
    return x


def pack(params: MultirotorParams) -> Array:
    """The parameters as the compiled kernel reads them."""
    a, c = params.airframe, params.controller
    return np.array([
        a.mass_kg, a.max_thrust_n, a.motor_tau_s, a.rate_tau_s, a.linear_drag_nspm,
        a.quadratic_drag, c.xy_p, c.z_p, c.xy_vel_p, c.xy_vel_i, c.xy_vel_d, c.z_vel_p,
        c.z_vel_i, c.z_vel_d, c.xy_vel_max_mps, c.z_vel_max_up_mps, c.z_vel_max_dn_mps,
        c.tilt_max_rad, c.thr_min, c.thr_max, c.thr_xy_margin, c.thr_hover, c.veld_lp_hz,
        c.att_p, c.rate_max_rps, GRAVITY_MPS2,
    ])


def fly(state: Array, setpoints: Array, setpoint_dt_s: float, wind: Array,
        estimate_error: Array, params: MultirotorParams) -> Array:
    """Integrate ``len(wind)`` steps of 1/rate_hz from ``state`` (changed in place).

    ``setpoints`` (S, 9) holds [p, v, a] setpoints (ENU, m, m/s, m/s²), each held
    for ``setpoint_dt_s``; ``wind`` (N, 3) the wind (m/s) and ``estimate_error``
    (N, 3) the error (m) of the position the controller sees, per integration step.
    Returns the path (N+1, 6) of [p, v] at the integration rate, start included.
    """
    return np.asarray(_fly(state, np.ascontiguousarray(setpoints, dtype=float),
                           float(setpoint_dt_s), np.ascontiguousarray(wind, dtype=float),
                           np.ascontiguousarray(estimate_error, dtype=float), pack(params),
                           1.0 / params.rate_hz))


@njit(cache=True)
def _constrain_xy(v0x: float, v0y: float, v1x: float, v1y: float,
                  vmax: float) -> tuple[float, float]:
    """ControlMath::constrainXY: v0 + s·v1 with ‖·‖ ≤ vmax, keeping v0 first."""
    sx, sy = v0x + v1x, v0y + v1y
    if sx * sx + sy * sy <= vmax * vmax:
        return sx, sy
    n0 = math.sqrt(v0x * v0x + v0y * v0y)
    if n0 >= vmax:
        return v0x / n0 * vmax, v0y / n0 * vmax
    n1 = math.sqrt(v1x * v1x + v1y * v1y)
    if n1 < 1e-9:
        return v0x, v0y
    ux, uy = v1x / n1, v1y / n1
    b = v0x * ux + v0y * uy
    s = -b + math.sqrt(b * b - (n0 * n0 - vmax * vmax))
    return v0x + s * ux, v0y + s * uy


@njit(cache=True)
def _thrust_setpoint(acc: Array, prm: Array) -> Array:
    """PositionControl::_accelerationControl in ENU: the normalised thrust vector."""
    g, tilt_max, thr_min, thr_hover = prm[25], prm[17], prm[18], prm[21]
    bz = np.array([acc[0], acc[1], g + acc[2]])
    bz /= math.sqrt(bz[0] ** 2 + bz[1] ** 2 + bz[2] ** 2)
    if bz[2] < math.cos(tilt_max):  # ControlMath::limitTilt
        h = math.sqrt(bz[0] ** 2 + bz[1] ** 2)
        bz[0] = bz[0] / h * math.sin(tilt_max)
        bz[1] = bz[1] / h * math.sin(tilt_max)
        bz[2] = math.cos(tilt_max)
    collective = (g + acc[2]) * thr_hover / g / bz[2]
    return bz * max(collective, thr_min)


@njit(cache=True)
def _saturate(thr: Array, prm: Array) -> Array:
    """Vertical priority with a horizontal margin (PositionControl::_velocityControl)."""
    thr_max, margin = prm[19], prm[20]
    nxy = math.sqrt(thr[0] ** 2 + thr[1] ** 2)
    z_max_sq = thr_max * thr_max - min(nxy, margin) ** 2
    thr[2] = min(thr[2], math.sqrt(z_max_sq))
    xy_max_sq = thr_max * thr_max - thr[2] * thr[2]
    xy_max = math.sqrt(xy_max_sq) if xy_max_sq > 0 else 0.0
    if nxy > xy_max:
        thr[0] *= xy_max / nxy
        thr[1] *= xy_max / nxy
    return thr


@njit(cache=True)
def _control(x: Array, sp: Array, err: Array, prm: Array, dt: float) -> Array:
    """One run of PositionControl::update: the normalised thrust vector; updates the
    integrator and the velocity derivative in ``x``."""
    g = prm[25]
    vel_sp = np.empty(3)
    px = sp[0] - (x[P] + err[0])
    py = sp[1] - (x[P + 1] + err[1])
    vel_sp[0], vel_sp[1] = _constrain_xy(prm[6] * px, prm[6] * py, sp[3], sp[4], prm[14])
    vel_sp[2] = min(max(sp[5] + prm[7] * (sp[2] - (x[P + 2] + err[2])), -prm[16]), prm[15])
    # the velocity derivative, low-passed at MPC_VELD_LP
    alpha = 1.0 - math.exp(-2.0 * math.pi * prm[22] * dt)
    for i in range(3):
        raw = (x[V + i] - x[VPREV + i]) / dt
        x[VDOT + i] += alpha * (raw - x[VDOT + i])
        x[VPREV + i] = x[V + i]
    kp = np.array([prm[8], prm[8], prm[11]])
    ki = np.array([prm[9], prm[9], prm[12]])
    kd = np.array([prm[10], prm[10], prm[13]])
    vel_err = vel_sp - x[V:V + 3]
    acc = sp[6:9] + kp * vel_err + x[VINT:VINT + 3] - kd * x[VDOT:VDOT + 3]
    thr = _saturate(_thrust_setpoint(acc, prm), prm)
    if (thr[2] <= prm[18] and vel_err[2] <= 0.0) or (thr[2] >= prm[19] and vel_err[2] >= 0.0):
        vel_err[2] = 0.0
    produced = thr[:2] * (g / prm[21])
    limited = produced if acc[0] ** 2 + acc[1] ** 2 > produced[0] ** 2 + produced[1] ** 2 \
        else acc[:2]
    vel_err[:2] -= (2.0 / prm[8]) * (acc[:2] - limited)
    for i in range(3):
        x[VINT + i] += vel_err[i] * ki[i] * dt
    x[VINT + 2] = min(abs(x[VINT + 2]), g) * (1.0 if x[VINT + 2] >= 0 else -1.0)
    return thr


@njit(cache=True)
def _attitude(x: Array, thr: Array, prm: Array, dt: float) -> None:
    """Turn the thrust axis towards ``thr`` and follow the thrust command (in ``x``)."""
    n = math.sqrt(thr[0] ** 2 + thr[1] ** 2 + thr[2] ** 2)
    bd = thr / n
    b3 = x[B3:B3 + 3]
    axis = np.cross(b3, bd)
    s = math.sqrt(axis[0] ** 2 + axis[1] ** 2 + axis[2] ** 2)
    angle = math.atan2(s, b3[0] * bd[0] + b3[1] * bd[1] + b3[2] * bd[2])
    rate = min(prm[23] * angle, prm[24])
    w_cmd = axis / s * rate if s > 1e-12 else np.zeros(3)
    keep_w = math.exp(-dt / prm[3])
    keep_t = math.exp(-dt / prm[2])
    for i in range(3):
        x[W + i] = w_cmd[i] + (x[W + i] - w_cmd[i]) * keep_w
    x[T] = n * prm[1] + (x[T] - n * prm[1]) * keep_t
    # rotate b3 about ω by |ω|·dt (Rodrigues), then renormalise
    w = x[W:W + 3]
    wn = math.sqrt(w[0] ** 2 + w[1] ** 2 + w[2] ** 2)
    if wn > 1e-12:
        k = w / wn
        th = wn * dt
        kb = np.cross(k, b3)
        b3n = b3 * math.cos(th) + kb * math.sin(th) + k * np.dot(k, b3) * (1 - math.cos(th))
        x[B3:B3 + 3] = b3n / math.sqrt(b3n[0] ** 2 + b3n[1] ** 2 + b3n[2] ** 2)


@njit(cache=True)
def _fly(x: Array, sps: Array, sp_dt: float, wind: Array, err: Array, prm: Array,
         dt: float) -> Array:
    n = wind.shape[0]
    path = np.empty((n + 1, 6))
    path[0, :] = x[:6]
    mass, k_lin, k_quad, g = prm[0], prm[4], prm[5], prm[25]
    for k in range(n):
        j = min(int(k * dt / sp_dt + 1e-9), sps.shape[0] - 1)
        thr = _control(x, sps[j], err[k], prm, dt)
        _attitude(x, thr, prm, dt)
        rel = x[V:V + 3] - wind[k]
        speed = math.sqrt(rel[0] ** 2 + rel[1] ** 2 + rel[2] ** 2)
        for i in range(3):
            f = x[T] * x[B3 + i] - (k_lin + k_quad * speed) * rel[i]
            if i == 2:
                f -= mass * g
            x[V + i] += f / mass * dt
            x[P + i] += x[V + i] * dt
        path[k + 1, :] = x[:6]
    return path
