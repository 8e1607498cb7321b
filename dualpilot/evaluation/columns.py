"""The columns of ``results.csv`` a mission fills: a flight's, or the oracle's verdict."""

from __future__ import annotations

import numpy as np

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.result import Ending, MissionResult
from dualpilot.oracle.oracle import FEASIBLE, OracleParams, solve
from dualpilot.readings import Profile


def flight_columns(result: MissionResult, reading: Profile) -> dict[str, object]:
    """The columns of :data:`COLUMNS` a flown mission fills."""
    times = result.planning_time_s["s1"] + result.planning_time_s["s2"]
    return dict(
        success=int(result.success), failure_cause=result.failure_cause,
        steps=result.steps, mission_time_s=result.mission_time_s,
        energy=round(result.energy, 6), switches=result.switches,
        switch_energy=round(result.switch_energy, 6),
        fire_substeps=sum(r.fire_substeps for r in result.records)
        + reading.mission.fire_substeps_per_motion * result.steps,
        s1_plans=len(result.planning_time_s["s1"]),
        s2_plans=len(result.planning_time_s["s2"]),
        planning_time_s_median=float(np.median(times)) if times else "",
        planning_time_s_p95=float(np.percentile(times, 95)) if times else "",
        planning_time_s_total=float(np.sum(times)),
        **tracking_columns(result, reading),
    )


def tracking_columns(result: MissionResult, reading: Profile) -> dict[str, object]:
    """Whether the flight breached d_safe where its plan did not (``tracking_breach``), and
    the p50 / p99 of its horizontal tracking error (m) over every integration step: 0 for
    the ideal plant (the flight is the plan), "" when nothing was flown."""
    breach = int(result.ending is Ending.TRACKING_BREACH)
    if reading.plant.plant == "ideal":
        return dict(tracking_breach=breach, tracking_error_p50_m=0.0, tracking_error_p99_m=0.0)
    tracked = result.tracking_percentiles()
    if tracked is None:
        return dict(tracking_breach=breach, tracking_error_p50_m="", tracking_error_p99_m="")
    return dict(tracking_breach=breach, tracking_error_p50_m=tracked[0],
                tracking_error_p99_m=tracked[1])


def oracle_columns(config: MissionConfig, params: OracleParams = OracleParams()
                   ) -> dict[str, object]:
    """The results.csv columns of the oracle's verdict on ``config``'s mission."""
    verdict = solve(config, params)
    if verdict.flight is not None:
        cols = flight_columns(verdict.flight, config.reading())
    else:
        cert = verdict.certificate
        cols = dict(success=0, steps=0, mission_time_s="", energy="", switches=0,
                    switch_energy=0, fire_substeps=cert.substeps if cert else 0, s1_plans=0,
                    s2_plans=0, planning_time_s_median="", planning_time_s_p95="",
                    planning_time_s_total=0.0, tracking_breach=0, tracking_error_p50_m="",
                    tracking_error_p99_m="")
    cols["failure_cause"] = "" if verdict.verdict == FEASIBLE else verdict.verdict
    if verdict.problem:
        cols["error"] = verdict.problem
    return cols


