"""Process settings shared by every service: CLI flags whose defaults come from the environment.

=================  ==================  =========================================
flag               environment         default
=================  ==================  =========================================
--uav-id           UAV_ID              uav1
--zenoh-connect    ZENOH_CONNECT       tcp/127.0.0.1:7447 (comma-separated)
--zenoh-listen     ZENOH_LISTEN        (none)
--zenoh-mode       ZENOH_MODE          client
--zenoh-tls-dir    ZENOH_TLS_DIR       (none: plain TCP; a directory made by
                                       ``python -m services.certs``: mutual TLS,
                                       client mode, the router's access control)
--speed-factor     SPEED_FACTOR        1 (0 or inf: unpaced)
--mavlink-url      MAVLINK_URL         per service (supervisor, uavsim)
--log-level        LOG_LEVEL           INFO
--log-format       LOG_FORMAT          json
--nice             NICE                0 (a simulator beside the system under test:
                                       10, so it never takes the planners' CPU)
--zenoh-lease-ms   ZENOH_LEASE_MS      0: Zenoh's own (10 s); how long a silent link
                                       keeps a session (docs/deployment.md)
=================  ==================  =========================================
"""

from __future__ import annotations

import argparse
import os
from dataclasses import dataclass

from . import keys
from .clock import check_speed_factor

DEFAULT_ZENOH = "tcp/127.0.0.1:7447"


def env(name: str, default: str) -> str:
    return os.environ.get(name, default)


@dataclass(frozen=True)
class Settings:
    service: str
    uav_id: str
    zenoh_connect: tuple[str, ...]
    zenoh_listen: tuple[str, ...]
    zenoh_mode: str
    speed_factor: float
    mavlink_url: str
    log_level: str
    log_format: str
    tls_dir: str = ""  # ZENOH_TLS_DIR: certificates of services.certs; "" is plain TCP
    nice: int = 0  # added to the process's nice value at start (0..19: lower priority only)
    #: the lease (ms) this session announces: a link silent for that long closes the session
    #: (0: Zenoh's default, 10 s; keep-alives go four times a lease)
    zenoh_lease_ms: int = 0


def _endpoints(text: str) -> tuple[str, ...]:
    return tuple(e.strip() for e in text.split(",") if e.strip())


def parser(service: str, description: str, mavlink_default: str = "") -> argparse.ArgumentParser:
    """An argument parser with the common flags; services add their own."""
    p = argparse.ArgumentParser(prog=f"python -m services.{service}", description=description)
    g = p.add_argument_group("common settings (flags override environment variables)")
    g.add_argument("--uav-id", default=env("UAV_ID", "uav1"), help="vehicle id [UAV_ID]")
    g.add_argument("--zenoh-connect", default=env("ZENOH_CONNECT", DEFAULT_ZENOH),
                   help="comma-separated Zenoh endpoints to connect to [ZENOH_CONNECT]")
    g.add_argument("--zenoh-listen", default=env("ZENOH_LISTEN", ""),
                   help="comma-separated Zenoh endpoints to listen on [ZENOH_LISTEN]")
    g.add_argument("--zenoh-mode", default=env("ZENOH_MODE", "client"),
                   choices=["client", "peer", "router"], help="Zenoh mode [ZENOH_MODE]")
    g.add_argument("--zenoh-tls-dir", default=env("ZENOH_TLS_DIR", ""),
                   help="mutual TLS and access control with the CA and certificates in this "
                        "directory (python -m services.certs) [ZENOH_TLS_DIR]")
    g.add_argument("--speed-factor", type=float, default=env("SPEED_FACTOR", "1"),
                   help="simulated seconds per wall second; 0 or inf: unpaced [SPEED_FACTOR]")
    if mavlink_default:
        g.add_argument("--mavlink-url", default=env("MAVLINK_URL", mavlink_default),
                       help="pymavlink connection string [MAVLINK_URL]")
    g.add_argument("--log-level", default=env("LOG_LEVEL", "INFO"), help="[LOG_LEVEL]")
    g.add_argument("--log-format", default=env("LOG_FORMAT", "json"), choices=["json", "text"],
                   help="[LOG_FORMAT]")
    g.add_argument("--zenoh-lease-ms", type=int, default=env("ZENOH_LEASE_MS", "0"),
                   help="the Zenoh lease this session announces, ms: a link silent this long "
                        "closes the session, which then reconnects; 0: Zenoh's own, 10 s "
                        "[ZENOH_LEASE_MS]")
    g.add_argument("--nice", type=int, default=env("NICE", "0"),
                   help="lower this process's priority by this much, 0..19 (a simulated vehicle "
                        "sharing a machine with the planners it tests) [NICE]")
    return p


def settings(service: str, args: argparse.Namespace) -> Settings:
    """Validate the common flags (ValueError on a bad value)."""
    connect = _endpoints(args.zenoh_connect)
    listen = _endpoints(args.zenoh_listen)
    if args.zenoh_mode == "client" and not connect:
        raise ValueError("a Zenoh client needs --zenoh-connect")
    if not 0 <= args.nice <= 19:
        raise ValueError(f"--nice must be in 0..19, got {args.nice}")
    lease = getattr(args, "zenoh_lease_ms", 0)
    if lease and not 500 <= lease <= 600_000:
        raise ValueError(f"--zenoh-lease-ms must be 0 or in 500..600000, got {lease}")
    return Settings(
        service=service,
        uav_id=keys.check_id(args.uav_id),
        zenoh_connect=connect,
        zenoh_listen=listen,
        zenoh_mode=args.zenoh_mode,
        speed_factor=check_speed_factor(args.speed_factor),
        mavlink_url=getattr(args, "mavlink_url", ""),
        log_level=args.log_level,
        log_format=args.log_format,
        tls_dir=getattr(args, "zenoh_tls_dir", ""),
        nice=args.nice,
        zenoh_lease_ms=lease,
    )
