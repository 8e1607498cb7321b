"""The user-space impairer's model and control protocol, on injected times.

Expected values are worked out from the definitions: a uniform delay on
[delay - jitter, delay + jitter] has mean ``delay`` and standard deviation
``2 jitter / sqrt(12)``; Bernoulli loss ``p`` over ``n`` frames loses ``n p`` frames with
standard deviation ``sqrt(n p (1 - p))``; an outage over [t0, t0 + s) blackholes exactly the
frames offered or due inside it.
"""

from __future__ import annotations

import json
import math
import socket
from pathlib import Path
from typing import Any

import pytest
from scipy import stats

from services.testbed.impairer.channel import Channel, Outage
from services.testbed.impairer.control import (
    ControlClient,
    ControlServer,
    ImpairerError,
    Request,
    parse,
)

SOURCES = ("air", "ground")


def delays(ch: Channel, n: int, spacing_s: float, start: float = 0.0) -> list[float]:
    out = []
    for k in range(n):
        now = start + k * spacing_s
        due = ch.offer(now, b"x")
        assert due is not None
        out.append((due - now) * 1000.0)
    return out


# -- delay and jitter -------------------------------------------------------------------------
def test_delay_is_uniform_on_delay_plus_minus_jitter() -> None:
    ch = Channel(7, Outage(), delay_ms=100.0, jitter_ms=20.0)
    d = delays(ch, 5000, spacing_s=1.0)  # 1 s apart: the in-order rule never binds
    assert min(d) >= 80.0 - 1e-9 and max(d) <= 120.0 + 1e-9
    sigma_mean = 40.0 / math.sqrt(12) / math.sqrt(5000)  # 0.163 ms
    assert abs(sum(d) / len(d) - 100.0) < 4 * sigma_mean
    assert stats.kstest(d, "uniform", args=(80.0, 40.0)).pvalue > 1e-3


def test_a_fixed_delay_without_jitter_is_exact() -> None:
    ch = Channel(0, Outage(), delay_ms=250.0)
    assert delays(ch, 10, 0.5) == pytest.approx([250.0] * 10)


def test_jitter_larger_than_the_delay_is_clipped_at_zero() -> None:
    ch = Channel(3, Outage(), delay_ms=5.0, jitter_ms=20.0)
    d = delays(ch, 20000, spacing_s=1.0)
    assert min(d) == 0.0 and max(d) <= 25.0
    # U(-15, 25) < 0 with probability 15/40
    zero = sum(1 for x in d if x == 0.0) / len(d)
    assert abs(zero - 0.375) < 4 * math.sqrt(0.375 * 0.625 / len(d))


def test_frames_leave_in_the_order_they_came() -> None:
    ch = Channel(11, Outage(), delay_ms=50.0, jitter_ms=40.0)
    dues = [ch.offer(k * 0.001, k.to_bytes(4, "big")) for k in range(1000)]  # 1 ms apart
    assert all(d is not None for d in dues)
    assert dues == sorted(dues)  # type: ignore[type-var]
    out = ch.due(10.0)
    assert [int.from_bytes(f, "big") for f in out] == list(range(1000))


def test_frames_are_due_only_at_their_time() -> None:
    ch = Channel(0, Outage(), delay_ms=125.0)  # times exact in binary
    ch.offer(0.0, b"a")
    ch.offer(0.0625, b"b")
    assert ch.next_due() == 0.125
    assert ch.due(0.1249) == []
    assert ch.due(0.125) == [b"a"]
    assert ch.due(0.1874) == []
    assert ch.due(0.1875) == [b"b"] and ch.queued() == 0


def test_a_new_delay_applies_to_later_frames_and_keeps_the_order() -> None:
    ch = Channel(0, Outage(), delay_ms=300.0)
    assert ch.offer(0.0, b"a") == pytest.approx(0.3)
    ch.configure(100.0, 0.0, 0.0)
    assert ch.offer(0.1, b"b") == pytest.approx(0.3)  # would be 0.2: not before "a"
    assert ch.offer(1.0, b"c") == pytest.approx(1.1)


# -- loss --------------------------------------------------------------------------------------
@pytest.mark.parametrize("p", [0.05, 0.1, 0.2])
def test_loss_rate_is_binomial(p: float) -> None:
    n = 20000
    ch = Channel(5, Outage(), loss=p)
    lost = sum(ch.offer(k * 0.001, b"x") is None for k in range(n))
    assert abs(lost - n * p) < 4 * math.sqrt(n * p * (1 - p))
    assert ch.counters.lost == lost and ch.counters.offered == n


def test_no_loss_and_total_loss() -> None:
    keep, drop = Channel(1, Outage(), loss=0.0), Channel(1, Outage(), loss=1.0)
    assert all(keep.offer(k, b"x") is not None for k in range(1000))
    assert all(drop.offer(k, b"x") is None for k in range(1000))


def test_a_seed_reproduces_every_draw_and_another_seed_does_not() -> None:
    def run(seed: int | str) -> list[float | None]:
        ch = Channel(seed, Outage(), delay_ms=100.0, jitter_ms=30.0, loss=0.2)
        return [ch.offer(k * 1.0, b"x") for k in range(500)]

    assert run("0:air") == run("0:air")
    assert run("0:air") != run("0:ground")


# -- outages -----------------------------------------------------------------------------------
def test_an_outage_blackholes_what_is_offered_or_due_inside_it() -> None:
    outage = Outage()
    ch = Channel(0, outage, delay_ms=100.0)
    assert outage.begin(10.0, 2.0) == 12.0  # down over [10, 12)
    ch.offer(9.5, b"before")        # due 9.6: delivered
    ch.offer(9.95, b"in-flight")    # due 10.05: inside the outage
    assert ch.offer(10.5, b"during") is None
    assert ch.offer(11.999, b"late") is None
    ch.offer(12.0, b"after")        # the link is up at 12.0: due 12.1
    assert ch.due(20.0) == [b"before", b"after"]
    assert ch.counters.blackholed == 3


def test_an_open_outage_lasts_until_the_link_is_restored() -> None:
    outage = Outage()
    outage.begin(1.0, math.inf)
    assert outage.down_at(1e6) and outage.until(5.0) == math.inf
    outage.end(7.0)
    assert outage.down_at(6.999) and not outage.down_at(7.0) and outage.until(7.0) is None


def test_a_second_outage_extends_the_first() -> None:
    outage = Outage()
    outage.begin(0.0, 10.0)
    outage.begin(5.0, 10.0)
    assert outage.until(6.0) == 15.0 and not outage.down_at(15.0)
    with pytest.raises(ValueError, match="> 0 s"):
        outage.begin(0.0, 0.0)


# -- control protocol --------------------------------------------------------------------------
def test_requests_parse() -> None:
    r = parse('{"cmd": "set", "source": "air", "delay_ms": 150, "loss": 0.05}', SOURCES)
    assert r.cmd == "set" and r.source == "air" and r.impairment is not None
    assert (r.impairment.delay_ms, r.impairment.jitter_ms, r.impairment.loss) == (150, 0, 0.05)
    assert parse('{"cmd": "set", "delay_ms": 1}', SOURCES).source is None
    assert parse('{"cmd": "outage", "seconds": 10}', SOURCES) == Request("outage", seconds=10.0)
    assert parse(b'{"cmd": "outage", "seconds": null}', SOURCES) == Request("outage")
    assert parse('{"cmd": "stats"}', SOURCES) == Request("stats")


@pytest.mark.parametrize(("line", "message"), [
    ("not json", "not JSON"),
    ("[1, 2]", "JSON object"),
    ('{"cmd": "reboot"}', "cmd must be one of"),
    ('{"cmd": "set", "loss": 5}', r"loss must be in \[0, 1\]"),
    ('{"cmd": "set", "delay_ms": -1}', "delay_ms must be in"),
    ('{"cmd": "set", "delay_ms": "10"}', "must be a number"),
    ('{"cmd": "set", "source": "moon"}', "source must be one of"),
    ('{"cmd": "set", "rate_mbit": 1}', "set takes delay_ms, jitter_ms, loss"),
    ('{"cmd": "outage", "seconds": -3}', "seconds must be"),
    ('{"cmd": "outage", "seconds": true}', "seconds must be"),
    ('{"cmd": "outage", "seconds": 1e400}', "seconds must be"),
    ('{"cmd": "outage", "seconds": 1, "x": 2}', "outage takes seconds only"),
    ('{"cmd": "up", "now": 1}', "up takes no fields"),
])
def test_bad_requests_are_refused_with_the_reason(line: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        parse(line, SOURCES)


def test_the_control_socket_applies_requests_and_refuses_bad_ones(tmp_path: Path) -> None:
    seen: list[Request] = []

    def handle(req: Request) -> dict[str, Any]:
        seen.append(req)
        return {"n": len(seen)}

    server = ControlServer(str(tmp_path / "c.sock"), SOURCES, handle)
    server.start()
    try:
        client = ControlClient(str(tmp_path / "c.sock"))
        assert client.call(cmd="outage", seconds=2.5) == {"ok": True, "n": 1}
        with pytest.raises(ImpairerError, match=r"loss must be in \[0, 1\]"):
            client.call(cmd="set", loss=1.5)
        assert seen == [Request("outage", seconds=2.5)]  # the refused one changed nothing
        # several requests on one connection, and a line too long
        with socket.socket(socket.AF_UNIX) as s:
            s.connect(str(tmp_path / "c.sock"))
            f = s.makefile("rwb")
            for line in (b'{"cmd": "ping"}\n', b"x" * 70000 + b"\n"):
                f.write(line)
                f.flush()
            replies = [json.loads(f.readline()), json.loads(f.readline())]
        assert replies[0] == {"ok": True, "n": 2}
        assert replies[1]["ok"] is False and "longer than" in replies[1]["error"]
    finally:
        server.close()
    assert not (tmp_path / "c.sock").exists()
    with pytest.raises(ImpairerError, match="c.sock"):
        ControlClient(str(tmp_path / "c.sock"), timeout_s=0.5).call(cmd="ping")
