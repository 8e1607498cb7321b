"""summary.json's numbers: success rates with Wilson intervals, means with normal intervals."""

from __future__ import annotations

import math

import numpy as np

from dualpilot.mission.config import controller_names


def wilson_interval(successes: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95 % Wilson score interval of a success rate."""
    if n == 0:
        return (float("nan"), float("nan"))
    p = successes / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return (centre - half, centre + half)


def mean_interval(values: list[float], z: float = 1.96) -> tuple[float, float, float]:
    """Mean and its 95 % normal-approximation interval."""
    if not values:
        return (float("nan"), float("nan"), float("nan"))
    arr = np.asarray(values, dtype=float)
    m = float(arr.mean())
    half = z * float(arr.std(ddof=1)) / math.sqrt(len(arr)) if len(arr) > 1 else 0.0
    return (m, m - half, m + half)


def summarize(
    rows: list[dict[str, str]], missions: int, timing: str, wall_s: float = float("nan")
) -> dict[str, object]:
    """summary.json: per controller success rate, mission time, energy, planning time, with CIs."""
    result: dict[str, object] = {"missions": missions, "timing": timing, "wall_s": wall_s}
    ctrl: dict[str, object] = {}
    for c in dict.fromkeys([*controller_names(), *(r["controller"] for r in rows)]):
        rs = [r for r in rows if r["controller"] == c]
        if not rs:
            continue
        ok = [r for r in rs if r["success"] == "1"]
        lo, hi = wilson_interval(len(ok), len(rs))
        t_mean, t_lo, t_hi = mean_interval([float(r["mission_time_s"]) for r in ok])
        e_mean, e_lo, e_hi = mean_interval([float(r["energy"]) for r in ok])
        plan_t = [float(r["planning_time_s_median"]) for r in rs if r["planning_time_s_median"]]
        causes: dict[str, int] = {}
        for r in rs:
            if r["success"] != "1":
                causes[r["failure_cause"]] = causes.get(r["failure_cause"], 0) + 1
        ctrl[c] = {
            "n": len(rs),
            "success_rate": len(ok) / len(rs),
            "success_rate_ci95": [lo, hi],
            "mission_time_s_mean": t_mean,
            "mission_time_s_ci95": [t_lo, t_hi],
            "energy_mean": e_mean,
            "energy_ci95": [e_lo, e_hi],
            "planning_time_s_median": float(np.median(plan_t)) if plan_t else float("nan"),
            "fire_substeps_per_step": float(
                np.sum([float(r.get("fire_substeps") or 0.0) for r in rs])
                / max(1.0, float(np.sum([max(1.0, float(r["steps"] or 0.0)) for r in rs])))),
            "switches_mean": float(np.mean([float(r["switches"]) for r in ok])) if ok else 0.0,
            "switch_energy_mean": float(np.mean([float(r.get("switch_energy") or 0.0)
                                                 for r in ok])) if ok else 0.0,
            "errors": sum(1 for r in rs if r["error"]),
            "failure_causes": causes,
            **tracking_summary(rs),
        }
    result["controllers"] = ctrl
    return result


def tracking_summary(rows: list[dict[str, str]]) -> dict[str, object]:
    """The plant's flights: missions lost to a ``tracking_breach`` (d_safe kept by the plan,
    not by the flight), and the median over missions of their tracking error's p50 and p99
    (m; nan when no row has one: rows written before the columns existed)."""
    p50 = [float(v) for r in rows if (v := r.get("tracking_error_p50_m"))]
    p99 = [float(v) for r in rows if (v := r.get("tracking_error_p99_m"))]
    return {
        "tracking_breaches": sum(1 for r in rows if r.get("tracking_breach") == "1"
                                 or r.get("failure_cause") == "tracking_breach"),
        "tracking_error_p50_m_median": float(np.median(p50)) if p50 else float("nan"),
        "tracking_error_p99_m_median": float(np.median(p99)) if p99 else float("nan"),
        "tracking_error_p99_m_max": float(np.max(p99)) if p99 else float("nan"),
    }
