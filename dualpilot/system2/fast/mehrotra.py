"""The compiled Mehrotra iterations of :class:`dualpilot.system2.fast.ipm.BandedQp`.

One call runs the whole predictor-corrector loop in machine code (Numba,
cached on disk). The banded Cholesky factorisation and solves are LAPACK's
``dpbtrf`` / ``dpbtrs`` (scipy's, by address), H z and the dot products are
BLAS, and every sparse product adds its terms in the order of scipy's
``csr_matvec`` / ``csc_matvec``: the iterates are those of the same loop
written with numpy and scipy, bit for bit. It runs without the GIL: a planner
service's other threads (the Zenoh callbacks that take the next request, the
other vehicles' planners) are not held up while it iterates.
"""

from __future__ import annotations

from typing import Any

import llvmlite.binding as llvm
import numpy as np
from numba import njit, types
from numba.extending import get_cython_function_address

from dualpilot.arrays import AnyArray

for _name in ("dpbtrf", "dpbtrs"):  # resolved by name, so the compiled loop can be cached
    llvm.add_symbol(f"dualpilot_{_name}",
                    get_cython_function_address("scipy.linalg.cython_lapack", _name))
_P = types.voidptr
_dpbtrf: Any = types.ExternalFunction("dualpilot_dpbtrf", types.void(_P, _P, _P, _P, _P, _P))
_dpbtrs: Any = types.ExternalFunction("dualpilot_dpbtrs",
                                 types.void(_P, _P, _P, _P, _P, _P, _P, _P, _P))

#: status codes of :func:`mehrotra`
SOLVED, MAX_ITER, DIVERGED, STALLED, FACTORIZATION = 0, 1, 2, 3, 4


@njit(cache=True)
def _gmul(ptr: AnyArray, idx: AnyArray, dat: AnyArray, x: AnyArray, out: AnyArray) -> None:
    """out = G x (G in CSR arrays; scipy's csr_matvec order)."""
    k = ptr[1] - ptr[0] if len(ptr) > 1 else 0
    if k == 3 and ptr[-1] == 3 * len(out):  # padded rows of width 3: unrolled
        for i in range(len(out)):
            b = 3 * i
            acc = 0.0
            acc += dat[b] * x[idx[b]]
            acc += dat[b + 1] * x[idx[b + 1]]
            acc += dat[b + 2] * x[idx[b + 2]]
            out[i] = acc
        return
    for i in range(len(out)):
        acc = 0.0
        for jj in range(ptr[i], ptr[i + 1]):
            acc += dat[jj] * x[idx[jj]]
        out[i] = acc


@njit(cache=True)
def csr_matvec(ptr: AnyArray, idx: AnyArray, dat: AnyArray, x: AnyArray) -> AnyArray:
    """A x for A in CSR arrays, term for term as scipy's ``csr_matvec`` (``A @ x``)."""
    out = np.empty(len(ptr) - 1)
    for i in range(len(out)):
        acc = 0.0
        for jj in range(ptr[i], ptr[i + 1]):
            acc += dat[jj] * x[idx[jj]]
        out[i] = acc
    return out


@njit(cache=True)
def _transpose(ptr: AnyArray, idx: AnyArray, dat: AnyArray,
               n_out: int) -> tuple[AnyArray, AnyArray, AnyArray]:
    """CSR arrays (ptr, source row, value) of Aᵀ for A in CSR arrays, each output's
    entries in the order a scatter over A's rows would add them."""
    tptr = np.zeros(n_out + 1, np.int64)
    for e in range(len(idx)):
        tptr[idx[e] + 1] += 1
    for c in range(n_out):
        tptr[c + 1] += tptr[c]
    fill = tptr[:-1].copy()
    trow, tdat = np.empty(len(idx), np.int64), np.empty(len(idx))
    for r in range(len(ptr) - 1):
        for e in range(ptr[r], ptr[r + 1]):
            c = idx[e]
            trow[fill[c]], tdat[fill[c]] = r, dat[e]
            fill[c] += 1
    return tptr, trow, tdat


@njit(cache=True)
def _tmul(tptr: AnyArray, trow: AnyArray, tdat: AnyArray, v: AnyArray, out: AnyArray) -> None:
    """out = Aᵀ v from :func:`_transpose`'s arrays: the sums of scipy's csc_matvec of A's
    CSR arrays, term for term in the same order, gathered instead of scattered."""
    for c in range(len(out)):
        acc = 0.0
        for e in range(tptr[c], tptr[c + 1]):
            acc += tdat[e] * v[trow[e]]
        out[c] = acc


@njit(cache=True)
def _ctmul(ptr: AnyArray, idx: AnyArray, dat: AnyArray, v: AnyArray, out: AnyArray) -> None:
    """out = A v for A in CSC arrays (scipy's csc_matvec order); Gᵀv from G's CSR arrays."""
    out[:] = 0.0
    for j in range(len(ptr) - 1):
        vj = v[j]
        for ii in range(ptr[j], ptr[j + 1]):
            out[idx[ii]] += dat[ii] * vj


@njit(cache=True)
def _min_ratio(num: AnyArray, den: AnyArray) -> float:
    """min(0, min_i num_i / den_i), NaN if any ratio is NaN (numpy's ``min(initial=0)``)."""
    out = 0.0
    for i in range(len(num)):
        r = num[i] / den[i]
        if np.isnan(r):
            return r
        if r < out:
            out = r
    return out


@njit(cache=True)
def _step(s: AnyArray, lam: AnyArray, ds: AnyArray, dl: AnyArray) -> float:
    """Largest step in (0, 1] keeping s + αΔs ≥ 0 and λ + αΔλ ≥ 0 (s, λ > 0)."""
    worst = -_min_ratio(ds, s)
    b = -_min_ratio(dl, lam)
    if b > worst:
        worst = b
    if worst < 1.0:
        worst = 1.0
    return 1.0 / worst


@njit(cache=True)
def _abs_max(x: AnyArray, initial: float) -> float:
    """max |x_i| (and ``initial``), NaN if any x_i is NaN."""
    out = initial
    for i in range(len(x)):
        a = abs(x[i])
        if np.isnan(a):
            return a
        if a > out:
            out = a
    return out


@njit(cache=True)
def _direction(rcs: AnyArray, w: AnyArray, r_p: AnyArray, r_d: AnyArray, t_ptr: AnyArray,
               t_row: AnyArray, t_dat: AnyArray, g_ptr: AnyArray, g_idx: AnyArray,
               g_dat: AnyArray, uplo: AnyArray, ints: AnyArray, factor: AnyArray,
               tmp_m: AnyArray, gtl: AnyArray, dz: AnyArray, gd: AnyArray, ds: AnyArray,
               dl: AnyArray) -> None:
    """One Newton direction for ``rcs`` = S⁻¹r_c, the band's Cholesky factor given:
    (H + GᵀWG)Δz = −r_d + Gᵀ(S⁻¹r_c − W r_p); Δs = −r_p − GΔz; Δλ = −S⁻¹r_c − WΔs.

    ``ints`` holds LAPACK's n, kd, nrhs, ldab, ldb, info.
    """
    for i in range(len(rcs)):
        tmp_m[i] = rcs[i] - w[i] * r_p[i]
    _tmul(t_ptr, t_row, t_dat, tmp_m, gtl)
    for i in range(len(dz)):
        dz[i] = -r_d[i] + gtl[i]
    _dpbtrs(uplo.ctypes, ints[0:].ctypes, ints[1:].ctypes, ints[2:].ctypes, factor.ctypes,
            ints[3:].ctypes, dz.ctypes, ints[4:].ctypes, ints[5:].ctypes)
    _gmul(g_ptr, g_idx, g_dat, dz, gd)
    for i in range(len(rcs)):
        ds[i] = -r_p[i] - gd[i]
        dl[i] = -rcs[i] - w[i] * ds[i]


@njit(cache=True)
def _lapack_band(h_band: AnyArray, b_idx: AnyArray) -> tuple[AnyArray, AnyArray]:
    """H's band and the band map's indices in LAPACK's column-major band storage:
    entry (d, j) of the (bw+1, n) lower band form at j·(bw+1) + d."""
    bw1, n = h_band.shape
    hf = np.empty(bw1 * n)
    for d in range(bw1):
        for j in range(n):
            hf[j * bw1 + d] = h_band[d, j]
    bf_idx = np.empty_like(b_idx)
    for k in range(len(b_idx)):
        d, j = divmod(b_idx[k], n)
        bf_idx[k] = j * bw1 + d
    return hf, bf_idx


@njit(cache=True)
def _residuals(h_dense: AnyArray, q: AnyArray, h: AnyArray, z: AnyArray, s: AnyArray,
               lam: AnyArray, t_ptr: AnyArray, t_row: AnyArray, t_dat: AnyArray,
               g_ptr: AnyArray, g_idx: AnyArray, g_dat: AnyArray, gtl: AnyArray, gz: AnyArray,
               r_d: AnyArray, r_p: AnyArray, m1: int) -> tuple[float, float, float]:
    """Dual residual r_d = Hz + q + Gᵀλ and primal r_p = Gz + s − h (in place);
    returns (μ = sᵀλ / max(m, 1), max |r_p| (0 without rows), max |r_d|)."""
    hz = h_dense @ z
    _tmul(t_ptr, t_row, t_dat, lam, gtl)
    for i in range(len(r_d)):
        r_d[i] = hz[i] + q[i] + gtl[i]
    _gmul(g_ptr, g_idx, g_dat, z, gz)
    for i in range(len(r_p)):
        r_p[i] = gz[i] + s[i] - h[i]
    mu = np.dot(s, lam) / m1
    res_p = _abs_max(r_p, -np.inf) if len(r_p) else 0.0
    res_d = _abs_max(r_d, -np.inf)
    return mu, res_p, res_d


@njit(cache=True)
def _stop(it: int, mu: float, res_p: float, res_d: float, tol: float, b_norm: float,
          q_norm: float, history: AnyArray, detect_infeasible: bool) -> int:
    """The status that ends iteration ``it`` (SOLVED, DIVERGED or STALLED), else −1.

    Records ``res_p`` in ``history``; STALLED: after 12 iterations with
    ``detect_infeasible``, a primal residual that has not halved in 5.
    """
    if res_p <= tol * b_norm and res_d <= tol * q_norm and mu <= tol:
        return SOLVED
    if not (np.isfinite(mu) and np.isfinite(res_d)) or mu > 1e14:
        return DIVERGED
    history[it] = res_p
    if (detect_infeasible and it >= 12 and res_p > 1e-4 * b_norm
            and res_p > 0.5 * history[it - 5]):
        return STALLED
    return -1


@njit(cache=True)
def _factor(s: AnyArray, lam: AnyArray, w: AnyArray, b_ptr: AnyArray, bf_idx: AnyArray,
            b_dat: AnyArray, hf: AnyArray, band: AnyArray, uplo: AnyArray,
            ints: AnyArray) -> int:
    """W = diag(λ/s) into ``w`` and the Cholesky factor of H + GᵀWG into ``band``
    (LAPACK's ``dpbtrf``); returns LAPACK's info (0: factorised)."""
    for i in range(len(w)):
        w[i] = lam[i] / s[i]
    _ctmul(b_ptr, bf_idx, b_dat, w, band)
    for k in range(len(band)):
        band[k] = hf[k] + band[k]
    _dpbtrf(uplo.ctypes, ints[0:].ctypes, ints[1:].ctypes, band.ctypes, ints[3:].ctypes,
            ints[5:].ctypes)
    return int(ints[5])


@njit(cache=True)
def _centering(s: AnyArray, lam: AnyArray, ds_a: AnyArray, dl_a: AnyArray, s_a: AnyArray,
               l_a: AnyArray, mu: float, m1: int) -> float:
    """Mehrotra's σ = (μ_aff / μ)³, μ_aff the gap after the largest affine step
    (``s_a``, ``l_a`` receive s + αΔs_a, λ + αΔλ_a); 0 when μ ≤ 0."""
    a_aff = _step(s, lam, ds_a, dl_a)
    for i in range(len(s)):
        s_a[i] = s[i] + a_aff * ds_a[i]
        l_a[i] = lam[i] + a_aff * dl_a[i]
    mu_aff = np.dot(s_a, l_a) / m1
    return (mu_aff / mu) ** 3.0 if mu > 0 else 0.0


@njit(cache=True)
def _advance(z: AnyArray, s: AnyArray, lam: AnyArray, dz: AnyArray, ds: AnyArray,
             dl: AnyArray) -> None:
    """(z, s, λ) += α (Δz, Δs, Δλ) in place, α = min(1, 0.99 × the largest feasible step)."""
    step = 0.99 * _step(s, lam, ds, dl)
    a = step if step < 1.0 else 1.0
    for i in range(len(dz)):
        z[i] = z[i] + a * dz[i]
    for i in range(len(s)):
        s[i] = s[i] + a * ds[i]
        lam[i] = lam[i] + a * dl[i]


@njit(cache=True, nogil=True)  # another thread of the process runs while it iterates
def mehrotra(h_dense: AnyArray, h_band: AnyArray, q: AnyArray, h: AnyArray, g_ptr: AnyArray,
             g_idx: AnyArray, g_dat: AnyArray, b_ptr: AnyArray, b_idx: AnyArray,
             b_dat: AnyArray, z0: AnyArray, slack0: float, max_iter: int, tol: float,
             detect_infeasible: bool) -> tuple[int, AnyArray, int, int]:
    """Mehrotra predictor-corrector for min ½zᵀHz + qᵀz s.t. G z ≤ h.

    ``h_band`` is H in lower band form (bw+1, n); ``b_*`` the CSC map w ↦
    band(GᵀWG) with band entries indexed d·n + j. Returns (status, z,
    iterations, LAPACK info).
    """
    bw1, n = h_band.shape
    m = len(h)
    m1 = max(m, 1)
    hf, bf_idx = _lapack_band(h_band, b_idx)
    uplo = np.array([76], dtype=np.uint8)  # 'L'
    ints = np.array([n, bw1 - 1, 1, bw1, n, 0], dtype=np.int32)  # n kd nrhs ldab ldb info
    t_ptr, t_row, t_dat = _transpose(g_ptr, g_idx, g_dat, n)  # Gᵀ, gathered
    z = z0.copy()
    gz = np.empty(m)
    _gmul(g_ptr, g_idx, g_dat, z, gz)
    s = np.empty(m)
    for i in range(m):
        s[i] = max(h[i] - gz[i], slack0)
    lam = np.ones(m)
    q_norm = 1.0 + _abs_max(q, 0.0)
    b_norm = 1.0 + _abs_max(h, 0.0)
    history = np.zeros(max_iter + 1)
    gtl, r_d, r_p, w = np.empty(n), np.empty(n), np.empty(m), np.empty(m)
    band, rhs, tmp_m, rcs = np.empty(bw1 * n), np.empty(n), np.empty(m), np.empty(m)
    ds_a, dl_a, ds, dl = np.empty(m), np.empty(m), np.empty(m), np.empty(m)
    s_a, l_a, gd = np.empty(m), np.empty(m), np.empty(m)
    status = MAX_ITER
    it = 0
    for it in range(1, max_iter + 1):
        mu, res_p, res_d = _residuals(h_dense, q, h, z, s, lam, t_ptr, t_row, t_dat, g_ptr,
                                      g_idx, g_dat, gtl, gz, r_d, r_p, m1)
        stop = _stop(it, mu, res_p, res_d, tol, b_norm, q_norm, history, detect_infeasible)
        if stop >= 0:
            status = stop
            break
        if _factor(s, lam, w, b_ptr, bf_idx, b_dat, hf, band, uplo, ints) != 0:
            status = FACTORIZATION
            break
        for i in range(m):
            rcs[i] = (s[i] * lam[i]) / s[i]
        _direction(rcs, w, r_p, r_d, t_ptr, t_row, t_dat, g_ptr, g_idx, g_dat, uplo, ints,
                   band, tmp_m, gtl, rhs, gd, ds_a, dl_a)  # the predictor
        sigma = _centering(s, lam, ds_a, dl_a, s_a, l_a, mu, m1)
        for i in range(m):
            rcs[i] = (s[i] * lam[i] + ds_a[i] * dl_a[i] - sigma * mu) / s[i]
        _direction(rcs, w, r_p, r_d, t_ptr, t_row, t_dat, g_ptr, g_idx, g_dat, uplo, ints,
                   band, tmp_m, gtl, rhs, gd, ds, dl)  # the corrector
        _advance(z, s, lam, rhs, ds, dl)
    return status, z, it, int(ints[5])
