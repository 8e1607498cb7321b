"""The oracle in 3-D where every front is taller than the band: the planar oracle, lifted.

docs/three_d.md §9: "when every region of the known future spans the band (every
cuboid's top ≥ the ceiling: a UAV in the band is never above one, so every distance is
planar) and start and G_o are at one altitude, the planar stages run as today (same
verdicts, same witnesses, lifted)". Whether a mission is such is decided from its
configuration before it starts (fronts appear during a mission), by its height reading
(:class:`~dualpilot.model.fire_height.FireHeightParams`):

* a front's lowest possible top: ``"above-ceiling"`` the ceiling + ε
  (:attr:`~dualpilot.spec.MissionSpec.above_ceiling_m`), ``"uniform"`` its
  ``fire_height_min_m``; ``"plume"`` follows the fire and has no such bound;
* the highest a UAV can be: the ceiling (every plan the run-time monitor passes keeps it,
  ± its ``area_tol_m``) plus what braking from the speed limit adds past a bound
  (:func:`~dualpilot.mission.braking.braking_overshoot_m`, 19.86 m at the paper's values).

When the top is at least that high no position any controller holds is above a cuboid,
every distance of the mission step (d_safe, the ignition keep-out, the failure rules) is
the planar one, and the 2-D certificate (reach sets per axis, Eq. (1)'s axes being
independent) speaks for the 3-D flights too; its goal (G's rectangle) contains the goal
box's footprint. The planar search's witness, flown at the start's altitude with no
vertical velocity or force, is a 3-D trajectory of Eq. (1) (docs/three_d.md, "The 2-D case
and the consistency test", 1), and it is flown through the 3-D mission step to be believed.

Every other 3-D mission (:func:`not_reduced` says why) is judged over the band: the
certificate's columns (:mod:`~dualpilot.oracle.columns`) and the 3-D lattice
(:mod:`~dualpilot.oracle.search3`).
"""

from __future__ import annotations

import numpy as np

from dualpilot.mission.braking import braking_overshoot_m
from dualpilot.mission.config import MissionConfig
from dualpilot.mission.monitor import MonitorParams
from dualpilot.model.altitude import lift_controls, lift_state
from dualpilot.oracle.search import Witness

__all__ = ["highest_uav_m", "lift", "lowest_top_m", "not_reduced", "planar_twin"]


def lowest_top_m(config: MissionConfig) -> float | None:
    """The lowest top (m above ground) a front of ``config``'s 3-D mission can have under its
    height reading; None when the reading bounds none ("plume": the fire's own)."""
    reading = config.reading()
    heights = reading.altitude.heights
    resolved = heights.resolved(reading.fire.scenario)
    if resolved == "above-ceiling":
        return config.spec().above_ceiling_m
    if resolved == "uniform":
        return heights.fire_height_min_m
    return None


def highest_uav_m(config: MissionConfig) -> float:
    """The highest (m above ground) a UAV of ``config``'s 3-D mission can be: the ceiling and
    the monitor's allowance, plus braking's overshoot from the speed limit (module docstring)."""
    spec = config.spec()
    return (spec.band.ceiling_m + MonitorParams().area_tol_m
            + braking_overshoot_m(spec.dynamics))


def not_reduced(config: MissionConfig) -> str:
    """Why ``config``'s 3-D mission does not reduce to the plane ("" when it does, and for a
    planar mission): a front may be lower than a UAV can fly, or the start and G_o are at
    different altitudes."""
    spec = config.spec()
    if spec.dim == 2:
        return ""
    why = []
    top, high = lowest_top_m(config), highest_uav_m(config)
    reading = config.reading().altitude.heights
    if top is None:
        why.append(f"fire_height={reading.resolved(config.reading().fire.scenario)} gives "
                   "fronts lower than the band")
    elif top < high:
        why.append(f"fire_height={reading.fire_height} lets a front's top ({top:g} m) be "
                   f"lower than a UAV can fly ({high:.2f} m: the ceiling and braking's "
                   "overshoot)")
    if spec.band.start_altitude_m != spec.band.goal_z_m:
        why.append(f"the start ({spec.band.start_altitude_m:g} m) and G_o "
                   f"({spec.band.goal_z_m:g} m) are at different altitudes")
    return " and ".join(why)


def planar_twin(config: MissionConfig) -> MissionConfig:
    """``config`` itself in 2-D; in 3-D the same mission in 2-D (its seed, geometry and
    reading with ``dim`` = 2: the same fire stream, so the same rectangles)."""
    if config.spec().dim == 2:
        return config
    return config.with_settings({"dim": 2})


def lift(witness: Witness, config: MissionConfig) -> Witness:
    """``witness`` as a trajectory of ``config``'s mission: itself in 2-D; in 3-D flown at the
    start's altitude with no vertical velocity or force."""
    spec = config.spec()
    if spec.dim == 2:
        return witness
    z = spec.band.start_altitude_m
    states = np.array([lift_state(x, z) for x in witness.states])
    return Witness(states, lift_controls(witness.controls))
