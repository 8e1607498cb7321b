"""A local certificate authority and one key and certificate per service, for Zenoh's mutual TLS.

``python -m services.certs --out DIR`` (``make certs``) writes ``DIR/ca.pem``
(the CA's certificate; its key ``ca.key`` is written too, to sign more
later, and is never given to a service) and ``DIR/<service>.pem`` and
``DIR/<service>.key`` for the router and each service of
:data:`services.common.keys.SERVICES`: the certificate's common name is the
service's name (the router's access control matches it,
services/common/acl.py; "monitor" may only listen), its subject alternative names ``localhost``,
``127.0.0.1`` and the service's compose host name. ``ZENOH_TLS_DIR=DIR``
turns TLS and access control on (services/common/bus.py).

It also writes ``DIR/zenohd.json5``, the same router configuration for the
``eclipse/zenoh`` image's ``zenohd --config`` (TLS listener on port 7447, the
access control), naming the files as mounted at ``--mount`` (default
``/certs``) in the container: docker-compose.yml shows how.

Keys are EC P-256, certificates valid for ``--days`` (default 825) days.
An existing directory is left as it is unless ``--force`` is given.
"""

from __future__ import annotations

import argparse
import datetime as dt
import ipaddress
import json
import os
import sys
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from services.common import acl
from services.common.keys import SERVICES

#: the identities a CA made here names: the router, every service and the launcher's read-only
#: observer "monitor"
IDENTITIES = ("router", *SERVICES, "monitor")
#: compose host names beside the service names (the router's service is called "zenoh")
HOSTS = {"router": ("zenoh",)}


def _key() -> ec.EllipticCurvePrivateKey:
    return ec.generate_private_key(ec.SECP256R1())


def _write_key(path: Path, key: ec.EllipticCurvePrivateKey) -> None:
    data = key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                             serialization.NoEncryption())
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as f:
        f.write(data)


def _write_cert(path: Path, cert: x509.Certificate) -> None:
    path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))


def make_ca(out: Path, name: str = "dualpilot local CA",
            days: int = 825) -> tuple[ec.EllipticCurvePrivateKey, x509.Certificate]:
    key = _key()
    subject = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)])
    now = dt.datetime.now(dt.UTC)
    cert = (x509.CertificateBuilder().subject_name(subject).issuer_name(subject)
            .public_key(key.public_key()).serial_number(x509.random_serial_number())
            .not_valid_before(now - dt.timedelta(minutes=5))
            .not_valid_after(now + dt.timedelta(days=days))
            .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
            .add_extension(x509.KeyUsage(digital_signature=True, key_cert_sign=True,
                                         crl_sign=True, content_commitment=False,
                                         key_encipherment=False, data_encipherment=False,
                                         key_agreement=False, encipher_only=False,
                                         decipher_only=False), critical=True)
            .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()),
                           critical=False)
            .sign(key, hashes.SHA256()))
    _write_key(out / "ca.key", key)
    _write_cert(out / "ca.pem", cert)
    return key, cert


def make_identity(out: Path, name: str, ca_key: ec.EllipticCurvePrivateKey,
                  ca_cert: x509.Certificate, days: int = 825) -> None:
    """``out/<name>.key`` and ``out/<name>.pem``: common name ``name``, signed by the CA."""
    key = _key()
    now = dt.datetime.now(dt.UTC)
    sans: list[x509.GeneralName] = [x509.DNSName(name), x509.DNSName("localhost"),
                                    *(x509.DNSName(h) for h in HOSTS.get(name, ())),
                                    x509.IPAddress(ipaddress.ip_address("127.0.0.1")),
                                    x509.IPAddress(ipaddress.ip_address("::1"))]
    cert = (x509.CertificateBuilder()
            .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)]))
            .issuer_name(ca_cert.subject).public_key(key.public_key())
            .serial_number(x509.random_serial_number())
            .not_valid_before(now - dt.timedelta(minutes=5))
            .not_valid_after(now + dt.timedelta(days=days))
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            .add_extension(x509.SubjectAlternativeName(sans), critical=False)
            .add_extension(x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH,
                                                  ExtendedKeyUsageOID.CLIENT_AUTH]),
                           critical=False)
            .add_extension(x509.AuthorityKeyIdentifier.from_issuer_public_key(
                ca_key.public_key()), critical=False)
            .sign(ca_key, hashes.SHA256()))
    _write_key(out / f"{name}.key", key)
    _write_cert(out / f"{name}.pem", cert)


def zenohd_config(mount: str = "/certs") -> dict[str, object]:
    """The router's config for ``zenohd --config`` with the certificates at ``mount``."""
    key, cert = f"{mount}/router.key", f"{mount}/router.pem"
    return {
        "mode": "router",
        "listen": {"endpoints": ["tls/[::]:7447"]},
        "scouting": {"multicast": {"enabled": False}},
        "transport": {"link": {"tls": {
            "root_ca_certificate": f"{mount}/ca.pem", "enable_mtls": True,
            "listen_private_key": key, "listen_certificate": cert,
            "connect_private_key": key, "connect_certificate": cert,
            "verify_name_on_connect": True}}},
        "access_control": acl.config(),
    }


def is_complete(out: Path, names: tuple[str, ...] = IDENTITIES) -> bool:
    files = ["ca.pem", *(f"{n}.{ext}" for n in names for ext in ("pem", "key"))]
    return all((out / f).is_file() for f in files)


def make(out: Path, names: tuple[str, ...] = IDENTITIES, force: bool = False,
         days: int = 825, ca_name: str = "dualpilot local CA", mount: str = "/certs") -> bool:
    """Make the CA, the identities and zenohd.json5 in ``out``; False (nothing written) when
    they exist."""
    if is_complete(out, names) and not force:
        return False
    out.mkdir(parents=True, exist_ok=True)
    (out / "zenohd.json5").write_text(json.dumps(zenohd_config(mount), indent=2) + "\n")
    ca_key, ca_cert = make_ca(out, ca_name, days)
    for name in names:
        make_identity(out, name, ca_key, ca_cert, days)
    return True


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m services.certs",
                                description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, required=True, help="directory to write (ZENOH_TLS_DIR)")
    p.add_argument("--days", type=int, default=825)
    p.add_argument("--mount", default="/certs",
                   help="where a container sees DIR (the paths in DIR/zenohd.json5)")
    p.add_argument("--force", action="store_true", help="replace an existing CA and keys")
    args = p.parse_args(argv)
    made = make(args.out, force=args.force, days=args.days, mount=args.mount)
    print(f"{'made' if made else 'kept the existing'} CA and certificates for "
          f"{', '.join(IDENTITIES)} in {args.out}/", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
