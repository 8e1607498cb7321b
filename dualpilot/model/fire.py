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

The process over the area is :class:`dualpilot.model.fire_field.FireField`;
this module holds its parameters, fronts and snapshots. ``FireParams.scenario``
other than "paper" names a fire-behaviour scenario (dualpilot/model/scenarios.py):
the field then runs Rothermel spread on a level set instead
(dualpilot/model/physics_fire.py), with the same births, keep-out, fronts and
snapshots.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from math import ceil, cos, sin, sqrt
from typing import Literal, get_args

import numpy as np

from dualpilot.model.geometry import Polytope, Rect
from dualpilot.model.scenarios import PAPER, scenario_names

#: Time base of birth and survival: every sub-step T_f, or once per time-step ΔT.
LifeBase = Literal["substep", "step"]
#: When a front's rectangle is drawn: every sub-step, every time-step, once at birth.
Extent = Literal["substep", "step", "birth"]
#: Draws of a birth (or a redraw) that must keep clear of a keep-out before giving up.
MAX_DRAWS = 1000


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
    """One active front: its state y = (speed, direction), current region and path hull."""

    front_id: int
    born_step: int
    speed_mps: float
    direction_rad: float
    region: Rect
    hull: Polytope

    def advance(self, rng: np.random.Generator, params: FireParams, redraw: bool = True,
                keep_out: tuple[np.ndarray, float] | None = None) -> FireFront:
        """One Gauss–Markov propagation sub-step (Eq. in Sec. II-B)."""
        return self.advance_clear(rng, params, redraw, keep_out)[0]

    def advance_clear(
        self, rng: np.random.Generator, params: FireParams, redraw: bool = True,
        keep_out: tuple[np.ndarray, float] | None = None,
    ) -> tuple[FireFront, bool]:
        """:meth:`advance`; also whether the region keeps clear of ``keep_out``.

        ``redraw`` False keeps the sides (the centre still moves); ``keep_out =
        (position, radius_m)`` redraws the sides until the region stays
        ``radius_m`` from ``position``. When even the smallest rectangle cannot
        (the front moved there), the previous sides are kept and False returned.
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
        region: Rect | None = None
        if redraw and keep_out is None:
            region = draw_rect(cx, cy, rng, params)
        elif redraw and keep_out is not None:
            smallest = Rect(cx, cy, params.side_min_m, params.side_min_m)
            if clear_of(smallest, keep_out):  # else every draw contains a violating one
                region = draw_clear(lambda: draw_rect(cx, cy, rng, params), keep_out)
            clear = region is not None
        if region is None:  # the sides kept, the centre moved
            region = Rect(cx, cy, self.region.width, self.region.height)
        hull = Polytope.from_vertices(np.vstack([self.hull.vertices, region.corners()]))
        moved = FireFront(self.front_id, self.born_step, speed, direction, region, hull)
        return moved, clear


def draw_rect(cx: float, cy: float, rng: np.random.Generator, params: FireParams) -> Rect:
    w, h = rng.uniform(params.side_min_m, params.side_max_m, size=2)
    return Rect(cx, cy, float(w), float(h))


def clear_of(region: Rect, keep_out: tuple[np.ndarray, float]) -> bool:
    return bool(region.polytope().distance(keep_out[0]) >= keep_out[1])


def draw_clear(draw: Callable[[], Rect], keep_out: tuple[np.ndarray, float]) -> Rect | None:
    """The first of :data:`MAX_DRAWS` draws that keeps clear of ``keep_out``; None if none."""
    for _ in range(MAX_DRAWS):
        region = draw()
        if clear_of(region, keep_out):
            return region
    return None


@dataclass(frozen=True)
class FireSnapshot:
    """What the EWS reports at one instant: active regions and the hulls to avoid."""

    regions: tuple[Rect, ...]
    hulls: tuple[Polytope, ...]
    front_ids: tuple[int, ...] = ()
    born_steps: tuple[int, ...] = ()


    def obstacles_for(self, position: np.ndarray, clearance_m: float) -> tuple[Polytope, ...]:
        """The regions a planner at ``position`` must avoid, one per front (m).

        Normally the hull △(C^i_{1:t}) of the front's path. Rectangles are
        redrawn every sub-step, so a hull can grow around a UAV that is far
        from the fire itself; a UAV cannot be asked to avoid a region it is
        already in, so such a front is represented by its current region.
        """
        out: list[Polytope] = []
        n_active = len(self.regions)
        for k, hull in enumerate(self.hulls):
            if hull.distance(position) >= clearance_m or k >= n_active:
                out.append(hull)
            else:
                out.append(self.regions[k].polytope())
        return tuple(out)
