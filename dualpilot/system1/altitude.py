"""Where System 1 flies in 3-D: the reading ``s1_altitude`` (docs/three_d.md, System 1).

The paper's System 1 stands in for a human operator (Sec. III-A); its evaluation flies
"assuming a fixed altitude" (Sec. IV-A) and says nothing of when a pilot would climb.
Two readings, :data:`~dualpilot.model.vertical.S1Altitude`:

* ``"slice-first"`` (the default): plan first in the horizontal slice at the UAV's
  altitude with the planar Alg. 1 (:func:`dualpilot.system1.rrt.plan_path`) against the
  bases of the prisms whose [z_lo − c, z_hi + c] holds that altitude (c the paths'
  clearance; a prism outside is more than c above or below the slice, so the slice's
  path keeps c from it too); only when the slice has no path does the 3-D tree grow
  (:func:`dualpilot.system1.rrt3.plan_path3`). A pilot keeps their altitude until a fire
  is in the way. When every prism spans the band the slice *is* the 2-D problem — same
  hulls, same random draws, the same path lifted — and the 3-D tree could find nothing
  more (every path of the band has a ground track at the same distances), so it is not
  grown.
* ``"volume"``: the 3-D tree at once.

The forecast's risk zones (the risk-aware variant) are timed along planar paths: they
are met in the slice only (footprints, or with heights, ``risk_zone_height = "fire"``,
the zones' prisms measured from the slice's altitude); a risk-aware plan that needs the
third dimension is not made (its planner then flies the plain plan,
:class:`~dualpilot.system1.planner.RiskSystem1`). Lengths m.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.geometry import Polytope, SegmentChecker
from dualpilot.model.prism import Prism
from dualpilot.model.risk import ArcRisk
from dualpilot.model.segment3 import SegmentChecker3
from dualpilot.model.vertical import S1Altitude
from dualpilot.spec import MissionSpec
from dualpilot.system1.rrt import RrtParams, RrtResult, plan_path
from dualpilot.system1.rrt3 import plan_path3


def slice_bases(prisms: Sequence[Prism], z: float, clearance_m: float) -> tuple[Polytope, ...]:
    """The bases of the prisms within ``clearance_m`` of the altitude ``z`` (m), in order."""
    return tuple(p.base for p in prisms if p.z_lo - clearance_m <= z <= p.z_hi + clearance_m)


def lift_path(path: Array | None, z: float) -> Array | None:
    """A planar path (k, 2) at the altitude ``z``: (k, 3)."""
    if path is None:
        return None
    return np.column_stack([path, np.full(len(path), z)])


def _in_slice(start: Array, prisms: Sequence[Prism], rng: np.random.Generator,
              spec: MissionSpec, params: RrtParams, risk: ArcRisk | None) -> RrtResult | None:
    """The planar Alg. 1 in the slice at the start's altitude, lifted; None when the slice
    cannot hold a plan (G's box misses the altitude, or the start is nearer than d_safe to
    a slice's base: a prism just below or above it)."""
    z = float(start[2])
    box = spec.goal_box
    if not box.z_lo <= z <= box.z_hi:
        return None
    bases = slice_bases(prisms, z, spec.clearance_m)
    checker = SegmentChecker(bases)
    if checker.point_distance(start[:2]) < spec.d_safe_m:
        return None
    res = plan_path(start[:2], spec.goal, bases, rng, spec.clearance_m, spec.area_size_m,
                    params, start_clearance_m=spec.d_safe_m, checker=checker, risk=risk)
    return RrtResult(lift_path(res.path, z), res.status, res.iterations, res.time_s,
                     lift_path(res.tree_path, z))


def plan_in_band(start: Array, prisms: Sequence[Prism], rng: np.random.Generator,
                 spec: MissionSpec, params: RrtParams, altitude: S1Altitude = "slice-first",
                 checker: SegmentChecker3 | None = None,
                 risk: ArcRisk | None = None) -> RrtResult:
    """Alg. 1 for a 3-D mission: a path (k, 3) from ``start`` (3,) into G keeping the spec's
    clearance from every prism, by the reading ``altitude`` (module docstring).

    Edges leaving the start keep d_safe at least (an escape, as in the plane); the slice
    and the tree share ``params.max_cpu_s``. ValueError
    as :func:`dualpilot.system1.rrt3.plan_path3` says; an unknown reading is one too.
    """
    t0, cpu0 = time.perf_counter(), time.thread_time()
    if altitude not in ("slice-first", "volume"):
        raise ValueError(f"s1_altitude must be 'slice-first' or 'volume', not {altitude!r}")
    p = np.asarray(start, dtype=float)
    sliced = None
    if altitude == "slice-first":
        sliced = _in_slice(p, prisms, rng, spec, params, risk)
        if sliced is not None and (sliced.found or all(x.spans(spec.band) for x in prisms)):
            return sliced
    if risk is not None:  # zones timed along planar paths: no risk-aware plan leaves the slice
        return sliced or RrtResult(None, "risk_planar", 0, time.perf_counter() - t0)
    left = params.max_cpu_s - (time.thread_time() - cpu0)  # one CPU cap for slice and tree
    res = plan_path3(p, spec.goal_box, prisms, rng, spec.clearance_m, spec.area_size_m,
                     spec.band, replace(params, max_cpu_s=max(left, 1e-3)),
                     start_clearance_m=spec.d_safe_m, checker=checker)
    if sliced is not None:  # the slice's samples and time count
        return RrtResult(res.path, res.status, sliced.iterations + res.iterations,
                         time.perf_counter() - t0, res.tree_path)
    return res
