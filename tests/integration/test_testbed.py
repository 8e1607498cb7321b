"""The test bed for real: hosts in network namespaces, flows through the shaped links.

Where namespaces cannot be made the ``testbed`` fixture skips these tests with its reason
(the last tests check that both ways). No assertion here reads how long the machine took:
delays are checked as lower bounds (a frame cannot arrive before the impairer's delay has
passed; load only adds), losses against the binomial law and the impairer's own counters, an
outage by which datagrams it must have blackholed and which it must have let through, the
bandwidth as an upper bound on a transfer's rate.
"""

from __future__ import annotations

import math
import os
import signal
import socket
import subprocess
import sys
import tempfile
import textwrap
import threading
import time
from pathlib import Path

import pytest

from services.testbed import leftovers, measure, netns
from services.testbed.availability import unavailable
from services.testbed.bed import TestBed
from services.testbed.impairment import Impairment
from services.testbed.topology import LinkSpec, Topology, owner
from tests.support.testbed import SKIP_PREFIX
from tests.support.waits import wait_for

REPO = Path(__file__).resolve().parents[2]
NOBODY = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"]


def owned_by(pid: int) -> list[str]:
    """The namespaces of every test bed process ``pid`` made."""
    return [ns for ns in netns.names() if (key := owner(ns)) is not None and key[0] == pid]


def mine(bed: TestBed) -> list[str]:
    """Namespaces and scratch directories of ``bed`` still on the machine."""
    left = [ns for ns in netns.names() if owner(ns) == (bed.pid, bed.serial)]
    return left + ([str(bed.scratch)] if bed.scratch.exists() else [])


# -- hosts ------------------------------------------------------------------------------------
def test_hosts_reach_their_peers_and_nothing_else(testbed: TestBed) -> None:
    air, ground, gcs = (testbed.host(h) for h in ("air", "ground", "gcs"))
    assert all(rtt is not None for rtt in measure.ping(air, ground, 3, 0.01))
    assert all(rtt is not None for rtt in measure.ping(gcs, air, 3, 0.01))
    routes = ground.run(["ip", "route"]).stdout
    assert "default" not in routes and "10.10.1.0/24 dev radio" in routes
    with measure.socket_in(ground.netns) as s, pytest.raises(OSError, match="unreachable"):
        s.sendto(b"x", (gcs.address("air"), 9))  # ground has no way to the ground station
    listing = air.run(["ip", "-br", "addr"]).stdout
    assert "10.10.1.1/24" in listing and "10.10.2.1/24" in listing and "127.0.0.1" in listing


def test_a_process_started_in_a_host_runs_there_and_stops_with_the_bed(tmp_path: Path) -> None:
    if reason := unavailable():
        pytest.skip(SKIP_PREFIX + reason)
    with TestBed(logs=tmp_path) as bed:
        proc = bed.host("ground").start("sleeper", [sys.executable, "-c",
                                                    "import time; time.sleep(600)"])
        # ``ip netns exec`` enters the namespace after the fork: the pid is listed once it has
        wait_for(lambda: proc.popen.pid in netns.pids(bed.host("ground").netns), 10.0,
                 "the sleeper's pid among the ground namespace's",
                 last=lambda: netns.pids(bed.host("ground").netns))
    assert proc.popen.returncode is not None and mine(bed) == []


# -- the impairer, measured with real packets -------------------------------------------------
def test_delay_and_jitter_are_lower_bounds_of_every_datagram(testbed: TestBed) -> None:
    radio = testbed.link("radio")
    radio.set(Impairment(delay_ms=100.0, jitter_ms=10.0), source="air")
    radio.set(Impairment(delay_ms=40.0), source="ground")
    air, ground = testbed.host("air"), testbed.host("ground")
    flow = measure.udp_flow(air, ground, 200, 100.0, drain_s=1.0)
    assert flow.received == 200 and flow.out_of_order == 0
    assert min(flow.delays_ms.values()) >= 90.0
    rtts = measure.ping(air, ground, 5, 0.05)
    assert all(r is not None and r >= 90.0 + 40.0 for r in rtts)  # each way its own delay
    stats = radio.stats()["directions"]
    assert stats["air"]["delay_ms"] == 100.0 and stats["ground"]["delay_ms"] == 40.0


@pytest.mark.parametrize("loss", [0.05, 0.2])
def test_loss_follows_the_binomial_law_and_the_counters(testbed: TestBed, loss: float) -> None:
    radio = testbed.link("radio")
    radio.set(Impairment(loss=loss), source="air")
    n = 2000
    flow = measure.udp_flow(testbed.host("air"), testbed.host("ground"), n, 1000.0, drain_s=1.0)
    lost = n - flow.received
    assert abs(lost - n * loss) < 5 * math.sqrt(n * loss * (1 - loss))
    stats = radio.stats()
    up = stats["directions"]["air"]
    assert stats["kernel_drops"] == 0 and stats["oversize"] == 0
    assert up["offered"] == n and up["lost"] == lost and up["delivered"] == flow.received
    assert stats["directions"]["ground"]["offered"] == 0  # nothing comes back over UDP


def test_jitter_never_reorders(testbed: TestBed) -> None:
    testbed.link("radio").set(Impairment(delay_ms=50.0, jitter_ms=40.0))
    flow = measure.udp_flow(testbed.host("air"), testbed.host("ground"), 1000, 1000.0,
                            drain_s=1.0)
    assert flow.received == 1000 and flow.out_of_order == 0


#: how long a datagram may wait for the impairer to read it on a loaded machine: one offered
#: this little before the outage began may meet it (seen: one sent ms before, two tests
#: side by side on 2 cores)
READ_GRACE_S = 0.25


def test_an_outage_at_run_time_blackholes_exactly_its_window(testbed: TestBed) -> None:
    radio, seconds = testbed.link("radio"), 2.0
    flows: list[measure.Flow] = []
    sender = threading.Thread(target=lambda: flows.append(measure.udp_flow(
        testbed.host("air"), testbed.host("ground"), 600, 100.0, drain_s=1.0)))
    sender.start()
    time.sleep(2.0)  # the flow runs for 6 s; the outage starts about a third of the way in
    before = time.monotonic()
    radio.outage(seconds)
    after = time.monotonic()
    sender.join()
    flow = flows[0]
    for seq, sent in enumerate(flow.sent_at):
        if sent >= after + seconds:    # offered after the window: must come through
            assert seq in flow.arrived_at, f"datagram {seq} sent after the outage was lost"
        elif sent >= after and seq in flow.arrived_at:   # offered inside or after the window
            assert flow.arrived_at[seq] >= before + seconds
        elif sent < before - READ_GRACE_S:  # offered well before: nothing else in the way
            assert seq in flow.arrived_at
    blackholed = radio.stats()["directions"]["air"]["blackholed"]
    assert blackholed == flow.sent - flow.received > 0


def test_an_open_outage_lasts_until_restored(testbed: TestBed) -> None:
    radio = testbed.link("radio")
    air, ground = testbed.host("air"), testbed.host("ground")
    radio.outage(None)
    assert measure.ping(air, ground, 3, 0.0, timeout_s=0.3) == [None, None, None]
    assert radio.stats()["down_for_s"] == "ever"
    radio.restore()
    assert all(r is not None for r in measure.ping(air, ground, 3, 0.0))


def test_the_bandwidth_bounds_a_tcp_transfer(testbed: TestBed) -> None:
    testbed.link("radio").set(Impairment(rate_mbit=1.0, delay_ms=20.0))
    nbytes = 250_000  # 2 s at 1 Mbit/s
    done = measure.tcp_transfer(testbed.host("air"), testbed.host("ground"), nbytes)
    assert done.nbytes == nbytes
    # the bucket (3028 B) is the most that can pass faster than the rate
    assert done.seconds >= (nbytes - 3028) * 8 / 1e6
    qdisc = subprocess.run(["tc", "-n", testbed.wire, "qdisc", "show", "dev", "radio-ground"],
                           capture_output=True, text=True, check=True).stdout
    assert "tbf" in qdisc and "rate 1Mbit" in qdisc


def test_the_ground_stations_link_is_shaped_on_its_own(testbed: TestBed) -> None:
    testbed.link("telem").set(Impairment(loss=0.1))
    n = 1000
    air, ground, gcs = (testbed.host(h) for h in ("air", "ground", "gcs"))
    telem = measure.udp_flow(gcs, air, n, 1000.0, drain_s=0.5)
    radio = measure.udp_flow(ground, air, n, 1000.0, drain_s=0.5)
    assert abs((n - telem.received) - 100) < 5 * math.sqrt(n * 0.1 * 0.9)
    assert radio.received == n


# -- up and down ------------------------------------------------------------------------------
def test_down_leaves_nothing_behind(tmp_path: Path) -> None:
    if reason := unavailable():
        pytest.skip(SKIP_PREFIX + reason)
    root_links = netns.ip("-br", "link").stdout
    bed = TestBed(logs=tmp_path)
    with bed:
        impairers = [link.proc for link in bed.links.values()]  # type: ignore[attr-defined]
        assert len(mine(bed)) == 5  # four namespaces and the scratch directory
        assert all(p is not None and p.poll() is None for p in impairers)
    assert mine(bed) == []
    assert all(p is not None and p.poll() is not None for p in impairers)
    assert netns.ip("-br", "link").stdout == root_links
    bed.down()  # again: nothing to do, no error


def test_a_failure_while_coming_up_undoes_what_was_made(tmp_path: Path) -> None:
    if reason := unavailable():
        pytest.skip(SKIP_PREFIX + reason)
    broken = Topology(hosts=("air", "ground"),
                      links=(LinkSpec("radio", "air", "ground", 1),
                             LinkSpec("telem", "gcs", "air", 2)))  # gcs: no such host
    bed = TestBed(topology=broken, logs=tmp_path)
    with pytest.raises(KeyError, match="gcs"):
        bed.up()
    assert mine(bed) == []


def test_a_crashed_owners_test_bed_is_removed_by_down(tmp_path: Path) -> None:
    if reason := unavailable():
        pytest.skip(SKIP_PREFIX + reason)
    script = textwrap.dedent("""
        import sys, time
        from services.testbed.bed import TestBed
        bed = TestBed(); bed.up()
        print(bed.scratch, flush=True)
        time.sleep(600)
    """)
    env = dict(os.environ, PYTHONPATH=str(REPO))
    owner_proc = subprocess.Popen([sys.executable, "-c", script], cwd=REPO, env=env,
                                  stdout=subprocess.PIPE, text=True)
    try:
        assert owner_proc.stdout is not None
        scratch = Path(owner_proc.stdout.readline().strip())
        ours = owned_by(owner_proc.pid)
        assert len(ours) == 4 and scratch.is_dir()
    finally:
        owner_proc.send_signal(signal.SIGKILL)  # no exit handler runs
        owner_proc.wait()
    wire = next(ns for ns in ours if ns.endswith("-wire"))
    deadline = time.monotonic() + 10
    while netns.pids(wire) and time.monotonic() < deadline:
        time.sleep(0.05)  # the impairers follow their owner (PR_SET_PDEATHSIG)
    assert netns.pids(wire) == []
    done = subprocess.run([sys.executable, "-m", "services.testbed", "down"], cwd=REPO,
                          env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert not set(ours) & set(netns.names()) and not scratch.exists()


def test_only_beds_whose_owner_is_gone_are_stale(testbed: TestBed) -> None:
    leftovers.remove_stale()  # this test's own bed: its owner is alive
    assert len(mine(testbed)) == 5


# -- where namespaces cannot be made ----------------------------------------------------------
def _skip_unless_root_and_nobody_can_run_python() -> None:
    if os.geteuid() != 0:
        pytest.skip(f"compares root with the user nobody (here: uid {os.geteuid()})")
    done = subprocess.run([*NOBODY, sys.executable, "-c", "pass"], capture_output=True,
                          timeout=60)
    if done.returncode != 0:
        pytest.skip(f"the user nobody cannot run {sys.executable}: {done.stderr[-200:]!r}")


def _unavailable_in(prefix: list[str], env: dict[str, str]) -> str:
    code = "from services.testbed.availability import unavailable; print(unavailable())"
    done = subprocess.run([*prefix, sys.executable, "-c", code], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=60, check=True)
    return done.stdout.strip()


def test_unavailable_says_why() -> None:
    if os.geteuid() != 0:
        pytest.skip(f"checks the reasons from root (here: uid {os.geteuid()})")
    env = dict(os.environ, PYTHONPATH=str(REPO))
    assert _unavailable_in([], env) == "None"
    no_ip = dict(env, PATH=str(Path(sys.executable).parent))
    assert _unavailable_in([], no_ip) == "no `ip` on PATH (Debian package iproute2)"


def test_unavailable_as_another_user_says_not_root() -> None:
    _skip_unless_root_and_nobody_can_run_python()
    env = dict(os.environ, PYTHONPATH=str(REPO))
    assert _unavailable_in(NOBODY, env).startswith("not root (uid 65534)")


def test_the_fixture_skips_with_the_reason_where_namespaces_cannot_be_made() -> None:
    _skip_unless_root_and_nobody_can_run_python()
    work = Path(tempfile.mkdtemp(prefix="testbed-fixture-"))
    try:
        work.chmod(0o755)
        (work / "conftest.py").write_text('pytest_plugins = ["tests.support.testbed"]\n')
        (work / "test_uses_the_bed.py").write_text(textwrap.dedent("""
            def test_bed(testbed):
                assert testbed.host("air").address("ground") == "10.10.1.1"
        """))
        for f in work.iterdir():
            f.chmod(0o644)
        env = dict(os.environ, PYTHONPATH=str(REPO), PYTHONDONTWRITEBYTECODE="1")
        argv = [sys.executable, "-m", "pytest", "-rs", "-p", "no:cacheprovider", "-q",
                "--rootdir", str(work), str(work)]
        as_nobody = subprocess.run([*NOBODY, *argv], cwd=work, env=env, capture_output=True,
                                   text=True, timeout=120)
        as_root = subprocess.run(argv, cwd=work, env=env, capture_output=True, text=True,
                                 timeout=120)
    finally:
        subprocess.run(["rm", "-rf", str(work)], check=False)
    assert "1 skipped" in as_nobody.stdout, as_nobody.stdout + as_nobody.stderr
    assert SKIP_PREFIX + "not root (uid 65534)" in as_nobody.stdout
    assert "1 passed" in as_root.stdout, as_root.stdout + as_root.stderr


def test_sockets_open_in_the_namespace_asked_for(testbed: TestBed) -> None:
    gcs = testbed.host("gcs").netns
    with measure.socket_in(gcs) as s:
        s.bind(("10.10.2.3", 0))  # an address only gcs has
    with measure.socket_in(gcs) as s, pytest.raises(OSError, match="assign"):
        s.bind(("10.10.1.2", 0))  # ground's
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as here, pytest.raises(OSError):
        here.bind(("10.10.2.3", 0))  # not in this process's own namespace


# -- the command line and netem -----------------------------------------------------------------
def test_the_command_brings_the_bed_up_and_takes_it_down_on_ctrl_c(tmp_path: Path) -> None:
    if reason := unavailable():
        pytest.skip(SKIP_PREFIX + reason)
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.Popen([sys.executable, "-m", "services.testbed", "up", "--delay-ms", "30",
                             "--loss", "0.01"], cwd=REPO, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True, start_new_session=True)
    try:
        assert proc.stdout is not None
        shown = []
        for line in proc.stdout:
            shown.append(line)
            if line.startswith("up;"):
                break
        text = "".join(shown)
        ours = owned_by(proc.pid)
        assert sorted(ours) == sorted(f"dptb{proc.pid}-1-{h}"
                                      for h in ("air", "ground", "gcs", "wire"))
        assert f"ip netns exec dptb{proc.pid}-1-air COMMAND" in text
        assert "radio 10.10.1.2" in text and "delay_ms=30.0" in text
    finally:
        os.killpg(proc.pid, signal.SIGINT)  # what Ctrl-C in a terminal sends
        code = proc.wait(30)
    assert code == 0
    assert owned_by(proc.pid) == []
    assert not leftovers.scratch_dir(proc.pid, 1).exists()


def test_netem_where_the_kernel_has_it_else_a_clear_refusal(tmp_path: Path) -> None:
    if reason := unavailable():
        pytest.skip(SKIP_PREFIX + reason)
    bed = TestBed(impairer="netem", logs=tmp_path)
    probe = TestBed(logs=tmp_path)  # "auto": the kernel's answer decides
    with probe:
        have_netem = probe.netem
        assert all(link.kind == ("netem" if have_netem else "impairer")
                   for link in probe.links.values())
    if not have_netem:
        with pytest.raises(netns.NetnsError, match="no netem qdisc"):
            bed.up()
        assert mine(bed) == []
        return
    with bed:  # a kernel with netem: the bridge, tbf and netem path, measured
        bed.link("radio").set(Impairment(delay_ms=60.0, rate_mbit=1.0))
        rtts = measure.ping(bed.host("air"), bed.host("ground"), 5, 0.05)
        assert all(r is not None and r >= 120.0 for r in rtts)
    assert mine(bed) == []
