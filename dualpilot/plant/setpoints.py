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

from functools import lru_cache

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


@lru_cache(maxsize=16)
def _hermite_basis(n: int, samples_per_s: float, duration_s: float) -> Array:
    """(3n, 4) weights of [p0, ΔT·v0, p1, ΔT·v1] for position, velocity·ΔT and
    acceleration·ΔT² at τ = k/(duration·rate), k < n."""
    tau = np.arange(n) / (duration_s * samples_per_s)
    t2, t3 = tau**2, tau**3
    pos = np.column_stack([2 * t3 - 3 * t2 + 1, t3 - 2 * t2 + tau, -2 * t3 + 3 * t2, t3 - t2])
    vel = np.column_stack([6 * t2 - 6 * tau, 3 * t2 - 4 * tau + 1, -6 * t2 + 6 * tau,
                           3 * t2 - 2 * tau])
    acc = np.column_stack([12 * tau - 6, 6 * tau - 4, -12 * tau + 6, 6 * tau - 2])
    out = np.vstack([pos, vel, acc])
    out.setflags(write=False)
    return out


def hermite_stream(start: Array, end: Array, duration_s: float, rate_hz: float,
                   dim: int, altitude_m: float) -> Array:
    """Setpoints (S, 9) of [p, v, a] (ENU; m, m/s, m/s²) at t = k/rate_hz, k < S, over one
    segment from model state ``start`` to ``end`` lasting ``duration_s``."""
    p0, v0 = to_plant(start, dim, altitude_m)
    p1, v1 = to_plant(end, dim, altitude_m)
    n = max(int(round(duration_s * rate_hz)), 1)
    d = duration_s
    curve = _hermite_basis(n, rate_hz, d) @ np.vstack([p0, d * v0, p1, d * v1])
    return np.hstack([curve[:n], curve[n:2 * n] / d, curve[2 * n:] / d**2])


def segment_path(start: Array, times_s: Array, dim: int, altitude_m: float) -> Array:
    """Eq. (1)'s path (len(times), 3): p_t + s·v_t at the times s (s) into the step."""
    p0, v0 = to_plant(start, dim, altitude_m)
    return np.asarray(p0 + np.asarray(times_s)[:, None] * v0)
