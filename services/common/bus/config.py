"""The Zenoh session's configuration: mode, endpoints, scouting, shared memory, TLS."""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from typing import Any

import zenoh

from services.common import acl
from services.common.cli import Settings


def zenoh_config(s: Settings) -> zenoh.Config:
    """Mode, endpoints, no multicast scouting, no shared memory, a client that waits for its router.

    Shared memory is off: by default Zenoh puts every message over 3 KB (a
    plan, a fire update) in a 16 MB shared-memory pool that it builds lazily,
    inside the first such send, which stalled the sender for 5–6 ms early in
    every mission; our messages are a few kB, and containers do not share
    /dev/shm anyway.

    With ``ZENOH_TLS_DIR`` (``s.tls_dir``) the endpoints are ``tls/``, each
    session presents its service's certificate (mutual TLS, :func:`tls_config`),
    every non-router session is a client, and the router enforces the access
    control of :mod:`services.common.acl`.
    """
    conf = zenoh.Config()
    mode, connect, listen = s.zenoh_mode, list(s.zenoh_connect), list(s.zenoh_listen)
    if s.tls_dir:
        # TLS and access control (services/common/acl.py): every service is a client, so all
        # its traffic crosses the router, where the access control is enforced (a peer's
        # direct links to other peers would bypass it)
        if mode != "router":
            mode, listen = "client", []
        connect, listen = tls_endpoints(connect), tls_endpoints(listen)
        conf.insert_json5("transport/link/tls", json.dumps(tls_config(s.tls_dir, s.service)))
        if mode == "router":
            conf.insert_json5("access_control", json.dumps(acl.config()))
    conf.insert_json5("mode", json.dumps(mode))
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("transport/shared_memory/enabled", "false")
    conf.insert_json5("connect/endpoints", json.dumps(connect))
    conf.insert_json5("listen/endpoints", json.dumps(listen))
    # wait (forever) for the router, retrying quickly: compose starts services in any order
    conf.insert_json5("connect/timeout_ms", "-1")
    conf.insert_json5("connect/exit_on_failure", "false")
    conf.insert_json5("connect/retry",
                      "{period_init_ms: 100, period_max_ms: 1000, period_increase_factor: 2}")
    if s.zenoh_lease_ms:  # a deployment setting (docs/deployment.md); keep-alives: 4 a lease
        conf.insert_json5("transport/link/tx/lease", str(int(s.zenoh_lease_ms)))
    return conf


def tls_endpoints(endpoints: Iterable[str]) -> list[str]:
    """``tcp/host:port`` → ``tls/host:port`` (other endpoints as they are)."""
    return ["tls/" + e.removeprefix("tcp/") if e.startswith("tcp/") else e for e in endpoints]


def tls_config(tls_dir: str, identity: str) -> dict[str, Any]:
    """``transport/link/tls`` for mutual TLS: ``identity``'s key and certificate from
    ``tls_dir`` (made by ``python -m services.certs``) both ways, peers checked against its CA.

    The names are checked too (``verify_name_on_connect``): the router's certificate names
    localhost, 127.0.0.1 and the compose host ``zenoh``.
    """
    d = os.path.abspath(tls_dir)
    key, cert = os.path.join(d, f"{identity}.key"), os.path.join(d, f"{identity}.pem")
    for path in (key, cert, os.path.join(d, "ca.pem")):
        if not os.path.isfile(path):
            raise FileNotFoundError(f"ZENOH_TLS_DIR: no {path} (python -m services.certs "
                                    f"--out {tls_dir})")
    return {"root_ca_certificate": os.path.join(d, "ca.pem"), "enable_mtls": True,
            "listen_private_key": key, "listen_certificate": cert,
            "connect_private_key": key, "connect_certificate": cert,
            "verify_name_on_connect": True}
