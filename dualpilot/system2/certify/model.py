"""Problem (P2) written in the planned positions alone: Eq. (1) as exact linear maps.

The variables are z = (p_{t+2|t}, …, p_{t+T+1|t}) / s (``scale`` s metres); p_{t+1|t} =
p_t + ΔT v_t is fixed by the state and p_{t+T+1|t} defines v_{t+T|t}. Eq. (1) gives

* v_τ = (p_{τ+1} − p_τ) / ΔT, τ = 1..T,
* u_τ = m / ΔT · (v_τ − (1 − ζ) v_{τ−1}), v_0 = v_t,
* Δu_τ = u_τ − u_{τ−1}, u_0 = u_{t|t},

so every (X, U) of (P2) is one z and back (the map is a bijection), and Eq. (S2) is
κ1 Σ_{τ=1..T} ‖p_τ − G_o‖² + κ2 ‖Δu‖². This module holds the constant maps of one
(T, dynamics, s) and the offsets of one state; it is independent of the fast method's
QP (dualpilot/system2/fast/qp.py), which a unit test checks it against.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from dualpilot.arrays import Array
from dualpilot.model.dynamics import DynamicsParams, speed_polygon
from dualpilot.model.geometry import Polytope


@dataclass(frozen=True)
class Maps:
    """Constant linear maps of z (sparse CSR), one per (T, dynamics, s, K).

    ``V`` (2T × 2T): v_1..v_T; ``U``: u_1..u_T; ``D``: Δu_1..Δu_T, each before the
    state's offsets (:class:`Offsets`). ``speed_v`` holds the rows of X on v (per axis:
    ±I; "norm": the K-gon normals n_k, one row per (τ, k), τ-major), ``speed`` the same
    rows on z and ``speed_max`` their bound (m/s).
    """

    horizon: int
    dynamics: DynamicsParams
    scale: float
    V: sp.csr_matrix
    U: sp.csr_matrix
    D: sp.csr_matrix
    speed_v: sp.csr_matrix
    speed: sp.csr_matrix
    speed_max: float

    @property
    def n(self) -> int:
        """Number of variables, 2T."""
        return 2 * self.horizon


@dataclass(frozen=True)
class Instance:
    """One (P2) instance: x_t (4,), u_{t|t} (2,, N), G_o (2,, m), κ = (κ1, κ2) of Eq. (S2),
    the hulls whose ε-inflation (P2_3)-(P2_4) forbids, ε (m), and the area's side (m;
    None: no area bound)."""

    x0: Array
    u_prev: Array
    goal: Array
    kappa: tuple[float, float]
    hulls: tuple[Polytope, ...]
    epsilon_m: float
    area_size_m: float | None


@dataclass(frozen=True)
class Offsets:
    """The parts of v, u, Δu fixed by the state x_t and u_{t|t}, and p_{t+1|t} (m)."""

    v: Array
    u: Array
    du: Array
    p1: Array


@lru_cache(maxsize=16)
def maps(horizon: int, dynamics: DynamicsParams, scale: float = 100.0,
         speed_sides: int = 16) -> Maps:
    """The :class:`Maps` of (T, dynamics, s, K), built once a process."""
    T, s = int(horizon), float(scale)
    dt, a, mass = dynamics.dt_s, 1.0 - dynamics.zeta, dynamics.mass_kg
    eye2 = sp.identity(2, format="csr")
    # positions p_1..p_{T+1} = M z + e (e carries p_1)
    m_pos = sp.vstack([sp.csr_matrix((2, 2 * T)), s * sp.identity(2 * T, format="csr")])
    diff_v = sp.kron(sp.diags([-np.ones(T), np.ones(T)], [0, 1], shape=(T, T + 1)), eye2) / dt
    shift = sp.kron(sp.diags([np.ones(T - 1)], [-1], shape=(T, T)), eye2)
    v_map = (diff_v @ m_pos).tocsr()
    u_map = ((mass / dt) * (v_map - a * (shift @ v_map))).tocsr()
    d_map = (u_map - shift @ u_map).tocsr()
    if dynamics.speed_limit == "norm":
        normals, cos_k = speed_polygon(speed_sides)
        speed_v = sp.kron(sp.identity(T, format="csr"), sp.csr_matrix(normals))
        speed_max = dynamics.v_max_mps * cos_k
    else:
        speed_v = sp.vstack([sp.identity(2 * T), -sp.identity(2 * T)])
        speed_max = dynamics.v_max_mps
    speed_v = sp.csr_matrix(speed_v)
    return Maps(T, dynamics, s, v_map, u_map, d_map, speed_v, (speed_v @ v_map).tocsr(),
                float(speed_max))


def offsets(mp: Maps, x0: Array, u_prev: Array) -> Offsets:
    """The offsets of v, u and Δu for the state ``x0`` (4,) and u_{t|t} ``u_prev`` (2,)."""
    T, dyn = mp.horizon, mp.dynamics
    dt, a, mass = dyn.dt_s, 1.0 - dyn.zeta, dyn.mass_kg
    x0 = np.asarray(x0, dtype=float)
    p1 = x0[:2] + dt * x0[2:]
    v = np.zeros(2 * T)
    v[:2] = -p1 / dt
    v_prev = np.concatenate([x0[2:], v[:-2]])
    u = (mass / dt) * (v - a * v_prev)
    du = u - np.concatenate([np.asarray(u_prev, dtype=float), u[:-2]])
    return Offsets(v, u, du, p1)


def positions(mp: Maps, z: Array, p1: Array) -> Array:
    """p_{t+1|t}..p_{t+T+1|t} (T+1, 2) in m from the scaled variables."""
    return np.vstack([np.asarray(p1, dtype=float)[None, :],
                      mp.scale * np.asarray(z, dtype=float).reshape(-1, 2)])


def controls(mp: Maps, z: Array, off: Offsets) -> Array:
    """u_{t+1|t}..u_{t+T|t} (T, 2) in N from the scaled variables."""
    return np.asarray(mp.U @ np.asarray(z, dtype=float) + off.u).reshape(-1, 2)


def variables(mp: Maps, pos: Array) -> Array:
    """z of the positions p_{t+2|t}..p_{t+T+1|t} (rows 1..T of ``pos``, m)."""
    return np.asarray(pos, dtype=float)[1:mp.horizon + 1].ravel() / mp.scale
