"""The vertical axis of the environment 𝓔 ⊂ ℝ³ (Sec. II-A): the altitude band, start and goal.

The paper's UAV moves in 3-D under Eq. (1) with 3×3 blocks; its evaluation flies the
plane "assuming a fixed altitude" (Sec. IV-A). Flying in 3-D needs what the paper
leaves open, each a named value here:

* the **altitude band** [floor, ceiling] (m above flat ground) that bounds 𝓔:
  the ceiling is the regulatory one, the floor keeps the ground at d_safe;
* the **start and goal altitudes**: G_o ∈ ℝ³ (Eq. S2) needs a height;
* the **goal box**: the paper's G is "a rectangular region centered at G_o"
  with size 100 m × 100 m; in 3-D it is that rectangle over an altitude range.

A 3-D state is [p_x, p_y, p_z, v_x, v_y, v_z] (Eq. (1)'s order: positions, then
velocities); :func:`lift_state` and :func:`planar_state` convert a 2-D state of the
evaluation at a fixed altitude to and from it. Lengths m, speeds m/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np
from numpy.typing import ArrayLike

from dualpilot.arrays import Array
from dualpilot.model.geometry import Rect

#: The ceiling (m above ground): the limit of the EU's open category, "120 m from the
#: closest point of the surface of the earth" (Commission Implementing Regulation (EU)
#: 2019/947, UAS.OPEN.010), and about the US small-UAS limit of 400 ft (121.92 m) above
#: ground level (14 CFR 107.51(b)); the lower of the two.
CEILING_M = 120.0
#: The floor (m above ground): the paper's safety threshold ("a predefined safety
#: threshold (denoted as d_safe = 20 m)", Sec. IV) kept from the ground as from a fire.
#: The scenarios' terrain is flat and without canopy (dualpilot/model/scenarios.py);
#: over a forest the floor would have to clear the canopy as well.
FLOOR_M = 20.0
#: The altitude (m above ground) every 2-D mission of the stack flies at: the supervisor's
#: ``--altitude-m`` (UAV_ALTITUDE_M) and the simulated vehicle's SIM_ALT_M default.
START_ALTITUDE_M = 50.0

#: Readings of the goal box's vertical extent: "band" (every altitude of the band above
#: the rectangle, G being "a rectangular region" of the ground) or "cube" (the altitudes
#: within half the rectangle's shorter side of G_o's, cut to the band).
GoalVertical = Literal["band", "cube"]


@dataclass(frozen=True)
class AltitudeBand:
    """The band [floor_m, ceiling_m] (m above flat ground) the UAV keeps, and its start and
    goal altitudes (``goal_altitude_m`` None: the start's, as at a fixed altitude)."""

    floor_m: float = FLOOR_M
    ceiling_m: float = CEILING_M
    start_altitude_m: float = START_ALTITUDE_M
    goal_altitude_m: float | None = None

    def __post_init__(self) -> None:
        vals = [self.floor_m, self.ceiling_m, self.start_altitude_m]
        if self.goal_altitude_m is not None:
            vals.append(self.goal_altitude_m)
        if not all(math.isfinite(v) for v in vals):
            raise ValueError(f"altitudes must be finite: {self}")
        if not 0.0 <= self.floor_m < self.ceiling_m:
            raise ValueError(f"need 0 <= floor_m < ceiling_m, got {self.floor_m}, "
                             f"{self.ceiling_m}")
        for name in ("start_altitude_m", "goal_altitude_m"):
            z = getattr(self, name)
            if z is not None and not self.contains(z):
                raise ValueError(f"{name} {z} lies outside the band "
                                 f"[{self.floor_m}, {self.ceiling_m}]")

    @property
    def goal_z_m(self) -> float:
        """G_o's altitude (m): ``goal_altitude_m``, else the start's."""
        return self.start_altitude_m if self.goal_altitude_m is None else self.goal_altitude_m

    @property
    def thickness_m(self) -> float:
        return self.ceiling_m - self.floor_m

    def contains(self, z: float, tol: float = 0.0) -> bool:
        """Whether altitude ``z`` (m) lies in the band, grown by ``tol`` (m)."""
        return self.floor_m - tol <= z <= self.ceiling_m + tol

    def above_ceiling_m(self, margin_m: float) -> float:
        """A top (m) no position of the band comes within ``margin_m`` below: ceiling + margin.

        A fire's cuboid this tall blocks every altitude of the band over its footprint,
        and the face above it cannot satisfy Eq. (P2_3) with ε ≤ ``margin_m`` anywhere in
        the band: the top-down evaluation's fire.
        """
        if not margin_m > 0.0:
            raise ValueError(f"margin_m must be positive, got {margin_m}")
        return self.ceiling_m + margin_m


@dataclass(frozen=True)
class GoalBox:
    """The goal G in 3-D: a rectangle of the ground over the altitudes [z_lo, z_hi] (m), and
    its centroid G_o (Eq. S2) at ``center_z`` (m)."""

    rect: Rect
    z_lo: float
    z_hi: float
    center_z: float

    def __post_init__(self) -> None:
        if not all(math.isfinite(v) for v in (self.z_lo, self.z_hi, self.center_z)):
            raise ValueError(f"goal altitudes must be finite: {self}")
        if not self.z_lo <= self.center_z <= self.z_hi:
            raise ValueError(f"need z_lo <= center_z <= z_hi, got {self}")

    @staticmethod
    def over(rect: Rect, band: AltitudeBand, vertical: GoalVertical = "band") -> GoalBox:
        """The goal of a mission: ``rect`` over the band's altitudes (``vertical`` "band") or
        within half the rectangle's shorter side of G_o's altitude ("cube"), cut to the band."""
        if vertical not in get_args(GoalVertical):
            raise ValueError(f"vertical must be one of {get_args(GoalVertical)}, "
                             f"not {vertical!r}")
        zc = band.goal_z_m
        if vertical == "band":
            return GoalBox(rect, band.floor_m, band.ceiling_m, zc)
        half = min(rect.width, rect.height) / 2
        return GoalBox(rect, max(band.floor_m, zc - half), min(band.ceiling_m, zc + half), zc)

    @property
    def center(self) -> Array:
        """G_o ∈ ℝ³ (m)."""
        return np.array([self.rect.center_x, self.rect.center_y, self.center_z])

    @property
    def lo(self) -> Array:
        return np.array([*self.rect.bounds[:2], self.z_lo])

    @property
    def hi(self) -> Array:
        return np.array([*self.rect.bounds[2:], self.z_hi])

    def contains(self, p: ArrayLike) -> bool:
        """Whether the 3-D point ``p`` lies in G (closed box)."""
        q = np.asarray(p, dtype=float)
        return self.rect.contains(q[:2]) and self.z_lo <= float(q[2]) <= self.z_hi

    def distance(self, p: ArrayLike) -> float:
        """Euclidean distance (m) from the 3-D point ``p`` to G (0 inside)."""
        q = np.asarray(p, dtype=float)
        dz = max(0.0, self.z_lo - float(q[2]), float(q[2]) - self.z_hi)
        dxy = self.rect.distance(q[:2])
        return dxy if dz == 0.0 else math.hypot(dxy, dz)


def lift_state(x: ArrayLike, z_m: float) -> Array:
    """A 2-D state [p_x, p_y, v_x, v_y] as the 3-D state at altitude ``z_m``, climbing at 0."""
    x2 = np.asarray(x, dtype=float)
    if x2.shape != (4,):
        raise ValueError(f"a planar state has shape (4,), got {x2.shape}")
    return np.array([x2[0], x2[1], z_m, x2[2], x2[3], 0.0])


def planar_state(x: ArrayLike) -> Array:
    """The 2-D state [p_x, p_y, v_x, v_y] of a 3-D state (its altitude and climb dropped)."""
    x3 = np.asarray(x, dtype=float)
    if x3.shape != (6,):
        raise ValueError(f"a 3-D state has shape (6,), got {x3.shape}")
    return np.array([x3[0], x3[1], x3[3], x3[4]])


def lift_controls(u: ArrayLike) -> Array:
    """Planar forces (T, 2) as 3-D forces (T, 3) with no vertical force (N)."""
    u2 = np.asarray(u, dtype=float).reshape(-1, 2)
    return np.column_stack([u2, np.zeros(len(u2))])
