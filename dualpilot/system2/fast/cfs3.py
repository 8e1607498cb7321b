"""The fast method's CFS loop in 3-D: each prism passed around or over, re-chosen at each QP.

A prism P_i (a fire's cuboid or swept hull: its footprint over [z_lo, z_hi]) is kept out
at a planned position p_τ by one of two kinds of row (:mod:`dualpilot.system2.fast.split`):
*around*, a supporting half-plane of its ε-inflated footprint Q_i (today's, which excludes
the whole prism), or *over*, z_τ ≥ z_hi + ε (possible only when that level lies in the
band). Either row keeps Eq. (P2_3)-(P2_4) at p_τ: the top's face with ε, or one of the
base's faces with ε. Before an iterate is feasible the reference (a homotopy) fixes the
kind: over where the reference's (x, y) lies in Q_i and the prism can be passed over,
else around. At a feasible iterate each row is re-chosen so that it holds the iterate
(a half-plane of Q_i that contains it and leans towards the relaxation, or the level the
iterate is already above), so the Eq. (S2) cost never rises, as in 2-D: where the
iterate is outside Q_i and above the level both kinds hold it, and the kind the
relaxation's point violates less is taken. Lengths m.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dualpilot.arrays import AnyArray, Array
from dualpilot.model.altitude import AltitudeBand
from dualpilot.model.prism import Prism
from dualpilot.system2.fast.cfs import Cfs, KeepOuts
from dualpilot.system2.fast.geometry import FaceStack, HullStack, Inflated
from dualpilot.system2.fast.split import OVER


@dataclass(frozen=True)
class KeepOuts3(KeepOuts):
    """:class:`KeepOuts` of prisms: ``polys`` are the ε-inflated footprints; ``top`` and
    ``bottom`` (per keep-out, m) are z_hi + ε and z_lo − ε (Eq. (P2_3)'s top and bottom
    faces with ε); ``level`` is the altitude an over-row keeps (z_hi + ε; +inf where that
    is above the band's ceiling less ``margin``: the prism is passed around only);
    ``band`` the altitudes p_2..p_T keep."""

    top: AnyArray
    bottom: AnyArray
    level: AnyArray
    band: AltitudeBand

    @staticmethod
    def of_prisms(prisms: list[Prism], eps: float, horizon: int, area: float | None,
                  band: AltitudeBand, margin: float) -> KeepOuts3:
        """The keep-outs of ``prisms`` (ε = ``eps``); an over-row needs its level +
        ``margin`` (m: the rows' and the band's margins) within the band."""
        polys = Inflated.make_many([p.base for p in prisms], eps)
        top = np.array([p.z_hi + eps for p in prisms])
        bottom = np.array([p.z_lo - eps for p in prisms])
        level = np.where(top + margin <= band.ceiling_m, top, np.inf)
        return KeepOuts3(polys, FaceStack.of(polys), HullStack.of(polys), None, horizon, area,
                         top, bottom, level, band)

    def margins3(self, pos: Array) -> AnyArray:
        """(points, keep-outs): max over every face of α·p − β − ε (m); ≥ 0: Eq. (P2_3)-(P2_4)
        hold."""
        pts = np.asarray(pos, dtype=float).reshape(-1, 3)
        xy = self.faces.margins(pts[:, :2])
        z = pts[:, 2:3]
        return np.maximum(xy, np.maximum(z - self.top[None, :], self.bottom[None, :] - z))

    def below(self, pos: Array, threshold: float) -> AnyArray:
        out = threshold > self.margins3(pos).T
        steps = self.steps()
        return out if steps is None else out & steps

    def violations(self, pos: Array) -> AnyArray:
        T = self.horizon
        hull, tt = np.nonzero(self.below(pos[1:T], 0.0))
        return np.column_stack([tt + 2, hull]).astype(np.int64).reshape(-1, 2)

    def in_area(self, pos: Array) -> bool:
        """Whether p_2..p_T lie in the area and the band (1 µm of slack)."""
        p = pos[1:self.horizon]
        z = p[:, 2]
        if not (np.all(z >= self.band.floor_m - 1e-6) and np.all(z <= self.band.ceiling_m + 1e-6)):
            return False
        if self.area is None:
            return True
        return bool(np.all(p[:, :2] >= -1e-6) and np.all(p[:, :2] <= self.area + 1e-6))

    def clip(self, pos: Array) -> Array:
        out = np.array(pos, dtype=float)
        if self.area is not None:
            out[:, :2] = np.clip(out[:, :2], 0.0, self.area)
        out[:, 2] = np.clip(out[:, 2], self.band.floor_m, self.band.ceiling_m)
        return out


class Cfs3(Cfs):
    """:class:`Cfs` with around- and over-rows (module docstring); positions (T+1, 3)."""

    keepouts: KeepOuts3

    def _around(self, nrm: Array) -> AnyArray:
        return np.asarray(nrm[:, 2] == 0.0)

    def _rows(self) -> tuple[Array, Array, Array]:
        """Rows (τ, normal (m, 3), rhs) of the active (τ, i) pairs, hull-major."""
        f, T, ko = self.plan.fast, self.T, self.keepouts
        hid, col = np.nonzero(self.active[:, 2:T + 1])
        self.last_hull_ids = hid.astype(np.int64)
        if not len(hid):
            return np.zeros(0, dtype=np.int64), np.zeros((0, 3)), np.zeros(0)
        tt = self.taus[col]
        hs = ko.stack
        point = self.cur[tt - 1] if (self.feasible_seen or self.elastic or self.n_elastic) \
            else self.ref[tt - 1]
        level = ko.level[hid]
        xy_margin = hs.margin(hid, point[:, :2])
        if self.feasible_seen:
            want = self.plan.desired[tt - 1]
            z_ok = point[:, 2] >= level
            lean_over = want[:, 2] - level > hs.margin(hid, want[:, :2])
            over = z_ok & ((xy_margin <= 0.0) | lean_over)
            sub = ~over
            nrm2, off, _ = hs.support_toward(hid[sub], point[sub, :2], want[sub, :2],
                                             slack=f.eps_margin_m)
        else:
            over = (xy_margin <= 0.0) & np.isfinite(level)
            sub = ~over
            nrm2, off, _ = hs.support(hid[sub], point[sub, :2])
        nrm = np.zeros((len(hid), 3))
        rhs = np.empty(len(hid))
        nrm[sub, :2] = nrm2
        rhs[sub] = off + f.eps_margin_m
        nrm[over] = OVER
        rhs[over] = level[over] + f.eps_margin_m
        if self.feasible_seen:  # keep the iterate: it lies at or above the level
            rhs[over] = np.minimum(rhs[over], np.maximum(point[over, 2], level[over]))
        return np.asarray(tt, dtype=np.int64), nrm, rhs
