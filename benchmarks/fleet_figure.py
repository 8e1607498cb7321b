"""The fleet-capacity curve: plan round trip p99 (and p50) against the number of vehicles.

Reads the ``capacity.json`` of one or more runs of benchmarks/fleet_capacity.py,
each given as ``LABEL=PATH`` (a run directory or its capacity.json), and
draws the round trip's p99 (solid) and p50 (dotted) and System 2's own
service p99 (dashed) per fleet size, with the 100 ms line the capacity is
judged by.

    .venv/bin/python benchmarks/fleet_figure.py "before=runs/fleet-old" "after=runs/fleet-new" \\
        --figure docs/figures/fleet_capacity.png
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import harness  # noqa: F401  (the repository on the path: before its packages)


def load(spec: str) -> tuple[str, list[dict[str, Any]]]:
    """``LABEL=PATH`` → (label, the run's rows sorted by fleet size)."""
    label, _, path = spec.partition("=")
    if not path:
        raise SystemExit(f"expected LABEL=PATH, got {spec!r}")
    p = Path(path)
    rows = json.loads((p / "capacity.json" if p.is_dir() else p).read_text())
    return label, sorted(rows, key=lambda r: r["vehicles"])


def draw(runs: list[tuple[str, list[dict[str, Any]]]], limit_ms: float, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.0, 5.2))
    for k, (label, rows) in enumerate(runs):
        color = f"C{k}"
        n = [r["vehicles"] for r in rows]
        ax.plot(n, [r["round_trip_ms"]["p99"] for r in rows], "o-", color=color,
                label=f"{label}: round trip p99")
        ax.plot(n, [r["round_trip_ms"]["p50"] for r in rows], "o:", color=color,
                label=f"{label}: round trip p50")
        ax.plot(n, [r["service_s2_ms"]["p99"] for r in rows], "s--", color=color, alpha=0.6,
                label=f"{label}: System 2 service p99")
    ax.axhline(limit_ms, color="k", lw=0.8)
    ax.text(1, limit_ms * 1.05, f"{limit_ms:g} ms", fontsize=8)
    ax.set_yscale("log")
    ax.set_xlabel("hosted vehicles at real time (2 cores)")
    ax.set_ylabel("plan round trip (ms)")
    ax.set_title("Fleet capacity: plan round trip against fleet size")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    print(f"wrote {path}")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("runs", nargs="+", help="LABEL=PATH of a fleet_capacity run (or capacity.json)")
    p.add_argument("--figure", type=Path, default=Path("docs/figures/fleet_capacity.png"))
    p.add_argument("--p99-ms", type=float, default=100.0)
    args = p.parse_args(argv)
    draw([load(s) for s in args.runs], args.p99_ms, args.figure)
    return 0


if __name__ == "__main__":
    sys.exit(main())
