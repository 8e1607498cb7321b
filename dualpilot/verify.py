"""Independent checks a plan must pass before anyone flies it.

A plan is accepted only if (i) its states follow Eq. (1) from its first
state under its controls, (ii) controls and velocities respect U and X (the speed limit per axis or
as a norm, :attr:`DynamicsParams.speed_limit`), and
(iii) the polyline through its positions keeps at least ``clearance_m``
from every hull, every segment checked exactly (no corner clipping).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from dualpilot.model.dynamics import Array, DynamicsParams, rollout
from dualpilot.model.geometry import Polytope, SegmentChecker, path_clearance


@dataclass(frozen=True)
class Verdict:
    ok: bool
    reason: str
    clearance_m: float


def verify_trajectory(
    states: Array,
    controls: Array,
    hulls: Sequence[Polytope],
    dynamics: DynamicsParams,
    clearance_m: float,
    tol: float = 1e-3,
    checker: SegmentChecker | None = None,
    rolled_out: bool = False,
) -> Verdict:
    """Check dynamics, bounds and exact clearance of a planned trajectory.

    ``checker`` may carry a :class:`SegmentChecker` already built for ``hulls``;
    ``rolled_out`` says the caller made ``states`` with :func:`rollout` from
    ``states[0]`` and ``controls`` (Eq. (1) then holds exactly and is not redone).
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
    clearance = (path_clearance(states[:, :2], hulls) if checker is None
                 else checker.path_clearance(states[:, :2]))
    if clearance < clearance_m - tol:
        return Verdict(False, f"clearance {clearance:.2f} m < {clearance_m} m", clearance)
    return Verdict(True, "ok", clearance)
