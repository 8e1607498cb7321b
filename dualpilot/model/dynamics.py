"""Agent dynamics, Eq. (1): x_t = Φ x_{t-1} + Γ u_t.

State ``x = [p, v]`` with position p (m) and velocity v (m/s), each of
dimension ``dim`` (3 in Sec. II-A, 2 in the evaluation of Sec. IV at fixed
altitude). Control u is the applied force (N).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Literal, get_args

import numpy as np

from dualpilot.arrays import AnyArray, Array
from dualpilot.lazy import lazy_module

#: the reach boxes' Numba kernel, loaded where a plan needs it
_reach_kernel = lazy_module("dualpilot.model.reach_kernel")

#: Readings of the speed limit X, see :attr:`DynamicsParams.speed_limit`.
SpeedLimit = Literal["axis", "norm"]


@dataclass(frozen=True)
class DynamicsParams:
    """Sec. IV-A values: ΔT = 1 s, ζ = 0.2, m = 1.05 kg, |u| ≤ 7.5 N per axis, v_max = 15 m/s."""

    dt_s: float = 1.0
    zeta: float = 0.2
    mass_kg: float = 1.05
    u_max_n: float = 7.5
    v_max_mps: float = 15.0
    dim: int = 2
    #: Reading of Sec. IV-A ("The UAV agent can reach a maximum velocity of 15m/s,
    #: utilizing an input control force in the range of [-7.5,7.5]N"): "axis" bounds
    #: every velocity component, |v_i| ≤ v_max (≈ 21.2 m/s on a diagonal); "norm"
    #: bounds the speed, ‖v‖ ≤ v_max. The force is a per-axis box in both.
    speed_limit: SpeedLimit = "axis"

    def __post_init__(self) -> None:
        if not (self.dt_s > 0 and self.mass_kg > 0 and 0 <= self.zeta < 1):
            raise ValueError(f"invalid dynamics parameters: {self}")
        if self.dim not in (2, 3):
            raise ValueError(f"dim must be 2 or 3, got {self.dim}")
        if not (self.u_max_n > 0 and self.v_max_mps > 0):
            raise ValueError("force and speed limits must be positive")
        if self.speed_limit not in get_args(SpeedLimit):
            raise ValueError(f"speed_limit must be one of {get_args(SpeedLimit)}, "
                             f"not {self.speed_limit!r}")

    @property
    def state_dim(self) -> int:
        return 2 * self.dim

    @property
    def max_speed_mps(self) -> float:
        """The largest ‖v‖ the speed limit allows: v_max·√dim per axis, v_max as a norm (m/s)."""
        if self.speed_limit == "norm":
            return self.v_max_mps
        return self.v_max_mps * math.sqrt(self.dim)

    def speeds(self, velocities: Array) -> Array:
        """The measure the speed limit bounds, per row of ``velocities`` (…, dim): max_i |v_i|
        per axis, ‖v‖ as a norm (m/s)."""
        v = np.asarray(velocities, dtype=float)
        if self.speed_limit == "norm":
            return np.asarray(np.linalg.norm(v, axis=-1))
        return np.asarray(np.max(np.abs(v), axis=-1))


def reach_radius(v0: Array, horizon: int, params: DynamicsParams) -> float:
    """Upper bound on ‖p_{t+τ|t} − p_t‖ for τ ≤ T from velocity v0 (m): ΔT·(‖v0‖ + (T−1)·the
    largest speed the limit allows)."""
    return params.dt_s * (float(np.linalg.norm(v0)) + (horizon - 1) * params.max_speed_mps)


def clip_velocity(v: Array, params: DynamicsParams) -> Array:
    """``v`` (m/s) clipped to the speed limit: per axis, or scaled onto the disc ‖v‖ = v_max."""
    if params.speed_limit == "norm":
        speed = float(np.linalg.norm(v))
        if speed > params.v_max_mps:
            return np.asarray(v, dtype=float) * (params.v_max_mps / speed)
        return np.asarray(v, dtype=float)
    return np.clip(v, -params.v_max_mps, params.v_max_mps)


def speed_polygon(sides: int) -> tuple[Array, float]:
    """Normals n_k = (cos θ_k, sin θ_k), θ_k = (2k+1)π/K, k < K, and cos(π/K).

    The regular K-gon n_k·v ≤ v_max·cos(π/K) lies inside the disc ‖v‖ ≤ v_max,
    its vertices on the circle at angles 2πk/K: for K a multiple of 8 the axes
    and the diagonals point at vertices, so a plan along them has one best
    speed, v_max (along a face the speed across it would be set only by the
    second-order terms of Eq. (S2)).
    """
    if sides < 3:
        raise ValueError(f"a speed polygon needs at least 3 sides, got {sides}")
    ang = math.pi * (2.0 * np.arange(sides) + 1.0) / sides
    return np.column_stack([np.cos(ang), np.sin(ang)]), math.cos(math.pi / sides)


@lru_cache(maxsize=64)
def transition_matrices(params: DynamicsParams = DynamicsParams()) -> tuple[Array, Array]:
    """Return (Φ, Γ) of Eq. (1), read-only (computed once per parameter set).

    Φ = [[I, ΔT·I], [0, (1-ζ)·I]],  Γ = [[0], [ΔT/m·I]].
    """
    n = params.dim
    eye = np.eye(n)
    phi = np.block([[eye, params.dt_s * eye], [np.zeros((n, n)), (1.0 - params.zeta) * eye]])
    gamma = np.vstack([np.zeros((n, n)), (params.dt_s / params.mass_kg) * eye])
    return _frozen(phi), _frozen(gamma)


def _frozen(a: AnyArray) -> Array:
    """``a`` as a read-only float array (shared by every caller of a cache)."""
    out = np.asarray(a, dtype=float)
    out.setflags(write=False)
    return out


@lru_cache(maxsize=64)
def _rollout_weights(params: DynamicsParams, horizon: int) -> tuple[Array, Array]:
    """(1-ζ)^k (column, k = 0..T) and the (T+1, T) control weights of :func:`rollout`."""
    decay = 1.0 - params.zeta
    k = np.arange(horizon + 1)
    expo = k[:, None] - 1 - k[None, :horizon]
    gain = params.dt_s / params.mass_kg
    weights = np.where(expo >= 0, decay ** np.maximum(expo, 0), 0.0) * gain
    return _frozen(decay ** k[:, None]), _frozen(weights)


def check_state(x: Array, params: DynamicsParams) -> Array:
    """Return ``x`` as a float array, or raise ValueError for a wrong shape or non-finite value."""
    arr = np.asarray(x, dtype=float)
    if arr.shape != (params.state_dim,):
        raise ValueError(f"state must have shape ({params.state_dim},), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"state must be finite, got {arr}")
    return arr


def step(x: Array, u: Array, params: DynamicsParams = DynamicsParams()) -> Array:
    """Advance one ΔT with Eq. (1); u is clipped to U and the velocity to the speed limit.

    The clips model the autopilot's actuator and speed limits (the planners
    already respect both, so for their plans the clip is a no-op).
    """
    x = check_state(x, params)
    u = np.clip(np.asarray(u, dtype=float), -params.u_max_n, params.u_max_n)
    if u.shape != (params.dim,) or not np.all(np.isfinite(u)):
        raise ValueError(f"control must be finite with shape ({params.dim},), got {u}")
    phi, gamma = transition_matrices(params)
    nxt = phi @ x + gamma @ u
    n = params.dim
    nxt[n:] = clip_velocity(nxt[n:], params)
    return np.asarray(nxt, dtype=float)


def rollout(x0: Array, controls: Array, params: DynamicsParams = DynamicsParams()) -> Array:
    """States x_0..x_T (shape (T+1, 2·dim)) under Eq. (1) without clipping."""
    x0 = check_state(x0, params)
    controls = np.asarray(controls, dtype=float).reshape(-1, params.dim)
    n, horizon = params.dim, len(controls)
    # Φ, Γ of transition_matrices in closed form: v_k = (1-ζ)^k v_0 + Σ_j (1-ζ)^(k-1-j) (ΔT/m) u_j,
    # p_k = p_0 + ΔT Σ_{j<k} v_j; one lower-triangular matrix product instead of T steps.
    decay_k, weights = _rollout_weights(params, horizon)
    vel = decay_k * x0[n:] + weights @ controls
    out = np.empty((horizon + 1, 2 * n))
    travelled = out[:, :n]  # Σ_{j<k} v_j, then p_k = p_0 + ΔT Σ_{j<k} v_j
    travelled[0] = 0.0
    np.cumsum(vel[:-1], axis=0, out=travelled[1:])
    out[:, :n] = x0[:n] + params.dt_s * travelled
    out[:, n:] = vel
    return out


def hover_state(position: Array, params: DynamicsParams = DynamicsParams()) -> Array:
    """A state at ``position`` with zero velocity."""
    pos = np.asarray(position, dtype=float)
    return check_state(np.concatenate([pos, np.zeros(params.dim)]), params)


def reach_boxes(x0: Array, horizon: int, dyn: DynamicsParams) -> tuple[Array, Array]:
    """Per-axis bounds on p_{t+τ|t}, τ = 1..T, under |u| ≤ u_max and |v| ≤ v_max (m).

    Valid under both speed limits (‖v‖ ≤ v_max implies |v_i| ≤ v_max). Eq. (1)
    per axis with the force and speed at their limits (compiled: it runs for
    every QP of a plan); the axes are independent, so the planar axes of a 3-D
    state get the planar numbers. ``x0`` is [p, v] of ``dyn.dim`` each. Returns (lo, hi),
    each (T, dim).
    """
    x = np.asarray(x0, dtype=float)
    if x.shape != (dyn.state_dim,):
        raise ValueError(f"state must have shape ({dyn.state_dim},), got {x.shape}")
    return _reach_kernel().reach(x, int(horizon), dyn.dim, 1.0 - dyn.zeta,
                 dyn.dt_s / dyn.mass_kg * dyn.u_max_n, float(dyn.v_max_mps), float(dyn.dt_s))
