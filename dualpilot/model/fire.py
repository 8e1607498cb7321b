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

``FireParams.scenario`` other than "paper" names a fire-behaviour scenario
(dualpilot/model/scenarios.py): the field then runs Rothermel spread on a level
set instead (dualpilot/model/physics_fire.py), with the same births, keep-out,
fronts and snapshots.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from math import ceil, cos, sin, sqrt
from typing import TYPE_CHECKING, Literal, get_args

import numpy as np

from dualpilot.model.geometry import Polytope, Rect
from dualpilot.model.scenarios import PAPER, get_scenario, scenario_names
from dualpilot.spec import MissionSpec

if TYPE_CHECKING:
    from dualpilot.model.physics_fire import PhysicsFire

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
            region = _draw_rect(cx, cy, rng, params)
        elif redraw and keep_out is not None:
            smallest = Rect(cx, cy, params.side_min_m, params.side_min_m)
            if _clear_of(smallest, keep_out):  # else every draw contains a violating one
                region = _draw_clear(lambda: _draw_rect(cx, cy, rng, params), keep_out)
            clear = region is not None
        if region is None:  # the sides kept, the centre moved
            region = Rect(cx, cy, self.region.width, self.region.height)
        hull = Polytope.from_vertices(np.vstack([self.hull.vertices, region.corners()]))
        moved = FireFront(self.front_id, self.born_step, speed, direction, region, hull)
        return moved, clear


def _draw_rect(cx: float, cy: float, rng: np.random.Generator, params: FireParams) -> Rect:
    w, h = rng.uniform(params.side_min_m, params.side_max_m, size=2)
    return Rect(cx, cy, float(w), float(h))


def _clear_of(region: Rect, keep_out: tuple[np.ndarray, float]) -> bool:
    return bool(region.polytope().distance(keep_out[0]) >= keep_out[1])


def _draw_clear(draw: Callable[[], Rect], keep_out: tuple[np.ndarray, float]) -> Rect | None:
    """The first of :data:`MAX_DRAWS` draws that keeps clear of ``keep_out``; None if none."""
    for _ in range(MAX_DRAWS):
        region = draw()
        if _clear_of(region, keep_out):
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


@dataclass
class FireField:
    """The fronts in the area [0, area_size_m]² and their evolution (the EWS's ground truth)."""

    params: FireParams = field(default_factory=FireParams)
    area_size_m: float = field(default_factory=lambda: MissionSpec().area_size_m)
    fronts: list[FireFront] = field(default_factory=list)
    extinct_hulls: list[Polytope] = field(default_factory=list)
    substeps_done: int = 0
    next_id: int = 0
    #: mission step of the last sub-step (a new number starts a time-step)
    last_step: int | None = None
    #: births dropped because no draw kept clear of the keep-out (see :meth:`substep`)
    births_skipped: int = 0
    #: redraws that could not keep clear (the front itself moved within the keep-out)
    redraws_unclear: int = 0
    #: the physics process of a named scenario (None: the paper's rectangles)
    physics: PhysicsFire | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.params.scenario != PAPER and self.physics is None:
            from dualpilot.model.physics_fire import PhysicsFire

            self.physics = PhysicsFire(get_scenario(self.params.scenario).params, self.params,
                                       self.area_size_m)

    def _take_physics(self) -> None:
        assert self.physics is not None
        self.fronts = list(self.physics.fronts)
        self.extinct_hulls = list(self.physics.extinct_hulls)
        self.births_skipped = self.physics.births_skipped
        self.next_id = self.physics.next_id

    def _birth_region(self, rng: np.random.Generator, center: tuple[float, float] | None,
                      keep_out: tuple[np.ndarray, float] | None) -> Rect | None:
        p = self.params

        def draw() -> Rect:
            if center is None:
                cx, cy = (float(v) for v in rng.uniform(0.0, self.area_size_m, size=2))
            else:
                cx, cy = center
            return _draw_rect(cx, cy, rng, p)

        return draw() if keep_out is None else _draw_clear(draw, keep_out)

    def spawn(
        self,
        rng: np.random.Generator,
        step: int,
        center: tuple[float, float] | None = None,
        keep_out: tuple[np.ndarray, float] | None = None,
    ) -> FireFront:
        """Birth of a front: centre uniform in the area (b_t), state from the means.

        ``keep_out = (position, radius_m)`` makes b_t uniform over the places
        whose region stays ``radius_m`` from ``position`` (redrawn until it
        does, at most :data:`MAX_DRAWS` times: ValueError when none does).
        """
        if self.physics is not None:
            front = self.physics.spawn(rng, step, center, keep_out)
            self._take_physics()
            return front
        region = self._birth_region(rng, center, keep_out)
        if region is None:
            assert keep_out is not None
            raise ValueError(f"no birth region in {MAX_DRAWS} draws keeps {keep_out[1]:g} m "
                             f"clear of {keep_out[0]}")
        return self._add(region, step)

    def _add(self, region: Rect, step: int) -> FireFront:
        p = self.params
        front = FireFront(
            front_id=self.next_id,
            born_step=step,
            speed_mps=p.speed_mean_mps,
            direction_rad=p.direction_mean_rad,
            region=region,
            hull=region.polytope(),
        )
        self.next_id += 1
        self.fronts.append(front)
        return front

    def substep(
        self,
        rng: np.random.Generator,
        step: int,
        keep_out: tuple[np.ndarray, float] | None = None,
    ) -> list[FireFront]:
        """One sub-step of T_f during mission step ``step``: survival, propagation, then birth.

        Returns the newborn fronts. With ``life_base = "step"`` survival and
        birth are drawn only at the first sub-step of a time-step (a new
        ``step``); ``extent`` says when the sides are redrawn. ``keep_out`` (the
        ignition clearance) applies to births, and to redraws when
        ``redraw_clearance``; a birth no draw can keep clear is skipped and
        counted in :attr:`births_skipped`.
        """
        p = self.params
        new_step = step != self.last_step
        self.last_step = step
        life = p.life_base == "substep" or new_step
        if self.physics is not None:  # a named scenario: Rothermel spread, the same births
            newborn = self.physics.substep(rng, step, life, keep_out)
            self._take_physics()
            self.substeps_done += 1
            return newborn
        redraw = p.extent == "substep" or (p.extent == "step" and new_step)
        redraw_keep = keep_out if p.redraw_clearance else None
        survivors: list[FireFront] = []
        for front in self.fronts:
            if not life or rng.random() < p.p_survive:
                moved, clear = front.advance_clear(rng, p, redraw, redraw_keep)
                self.redraws_unclear += not clear
                survivors.append(moved)
            elif p.keep_extinct_hulls:
                self.extinct_hulls.append(front.hull)
        self.fronts = survivors
        born: list[FireFront] = []
        if life and rng.random() < p.p_birth:
            region = self._birth_region(rng, None, keep_out)
            if region is None:
                self.births_skipped += 1
            else:
                born.append(self._add(region, step))
        self.substeps_done += 1
        return born

    def snapshot(self) -> FireSnapshot:
        hulls = tuple(f.hull for f in self.fronts) + tuple(self.extinct_hulls)
        return FireSnapshot(
            regions=tuple(f.region for f in self.fronts),
            hulls=hulls,
            front_ids=tuple(f.front_id for f in self.fronts),
            born_steps=tuple(f.born_step for f in self.fronts),
        )
