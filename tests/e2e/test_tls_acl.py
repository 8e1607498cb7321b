"""Mutual TLS and the router's access control, real processes on loopback.

The stack runs with ``ZENOH_TLS_DIR`` (certificates of ``services.certs``):
the test process plays the supervisor with the supervisor's certificate and
checks that System 2 answers it; a peer without credentials (plain TCP, or
TLS with a certificate of another CA) cannot connect at all; a peer with a
valid certificate of the wrong service ("uavsim") can neither answer
``plan/system2`` nor publish on ``ews/*`` or ``plan/*`` nor claim System 2's
liveliness token. Last, a short mission through ``services.launch --tls``.
"""

from __future__ import annotations

import json
import queue
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import zenoh

from services import certs, launch
from services.common import bus, keys
from tests.support.waits import Logs, check, logs_in, wait_for

from .conftest import alive, router_ready, run_process

pytestmark = [pytest.mark.slow, pytest.mark.timeout(180)]

UAV = "tls1"
PLAN2 = keys.plan(UAV, 2)


@pytest.fixture(scope="module")
def stack(tmp_path_factory: pytest.TempPathFactory) -> Iterator[launch.Stack]:
    """Router, EWS, both planners and uavsim with TLS and access control; no supervisor."""
    run_dir = tmp_path_factory.mktemp("tls") / "stack"
    cfg = launch.StackConfig(run_dir=run_dir, free_ports=True, uav_id=UAV, log_format="text",
                             services=("ews", "system1", "system2", "uavsim"), tls=True)
    with launch.Stack(cfg) as st:
        router_ready(st.endpoint, logs_in(st.logs))
        yield st


def session(st: launch.Stack, identity: str) -> Any:
    assert st.tls_dir is not None
    return launch.client_session(st.endpoint, st.tls_dir, identity)


def holder(live: bus.Liveliness, service: str, logs: Logs, timeout_s: float = 60.0) -> str:
    alive(live, [service], timeout_s, logs)
    return wait_for(lambda: live.holder(service), timeout_s,
                    f"the session holding {service}'s token", logs)


def taken(q: queue.Queue[Any], pred: Callable[[Any], bool], timeout_s: float, what: str,
          logs: Logs) -> Any:
    """The first item of ``q`` with ``pred`` (the items before it are dropped)."""
    last: list[Any] = []

    def matching() -> Any:
        try:
            last[:] = [q.get(timeout=0.2)]
        except queue.Empty:
            return None
        return last[0] if pred(last[0]) else None

    return wait_for(matching, timeout_s, what, logs, period_s=0,
                    last=lambda: last[0] if last else "nothing")


def replies(sess: Any, key: str, timeout_s: float = 20.0) -> list[tuple[str, bytes, bool]]:
    """(replier zid, payload, ok) of every reply; the channel closes once every queryable the
    router routed the query to has answered (or at the timeout)."""
    out = []
    for rep in sess.get(key, payload=b"\x00not a plan request", timeout=timeout_s,
                        consolidation=zenoh.ConsolidationMode.NONE):
        body = rep.ok if rep.ok is not None else rep.err
        out.append((bus.replier(rep), body.payload.to_bytes(), rep.ok is not None))
    return out


def test_certs_name_each_service(tmp_path: Path) -> None:
    from cryptography import x509
    from cryptography.x509.oid import NameOID

    assert certs.make(tmp_path) and not certs.make(tmp_path)  # a complete directory is kept
    for name in certs.IDENTITIES:
        cert = x509.load_pem_x509_certificate((tmp_path / f"{name}.pem").read_bytes())
        cn = cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value
        assert cn == name
        assert (tmp_path / f"{name}.key").stat().st_mode & 0o077 == 0
    zenoh.Config.from_json5((tmp_path / "zenohd.json5").read_text())  # zenohd's, as compose's


def test_supervisor_credentials_get_the_real_planner(stack: launch.Stack) -> None:
    with session(stack, "supervisor") as sup:
        live = bus.Liveliness(sup, UAV)
        real = holder(live, "system2", logs_in(stack.logs))
        got = replies(sup, PLAN2)
    assert got and {zid for zid, _, _ in got} == {real}, got


def plain_or_foreign_open(conf: zenoh.Config) -> None:
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("connect/timeout_ms", "3000")
    conf.insert_json5("connect/exit_on_failure", "true")
    with pytest.raises(zenoh.ZError):
        zenoh.open(conf).close()


def test_no_credentials_no_connection(stack: launch.Stack, tmp_path: Path) -> None:
    plain = zenoh.Config()  # plain TCP to the router's TLS port
    plain.insert_json5("connect/endpoints", json.dumps([stack.endpoint]))
    plain_or_foreign_open(plain)
    certs.make(tmp_path, ca_name="another CA")  # a valid-looking "supervisor" of another CA
    foreign = zenoh.Config()
    foreign.insert_json5("connect/endpoints", json.dumps(bus.tls_endpoints([stack.endpoint])))
    foreign.insert_json5("transport/link/tls",
                         json.dumps(bus.tls_config(str(tmp_path), "supervisor")))
    plain_or_foreign_open(foreign)


class Marker:
    """Liveliness tokens the rogue may declare (its own ``alive/uavsim/<zid>-<n>``), awaited by
    the supervisor: the router handles one link's messages in order, so once a marker arrives
    everything the rogue sent before it has been admitted or dropped."""

    def __init__(self, sup: Any, rogue: Any, logs: Logs):
        self.rogue, self.zid, self.n, self.logs = rogue, str(rogue.info.zid()), 0, logs
        self.seen: queue.Queue[str] = queue.Queue()
        self.sub = sup.liveliness().declare_subscriber(
            keys.alive(UAV, "uavsim") + "/**", lambda s: self.seen.put(str(s.key_expr)))
        self.tokens: list[Any] = []

    def sync(self) -> None:
        self.n += 1
        key = keys.holder(UAV, "uavsim", f"{self.zid}-{self.n}")
        self.tokens.append(self.rogue.liveliness().declare_token(key))
        taken(self.seen, lambda k: k == key, 20, f"the supervisor to see the marker {key}",
              self.logs)

    def close(self) -> None:
        for obj in (*self.tokens, self.sub):
            obj.undeclare()


ROGUE = (b"rogue fires", b"rogue plan", b"rogue command")


def test_wrong_service_can_neither_answer_nor_publish(stack: launch.Stack) -> None:
    fires = keys.fires(UAV)
    with session(stack, "supervisor") as sup, session(stack, "uavsim") as rogue, \
            session(stack, "ews") as ews:
        logs = logs_in(stack.logs)
        live = bus.Liveliness(sup, UAV)
        real = holder(live, "system2", logs)
        received: queue.Queue[tuple[str, bytes]] = queue.Queue()
        sub = sup.declare_subscriber(f"{keys.ns(UAV)}/**", lambda s: received.put(
            (str(s.key_expr), s.payload.to_bytes())))
        marker = Marker(sup, rogue, logs)
        impostor = rogue.declare_queryable(PLAN2)  # a channel: what reaches it stays there
        claim = rogue.liveliness().declare_token(
            keys.holder(UAV, "system2", str(rogue.info.zid())))
        marker.sync()  # the router has seen (and refused) the queryable and the claim
        # the supervisor's query still reaches only the real planner (the channel of replies
        # closes when every queryable the router sent it to has answered: System 2 alone)
        got = replies(sup, PLAN2)
        assert got and {zid for zid, _, _ in got} == {real}, got
        assert impostor.try_recv() is None
        # puts on the EWS's and a planner's keys are dropped at the router
        rogue.put(fires, ROGUE[0])
        rogue.put(PLAN2, ROGUE[1])
        rogue.put(keys.fire_command(UAV), ROGUE[2])
        marker.sync()
        ews.put(fires, b"real fires")  # the owner's put does arrive

        def real_fires(item: tuple[str, bytes]) -> bool:
            assert item[1] not in ROGUE, item
            return item == (fires, b"real fires")

        taken(received, real_fires, 20, "the EWS's own put on its fires key", logs)
        while not received.empty():
            assert (item := received.get())[1] not in ROGUE, item
        # and its claim on System 2's token never reached anyone
        assert live.holders.get("system2") == [real]
        marker.close()
        for obj in (claim, impostor, sub, live.sub):
            obj.undeclare()


def test_mission_through_launch_tls(tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc = run_process(
        [sys.executable, "-m", "services.launch", "--tls", "--max-steps", "5", "--free-ports",
         "--speed-factor", "50", "--no-figures", "--quiet", "--log-format", "text",
         "--timeout-s", "120", "--out", str(out)], 170, "services.launch --tls",
        lambda: logs_in(out), cwd=launch.REPO)
    check(proc.returncode == 0, "services.launch --tls to exit with 0", logs_in(out),
          proc.stdout[-3000:] + proc.stderr[-3000:])
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"] == 5 and summary["ending"] == "step_limit", summary
    assert certs.is_complete(out / "tls")
    assert "all cleanly" in proc.stdout
    assert "tls=" in (out / "logs" / "system2.log").read_text()
