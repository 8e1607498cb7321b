"""Firefront process, Sec. II-B: Bernoulli birth/survival, Gauss–Markov propagation.

One propagation sub-step lasts ``T_f`` seconds. Per sub-step:

* each active front survives with probability p_s (else it is extinguished);
* a survivor's speed y^ν and direction y^d follow the Gauss–Markov model
  y_t = γ y_{t-1} + (1-γ) ȳ + sqrt(1-γ²) ŷ,  ŷ ~ N(0, σ),
  and its centre moves y^ν·T_f metres along y^d (rad, from the +x axis);
* its extent is a rectangle whose two sides are drawn from U[100, 250] m;
* with probability p_b a new front is born, centre uniform in the area.

Two readings of Sec. II-B/IV are parameters (:class:`FireParams`): the time
base of birth and survival (``life_base``: every sub-step T_f, or once per
time-step ΔT, the other sub-steps only moving the fronts) and when the extent
is drawn (``extent``: every sub-step, once per time-step, or once at birth).
A time-step starts at the first sub-step run with a new mission step number.

Each front remembers the convex hull of every rectangle it has occupied,
△(C^i_{1:t}), the region planners must avoid (constraint P1_4).

In 3-D (docs/three_d.md) each front's region is a cuboid C_t standing on the ground: its
rectangle over [0, ``top_m``], the top drawn with the rectangle from the heights' own
stream (:class:`dualpilot.model.fire_height.FireHeights`), so the fire stream's draws
are the 2-D process's; its △ is the prism of the planar hull up to the highest top so far
(``hull_top_m``), which contains every cuboid the front occupied. In 2-D the tops are
None and nothing is drawn.

The process over the area is :class:`dualpilot.model.fire_field.FireField`;
this module holds its parameters, fronts and snapshots. ``FireParams.scenario``
other than "paper" names a fire-behaviour scenario (dualpilot/model/scenarios.py):
the field then runs Rothermel spread on a level set instead
(dualpilot/model/physics_fire.py), with the same births, keep-out, fronts and
snapshots.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from math import ceil, cos, sin, sqrt
from typing import Literal, get_args

import numpy as np

from dualpilot.model.fire_height import FireHeights
from dualpilot.model.geometry import Polytope, Rect
from dualpilot.model.prism import Cuboid, Prism
from dualpilot.model.scenarios import PAPER, scenario_names

#: Time base of birth and survival: every sub-step T_f, or once per time-step ΔT.
LifeBase = Literal["substep", "step"]
#: When a front's rectangle is drawn: every sub-step, every time-step, once at birth.
Extent = Literal["substep", "step", "birth"]
#: Draws of a birth (or a redraw) that must keep clear of a keep-out before giving up.
MAX_DRAWS = 1000
#: A front's region: its rectangle (2-D), or its cuboid (3-D).
Region = Rect | Cuboid
#: Where no front may ignite: (the UAV's position (2,) or (3,) (m), radius (m)).
KeepOutZone = tuple[np.ndarray, float]


@dataclass(frozen=True)
class FireParams:
    """Sec. IV-A values. Speeds m/s, angles rad, lengths m, T_f s."""

    p_birth: float = 0.1
    p_survive: float = 0.75
    speed_mean_mps: float = 3.0
    direction_mean_rad: float = np.pi / 4
    speed_sigma_mps: float = 0.8
    direction_sigma_rad: float = np.pi / 20
    gamma: float = 0.8
    side_min_m: float = 100.0
    side_max_m: float = 250.0
    substep_s: float = 0.5
    #: Reading of Ĉ_t: False keeps the hulls of active fronts only (an
    #: extinguished front no longer threatens the UAV); True keeps every hull.
    keep_extinct_hulls: bool = False
    #: Reading of "p_s ... propagates to the next time-step": Bernoulli birth and
    #: survival every sub-step T_f ("substep") or once per time-step ΔT ("step").
    life_base: LifeBase = "substep"
    #: Reading of "the extend ... at each time-step ... uniformly sampled": sides
    #: redrawn every sub-step, every time-step, or drawn once at birth.
    extent: Extent = "substep"
    #: Apply a sub-step's keep-out (the ignition clearance) to extent redraws too,
    #: not only to births: a redraw never puts the region within it of the UAV.
    redraw_clearance: bool = False
    #: The fire process: "paper" (these rectangles) or a named fire-behaviour scenario
    #: (dualpilot/model/scenarios.py: Rothermel spread; p_b, life_base, T_f and
    #: keep_extinct_hulls still apply, the front's motion and extent come from the physics).
    scenario: str = PAPER

    def __post_init__(self) -> None:
        if self.scenario not in scenario_names():
            raise ValueError(f"scenario must be one of {scenario_names()}, "
                             f"not {self.scenario!r}")
        if self.life_base not in get_args(LifeBase):
            raise ValueError(f"life_base must be one of {get_args(LifeBase)}, "
                             f"not {self.life_base!r}")
        if self.extent not in get_args(Extent):
            raise ValueError(f"extent must be one of {get_args(Extent)}, not {self.extent!r}")
        for name in ("p_birth", "p_survive", "gamma"):
            val = getattr(self, name)
            if not 0.0 <= val <= 1.0:
                raise ValueError(f"{name} must be in [0, 1], got {val}")
        if not 0 < self.side_min_m <= self.side_max_m:
            raise ValueError("need 0 < side_min_m <= side_max_m")
        if self.substep_s <= 0:
            raise ValueError("substep_s must be positive")


def substeps_for(planning_time_s: float, params: FireParams = FireParams()) -> int:
    """⌈T_s / T_f⌉: fire sub-steps that elapse while a plan is computed (at least 1)."""
    if not np.isfinite(planning_time_s) or planning_time_s < 0:
        raise ValueError(f"planning time must be finite and >= 0, got {planning_time_s}")
    return max(1, ceil(planning_time_s / params.substep_s - 1e-12))


@dataclass(frozen=True)
class FireFront:
    """One active front: its state y = (speed, direction), current region and path hull; in
    3-D its cuboid's top and the highest top so far, its hull prism's (m; None in 2-D)."""

    front_id: int
    born_step: int
    speed_mps: float
    direction_rad: float
    region: Rect
    hull: Polytope
    top_m: float | None = None
    hull_top_m: float | None = None

    @property
    def cuboid(self) -> Cuboid:
        """C_t in 3-D: the region over [0, top_m] (ValueError for a 2-D front)."""
        if self.top_m is None:
            raise ValueError(f"front {self.front_id} has no height (a 2-D front)")
        return Cuboid(self.region, self.top_m)

    @property
    def current(self) -> Region:
        """The region the step measures d_t and d_safe to: the rectangle, or the cuboid."""
        return self.region if self.top_m is None else self.cuboid

    def advance(self, rng: np.random.Generator, params: FireParams, redraw: bool = True,
                keep_out: KeepOutZone | None = None,
                heights: FireHeights | None = None) -> FireFront:
        """One Gauss–Markov propagation sub-step (Eq. in Sec. II-B)."""
        return self.advance_clear(rng, params, redraw, keep_out, heights)[0]

    def advance_clear(
        self, rng: np.random.Generator, params: FireParams, redraw: bool = True,
        keep_out: KeepOutZone | None = None, heights: FireHeights | None = None,
    ) -> tuple[FireFront, bool]:
        """:meth:`advance`; also whether the region keeps clear of ``keep_out``.

        ``redraw`` False keeps the sides (the centre still moves); ``keep_out =
        (position, radius_m)`` redraws the sides until the region stays
        ``radius_m`` from ``position``. When even the smallest rectangle cannot
        (the front moved there), the previous sides are kept and False returned.
        With ``heights`` (3-D) a redrawn rectangle gets a new top from the heights'
        stream and the keep-out is measured to the cuboid; kept sides keep their top.
        """
        g = params.gamma
        noise = sqrt(1.0 - g * g)
        speed = (
            g * self.speed_mps
            + (1 - g) * params.speed_mean_mps
            + noise * rng.normal(0.0, params.speed_sigma_mps)
        )
        direction = (
            g * self.direction_rad
            + (1 - g) * params.direction_mean_rad
            + noise * rng.normal(0.0, params.direction_sigma_rad)
        )
        dist = speed * params.substep_s
        cx = self.region.center_x + dist * cos(direction)
        cy = self.region.center_y + dist * sin(direction)
        clear = True
        drawn: Region | None = None
        if redraw and keep_out is None:
            drawn = draw_region(cx, cy, rng, params, heights)
        elif redraw and keep_out is not None:
            smallest = lowest(Rect(cx, cy, params.side_min_m, params.side_min_m), heights)
            if clear_of(smallest, keep_out):  # else every draw contains a violating one
                drawn = draw_clear(lambda: draw_region(cx, cy, rng, params, heights), keep_out)
            clear = drawn is not None
        top = self.top_m
        if drawn is None:  # the sides kept, the centre moved
            region = Rect(cx, cy, self.region.width, self.region.height)
        elif isinstance(drawn, Cuboid):
            region, top = drawn.rect, drawn.top_m
        else:
            region = drawn
        hull = Polytope.from_vertices(np.vstack([self.hull.vertices, region.corners()]))
        hull_top = top if top is None or self.hull_top_m is None else max(top, self.hull_top_m)
        moved = FireFront(self.front_id, self.born_step, speed, direction, region, hull, top,
                          hull_top)
        return moved, clear


def draw_rect(cx: float, cy: float, rng: np.random.Generator, params: FireParams) -> Rect:
    w, h = rng.uniform(params.side_min_m, params.side_max_m, size=2)
    return Rect(cx, cy, float(w), float(h))


def draw_region(cx: float, cy: float, rng: np.random.Generator, params: FireParams,
                heights: FireHeights | None) -> Region:
    """A rectangle centred at (cx, cy) from the fire stream; with ``heights`` (3-D) its
    cuboid, the top from the heights (their own stream)."""
    rect = draw_rect(cx, cy, rng, params)
    return rect if heights is None else Cuboid(rect, heights.draw())


def lowest(rect: Rect, heights: FireHeights | None) -> Region:
    """``rect`` as the lowest cuboid ``heights`` can draw over it (``rect`` in 2-D): the one a
    keep-out is easiest to keep from."""
    if heights is None:
        return rect
    if heights.reading == "uniform":
        return Cuboid(rect, heights.params.fire_height_min_m)
    return Cuboid(rect, heights.above_ceiling_m)


def clear_of(region: Region, keep_out: KeepOutZone) -> bool:
    """Whether ``region`` keeps ``keep_out``'s radius from its position: in the plane (a
    rectangle, or a 2-D position), else to the cuboid (its planar part the polygon's
    distance, as in 2-D)."""
    pos, radius = keep_out
    if isinstance(region, Rect):
        return bool(region.polytope().distance(pos) >= radius)
    d_xy = region.rect.polytope().distance(pos)
    d_z = region.z_gap(float(pos[2])) if len(pos) == 3 else 0.0
    d = d_xy if d_z == 0.0 else float(np.hypot(d_xy, d_z))
    return bool(d >= radius)


def draw_clear(draw: Callable[[], Region], keep_out: KeepOutZone) -> Region | None:
    """The first of :data:`MAX_DRAWS` draws that keeps clear of ``keep_out``; None if none."""
    for _ in range(MAX_DRAWS):
        region = draw()
        if clear_of(region, keep_out):
            return region
    return None


@dataclass(frozen=True)
class FireSnapshot:
    """What the EWS reports at one instant: active regions and the hulls to avoid.

    In 3-D the tops (m above ground) too: ``tops_m`` one per region (its cuboid C_t's),
    ``hull_tops_m`` one per hull (its prism's: the highest top of the front so far). Both
    empty in 2-D; an empty pair read by a 3-D mission means every cuboid is taller than the
    band (:meth:`with_tops`), so a snapshot, record or message without tops keeps its meaning.
    """

    regions: tuple[Rect, ...]
    hulls: tuple[Polytope, ...]
    front_ids: tuple[int, ...] = ()
    born_steps: tuple[int, ...] = ()
    tops_m: tuple[float, ...] = ()
    hull_tops_m: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        if self.tops_m and len(self.tops_m) != len(self.regions):
            raise ValueError(f"{len(self.tops_m)} tops for {len(self.regions)} regions")
        if self.hull_tops_m and len(self.hull_tops_m) != len(self.hulls):
            raise ValueError(f"{len(self.hull_tops_m)} hull tops for {len(self.hulls)} hulls")
        if bool(self.tops_m) != bool(self.hull_tops_m) and self.regions:
            raise ValueError("a snapshot has tops for its regions and its hulls, or none")

    @property
    def has_tops(self) -> bool:
        """Whether the tops are given (a 3-D snapshot with at least one hull)."""
        return bool(self.hull_tops_m)

    def with_tops(self, top_m: float) -> FireSnapshot:
        """This snapshot with every region and hull ``top_m`` tall when it carries no tops (a
        3-D mission reads a snapshot without tops as fires taller than its band:
        :attr:`dualpilot.spec.MissionSpec.above_ceiling_m`)."""
        if self.has_tops or not self.hulls:
            return self
        return replace(self, tops_m=(top_m,) * len(self.regions),
                       hull_tops_m=(top_m,) * len(self.hulls))

    def _need_tops(self) -> None:
        if self.hulls and not self.has_tops:
            raise ValueError("a 2-D snapshot has no cuboids: give it tops (with_tops)")

    def cuboids(self) -> tuple[Cuboid, ...]:
        """The active fronts' cuboids C_t (3-D), in the order of ``regions``."""
        self._need_tops()
        return tuple(Cuboid(r, t) for r, t in zip(self.regions, self.tops_m, strict=True))

    def hull_prisms(self) -> tuple[Prism, ...]:
        """The hulls △(C^i_{1:t}) as prisms over [0, hull top] (3-D), in the order of
        ``hulls``."""
        self._need_tops()
        return tuple(Prism(h, 0.0, t) for h, t in zip(self.hulls, self.hull_tops_m,
                                                       strict=True))

    def obstacles(self, position: np.ndarray,
                  clearance_m: float) -> tuple[Polytope, ...] | tuple[Prism, ...]:
        """What a planner at ``position`` must avoid (m): :meth:`obstacles_for` for a 2-D
        position, :meth:`prisms_for` for a 3-D one."""
        if len(position) == 3:
            return self.prisms_for(position, clearance_m)
        return self.obstacles_for(position, clearance_m)

    def obstacles_for(self, position: np.ndarray, clearance_m: float) -> tuple[Polytope, ...]:
        """The regions a planner at the 2-D ``position`` must avoid, one per front (m).

        Normally the hull △(C^i_{1:t}) of the front's path. Rectangles are
        redrawn every sub-step, so a hull can grow around a UAV that is far
        from the fire itself; a UAV cannot be asked to avoid a region it is
        already in, so such a front is represented by its current region.
        """
        if len(position) != 2:
            raise ValueError("obstacles_for takes a planar position; a 3-D one's are "
                             "prisms_for (or obstacles)")
        out: list[Polytope] = []
        n_active = len(self.regions)
        for k, hull in enumerate(self.hulls):
            if hull.distance(position) >= clearance_m or k >= n_active:
                out.append(hull)
            else:
                out.append(self.regions[k].polytope())
        return tuple(out)

    def prisms_for(self, position: np.ndarray, clearance_m: float) -> tuple[Prism, ...]:
        """:meth:`obstacles_for` in 3-D: each front's hull prism (:meth:`hull_prisms`), or its
        cuboid when the UAV at the 3-D ``position`` is within ``clearance_m`` of the hull
        (distances in 3-D: a UAV above a low hull's top is not in it)."""
        position = np.asarray(position, dtype=float)
        out: list[Prism] = []
        n_active = len(self.regions)
        for k, prism in enumerate(self.hull_prisms()):
            if prism.distance(position) >= clearance_m or k >= n_active:
                out.append(prism)
            else:
                out.append(Prism(self.regions[k].polytope(), 0.0, self.tops_m[k]))
        return tuple(out)

    def current(self) -> tuple[Region, ...]:
        """The active regions as the step measures them: rectangles, or cuboids with tops."""
        return self.cuboids() if self.has_tops else self.regions
