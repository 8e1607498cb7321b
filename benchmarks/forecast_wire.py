"""What the forecast costs on the wire: plan-request bytes and codec time with and without it,
and the forecast's compute per step.

    .venv/bin/python benchmarks/forecast_wire.py --scenario grass-15 --seeds 0-4

Flies each seed in-process with a risk-aware controller (``--controller``, default
``concurrent+risk``); every plan request a step makes is encoded as the stack encodes
it (services/common/convert/plan.py: the grid's slices zlib-compressed), once with its
forecast and once without, then decoded and checked as a planner service does. The
forecast's compute is the fire port's (the EWS runs the same function,
dualpilot/model/field_forecast.py), timed per call. Prints p50 and p99 of each and the
ratios, measured in this one run.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from typing import Any

import harness  # noqa: F401  (the repository on the path: before its packages)
import numpy as np

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import local_mission
from dualpilot.mission.ports import PlanRequest
from services.common import wire
from services.common.convert import plan as plan_convert
from services.msgs import plan_pb2

STAMP = wire.Stamper("supervisor", "bench")


def parse_seeds(text: str) -> list[int]:
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def codec(req: PlanRequest, seq: int) -> tuple[int, float]:
    """(bytes, s to encode, serialize, parse and decode) of one plan request."""
    t0 = time.perf_counter()
    msg = plan_convert.plan_query_msg(plan_convert.PlanQuery(req, "m", seq, 30.0), STAMP, 0.0)
    payload = msg.SerializeToString()
    plan_convert.plan_request_from_msg(wire.parse(payload, plan_pb2.PlanRequest))
    return len(payload), time.perf_counter() - t0


def fly(config: MissionConfig, out: dict[str, list[float]]) -> None:
    mission = local_mission(config)
    ask, fires = mission.planners.plan, mission.fires
    forecast = fires.forecast  # type: ignore[attr-defined]

    def timed_forecast(n: int) -> Any:
        t0 = time.perf_counter()
        fc = forecast(n)
        out["forecast_s"].append(time.perf_counter() - t0)
        return fc

    def plan(request: PlanRequest) -> Any:
        if request.forecast is not None:
            n, s = codec(request, request.t)
            out["bytes_risk"].append(n)
            out["codec_risk_s"].append(s)
            n, s = codec(dataclasses.replace(request, forecast=None), request.t)
            out["bytes_plain"].append(n)
            out["codec_plain_s"].append(s)
        return ask(request)

    fires.forecast = timed_forecast  # type: ignore[attr-defined]
    mission.planners.plan = plan  # type: ignore[method-assign]
    mission.run()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", default="grass-15")
    ap.add_argument("--seeds", default="0-4")
    ap.add_argument("--controller", default="concurrent+risk")
    args = ap.parse_args()
    out: dict[str, list[float]] = {k: [] for k in (
        "bytes_risk", "bytes_plain", "codec_risk_s", "codec_plain_s", "forecast_s")}
    for seed in parse_seeds(args.seeds):
        settings = (("scenario", args.scenario),) if args.scenario else ()
        fly(MissionConfig.named(args.controller, seed=seed, settings=settings), out)
    print(f"{args.controller} on {args.scenario or 'today'}, seeds {args.seeds}: "
          f"{len(out['bytes_risk'])} plan requests, {len(out['forecast_s'])} forecasts")
    for key in out:
        v = np.asarray(out[key], dtype=float)
        if not len(v):
            continue
        scale, unit = (1e3, "ms") if key.endswith("_s") else (1e-3, "kB")
        p50, p99 = np.percentile(v, [50, 99]) * scale
        print(f"  {key:14s} p50 {p50:9.3f} {unit}   p99 {p99:9.3f} {unit}")
    for a, b in (("bytes_risk", "bytes_plain"), ("codec_risk_s", "codec_plain_s")):
        if out[a]:
            print(f"  {a} / {b}: {np.median(out[a]) / np.median(out[b]):.1f}x (medians)")


if __name__ == "__main__":
    main()
