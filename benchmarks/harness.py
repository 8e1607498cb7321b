"""What the benchmark scripts share: the repository on the path, CPU load, summaries, output.

Every script in benchmarks/ imports this module first (``import harness``): it
puts the repository on ``sys.path`` (a script run as ``python benchmarks/x.py``
finds ``dualpilot`` and ``services`` without an install), starts and stops the
busy processes a measurement under load runs beside (:func:`busy`), sums a sample
up the same way everywhere (:func:`quantiles`), writes its figures
(:func:`emit`), runs ``dualpilot evaluate`` and reads its rows (:func:`run_evaluate`,
:func:`read_results`) and pairs two runs' successes (:func:`mcnemar`). Figures are
reported, never asserted (docs/benchmarks.md).
"""

from __future__ import annotations

import contextlib
import csv
import json
import subprocess
import sys
import time
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy.stats import binomtest

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


#: one row of an evaluation's results.csv, column → text
Row = dict[str, str]


def run_evaluate(missions: int, seed: int, jobs: int, controllers: str, out: Path,
                 extra: Sequence[str] = ()) -> float:
    """Run ``dualpilot evaluate`` with the paper's timing into ``out`` (``extra``: its further
    flags, e.g. ``--profile``, ``--set``); the run's wall time (s)."""
    cmd = [sys.executable, "-m", "dualpilot.cli", "evaluate", "--missions", str(missions),
           "--seed", str(seed), "--jobs", str(jobs), "--timing", "paper", "--controllers",
           controllers, "--out", str(out), *extra]
    start = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, cwd=REPO)
    return time.perf_counter() - start


def read_results(out: Path) -> dict[tuple[str, str], Row]:
    """The rows of the evaluation in ``out`` (its results.csv), keyed (mission, controller)."""
    with (out / "results.csv").open() as f:
        return {(r["mission"], r["controller"]): r for r in csv.DictReader(f)}


def mcnemar(pairs: Iterable[tuple[Row, Row]]) -> tuple[int, int, float | None]:
    """McNemar's exact test on paired missions: (successes of the first run only, of the second
    only, the two-sided binomial p on those discordant pairs; None when there are none)."""
    flags = [(a["success"] == "1", b["success"] == "1") for a, b in pairs]
    only_a = sum(a and not b for a, b in flags)
    only_b = sum(b and not a for a, b in flags)
    p = float(binomtest(only_a, only_a + only_b).pvalue) if only_a + only_b else None
    return only_a, only_b, p
