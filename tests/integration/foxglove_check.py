"""Reading what the live view and mission.mcap carry, independently of the code that wrote it.

* :func:`read_mcap`: every message of an MCAP file, decoded with the schema the
  file itself carries (``mcap`` and ``mcap-protobuf-support``; JSON by ``json``).
* :class:`FoxgloveClient`: a WebSocket client of the Foxglove protocol
  (github.com/foxglove/ws-protocol's spec, ``foxglove.websocket.v1``; foxglove-sdk's
  servers name the same protocol ``foxglove.sdk.v1`` and accept only that name):
  serverInfo, advertise, subscribe, binary messageData (opcode 1: subscription id
  u32 LE, log time u64 LE ns, payload).
* :func:`compare_with_log`: each step of steps.jsonl against the recording.
"""

from __future__ import annotations

import asyncio
import base64
import json
import struct
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from mcap.records import Schema

#: offered as the Foxglove app does; foxglove-sdk 0.30 picks the first
SUBPROTOCOLS = ("foxglove.sdk.v1", "foxglove.websocket.v1")
SUBPROTOCOL = "foxglove.sdk.v1"


def decode(schema_name: str, schema_encoding: str, schema_data: bytes,
           message_encoding: str, payload: bytes) -> Any:
    """One message: protobuf via the FileDescriptorSet it names, JSON as a dict."""
    if message_encoding == "json":
        return json.loads(payload)
    assert (message_encoding, schema_encoding) == ("protobuf", "protobuf"), (
        message_encoding, schema_encoding)
    from mcap_protobuf.decoder import DecoderFactory

    schema = Schema(id=1, name=schema_name, encoding=schema_encoding, data=schema_data)
    decoder = DecoderFactory().decoder_for("protobuf", schema)
    assert decoder is not None, schema_name
    return decoder(payload)


@dataclass
class Recording:
    """Messages by topic, each (log time ns, decoded); schema (name, encoding) by topic."""

    messages: dict[str, list[tuple[int, Any]]] = field(default_factory=lambda: defaultdict(list))
    schemas: dict[str, tuple[str, str]] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)


def read_mcap(path: Path) -> Recording:
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    rec = Recording()
    with Path(path).open("rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        for schema, channel, message in reader.iter_messages():
            assert schema is not None
            rec.schemas[channel.topic] = (schema.name, schema.encoding)
            rec.messages[channel.topic].append((message.log_time, decode(
                schema.name, schema.encoding, schema.data, channel.message_encoding,
                message.data)))
        fh.seek(0)
        rec.metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
    return rec


def meta(entity: Any) -> dict[str, str]:
    return {kv.key: kv.value for kv in entity.metadata}


def points(line: Any) -> np.ndarray:
    return np.array([[p.x, p.y] for p in line.points]).reshape(-1, 2)


def rect_corners(cx: float, cy: float, w: float, h: float) -> np.ndarray:
    """The corners, counter-clockwise from the south-west one: worked out by hand."""
    return np.array([[cx - w / 2, cy - h / 2], [cx + w / 2, cy - h / 2],
                     [cx + w / 2, cy + h / 2], [cx - w / 2, cy + h / 2]])


def check_fires(update: Any, step: dict[str, Any]) -> None:
    """A fires SceneUpdate against one step line's regions, hulls, front ids and birth steps."""
    assert [d.type for d in update.deletions] == [1]  # ALL: the previous step's fronts go
    fronts = [e for e in update.entities if e.id.startswith("front/")]
    assert [e.id for e in fronts] == [f"front/{i}" for i in step["front_ids"]]
    for e, region, fid, born in zip(fronts, step["regions"], step["front_ids"],
                                    step["born_steps"], strict=True):
        assert meta(e) == {"front_id": str(fid), "born_step": str(born)}
        assert np.allclose(points(e.lines[0]), rect_corners(*region), atol=1e-9)
    hulls = [points(e.lines[1]) for e in fronts] + [
        points(e.lines[0]) for e in update.entities if e.id.startswith("hull/")]
    assert len(hulls) == len(step["hulls"])
    for got, want in zip(hulls, step["hulls"], strict=True):
        assert np.allclose(got, np.array(want), atol=1.1e-3)  # steps.jsonl: 1e-3 m


def plan_status_of(plan_status: str, system: int) -> str:
    """The statuses of ``system`` in a step's plan_status text, by hand."""
    mine = [p.split(":", 1)[1] for p in plan_status.split(";") if p.startswith(f"s{system}:")]
    return ";".join(mine)


def check_plan(update: Any, step: dict[str, Any], system: int) -> None:
    (e,) = update.entities
    m = meta(e)
    flown = step["system"] == system
    want = plan_status_of(step["plan_status"], system) or ("kept" if flown else "not_asked")
    assert m == {"system": str(system), "step": str(step["t"]), "status": want,
                 "flown": str(flown).lower()}, (m, step["plan_status"])
    if flown:
        assert np.allclose(points(e.lines[0]), np.array(step["plan"])[:, :2], atol=1.1e-3)
    else:
        assert not e.lines


def check_decision(doc: dict[str, Any], step: dict[str, Any], controller: str) -> None:
    d = step["decision"]
    assert doc["t"] == step["t"] == d["t"]
    assert doc["time_s"] == step["time_s"]
    for name in ("xi", "p", "psi"):
        assert doc[name] == [float(v) for v in d[name]], name
    assert (doc["attention"], doc["system"], doc["objective"]) == (
        d["attention"], d["system"], d["objective"])
    assert doc["flown_system"] == step["system"]
    forced = {"s1": 1, "s2": 2}.get(controller, d["system"])
    assert doc["commanded_system"] == forced
    assert doc["d_t_m"] == (None if d["d_t"] == "inf" else float(d["d_t"]))


def check_uav(update: Any, x: list[Any], t: int) -> None:
    (e,) = update.entities
    m = meta(e)
    assert (m["step"], float(m["east_m"]), float(m["north_m"])) == (str(t), float(x[0]),
                                                                    float(x[1]))
    assert (e.cubes[0].pose.position.x, e.cubes[0].pose.position.y) == (float(x[0]),
                                                                       float(x[1]))


def compare_with_log(rec: Recording, entries: list[dict[str, Any]], uav: str) -> int:
    """Every step line of a steps.jsonl against ``rec``; returns the steps compared."""
    head = next(e for e in entries if e.get("kind") == "mission")
    steps = [e for e in entries if e.get("kind") == "step"]
    p = f"/{uav}"
    by_time: dict[str, dict[int, Any]] = {
        topic: dict(msgs) for topic, msgs in rec.messages.items()}
    for topic in ("fires", "decision", "plan/system1", "plan/system2", "area"):
        assert len(rec.messages[f"{p}/{topic}"]) == len(steps), topic
    times = [s["time_s"] for s in steps]
    assert times == sorted(times) and len(set(times)) == len(times), "one time per step"
    for s in steps:
        t_ns = round(s["time_s"] * 1e9)
        check_fires(by_time[f"{p}/fires"][t_ns], s)
        check_decision(by_time[f"{p}/decision"][t_ns], s, head["controller"])
        for k in (1, 2):
            check_plan(by_time[f"{p}/plan/system{k}"][t_ns], s, k)
        check_uav(by_time[f"{p}/uav"][t_ns], s["state"], s["t"])
    path = rec.messages[f"{p}/path"][-1][1].entities[0]
    flown = [s["state"][:2] for s in steps]
    end = next((e for e in entries if e.get("kind") == "end"), None)
    if end is not None and end.get("final_state") is not None:
        flown.append(end["final_state"][:2])
    assert np.allclose(points(path.lines[0]), np.array(flown, dtype=float), atol=1e-9)
    return len(steps)


# -- the Foxglove WebSocket protocol ----------------------------------------------------------
class FoxgloveClient:
    """A Foxglove WebSocket client (``websockets``): advertised channels, subscriptions and the
    messages received on them, decoded with each channel's advertised schema."""

    def __init__(self, url: str):
        self.url = url
        self.server_info: dict[str, Any] = {}
        self.channels: dict[int, dict[str, Any]] = {}  # id → advertised channel
        self.subs: dict[int, int] = {}  # subscription id → channel id
        self.received: dict[str, list[tuple[int, Any]]] = defaultdict(list)
        self.ws: Any = None

    async def __aenter__(self) -> FoxgloveClient:
        import websockets
        from websockets.typing import Subprotocol

        offered = [Subprotocol(p) for p in SUBPROTOCOLS]
        self.ws = await websockets.connect(self.url, subprotocols=offered,
                                           max_size=64 * 1024 * 1024)
        assert self.ws.subprotocol == SUBPROTOCOL
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.ws.close()

    def by_topic(self) -> dict[str, dict[str, Any]]:
        return {c["topic"]: c for c in self.channels.values()}

    async def pump(self, seconds: float) -> None:
        """Handle what the server sends for ``seconds``."""
        loop = asyncio.get_running_loop()
        end = loop.time() + seconds
        while (left := end - loop.time()) > 0:
            try:
                frame = await asyncio.wait_for(self.ws.recv(), timeout=left)
            except TimeoutError:
                return
            self.handle(frame)

    def handle(self, frame: str | bytes) -> None:
        if isinstance(frame, str):
            msg = json.loads(frame)
            if msg["op"] == "serverInfo":
                self.server_info = msg
            elif msg["op"] == "advertise":
                for c in msg["channels"]:
                    self.channels[int(c["id"])] = c
            elif msg["op"] == "unadvertise":
                for cid in msg["channelIds"]:
                    self.channels.pop(int(cid), None)
            return
        assert frame[0] == 1, f"binary opcode {frame[0]}"
        sub_id, log_time = struct.unpack_from("<IQ", frame, 1)
        c = self.channels[self.subs[sub_id]]
        data = c["schema"].encode() if c.get("schemaEncoding") != "protobuf" else (
            base64.b64decode(c["schema"]))
        self.received[c["topic"]].append((log_time, decode(
            c["schemaName"], c.get("schemaEncoding", ""), data, c["encoding"],
            bytes(frame[13:]))))

    async def subscribe(self, topics: list[str]) -> None:
        wanted = [c for c in self.channels.values() if c["topic"] in topics
                  and int(c["id"]) not in self.subs.values()]
        subs = []
        for c in wanted:
            sid = len(self.subs) + 1
            self.subs[sid] = int(c["id"])
            subs.append({"id": sid, "channelId": int(c["id"])})
        if subs:
            await self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
