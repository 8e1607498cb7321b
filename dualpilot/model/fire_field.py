"""The fire process over the area, Sec. II-B: the fronts and their evolution (the EWS's truth).

Per sub-step of T_f: survival (p_s), Gauss–Markov propagation and redraws of the
fronts (:class:`dualpilot.model.fire.FireFront`), then a birth (p_b), the ignition
keep-out applied; :meth:`FireField.snapshot` is what the EWS reports. A named
fire-behaviour scenario (``FireParams.scenario``) runs its level set instead
(:class:`dualpilot.model.physics_fire.PhysicsFire`), with the same births,
keep-out, fronts and snapshots. In 3-D (``heights`` given) every front is a cuboid with
a top (:mod:`dualpilot.model.fire`), from the heights' own stream; the fire stream's draws
are the 2-D process's. Lengths in m.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dualpilot.model.fire import (
    MAX_DRAWS,
    FireFront,
    FireParams,
    FireSnapshot,
    KeepOutZone,
    Region,
    draw_clear,
    draw_region,
)
from dualpilot.model.fire_height import FireHeights
from dualpilot.model.geometry import Polytope
from dualpilot.model.physics_fire import PhysicsFire
from dualpilot.model.prism import Cuboid
from dualpilot.model.scenarios import PAPER, get_scenario
from dualpilot.spec import MissionSpec


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
    #: where the fronts' tops come from (3-D); None: a 2-D process, fronts without heights
    heights: FireHeights | None = field(default=None, repr=False, compare=False)
    #: the tops of ``extinct_hulls`` (3-D), in their order
    extinct_tops: list[float] = field(default_factory=list)

    def __post_init__(self) -> None:
        if self.params.scenario != PAPER and self.physics is None:
            self.physics = PhysicsFire(get_scenario(self.params.scenario).params, self.params,
                                       self.area_size_m, self.heights)

    def _take_physics(self) -> None:
        assert self.physics is not None
        self.fronts = list(self.physics.fronts)
        self.extinct_hulls = list(self.physics.extinct_hulls)
        self.extinct_tops = list(self.physics.extinct_tops)
        self.births_skipped = self.physics.births_skipped
        self.next_id = self.physics.next_id

    def _birth_region(self, rng: np.random.Generator, center: tuple[float, float] | None,
                      keep_out: KeepOutZone | None) -> Region | None:
        p = self.params

        def draw() -> Region:
            if center is None:
                cx, cy = (float(v) for v in rng.uniform(0.0, self.area_size_m, size=2))
            else:
                cx, cy = center
            return draw_region(cx, cy, rng, p, self.heights)

        return draw() if keep_out is None else draw_clear(draw, keep_out)

    def spawn(
        self,
        rng: np.random.Generator,
        step: int,
        center: tuple[float, float] | None = None,
        keep_out: KeepOutZone | None = None,
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

    def _add(self, drawn: Region, step: int) -> FireFront:
        p = self.params
        region, top = (drawn.rect, drawn.top_m) if isinstance(drawn, Cuboid) else (drawn, None)
        front = FireFront(
            front_id=self.next_id,
            born_step=step,
            speed_mps=p.speed_mean_mps,
            direction_rad=p.direction_mean_rad,
            region=region,
            hull=region.polytope(),
            top_m=top,
            hull_top_m=top,
        )
        self.next_id += 1
        self.fronts.append(front)
        return front

    def substep(
        self,
        rng: np.random.Generator,
        step: int,
        keep_out: KeepOutZone | None = None,
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
                moved, clear = front.advance_clear(rng, p, redraw, redraw_keep, self.heights)
                self.redraws_unclear += not clear
                survivors.append(moved)
            elif p.keep_extinct_hulls:
                self.extinct_hulls.append(front.hull)
                if front.hull_top_m is not None:
                    self.extinct_tops.append(front.hull_top_m)
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
        tops: tuple[float, ...] = ()
        hull_tops: tuple[float, ...] = ()
        if self.heights is not None:
            tops = tuple(float(f.top_m) for f in self.fronts if f.top_m is not None)
            hull_tops = tuple(float(f.hull_top_m) for f in self.fronts
                              if f.hull_top_m is not None) + tuple(self.extinct_tops)
        return FireSnapshot(
            regions=tuple(f.region for f in self.fronts),
            hulls=hulls,
            front_ids=tuple(f.front_id for f in self.fronts),
            born_steps=tuple(f.born_step for f in self.fronts),
            tops_m=tops,
            hull_tops_m=hull_tops,
        )

    def current(self) -> tuple[Region, ...]:
        """The active fronts' regions now: rectangles (2-D) or cuboids (3-D)."""
        return tuple(f.current for f in self.fronts)
