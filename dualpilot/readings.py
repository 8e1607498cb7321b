"""Named readings of the paper and the profiles that group them (Sec. II-B, III-C, IV).

A *reading* is a field of :class:`~dualpilot.model.fire.FireParams`,
:class:`~dualpilot.mission.params.MissionParams`,
:class:`~dualpilot.supervisor.paper.decision.SupervisorParams`,
:class:`~dualpilot.model.dynamics.DynamicsParams` or, for the third dimension,
:class:`~dualpilot.model.vertical.VerticalParams` where the paper can
reasonably be read two ways. A :class:`Profile` is a frozen set of the five,
with the sentences of the paper it rests on; its dynamics, altitude band and goal
reading go into the mission spec (:meth:`Profile.spec`). Every field is addressed by
its bare name (the classes share none; the altitude part's nested band, heights and
plume are addressed by their fields' names too), so ``--set life_base=step`` and
``--set ceiling_m=100`` work on ``mission``, ``evaluate`` and ``sweep`` alike. The
plant's readings (:class:`~dualpilot.plant.reading.PlantReading`: which vehicle flies, in
what air; not readings of the paper, which flies Eq. (1) itself) are a part too, and its
tube margin goes into the mission spec (``--set plant=multirotor``).
"""

from __future__ import annotations

import dataclasses
import types
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from functools import cache
from typing import Any, Literal, Union, get_args, get_origin, get_type_hints

from dualpilot.mission.params import MissionParams
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.model.fire import FireParams
from dualpilot.model.vertical import VerticalParams
from dualpilot.plant.plant import PlantParams
from dualpilot.plant.reading import (
    PlantReading,
    auto_velocity_margin_mps,
    measurement_tol,
    plant_params,
)
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.paper.decision import SupervisorParams

#: The fields that are readings of the paper (the rest are its Sec. IV-A numbers).
READINGS = ("life_base", "extent", "redraw_clearance", "keep_extinct_hulls",
            "ignition_clearance_m", "d_t_reading", "failure_rule", "fire_substeps_per_motion",
            "attention_draw", "speed_limit", "dim", "ceiling_m", "floor_m", "start_altitude_m",
            "goal_altitude_m", "goal_vertical", "fire_height", "plume_intensity", "uav_limit_c",
            "s1_altitude", "risk_zone_height")

#: The plant's readings (not the paper's: dualpilot/plant/reading.py), in field order.
PLANT_READINGS = tuple(f.name for f in dataclasses.fields(PlantReading))

_PARTS = {"fire": FireParams, "mission": MissionParams, "supervisor": SupervisorParams,
          "dynamics": DynamicsParams, "altitude": VerticalParams,
          "plant": PlantReading}
#: The parts whose nested parameter objects' fields are addressed by their bare names too.
_NESTED = frozenset({"altitude"})


@cache
def _leaves(part: str) -> dict[str, tuple[tuple[str, ...], type]]:
    """Each field ``part`` holds by its bare name: (its path within the part, the class that
    declares it). A nested parameter object of a :data:`_NESTED` part is walked into."""
    cls = _PARTS[part]
    hints = get_type_hints(cls)
    out: dict[str, tuple[tuple[str, ...], type]] = {}
    for f in dataclasses.fields(cls):
        inner = hints[f.name]
        if part in _NESTED and dataclasses.is_dataclass(inner) and isinstance(inner, type):
            for g in dataclasses.fields(inner):
                out[g.name] = ((f.name, g.name), inner)
        else:
            out[f.name] = ((f.name,), cls)
    return out


def _replaced(obj: Any, changes: Mapping[tuple[str, ...], Any]) -> Any:
    """``obj`` with each path of ``changes`` set (a nested object replaced once, whole)."""
    direct = {path[0]: v for path, v in changes.items() if len(path) == 1}
    nested: dict[str, dict[tuple[str, ...], Any]] = {}
    for path, v in changes.items():
        if len(path) > 1:
            nested.setdefault(path[0], {})[path[1:]] = v
    for name, sub in nested.items():
        direct[name] = _replaced(getattr(obj, name), sub)
    return replace(obj, **direct) if direct else obj


@dataclass(frozen=True)
class Profile:
    """One reading of the paper: fire, mission, supervisor, dynamics and altitude parameters,
    and its sources."""

    name: str
    fire: FireParams = field(default_factory=FireParams)
    mission: MissionParams = field(default_factory=MissionParams)
    supervisor: SupervisorParams = field(default_factory=SupervisorParams)
    dynamics: DynamicsParams = field(default_factory=DynamicsParams)
    altitude: VerticalParams = field(default_factory=VerticalParams)
    plant: PlantReading = field(default_factory=PlantReading)
    summary: str = ""
    #: the sentences of the paper (or the reason) each reading rests on
    sources: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        self.altitude.heights.resolved(self.fire.scenario)  # a height reading of this process

    def values(self) -> dict[str, Any]:
        """Every scalar parameter by name (nested and tuple fields left out; the altitude
        part's nested band, heights and plume by their fields)."""
        out: dict[str, Any] = {}
        for part in _PARTS:
            obj = getattr(self, part)
            for name, (path, _) in _leaves(part).items():
                v = obj
                for step in path:
                    v = getattr(v, step)
                if v is None or isinstance(v, (bool, int, float, str)):
                    out[name] = v
        return out

    def readings(self) -> dict[str, Any]:
        """The reading fields only, in :data:`READINGS` order."""
        values = self.values()
        return {k: values[k] for k in READINGS}

    def plant_readings(self) -> dict[str, Any]:
        """The plant's readings, in :data:`PLANT_READINGS` order."""
        return {k: getattr(self.plant, k) for k in PLANT_READINGS}

    def plant_params(self) -> PlantParams:
        """The plant the mission flies (the fire scenario's wind on a fire-behaviour
        scenario)."""
        return plant_params(self.plant, self.fire.scenario)

    def with_settings(self, settings: Mapping[str, Any], name: str | None = None) -> Profile:
        """This profile with ``settings`` (field name → value, or its text) applied."""
        changes: dict[str, dict[tuple[str, ...], Any]] = {k: {} for k in _PARTS}
        for key, value in settings.items():
            part = part_of(key)
            path = _leaves(part)[key][0]
            changes[part][path] = parse_value(key, value) if isinstance(value, str) else value
        parts = {part: _replaced(getattr(self, part), changes[part]) for part in _PARTS}
        return replace(self, name=name or self.name, **parts)

    def spec(self, base: MissionSpec) -> MissionSpec:
        """``base`` flown with this profile's dynamics (Eq. (1) and its limits), altitude band,
        goal reading and risk zones' heights (read in 3-D only), its plans keeping the plant's
        tube margin (``tracking_margin_m``; 0 for the ideal plant), its velocity counterpart
        (``tracking_margin_mps``, :func:`~dualpilot.plant.reading.auto_velocity_margin_mps`;
        read only by ``reanchor_tol = "tube"``) and checked with its measurements'
        tolerance (``measurement_tol``; 0 when exact)."""
        self.plant_params()  # ValueError: a wind that is not the fire scenario's
        a = self.altitude
        spec = base
        if (base.dynamics, base.band, base.goal_vertical) != (self.dynamics, a.band,
                                                               a.goal_vertical):
            spec = replace(base, dynamics=self.dynamics, band=a.band,
                           goal_vertical=a.goal_vertical)
        tol = measurement_tol(self.plant, self.dynamics.dt_s, self.dynamics.dim)
        if tol != spec.measurement_tol:
            spec = replace(spec, measurement_tol=tol)
        vel = auto_velocity_margin_mps(self.plant)
        if vel != spec.tracking_margin_mps:
            spec = replace(spec, tracking_margin_mps=vel)
        spec = spec.with_tracking_margin(self.plant.margin_m(self.dynamics.dim))
        zones = a.zone_heights(spec, self.fire.scenario)
        return spec if zones == spec.zone_heights else replace(spec, zone_heights=zones)


def part_of(name: str) -> str:
    """Which parameter class ("fire", "mission", "supervisor", "dynamics", "altitude",
    "plant") holds ``name``."""
    for part in _PARTS:
        if name in _leaves(part):
            return part
    raise ValueError(f"unknown parameter {name!r}; known: {', '.join(sorted(settable()))}")


def settable() -> list[str]:
    """Every field a setting can name."""
    return sorted(Profile(name="").values())


def _field_type(name: str) -> Any:
    _, cls = _leaves(part_of(name))[name]
    return get_type_hints(cls)[name]


def value_text(value: Any) -> str:
    """A reading's value as the text :func:`parse_value` reads back (floats exactly, by repr)."""
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value) if isinstance(value, float) else str(value)


def parse_value(name: str, text: str) -> Any:
    """The value of field ``name`` written as ``text`` ("none" for None, "true"/"false")."""
    tp = _field_type(name)
    args = get_args(tp)
    union = get_origin(tp) in (Union, types.UnionType)
    words = [w for a in args if get_origin(a) is Literal for w in get_args(a)] if union else []
    if words:  # a number or a word ("auto")
        if text.strip() in words:
            return text.strip()
        tp = next(a for a in args if get_origin(a) is not Literal)
        args = ()
    optional = union and type(None) in args
    if optional:
        if text.strip().lower() in ("none", "", "null"):
            return None
        tp = next(a for a in args if a is not type(None))
    if tp is bool:
        low = text.strip().lower()
        if low not in ("true", "false", "1", "0", "yes", "no"):
            raise ValueError(f"{name} takes true or false, not {text!r}")
        return low in ("true", "1", "yes")
    if tp is int:
        return int(text)
    if tp is float:
        return float(text)
    if get_origin(tp) is Literal:
        if text not in get_args(tp):
            raise ValueError(f"{name} takes one of {get_args(tp)}, not {text!r}")
        return text
    if tp is str:
        return text
    raise ValueError(f"{name} ({tp}) cannot be set from the command line")


def parse_settings(items: Iterable[str]) -> dict[str, str]:
    """``["name=value", ...]`` as a dict (values still text)."""
    out: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ValueError(f"a setting is 'name=value', got {item!r}")
        part_of(key.strip())
        out[key.strip()] = value.strip()
    return out


_TODAY = Profile(
    name="today",
    summary="this project's defaults: birth/survival and extent redraw every sub-step T_f, "
            "fronts ignite anywhere, any active region within d_safe fails the mission",
    sources=(
        "Sec. IV: 'we set the firefront propagation time to T_f = 0.5 s ... we propagate the "
        "firefronts ⌈T_s/T_f⌉ times in sequence' — read as: every sub-step is a full step of "
        "the process of Sec. II-B (birth, survival, motion, a new extent).",
        "Sec. IV-A: 'the birth density b_t(.) is uniform inside the environment' — fronts may "
        "ignite on the UAV.",
        "Sec. IV: 'check whether the distance between the propagated firefronts and the agent's "
        "idle position ... has dropped below d_safe' — read as: any active region.",
        "Sec. III-C: 'the location of the nearest firefront' → d_t to the nearest active "
        "region (a birth-step-only d_t makes ξ₁ a one-step spike, against Fig. r1(g), where "
        "ξ₁ stays high for about 20 steps).",
        "Sec. IV-A: 'The UAV agent can reach a maximum velocity of 15m/s, utilizing an input "
        "control force in the range of [-7.5,7.5]N' — read like the force, per axis: "
        "speed_limit = axis (≈ 21.2 m/s on a diagonal).",
    ),
)

_LITERAL = Profile(
    name="literal",
    fire=FireParams(life_base="step", extent="step"),
    mission=MissionParams(d_t_reading="newborn", failure_rule="become"),
    dynamics=DynamicsParams(speed_limit="norm"),
    summary="the most literal reading of Sec. II-B/IV: birth and survival once per time-step, "
            "the extent drawn per time-step, d_t to the fronts that emerged at t, failure when "
            "the distance becomes less than d_safe; fronts ignite anywhere; the speed limit "
            "bounds |v|",
    sources=(
        "Sec. II-B: 'at each time step t, a stochastic number N_t of firefronts emerge' and "
        "'p_s is the probability that the firefront propagates to the next time-step' → "
        "life_base = step.",
        "Sec. IV-A: 'the extend (i.e., size) of each firefront at each time-step is represented "
        "as a rectangle with dimensions uniformly sampled from the range [100,250] m' → "
        "extent = step.",
        "Sec. IV-A: 'the birth density b_t(.) is uniform inside the environment' → no "
        "ignition clearance.",
        "Sec. III-C: 'the location of the nearest firefront, ŷ_t, which emerged at time-step t' "
        "→ d_t_reading = newborn.",
        "Sec. IV: 'the distance between the agent and a newly emerged firefront becomes less "
        "than ... d_safe' and '... has dropped below d_safe' → failure_rule = become.",
        "Sec. IV: 'Before transitioning the agent to the next state, we propagate the "
        "firefronts ⌈T_s/T_f⌉ times' → no fire motion while the UAV flies.",
        "Sec. IV-A: 'The UAV agent can reach a maximum velocity of 15m/s, utilizing an input "
        "control force in the range of [-7.5,7.5]N' → speed_limit = norm (a maximum velocity "
        "is a speed, |v| ≤ 15 m/s; the force, a range, stays per axis).",
    ),
)

_FIG_R5 = Profile(
    name="fig-r5",
    fire=FireParams(life_base="step", extent="birth"),
    mission=MissionParams(ignition_clearance_m=20.0),
    summary="the reading closest to Fig. r5 (CC/S1/S2 98.5/95.0/96.0 % on 200 missions, "
            "seed 0, paper timing): "
            "birth and survival once per time-step, the extent drawn once at birth, no front "
            "ignites within 20 m (d_safe) of the UAV",
    sources=(
        "Sec. II-B: 'p_s is the probability that the firefront propagates to the next "
        "time-step' → life_base = step.",
        "Sec. II-B: 'a firefront Y_t occupies a distinct volume ... a time-varying rectangular "
        "cuboid C_t' — read as one front, one rectangle that moves → extent = birth.",
        "Sec. IV: 'A mission is considered failed if the agent is trapped by a firefront' — a "
        "front igniting on the UAV traps no one, it ends the mission by chance: "
        "ignition_clearance_m = d_safe.",
        "Sec. IV: 'approximately 40% of the missions using System 2 ..., compared to around 95% "
        "with System 1 ... CC ... around 90%' — the target; this profile comes closest on S1 "
        "and CC, no reading found brings S2 down to 40 % with S1 at 95 % (docs/results.md).",
    ),
)

_TODAY_3D = replace(
    _TODAY,
    name="today-3d",
    dynamics=DynamicsParams(dim=3),
    summary="today's readings in the paper's three dimensions: Eq. (1) with 3×3 blocks, an "
            "altitude band of 20-120 m above ground, start and G_o at 50 m, the goal box over "
            "the whole band, each front a cuboid taller than the ceiling on the paper's "
            "process (the top-down evaluation's numbers) and as tall as its fire's plume on "
            "a fire-behaviour scenario",
    sources=_TODAY.sources + (
        "Sec. II-A: 'a UAV agent ... is operating within a bounded 3D stochastic disaster "
        "environment E ⊂ R³' and 'x_t ∈ X ⊂ R⁶' → dim = 3.",
        "Sec. IV: 'we demonstrate our results in a top-down view (i.e., 2-dimensional "
        "settings)' and 'the UAV agent evolves (assuming a fixed altitude)' → the start and "
        "G_o at one altitude, 50 m, the altitude of the stack's 2-D missions.",
        "Sec. II-B: 'a time-varying rectangular cuboid C_t, characterized by its dynamically "
        "changing dimensions', whose height Sec. IV-A never draws ('a rectangle with "
        "dimensions uniformly sampled from the range [100,250]m') → fire_height = auto: "
        "taller than the ceiling on the paper's process, so that a 3-D mission is the "
        "top-down one; the plume's height on a fire-behaviour scenario.",
        "The paper gives 𝓔 no height → the band: the EU open category's ceiling, '120 m "
        "from the closest point of the surface of the earth' (Regulation (EU) 2019/947, "
        "UAS.OPEN.010), and a floor of d_safe = 20 m above the ground.",
        "Sec. IV: 'the goal region G is represented as a rectangular region centered at "
        "G_o' → goal_vertical = band: every altitude of the band above the rectangle is in "
        "G.",
        "Sec. III-A: System 1 is 'the human process of creating a safe path', 'rooted in "
        "human intuition', and Sec. IV flies it 'assuming a fixed altitude' → s1_altitude "
        "= slice-first: System 1 plans at the UAV's altitude and climbs only when the "
        "fires leave no path there.",
        "The paper's planners have no forecast (the risk-aware variants are this project's, "
        "dualpilot/model/risk.py) and Sec. II-B's cuboids have no height on the paper's "
        "process → risk_zone_height = band: a forecast risk zone is as tall as every "
        "altitude (its footprint against the ground track), the conservative reading; "
        "'fire' gives a zone the height of the fires it forecasts.",
    ),
)

PROFILES: dict[str, Profile] = {p.name: p for p in (_TODAY, _LITERAL, _FIG_R5, _TODAY_3D)}


def get_profile(name: str) -> Profile:
    """The profile called ``name``."""
    try:
        return PROFILES[name]
    except KeyError:
        raise ValueError(f"unknown profile {name!r}; known: {', '.join(PROFILES)}") from None


def profile_table() -> str:
    """The profiles' readings side by side (text), then their sources."""
    names = list(PROFILES)
    rows = [("parameter", *names)]
    for key in READINGS:
        rows.append((key, *(str(PROFILES[n].readings()[key]) for n in names)))
    base = PROFILES["today"].values()
    for key, v in base.items():
        if key in READINGS:
            continue
        if any(PROFILES[n].values()[key] != v for n in names):
            rows.append((key, *(str(PROFILES[n].values()[key]) for n in names)))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    for n in names:
        p = PROFILES[n]
        lines += ["", f"{n}: {p.summary}"] + [f"  - {s}" for s in p.sources]
    return "\n".join(lines)
