"""The setpoint stream of one Eq. (1) segment, and the segment's own path.

Eq. (1) moves the position by ΔT·v_t over a step and the velocity from v_t to
v_{t+1} = (1 − ζ) v_t + ΔT u_t / m. Between the two states the planners' model
says nothing more; its path, as the clearance of the planners treats it, is the
straight segment p_t + s·v_t, s ∈ [0, ΔT] (:func:`segment_path`).

A flight controller needs a smooth reference: the stream is the cubic Hermite
curve through (p_t, v_t) and (p_{t+1}, v_{t+1}) with its velocity and
acceleration as feed-forward (the fields of SET_POSITION_TARGET_LOCAL_NED),
sampled at the stream's rate. It meets the straight segment at both ends and
departs from it by ΔT (τ² − τ³) ‖v_t − v_{t+1}‖ at τ = s/ΔT, at most
4/27 · ΔT ‖Δv‖ (≈ 1 m for the largest Δv of Sec. IV-A, 7.1 m/s).
"""

from __future__ import annotations

import numpy as np

from dualpilot.arrays import Array


def to_plant(x: Array, dim: int, altitude_m: float) -> tuple[Array, Array]:
    """A model state [p, v] (2-D or 3-D) as 3-D position and velocity (a 2-D state holds
    ``altitude_m``)."""
    x = np.asarray(x, dtype=float)
    p, v = np.zeros(3), np.zeros(3)
    p[:dim], v[:dim] = x[:dim], x[dim:2 * dim]
    if dim == 2:
        p[2] = altitude_m
    return p, v


def hermite_stream(start: Array, end: Array, duration_s: float, rate_hz: float,
                   dim: int, altitude_m: float) -> Array:
    """Setpoints (S, 9) of [p, v, a] (ENU; m, m/s, m/s²) at t = k/rate_hz, k < S, over one
    segment from model state ``start`` to ``end`` lasting ``duration_s``."""
    p0, v0 = to_plant(start, dim, altitude_m)
    p1, v1 = to_plant(end, dim, altitude_m)
    n = max(int(round(duration_s * rate_hz)), 1)
    tau = (np.arange(n) / (duration_s * rate_hz))[:, None]
    d = duration_s
    pos = ((2 * tau**3 - 3 * tau**2 + 1) * p0 + (tau**3 - 2 * tau**2 + tau) * d * v0
           + (-2 * tau**3 + 3 * tau**2) * p1 + (tau**3 - tau**2) * d * v1)
    vel = ((6 * tau**2 - 6 * tau) * p0 / d + (3 * tau**2 - 4 * tau + 1) * v0
           + (-6 * tau**2 + 6 * tau) * p1 / d + (3 * tau**2 - 2 * tau) * v1)
    acc = ((12 * tau - 6) * p0 / d**2 + (6 * tau - 4) * v0 / d
           + (-12 * tau + 6) * p1 / d**2 + (6 * tau - 2) * v1 / d)
    return np.hstack([pos, vel, acc])


def segment_path(start: Array, times_s: Array, dim: int, altitude_m: float) -> Array:
    """Eq. (1)'s path (len(times), 3): p_t + s·v_t at the times s (s) into the step."""
    p0, v0 = to_plant(start, dim, altitude_m)
    return np.asarray(p0 + np.asarray(times_s)[:, None] * v0)
