"""Independent checks a plan must pass before anyone flies it.

A plan is accepted only if (i) its states follow Eq. (1) from its first
state under its controls, (ii) controls and velocities respect U and X (the speed limit per axis or
as a norm, :attr:`DynamicsParams.speed_limit`), and
(iii) the polyline through its positions keeps at least ``clearance_m``
from every hull, every segment checked exactly (no corner clipping).

In 3-D (``dynamics.dim == 3``) the hulls are prisms (the fires' cuboids and swept hulls,
:class:`~dualpilot.model.prism.Prism`), the clearance is the 3-D distance of every segment
(:class:`~dualpilot.model.segment3.SegmentChecker3`), and with a ``band`` (iv) every planned
altitude lies in [floor, ceiling].
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from dualpilot.model.altitude import AltitudeBand
from dualpilot.model.dynamics import Array, DynamicsParams, rollout
from dualpilot.model.geometry import Polytope, SegmentChecker, path_clearance
from dualpilot.model.prism import Prism
from dualpilot.model.segment3 import SegmentChecker3, prism_path_clearance


@dataclass(frozen=True)
class Verdict:
    ok: bool
    reason: str
    clearance_m: float


def verify_trajectory(
    states: Array,
    controls: Array,
    hulls: Sequence[Polytope] | Sequence[Prism],
    dynamics: DynamicsParams,
    clearance_m: float,
    tol: float = 1e-3,
    checker: SegmentChecker | SegmentChecker3 | None = None,
    rolled_out: bool = False,
    band: AltitudeBand | None = None,
) -> Verdict:
    """Check dynamics, bounds and exact clearance of a planned trajectory.

    ``checker`` may carry a :class:`SegmentChecker` (a :class:`SegmentChecker3` in 3-D)
    already built for ``hulls``; ``rolled_out`` says the caller made ``states`` with
    :func:`rollout` from ``states[0]`` and ``controls`` (Eq. (1) then holds exactly and is
    not redone). ``band`` (3-D): every planned altitude p_z of rows 1.. within [floor,
    ceiling] ± ``tol``.
    """
    states = np.asarray(states, dtype=float)
    controls = np.asarray(controls, dtype=float)
    n = dynamics.dim
    if states.ndim != 2 or states.shape[1] != 2 * n or len(states) != len(controls) + 1:
        return Verdict(False, f"bad shapes {states.shape} / {controls.shape}", float("nan"))
    if not (np.isfinite(states).all() and np.isfinite(controls).all()):
        return Verdict(False, "non-finite values", float("nan"))
    if not rolled_out:
        expected = rollout(states[0], controls, dynamics)
        err = float(np.max(np.abs(expected - states))) if len(states) else 0.0
        # Relative tolerance: solver outputs are accurate to ~1e-6 of the state scale.
        if err > tol * max(1.0, float(np.max(np.abs(states)))):
            return Verdict(False, f"states violate Eq. (1) by {err:.3g}", float("nan"))
    if (np.abs(controls) > dynamics.u_max_n + tol).any():
        return Verdict(False, f"control exceeds {dynamics.u_max_n} N", float("nan"))
    if dynamics.speed_limit == "norm":  # ‖v‖ ≤ v_max
        if (dynamics.speeds(states[1:, n:]) > dynamics.v_max_mps + tol).any():
            return Verdict(False, f"speed exceeds {dynamics.v_max_mps} m/s", float("nan"))
    elif (np.abs(states[1:, n:]) > dynamics.v_max_mps + tol).any():
        return Verdict(False, f"velocity exceeds {dynamics.v_max_mps} m/s", float("nan"))
    if n == 3:
        if band is not None:
            z = states[1:, 2]
            if len(z) and (z.min() < band.floor_m - tol or z.max() > band.ceiling_m + tol):
                worst = float(z.min() if z.min() < band.floor_m - tol else z.max())
                return Verdict(False, f"altitude {worst:.2f} m leaves the band "
                                      f"[{band.floor_m:g}, {band.ceiling_m:g}] m", float("nan"))
        if not all(isinstance(h, Prism) for h in hulls):
            return Verdict(False, "a 3-D plan is checked against prisms, not planar hulls",
                           float("nan"))
        clearance = (prism_path_clearance(states[:, :3], hulls)  # type: ignore[arg-type]
                     if checker is None else checker.path_clearance(states[:, :3]))
    else:
        clearance = (path_clearance(states[:, :2], hulls)  # type: ignore[arg-type]
                     if checker is None else checker.path_clearance(states[:, :2]))
    if clearance < clearance_m - tol:
        return Verdict(False, f"clearance {clearance:.2f} m < {clearance_m} m", clearance)
    return Verdict(True, "ok", clearance)
