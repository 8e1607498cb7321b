"""The ranges and sizes every decoder enforces, and the checks that raise on them.

Positions within ``MAX_ABS_M`` of the origin (m), speeds (m/s), forces (N), sizes
(fronts, hull vertices, horizon, text), altitudes and the tops of fires (m above ground,
within [0, ``MAX_ALTITUDE_M``]). A failed check raises
:class:`~services.common.rejections.CodecError` with the reason ``not_finite``,
``out_of_range`` or ``size``. The core's state is x = [p_east, p_north, v_east,
v_north] (Sec. IV, 2-D at fixed altitude), or in 3-D x = [p_east, p_north, p_up, v_east,
v_north, v_up] (docs/three_d.md).
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from dualpilot.arrays import Array
from services.common.rejections import Reason, invalid

MAX_ABS_M = 1.0e5  # positions and fire geometry (m)
#: altitudes and the tops of fires (m above ground): [0, MAX_ALTITUDE_M]
MAX_ALTITUDE_M = 10_000.0
#: A plan request's positions, goal, waypoints and fires lie within the mission's area
#: [0, A]² grown by this many A on every side: "far outside the area" is rejected.
AREA_MARGIN = 1.0
MAX_SPEED_MPS = 1.0e3
MAX_FORCE_N = 1.0e4
MAX_FRONTS = 256
MAX_RISK_ZONES = 4096  # risk zones of one plan (polygons)
MAX_VERTICES = 1024
MAX_HORIZON = 10_000
MAX_WAYPOINTS = 1000
MAX_SUBSTEPS = 10_000
MAX_SUBSTEP_S = 60.0  # T_f (s)
MAX_FORECAST_CELLS = 1 << 20  # cells of one slice of the occupancy forecast's grid
MAX_FORECAST_SLICES = 4096
MAX_TEXT = 65_536
MIN_SPEED_FACTOR = 1.0e-3  # a paced clock: at least 1 simulated ms per wall s
MAX_CLOCK_SKEW_S = 86_400.0  # a clock anchor within a day of the receiver's wall clock


def check_floats(vals: list[float], what: str, bound: float) -> list[float]:
    """``vals`` when each is finite and within ±``bound``; raises CodecError else."""
    # plain Python: for the few numbers of a message this beats numpy's per-call overhead
    for v in vals:
        if not math.isfinite(v):
            raise invalid(f"{what} must be finite, got {vals[:8]}", Reason.NOT_FINITE)
        if abs(v) > bound:
            raise invalid(f"{what} must lie within ±{bound:g}, got {vals[:8]}",
                          Reason.OUT_OF_RANGE)
    return vals


def finite(values: Iterable[float], what: str, bound: float) -> Array:
    """:func:`check_floats` of ``values``, as an array."""
    return np.array(check_floats([float(v) for v in values], what, bound))


def check_count(n: int, what: str, limit: int, minimum: int = 0) -> None:
    """``minimum`` ≤ n ≤ ``limit`` items, or CodecError (``size``)."""
    if not minimum <= n <= limit:
        raise invalid(f"{what}: {n} items, allowed {minimum}..{limit}", Reason.SIZE)


def check_int(n: int, what: str, lo: int, hi: int) -> int:
    """``n`` when ``lo`` ≤ n ≤ ``hi`` (a number, not a count of items), or CodecError
    (``out_of_range``)."""
    if not lo <= n <= hi:
        raise invalid(f"{what} must be in {lo}..{hi}, got {n}", Reason.OUT_OF_RANGE)
    return int(n)


def check_text(s: str, what: str, limit: int = MAX_TEXT) -> str:
    """``s`` when at most ``limit`` characters long, or CodecError (``size``)."""
    if len(s) > limit:
        raise invalid(f"{what} longer than {limit} characters", Reason.SIZE)
    return s


def check_in_box(points: Array, lo: float, hi: float, what: str) -> None:
    """Every (east, north) row of ``points`` lies in [lo, hi]² (m)."""
    if len(points) and (points.min() < lo or points.max() > hi):
        raise invalid(f"{what} lies outside [{lo:g}, {hi:g}] m (far outside the area)",
                      Reason.OUT_OF_RANGE)


def check_altitudes(vals: list[float], what: str) -> list[float]:
    """``vals`` when each is finite and within [0, MAX_ALTITUDE_M] (m above ground); raises
    CodecError else."""
    check_floats(vals, what, MAX_ALTITUDE_M)
    if any(v < 0.0 for v in vals):
        raise invalid(f"{what} must lie within [0, {MAX_ALTITUDE_M:g}] m, got {vals[:8]}",
                      Reason.OUT_OF_RANGE)
    return vals


def check_state_values(x: Array, what: str = "state") -> Array:
    """A core state [p_e, p_n, v_e, v_n], or in 3-D [p_e, p_n, p_up, v_e, v_n, v_up]: within
    ±MAX_ABS_M (m) east and north, [0, MAX_ALTITUDE_M] up, ±MAX_SPEED_MPS (m/s)."""
    x = np.asarray(x, dtype=float)
    if x.shape == (6,):
        e, n, up, ve, vn, vu = x.tolist()
        check_floats([e, n], f"{what} position", MAX_ABS_M)
        check_altitudes([up], f"{what} altitude")
        check_floats([ve, vn, vu], f"{what} velocity", MAX_SPEED_MPS)
        return x
    if x.shape != (4,):
        raise invalid(f"{what} must have 4 entries (6 in 3-D), got shape {x.shape}",
                      Reason.SIZE)
    e, n, ve, vn = x.tolist()  # plain floats: checked at 10 Hz per vehicle, both ways
    check_floats([e, n], f"{what} position", MAX_ABS_M)
    check_floats([ve, vn], f"{what} velocity", MAX_SPEED_MPS)
    return x
