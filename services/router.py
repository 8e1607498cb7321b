"""A Zenoh router in a Python process: the local stand-in for ``zenohd``.

No package here ships zenohd; a zenoh-python session in ``router`` mode
routes for clients just the same (ARCHITECTURE §10). ``docker compose`` uses
the ``eclipse/zenoh`` image instead. ``python -m services.router --listen
tcp/127.0.0.1:7447``.

``--zenoh-connect`` (default ``ROUTER_CONNECT``) joins other routers: an air host's router
joins the ground's (docs/deployment.md), and ``ZENOH_LEASE_MS`` sets the lease of that
session.

With ``ZENOH_TLS_DIR`` (``--zenoh-tls-dir``, certificates of ``python -m
services.certs``) it listens on ``tls/`` instead, requires each session's
certificate from that CA (mutual TLS) and enforces the access control of
services/common/acl.py (default deny; what each service may publish, answer
and ask, by certificate common name): bus.zenoh_config builds it all.
"""

from __future__ import annotations

from services.common import bus
from services.common import cli as common_cli


def main(argv: list[str] | None = None) -> int:
    p = common_cli.parser("router", __doc__.splitlines()[0])
    p.set_defaults(zenoh_mode="router", zenoh_connect=common_cli.env("ROUTER_CONNECT", ""),
                   zenoh_listen=common_cli.env("ZENOH_LISTEN", "tcp/127.0.0.1:7447"))
    args = p.parse_args(argv)
    args.zenoh_mode = "router"
    try:
        settings = common_cli.settings("router", args)
    except ValueError as err:
        p.error(str(err))
    if not settings.zenoh_listen:
        p.error("a router needs --zenoh-listen")

    def body(ctx: bus.Context) -> None:
        ctx.announce()
        ctx.stop.wait()

    return bus.run_service(settings, body)


if __name__ == "__main__":
    bus.leave(main())
