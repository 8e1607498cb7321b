"""The frozen mission spec: area, start, goal, dynamics, d_safe, clearance, seed (Sec. IV-A).

Every part of a mission reads its geometry and margins from one
:class:`MissionSpec`: the loop, both planners, every verifier, the EWS and the
records. d_safe and the planners' clearance are written here and nowhere
else; the random streams are derived from the seed here and nowhere else.

In 3-D (``dynamics.dim == 3``, docs/three_d.md) the spec also says the altitude band, the
start and goal altitudes (:class:`~dualpilot.model.altitude.AltitudeBand`) and the goal's
vertical extent: positions are [x, y, z] with z up, m above flat ground (NED's down axis
is the MAVLink boundary's alone). ``start`` and ``goal`` stay planar; :attr:`start_position`,
:attr:`goal_center` and :meth:`in_goal` are the dimension's.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field, replace

import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.altitude import AltitudeBand, GoalBox, GoalVertical
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.model.geometry import Rect
from dualpilot.model.zone_heights import BAND, ZoneHeights

#: Sec. IV: "a predefined safety threshold (denoted as d_safe = 20 m)".
D_SAFE_M = 20.0
#: The planners' clearance from the hulls: P2's ε (Eq. P2_3) and Alg. 1's PathFree margin.
#: Positions 25 m outside every face keep the straight segment between two of them
#: (at most 15·√2 m long) more than d_safe from the hull.
CLEARANCE_M = 25.0


class Stream(enum.Enum):
    """The independent random streams of one mission."""

    FIRE = "fire"
    SUPERVISOR = "supervisor"
    SYSTEM1 = "system1"
    #: the fronts' heights (3-D, ``fire_height = "uniform"``): apart from the fire stream, so
    #: a 3-D mission's rectangles are the 2-D mission's, seed for seed
    FIRE_HEIGHT = "fire_height"
    #: the plant's wind and measurement errors (dualpilot/plant)
    PLANT = "plant"


#: The tube margin's resolution: steps of 2⁻²⁰ m (:meth:`MissionSpec.with_tracking_margin`).
_MARGIN_STEPS = 2.0 ** 20

#: Seed-sequence key of System 1's stream, apart from the fire and supervisor streams.
_SYSTEM1_KEY = 7
#: Seed-sequence key of the plant's stream: its own entropy, so flying a plant moves no draw of
#: the other streams.
_PLANT_KEY = 17
#: Seed-sequence key of the fire forecast's streams (dualpilot/model/front_forecast.py).
_FORECAST_KEY = 11
#: Seed-sequence key of the fronts' heights (:attr:`Stream.FIRE_HEIGHT`).
_FIRE_HEIGHT_KEY = 13


def stream_rng(seed: int, stream: Stream) -> np.random.Generator:
    """The generator of one stream of the mission seeded with ``seed``."""
    if stream is Stream.SYSTEM1:
        return np.random.default_rng(np.random.SeedSequence([seed, _SYSTEM1_KEY]))
    if stream is Stream.FIRE_HEIGHT:
        return np.random.default_rng(np.random.SeedSequence([seed, _FIRE_HEIGHT_KEY]))
    if stream is Stream.PLANT:
        return np.random.default_rng(np.random.SeedSequence([seed, _PLANT_KEY]))
    fire, supervisor = np.random.SeedSequence(seed).spawn(2)
    return np.random.default_rng(fire if stream is Stream.FIRE else supervisor)


def forecast_rng(seed: int, issued_substep: int) -> np.random.Generator:
    """The stream of the fire forecast made after ``issued_substep`` sub-steps of the mission
    seeded with ``seed``: entropy of its own, so drawing it moves no mission stream."""
    return np.random.default_rng(np.random.SeedSequence([seed, _FORECAST_KEY, issued_substep]))


@dataclass(frozen=True)
class MissionSpec:
    """Where a mission flies and with what margins; frozen, shared by every part.

    Lengths in m (local frame, x east, y north, z up), the area is the square
    [0, area_size_m]²; ``dynamics`` holds ΔT, ζ, m and the limits of Eq. (1). ``band`` and
    ``goal_vertical`` are read only in 3-D (``dynamics.dim == 3``): the altitudes the UAV
    keeps, its start and G_o's altitudes, and the goal box's vertical reading
    (:meth:`~dualpilot.model.altitude.GoalBox.over`). ``d_safe_m`` and ``clearance_m`` are
    what plans keep: the paper's d_safe and ε plus ``tracking_margin_m``, the tube a flying
    plant's error needs (0: the ideal plant); the flight itself is judged against
    :attr:`flight_d_safe_m`, the paper's d_safe.
    """

    start: tuple[float, float] = (50.0, 50.0)
    goal: Rect = Rect(900.0, 900.0, 100.0, 100.0)
    area_size_m: float = 1000.0
    d_safe_m: float = D_SAFE_M
    clearance_m: float = CLEARANCE_M
    seed: int = 0
    dynamics: DynamicsParams = field(default_factory=DynamicsParams)
    band: AltitudeBand = field(default_factory=AltitudeBand)
    goal_vertical: GoalVertical = "band"
    tracking_margin_m: float = 0.0
    #: how far (m and m/s, ∞-norm) two measurements of one state may differ: the run-time
    #: monitor's "starts at the measured state" tolerance grows by it (0: exact measurements)
    measurement_tol: float = 0.0
    #: how tall the forecast's risk zones are in 3-D (``risk_zone_height``,
    #: dualpilot/model/zone_heights.py), read by every consumer of the zones alike
    zone_heights: ZoneHeights = BAND
    #: the tube's velocity counterpart (m/s): how far a flying plant's velocity may depart
    #: from its plan's (:func:`dualpilot.plant.reading.auto_velocity_margin_mps`; 0: the ideal
    #: plant); read only by the concurrent supervisor's ``reanchor_tol = "tube"``
    tracking_margin_mps: float = 0.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.area_size_m) and self.area_size_m > 0):
            raise ValueError(f"area_size_m must be positive, got {self.area_size_m}")
        if not (0 <= self.d_safe_m <= self.clearance_m):
            raise ValueError(f"need 0 <= d_safe_m <= clearance_m, got {self.d_safe_m}, "
                             f"{self.clearance_m}")
        if not 0.0 <= 2.0 * self.tracking_margin_m <= self.d_safe_m:
            raise ValueError(f"need 0 <= tracking_margin_m <= d_safe_m / 2 (the tube is at "
                             f"most the paper's d_safe), got {self.tracking_margin_m}, "
                             f"{self.d_safe_m}")
        if not (math.isfinite(self.measurement_tol) and self.measurement_tol >= 0.0):
            raise ValueError(f"measurement_tol must be >= 0, got {self.measurement_tol}")
        if not (math.isfinite(self.tracking_margin_mps) and self.tracking_margin_mps >= 0.0):
            raise ValueError(f"tracking_margin_mps must be >= 0, got {self.tracking_margin_mps}")
        if not self.goal.inside(self.area):
            raise ValueError(f"goal {self.goal} lies outside the {self.area_size_m} m area")
        if not self.area.contains(np.array(self.start)):
            raise ValueError(f"start {self.start} lies outside the area")
        GoalBox.over(self.goal, self.band, self.goal_vertical)  # ValueError: unknown reading

    @property
    def dim(self) -> int:
        """The dimension of positions (2: the top-down evaluation, 3: Sec. II's 𝓔 ⊂ ℝ³)."""
        return self.dynamics.dim

    @property
    def goal_box(self) -> GoalBox:
        """G in 3-D: the goal rectangle over the altitudes of ``goal_vertical``."""
        return GoalBox.over(self.goal, self.band, self.goal_vertical)

    @property
    def start_position(self) -> Array:
        """Where the UAV starts (m), shape (dim,): ``start``, at the band's start altitude in
        3-D."""
        if self.dim == 3:
            return np.array([*self.start, self.band.start_altitude_m])
        return np.array(self.start, dtype=float)

    @property
    def goal_center(self) -> Array:
        """G_o of Eq. (S2) (m), shape (dim,): the goal's centre, at G_o's altitude in 3-D."""
        if self.dim == 3:
            return self.goal_box.center
        return self.goal.center

    def in_goal(self, position: Array) -> bool:
        """Whether ``position`` (dim,) lies in G: the rectangle (2-D), the goal box (3-D)."""
        if self.dim == 3:
            return self.goal_box.contains(position)
        return self.goal.contains(position)

    @property
    def above_ceiling_m(self) -> float:
        """The top (m) of a cuboid taller than the band: the ceiling plus the planners'
        clearance ε (:meth:`~dualpilot.model.altitude.AltitudeBand.above_ceiling_m`), what a
        front without a height of its own is (the top-down evaluation's fire)."""
        return self.band.above_ceiling_m(self.clearance_m)

    @property
    def flight_d_safe_m(self) -> float:
        """The distance (m) the flight must keep from the fires: d_safe without the tube."""
        return self.d_safe_m - self.tracking_margin_m

    def with_tracking_margin(self, margin_m: float) -> MissionSpec:
        """This spec with its plans keeping ``margin_m`` (m) more than the paper's d_safe and
        ε (the tube around a flying plant's path); the flight is still judged against the
        paper's d_safe (:attr:`flight_d_safe_m`). The margin is kept in steps of 2⁻²⁰ m
        (about 1 µm), so that adding and removing it is exact."""
        base = self.flight_d_safe_m
        if not 0.0 <= margin_m <= base:
            raise ValueError(f"need 0 <= tracking_margin_m <= d_safe ({base:g} m), "
                             f"got {margin_m}")
        kept = math.ceil(margin_m * _MARGIN_STEPS) / _MARGIN_STEPS
        if kept == self.tracking_margin_m:
            return self
        return replace(self, d_safe_m=base + kept,
                       clearance_m=self.clearance_m - self.tracking_margin_m + kept,
                       tracking_margin_m=kept)

    @property
    def area(self) -> Rect:
        """The area E as a rectangle (m)."""
        a = self.area_size_m
        return Rect(a / 2, a / 2, a, a)

    def rng(self, stream: Stream) -> np.random.Generator:
        """The generator of one stream; the same seed gives the same mission."""
        return stream_rng(self.seed, stream)

    @staticmethod
    def random(rng: np.random.Generator, seed: int, area_size_m: float = 1000.0) -> MissionSpec:
        """A random configuration: start near one corner, goal near the opposite one."""
        start = rng.uniform(25.0, 200.0, size=2)
        gc = rng.uniform(area_size_m - 250.0, area_size_m - 75.0, size=2)
        return MissionSpec(
            start=(float(start[0]), float(start[1])),
            goal=Rect(float(gc[0]), float(gc[1]), 100.0, 100.0),
            area_size_m=area_size_m,
            seed=seed,
        )
