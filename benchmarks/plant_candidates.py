"""Candidate plants for the multirotor: speed, fidelity and determinism (docs/plant.md).

Runs each candidate on the same flights: a 10 m position step, a 1 s Eq. (1)
segment flown from steady flight at 10 m/s, an acceleration beyond the tilt
limit, and a 60 s flight for the wall time per simulated second at 100 and
200 Hz. RotorPy, JSBSim and PyFlyt (speed only) are not project dependencies: run
this in a scratch environment that has them (``pip install rotorpy==3.0.0
jsbsim==1.3.3 torch==2.13.0 pyflyt==0.29.0`` beside the project's pins; PyFlyt
brings numpy 1.26), from the repository root::

    PYTHONPATH=. VENV/bin/python benchmarks/plant_candidates.py

A candidate whose package is missing is reported as such. Prints one JSON document.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit

from dualpilot.model.dynamics import DynamicsParams, step
from dualpilot.plant.multirotor import (
    B3,
    STATE_LEN,
    VPREV,
    V,
    _control,
    fly,
    hover_vector,
    pack,
)
from dualpilot.plant.params import GRAVITY_MPS2, MultirotorParams
from dualpilot.plant.setpoints import hermite_stream, segment_path

ALT_M = 50.0
#: A flight: (setpoints (S, 9) at 20 Hz, duration (s), initial position (m) and velocity (m/s),
#: ENU, integration rate (Hz)) -> path (N+1, 6) of [p, v]
Flyer = Callable[[np.ndarray, float, np.ndarray, np.ndarray, float], np.ndarray]
ORIGIN = np.array([0.0, 0.0, ALT_M])


def step_setpoints(seconds: float) -> np.ndarray:
    sp = np.zeros((int(seconds * 20), 9))
    sp[:, 0], sp[:, 2] = 10.0, ALT_M
    return sp


def segment_case() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """1 s of Eq. (1) from (0, 0) at 10 m/s east with u = (−7.5, 7.5) N, after 5 s of steady
    flight along the same line; returns setpoints, the times of the segment and its path."""
    dyn = DynamicsParams()
    steady = np.zeros((100, 9))
    t = np.arange(100) / 20.0
    steady[:, 0] = -50.0 + 10.0 * t
    steady[:, 2] = ALT_M
    steady[:, 3] = 10.0
    x0 = np.array([0.0, 0.0, 10.0, 0.0])
    x1 = step(x0, np.array([-7.5, 7.5]), dyn)
    seg = hermite_stream(x0, x1, 1.0, 20.0, 2, ALT_M)
    times = np.linspace(0.0, 1.0, 101)
    return np.vstack([steady, seg]), times, segment_path(x0, times, 2, ALT_M)


def saturation_setpoints() -> np.ndarray:
    sp = np.zeros((40, 9))
    sp[:, 2] = ALT_M
    sp[:, 6] = 20.0  # 20 m/s² east, twice the tilt limit's g·tan 45°
    return sp


def metrics(fly_fn: Flyer, rate_hz: float) -> dict[str, Any]:
    out: dict[str, Any] = {}
    path = fly_fn(step_setpoints(15.0), 15.0, ORIGIN, np.zeros(3), rate_hz)
    x = path[:, 0]
    t = np.arange(len(x)) / rate_hz
    outside = np.nonzero(np.abs(x - 10.0) > 0.5)[0]
    out["step_overshoot_pct"] = float((x.max() - 10.0) / 10.0 * 100.0)
    out["step_settle_5pct_s"] = float(t[outside[-1] + 1]) if len(outside) else 0.0
    out["step_rise_10_90_s"] = float(t[np.argmax(x >= 9.0)] - t[np.argmax(x >= 1.0)])
    out["step_alt_dev_m"] = float(np.abs(path[:, 2] - ALT_M).max())
    sp, times, ref = segment_case()
    path = fly_fn(sp, 6.0, sp[0, :3], np.array([10.0, 0.0, 0.0]), rate_hz)
    seg = path[int(5 * rate_hz):][: len(times)] if rate_hz == 100 else \
        path[int(5 * rate_hz)::int(rate_hz // 100)][: len(times)]
    err = np.linalg.norm(seg[:, :3] - ref, axis=1)
    out["segment_max_err_m"] = float(err.max())
    out["segment_end_err_m"] = float(err[-1])
    return out


def wall_per_sim_s(fly_fn: Flyer, rate_hz: float, seconds: float = 60.0) -> float:
    sp, _, _ = segment_case()
    sp = np.tile(sp[:20], (int(seconds), 1))
    sp[:, 0] = np.arange(len(sp)) / 20.0 * 10.0 - 50.0
    t0 = time.perf_counter()
    fly_fn(sp, seconds, sp[0, :3], np.array([10.0, 0.0, 0.0]), rate_hz)
    return (time.perf_counter() - t0) / seconds


# --- our own, compiled -------------------------------------------------------------------

def ours(sp: np.ndarray, seconds: float, p0: np.ndarray, v0: np.ndarray,
         rate_hz: float) -> np.ndarray:
    params = MultirotorParams(rate_hz=rate_hz)
    x = hover_vector(p0, v0, params)
    paths = []
    per = int(rate_hz)  # one ΔT per call, as the mission step flies it
    for k in range(int(seconds)):
        chunk = sp[k * 20:(k + 1) * 20]
        paths.append(fly(x, chunk, 0.05, np.zeros((per, 3)), np.zeros((per, 3)), params)[:-1])
    return np.vstack(paths + [x[None, :6]])


def ours_saturation(rate_hz: float) -> dict[str, float]:
    params = MultirotorParams(rate_hz=rate_hz)
    x = hover_vector(np.array([0.0, 0.0, ALT_M]), np.zeros(3), params)
    tilt, thrust = [], []
    sp = saturation_setpoints()
    prm = pack(params)
    for k in range(int(2 * rate_hz)):
        j = min(int(k / rate_hz * 20), len(sp) - 1)
        fly(x, sp[j:j + 1], 1.0, np.zeros((1, 3)), np.zeros((1, 3)), params)
        tilt.append(math.degrees(math.acos(x[B3 + 2])))
        thrust.append(x[12] / prm[1])
    return {"max_tilt_deg": max(tilt), "max_thrust_frac": max(thrust)}


# --- RotorPy ------------------------------------------------------------------------------

def rotorpy_flyer() -> tuple[Flyer, Callable[[int], float]]:
    from rotorpy.controllers.quadrotor_control import SE3Control
    from rotorpy.vehicles.multirotor import Multirotor
    from rotorpy.vehicles.px4_sihsim_quadx_params import quad_params

    def run(sp: np.ndarray, seconds: float, p0: np.ndarray, v0: np.ndarray,
            rate_hz: float) -> np.ndarray:
        hover = math.sqrt(quad_params["mass"] * GRAVITY_MPS2 / (4 * quad_params["k_eta"]))
        state = {"x": p0.astype(float), "v": v0.astype(float),
                 "q": np.array([0.0, 0.0, 0.0, 1.0]), "w": np.zeros(3), "wind": np.zeros(3),
                 "rotor_speeds": np.full(4, hover)}
        vehicle = Multirotor(quad_params, initial_state=state, enable_ground=False)
        ctrl = SE3Control(quad_params)
        dt = 1.0 / rate_hz
        path = [np.concatenate([state["x"], state["v"]])]
        for k in range(int(seconds * rate_hz)):
            s = sp[min(int(k * dt * 20 + 1e-9), len(sp) - 1)]
            flat = {"x": s[:3], "x_dot": s[3:6], "x_ddot": s[6:9], "x_dddot": np.zeros(3),
                    "x_ddddot": np.zeros(3), "yaw": 0.0, "yaw_dot": 0.0, "yaw_ddot": 0.0}
            state = vehicle.step(state, ctrl.update(k * dt, state, flat), dt)
            path.append(np.concatenate([state["x"], state["v"]]))
        return np.array(path)

    def dryden(n: int) -> float:
        from rotorpy.wind.dryden_winds import DrydenGust
        wind = DrydenGust(dt=0.01, avg_wind=np.array([10.0, 0, 0]),
                          sig_wind=np.array([2.5, 2.5, 1.5]), altitude=ALT_M)
        t0 = time.perf_counter()
        for k in range(n):
            wind.update(k * 0.01, np.zeros(3))
        return (time.perf_counter() - t0) / (n * 0.01)

    return run, dryden


# --- JSBSim's F450 under our controller ---------------------------------------------------

FT = 0.3048


def jsbsim_flyer() -> Flyer:
    import jsbsim

    def run(sp: np.ndarray, seconds: float, p0: np.ndarray, v0: np.ndarray,
            rate_hz: float) -> np.ndarray:
        fdm = jsbsim.FGFDMExec(None)
        fdm.set_debug_level(0)
        fdm.load_model("F450")
        fdm.set_dt(1.0 / rate_hz)
        fdm["ic/h-agl-ft"] = p0[2] / FT
        fdm["ic/lat-geod-deg"], fdm["ic/long-gc-deg"], fdm["ic/psi-true-deg"] = 44.7, -93.0, 90.0
        fdm["ic/vn-fps"], fdm["ic/ve-fps"] = v0[1] / FT, v0[0] / FT
        fdm.run_ic()
        fdm["propulsion/set-running"] = -1
        fdm["fcs/ScasEngage"] = 1.0
        lat0, lon0 = fdm["position/lat-geod-rad"], fdm["position/long-gc-rad"]
        params = MultirotorParams(rate_hz=rate_hz)
        prm = pack(params)
        x = np.zeros(STATE_LEN)
        x[V:V + 3] = v0
        x[VPREV:VPREV + 3] = v0
        dt = 1.0 / rate_hz
        names = ["position/long-gc-rad", "position/lat-geod-rad", "position/h-agl-ft",
                 "velocities/v-east-fps", "velocities/v-north-fps", "velocities/v-down-fps",
                 "attitude/phi-rad", "attitude/theta-rad", "attitude/psi-rad"]
        origin = np.array([lon0, lat0, p0[0], p0[1]])
        steps = int(seconds * rate_hz)
        path = np.empty((steps + 1, 6))
        for k in range(steps + 1):
            reads = np.array([fdm[name] for name in names])
            s = sp[min(int(k * dt * 20 + 1e-9), len(sp) - 1)]
            cmd = _jsb_glue(reads, s, x, prm, dt, origin, path[k])
            if k == steps:
                break
            fdm["fcs/aileron-cmd-norm"] = cmd[0]
            fdm["fcs/elevator-cmd-norm"] = cmd[1]
            fdm["fcs/throttle-cmd-norm"] = cmd[2]
            fdm.run()
        return np.array(path)

    return run


def jsbsim_floor(rate_hz: float, seconds: float = 60.0) -> float:
    """JSBSim's F450 alone: wall (s) per simulated second of run() and the 12 reads a
    controller needs, with no controller (the least any loop around it costs)."""
    import jsbsim

    fdm = jsbsim.FGFDMExec(None)
    fdm.set_debug_level(0)
    fdm.load_model("F450")
    fdm.set_dt(1.0 / rate_hz)
    fdm["ic/h-agl-ft"] = ALT_M / FT
    fdm.run_ic()
    fdm["propulsion/set-running"] = -1
    names = ["position/lat-geod-rad", "position/long-gc-rad", "position/h-agl-ft",
             "velocities/v-north-fps", "velocities/v-east-fps", "velocities/v-down-fps",
             "attitude/phi-rad", "attitude/theta-rad", "attitude/psi-rad",
             "velocities/p-rad_sec", "velocities/q-rad_sec", "velocities/r-rad_sec"]
    t0 = time.perf_counter()
    for _ in range(int(seconds * rate_hz)):
        fdm["fcs/throttle-cmd-norm"] = 0.42
        fdm.run()
        for name in names:
            fdm[name]
    return (time.perf_counter() - t0) / seconds


#: the F450's hover throttle, trimmed by hand: it climbs at 0.45 and sinks at 0.40
HOVER_THROTTLE = 0.42


@njit(cache=True)
def _jsb_glue(reads: np.ndarray, sp: np.ndarray, x: np.ndarray, prm: np.ndarray, dt: float,
              origin: np.ndarray, out: np.ndarray) -> np.ndarray:
    """One step of our controller on JSBSim's F450 (one compiled call): local ENU state from
    the reads, PX4's position control, the attitude P as body-rate references for the F450's
    rate loop (``fcs/ScasEngage``, 0.75 rad/s per unit) and the throttle; writes [p, v] to
    ``out`` and returns (aileron, elevator, throttle) commands."""
    r_earth = 6378137.0
    x[0] = (reads[0] - origin[0]) * r_earth * math.cos(origin[1]) + origin[2]
    x[1] = (reads[1] - origin[1]) * r_earth + origin[3]
    x[2] = reads[2] * FT
    x[V], x[V + 1], x[V + 2] = reads[3] * FT, reads[4] * FT, -reads[5] * FT
    out[:3], out[3:] = x[:3], x[V:V + 3]
    thr = _control(x, sp, np.zeros(3), prm, dt)
    rot = _body_to_ned(reads[6], reads[7], reads[8])
    b3 = np.array([-rot[1, 2], -rot[0, 2], rot[2, 2]])
    bd = thr / np.sqrt(np.sum(thr * thr))
    axis = np.cross(b3, bd)
    sn = np.sqrt(np.sum(axis * axis))
    w_enu = np.zeros(3)
    if sn > 1e-12:
        w_enu = axis / sn * min(prm[23] * math.atan2(sn, np.sum(b3 * bd)), prm[24])
    w_body = rot.T @ np.array([w_enu[1], w_enu[0], -w_enu[2]])
    frac = np.sqrt(np.sum(thr * thr)) / prm[21]
    return np.array([min(max(w_body[0] / 0.75, -1.0), 1.0),
                     min(max(w_body[1] / 0.75, -1.0), 1.0),
                     HOVER_THROTTLE * math.sqrt(max(frac, 0.0))])


@njit(cache=True)
def _body_to_ned(phi: float, theta: float, psi: float) -> np.ndarray:
    cf, sf, ct, st, cp, sp = (math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta),
                              math.cos(psi), math.sin(psi))
    return np.array([
        [ct * cp, sf * st * cp - cf * sp, cf * st * cp + sf * sp],
        [ct * sp, sf * st * sp + cf * cp, cf * st * sp - sf * cp],
        [-st, sf * ct, cf * ct],
    ])


def pyflyt_wall_per_sim_s(seconds: float = 20.0) -> float:
    """PyFlyt's QuadX (PyBullet at 240 Hz, its cascade at 120 Hz) holding a position
    setpoint: wall (s) per simulated second; speed only."""
    from PyFlyt.core import Aviary

    env = Aviary(start_pos=np.array([[0.0, 0.0, ALT_M]]), start_orn=np.zeros((1, 3)),
                 render=False, drone_type="quadx", seed=0)
    env.set_mode(7)  # QuadX mode 7: position (x, y), yaw and altitude
    env.set_setpoint(0, np.array([10.0, 0.0, 0.0, ALT_M]))
    t0 = time.perf_counter()
    while env.elapsed_time < seconds:
        env.step()
    return (time.perf_counter() - t0) / env.elapsed_time


def measure(name: str, fly_fn: Flyer, slow: bool) -> dict[str, Any]:
    res: dict[str, Any] = {}
    for rate in (100.0, 200.0):
        seconds = 5.0 if slow else 60.0
        wall = [wall_per_sim_s(fly_fn, rate, seconds) for _ in range(1 if slow else 3)]
        res[f"wall_ms_per_sim_s_{int(rate)}hz"] = 1e3 * float(np.median(wall))
    res.update(metrics(fly_fn, 100.0))
    a = fly_fn(step_setpoints(3.0), 3.0, ORIGIN, np.zeros(3), 100.0)
    b = fly_fn(step_setpoints(3.0), 3.0, ORIGIN, np.zeros(3), 100.0)
    res["deterministic"] = bool(np.array_equal(a, b))
    return res


def main() -> None:
    report: dict[str, Any] = {}
    ours(step_setpoints(1.0), 1.0, ORIGIN, np.zeros(3), 100.0)  # compile (cached on disk)
    report["ours"] = measure("ours", ours, slow=False)
    report["ours"].update(ours_saturation(100.0))
    try:
        run, dryden = rotorpy_flyer()
        report["rotorpy"] = measure("rotorpy", run, slow=True)
        report["rotorpy"]["dryden_ms_per_sim_s_100hz"] = 1e3 * dryden(1000)
    except ImportError as exc:
        report["rotorpy"] = {"missing": str(exc)}
    try:
        report["jsbsim_f450"] = measure("jsbsim", jsbsim_flyer(), slow=False)
        for rate in (100.0, 200.0):
            report["jsbsim_f450"][f"floor_ms_per_sim_s_{int(rate)}hz"] = \
                1e3 * jsbsim_floor(rate)
    except ImportError as exc:
        report["jsbsim_f450"] = {"missing": str(exc)}
    try:
        report["pyflyt"] = {"wall_ms_per_sim_s_240hz": 1e3 * pyflyt_wall_per_sim_s()}
    except ImportError as exc:
        report["pyflyt"] = {"missing": str(exc)}
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
