"""3-D missions under fires taller than the band against the 2-D missions, over many seeds.

    .venv/bin/python benchmarks/consistency3d.py --seeds 40 --jobs 2

The sweep behind ``tests/unit/dualpilot/mission/test_consistency3d.py`` (which flies two
seeds of each case in ``make test``): for each controller whose 2-D planners fly under
the reduction (cc, s1, s2, cc+risk) and each of the paper's process, grass-5 and shrub,
seeds 0..N-1 of the mission flown in 2-D and in 3-D with ``fire_height=above-ceiling``
by the same planners (tests/support/lifted.py), compared row for row by the test's own
check (``assert_same_mission``: every column but wall and planning times, the altitude
50 m, the climb and the vertical force 0). Prints a Markdown table: per case, the pairs
identical, the pairs that differ (with the first seed and the check's message) and the
seconds the case took. Missions run in ``--jobs`` processes, one pair at a time each.
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor

import harness  # noqa: F401  (the repository on the path: before its packages)

from tests.support.lifted import LIFTED, SCENARIOS, assert_same_mission, flown_pair


def compare(case: tuple[str, str, int]) -> tuple[str, str, int, str, float]:
    """(name, scenario, seed, "" if identical else the check's message, seconds)."""
    name, scenario, seed = case
    t0 = time.perf_counter()
    try:
        assert_same_mission(*flown_pair(name, seed, scenario))
        diff = ""
    except AssertionError as exc:
        diff = (str(exc).splitlines() or ["assertion"])[0][:80] or "assertion"
    return name, scenario, seed, diff, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=40, help="seeds 0..N-1 of each case")
    ap.add_argument("--jobs", type=int, default=2, help="processes")
    args = ap.parse_args()
    cases = [(n, s, seed) for n in LIFTED for s in SCENARIOS for seed in range(args.seeds)]
    rows: dict[tuple[str, str], list[tuple[int, str, float]]] = {}
    with ProcessPoolExecutor(args.jobs) as pool:
        for name, scenario, seed, diff, secs in pool.map(compare, cases):
            rows.setdefault((name, scenario), []).append((seed, diff, secs))
    print(f"seeds 0..{args.seeds - 1} of each case, {args.jobs} processes\n")
    print("| controller | scenario | identical | differ | first differing seed | s (wall) |")
    print("|---|---|---|---|---|---|")
    total = same = 0
    for (name, scenario), got in rows.items():
        differ = [(seed, diff) for seed, diff, _ in got if diff]
        first = f"{differ[0][0]}: {differ[0][1]}" if differ else "-"
        secs = sum(s for _, _, s in got)
        print(f"| {name} | {scenario} | {len(got) - len(differ)} | {len(differ)} | {first} "
              f"| {secs:.0f} |")
        total += len(got)
        same += len(got) - len(differ)
    print(f"\n{same} of {total} pairs identical")


if __name__ == "__main__":
    main()
