"""The fire future the oracle knows: the mission's own fire stream, run ahead sub-step by sub-step.

The fires of a mission are :class:`~dualpilot.model.fire_field.FireField` on the
spec's fire stream (:meth:`dualpilot.spec.MissionSpec.rng`), advanced by the
mission step one sub-step of T_f at a time with the step number t. The oracle
flies one planning sub-step a step (the fewest a step can take: ⌈T_s/T_f⌉ ≥ 1)
plus the reading's ``fire_substeps_per_motion``, so sub-step s (1-based) belongs
to step t = ⌊(s − 1) / k⌋, k = 1 + fire_substeps_per_motion.

Two things could make the fires depend on the flight, and each is handled where
it matters:

* **the ignition clearance** (``ignition_clearance_m``): a birth drawn within it
  of the UAV is redrawn, which moves the stream. The future here is run with no
  keep-out; it is the mission's future for every flight that never comes within
  the clearance of a region at the sub-step it is drawn (the redraw then never
  happens, the draws are the same). The search keeps that distance from every
  region (:mod:`~dualpilot.oracle.search`), the certificate gives up where a
  reachable position could trigger a redraw (:mod:`~dualpilot.oracle.certificate`);
* **the length of a step** (``life_base`` or ``extent`` "step"): births, survival
  and redraws are drawn at the first sub-step of each step, so the fires depend
  on how many sub-steps each step takes. :attr:`FireFuture.schedule_free` says
  whether they do not; when they do, this future is that of a controller whose
  steps take one planning sub-step (System 1's pace under the paper's timing).

Regions are kept as arrays of bounds (x_lo, y_lo, x_hi, y_hi) in m, per sub-step; of a 3-D
mission (its heights' own stream, :meth:`dualpilot.model.vertical.VerticalParams.fire_heights`)
with the cuboid's top as a fifth column (x_lo, y_lo, x_hi, y_hi, top), the rectangles the
same.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from dualpilot.arrays import AnyArray, Array
from dualpilot.mission.config import MissionConfig
from dualpilot.model.fire import FireParams
from dualpilot.model.fire_field import FireField
from dualpilot.model.scenarios import PAPER
from dualpilot.spec import Stream


class Future(Protocol):
    """What the search and the certificate read of a fire future (:class:`FireFuture`, or a
    scripted one in the tests)."""

    #: sub-steps a step of the oracle takes
    substeps_per_step: int

    @property
    def schedule_free(self) -> bool: ...

    def regions(self, s: int) -> Array: ...

    def newborn(self, s: int) -> Array: ...

    def packed(self, substeps: int) -> tuple[Array, AnyArray]: ...


def schedule_free(fire: FireParams) -> bool:
    """Whether the fires are the same whatever the sub-steps of each step: births and
    survival drawn every sub-step, and no extent redraw tied to the step (a physics
    scenario has no drawn extent)."""
    return fire.life_base == "substep" and (fire.scenario != PAPER or fire.extent != "step")


class FireFuture:
    """The regions after each sub-step of one mission's fires, generated on demand.

    ``regions(s)`` are the active regions after s sub-steps (s = 0: the start);
    ``newborn(s)`` the regions of the fronts whose id first appears after sub-step s.
    """

    def __init__(self, config: MissionConfig):
        reading = config.reading()
        spec = config.spec()
        self.fire = reading.fire
        self.mission = reading.mission
        self.area_size_m = spec.area_size_m
        #: sub-steps a step of the oracle takes: one to plan, then those in flight
        self.substeps_per_step = 1 + reading.mission.fire_substeps_per_motion
        heights = reading.altitude.fire_heights(spec, reading.fire.scenario)
        #: columns of a region's row: 4, or 5 with the top in 3-D
        self.width = 4 if heights is None else 5
        self._field = FireField(params=reading.fire, area_size_m=spec.area_size_m,
                                heights=heights)
        self._rng = spec.rng(Stream.FIRE)
        self._seen: set[int] = set()
        self._regions: list[Array] = []
        self._newborn: list[Array] = []
        self._record()

    @property
    def schedule_free(self) -> bool:
        """The fires do not depend on the sub-steps a step takes (:func:`schedule_free`)."""
        return schedule_free(self.fire)

    @property
    def substeps(self) -> int:
        """Sub-steps generated so far."""
        return len(self._regions) - 1

    def _record(self) -> None:
        fronts = self._field.fronts
        rows = [f.region.bounds if self.width == 4 else (*f.region.bounds, f.top_m)
                for f in fronts]
        boxes = np.array(rows, dtype=float).reshape(-1, self.width)
        fresh = [k for k, f in enumerate(fronts) if f.front_id not in self._seen]
        self._seen.update(f.front_id for f in fronts)
        self._regions.append(boxes)
        self._newborn.append(boxes[fresh] if fresh else np.empty((0, self.width)))

    def extend(self, substeps: int) -> None:
        """Run the fires until ``substeps`` sub-steps are known."""
        while self.substeps < substeps:
            step = self.substeps // self.substeps_per_step
            self._field.substep(self._rng, step)
            self._record()

    def regions(self, s: int) -> Array:
        """Bounds (k, 4) of the active regions after ``s`` sub-steps (m); (k, 5) with the
        tops in 3-D."""
        self.extend(s)
        return self._regions[s]

    def newborn(self, s: int) -> Array:
        """Bounds (k, 4) of the regions of fronts first seen after sub-step ``s`` (m)."""
        self.extend(s)
        return self._newborn[s]

    def packed(self, substeps: int) -> tuple[Array, AnyArray]:
        """(bounds, offsets) for a compiled kernel: the regions after sub-step s are
        ``bounds[offsets[s]:offsets[s + 1]]``, s = 0..``substeps``."""
        self.extend(substeps)
        parts = self._regions[: substeps + 1]
        offsets = np.zeros(len(parts) + 1, dtype=np.int64)
        offsets[1:] = np.cumsum([len(p) for p in parts])
        bounds = np.vstack(parts) if offsets[-1] else np.empty((0, self.width))
        return np.ascontiguousarray(bounds, dtype=float), offsets
