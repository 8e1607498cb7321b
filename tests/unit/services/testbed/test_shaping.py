"""The test bed's pure parts: impairments, tc command lines, hosts, addresses and names.

The tbf numbers are worked out by hand: 10 Mbit/s is 1.25 MB/s, so a 5 ms bucket is
6250 B and a 500 ms queue 625000 B; at 0.25 Mbit/s (31250 B/s) the bucket is held at two
1514-byte frames (3028 B) and the queue is 15625 B.
"""

from __future__ import annotations

import pytest

from services.testbed import shaping
from services.testbed.impairment import Impairment
from services.testbed.topology import TOPOLOGY, netns_name, owner


def test_impairment_defaults_are_a_perfect_link() -> None:
    imp = Impairment()
    assert (imp.delay_ms, imp.jitter_ms, imp.loss, imp.rate_mbit) == (0, 0, 0, None)
    assert not imp.per_frame and Impairment(loss=0.01).per_frame


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"loss": 5.0}, r"loss must be in \[0, 1\]"),          # percent for a fraction
    ({"delay_ms": 61_000.0}, "delay_ms must be in"),       # beyond a minute: a unit slip
    ({"jitter_ms": -1.0}, "jitter_ms must be in"),
    ({"rate_mbit": 0.0}, "rate_mbit must be in"),
    ({"delay_ms": float("nan")}, "delay_ms must be in"),
    ({"queue_ms": 0.0}, "queue_ms must be in"),
])
def test_impairment_refuses_values_out_of_range(kwargs: dict[str, float], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        Impairment(**kwargs)  # type: ignore[arg-type]


def test_impairment_wire_round_trip_and_unknown_fields() -> None:
    imp = Impairment(150.0, 20.0, 0.05, 1.0, 300.0)
    assert Impairment.from_wire(imp.wire()) == imp
    with pytest.raises(ValueError, match=r"unknown impairment fields \['latency'\]"):
        Impairment.from_wire({"latency": 3})


@pytest.mark.parametrize(("mbit", "expected"), [
    (10.0, (10_000_000, 6250, 625_000)),
    (1.0, (1_000_000, 3028, 62_500)),
    (0.25, (250_000, 3028, 15_625)),
])
def test_token_bucket_sizes(mbit: float, expected: tuple[int, int, int]) -> None:
    assert shaping.bucket(mbit, 500.0) == expected


def test_tbf_command_line() -> None:
    assert shaping.tbf_argv("radio-ground", 0.25, 500.0) == [
        "tc", "qdisc", "replace", "dev", "radio-ground", "root", "handle", "1:", "tbf",
        "rate", "250000bit", "burst", "3028", "limit", "15625"]


def test_without_netem_only_the_bandwidth_is_the_kernels() -> None:
    imp = Impairment(delay_ms=100.0, loss=0.1, rate_mbit=1.0)
    assert shaping.qdisc_argvs("d", imp, netem=False) == [shaping.tbf_argv("d", 1.0, 500.0)]
    assert shaping.qdisc_argvs("d", Impairment(delay_ms=100.0), netem=False) == []


def test_netem_is_a_child_of_tbf_or_the_root() -> None:
    imp = Impairment(delay_ms=150.0, jitter_ms=20.0, loss=0.05, rate_mbit=1.0)
    assert shaping.qdisc_argvs("d", imp, netem=True) == [
        shaping.tbf_argv("d", 1.0, 500.0),
        ["tc", "qdisc", "replace", "dev", "d", "parent", "1:1", "handle", "10:",
         "netem", "delay", "150ms", "20ms", "loss", "5%"]]
    assert shaping.qdisc_argvs("d", Impairment(delay_ms=300.0), netem=True) == [
        ["tc", "qdisc", "replace", "dev", "d", "root", "handle", "10:",
         "netem", "delay", "300ms", "loss", "0%"]]
    # an outage under netem: every frame lost, on a link that is otherwise perfect too
    assert shaping.qdisc_argvs("d", Impairment(), netem=True, down=True)[0][-2:] == [
        "loss", "100%"]


def test_tc_in_a_namespace() -> None:
    assert shaping.in_ns("ns1", ["tc", "qdisc", "del", "dev", "x", "root"]) == [
        "tc", "-n", "ns1", "qdisc", "del", "dev", "x", "root"]


def test_hosts_links_and_addresses() -> None:
    radio, telem = TOPOLOGY.links
    assert TOPOLOGY.link_between("ground", "air") is radio
    assert TOPOLOGY.link_between("air", "gcs") is telem
    with pytest.raises(KeyError, match="no link between ground and gcs"):
        TOPOLOGY.link_between("ground", "gcs")
    assert [TOPOLOGY.address(radio, h) for h in radio.hosts] == ["10.10.1.1", "10.10.1.2"]
    assert [TOPOLOGY.address(telem, h) for h in telem.hosts] == ["10.10.2.3", "10.10.2.1"]
    assert TOPOLOGY.mac(telem, "gcs") == "02:10:10:02:03:01"
    assert [lk.name for lk in TOPOLOGY.links_of("air")] == ["radio", "telem"]
    # interface names fit IFNAMSIZ (15 characters)
    assert all(len(lk.wire_end(h)) <= 15 for lk in TOPOLOGY.links for h in lk.hosts)


def test_namespace_names_carry_their_owner() -> None:
    name = netns_name(4242, 3, "ground")
    assert name == "dptb4242-3-ground" and owner(name) == (4242, 3)
    for other in ("ground", "dptb-3-air", "dptbx-1-air", "cni-1234", "dptb12-1-Air"):
        assert owner(other) is None
