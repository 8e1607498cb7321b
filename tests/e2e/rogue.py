"""A rogue Zenoh process for tests/e2e/test_attacks.py: ``python -m tests.e2e.rogue MODE``.

Modes (``--uav``, ``--connect`` the router endpoint):

* ``plan-byzantine``: declares ``plan/system2`` and its own replica key
  ``plan/system2/<zid>`` and holds System 2's liveliness tokens (as a real
  replica would), prepares any mission and answers every
  plan request with a well-formed OK plan that is unsafe: it jumps into the
  centre of the nearest obstacle, pushes 9,999 N, or starts 50 km away.
* ``plan-impostor``: answers ``plan/system2/**`` (every replica's key) at once
  beside the real System 2,
  without its token, with a plan that would pass the monitor (it brakes);
  its plans carry ``info.source = "impostor"``.
* ``ews-impostor``: answers ``ews/command`` at once beside the real EWS,
  without its token, with "no fires", and a forecast query with a forecast of
  exactly the step and fire revision asked for that sees no risk anywhere
  (its compute time :data:`FORGED_COMPUTE_S` marks it).
* ``plan-hung``: holds System 2's tokens, prepares, then never answers a plan
  request (and has no status queryable).

It prints ``ready`` once its queryables and tokens are declared.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading

import numpy as np
import zenoh

from dualpilot.mission.ports import PlanRequest
from dualpilot.model.dynamics import DynamicsParams, rollout
from dualpilot.model.forecast import OccupancyForecast
from dualpilot.plan import Plan, PlanStatus
from services.common import bus, keys, wire
from services.common.convert import fire as fire_convert
from services.common.convert import plan as plan_convert
from services.msgs import fire_pb2, plan_pb2

DYN = DynamicsParams()
#: the compute time the rogue EWS's forged forecasts claim (s): a step record that shows it
#: planned on a forgery
FORGED_COMPUTE_S = 999.0


def forged_forecast(item: bus.Received, uav: str) -> fire_pb2.FireUpdate:
    """A forecast answering exactly the query ``item`` carries, with no risk anywhere."""
    cmd = fire_convert.fire_command_from_msg(
        wire.parse(item.payload, fire_pb2.FireCommand, item.encoding))
    update = fire_pb2.FireUpdate()
    stamper = wire.Stamper("ews", uav)
    stamper.stamp(update.header)
    state = fire_convert.fire_state_msg([], [], cmd.step, cmd.substeps_done, 0.5, stamper, 0.0)
    update.states.append(state)
    horizons = tuple(range(0, 81, 2))
    nothing = OccupancyForecast(resolution_m=10.0, substep_s=0.5, horizons=horizons,
                                levels=np.zeros((len(horizons), 100, 100), dtype=np.uint8),
                                issued_substep=cmd.substeps_done)
    fire_convert.forecast_reply_msg(nothing, cmd.step, FORGED_COMPUTE_S, update.forecast)
    stamper.stamp(update.forecast.header)
    return update


def _open(endpoint: str) -> zenoh.Session:
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    return zenoh.open(conf)


def byzantine_plan(req: PlanRequest, k: int) -> Plan:
    """A well-formed OK plan that must never be flown (one of three lies, by request count)."""
    x = np.asarray(req.state, dtype=float)
    controls = np.zeros((10, 2))
    if k % 3 == 0 and req.obstacles:  # next position: the centre of the nearest obstacle
        centres = [np.mean(o.vertices, axis=0) for o in req.obstacles]
        c = min(centres, key=lambda p: float(np.hypot(*(p - x[:2]))))
        states = rollout(x, controls, DYN)
        states[1:, :2] = c
    elif k % 3 == 1:  # 9,999 N (follows Eq. (1))
        controls = np.zeros((3, 2))
        controls[0] = 9999.0
        states = rollout(x, controls, DYN)
    else:  # a plan 50 km away
        x50 = x.copy()
        x50[:2] += 50_000.0
        states = rollout(x50, controls, DYN)
    return Plan(system=2, status=PlanStatus.OK, states=states, controls=controls,
                compute_time_s=0.001, info={"source": "byzantine"})


def braking_plan(req: PlanRequest) -> Plan:
    x = np.asarray(req.state, dtype=float)
    u = np.clip(-DYN.mass_kg * (1 - DYN.zeta) * x[2:] / DYN.dt_s, -DYN.u_max_n, DYN.u_max_n)
    controls = np.zeros((5, 2))
    controls[0] = u
    return Plan(system=2, status=PlanStatus.OK, states=rollout(x, controls, DYN),
                controls=controls, compute_time_s=0.001, info={"source": "impostor"})


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("mode", choices=["plan-byzantine", "plan-impostor", "ews-impostor",
                                    "plan-hung"])
    p.add_argument("--uav", required=True)
    p.add_argument("--connect", required=True)
    args = p.parse_args()
    stop = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    stamper = wire.Stamper("system2", args.uav)
    count = [0]
    with _open(args.connect) as session:
        inbox = bus.Inbox()
        zid = str(session.info.zid())
        if args.mode in ("plan-byzantine", "plan-hung"):  # a replica: the shared and own key
            names = [keys.plan(args.uav, 2), keys.plan_replica(args.uav, 2, zid)]
        elif args.mode == "plan-impostor":  # every replica's key, and the shared one
            names = [keys.plan(args.uav, 2) + "/**"]
        else:
            names = [keys.fire_command(args.uav)]
        queryables = [session.declare_queryable(key, inbox.on_query) for key in names]
        tokens = []
        if args.mode in ("plan-byzantine", "plan-hung"):
            names = [keys.alive(args.uav, "system2")]
            if hasattr(keys, "holder"):  # (a stack without holder tokens)
                names.insert(0, keys.holder(args.uav, "system2", zid))
            tokens = [session.liveliness().declare_token(n) for n in names]
        print("ready", flush=True)
        while not stop.is_set():
            item = inbox.get(timeout=0.2)
            if item is None or item.query is None:
                continue
            if args.mode == "ews-impostor":
                cmd = wire.parse(item.payload, fire_pb2.FireCommand, item.encoding)
                if cmd.WhichOneof("command") == "forecast":
                    bus.reply(item.query, forged_forecast(item, args.uav))
                    continue
                update = fire_pb2.FireUpdate()
                state = fire_convert.fire_state_msg([], [], cmd.advance.step, 0, 0.5,
                                                      wire.Stamper("ews", args.uav), 0.0)
                update.states.append(state)
                bus.reply(item.query, update)
                continue
            req = plan_convert.plan_request_from_msg(
                wire.parse(item.payload, plan_pb2.PlanRequest, item.encoding))
            prepare = isinstance(req, plan_convert.Prepare)
            if args.mode == "plan-hung" and not prepare:
                continue  # prepared, then never answers (as a planner stuck in its solver)
            if isinstance(req, plan_convert.Prepare):
                msg = plan_pb2.Plan(step=0, system=2, status=plan_pb2.PLAN_STATUS_OK,
                                    message="prepared", request_seq=req.seq)
                stamper.stamp(msg.header)
            else:
                plan = (byzantine_plan(req.request, count[0]) if args.mode == "plan-byzantine"
                        else braking_plan(req.request))
                count[0] += 1
                msg = plan_convert.plan_to_msg(plan, req.request.t, req.seq, stamper)
            bus.reply(item.query, msg)
        for t in tokens:
            t.undeclare()
        for q in queryables:
            q.undeclare()
    return 0


if __name__ == "__main__":
    sys.exit(main())
