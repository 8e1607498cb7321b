"""System 1's low-level tracker: discrete-time LQR on Eq. (1) following the reference path.

Sec. III-A: an LQR with gain K tracks the reference x̂_{t+τ|t} from Alg. 1,
minimising J = Σ (x − x̂)ᵀ Q (x − x̂) + ûᵀ R û with Q = 2·I₄, R = 0.1·I₂
(Sec. IV-A). K comes from the discrete algebraic Riccati equation of (Φ, Γ).
In 3-D (Q = 2·I₆, R = 0.1·I₃) the gain is the same scalars per axis, taken from the
planar DARE (:func:`tracker_gain`).

Our reading, each a parameter:

* The path is a geometric path; we time-parameterise it (positions and
  velocities per ΔT) at a reference speed along the path with a trapezoidal
  profile (accelerate from the UAV's current along-path speed, decelerate to
  rest at the path's end, which lies in G). After the end the reference holds
  there.
* The paper writes û = −K(x − x̂). We add the feed-forward u_ff that makes
  the reference itself satisfy Eq. (1) as far as Γ allows,
  u_ff,k = (m/ΔT)(v̂_{k+1} − (1 − ζ) v̂_k), which cancels the drag ζ (without
  it the UAV lags the reference by ζ·m·v/K). ``feedforward=False`` gives the
  paper's law.
* u is clipped to U (|u| ≤ 7.5 N per axis) and, per axis, reduced so the next
  velocity stays within |v| ≤ 15 m/s; states are rolled out with Eq. (1)
  exactly, so the result passes :func:`dualpilot.verify.verify_trajectory`'s
  dynamics check. Under ``DynamicsParams.speed_limit = "norm"`` the clipped u
  is scaled by the largest α ∈ [0, 1] with ‖(1 − ζ) v_k + α u ΔT/m‖ ≤ 15 m/s
  (:func:`_track_norm`).

Option (not the paper's; System 1's ``tracker="lqr_du"``): an LQR on the state
augmented with the previous control, z = [x − x̂; w₋] with input Δw
(:func:`lqr_du_gain`), stage cost eᵀQe + wᵀRw + ΔwᵀR_Δ Δw, where w = u − u_ff
is the feedback part of u (u itself without the feed-forward), started from the
control last applied (:func:`track` with ``prev_control``).

Indexing follows :class:`dualpilot.plan.Plan`: ``states[k+1] = Φ states[k] + Γ controls[k]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np
from numba import njit
from scipy.linalg import solve_discrete_are

from dualpilot.model.dynamics import Array, DynamicsParams, check_state, transition_matrices


@dataclass(frozen=True)
class LqrParams:
    """Weights Q = q·I, R = r·I (Sec. IV-A: q = 2, r = 0.1) and the reference profile.

    ``accel_mps2`` and ``decel_mps2`` shape the reference speed profile along
    the path (m/s²); ``feedforward`` adds the drag-compensating u_ff.
    """

    q: float = 2.0
    r: float = 0.1
    feedforward: bool = True
    accel_mps2: float = 3.0
    decel_mps2: float = 2.0

    def __post_init__(self) -> None:
        if not (self.q > 0 and self.r > 0):
            raise ValueError(f"LQR weights must be positive, got q={self.q}, r={self.r}")
        if not (self.accel_mps2 > 0 and self.decel_mps2 > 0):
            raise ValueError("accel_mps2 and decel_mps2 must be positive")


def lqr_gain(dynamics: DynamicsParams = DynamicsParams(), q: float = 2.0,
             r: float = 0.1) -> tuple[Array, Array]:
    """Infinite-horizon discrete LQR for Eq. (1): returns (K, P).

    P solves the DARE P = ΦᵀPΦ − ΦᵀPΓ(R + ΓᵀPΓ)⁻¹ΓᵀPΦ + Q and
    K = (R + ΓᵀPΓ)⁻¹ΓᵀPΦ, so that u = −K x.
    """
    if not (q > 0 and r > 0):
        raise ValueError(f"LQR weights must be positive, got q={q}, r={r}")
    k, p = _lqr_gain(dynamics, float(q), float(r))
    return k.copy(), p.copy()


@lru_cache(maxsize=16)
def _lqr_gain(dynamics: DynamicsParams, q: float, r: float) -> tuple[Array, Array]:
    """:func:`lqr_gain`, solved once a process per (dynamics, q, r)."""
    phi, gamma = transition_matrices(dynamics)
    qm = q * np.eye(dynamics.state_dim)
    rm = r * np.eye(dynamics.dim)
    p = solve_discrete_are(phi, gamma, qm, rm)
    k = np.linalg.solve(rm + gamma.T @ p @ gamma, gamma.T @ p @ phi)
    return np.asarray(k, dtype=float), np.asarray(p, dtype=float)


#: R_Δ = r_delta_u·I, the weight on Δu of :func:`lqr_du_gain` (against Q = 2·I,
#: R = 0.1·I). At 100: k_p, k_v, k_u ≈ 0.090, 0.292, 0.594 (plain: 0.629, 1.453, 1),
#: closed-loop spectral radius 0.74 (plain 0.37); the first jump of a handover and
#: a plan's Σ‖Δu‖² fall ~4x and ~2.5x (median) with the same plans verifying, for a
#: larger cross-track overshoot when the UAV arrives with a velocity across the path
#: (18 m instead of 11 m at 10 m/s); 300 and more start needing slower retries.
#: benchmarks/handover_energy.py measures it.
R_DELTA_U = 100.0


def lqr_du_gain(dynamics: DynamicsParams = DynamicsParams(), q: float = 2.0, r: float = 0.1,
                r_delta_u: float = R_DELTA_U) -> tuple[Array, Array]:
    """Discrete LQR on Eq. (1) augmented with the previous control: returns (K_z, P_z).

    z = [x; u₋] (2·dim + dim), input Δu with u = u₋ + Δu:
    z' = A z + B Δu, A = [[Φ, Γ], [0, I]], B = [[Γ], [I]]. The stage cost
    xᵀQx + uᵀRu + ΔuᵀR_Δ Δu (Q = q·I, R = r·I, R_Δ = r_delta_u·I) is
    zᵀ diag(Q, R) z + Δuᵀ(R + R_Δ)Δu + 2 zᵀS Δu with S = [[0], [R]]; P_z solves
    that DARE and K_z = (R + R_Δ + BᵀP_zB)⁻¹(BᵀP_zA + Sᵀ), so Δu = −K_z z.
    K_z = [k_p·I, k_v·I, k_u·I]; as R_Δ → 0 it tends to [K, I] with K of
    :func:`lqr_gain` (u = −Kx, the plain LQR).
    """
    if not (q > 0 and r > 0):
        raise ValueError(f"LQR weights must be positive, got q={q}, r={r}")
    if not (r_delta_u >= 0 and np.isfinite(r_delta_u)):
        raise ValueError(f"r_delta_u must be finite and >= 0, got {r_delta_u}")
    k, p = _lqr_du_gain(dynamics, float(q), float(r), float(r_delta_u))
    return k.copy(), p.copy()


@lru_cache(maxsize=16)
def _lqr_du_gain(dynamics: DynamicsParams, q: float, r: float, r_delta_u: float
                 ) -> tuple[Array, Array]:
    """:func:`lqr_du_gain`, solved once a process per (dynamics, q, r, r_delta_u)."""
    phi, gamma = transition_matrices(dynamics)
    n, nx = dynamics.dim, dynamics.state_dim
    eye = np.eye(n)
    a = np.block([[phi, gamma], [np.zeros((n, nx)), eye]])
    b = np.vstack([gamma, eye])
    qz = np.block([[q * np.eye(nx), np.zeros((nx, n))], [np.zeros((n, nx)), r * eye]])
    rz = (r + r_delta_u) * eye
    s = np.vstack([np.zeros((nx, n)), r * eye])
    p = solve_discrete_are(a, b, qz, rz, s=s)
    k = np.linalg.solve(rz + b.T @ p @ b, b.T @ p @ a + s.T)
    return np.asarray(k, dtype=float), np.asarray(p, dtype=float)


def tracker_gain(dynamics: DynamicsParams, q: float = 2.0, r: float = 0.1,
                 r_delta_u: float | None = None) -> Array:
    """System 1's gain for ``dynamics`` of any dimension, from the planar DARE.

    :func:`lqr_gain` (``r_delta_u`` None) or :func:`lqr_du_gain` solved for the plane, and
    in 3-D the same scalars on every axis: [k_p·I₃, k_v·I₃] (or [k_p·I₃, k_v·I₃, k_u·I₃]).
    Q = q·I and R = r·I act on each axis alike, so this is the 3-D gain; but the 6×6 (9×9)
    DARE's solution differs from the planar one in the 15th digit (docs/three_d.md), and
    these scalars let a 3-D plan's planar axes be the 2-D plan's bit for bit.
    """
    planar = dynamics if dynamics.dim == 2 else replace(dynamics, dim=2)
    if r_delta_u is None:
        k2, _ = lqr_gain(planar, q, r)
    else:
        k2, _ = lqr_du_gain(planar, q, r, r_delta_u)
    if dynamics.dim == 2:
        return k2
    kp, kv, ku = _gain_form(k2.tobytes(), k2.shape, 2)
    eye = np.eye(dynamics.dim)
    return np.hstack([kp * eye, kv * eye] + ([] if ku is None else [ku * eye]))


def _check_path(path: Array, dim: int) -> Array:
    pts = np.asarray(path, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != dim or len(pts) < 1:
        raise ValueError(f"path must have shape (k >= 1, {dim}), got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("path must be finite")
    return pts


def speed_profile(
    length_m: float, horizon: int, speed_mps: float, dt_s: float,
    v0_mps: float = 0.0, accel_mps2: float = 3.0, decel_mps2: float = 2.0,
) -> Array:
    """Arc length s_k (m), k = 0..horizon+1, along a path of ``length_m``.

    Speed starts at ``v0_mps`` (clipped to [0, speed]; the UAV's speed along
    the path), rises at ``accel_mps2`` to ``speed_mps`` and falls at
    ``decel_mps2`` so that the reference comes to rest at the end of the
    path, then holds there. As in Eq. (1), s_{k+1} = s_k + ΔT·v_k.
    """
    if not (speed_mps > 0 and np.isfinite(speed_mps)):
        raise ValueError(f"reference speed must be positive, got {speed_mps}")
    if horizon < 1:
        raise ValueError(f"horizon must be >= 1, got {horizon}")
    v = float(np.clip(v0_mps, 0.0, speed_mps))
    return _arc_lengths(float(length_m), int(horizon), float(speed_mps), float(dt_s), v,
                        float(accel_mps2), float(decel_mps2))


@njit(cache=True)
def _arc_lengths(length_m: float, horizon: int, speed_mps: float, dt_s: float, v: float,
                 accel_mps2: float, decel_mps2: float) -> Array:
    """The recursion of :func:`speed_profile` (compiled; Python's min order kept)."""
    s = np.empty(horizon + 2)
    s[0] = 0.0
    for k in range(horizon + 1):
        # Eq. (1) moves the position by ΔT times the speed at the start of the step
        s[k + 1] = _pmin(length_m, s[k] + v * dt_s)
        v = _pmin(_pmin(speed_mps, v + accel_mps2 * dt_s),
                  math.sqrt(2.0 * decel_mps2 * (length_m - s[k + 1])))
    return s


def reference_states(
    path: Array, horizon: int, speed_mps: float,
    dynamics: DynamicsParams = DynamicsParams(), v0_mps: float = 0.0,
    params: LqrParams = LqrParams(),
) -> Array:
    """Time-parameterised reference x̂_k = [p̂_k, v̂_k], k = 0..horizon (shape (horizon+1, 2·dim)).

    p̂_k is the point at arc length s_k of :func:`speed_profile` on the
    polyline ``path`` (k, dim) and v̂_k = (p̂_{k+1} − p̂_k)/ΔT, so the
    reference positions follow p̂_{k+1} = p̂_k + ΔT·v̂_k exactly.
    """
    pts = _check_path(path, dynamics.dim)
    seg = np.diff(pts, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    s = speed_profile(float(cum[-1]), horizon, speed_mps, dynamics.dt_s, v0_mps,
                      params.accel_mps2, params.decel_mps2)
    pos = np.empty((len(s), dynamics.dim))
    for d in range(dynamics.dim):
        pos[:, d] = np.interp(s, cum, pts[:, d]) if len(pts) > 1 else pts[0, d]
    vel = np.diff(pos, axis=0) / dynamics.dt_s
    return np.hstack([pos[:-1], vel])


def track(
    x0: Array, reference: Array, gain: Array,
    dynamics: DynamicsParams = DynamicsParams(), feedforward: bool = True,
    prev_control: Array | None = None,
) -> tuple[Array, Array]:
    """Closed loop u_k = u_ff,k − K(x_k − x̂_k), clipped to U and to the speed limit.

    Returns (states (T+1, 2·dim), controls (T, dim)) with T = len(reference) − 1
    and states[0] = x0; the states follow Eq. (1) exactly under the controls.
    K must have the form [k_p·I, k_v·I] that :func:`lqr_gain` returns (Φ, Γ
    and Q = q·I, R = r·I act on each axis alike, so the axes decouple); the
    loop then runs per axis, compiled (:func:`_track_axes`).

    A gain [k_p·I, k_v·I, k_u·I] of :func:`lqr_du_gain` runs the Δu tracker
    instead, from u₋₁ = ``prev_control`` (u_{t|t}, N; None: zero), see
    :func:`_track_du`. ``prev_control`` is refused with the plain gain,
    which has no use for it.
    """
    x = check_state(x0, dynamics)
    ref = np.asarray(reference, dtype=float)
    n = dynamics.dim
    if ref.ndim != 2 or ref.shape[1] != 2 * n or len(ref) < 2:
        raise ValueError(f"reference must have shape (T+1 >= 2, {2 * n}), got {ref.shape}")
    kp, kv, ku, u_prev = _gain_terms(np.asarray(gain, dtype=float), n, prev_control)
    if dynamics.speed_limit == "norm":
        return _track_norm(x, ref, kp, kv, ku, u_prev, dynamics, feedforward)
    if ku is not None:
        return _track_du(x, ref, kp, kv, ku, u_prev, dynamics, feedforward)
    dt, decay = dynamics.dt_s, 1.0 - dynamics.zeta
    m_dt = dynamics.mass_kg / dt
    dt_m = dt / dynamics.mass_kg
    u_max, v_max = dynamics.u_max_n, dynamics.v_max_mps
    return _track_axes(x, ref, kp, kv, 1.0 if feedforward else 0.0, dt, decay, m_dt, dt_m,
                       u_max, v_max)


def _gain_terms(k: Array, n: int, prev_control: Array | None
                ) -> tuple[float, float, float | None, Array]:
    """(k_p, k_v, k_u, u₋₁) of a gain of :func:`lqr_gain` (k_u None, u₋₁ = 0) or of
    :func:`lqr_du_gain` (u₋₁ = ``prev_control``, None: 0); ValueError for any other."""
    kp, kv, ku = _gain_form(k.tobytes(), k.shape, n)
    if ku is not None:
        u_prev = np.zeros(n) if prev_control is None else np.asarray(prev_control, dtype=float)
        if u_prev.shape != (n,) or not np.all(np.isfinite(u_prev)):
            raise ValueError(f"prev_control must be finite with shape ({n},), got {u_prev}")
        return kp, kv, ku, u_prev
    if prev_control is not None:
        raise ValueError("prev_control needs the Δu gain of lqr_du_gain (shape (dim, 3·dim))")
    return kp, kv, None, np.zeros(n)


@lru_cache(maxsize=64)
def _gain_form(data: bytes, shape: tuple[int, ...], n: int) -> tuple[float, float, float | None]:
    """(k_p, k_v, k_u) of a gain [k_p·I, k_v·I] (k_u None) or [k_p·I, k_v·I, k_u·I] given
    by its bytes and shape (checked once per gain); ValueError for any other."""
    k = np.frombuffer(data, dtype=float).reshape(shape)
    kp, kv = float(k[0, 0]), float(k[0, n])
    eye = np.eye(n)
    if k.shape == (n, 3 * n):
        ku = float(k[0, 2 * n])
        if not np.allclose(k, np.hstack([kp * eye, kv * eye, ku * eye])):
            raise ValueError(f"gain must be [k_p·I, k_v·I, k_u·I] of shape ({n}, {3 * n}), "
                             f"got {k}")
        return kp, kv, ku
    if k.shape != (n, 2 * n) or not np.allclose(k, np.hstack([kp * eye, kv * eye])):
        raise ValueError(f"gain must be [k_p·I, k_v·I] of shape ({n}, {2 * n}), got {k}")
    return kp, kv, None


@njit(cache=True)
def _pmin(a: float, b: float) -> float:
    """Python's ``min(a, b)``: ``a`` unless ``b < a``."""
    return b if b < a else a


@njit(cache=True)
def _pmax(a: float, b: float) -> float:
    """Python's ``max(a, b)``: ``a`` unless ``b > a``."""
    return b if b > a else a


@njit(cache=True)
def _track_axes(x: Array, ref: Array, kp: float, kv: float, ff: float, dt: float, decay: float,
                m_dt: float, dt_m: float, u_max: float, v_max: float) -> tuple[Array, Array]:
    """The loop of :func:`track`, per axis (compiled; the same float operations in order)."""
    n = len(x) // 2
    horizon = ref.shape[0] - 1
    states = np.empty((horizon + 1, 2 * n))
    controls = np.empty((horizon, n))
    for i in range(n):
        p, v = x[i], x[n + i]
        states[0, i], states[0, n + i] = p, v
        for t in range(horizon):
            u = (-kp * (p - ref[t, i]) - kv * (v - ref[t, n + i])
                 + ff * m_dt * (ref[t + 1, n + i] - decay * ref[t, n + i]))
            # clip to U, then keep |v_{k+1}| ≤ v_max: v_{k+1} = (1-ζ) v_k + u ΔT/m
            v_free = decay * v
            lo = _pmax(-u_max, (-v_max - v_free) * m_dt)
            hi = _pmin(u_max, (v_max - v_free) * m_dt)
            u = _pmin(_pmax(_pmin(_pmax(u, lo), hi), -u_max), u_max)  # U wins when |v_k| > v_max
            p, v = p + dt * v, v_free + dt_m * u
            states[t + 1, i], states[t + 1, n + i], controls[t, i] = p, v, u
    return states, controls


def _track_du(
    x: Array, ref: Array, kp: float, kv: float, ku: float, u_prev_all: Array,
    dynamics: DynamicsParams, feedforward: bool,
) -> tuple[Array, Array]:
    """The Δu tracker: u_k = u_ff,k + w_k, w_k = w_{k−1} − k_p e_p − k_v e_v − k_u w_{k−1}.

    e = x_k − x̂_k and w_k = u_k − u_ff,k is the feedback part of the control
    applied (after the clips), so [e; w₋] is the augmented state of
    :func:`lqr_du_gain` in error coordinates (the reference satisfies Eq. (1)
    under u_ff). The control before the horizon is u₋₁ = ``prev_control`` with
    u_ff,−1 := u_ff,0 (the reference is taken as steady before it starts).
    Clips as in :func:`track`.

    First jump. Unclipped, Δu_0 = u_0 − u₋₁ = −k_p e_p,0 − k_v e_v,0 − k_u w₋₁ per
    axis, w₋₁ = u₋₁ − u_ff,0. The clip of axis i is the projection on an
    interval [lo_i, hi_i] (U ∩ the speed limit at v_0), 1-Lipschitz, so

        |u_0,i − u₋₁,i| ≤ |k_p e_p,0,i + k_v e_v,0,i + k_u w₋₁,i| + dist(u₋₁,i, [lo_i, hi_i]),

    the last term 0 when u₋₁ is feasible at x_0 (|u| ≤ u_max and |v_1| ≤ v_max).
    System 1's references start at the UAV's position (e_p,0 = 0), so then
    ‖u_0 − u₋₁‖ ≤ k_v‖e_v,0‖ + k_u‖u₋₁ − u_ff,0‖; the plain tracker's
    u_0 = clip(u_ff,0 − k_v e_v,0) ignores u₋₁, so its jump can reach 2√2·u_max.
    """
    n = dynamics.dim
    horizon = len(ref) - 1
    dt, decay = dynamics.dt_s, 1.0 - dynamics.zeta
    m_dt = dynamics.mass_kg / dt
    dt_m = dt / dynamics.mass_kg
    u_max, v_max = dynamics.u_max_n, dynamics.v_max_mps
    ff = 1.0 if feedforward else 0.0
    states = np.empty((horizon + 1, 2 * n))
    controls = np.empty((horizon, n))
    for i in range(n):
        rp, rv = ref[:, i].tolist(), ref[:, n + i].tolist()
        p, v = float(x[i]), float(x[n + i])
        w = float(u_prev_all[i]) - ff * m_dt * (rv[1] - decay * rv[0])  # w₋₁
        ps, vs, us = [p], [v], []
        for t in range(horizon):
            u_ff = ff * m_dt * (rv[t + 1] - decay * rv[t])
            u = u_ff + (1.0 - ku) * w - kp * (p - rp[t]) - kv * (v - rv[t])
            v_free = decay * v
            lo = max(-u_max, (-v_max - v_free) * m_dt)
            hi = min(u_max, (v_max - v_free) * m_dt)
            u = min(max(min(max(u, lo), hi), -u_max), u_max)  # U wins when |v_k| > v_max
            w = u - u_ff
            p, v = p + dt * v, v_free + dt_m * u
            ps.append(p)
            vs.append(v)
            us.append(u)
        states[:, i], states[:, n + i], controls[:, i] = ps, vs, us
    return states, controls


@njit(cache=True)
def _dot(a: Array, b: Array) -> float:
    acc = 0.0
    for i in range(len(a)):
        acc += a[i] * b[i]
    return acc


@njit(cache=True)
def _clip(x: float, lo: float, hi: float) -> float:
    return min(max(x, lo), hi)


@njit(cache=True)
def _norm_step(u: Array, v_free: Array, u_max: float, v_max: float, dt_m: float) -> None:
    """u (in place) clipped to U, then scaled so ‖v_free + u ΔT/m‖ ≤ v_max (``norm``).

    With ‖v_free‖ ≤ v_max the scale is the largest α ∈ [0, 1] that keeps the
    next velocity on the disc (α·u stays in U); otherwise the control that
    brings the velocity closest to the disc's edge, clipped to U.
    """
    n = len(u)
    for i in range(n):
        u[i] = _clip(u[i], -u_max, u_max)
    v_next = v_free + dt_m * u
    if _dot(v_next, v_next) <= v_max * v_max:
        return
    c = _dot(v_free, v_free) - v_max * v_max
    if c > 0.0:  # already above the limit after the drag: brake towards the disc
        scale = v_max / math.sqrt(_dot(v_free, v_free))
        for i in range(n):
            u[i] = _clip((v_free[i] * scale - v_free[i]) / dt_m, -u_max, u_max)
        return
    a = dt_m * dt_m * _dot(u, u)
    b = 2.0 * dt_m * _dot(v_free, u)
    alpha = _clip((-b + math.sqrt(max(b * b - 4.0 * a * c, 0.0))) / (2.0 * a), 0.0, 1.0)
    for i in range(n):
        u[i] = alpha * u[i]


def _track_norm(
    x: Array, ref: Array, kp: float, kv: float, ku: float | None, u_prev: Array,
    dynamics: DynamicsParams, feedforward: bool,
) -> tuple[Array, Array]:
    """:func:`track` and :func:`_track_du` (``ku`` given) under ‖v‖ ≤ v_max: the axes
    couple, so the loop runs over time with vectors; each control goes through
    :func:`_norm_step`."""
    n = dynamics.dim
    dt, decay = dynamics.dt_s, 1.0 - dynamics.zeta
    ff = 1.0 if feedforward else 0.0
    if ku is None:  # the plain tracker: no memory of the previous feedback
        ku, w = 1.0, np.zeros(n)
    else:  # w₋₁ = u₋₁ − u_ff,0
        w = u_prev - ff * (dynamics.mass_kg / dt) * (ref[1, n:] - decay * ref[0, n:])
    return _norm_loop(x, ref, kp, kv, ku, ff, w, dt, decay, dynamics.u_max_n,
                      dynamics.v_max_mps, dynamics.mass_kg)


@njit(cache=True)
def _norm_loop(x: Array, ref: Array, kp: float, kv: float, ku: float, ff: float, w: Array,
               dt: float, decay: float, u_max: float, v_max: float,
               mass: float) -> tuple[Array, Array]:
    """The loop of :func:`_track_norm` (compiled)."""
    n = len(x) // 2
    horizon = ref.shape[0] - 1
    m_dt, dt_m = mass / dt, dt / mass
    p, v = x[:n].copy(), x[n:].copy()
    states = np.empty((horizon + 1, 2 * n))
    controls = np.empty((horizon, n))
    states[0] = x
    u = np.empty(n)
    for t in range(horizon):
        u_ff = ff * m_dt * (ref[t + 1, n:] - decay * ref[t, n:])
        for i in range(n):
            u[i] = (u_ff[i] + (1.0 - ku) * w[i] - kp * (p[i] - ref[t, i])
                    - kv * (v[i] - ref[t, n + i]))
        v_free = decay * v
        _norm_step(u, v_free, u_max, v_max, dt_m)
        w = u - u_ff
        p, v = p + dt * v, v_free + dt_m * u
        states[t + 1, :n], states[t + 1, n:] = p, v
        controls[t] = u
    return states, controls
