"""What each navigation state flies: the target of Eq. (1) and of the altitude, step by step.

On the vehicle's own clock (``--clock realtime``) :meth:`Navigator.step` is
one ΔT of flight for the state the commander flies (services/uavsim/commander.py):

* OFFBOARD: the companion's newest setpoint [p*, v*] (its z: the altitude);
* HOLD: where the state began, or a reposition target (DO_REPOSITION);
* TAKEOFF: up to the take-off altitude where the vehicle is;
* LAND: down where the state began, the last MPC_LAND_ALT2 m at MPC_LAND_SPEED;
* RETURN: up to RTL_RETURN_ALT (if lower), home at the cruise speed, then Land;
* MISSION: the uploaded items (services/uavsim/missionrun.py);
* POSITION: the sticks (MANUAL_CONTROL) as velocities, MPC_VEL_MANUAL at full deflection.

A point is approached at the cruise speed (``MPC_XY_CRUISE``; DO_CHANGE_SPEED
and a reposition's ground speed change it) by steering Eq. (1) to the
velocity that closes half the distance each second, at most the cruise
speed (:func:`approach`). The vehicle moves horizontally only in the air.

In lockstep (``--clock lockstep``, the stack) the companion's stamps are the
only clock: a new setpoint is one step of Eq. (1) (:meth:`Navigator.fly_setpoint`),
the altitude is SIM_ALT_M in the air (Sec. IV is 2-D) or, flying a 3-D Eq. (1)
(a mission of ``dim=3``), the state's own p_z, a take-off and a
landing are instantaneous, and states that need flight time cannot run.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from dualpilot.model.dynamics import Array
from services.common import mav

from .flavour import Nav
from .missionrun import Frame, Goal, MissionRun
from .params import Parameters
from .vehicle import Vehicle

#: full stick deflection (MANUAL_CONTROL ±1000) in POSITION, m/s (PX4's MPC_VEL_MANUAL)
VEL_MANUAL_MPS = 10.0
#: the vehicle counts as on the ground at or below this height, m
GROUND_M = 0.01


def approach(x: Array, goal: tuple[float, float], speed: float, dt_s: float) -> Array:
    """The Eq. (1) target [p*, v*] that flies state ``x`` towards ``goal`` (m east, north) at
    most ``speed`` m/s: the velocity closing half the distance in ΔT, capped."""
    p = np.asarray(x[:2], dtype=float)
    d = np.asarray(goal, dtype=float) - p
    dist = float(np.hypot(*d))
    if dist < 1e-9:
        return np.array([goal[0], goal[1], 0.0, 0.0])
    v = d / dist * min(speed, 0.5 * dist / dt_s)
    return np.concatenate([p + v * dt_s, v])


@dataclass
class Events:
    """What happened in a step, for the commander and the ground station."""

    done: Nav | None = None  #: this state's job is done
    reached: list[int] | None = None  #: mission items reached
    rtl: bool = False  #: the mission asks to return
    touchdown: bool = False  #: the vehicle has just landed


class Navigator:
    """The targets of the state flown (module docstring)."""

    def __init__(self, vehicle: Vehicle, params: Parameters, home: tuple[float, float],
                 frame: Frame, own_clock: bool,
                 mission_items: Callable[[], list[mav.MissionItem]]):
        self.v = vehicle
        self.p = params
        self.home = home  #: m east, north
        self.frame = frame
        self.own_clock = own_clock
        self.mission_items = mission_items
        self.in_air_lockstep = False
        self.setpoint: tuple[Array, float] | None = None  #: offboard: [p*, v*], altitude
        self.flown_offboard = False  #: a setpoint flew the vehicle since OFFBOARD began
        self.goal = Goal(float(vehicle.state[0]), float(vehicle.state[1]), 0.0)
        self.speed = params["MPC_XY_CRUISE"]
        self.takeoff_alt = params["MIS_TAKEOFF_ALT"]
        self.returning_home = False
        self.mission: MissionRun | None = None
        self.sticks = (0.0, 0.0, 500.0)  #: MANUAL_CONTROL x, y, z

    # -- where the vehicle is ------------------------------------------------------------------
    @property
    def alt(self) -> float:
        if self.own_clock:
            return self.v.alt_m
        if not self.in_air_lockstep:
            return 0.0
        return float(self.v.state[2]) if self.v.dyn.dim == 3 else self.p["SIM_ALT_M"]

    @property
    def landed(self) -> bool:
        if self.own_clock:
            return self.v.alt_m <= GROUND_M and self.v.vz_mps <= 0.0
        return not self.in_air_lockstep

    def here(self) -> Goal:
        return Goal(float(self.v.state[0]), float(self.v.state[1]), self.alt)

    # -- entering a state ----------------------------------------------------------------------
    def enter(self, nav: Nav, brake: bool = True, mission_seq: int = 0) -> None:
        """Set the targets of ``nav`` from where the vehicle is (``brake``: stop at once, a
        multirotor's position hold; the lockstep failsafe holds as it is)."""
        self.goal = self.here()
        self.speed = self.p["MPC_XY_CRUISE"]
        if nav is Nav.OFFBOARD:
            self.flown_offboard = False
        elif nav is Nav.HOLD and brake:
            self.v.brake()
        elif nav is Nav.TAKEOFF:
            self.goal = Goal(self.goal.east, self.goal.north, max(self.alt, self.takeoff_alt))
            self.in_air_lockstep = True
        elif nav is Nav.LAND:
            self.goal = Goal(self.goal.east, self.goal.north, 0.0)
            if not self.own_clock:
                self.v.brake()
                self.in_air_lockstep = False
        elif nav is Nav.RETURN:
            self.returning_home = False
            self.goal = Goal(self.goal.east, self.goal.north,
                             max(self.alt, self.p["RTL_RETURN_ALT"]))
        elif nav is Nav.MISSION:
            self.mission = MissionRun(self.mission_items(), self.frame, self.p["MIS_ACC_RAD"],
                                      self.p["MIS_TAKEOFF_ALT"])
            self.mission.start(mission_seq, self.here(), self.landed)

    def reposition(self, east: float | None, north: float | None, alt: float | None,
                   speed: float | None) -> None:
        """A new goal for HOLD (ArduPilot: GUIDED); None keeps that coordinate."""
        here = self.here()
        self.goal = Goal(here.east if east is None else east,
                         here.north if north is None else north, here.alt if alt is None else alt)
        if speed is not None and speed > 0:
            self.speed = min(speed, self.p["MPC_XY_VEL_MAX"])
        self.setpoint = None  # GUIDED flies the reposition, not an old setpoint

    def armed_in(self, nav: Nav) -> None:
        """Armed while flying ``nav``: offboard control takes off at once in lockstep (2-D)."""
        if not self.own_clock and nav is Nav.OFFBOARD:
            self.in_air_lockstep = True

    def disarmed(self) -> None:
        self.v.brake()
        self.in_air_lockstep = False
        if self.own_clock:
            self.v.alt_m = 0.0

    # -- lockstep ------------------------------------------------------------------------------
    def fly_setpoint(self, target: Array, due_ms: int) -> bool:
        """Lockstep: one step of Eq. (1) towards a new setpoint; True if the vehicle moved."""
        moved = self.v.apply(target, due_ms)
        self.flown_offboard = self.flown_offboard or moved
        return moved

    # -- on the vehicle's own clock ------------------------------------------------------------
    def step(self, nav: Nav, armed: bool, due_ms: int) -> Events:
        """One ΔT of flight of ``nav`` ending at ``due_ms`` (the clock runs when disarmed too)."""
        if not armed:
            self.v.time_ms = due_ms
            return Events()
        was_landed = self.landed
        target, alt, ev = self._targets(nav)
        self.v.climb(alt, self.p["MPC_Z_VEL_MAX_UP"], self._sink_rate(nav))
        if self.v.alt_m > GROUND_M:
            self.v.apply(target, due_ms)
            self.flown_offboard = self.flown_offboard or nav is Nav.OFFBOARD
        else:
            self.v.brake()
            self.v.time_ms = due_ms
        ev.touchdown = self.landed and not was_landed
        return ev

    def _sink_rate(self, nav: Nav) -> float:
        if nav is Nav.LAND and self.v.alt_m <= self.p["MPC_LAND_ALT2"]:
            return self.p["MPC_LAND_SPEED"]
        return self.p["MPC_Z_VEL_MAX_DN"]

    def _targets(self, nav: Nav) -> tuple[Array, float, Events]:
        """The horizontal target, the altitude target and the events of this step."""
        dt = self.v.dyn.dt_s
        x = self.v.state
        if nav is Nav.OFFBOARD and self.setpoint is not None:
            return self.setpoint[0], self.setpoint[1], Events()
        if nav is Nav.RETURN:
            return self._return(x, dt)
        if nav is Nav.MISSION:
            return self._mission(x, dt)
        if nav is Nav.POSITION:
            return self._sticks(x, dt)
        ev = Events()
        if nav is Nav.TAKEOFF and abs(self.v.alt_m - self.goal.alt) < 0.5:
            ev.done = Nav.TAKEOFF
        return approach(x, (self.goal.east, self.goal.north), self.speed, dt), self.goal.alt, ev

    def _return(self, x: Array, dt: float) -> tuple[Array, float, Events]:
        """Climb to the return altitude, then fly home; done there."""
        ev = Events()
        if not self.returning_home and self.v.alt_m >= self.goal.alt - 0.5:
            self.returning_home = True
            self.goal = Goal(*self.home, self.goal.alt)
        if (self.returning_home and math.hypot(x[0] - self.home[0], x[1] - self.home[1]) < 0.5
                and math.hypot(x[2], x[3]) < 0.5):  # over home, slowed: land there
            ev.done = Nav.RETURN
        return approach(x, (self.goal.east, self.goal.north), self.speed, dt), self.goal.alt, ev

    def _mission(self, x: Array, dt: float) -> tuple[Array, float, Events]:
        assert self.mission is not None
        step = self.mission.step(self.here(), dt)
        if step.speed is not None:
            self.speed = min(step.speed, self.p["MPC_XY_VEL_MAX"])
        ev = Events(done=Nav.MISSION if step.done else None, reached=step.reached, rtl=step.rtl)
        g = step.goal
        alt = 0.0 if step.landing else g.alt
        return approach(x, (g.east, g.north), self.speed, dt), alt, ev

    def _sticks(self, x: Array, dt: float) -> tuple[Array, float, Events]:
        """POSITION: pitch (x) flies north, roll (y) east, throttle (z) climbs (500: hold)."""
        sx, sy, sz = self.sticks
        v = np.array([sy, sx]) / 1000.0 * VEL_MANUAL_MPS
        climb = (sz - 500.0) / 500.0 * self.p["MPC_Z_VEL_MAX_UP"] * dt
        self.goal = Goal(self.goal.east, self.goal.north, max(0.0, self.v.alt_m + climb))
        p = np.asarray(x[:2], dtype=float)
        return np.concatenate([p + v * dt, v]), self.goal.alt, Events()
