"""Generate the Python message classes in ``services/msgs`` from ``proto/`` (``make proto``).

protoc names Python modules after the .proto paths (``dualpilot/v1/…``), which
would clash with the core package ``dualpilot``; the generated modules are
therefore flattened into ``services/msgs`` and their imports rewritten to
``services.msgs``. The descriptors keep their ``dualpilot.v1`` names.

``python -m services.protogen [--out DIR]``; a test regenerates into a temporary
directory and compares, so stale generated code fails the suite.
"""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
PROTO_ROOT = REPO / "proto"
PROTO_DIR = PROTO_ROOT / "dualpilot" / "v1"
MSGS_DIR = REPO / "services" / "msgs"
_IMPORT = re.compile(r"^from dualpilot\.v1 import ", re.MULTILINE)
INIT = '"""Generated protobuf messages of dualpilot.v1 (``make proto``; do not edit)."""\n'


def generate(out_dir: Path = MSGS_DIR) -> list[Path]:
    """Run protoc on every ``proto/dualpilot/v1/*.proto`` and write the modules to ``out_dir``."""
    import grpc_tools
    from grpc_tools import protoc

    protos = sorted(PROTO_DIR.glob("*.proto"))
    if not protos:
        raise FileNotFoundError(f"no .proto files under {PROTO_DIR}")
    include = Path(grpc_tools.__file__).parent / "_proto"
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        args = [
            "protoc", f"-I{PROTO_ROOT}", f"-I{include}",
            f"--python_out={tmp}", f"--pyi_out={tmp}",
            *(str(p.relative_to(PROTO_ROOT)) for p in protos),
        ]
        if protoc.main(args) != 0:
            raise RuntimeError(f"protoc failed: {' '.join(args)}")
        written = []
        for src in sorted((Path(tmp) / "dualpilot" / "v1").iterdir()):
            if src.suffix not in (".py", ".pyi"):
                continue
            dst = out_dir / src.name
            dst.write_text(_IMPORT.sub("from services.msgs import ", src.read_text()))
            written.append(dst)
    init = out_dir / "__init__.py"
    init.write_text(INIT)
    return [init, *written]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=MSGS_DIR)
    parser.add_argument("--clean", action="store_true", help="remove *_pb2* files in --out first")
    args = parser.parse_args(argv)
    if args.clean and args.out.is_dir():
        for old in args.out.glob("*_pb2.py*"):
            old.unlink()
    for path in generate(args.out):
        print(path)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
