"""What the benchmark scripts share: the repository on the path, CPU load, summaries, output.

Every script in benchmarks/ imports this module first (``import harness``): it
puts the repository on ``sys.path`` (a script run as ``python benchmarks/x.py``
finds ``dualpilot`` and ``services`` without an install), starts and stops the
busy processes a measurement under load runs beside (:func:`busy`), sums a sample
up the same way everywhere (:func:`quantiles`) and writes its figures
(:func:`emit`). Figures are reported, never asserted (docs/benchmarks.md).
"""

from __future__ import annotations

import contextlib
import json
import subprocess
import sys
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

#: seeds the in-process cognitive controller flies to the goal with the paper's timing
#: (found at the time of writing; benchmarks/load_vehicles.py --check re-verifies them)
SUCCESS_SEEDS = (26, 57, 125, 214, 271, 302, 329, 336, 358, 360)


def cpu_load(n: int) -> list[subprocess.Popen[bytes]]:
    """``n`` processes that keep a core busy each until killed (see :func:`busy`)."""
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]


@contextlib.contextmanager
def busy(n: int) -> Iterator[list[subprocess.Popen[bytes]]]:
    """``n`` busy processes for the ``with`` block; killed on the way out, however it ends."""
    procs = cpu_load(n)
    try:
        yield procs
    finally:
        for proc in procs:
            proc.kill()
            proc.wait()


def quantiles(values: Iterable[float], qs: Iterable[float] = (50, 99), ndigits: int = 2,
              scale: float = 1.0) -> dict[str, float]:
    """``{"p50": …, "p99": …, "max": …, "n": …}`` of ``values`` × ``scale`` (percentiles ``qs``;
    an empty sample gives zeros and n = 0)."""
    a = np.asarray(list(values), dtype=float) * scale
    n = len(a)
    if not n:
        a = np.zeros(1)
    out = {f"p{q:g}": round(float(np.percentile(a, q)), ndigits) for q in qs}
    out["max"] = round(float(a.max()), ndigits)
    out["n"] = n
    return out


def emit(doc: Any, out: Path | None = None, indent: int | None = 2) -> None:
    """Print ``doc`` as JSON and, with ``out``, write it there too."""
    text = json.dumps(doc, indent=indent, default=str)
    print(text, flush=True)
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text + "\n")
