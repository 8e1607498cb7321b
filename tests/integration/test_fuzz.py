"""Fuzzing the real service processes on every Zenoh key they subscribe to or answer.

The EWS and both planner services run as processes; the test process throws
at ``ews/command``, ``plan/system1``, ``plan/system2`` (queries),
``operator/waypoints`` (puts, both planners subscribe) and every
``status/<service>`` key: random and truncated bytes, flipped bytes, wrong
message types, NaN and infinities, huge numbers, coordinates far outside the
area, unknown enum values, wrong lengths, unknown schema versions and 10 MB
payloads. Every input is first decoded locally with the same codec: only
inputs the codec rejects are sent (a valid FireCommand would reset the fire
process), so the reason each service must count is known in advance.

Checks: no service exits; every query gets an error reply; each service's
status (``<ns>/status/<service>``) counts every rejection under the key it
arrived on, with the expected reason; the rejection log stays small (it is
rate-limited); a valid plan request and valid fire commands after the flood
are answered correctly.

Quick run in the normal suite (a few hundred inputs per entry point);
``test_fuzz_10k_inputs_per_entry_point`` (slow) sends 10,000 per entry point.
"""

from __future__ import annotations

import collections
import math
import threading
import time
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest
import zenoh
from google.protobuf.descriptor import FieldDescriptor
from google.protobuf.message import Message

from dualpilot.mission.ports import PlanRequest
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.model.fire import FireParams
from dualpilot.model.fire_field import FireField
from dualpilot.plan import Objective, PlanStatus
from dualpilot.spec import MissionSpec, Stream, stream_rng
from dualpilot.verify import verify_trajectory
from services.common import bus, keys, limits, rejections, wire
from services.common.clock import Anchor
from services.common.convert import common as common_convert
from services.common.convert import fire as fire_convert
from services.common.convert import plan as plan_convert
from services.common.convert import vehicle as vehicle_convert
from services.msgs import common_pb2, fire_pb2, plan_pb2, supervisor_pb2, vehicle_pb2
from tests.support.missions import config_for

HUGE_BYTES = 10 * 1024 * 1024
QUICK_INPUTS = 300
SLOW_INPUTS = 10_000


# -- valid messages to start from -----------------------------------------------------------------
def fire_state(uav: str, seed: int = 5) -> fire_pb2.FireState:
    rng = np.random.default_rng(seed)
    f = FireField(params=FireParams(p_survive=1.0))
    f.spawn(rng, 0, center=(500.0, 500.0))
    f.spawn(rng, 0)
    for _ in range(3):
        f.substep(rng, 0)
    return fire_convert.fire_state_msg(f.fronts, [], 0, f.substeps_done, 0.5,
                                         wire.Stamper("fuzz", uav), 0.0)


def plan_request(uav: str, system: int, mission_id: str = "fuzz-mission",
                 fires: fire_pb2.FireState | None = None,
                 prepare: bool = True) -> plan_pb2.PlanRequest:
    """A valid request (a fire at (500, 500), start (50, 50)), as in test_planner_services;
    with the mission spec (a prepare request) unless ``prepare`` is False."""
    if fires is None:
        rng = np.random.default_rng(5)
        f = FireField(params=FireParams(p_survive=1.0))
        f.spawn(rng, 0, center=(500.0, 500.0))
        fires = fire_convert.fire_state_msg(f.fronts, [], 0, 1, 0.5, wire.Stamper("fuzz", uav),
                                              0.0)
    stamper = wire.Stamper("fuzz", uav)
    if prepare:
        spec = MissionSpec(seed=7)
        prep = plan_convert.Prepare(mission_id, system, spec, config_for(spec), deadline_s=60.0)
        return plan_convert.prepare_msg(prep, stamper, 0.0)
    req = PlanRequest(t=0, system=system, state=np.array([50.0, 50.0, 0.0, 0.0]),
                      prev_control=np.zeros(2),
                      obstacles=fire_convert.snapshot_from_msg(fires).hulls,
                      objective=Objective.MISSION_TIME)
    return plan_convert.plan_query_msg(plan_convert.PlanQuery(req, mission_id, 0, 60.0),
                                       stamper, 0.0)


def fire_command(uav: str, kind: str, mission_id: str = "fuzz-mission", seed: int = 3,
                 step: int = 0, substeps: int = 2) -> fire_pb2.FireCommand:
    m = fire_pb2.FireCommand(mission_id=mission_id)
    wire.Stamper("fuzz", uav).stamp(m.header)
    if kind == "reset":
        m.reset.seed = seed
    else:
        m.advance.step, m.advance.substeps = step, substeps
        common_convert.clock_to_msg(Anchor(0.0, time.time_ns(), 0.0), m.advance.clock)
    return m


def waypoints(uav: str) -> vehicle_pb2.OperatorWaypoints:
    return vehicle_convert.waypoints_msg(
        vehicle_convert.Waypoints("fuzz-mission", 1, np.array([[100.0, 200.0], [800.0, 900.0]])),
        wire.Stamper("fuzz", uav))


def other_messages(uav: str) -> list[Message]:
    """Valid messages of every type: the 'wrong message type' inputs."""
    d = supervisor_pb2.Decision(step=1, d_t_m=50.0, attention=1, system=1,
                                objective=plan_pb2.OBJECTIVE_MISSION_TIME)
    d.xi.extend([1.0, 1.0, 1.0])
    d.p.extend([0.2, 0.3, 0.5])
    d.psi.extend([0.5, 0.5])
    ev = supervisor_pb2.MissionEvent(kind=supervisor_pb2.MISSION_EVENT_KIND_STARTED, mission_id="x")
    state = vehicle_pb2.VehicleState(east_m=50.0, north_m=50.0)
    clock = common_pb2.Clock(sim_time_s=1.0, speed_factor=1.0, anchor_wall_ns=time.time_ns())
    err = common_pb2.Error(code=common_pb2.ERROR_CODE_INVALID, message="e")
    plan = plan_pb2.Plan(system=1, status=plan_pb2.PLAN_STATUS_INFEASIBLE)
    out: list[Message] = [d, ev, state, clock, err, plan, fire_state(uav), waypoints(uav),
                          plan_request(uav, 1), fire_command(uav, "reset")]
    for m in out:
        wire.Stamper("fuzz", uav).stamp(m.header)  # type: ignore[attr-defined]
    return out


# -- the corpus -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Entry:
    """One entry point: a key, what it expects, how a service decodes it."""

    name: str
    key: str
    cls: type[Message]
    convert: Callable[[Any], Any]
    base: Callable[[], Message]
    query: bool = True


def entries(uav: str) -> list[Entry]:
    return [
        Entry("ews/command", keys.fire_command(uav), fire_pb2.FireCommand,
              fire_convert.fire_command_from_msg, lambda: fire_command(uav, "advance")),
        Entry("plan/system1", keys.plan(uav, 1), plan_pb2.PlanRequest,
              plan_convert.plan_request_from_msg,
              lambda: plan_request(uav, 1, fires=fire_state(uav), prepare=False)),
        Entry("plan/system2", keys.plan(uav, 2), plan_pb2.PlanRequest,
              plan_convert.plan_request_from_msg,
              lambda: plan_request(uav, 2, fires=fire_state(uav), prepare=False)),
        Entry("operator/waypoints", keys.waypoints(uav), vehicle_pb2.OperatorWaypoints,
              vehicle_convert.waypoints_from_msg, lambda: waypoints(uav), query=False),
    ]


def _scalar_fields(msg: Message, path: tuple[Any, ...] = ()) -> Iterator[tuple[tuple[Any, ...],
                                                                               FieldDescriptor]]:
    for fd in msg.DESCRIPTOR.fields:
        if fd.message_type is not None:
            if fd.is_repeated:
                for i, sub in enumerate(getattr(msg, fd.name)):
                    yield from _scalar_fields(sub, (*path, (fd.name, i)))
            else:
                yield from _scalar_fields(getattr(msg, fd.name), (*path, (fd.name, None)))
        else:
            yield (*path, (fd.name, None)), fd


def _owner(msg: Message, path: tuple[Any, ...]) -> Any:
    obj: Any = msg
    for name, index in path[:-1]:
        obj = getattr(obj, name) if index is None else getattr(obj, name)[index]
    return obj


_SPECIAL = [math.nan, math.inf, -math.inf]
_HUGE = [1e300, -1e300, 1e6, -1e6, 2e5, -2e5, 5e4, -5e4, 3e3, -3e3]
_INTS = {FieldDescriptor.TYPE_UINT32: 2**32 - 1, FieldDescriptor.TYPE_UINT64: 2**64 - 1,
         FieldDescriptor.TYPE_INT64: 2**63 - 1, FieldDescriptor.TYPE_INT32: 2**31 - 1,
         FieldDescriptor.TYPE_ENUM: 2**31 - 1}


class Corpus:
    """Seeded bad inputs for one entry point, each with the reason the codec gives."""

    KINDS = ("random", "truncated", "flipped", "wrong_type", "nan", "huge_number", "far",
             "schema", "mutate", "enum", "length")

    def __init__(self, entry: Entry, uav: str, seed: int):
        self.entry = entry
        self.rng = np.random.default_rng(seed)
        self.base = entry.base()
        self.base_bytes = self.base.SerializeToString()
        self.others = [m for m in other_messages(uav) if type(m) is not entry.cls]
        self.fields = list(_scalar_fields(self.base))
        self.floats = [(p, fd) for p, fd in self.fields
                       if fd.type == FieldDescriptor.TYPE_DOUBLE]
        self.ints = [(p, fd) for p, fd in self.fields if fd.type in _INTS]
        self.skipped = 0  # generated inputs the codec accepts (never sent)

    def reason(self, payload: bytes, enc: str | None) -> str | None:
        """The reason the service's codec rejects this input, None if it accepts it."""
        try:
            self.entry.convert(wire.parse(payload, self.entry.cls, enc))
        except rejections.CodecError as err:
            return str(err.reason)
        return None

    def _copy(self) -> Any:
        m = self.entry.cls()
        m.CopyFrom(self.base)
        return m

    def _set(self, msg: Message, pick: tuple[Any, ...], value: Any) -> None:
        path, fd = pick
        obj = _owner(msg, path)
        if fd.is_repeated:
            vals = list(getattr(obj, path[-1][0]))
            if vals:
                vals[int(self.rng.integers(len(vals)))] = value
            else:
                vals = [value]
            getattr(obj, path[-1][0])[:] = vals
        else:
            setattr(obj, path[-1][0], value)

    def _choice(self, seq: list[Any]) -> Any:
        return seq[int(self.rng.integers(len(seq)))]

    def one(self, kind: str) -> tuple[bytes, str | None]:
        rng, enc = self.rng, wire.encoding_name(self.entry.cls)
        if kind == "random":
            return rng.bytes(int(rng.integers(0, 2000))), None if rng.random() < 0.5 else enc
        if kind == "truncated":
            return self.base_bytes[:int(rng.integers(0, len(self.base_bytes)))], enc
        if kind == "flipped":
            buf = bytearray(self.base_bytes)
            for _ in range(int(rng.integers(1, 5))):
                buf[int(rng.integers(len(buf)))] = int(rng.integers(256))
            return bytes(buf), enc
        if kind == "wrong_type":
            other = self._choice(self.others)
            return other.SerializeToString(), (wire.encoding_name(other) if rng.random() < 0.7
                                               else self._choice(["text/plain",
                                                                  "application/json", None]))
        m = self._copy()
        if kind in ("nan", "huge_number"):
            self._set(m, self._choice(self.floats), self._choice(
                _SPECIAL if kind == "nan" else _HUGE))
        elif kind == "far":
            self._far(m)
        elif kind == "schema":
            m.header.schema_version = int(rng.integers(2, 2**32))
        elif kind == "mutate":
            for _ in range(int(rng.integers(1, 4))):
                pick = self._choice(self.fields)
                self._set(m, pick, self._value(pick[1]))
        elif kind == "enum":
            pick = self._choice(self.ints)
            self._set(m, pick, int(rng.integers(3, min(_INTS[pick[1].type], 2**62))))
        elif kind == "length":
            reps = [(p, fd) for p, fd in self.floats if fd.is_repeated] or self.floats
            path, fd = self._choice(reps)
            obj = _owner(m, path)
            if fd.is_repeated:
                getattr(obj, path[-1][0]).append(1.0)  # an odd number of coordinates
            else:  # no packed field: too many items instead
                return self._too_many(), enc
        return m.SerializeToString(), enc

    def _value(self, fd: FieldDescriptor) -> Any:
        if fd.type == FieldDescriptor.TYPE_DOUBLE:
            return self._choice([*_SPECIAL, *_HUGE, -1.0, 0.0, float(self.rng.normal() * 1e4)])
        if fd.type in _INTS:
            hi = _INTS[fd.type]
            return self._choice([0, 1, 2, 3, hi, int(self.rng.integers(0, min(hi, 2**62)))])
        if fd.type == FieldDescriptor.TYPE_BOOL:
            return bool(self.rng.random() < 0.5)
        if fd.type == FieldDescriptor.TYPE_BYTES:  # forecast slices: empty, noise, a bomb
            return self._choice([b"", b"\x00", self.rng.bytes(int(self.rng.integers(1, 300))),
                                 zlib.compress(bytes(1 << 20))])
        return self._choice(["", "x" * 70_000, "ü" * 300, "\x00"])

    def _far(self, m: Any) -> None:
        far = float(self._choice([1, -1]) * self.rng.uniform(2.5e3, 9e4))
        name = self.entry.cls.DESCRIPTOR.name
        if name == "PlanRequest":
            target = self._choice(["state", "obstacle", "goal"])
            if target == "state":
                m.state.east_m = far
            elif target == "obstacle":
                m.obstacles[0].vertices_m[1] = far
            else:
                m.mission.goal.center_north_m = far
        elif name == "OperatorWaypoints":
            m.waypoints[0].east_m = far * 10  # beyond MAX_ABS_M
        else:  # FireCommand: a clock a year away, or one that would never tick
            m.advance.clock.speed_factor = 1.0
            m.advance.clock.anchor_wall_ns = time.time_ns() + int(3e16)

    def _too_many(self) -> bytes:
        m = self._copy()
        if self.entry.cls is vehicle_pb2.OperatorWaypoints:
            for _ in range(limits.MAX_WAYPOINTS + 1):
                m.waypoints.add(east_m=1.0, north_m=1.0)
        else:
            m.mission_id = "x" * 300
        return bytes(m.SerializeToString())

    def huge(self) -> tuple[bytes, str | None]:
        """A 10 MB payload: random bytes or a valid message padded with a huge string."""
        if self.rng.random() < 0.5:
            return self.rng.bytes(HUGE_BYTES), None
        return self.base_bytes + b"\x7a" + b"\xff" * HUGE_BYTES, wire.encoding_name(
            self.entry.cls)

    def take(self, n: int, huge: int = 1) -> Iterator[tuple[bytes, str | None, str]]:
        """``n`` rejected inputs (``huge`` of them 10 MB) with their reasons."""
        sent = 0
        for _ in range(huge):
            payload, enc = self.huge()
            reason = self.reason(payload, enc)
            assert reason == "too_large"
            yield payload, enc, reason
            sent += 1
        i = 0
        while sent < n:
            payload, enc = self.one(self.KINDS[i % len(self.KINDS)])
            i += 1
            reason = self.reason(payload, enc)
            if reason is None:
                self.skipped += 1
                continue
            yield payload, enc, reason
            sent += 1


# -- sending --------------------------------------------------------------------------------------
@dataclass
class Replies:
    ok: int = 0
    err: int = 0
    none: int = 0  # queries answered by nobody
    error_codes: collections.Counter[int] = field(default_factory=collections.Counter)


class Sender:
    """Queries with a bounded number outstanding (so no inbox overflows) and blocking puts."""

    def __init__(self, session: Any, window: int = 32):
        self.session = session
        self.slots = threading.Semaphore(window)
        self.window = window
        self.lock = threading.Lock()
        self.replies: dict[str, Replies] = collections.defaultdict(Replies)

    def query(self, key: str, payload: bytes, enc: str | None, timeout_s: float = 60.0) -> None:
        self.slots.acquire()
        got: list[bool] = []

        def on_reply(r: Any) -> None:  # only records (no Zenoh calls in callbacks)
            with self.lock:
                got.append(True)
                rep = self.replies[key]
                if r.ok is not None:
                    rep.ok += 1
                else:
                    rep.err += 1
                    try:
                        rep.error_codes[common_pb2.Error.FromString(
                            r.err.payload.to_bytes()).code] += 1
                    except Exception:
                        rep.error_codes[-1] += 1

        def on_done() -> None:
            with self.lock:
                if not got:
                    self.replies[key].none += 1
            self.slots.release()

        kw: dict[str, Any] = {"payload": payload, "timeout": timeout_s}
        if enc is not None:
            kw["encoding"] = zenoh.Encoding(enc)
        self.session.get(key, zenoh.handlers.Callback(on_reply, on_done), **kw)

    def put(self, key: str, payload: bytes, enc: str | None) -> None:
        kw: dict[str, Any] = {"congestion_control": zenoh.CongestionControl.BLOCK}
        if enc is not None:
            kw["encoding"] = zenoh.Encoding(enc)
        self.session.put(key, payload, **kw)

    def drain(self, timeout_s: float = 120.0) -> None:
        """Wait until every query has its final reply."""
        deadline = time.monotonic() + timeout_s
        taken = 0
        while taken < self.window:
            assert self.slots.acquire(timeout=max(0.0, deadline - time.monotonic())), (
                "queries still unanswered")
            taken += 1
        for _ in range(taken):
            self.slots.release()


@dataclass
class FloodResult:
    expected: dict[str, collections.Counter[str]]
    sent: dict[str, int]
    skipped: dict[str, int]
    wall_s: float


def flood(session: Any, uav: str, per_entry: int, huge: int, seed: int,
          stop: threading.Event | None = None, include: tuple[str, ...] = (),
          status_services: tuple[str, ...] = ("ews", "system1", "system2")) -> FloodResult:
    """Send ``per_entry`` rejected inputs to each entry point, round-robin, until ``stop``;
    wait for every reply. Garbage also goes to the status queryables of ``status_services``."""
    sender = Sender(session)
    chosen = [e for e in entries(uav) if not include or e.name in include]
    corpora = {e.name: Corpus(e, uav, seed + i) for i, e in enumerate(chosen)}
    streams = {e.name: corpora[e.name].take(per_entry, huge) for e in chosen}
    expected: dict[str, collections.Counter[str]] = {e.key: collections.Counter() for e in chosen}
    sent = dict.fromkeys(expected, 0)
    status_keys = [keys.status(uav, s) for s in status_services]
    t0 = time.monotonic()
    live = list(chosen)
    k = 0
    while live and not (stop is not None and stop.is_set()):
        for e in list(live):
            item = next(streams[e.name], None)
            if item is None:
                live.remove(e)
                continue
            payload, enc, reason = item
            expected[e.key][reason] += 1
            sent[e.key] += 1
            if e.query:
                sender.query(e.key, payload, enc)
            else:
                sender.put(e.key, payload, enc)
        k += 1
        if k % 50 == 0:  # garbage to the status queryables too: they ignore the payload
            sender.query(status_keys[k // 50 % len(status_keys)], b"\xff" * (k % 300), None)
    sender.drain()
    for e in chosen:
        if e.query:
            r = sender.replies[e.key]
            assert r.ok == 0 and r.none == 0 and r.err == sent[e.key], (e.key, r)
            assert set(r.error_codes) <= {common_pb2.ERROR_CODE_MALFORMED,
                                          common_pb2.ERROR_CODE_INVALID}, r.error_codes
    for key in status_keys:
        if key in sender.replies:
            r = sender.replies[key]
            assert r.err == 0 and r.none == 0, (key, r)
    return FloodResult(expected, sent, {e.key: corpora[e.name].skipped for e in chosen},
                       time.monotonic() - t0)


def rejected_on(session: Any, uav: str, service: str, key: str) -> collections.Counter[str]:
    return collections.Counter(bus.query_status(session, uav, service)["rejected"].get(key, {}))


def check_counted(session: Any, uav: str, before: dict[tuple[str, str], collections.Counter[str]],
                  result: FloodResult, wait_until: Any) -> None:
    """Each service's status counts every rejection of the flood under its key and reason."""
    owners = {keys.fire_command(uav): ["ews"], keys.plan(uav, 1): ["system1"],
              keys.plan(uav, 2): ["system2"], keys.waypoints(uav): ["system1", "system2"]}
    for key, want in result.expected.items():
        for service in owners[key]:
            def delta(s: str = service, k: str = key) -> collections.Counter[str]:
                now = rejected_on(session, uav, s, k)
                now.subtract(before[(s, k)])
                return +now

            # puts are not acknowledged: wait until the subscriber has taken them all
            n = result.sent[key]
            assert wait_until(lambda d=delta, n=n: sum(d().values()) >= n, 60), (
                service, key, delta(), want)
            got = delta()
            if key == keys.waypoints(uav):
                # a subscriber's inbox may overflow under a flood of puts: counted as such
                assert sum(got.values()) == result.sent[key], (service, got, want)
                assert all(got[r] <= want[r] for r in got if r != "overflow"), (got, want)
            else:
                assert got == want, (service, key, got, want)


def counters(session: Any, uav: str) -> dict[tuple[str, str], collections.Counter[str]]:
    out = {}
    for key, services in ((keys.fire_command(uav), ["ews"]), (keys.plan(uav, 1), ["system1"]),
                          (keys.plan(uav, 2), ["system2"]),
                          (keys.waypoints(uav), ["system1", "system2"])):
        for s in services:
            out[(s, key)] = rejected_on(session, uav, s, key)
    return out


def check_still_serving(session: Any, uav: str, mission_id: str) -> None:
    """After the flood: verified plans from both planners, and a correct fire process."""
    for system in (1, 2):
        bus.request(session, keys.plan(uav, system), plan_request(uav, system, mission_id), 120.0)
        payload, enc = bus.request(session, keys.plan(uav, system),
                                   plan_request(uav, system, mission_id, prepare=False), 120.0)
        plan = plan_convert.plan_from_msg(wire.parse(payload, plan_pb2.Plan, enc), system)
        assert plan.status is PlanStatus.OK, plan.message
        assert np.array_equal(plan.states[0], [50.0, 50.0, 0.0, 0.0])
        rng = np.random.default_rng(5)
        f = FireField(params=FireParams(p_survive=1.0))
        f.spawn(rng, 0, center=(500.0, 500.0))
        verdict = verify_trajectory(plan.states, plan.controls, tuple(x.hull for x in f.fronts),
                                    DynamicsParams(), MissionSpec().d_safe_m)
        assert verdict.ok, verdict.reason
    payload, enc = bus.request(session, keys.fire_command(uav),
                               fire_command(uav, "reset", mission_id, seed=11), 30.0)
    first = wire.parse(payload, fire_pb2.FireUpdate, enc)
    payload, enc = bus.request(session, keys.fire_command(uav),
                               fire_command(uav, "advance", mission_id, step=0, substeps=3), 30.0)
    update = wire.parse(payload, fire_pb2.FireUpdate, enc)
    assert len(first.states) == 1 and first.states[0].substeps_done == 0
    assert [s.substeps_done for s in update.states] == [1, 2, 3]
    # the same seed in-process gives the same fire (the flood changed nothing)
    ref = FireField(params=FireParams())
    ref_rng = stream_rng(11, Stream.FIRE)
    for _ in range(3):
        ref.substep(ref_rng, 0)
    assert fire_convert.snapshot_from_msg(update.states[-1]).regions == ref.snapshot().regions


# -- the tests ------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def stack(services: Any, liveliness: bus.Liveliness) -> Any:
    for name in ("ews", "system1", "system2"):
        services.start(name)
    names = ["ews", "system1", "system2"]
    assert liveliness.wait_for(names, 90), "\n".join(services.log(n)[-2000:] for n in names)
    return services


def _no_exits(stack: Any) -> None:
    dead = [(p.name, p.popen.returncode) for p in stack.group.procs if p.popen.poll() is not None]
    assert not dead, (dead, {n: stack.log(n)[-3000:] for n, _ in dead})


@pytest.mark.timeout(240)
def test_every_service_serves_its_status(stack: Any, session: Any) -> None:
    for service in ("ews", "system1", "system2"):
        st = bus.query_status(session, stack.uav, service)
        assert st["service"] == service and st["uav"] == stack.uav and st["uptime_s"] > 0
        assert set(st["reasons"]) == {r.value for r in rejections.Reason}
        assert isinstance(st["rejected"], dict) and st["rejected_total"] >= 0


@pytest.mark.timeout(300)
def test_fuzz_quick(stack: Any, session: Any, wait_until: Any) -> None:
    before = counters(session, stack.uav)
    result = flood(session, stack.uav, QUICK_INPUTS, huge=1, seed=1)
    _no_exits(stack)
    check_counted(session, stack.uav, before, result, wait_until)
    check_still_serving(session, stack.uav, "after-quick-fuzz")
    _no_exits(stack)
    for name in ("ews", "system1", "system2"):
        assert len(stack.log(name)) < 200_000, f"{name}'s log grew too much"


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_fuzz_10k_inputs_per_entry_point(stack: Any, session: Any, wait_until: Any) -> None:
    before = counters(session, stack.uav)
    sizes = {n: len(stack.log(n)) for n in ("ews", "system1", "system2")}
    result = flood(session, stack.uav, SLOW_INPUTS, huge=3, seed=100)
    _no_exits(stack)
    assert all(n >= SLOW_INPUTS for n in result.sent.values()), result.sent
    check_counted(session, stack.uav, before, result, wait_until)
    check_still_serving(session, stack.uav, "after-10k-fuzz")
    _no_exits(stack)
    for name, size in sizes.items():  # rate-limited: a flood cannot fill the disk
        assert len(stack.log(name)) - size < 1_000_000, f"{name}'s log grew too much"
    print(f"\n10k fuzz: {sum(result.sent.values())} inputs in {result.wall_s:.1f} s "
          f"({sum(result.sent.values()) / result.wall_s:.0f}/s); skipped (valid) {result.skipped}")
